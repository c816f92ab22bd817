"""The build cache under faults (native/build.py, "How the cache stays sound"): concurrent
cold builds from threads and processes, corrupted / truncated / missing artifacts,
relative, non-directory and unusable cache paths, compiler errors and warnings.

A tiny C module (one function) stands in for a robot core, so each cold build takes a
fraction of a second; one test builds a real robot core from a relative cache path.
Checks that must survive a crash of the loading process run in subprocesses.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from deltagen.native import build

TINY_C = """#include "tiny.h"
int tiny_add(int a, int b) { return a + b; }
"""
TINY_H = "int tiny_add(int a, int b);\n"
TINY_CDEF = "int tiny_add(int a, int b);\n"

# loads the tiny module from the cache named by DELTAGEN_CACHE and calls it
LOADER = textwrap.dedent("""
    import sys
    from deltagen.native import build
    module = build.load("tiny", "tiny", sys.argv[1])
    print(module.lib.tiny_add(2, 3))
""")


@pytest.fixture
def tiny(tmp_path):
    source = tmp_path / "src"
    source.mkdir()
    # a comment unique to the test: its own cache key, never a module loaded before
    (source / "tiny.c").write_text(f"/* {tmp_path.name} */\n" + TINY_C)
    (source / "tiny.h").write_text(TINY_H)
    (source / "tiny.cdef.h").write_text(TINY_CDEF)
    return source


def _run_loader(source: Path, private_cache: Path, cwd: Path | None = None):
    env = dict(os.environ, DELTAGEN_CACHE=str(private_cache))
    return subprocess.run(
        [sys.executable, "-c", LOADER, str(source)],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _artifact(private_cache: Path) -> Path:
    (folder,) = [p for p in private_cache.iterdir() if p.name.startswith("_deltagen_tiny_")]
    (so,) = folder.glob("*.so")
    return so


def test_cold_build_writes_a_verified_artifact(tiny, private_cache):
    proc = _run_loader(tiny, private_cache)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "5"
    so = _artifact(private_cache)
    assert (so.parent / "manifest.json").is_file()
    assert build._verified(so.parent, so)


@pytest.mark.parametrize(
    "fault",
    ["truncated", "zero_length", "garbage", "missing_so", "missing_manifest", "wrong_manifest"],
)
def test_a_damaged_artifact_is_rebuilt_not_loaded(tiny, private_cache, fault):
    """Before the fix a truncated .so killed every later process with SIGBUS and an empty
    one or a folder without its .so gave a permanent ImportError."""
    assert _run_loader(tiny, private_cache).returncode == 0
    so = _artifact(private_cache)
    data = so.read_bytes()
    if fault == "truncated":
        so.write_bytes(data[: len(data) // 3])
    elif fault == "zero_length":
        so.write_bytes(b"")
    elif fault == "garbage":
        so.write_bytes(os.urandom(len(data)))
    elif fault == "missing_so":
        so.unlink()
    elif fault == "missing_manifest":
        (so.parent / "manifest.json").unlink()
    elif fault == "wrong_manifest":
        (so.parent / "manifest.json").write_text('{"size": 1, "sha256": "00"}')
    proc = _run_loader(tiny, private_cache)
    assert proc.returncode == 0, f"rc {proc.returncode}: {proc.stderr[-2000:]}"
    assert proc.stdout.strip() == "5"
    assert build._verified(so.parent, _artifact(private_cache))


def test_concurrent_cold_builds_from_threads(tiny, private_cache):
    """Before the fix cffi's compile changed the working directory of the whole process,
    so threads building at once collided."""
    cwd = os.getcwd()
    results, errors, cwds = [], [], set()
    barrier = threading.Barrier(4)

    def worker():
        try:
            barrier.wait()
            results.append(build.load("tiny", "tiny", tiny).lib.tiny_add(20, 22))
            cwds.add(os.getcwd())
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert errors == []
    assert results == [42] * 4
    assert cwds == {cwd} and os.getcwd() == cwd
    assert len([p for p in private_cache.iterdir() if p.name.startswith("_deltagen_tiny_")]) == 1


def test_concurrent_cold_builds_from_processes(tiny, private_cache):
    env = dict(os.environ, DELTAGEN_CACHE=str(private_cache))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", LOADER, str(tiny)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(4)
    ]
    outputs = [p.communicate(timeout=300) for p in procs]
    for proc, (out, err) in zip(procs, outputs):
        assert proc.returncode == 0, err
        assert out.strip() == "5"
    assert not [p for p in private_cache.iterdir() if ".bad." in p.name or p.name.endswith(".tmp")]


def test_relative_cache_path_is_resolved_once(tiny, tmp_path):
    """Before the fix a relative DELTAGEN_CACHE made every build fail with a message that
    blamed the compiler."""
    work = tmp_path / "cwd"
    work.mkdir()
    proc = _run_loader(tiny, Path("relative-cache"), cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert (work / "relative-cache").is_dir()
    assert _artifact(work / "relative-cache").is_file()


def test_relative_cache_path_builds_a_robot_core(tmp_path):
    """The same for a real core: a user arm rendered and compiled from a relative cache."""
    script = textwrap.dedent("""
        import numpy as np
        from deltagen import SerialRobot
        arm = SerialRobot.from_dh([{"a": 0.3}, {"a": 0.2}], "standard", name="planar2")
        T = arm.fk(np.array([0.1, 0.2]))
        print(float(T[0, 3]))
    """)
    work = tmp_path / "cwd"
    work.mkdir()
    env = dict(os.environ, DELTAGEN_CACHE="rel")
    proc = subprocess.run(
        [sys.executable, "-c", script],
        env=env,
        cwd=work,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr.strip() == "", "a successful build printed to the terminal"
    assert (work / "rel").is_dir()


def test_cache_path_that_is_a_file(tiny, tmp_path, monkeypatch):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    monkeypatch.setenv("DELTAGEN_CACHE", str(blocker))
    with pytest.raises(build.BuildError, match="not a directory") as info:
        build.load("tiny", "tiny", tiny)
    assert str(blocker) in str(info.value)


def test_cache_path_that_cannot_be_created(tiny, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    bad = blocker / "cache"
    monkeypatch.setenv("DELTAGEN_CACHE", str(bad))
    with pytest.raises(build.BuildError, match="cannot be created") as info:
        build.load("tiny", "tiny", tiny)
    assert str(bad) in str(info.value)


def test_reference_backend_works_without_a_usable_cache(tmp_path, monkeypatch):
    import numpy as np

    from deltagen import DeltaRobot, SerialRobot

    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    monkeypatch.setenv("DELTAGEN_CACHE", str(blocker))
    p = DeltaRobot.default(backend="reference").fk(np.array([0.1, 0.2, 0.3]))
    assert np.all(np.isfinite(p))
    arm = SerialRobot.from_dh(
        [{"a": 0.3}, {"a": 0.2}], "standard", name="planar2", backend="reference"
    )
    assert np.isfinite(arm.fk(np.array([0.1, 0.2]))).all()


def test_compiler_error_text_reaches_the_user(tiny, private_cache):
    (tiny / "tiny.c").write_text(TINY_C + "int broken_function(void) { return undeclared_name; }\n")
    with pytest.raises(build.BuildError) as info:
        build.load("tiny", "tiny", tiny)
    text = str(info.value)
    assert "undeclared_name" in text and "error" in text
    assert "is a C compiler installed" not in text


def test_warnings_of_a_successful_build_stay_quiet(tiny, private_cache, capfd):
    (tiny / "tiny.c").write_text(TINY_C + "int unused_arg(int x, int y) { return x; }\n")
    assert build.load("tiny", "tiny", tiny).lib.tiny_add(1, 1) == 2
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_missing_compiler_is_named(tiny, private_cache, monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/deltagen-cc")
    with pytest.raises(build.BuildError, match="deltagen-cc"):
        build.load("tiny", "tiny", tiny)


def _read_only(folder: Path, how: str, monkeypatch) -> None:
    """Make ``folder`` read-only: chmod 0o555 (root ignores permissions: skipped there), or
    os.access reporting no write permission for it (what the cache check asks; works as
    root too)."""
    folder.mkdir(parents=True, exist_ok=True)
    if how == "chmod":
        if os.geteuid() == 0:
            pytest.skip("root ignores directory permissions")
        folder.chmod(0o555)
        return
    real_access = os.access

    def access(path, mode, *args, **kwargs):
        if Path(path).resolve() == folder.resolve() and mode & os.W_OK:
            return False
        return real_access(path, mode, *args, **kwargs)

    monkeypatch.setattr(build.os, "access", access)


@pytest.mark.parametrize("how", ["chmod", "access"])
def test_read_only_cache_dir_is_named(tiny, tmp_path, monkeypatch, how):
    folder = tmp_path / "read-only-cache"
    _read_only(folder, how, monkeypatch)
    monkeypatch.setenv("DELTAGEN_CACHE", str(folder))
    try:
        with pytest.raises(build.BuildError, match="not writable") as info:
            build.load("tiny", "tiny", tiny)
        assert str(folder) in str(info.value)
        assert "DELTAGEN_CACHE" in str(info.value)
        assert list(folder.iterdir()) == []  # nothing half-written was left behind
    finally:
        folder.chmod(0o755)


@pytest.mark.parametrize("how", ["chmod", "access"])
def test_reference_backend_works_with_a_read_only_cache(tmp_path, monkeypatch, how):
    import numpy as np

    from deltagen import DeltaRobot, SerialRobot

    folder = tmp_path / "read-only-cache"
    _read_only(folder, how, monkeypatch)
    monkeypatch.setenv("DELTAGEN_CACHE", str(folder))
    try:
        robot = DeltaRobot.default(backend="reference")
        q = np.array([0.1, 0.2, 0.3])
        assert np.allclose(robot.ik(robot.fk(q)), q, atol=1e-12)  # a round trip, not a number
        arm = SerialRobot.from_dh(
            [{"a": 0.3}, {"a": 0.2}], "standard", name="planar2", backend="reference"
        )
        T = arm.fk(np.array([0.1, 0.2]))
        assert np.isclose(T[0, 3], 0.3 * np.cos(0.1) + 0.2 * np.cos(0.3))
    finally:
        folder.chmod(0o755)


# a fresh interpreter (no core loaded yet) whose os.access refuses writes to the cache: the
# public compiled API gives the cache's BuildError naming the path, the reference one works
READ_ONLY_API = textwrap.dedent("""
    import os, sys
    from pathlib import Path
    cache = Path(sys.argv[1]).resolve()
    real_access = os.access
    def access(path, mode, *args, **kwargs):
        if Path(path).resolve() == cache and mode & os.W_OK:
            return False
        return real_access(path, mode, *args, **kwargs)
    os.access = access
    from deltagen import DeltaRobot
    from deltagen.native.build import BuildError
    try:
        DeltaRobot.default()
    except BuildError as exc:
        print("BuildError:", exc)
    q = [0.1, 0.2, 0.3]
    robot = DeltaRobot.default(backend="reference")
    print("reference round trip", max(abs(a - b) for a, b in zip(robot.ik(robot.fk(q)), q)))
""")


def test_compiled_api_names_a_read_only_cache_in_a_fresh_process(tmp_path):
    cache = tmp_path / "read-only-cache"
    cache.mkdir()
    env = dict(os.environ, DELTAGEN_CACHE=str(cache))
    proc = subprocess.run(
        [sys.executable, "-c", READ_ONLY_API, str(cache)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("BuildError:") and "not writable" in lines[0]
    assert str(cache) in lines[0]
    assert float(lines[1].split()[-1]) < 1e-12
    assert "Traceback" not in proc.stderr
    assert list(cache.iterdir()) == []


def test_optimisation_level_is_part_of_the_key_and_the_command(tiny, private_cache):
    """-O3 (default) and -O2 (modules rendered at run time, native/serial.py) are two
    artifacts, each built with its own level; anything else is refused."""
    o3 = build.load("tiny", "tiny", tiny)
    o2 = build.load("tiny", "tiny", tiny, opt="-O2")
    assert o3 is not o2 and o2.lib.tiny_add(2, 3) == 5
    commands = sorted(
        (p / "manifest.json").read_text()
        for p in private_cache.iterdir()
        if p.name.startswith("_deltagen_")
    )
    assert len(commands) == 2
    assert sum("-O2" in c for c in commands) == 1 and sum("-O3" in c for c in commands) == 1
    with pytest.raises(ValueError, match="opt"):
        build.compile_flags("tiny", "-Ofast")


@pytest.mark.slow
def test_o2_and_o3_give_the_same_bits(monkeypatch):
    """A checked-in module with every kind of kernel (kinematics with sin/cos loops,
    closed-form IK, dynamics) built at -O2 gives the same doubles as at -O3 (the level of
    modules rendered at run time, native/serial.py: no level may change a floating-point
    result without -ffast-math and with FMA contraction off under -std=c99). The Miskolc
    RRRR arm: the Puma 560's kernel set (fk, jacobian, jacobian_dot, ik_all, inverse
    dynamics, mass matrix, ...) in half its C, so the -O2 build costs half a Puma's."""
    import numpy as np

    from deltagen import SerialRobot
    from deltagen.native import serial as native_serial

    # the suite's cache: the -O3 module is the one the other tests load (built once per
    # run), only the -O2 one is this test's own
    arm = SerialRobot.load("miskolc_rrrr", threads=1)
    prefix, dof = "deltagen_miskolc_rrrr", arm.n
    # the checked-in module as a whole (on a cold cache the arm itself starts from its
    # parts, native/serial.py: load_dynamics would be the dynamics part, without fk)
    modules = [native_serial.complete_module(arm.description)]
    monkeypatch.setattr(native_serial, "_opt", lambda folder: "-O2")
    modules.append(native_serial._load(arm.description))
    assert modules[0] is not modules[1]
    rng = np.random.default_rng(4)
    n = 2000
    k = len(arm.analytic_configs())
    assert k == 4  # ik_all's branches: front/back x elbow up/down (model/structure.py)
    # within the joint limits: ik_all's branches are valid only there (the pose's own one)
    q = rng.uniform(arm.qlim[:, 0], arm.qlim[:, 1], (n, dof))
    qd, qdd = rng.uniform(-2, 2, (2, n, dof))
    T = arm.fk(q)

    def call(module, name, inputs, widths, flags=()):
        ffi = module.ffi
        outs = [np.zeros((n, w)) for w in widths] + [np.zeros((n, w), np.uint8) for w in flags]
        status = np.zeros(n, np.int8)
        args = [ffi.from_buffer("double[]", np.ascontiguousarray(x)) for x in inputs]
        args += [ffi.from_buffer("double[]", o) for o in outs[: len(widths)]]
        args += [ffi.from_buffer("uint8_t[]", o) for o in outs[len(widths) :]]
        fn = getattr(module.lib, f"{prefix}_{name}")
        assert fn(n, *args, ffi.from_buffer("int8_t[]", status)) == 0, name
        return [*outs, status]

    results = [
        {
            "fk": call(m, "fk", [q], [16]),
            "jacobian": call(m, "jacobian", [q], [6 * dof]),
            "fk_jacobian": call(m, "fk_jacobian", [q], [16, 6 * dof]),
            "jacobian_dot": call(m, "jacobian_dot", [q, qd], [6 * dof]),
            "ik_all": call(m, "ik_all", [T.reshape(n, 16)], [k * dof], [k]),
            "inverse_dynamics": call(m, "inverse_dynamics", [q, qd, qdd], [dof]),
            "mass_matrix": call(m, "mass_matrix", [q], [dof * dof]),
            "gravity_torque": call(m, "gravity_torque", [q], [dof]),
            "coriolis": call(m, "coriolis", [q, qd], [dof * dof]),
            "nonlinear_effects": call(m, "nonlinear_effects", [q, qd], [dof]),
        }
        for m in modules
    ]
    # not vacuous: the closed form solves most poses, and every value is a number
    assert results[0]["ik_all"][1].any(axis=1).mean() > 0.5
    for name, values in results[0].items():
        assert np.isfinite(values[0]).any(), name
        for a, b in zip(values, results[1][name]):
            assert np.array_equal(a, b, equal_nan=True), name


def test_the_suite_never_uses_the_users_cache():
    """tests/conftest.py points DELTAGEN_CACHE at the suite's own folder before deltagen is
    imported: the cache resolves there, not to the user's ~/.cache/deltagen, and no module
    this process has loaded came from the user's cache."""
    from deltagen import paths

    home_cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    users = Path(home_cache, "deltagen").resolve()
    root = paths.cache_dir().resolve()
    assert root == Path(os.environ["DELTAGEN_CACHE"]).resolve()
    assert root != users and users not in root.parents
    for module in list(build._LOADED.values()):
        assert users not in Path(module.__file__).resolve().parents, module.__file__


def test_the_cache_follows_a_later_change_of_deltagen_cache(tiny, tmp_path, monkeypatch):
    """DELTAGEN_CACHE is read at every build, not once per process: a test (or a user) that
    changes it gets the new folder, and the module is built there."""
    from deltagen import paths

    for name in ("first", "second"):
        folder = tmp_path / name
        monkeypatch.setenv("DELTAGEN_CACHE", str(folder))
        assert paths.cache_dir() == folder
    module = build.load("tiny", "tiny", tiny)
    assert module.lib.tiny_add(2, 3) == 5
    assert Path(module.__file__).parent.parent == tmp_path / "second"
    assert not (tmp_path / "first").exists()
