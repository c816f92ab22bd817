"""The one-pose C entries of ik: ik_all of one pose with the pose's check in C
(deltagen/native/lean_ext.c ``pose_kernel``; SerialRobot.ik_all calls it first).

Evidence: (1) the C rigidity check agrees with an independent numpy statement of the rule
(|R R^T - I| entrywise and the bottom row, written here with a matrix product, not the
row sums of solve/ik.py) on poses perturbed clearly inside and clearly outside the
tolerances, with check_poses (the batch rule) on poses at the boundary, and refuses NaN and
+-inf in each of the 16 entries; (2) the one-pose answer is bit for bit the batch kernel's
row (a second caller of the same C function), and every valid branch's fk -- the numpy
reference's, not the compiled core's -- reproduces the pose; (3) a non-rigid or non-finite
pose, an overflowing one, and inputs the C path does not take (other dtypes, shapes, lists,
byte order) get exactly the outcome of the general path: the same q/valid (NaN and False)
or the same error, with the extension disabled as the second witness; (4) an unreachable
pose is answered in C with the batch path's flags; (5) many calls leave no memory behind.
The numeric solver of one target (``newton_kernel``): bit for bit the cffi path's answer
(DELTAGEN_LEAN_EXT=0) and the batch row, for any restarts and seed; the API's answers
checked with the numpy reference's fk. Numeric ik of one pose in one call
(``ik_one_kernel``): its answer is that of its three parts called one by one (the rigid
check, the solver, the cheap singularity test), and through SerialRobot.ik the cffi arm's
(q or the same error, the three-call path never taken) for every pose kind; only requests
that ik's checks accepted, in plain str, are noted for it; a pose the one-pose path left
unsolved is not solved again by it.
"""

from __future__ import annotations

import sysconfig
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.errors import UnreachableError
from deltagen.native import lean
from deltagen.reference import serial as reference
from deltagen.solve import ik as solve_ik

HEADERS = (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file()
pytestmark = pytest.mark.skipif(not HEADERS, reason="no Python.h: the extension cannot be built")

TOLS = (solve_ik._RIGID_TOL, solve_ik._BOTTOM_TOL)


@pytest.fixture(scope="module")
def puma():
    arm = SerialRobot.load("puma560", threads=1)
    arm.ik_all(arm.fk(np.zeros(6)))  # the first call makes the one-pose paths
    return arm


@pytest.fixture(scope="module")
def puma_without_ext():
    mp = pytest.MonkeyPatch()
    mp.setenv("DELTAGEN_LEAN_EXT", "0")
    try:
        arm = SerialRobot.load("puma560", threads=1)
        arm.ik_all(arm.fk(np.zeros(6)))
    finally:
        mp.undo()
    return arm


def _rotation(rng):
    """A random rotation from a unit quaternion (Shoemake's method)."""
    u1, u2, u3 = rng.uniform(0.0, 1.0, 3)
    w, x, y, z = (
        np.sqrt(1 - u1) * np.sin(2 * np.pi * u2),
        np.sqrt(1 - u1) * np.cos(2 * np.pi * u2),
        np.sqrt(u1) * np.sin(2 * np.pi * u3),
        np.sqrt(u1) * np.cos(2 * np.pi * u3),
    )
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose(rng):
    T = np.eye(4)
    T[:3, :3] = _rotation(rng)
    T[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    return T


def _independent_rigid(T, tol, bottom):
    """The rule stated with a matrix product (solve/ik.py writes out row sums)."""
    if not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(
        np.max(np.abs(R @ R.T - np.eye(3))) < tol
        and np.max(np.abs(T[3] - [0.0, 0.0, 0.0, 1.0])) < bottom
    )


def test_the_c_check_states_the_rigid_transform_rule():
    ext = lean.extension()
    rng = np.random.default_rng(2101)
    tol, bottom = TOLS
    for _ in range(300):
        T = _pose(rng)
        assert ext.rigid_pose(T, tol, bottom) is True
        # clearly outside: a rotation entry off by 100 tol, or the bottom row by 100 bottom
        for scale, rows in ((100 * tol, slice(0, 3)), (100 * bottom, slice(3, 4))):
            bad = T.copy()
            i = rng.integers(rows.start, rows.stop)
            j = rng.integers(0, 3) if rows.start == 0 else rng.integers(0, 4)
            bad[i, j] += scale * rng.choice([-1.0, 1.0])
            assert _independent_rigid(bad, tol, bottom) is False
            assert ext.rigid_pose(bad, tol, bottom) is False
        # clearly inside: entries off by a hundredth of the tolerance
        near = T.copy()
        near[:3, :3] += rng.uniform(-1e-2 * tol, 1e-2 * tol, (3, 3)) / 3
        near[3, :] += rng.uniform(-1e-2 * bottom, 1e-2 * bottom, 4)
        assert _independent_rigid(near, tol, bottom) is True
        assert ext.rigid_pose(near, tol, bottom) is True
    # at the boundary: the C check and the batch check (check_poses, numpy rows) agree
    # on every pose, whichever side it falls on
    boundary = []
    for _ in range(400):
        T = _pose(rng)
        T[:3, :3] *= 1.0 + rng.uniform(-1.0, 1.0) * tol  # row norms squared ~ 1 +- 2 tol
        T[3, rng.integers(0, 4)] += rng.uniform(-2.0, 2.0) * bottom
        boundary.append(T)
    batch = np.array(boundary)
    _, _, finite, rigid = solve_ik.check_poses(batch)
    assert finite.all() and 0 < rigid.sum() < len(boundary)  # both sides were drawn
    for T, r in zip(boundary, rigid):
        assert ext.rigid_pose(T, tol, bottom) is bool(r)
        assert solve_ik.check_one_pose(T.ravel().tolist())[1] is bool(r)
        assert solve_ik.rigid_one(T) is bool(r) and solve_ik.rigid_one(T.T.T) is bool(r)
    # a NaN or an infinity in any of the 16 entries
    T = _pose(rng)
    for k in range(16):
        for value in (np.nan, np.inf, -np.inf):
            bad = T.copy()
            bad.flat[k] = value
            assert ext.rigid_pose(bad, tol, bottom) is False
    assert ext.rigid_pose(T.tolist(), tol, bottom) is None  # not a (4, 4) float64 array


def test_one_pose_is_the_batch_row_and_every_valid_branch_reaches_it(puma, monkeypatch):
    one = puma.ik_planner.ik_all_checked
    assert one is not None and type(one).__name__ == "builtin_function_or_method"
    rng = np.random.default_rng(2102)
    lim = puma.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (200, 6))
    T = np.ascontiguousarray(puma.fk(q))
    q_batch, valid_batch = puma.ik_all(T)
    k = valid_batch.shape[1]

    def refuse(*args, **kwargs):
        raise AssertionError("the one-pose call went through the general path")

    monkeypatch.setattr(puma.ik_planner, "solve_all", refuse)  # the general path
    for i in range(T.shape[0]):
        result = puma.ik_all(T[i])
        assert result.complete is True
        qi, vi = result
        assert qi.shape == (k, 6) and vi.shape == (k,) and vi.dtype == np.bool_
        assert np.array_equal(qi, q_batch[i], equal_nan=True)
        assert np.array_equal(vi, valid_batch[i])
        assert vi.any()  # fk of an in-limit q: reachable
        Tq, _ = reference.fk(puma.description, np.ascontiguousarray(qi[vi]))
        assert np.max(np.abs(Tq - T[i])) < 1e-9
    # any strides: the same answer as the contiguous pose
    fortran = np.asfortranarray(T[5])
    assert np.array_equal(puma.ik_all(fortran)[0], q_batch[5], equal_nan=True)
    wide = np.zeros((4, 8))
    wide[:, ::2] = T[6]
    assert np.array_equal(puma.ik_all(wide[:, ::2])[0], q_batch[6], equal_nan=True)


def _bad_poses():
    T = np.eye(4)
    T[:3, 3] = [0.4, 0.1, 0.3]
    sheared = T.copy()
    sheared[0, 1] = 1e-3
    bottom = T.copy()
    bottom[3, 0] = 1e-9
    scaled = T.copy()
    scaled[:3, :3] *= 1.01
    nan = T.copy()
    nan[1, 2] = np.nan
    inf = T.copy()
    inf[2, 3] = np.inf
    ninf = T.copy()
    ninf[3, 3] = -np.inf
    huge = T.copy()
    huge[:3, 3] = 1e308  # finite and rigid, far out of reach: UNREACHABLE
    far = T.copy()
    far[:3, 3] = [5.0, 5.0, 5.0]  # out of reach: UNREACHABLE, answered in C
    return [
        ("sheared", sheared, False),
        ("bottom row", bottom, False),
        ("scaled", scaled, False),
        ("NaN", nan, False),
        ("inf", inf, False),
        ("-inf", ninf, False),
        ("overflow", huge, True),
        ("unreachable", far, True),
        ("float32", T.astype(np.float32), False),
        ("big-endian", T.astype(">f8"), False),
        ("list", T.tolist(), False),
        ("(1, 4, 4)", T[None], False),
        ("(4, 4, 1)", T[:, :, None], False),
        ("(3, 4)", T[:3], False),
    ]


def _outcome(f, *args):
    try:
        q, valid = f(*args)
    except Exception as exc:  # noqa: BLE001 - compared by type and message
        return type(exc), str(exc)
    return np.asarray(q), np.asarray(valid)


def _same(a, b):
    if isinstance(a[0], type) or isinstance(b[0], type):
        return a == b
    return np.array_equal(a[0], b[0], equal_nan=True) and np.array_equal(a[1], b[1])


@pytest.mark.parametrize("label, T, answered_in_c", _bad_poses(), ids=lambda x: str(x)[:12])
def test_every_other_pose_has_the_general_paths_outcome(
    puma, puma_without_ext, label, T, answered_in_c
):
    one = puma.ik_planner.ik_all_checked
    assert (one(T) is not None) is answered_in_c
    got = _outcome(puma.ik_all, T)
    assert _same(got, _outcome(puma_without_ext.ik_all, T))  # no C path there
    assert _same(got, _outcome(puma.ik_planner.ik_all, T, "auto"))  # the general path
    if label in ("sheared", "bottom row", "scaled", "NaN", "inf", "-inf", "overflow"):
        q, valid = got  # ik_all's contract: NaN and invalid, no error
        assert np.isnan(q).all() and not valid.any()
    if label == "unreachable":
        assert not got[1].any()
    # ik (one solution) refuses the bad poses as before
    if label in ("sheared", "NaN", "inf"):
        with pytest.raises(Exception) as raised:
            puma.ik(T)
        assert "T" in str(raised.value)


def test_other_methods_keep_their_paths(puma):
    T = puma.fk(np.array([0.1, -0.4, 0.3, 0.2, 0.5, -0.1]))
    assert np.array_equal(
        puma.ik_all(T, method="closed_form")[0], puma.ik_all(T)[0], equal_nan=True
    )
    with pytest.raises(Exception, match="method must be"):
        puma.ik_all(T, method="nope")


def test_many_calls_leave_no_memory_behind(puma):
    T = puma.fk(np.array([0.2, -0.3, 0.1, 0.4, 0.6, -0.2]))
    bad = T.copy()
    bad[0, 0] = np.nan
    for _ in range(200):  # warm-up: numpy's caches
        puma.ik_all(T)
        puma.ik_planner.ik_all_checked(bad)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(20_000):
            puma.ik_all(T)
            puma.ik_planner.ik_all_checked(bad)
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert after - before < 20_000


# ---- the numerical IK of one target through the extension (lean_ext.c newton_kernel) ----


@pytest.fixture(scope="module")
def solvers():
    """The one-target numeric solver of the Puma with the extension, and the same arm's
    with the cffi path (DELTAGEN_LEAN_EXT=0): the behaviour to keep."""
    from deltagen.solve.numeric import single_solver

    arm = SerialRobot.load("puma560", threads=1)
    mp = pytest.MonkeyPatch()
    mp.setenv("DELTAGEN_LEAN_EXT", "0")
    try:
        cffi_solver = single_solver(arm)
    finally:
        mp.undo()
    return arm, single_solver(arm), cffi_solver


def test_numeric_one_target_is_the_cffi_paths_and_the_batchs(solvers):
    from deltagen.solve import numeric as ikn

    arm, solver, cffi_solver = solvers
    rng = np.random.default_rng(2105)
    lim = arm.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (60, 6))
    T = np.ascontiguousarray(arm.fk(q))
    mid = np.ascontiguousarray(lim.mean(axis=1))
    batch = ikn.solve(arm, T, q0=mid)  # the batch path, every attempt in C
    for i in range(T.shape[0]):
        a = solver(T[i], mid)
        assert np.array_equal(a, cffi_solver(T[i], mid))
        if batch.converged[i]:
            assert np.array_equal(a, batch.q[i])
        else:
            assert a is None
        # other restarts / seeds: the same on both paths
        b = solver(T[i], mid, 0, 3)
        c = cffi_solver(T[i], mid, 0, 3)
        assert (b is None and c is None) or np.array_equal(b, c)
    # inputs read from a local copy, or left to the general path
    Tf = np.asfortranarray(T[1])
    assert np.array_equal(solver(Tf, mid), solver(T[1], mid))
    assert np.array_equal(solver(T[1], mid.tolist()), solver(T[1], mid))
    assert solver(T[1].tolist(), mid) is None  # not an ndarray: the general path
    assert solver(T[1], mid[:5]) is None
    assert solver(T[1].astype(np.float32), mid) is None
    # an unreachable target does not converge: None, the general path reports it
    far = T[1].copy()
    far[:3, 3] = [5.0, 5.0, 5.0]
    assert solver(far, mid, 0) is None and cffi_solver(far, mid, 0) is None


def test_numeric_ik_through_the_api_keeps_its_answers(solvers):
    arm = solvers[0]
    rng = np.random.default_rng(2106)
    lim = arm.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (30, 6))
    T = np.ascontiguousarray(arm.fk(q))
    for i in range(T.shape[0]):
        qi = arm.ik(T[i], method="numeric")
        Tq, _ = reference.fk(arm.description, qi[None])
        assert np.max(np.abs(Tq[0] - T[i])) < 1e-9  # the numpy reference's fk
        assert np.all((qi >= lim[:, 0]) & (qi <= lim[:, 1]))
    bad = T[0].copy()
    bad[0, 0] = np.nan
    with pytest.raises(Exception, match="NaN"):
        arm.ik(bad, method="numeric")


def test_numeric_one_target_in_threads_gets_its_own_answer(solvers):
    from concurrent.futures import ThreadPoolExecutor

    arm, solver, _ = solvers
    rng = np.random.default_rng(2107)
    lim = arm.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (40, 6))
    T = np.ascontiguousarray(arm.fk(q))
    mid = np.ascontiguousarray(lim.mean(axis=1))
    alone = [solver(Ti, mid) for Ti in T]
    with ThreadPoolExecutor(4) as pool:  # the solve runs without the GIL
        together = list(pool.map(lambda Ti: solver(Ti, mid), list(T) * 3))
    for i, a in enumerate(together):
        b = alone[i % len(alone)]
        assert (a is None and b is None) or np.array_equal(a, b)


# ---- numeric ik of one pose in one call (lean_ext.c ik_one_kernel; SerialRobot.ik) ----

WRIST_SINGULAR_Q = np.array([0.1, 0.3, -0.4, 0.2, 0.0, 0.5])  # q5 = 0: the Puma's wrist


def _targets(arm, count, seed):
    rng = np.random.default_rng(seed)
    lim = arm.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (count, 6))
    return np.ascontiguousarray(arm.fk(q))


def test_numeric_one_pose_in_one_call_is_the_three_calls(solvers):
    """ik_one_kernel against its parts called one by one: rigid_pose, the solver from the
    start and the cheap singularity test of the solution."""
    arm, solver, _ = solvers
    ext = lean.extension()
    mid = np.ascontiguousarray(arm.qlim.mean(axis=1))
    regular = arm.ik_planner.regular_single
    assert solver.lean is not None and regular is not None
    fused = ext.ik_one_kernel(solver.lean, regular, mid, *TOLS)
    allow = ext.ik_one_kernel(solver.lean, None, mid, *TOLS)  # no test: singular="allow"
    T = _targets(arm, 40, 2108)
    for Ti in T:
        q = solver(Ti, mid)
        assert q is not None and regular(q) is True
        for got in (fused(Ti), allow(Ti), fused(np.asfortranarray(Ti))):
            assert type(got) is np.ndarray and np.array_equal(got, q)
    # solved, not cleared by the cheap test: (q,), the caller's SVD decides
    Ts = np.ascontiguousarray(arm.fk(WRIST_SINGULAR_Q))
    q = solver(Ts, mid)
    assert q is not None and regular(q) is False
    got = fused(Ts)
    assert type(got) is tuple and len(got) == 1 and np.array_equal(got[0], q)
    assert np.array_equal(allow(Ts), q)
    # not a finite rigid pose: None, though the solver alone answers (it reads no bottom row)
    for i, j, value in ((3, 0, 1e-9), (0, 0, 1.0 + 1e-5), (1, 3, np.nan), (2, 2, np.inf)):
        bad = T[0].copy()
        bad[i, j] = value
        assert fused(bad) is None and allow(bad) is None
    off = T[0].copy()
    off[3, 0] = 1e-9
    assert solver(off, mid) is not None
    # no convergence: None
    far = T[0].copy()
    far[:3, 3] = [5.0, 5.0, 5.0]
    assert fused(far) is None
    # not one (4, 4) float64 array in native byte order: False, the other paths take it
    swapped = T[0].astype(T[0].dtype.newbyteorder())
    for other in (T[0].tolist(), T[0].astype(np.float32), T[:1], T[0][:3], swapped, None):
        assert fused(other) is False
    assert fused() is False and fused(T[0], mid) is False


def test_numeric_one_pose_kernel_refuses_what_it_does_not_serve(solvers):
    arm, solver, _ = solvers
    ext = lean.extension()
    mid = np.ascontiguousarray(arm.qlim.mean(axis=1))
    regular = arm.ik_planner.regular_single
    for args in (
        (regular, regular, mid, *TOLS),  # not the solver's callable
        (solver.lean, solver.lean, mid, *TOLS),  # not the test's
        (solver.lean, regular, mid[:5], *TOLS),  # a start of another length
        (solver.lean, regular, mid, 0.0, TOLS[1]),
        (solver.lean, regular, mid, TOLS[0], -1.0),
        (len, None, mid, *TOLS),
    ):
        with pytest.raises(ValueError, match="ik_one_kernel"):
            ext.ik_one_kernel(*args)


@pytest.fixture(scope="module")
def numeric_arms():
    """The Puma with the extension, and with the cffi path (DELTAGEN_LEAN_EXT=0): there ik
    takes the path of three calls (planner.one), the behaviour to keep."""
    mp = pytest.MonkeyPatch()
    mp.setenv("DELTAGEN_LEAN_EXT", "0")
    try:
        plain = SerialRobot.load("puma560", threads=1)
    finally:
        mp.undo()
    return SerialRobot.load("puma560", threads=1), plain


def _ik_outcome(fn, *args, **kwargs):
    """q, or the error's (type, message)."""
    try:
        return fn(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 - compared by type and message
        return type(exc), str(exc)


def _same_ik(a, b):
    if isinstance(a, tuple) or isinstance(b, tuple):
        return a == b
    return np.array_equal(a, b) and a.dtype == b.dtype and a.shape == b.shape


def test_ik_answers_an_accepted_request_in_one_call(numeric_arms, monkeypatch):
    arm, plain = numeric_arms
    planner = arm.ik_planner
    T = _targets(arm, 12, 2109)
    singular = np.ascontiguousarray(arm.fk(WRIST_SINGULAR_Q))
    far = T[0].copy()
    far[:3, 3] = [5.0, 0.0, 0.0]
    off = T[0].copy()
    off[3, 0] = 1e-9
    poses = [*T, singular, far, off, np.asfortranarray(T[1])]
    kinds = ({}, {"singular": "allow"})
    expected = [[_ik_outcome(plain.ik, P, method="numeric", **kw) for P in poses] for kw in kinds]
    assert planner.lean_requests == {}
    for kw, want in zip(kinds, expected, strict=True):
        first = _ik_outcome(arm.ik, T[0], method="numeric", **kw)  # accepted, noted
        assert _same_ik(first, want[0])
        key = ("numeric", "raise", kw.get("singular", "raise"))
        assert planner.lean_requests[key] is planner.lean_numeric(key[2]) is not None
    # from now on one C call answers: the three-call path is not taken for these poses
    one = planner.one
    monkeypatch.setattr(planner, "one", lambda *a: pytest.fail("planner.one was called"))
    for kw, want in zip(kinds, expected, strict=True):
        for P, w in zip(poses, want, strict=True):
            assert _same_ik(_ik_outcome(arm.ik, P, method="numeric", **kw), w)
    # the cases the poses were chosen for, as the three-call path answers them
    assert expected[0][12][0].__name__ == "SingularityError"  # not cleared: the SVD's
    assert type(expected[1][12]) is np.ndarray  # singular="allow"
    assert expected[0][13][0].__name__ == "UnreachableError"
    assert expected[0][14][0].__name__ == "InputError"
    monkeypatch.setattr(planner, "one", one)
    # other poses and arguments: the usual paths, the same answers
    for P in (T[2].tolist(), T[2][None], T[2].astype(np.float32)):
        assert _same_ik(
            _ik_outcome(arm.ik, P, method="numeric"), _ik_outcome(plain.ik, P, method="numeric")
        )


def test_only_plain_accepted_requests_are_noted():
    arm = SerialRobot.load("puma560", threads=1)
    planner = arm.ik_planner
    T = _targets(arm, 1, 2110)[0]
    calls = (
        dict(method="numerik"),  # refused by ik's checks
        dict(method="numeric", errors="x"),
        dict(method="numeric", singular="x"),
        dict(method="numeric", foo=1),
        dict(method="numeric", config="lefty"),
        dict(method=np.str_("numeric")),  # accepted, not a plain str: not noted
        dict(method="numeric", errors=np.str_("raise")),
        dict(method="numeric", q0=np.zeros(6)),  # q0, options: not this request
        dict(method="numeric", restarts=3),
        dict(method="auto"),  # the Puma's closed form
    )
    for kw in calls:
        _ik_outcome(arm.ik, T, **kw)
    assert planner.lean_requests == {}
    arm.ik(T, method="numeric", errors="nan")  # noted, answered by the usual path
    assert planner.lean_requests == {("numeric", "nan", "raise"): None}
    # where the one call does not serve: the numpy engine, a partial default mask (a
    # SCARA), a 7-joint arm's singularity check (no square Jacobian for the C test)
    assert SerialRobot.load("puma560", "reference").ik_planner.lean_numeric("raise") is None
    assert SerialRobot.load("lecture_scara", threads=1).ik_planner.lean_numeric("allow") is None
    panda = SerialRobot.load("panda", threads=1).ik_planner
    assert panda.lean_numeric("raise") is None and panda.lean_numeric("allow") is not None


def test_a_pose_the_one_pose_path_left_is_not_solved_again_by_it(monkeypatch):
    """A pose within reach that no attempt solves (the identity: the Puma's tool point at
    its base): the one-pose path once, then the general path's batch solve."""
    from deltagen.solve import numeric as ikn

    arm = SerialRobot.load("puma560", threads=1)
    planner = arm.ik_planner
    unsolved = np.eye(4)
    counts = {"one": 0, "solve": 0, "lean": 0}
    one, solve = planner.one, ikn.solve

    def counted_one(*args):
        counts["one"] += 1
        return one(*args)

    def counted_solve(*args, **kwargs):
        counts["solve"] += 1
        return solve(*args, **kwargs)

    monkeypatch.setattr(planner, "one", counted_one)
    monkeypatch.setattr(ikn, "solve", counted_solve)
    with pytest.raises(UnreachableError, match="no convergence"):
        arm.ik(unsolved, method="numeric")  # the first call: the three-call path
    assert counts == {"one": 1, "solve": 1, "lean": 0}
    lean = planner.lean_requests[("numeric", "raise", "raise")]

    def counted_lean(T):
        counts["lean"] += 1
        return lean(T)

    planner.lean_requests[("numeric", "raise", "raise")] = counted_lean
    with pytest.raises(UnreachableError, match="no convergence"):
        arm.ik(unsolved, method="numeric")  # the one call
    assert counts == {"one": 1, "solve": 2, "lean": 1}
