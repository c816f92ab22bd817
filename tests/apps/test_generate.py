"""`deltagen generate`: the checked-in generated/ is current, --check catches a stale or
missing file with a diff, and generation is deterministic (byte-identical across
processes with different hash seeds). Only copies of generated/ are ever modified."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

from deltagen import cli, paths
from deltagen.api.serial import bundled_robots, bundled_urdfs
from deltagen.apps import generate

DELTA = ("delta_kinematics.c", "delta_kinematics.h", "delta_kinematics.cdef.h")
# the linear delta's and the tripod's cores (one each, the geometry in a struct)
THREE_SPHERES = tuple(
    f"{stem}{ext}"
    for stem in ("linear_delta_kinematics", "tripod_kinematics")
    for ext in (".c", ".h", ".cdef.h")
)
FIVE_AXIS = ("five_axis_kinematics.c", "five_axis_kinematics.h", "five_axis_kinematics.cdef.h")
# the delta core, the linear delta's, the tripod's and the 5-axis machines' cores, and one
# C module per bundled serial arm (TOML and URDF)
NAMES = (
    DELTA
    + THREE_SPHERES
    + FIVE_AXIS
    + tuple(
        f"serial_{name}{ext}"
        for name in bundled_robots() + bundled_urdfs()
        for ext in (".c", ".h", ".cdef.h")
    )
)
# the parallel-kinematics families, one module each (geometry in a run-time struct)
NAMES += ("hexapod_kinematics.c", "hexapod_kinematics.h", "hexapod_kinematics.cdef.h")
# each module's kernel manifest (codegen.render.kernel_manifest)
NAMES += tuple(sorted({f"{name.split('.')[0]}.kernels.json" for name in NAMES}))


@pytest.fixture(scope="module")
def rendered():
    """Every generated file as checked in: tests/codegen/test_generated_*.py render each
    module and compare it with these files, so the tests below read them instead of
    deriving every robot once more."""
    return {p.name: p.read_text() for p in paths.generated_dir().iterdir()}


@pytest.fixture
def render_once(monkeypatch, rendered):
    """`generate`'s render returns the module's render (same text, no re-derivation)."""
    monkeypatch.setattr(generate, "generated_files", lambda: dict(rendered))


@pytest.fixture
def generated_copy(tmp_path, monkeypatch, render_once):
    """A copy of generated/ that `deltagen generate` will use instead of the real one."""
    copy = tmp_path / "generated"
    shutil.copytree(paths.generated_dir(), copy)
    monkeypatch.setattr(generate, "generated_dir", lambda: copy)
    monkeypatch.setattr(paths, "generated_dir", lambda: copy)
    return copy


def test_every_module_is_rendered(rendered):
    assert set(rendered) == set(NAMES)
    for name, text in rendered.items():
        assert text.endswith("\n") and "\r" not in text, name
        assert "do not edit" in text and "deltagen" in text, name
    assert set(DELTA) <= set(rendered)


def _layout_problems(name, text):
    """Runs of blank lines, trailing whitespace, and code lines whose indentation is not
    four spaces per open brace (continuation lines and comments aside)."""
    problems = []
    if "\n\n\n" in text:
        problems.append(f"{name}: a run of blank lines")
    if re.search(r"[ \t]\n", text):
        problems.append(f"{name}: trailing whitespace")
    depth, in_comment, prev, cplusplus = 0, False, ";", False
    for number, line in enumerate(text.splitlines(), 1):
        code = line.strip()
        if code.startswith("#ifdef __cplusplus"):
            cplusplus = True
            continue
        if cplusplus:  # extern "C" { and its }: no indentation level
            cplusplus = False
            continue
        if in_comment:
            in_comment = "*/" not in code
            continue
        if code.startswith("/*"):
            in_comment = "*/" not in code
            continue
        if not code or code.startswith("#"):
            continue
        want = 4 * (depth - (1 if code.startswith("}") else 0))
        indent = len(line) - len(line.lstrip(" "))
        if prev[-1:] in (";", "{", "}") and indent != want:
            problems.append(f"{name}:{number}: indented {indent}, expected {want}: {code[:60]}")
        depth += code.count("{") - code.count("}")
        prev = re.sub(r"/\*.*?\*/", "", code).rstrip()
    return problems


def test_generated_layout_is_clean(rendered):
    """trim_blocks/lstrip_blocks and the templates give C without stray indentation or runs
    of blank lines, and each file names the template it was rendered from."""
    c_files = {name: text for name, text in rendered.items() if not name.endswith(".json")}
    problems = [p for name, text in c_files.items() for p in _layout_problems(name, text)]
    assert problems == [], "\n".join(problems[:20])
    for name, text in c_files.items():
        template = {".c": "source.c.j2", ".h": "header.h.j2"}.get(
            name[name.index(".") :], "cdef.h.j2"
        )
        assert f"deltagen/codegen/templates/{template}" in text.split("*/")[0], name


def test_checkout_is_current(capsys, render_once):
    assert cli.main(["generate", "--check"]) == 0
    assert "up to date" in capsys.readouterr().out
    assert generate.check() == []


def test_check_reports_a_modified_file_with_a_diff(generated_copy, capsys):
    target = generated_copy / "delta_kinematics.c"
    text = target.read_text()
    marker = "#define DELTAGEN_DELTA_BLOCK"
    assert marker in text
    target.write_text(text.replace(marker, "/* hand edit */\n" + marker, 1))

    problems = generate.check(generated_copy)
    assert len(problems) == 1 and problems[0].startswith("delta_kinematics.c is stale")
    assert "-/* hand edit */" in problems[0] and "+++" in problems[0]

    assert cli.main(["generate", "--check"]) == 1
    err = capsys.readouterr().err
    assert "delta_kinematics.c is stale" in err and "-/* hand edit */" in err
    assert "run `deltagen generate`" in err

    # regenerating the copy repairs it, and a second run writes nothing
    assert cli.main(["generate"]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {target}"
    assert generate.check(generated_copy) == []
    assert generate.write(generated_copy) == []


def test_check_reports_missing_and_changed_files(generated_copy, capsys):
    (generated_copy / "delta_kinematics.h").unlink()
    cdef = generated_copy / "delta_kinematics.cdef.h"
    cdef.write_text(cdef.read_text().replace("int8_t", "int16_t"))
    problems = generate.check(generated_copy)
    assert sorted(p.split(" ")[0] for p in problems) == [
        "delta_kinematics.cdef.h",
        "delta_kinematics.h",
    ]
    assert any("delta_kinematics.h is missing" in p for p in problems)
    assert any("int16_t" in p for p in problems)
    assert cli.main(["generate", "--check"]) == 1
    capsys.readouterr()


def test_check_fails_on_a_stray_file(generated_copy, capsys):
    """A file in generated/ that the generator does not produce (a removed robot's module, a
    hand-made file) fails --check; `generate` warns about it and leaves it alone."""
    (generated_copy / "serial_retired_arm.c").write_text("/* an old module */\n")
    problems = generate.check(generated_copy)
    assert len(problems) == 1 and problems[0].startswith("serial_retired_arm.c is stray")
    assert generate.stray(generated_copy) == ["serial_retired_arm.c"]
    assert cli.main(["generate", "--check"]) == 1
    assert "serial_retired_arm.c is stray" in capsys.readouterr().err
    assert cli.main(["generate"]) == 0
    assert "serial_retired_arm.c is not produced" in capsys.readouterr().err
    (generated_copy / "serial_retired_arm.c").unlink()
    assert generate.check(generated_copy) == []


def test_write_into_an_empty_directory(tmp_path, rendered, render_once):
    written = generate.write(tmp_path / "out")
    assert sorted(p.name for p in written) == sorted(NAMES)
    for name in NAMES:
        assert (tmp_path / "out" / name).read_text() == rendered[name]


# The fresh interpreter renders the delta core and two arms (the closed-form Puma with its
# dynamics, the offset-wrist Puma with the combined method): every kind of derivation, at a
# quarter of a full render's cost; the whole set is compared with generated/ in-process by
# tests/codegen/test_generated_*.py (under pytest's own, random hash seed).
DETERMINISM_ARMS = ("puma560", "puma560_offset_wrist")


@pytest.mark.slow
def test_rendering_is_deterministic_across_processes(tmp_path):
    """A fresh interpreter with a fixed hash seed renders the checked-in bytes, which the
    in-process renders of tests/codegen/test_generated_*.py (another, random seed) equal."""
    script = textwrap.dedent("""
        import sys
        from pathlib import Path
        from deltagen.codegen.delta import delta_sources
        from deltagen.codegen.serial import arm_sources
        from deltagen.model.serial import SerialDescription
        from deltagen.paths import robots_dir

        files = dict(delta_sources())
        for name in sys.argv[2:]:
            files.update(arm_sources(SerialDescription.from_toml(robots_dir() / f"{name}.toml")))
        out = Path(sys.argv[1])
        out.mkdir(parents=True)
        for name, text in files.items():
            (out / name).write_text(text)
    """)
    procs = []
    for seed in ("4242",):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        out = tmp_path / f"seed{seed}"
        procs.append(
            (
                out,
                subprocess.Popen(
                    [sys.executable, "-c", script, str(out), *DETERMINISM_ARMS],
                    env=env,
                    cwd=str(paths.generated_dir().parent),
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                ),
            )
        )
    for _out, proc in procs:
        stdout, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, stderr.decode()
    ((a, _),) = procs
    names = sorted(p.name for p in a.iterdir())
    assert len(names) == 4 * (1 + len(DETERMINISM_ARMS)), names  # .c .h .cdef.h .kernels.json
    for name in names:
        assert (a / name).read_bytes() == (paths.generated_dir() / name).read_bytes(), name


def test_rendering_uses_the_templates(tmp_path, monkeypatch, rendered):
    """The emitted C is laid out by templates/*.j2: a changed template changes the output."""
    from deltagen.codegen import render

    copy = tmp_path / "templates"
    shutil.copytree(paths.template_dir(), copy)
    header = copy / "header.h.j2"
    header.write_text("/* template marker */\n" + header.read_text())
    monkeypatch.setattr(render, "template_dir", lambda: copy)
    # one module alone, the quickest to derive (the lecture's PRP arm): the templates are
    # shared by every module
    again = generate.module_renderers()["serial_lecture_prp"]()
    marked = "/* template marker */\n" + rendered["serial_lecture_prp.h"]
    assert again["serial_lecture_prp.h"] == marked
    assert again["serial_lecture_prp.c"] == rendered["serial_lecture_prp.c"]
