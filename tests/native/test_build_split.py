"""A module split into translation units at build time (native/build.py: the kernels
compile in parallel, for a short cold load): the split is exact, gives the same doubles as
the whole file, names the module's own file and line in a compiler error, and two processes
loading the same cold module still build it once."""

from __future__ import annotations

import functools
import os
import re
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from deltagen.inputs import InputError
from deltagen.native import build
from deltagen.paths import generated_dir

# three kernels; the second one's body is replaced by BROKEN in the error test
KERNELS_C = """/* {tag} */
#include "kern.h"

#define KERN_SCALE 3

int kern_a(int x)
{{
    return KERN_SCALE * x;
}}

/* the second kernel
 * (a comment before it belongs to the unit before) */
int kern_b(int x)
{{
    {body}
}}

int kern_c(int x)
{{
    return kern_a(x) + kern_b(x);
}}
"""
KERNELS_H = "int kern_a(int x);\nint kern_b(int x);\nint kern_c(int x);\n"

LOADER = textwrap.dedent("""
    import sys
    from deltagen.native import build
    module = build.load("kern", "kern", sys.argv[1], split=True)
    print(module.lib.kern_c(5))
""")


def _write_kernels(folder: Path, body: str = "return x + 1;") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "kern.c").write_text(KERNELS_C.format(tag=folder, body=body))
    (folder / "kern.h").write_text(KERNELS_H)
    (folder / "kern.cdef.h").write_text(KERNELS_H)
    return folder


@pytest.mark.parametrize("path", sorted(generated_dir().glob("*.c")), ids=lambda p: p.name)
def test_every_checked_in_module_splits_into_its_kernels(path):
    """The units hold the whole file (preamble + kernels, in order, nothing lost or
    repeated) and each kernel starts at one of the file's exported definitions."""
    text = path.read_text()
    units = build.split_units(text)
    assert units is not None, f"{path.name} would compile as one unit"
    preamble, kernels = units
    lines = text.split("\n")
    assert preamble + [line for _, body in kernels for line in body] == lines
    exported = set(re.findall(r"^int (deltagen_\w+)\(", text, re.MULTILINE))
    starts = {re.match(r"int (deltagen_\w+)\(", body[0]).group(1) for _, body in kernels}
    assert starts == exported
    for first, body in kernels:
        assert lines[first - 1] == body[0]  # #line numbers are 1-based file lines


@pytest.mark.parametrize(
    "text",
    [
        "int a(void)\n{\n    return 1;\n}\n",  # one definition: nothing to split
        "#include <math.h>\nint a(void)\n{\n    return 1;\n}\n"
        "static int h(void)\n{\n    return 2;\n}\nint b(void)\n{\n    return h();\n}\n",
        "int a(void)\n{\n    return 1;\n}\n#define TWO 2\nint b(void)\n{\n    return TWO;\n}\n",
        "int a(void)\n{\n    return 1;\n}\nconst int table[2] = {1, 2};\n"
        "int b(void)\n{\n    return table[1];\n}\n",
    ],
    ids=["one-definition", "static-helper", "macro-between", "file-scope-data"],
)
def test_layouts_the_split_cannot_keep_exact_compile_as_one_unit(text):
    assert build.split_units(text) is None


def test_split_module_computes_what_the_whole_file_does(tmp_path, private_cache):
    source = _write_kernels(tmp_path / "src")
    split = build.load("kern", "kern", source, split=True)
    whole = build.load("kern", "kern", source, split=False)
    assert split is not whole
    for x in (-7, 0, 5, 11):
        assert split.lib.kern_c(x) == whole.lib.kern_c(x) == 3 * x + x + 1
    manifests = [
        (p / "manifest.json").read_text() for p in private_cache.iterdir() if "_kern_" in p.name
    ]
    assert len(manifests) == 2
    assert sum(".unit" in m for m in manifests) == 1  # one built from units, one whole


def test_a_build_splits_when_compilers_can_run_at_once_and_a_built_module_serves_either_way(
    tmp_path, private_cache, monkeypatch
):
    """Unless told (``split``), a module is split when more than one compiler may run at
    once (native/build.py _build_jobs) and compiled as one unit when one may: nothing runs
    in parallel then, and one unit costs less compiler time. Either build, once in the
    cache, is the one loaded, whatever the cores: the same bits, no second compile."""

    def manifests():
        return [
            (p / "manifest.json").read_text()
            for p in private_cache.iterdir()
            if p.name.startswith("_deltagen_kern_") and (p / "manifest.json").is_file()
        ]

    one, many = _write_kernels(tmp_path / "one"), _write_kernels(tmp_path / "many")
    monkeypatch.setattr(build, "_build_jobs", lambda: 1)
    assert not build.is_built("kern", "kern", one)
    build.load("kern", "kern", one)
    assert [".unit" in m for m in manifests()] == [False]
    monkeypatch.setattr(build, "_build_jobs", lambda: 2)
    build.load("kern", "kern", many)
    assert sorted(".unit" in m for m in manifests()) == [False, True]
    assert build.is_built("kern", "kern", one) and build.is_built("kern", "kern", many)
    assert build.is_built("kern", "kern", one, split=False)
    assert not build.is_built("kern", "kern", one, split=True)
    # the one-unit build serves a process with two cores, the split one a process with one
    assert build.load("kern", "kern", one).lib.kern_c(5) == 21
    monkeypatch.setattr(build, "_build_jobs", lambda: 1)
    assert build.load("kern", "kern", many).lib.kern_c(5) == 21
    assert len(manifests()) == 2


@pytest.mark.parametrize("split", [True, False], ids=["split", "whole"])
def test_compiler_error_in_one_kernel_names_the_file_and_line(tmp_path, private_cache, split):
    source = _write_kernels(tmp_path / "src", body="return x + undeclared_name;")
    line = 1 + (source / "kern.c").read_text().split("\n").index("    return x + undeclared_name;")
    with pytest.raises(build.BuildError) as info:
        build.load("kern", "kern", source, split=split)
    text = str(info.value)
    assert "compiling kern.c failed" in text
    assert re.search(rf"kern\.c:{line}:\d+: error: .undeclared_name. undeclared", text), text
    assert ".unit" not in text.split("\n", 2)[2]  # the messages name kern.c, not a unit


def _logging_compiler(tmp_path: Path) -> tuple[str, Path]:
    """A CC that appends its arguments to a log, then runs the real compiler."""
    log = tmp_path / "cc.log"
    real = build._compiler_command()[0]
    script = tmp_path / "logcc"
    script.write_text(f'#!/bin/sh\necho "$*" >> {log}\nexec {real} "$@"\n')
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    return str(script), log


def test_two_processes_loading_a_cold_split_module_build_it_once(tmp_path):
    source = _write_kernels(tmp_path / "src")
    cc, log = _logging_compiler(tmp_path)
    cache = tmp_path / "cache"
    env = dict(os.environ, DELTAGEN_CACHE=str(cache), CC=cc)
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", LOADER, str(source)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
        assert out.strip() == str(3 * 5 + 5 + 1)
    calls = log.read_text().splitlines()
    links = [c for c in calls if " -c " not in f" {c} "]
    compiles = [c for c in calls if " -c " in f" {c} "]
    assert len(links) == 1, calls
    assert sum(".unit" in c for c in compiles) == 3  # kern_a, kern_b, kern_c, once each
    assert len([p for p in cache.iterdir() if p.name.startswith("_deltagen_kern_")]) == 1


@pytest.mark.slow  # a build of an arm's full module (the other is the suite's own)
def test_split_module_gives_the_bits_of_the_single_unit_build(monkeypatch):
    """Every kernel of an arm's module (kinematics, closed-form and numerical IK, dynamics,
    forward dynamics through the runtime's Cholesky) built as one unit per kernel gives the
    same doubles as built from the whole file. The Miskolc RRRR arm: the Puma 560's kernel
    set (sin/cos loops, a closed-form ik_all, every dynamics kernel) in half its C; the
    split is per kernel whatever the arm (test_every_checked_in_module_splits_into_its_kernels
    checks every module's units)."""
    from deltagen import SerialRobot
    from deltagen.native import serial as native_serial

    # the suite's cache: one of the two builds is the module the other tests load
    arms = {}
    for split in (True, False):
        monkeypatch.setattr(native_serial, "load", functools.partial(build.load, split=split))
        arms[split] = SerialRobot.load("miskolc_rrrr", threads=1)
        arms[split]._core.load_dynamics()
    assert arms[True]._core._lib is not arms[False]._core._lib
    rng = np.random.default_rng(10)
    n = 1500
    lo, hi = arms[True].qlim[:, 0], arms[True].qlim[:, 1]
    q = rng.uniform(lo, hi, (n, arms[True].n))
    qd, qdd, tau = rng.uniform(-2, 2, (3, n, arms[True].n))
    T = arms[True].fk(q)

    def results(arm):
        core = arm._core
        q_all, valid, ik_status = core.ik_all(np.ascontiguousarray(T), 4)
        return {
            "fk": core.fk(q),
            "frames": core.frames(q),
            "jacobian": core.jacobian(q),
            "fk_jacobian": core.fk_jacobian(q),
            "jacobian_dot": core.jacobian_dot(q, qd),
            "ik_all": (q_all, valid, ik_status),
            "ik_newton": arm.ik(T[:200], q0=q[:200] + 0.05, method="numeric", errors="nan"),
            "inverse_dynamics": core.inverse_dynamics(q, qd, qdd),
            "mass_matrix": core.mass_matrix(q),
            "gravity_torque": core.gravity_torque(q),
            "coriolis": core.coriolis(q, qd),
            "nonlinear_effects": core.nonlinear_effects(q, qd),
            "forward_dynamics": core.forward_dynamics(q, qd, tau),
        }

    split, whole = results(arms[True]), results(arms[False])
    for name, values in split.items():
        values = values if isinstance(values, tuple) else (values,)
        other = whole[name] if isinstance(whole[name], tuple) else (whole[name],)
        for a, b in zip(values, other):
            a, b = np.asarray(a), np.asarray(b)
            assert a.dtype == b.dtype and a.shape == b.shape, name
            assert np.array_equal(a, b, equal_nan=True), name
        assert np.isfinite(np.asarray(values[0], dtype=float)).any(), name  # not all NaN


def test_build_jobs_follow_the_usable_cores_and_the_cap(monkeypatch):
    cores = len(os.sched_getaffinity(0))
    monkeypatch.delenv("DELTAGEN_BUILD_JOBS", raising=False)
    assert build._build_jobs() == cores
    monkeypatch.setenv("DELTAGEN_BUILD_JOBS", "1")
    assert build._build_jobs() == 1
    monkeypatch.setenv("DELTAGEN_BUILD_JOBS", str(cores + 5))
    assert build._build_jobs() == cores  # a cap, never more compilers than cores
    monkeypatch.setenv("DELTAGEN_BUILD_JOBS", "")  # empty: as if unset
    assert build._build_jobs() == cores
    for bad in ("0", "-2", "many"):  # an error naming the variable, as DELTAGEN_THREADS's
        monkeypatch.setenv("DELTAGEN_BUILD_JOBS", bad)
        with pytest.raises(InputError, match="DELTAGEN_BUILD_JOBS must be a positive integer"):
            build._build_jobs()
