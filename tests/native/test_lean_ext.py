"""The CPython-extension entry of the single-row calls (deltagen/native/lean_ext.c).

Evidence: (1) the one-row call through the extension equals the batch kernel's row bit for
bit (a second caller of the same C function, through cffi and numpy); (2) for every input
the extension does not take, and every bad input, the outcome -- the result, or the
exception's type and message -- is exactly that of the Python lean path
(DELTAGEN_LEAN_EXT=0), which tests/api/test_checks.py ties to the general path; (3) threads
calling at once get their own rows; (4) 100 000 calls leave no memory behind (results,
declined calls, the inputs' reference counts); (5) where the extension cannot be built the
Python lean path serves, and a broken source gives a BuildError with the compiler's text.
tests/native/test_lean.py covers every quantity's one-row call against the batch; the
first test here makes sure those calls are the extension's.
"""

from __future__ import annotations

import sys
import sysconfig
import tracemalloc
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot
from deltagen.native import lean
from deltagen.native.build import BuildError, load_extension

HEADERS = (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file()
needs_ext = pytest.mark.skipif(not HEADERS, reason="no Python.h: the extension cannot be built")


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560", threads=1)


@pytest.fixture(scope="module")
def puma_python_lean():
    """The same arm with the Python (cffi) lean path: the behaviour to keep."""
    mp = pytest.MonkeyPatch()
    mp.setenv("DELTAGEN_LEAN_EXT", "0")
    try:
        robot = SerialRobot.load("puma560", threads=1)
        robot.inverse_dynamics(np.zeros(6), np.zeros(6), np.zeros(6))  # makes its singles
    finally:
        mp.undo()
    return robot


@pytest.fixture(scope="module")
def delta():
    return DeltaRobot.from_toml("robots/default_delta.toml", threads=1)


def _is_ext(f) -> bool:
    return type(f).__name__ == "builtin_function_or_method" and f.__name__ == "lean_call"


@needs_ext
def test_single_calls_use_the_extension(puma, delta, puma_python_lean):
    assert lean.extension() is not None
    zero = np.zeros(6)
    # each one-state function is made on its kernel's first call (api/serial.py)
    puma.inverse_dynamics(zero, zero, zero)
    puma.forward_dynamics(zero, zero, zero)
    puma.mass_matrix(zero)
    for f in (puma._fk_single, puma._jacobian_single, puma._id_single, puma._fd_single):
        assert _is_ext(f), f
    assert _is_ext(puma._mass_single)
    for name in delta._core._SINGLE:
        assert _is_ext(delta._core.single(name)), name
    assert not _is_ext(puma_python_lean._id_single)  # DELTAGEN_LEAN_EXT=0 is honoured
    assert not _is_ext(puma_python_lean._fk_single)


@needs_ext
def test_one_row_equals_the_batch_row_bit_for_bit(puma, monkeypatch):
    rng = np.random.default_rng(110)
    m = 200
    q = rng.uniform(-np.pi, np.pi, (m, 6))
    qd, qdd = rng.uniform(-3, 3, (m, 6)), rng.uniform(-30, 30, (m, 6))
    tau, T, J = puma.inverse_dynamics(q, qd, qdd), puma.fk(q), puma.jacobian(q)
    ints = [1, -2, 0, 3, 1, 2]
    T_ints = puma.fk(np.array([ints], dtype=float))[0]

    def refuse(*args, **kwargs):
        raise AssertionError("the one-row call went through the batch path")

    monkeypatch.setattr(puma._core, "_run", refuse)
    for i in range(m):
        assert np.array_equal(puma.inverse_dynamics(q[i], qd[i], qdd[i]), tau[i])
        assert np.array_equal(puma.fk(q[i]), T[i])
        assert np.array_equal(puma.jacobian(q[i]), J[i])
    # the inputs the extension reads from a local copy give the same bits
    wide = np.zeros((6, 3))
    wide[:, 1] = q[7]
    assert np.array_equal(puma.inverse_dynamics(wide[:, 1], qd[7], qdd[7]), tau[7])
    raw = np.zeros(6 * 8 + 1, dtype=np.uint8)[1:].view(np.float64)  # unaligned
    raw[:] = q[8]
    assert not raw.flags.aligned
    assert np.array_equal(puma.inverse_dynamics(raw, qd[8], qdd[8]), tau[8])
    ro = q[9].copy()
    ro.flags.writeable = False
    assert np.array_equal(puma.inverse_dynamics(ro, qd[9], qdd[9]), tau[9])
    assert np.array_equal(
        puma.inverse_dynamics(q[3].tolist(), tuple(qd[3].tolist()), qdd[3]), tau[3]
    )
    assert np.array_equal(puma.fk(ints), T_ints)


def _inputs():
    """(label, q) for one configuration: good ones the extension reads, inputs it leaves to
    the general path, and bad ones (each must fail or pass exactly as before)."""
    rng = np.random.default_rng(111)
    q = rng.uniform(-1, 1, 6)
    nan = q.copy()
    nan[2] = np.nan
    inf = q.copy()
    inf[0] = np.inf
    fortran = np.asfortranarray(np.stack([q, q]))
    ro = q.copy()
    ro.flags.writeable = False
    return [
        ("ndarray", q),
        ("list", q.tolist()),
        ("tuple", tuple(q.tolist())),
        ("read-only", ro),
        ("strided view", np.stack([q, q], axis=1)[:, 0]),
        ("Fortran (2, 6)", fortran),
        ("big-endian", q.astype(">f8")),
        ("float32", q.astype(np.float32)),
        ("int array", np.arange(6)),
        ("int list", [0, 1, 2, 3, 4, 5]),
        ("(1, 6)", q[None]),
        ("(6, 1)", q[:, None]),
        ("(5,)", q[:5]),
        ("(7,)", np.append(q, 0.0)),
        ("empty", np.zeros(0)),
        ("0-d", np.float64(0.5)),
        ("0-d array", np.array(0.5)),
        ("Python float", 0.5),
        ("NaN", nan),
        ("inf", inf),
        ("NaN in a list", nan.tolist()),
        ("bool array", np.ones(6, dtype=bool)),
        ("bool in a list", [True, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ("complex", q.astype(complex)),
        ("strings", ["a"] * 6),
        ("None", None),
        ("huge int", [10**400, 0, 0, 0, 0, 0]),
        ("numpy scalars in a list", [np.float64(v) for v in q]),
        ("matrix subclass", np.asmatrix(q)),
        ("short list", [0.0] * 5),
    ]


def _outcome(f, *args):
    try:
        return ("ok", f(*args))
    except Exception as exc:  # noqa: BLE001 -- the outcome to compare is any exception
        return ("raised", type(exc), str(exc))


def _same(a, b):
    if a[0] != b[0]:
        return False
    if a[0] == "raised":
        return a[1:] == b[1:]
    x, y = np.asarray(a[1]), np.asarray(b[1])
    return type(a[1]) is type(b[1]) and x.shape == y.shape and np.array_equal(x, y, equal_nan=True)


@needs_ext
@pytest.mark.parametrize("label, q", _inputs(), ids=[label for label, _ in _inputs()])
def test_every_input_has_the_outcome_of_the_python_lean_path(puma, puma_python_lean, label, q):
    rng = np.random.default_rng(112)
    qd, qdd = rng.uniform(-2, 2, 6), rng.uniform(-9, 9, 6)
    for case in (
        lambda r: r.inverse_dynamics(q, qd, qdd),
        lambda r: r.inverse_dynamics(qd, q, qdd),
        lambda r: r.inverse_dynamics(qd, qdd, q),
        lambda r: r.fk(q),
        lambda r: r.jacobian(q),
        lambda r: r.mass_matrix(q),
    ):
        a, b = _outcome(case, puma), _outcome(case, puma_python_lean)
        assert _same(a, b), (label, a, b)
    if label in ("NaN", "inf", "(5,)", "0-d", "None", "strings", "bool in a list"):
        assert _outcome(puma.inverse_dynamics, q, qd, qdd)[0] == "raised"


@needs_ext
def test_the_delta_keeps_its_outcomes(delta, monkeypatch):
    rng = np.random.default_rng(113)
    q, qd, qdd = (rng.uniform(-0.3, 0.9, 3) for _ in range(3))
    monkeypatch.setenv("DELTAGEN_LEAN_EXT", "0")
    old = DeltaRobot.from_toml("robots/default_delta.toml", threads=1)
    assert not _is_ext(old._core.single("fk"))
    nan = q.copy()
    nan[1] = np.nan
    cases = [
        lambda r: r.fk(q),
        lambda r: r.fk(nan),
        lambda r: r.fk(q[:2]),
        lambda r: r.fk_acc(q, qd, qdd),
        lambda r: r.ik(r.fk(q)),
        lambda r: r.ik(np.array([5.0, 5.0, 5.0])),  # out of reach
        lambda r: r.jacobian(q.tolist()),
        lambda r: r.inverse_dynamics(q, qd, qdd, 0.4),
        lambda r: r.inverse_dynamics(q, qd, qdd, -0.4),  # a negative payload
        lambda r: r.inverse_dynamics(q, qd, qdd, float("nan")),
        lambda r: r.inverse_dynamics(q, qd, qdd, 2),
        lambda r: r.inverse_dynamics(q, qd, qdd, True),
        lambda r: r.inverse_dynamics(q, qd, qdd),
    ]
    for i, case in enumerate(cases):
        a, b = _outcome(case, delta), _outcome(case, old)
        if a[0] == "ok" and isinstance(a[1], tuple):
            assert b[0] == "ok" and len(a[1]) == len(b[1]), i
            assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a[1], b[1])), i
        else:
            assert _same(a, b), (i, a, b)


@needs_ext
def test_threads_calling_at_once_get_their_own_rows(puma, delta):
    rng = np.random.default_rng(114)
    m = 400
    q, qd, qdd = (rng.uniform(-1, 1, (m, 6)) for _ in range(3))
    tau, J = puma.inverse_dynamics(q, qd, qdd), puma.jacobian(q)
    p3 = rng.uniform(-0.3, 0.9, (m, 3))
    fk3, acc = delta.fk(p3), delta.fk_acc(p3, p3, p3)

    def rows(lo):
        ok = True
        for _ in range(3):
            for i in range(lo, m, 4):
                ok &= np.array_equal(puma.inverse_dynamics(q[i], qd[i], qdd[i]), tau[i])
                ok &= np.array_equal(puma.jacobian(q[i]), J[i])
                ok &= np.array_equal(delta.fk(p3[i]), fk3[i])
                got = delta.fk_acc(p3[i], p3[i], p3[i])
                ok &= all(np.array_equal(g, a[i]) for g, a in zip(got, acc))
        return ok

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(rows, range(4)))


@needs_ext
def test_many_calls_leave_no_memory_behind(puma):
    """100 000 calls: accepted ones (a fresh array each), declined ones (NaN: the output
    array made before the kernel ran is released), lists; tracemalloc sees numpy's data and
    every Python object, and the inputs' reference counts do not move."""
    rng = np.random.default_rng(115)
    q, qd, qdd = (rng.uniform(-1, 1, 6) for _ in range(3))
    nan = q.copy()
    nan[0] = np.nan
    as_list = q.tolist()
    puma.inverse_dynamics(q, qd, qdd)  # makes the one-state functions
    call = puma._id_single
    assert _is_ext(call)
    counts = [sys.getrefcount(x) for x in (q, qd, qdd, nan, as_list)]
    for _ in range(1000):  # warm-up: caches settle
        call(q, qd, qdd)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(25_000):
            call(q, qd, qdd)
            assert call(nan, qd, qdd) is None
            call(as_list, qd, qdd)
            call(q, qd)  # a wrong argument count: None
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert after - before < 64 * 1024, after - before  # one leaked array per call: > 10 MB
    assert [sys.getrefcount(x) for x in (q, qd, qdd, nan, as_list)] == counts


def test_without_the_extension_the_python_lean_path_serves(puma, monkeypatch):
    """A failed extension build (no Python.h, no compiler) is silent: single_call returns
    the Python lean function, which gives the batch row."""

    def fail(*args, **kwargs):
        raise BuildError("compiling lean_ext.c failed: Python.h: No such file or directory")

    monkeypatch.setattr(lean, "_EXT", [])
    monkeypatch.setattr(lean, "load_extension", fail)
    assert lean.extension() is None
    f = puma._core.single("fk")
    assert not _is_ext(f)
    q = np.random.default_rng(116).uniform(-1, 1, (3, 6))
    assert np.array_equal(f(q[1]), puma.fk(q)[1])


def test_a_broken_extension_source_raises_a_build_error(tmp_path, monkeypatch):
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / "cache"))
    source = tmp_path / "broken_ext.c"
    source.write_text("#include <Python.h>\nthis is not C;\n")
    with pytest.raises(BuildError, match="broken_ext.c failed"):
        load_extension(source, "broken_ext")
    assert not any(p.suffix == ".so" for p in (tmp_path / "cache").rglob("*"))


@needs_ext
def test_kernel_refuses_forms_it_does_not_serve(puma):
    module = lean.extension()
    ffi, fn = puma._core.c_function("fk")
    address = int(ffi.cast("uintptr_t", fn))
    good = (address, 0, 0, 6, 1, 0, ((4, 4),), 0, None)
    assert callable(module.kernel(*good))
    for bad in (
        (0, *good[1:]),  # no function
        (*good[:3], 65, *good[4:]),  # wider than the stack buffers
        (*good[:4], 5, *good[5:]),  # five rows
        (*good[:6], ((4, 4),) * 4, *good[7:]),  # four outputs
        (*good[:6], ((0,),), *good[7:]),  # an empty output
        (good[0], 1, 0, *good[3:]),  # the delta's form without its geometry
        (good[0], 2, 0, *good[3:]),  # a struct's form without its struct
        (good[0], 3, 1, *good[3:]),  # no such form
    ):
        with pytest.raises(ValueError):
            module.kernel(*bad)


def _struct_robots(lean_ext: bool) -> dict:
    """The families whose kernels take a parameter struct and no axes count (native/core.py:
    the linear delta, the tripod, the five-axis machine), made with the extension on or
    off (DELTAGEN_LEAN_EXT), and one valid input row per one-pose kernel."""
    from deltagen import FiveAxisMachine, LinearDelta, Tripod

    mp = pytest.MonkeyPatch()
    mp.setenv("DELTAGEN_LEAN_EXT", "1" if lean_ext else "0")
    try:
        robots = {
            "linear_delta": LinearDelta.default(threads=1),
            "tripod": Tripod.default(threads=1),
            "five_axis": FiveAxisMachine.load("xyzac_trt", threads=1),
        }
    finally:
        mp.undo()
    return robots


def _method(name: str):
    """call(robot, *args): the public method ``name`` of ``robot``."""
    return lambda robot, *args: getattr(robot, name)(*args)


@needs_ext
@pytest.mark.parametrize("kind", ["linear_delta", "tripod", "five_axis"])
def test_struct_families_take_the_extension_with_the_same_outcomes(kind):
    """The one-pose calls of a family whose kernels take (struct, rows, ...) go through the
    extension (lean_ext.c's third form) and give what the Python lean path gives, bit for
    bit, valid rows and refused ones alike; and a valid row equals the batch row."""
    robot = _struct_robots(True)[kind]
    python = _struct_robots(False)[kind]
    rng = np.random.default_rng(115)
    if kind == "five_axis":
        q = np.clip(rng.uniform(-0.2, 0.2, 5), -1, 1)
        calls = {
            "fk": [(q,), (q.tolist(),), (np.append(q, np.nan)[1:],), (q[:4],)],
        }
        api = {"fk": _method("fk")}
    else:
        # a reachable row: the first of random joint values whose fk is valid
        trial = rng.uniform(0.0, 1.5, (500, 3))
        points = robot.fk(trial, errors="nan")
        points = points[0] if isinstance(points, tuple) else points
        ok = np.isfinite(points).all(axis=1)
        q = trial[np.argmax(ok)]
        assert ok.any()
        p = robot.fk(q)
        qd, qdd = rng.uniform(-0.1, 0.1, 3), rng.uniform(-0.1, 0.1, 3)
        nan = q.copy()
        nan[2] = np.nan
        calls = {
            "fk": [(q,), (q.tolist(),), (nan,), (q[:2],), (np.full(3, 50.0),)],
            "ik": [(p,), (np.full(3, 50.0),)],
            "jacobian": [(q,)],
            "fk_vel": [(q, qd)],
            "fk_acc": [(q, qd, qdd)],
            "ik_vel": [(p, qd)],
            "ik_acc": [(p, qd, qdd)],
        }
        api = {name: _method(name) for name in calls}
    for name in calls:
        assert _is_ext(getattr(robot, f"_{name}_single")), (kind, name)
    for name, cases in calls.items():
        for args in cases:
            a, b = _outcome(api[name], robot, *args), _outcome(api[name], python, *args)
            if a[0] == "ok" and isinstance(a[1], tuple):
                assert b[0] == "ok" and len(a[1]) == len(b[1]), (name, args)
                assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a[1], b[1]))
            else:
                assert _same(a, b), (kind, name, args, a, b)
    batch = api["fk"](robot, np.stack([q, q]))
    one = api["fk"](robot, q)
    for x, y in zip(
        one if isinstance(one, tuple) else (one,), batch if isinstance(batch, tuple) else (batch,)
    ):
        assert np.array_equal(x, y[1])
