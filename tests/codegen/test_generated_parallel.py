"""generated/ is current, module by module: each checked-in module of the parallel
machines (the delta, the linear delta, the tripod, the 5-axis machine, the hexapod) is
rendered alone and compared with its files, and generated/ holds nothing but the modules
the generator renders. With tests/codegen/test_generated_serial_*.py this is what
`deltagen generate --check` checks, in parallel; `pytest --update-generated` rewrites."""

from __future__ import annotations

import pytest
from helpers import compare_or_update_generated, generated_stems, update_generated

from deltagen.paths import generated_dir

PARALLEL = [stem for stem in generated_stems() if not stem.startswith("serial_")]


def test_generated_holds_only_rendered_modules():
    """Every file of generated/ is ``<stem>.<ext>`` of a module the generator renders (a
    removed robot's module or a hand-made file is stray), and every module has files."""
    stems = set(generated_stems())
    files = sorted(p.name for p in generated_dir().iterdir())
    stray = [name for name in files if name.split(".", 1)[0] not in stems]
    assert stray == [], f"stray files in generated/ (delete them): {stray}"
    assert {name.split(".", 1)[0] for name in files} == stems
    assert set(PARALLEL) == {
        "delta_kinematics",
        "linear_delta_kinematics",
        "tripod_kinematics",
        "five_axis_kinematics",
        "hexapod_kinematics",
    }


@pytest.mark.parametrize("stem", PARALLEL)
def test_module_is_current(stem, request):
    compare_or_update_generated(stem, update_generated(request.config))


def test_a_stale_missing_or_stray_file_fails_and_the_update_flag_rewrites(tmp_path, monkeypatch):
    """The check itself, on a folder of its own and a stand-in renderer: a hand edit, a
    missing file and a stray ``<stem>.*`` each fail naming the file (with the diff), and
    the update flag writes the render and removes the stray file, after which it passes."""
    from deltagen import paths
    from deltagen.apps import generate

    render = {"arm_x.c": "int x;\n", "arm_x.h": "/* x */\n"}
    monkeypatch.setattr(generate, "module_renderers", lambda: {"arm_x": lambda: dict(render)})
    monkeypatch.setattr(paths, "generated_dir", lambda: tmp_path)
    (tmp_path / "arm_x.c").write_text("int x; /* hand edit */\n")
    (tmp_path / "arm_x.old").write_text("retired\n")
    (tmp_path / "arm_xy.c").write_text("another module's file\n")
    with pytest.raises(AssertionError) as failure:
        compare_or_update_generated("arm_x", update=False)
    text = str(failure.value)
    assert "arm_x.c is stale" in text and "-int x; /* hand edit */" in text
    assert "arm_x.h is missing" in text and "arm_x.old is stray" in text
    assert "arm_xy.c" not in text
    compare_or_update_generated("arm_x", update=True)
    assert {p.name for p in tmp_path.iterdir()} == {"arm_x.c", "arm_x.h", "arm_xy.c"}
    assert (tmp_path / "arm_x.c").read_text() == "int x;\n"
    compare_or_update_generated("arm_x", update=False)
