"""The UR family's closed form in C (derive/serial/ik_closed_form.py, ``_parallel_triple``;
the bundled UR5's ``deltagen_ur5_ik_all``) against the numpy solver (solve.analytic.
_ParallelTripleSolver, written on the product-of-exponentials model) on 20,000+ poses,
a third of them near a singularity: the wrist (q5 near 0), the elbow (q3 near 0,
stretched) and the shoulder (the shoulder factor of det J, found by root finding on the
compiled Jacobian along q2, each root then confirmed on the reference Jacobian). Evidence
besides the numpy solver: forward kinematics of the
reference backend (DH-free universal coordinates, a product of matrices) for every valid
branch, and the configuration each pose was made from among the valid branches.

Also the joint-limit fit's shortcut (deltagen_limits.h: limits holding the whole circle
return the wrapped angle at once): bit for bit the general path, written here in numpy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import compiled_fit_angle, rtb_dh_rows

from deltagen import SerialRobot
from deltagen.solve.analytic import analytic_solver

OFFSETS = (0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6)


def _wrapped(a):
    return np.abs(np.remainder(a + math.pi, 2 * math.pi) - math.pi)


def _shoulder_singular(compiled, ref, q, rng):
    """Configurations with the shoulder factor of det J at zero: for each q, a root of
    det J along q2 (bisection, batched, on a sign change of a 64-point scan; rows without
    one are left out). The scan and the bisection (145 Jacobians per row) call the compiled
    Jacobian (the reference's numpy product took 15 s of the module's set-up); each root
    is then checked on the reference Jacobian: det J there is as small as the rounding of
    the Jacobian's entries allows, far below its size a step away on the scan."""

    def det(q2, rows, arm=compiled):
        x = rows.copy()
        x[:, 1] = q2
        return np.linalg.det(arm.jacobian(x))

    grid = np.linspace(-math.pi, math.pi, 65)
    d = np.stack([det(np.full(len(q), g), q) for g in grid], axis=1)
    change = np.sign(d[:, :-1]) * np.sign(d[:, 1:]) < 0
    keep = change.any(axis=1)
    q, change = q[keep], change[keep]
    pick = np.array([rng.choice(np.flatnonzero(c)) for c in change])
    lo, hi = grid[pick], grid[pick + 1]
    f_lo = det(lo, q)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        f_mid = det(mid, q)
        same = np.sign(f_mid) == np.sign(f_lo)
        lo, f_lo = np.where(same, mid, lo), np.where(same, f_mid, f_lo)
        hi = np.where(same, hi, mid)
    q = q.copy()
    q[:, 1] = 0.5 * (lo + hi)
    # independent evidence of the roots: the reference Jacobian's det at q2 and a scan
    # step away (|det J| there is of the order of its typical size)
    at_root = np.abs(det(q[:, 1], q, ref))
    step = np.abs(det(q[:, 1] + grid[1] - grid[0], q, ref))
    assert np.all(at_root < 1e-9 * np.median(step)), (at_root.max(), np.median(step))
    return q


def poses(compiled, ref, n_random=16_000, n_each=1500, seed=2026):
    """(q, T, kind): random configurations, then wrist-, elbow- and shoulder-singular ones
    moved by OFFSETS (kind 0 random, 1 wrist, 2 elbow, 3 shoulder)."""
    rng = np.random.default_rng(seed)
    q = [rng.uniform(-math.pi, math.pi, (n_random, 6))]
    kind = [np.zeros(n_random, int)]
    for k, joint in ((1, 4), (2, 2)):
        base = rng.uniform(-math.pi, math.pi, (n_each, 6))
        base[:, joint] = np.asarray(OFFSETS)[rng.integers(len(OFFSETS), size=n_each)]
        q.append(base)
        kind.append(np.full(n_each, k))
    base = _shoulder_singular(compiled, ref, rng.uniform(-math.pi, math.pi, (n_each, 6)), rng)
    base[:, 1] += np.asarray(OFFSETS)[rng.integers(len(OFFSETS), size=len(base))]
    q.append(base)
    kind.append(np.full(len(base), 3))
    q = np.concatenate(q)
    return q, ref.fk(q), np.concatenate(kind)


@pytest.fixture(scope="module")
def ur5_solutions():
    compiled = SerialRobot.load("ur5")
    ref = SerialRobot.load("ur5", backend="reference")
    assert compiled._core.has_ik_all
    q, T, kind = poses(compiled, ref)
    Qc, Vc = compiled.ik_all(T)
    Qn, Vn = analytic_solver(ref.description).solve(T)
    return ref, q, T, kind, Qc, Vc, Qn, Vn


def test_enough_poses_of_every_kind(ur5_solutions):
    _, q, _, kind, *_ = ur5_solutions
    assert len(q) >= 20_000
    assert np.bincount(kind).min() >= 800, np.bincount(kind)


def test_c_branches_equal_the_numpy_solver(ur5_solutions):
    """The same valid flags away from the wrist singularity, and the same joint values on
    branches valid in both: to 1e-12 rad on 99.9% of the random poses, 1e-10 on all (the
    two take q1 and q5 from their cosines in different ways, arccos in numpy, atan2 of
    sqrt(1 - c^2) in C: they part by up to ~1e-10 where that cosine is near +-1). Near the
    singularities the joint values are as ill-conditioned as the pose allows; there the
    forward kinematics (next test) is the check."""
    _, _, _, kind, Qc, Vc, Qn, Vn = ur5_solutions
    away = kind != 1
    assert np.array_equal(Vc[away], Vn[away]), np.argwhere(Vc[away] != Vn[away])[:10]
    assert Vc.sum() > 0.8 * 8 * len(Vc)
    d = _wrapped(Qc - Qn)[Vc & Vn & (kind == 0)[:, None]]
    assert np.quantile(d, 0.999) < 1e-12
    assert d.max() < 1e-10
    # a branch without a real solution is NaN in C, as in numpy
    assert np.isnan(Qc[~Vc & np.isnan(Qn).all(-1)]).all()


def test_every_valid_branch_reproduces_the_pose_and_the_original_is_found(ur5_solutions):
    """Every valid branch meets the pose: to 1e-10 away from the wrist singularity, to the
    solver's check (1e-8) near it, where q5 comes from its cosine (the numpy solver does
    no better there). Before the zero-direction fix of _atan2 branches at the exact
    wrist singularity were valid with q6 off by pi (pose missed by up to 2 m)."""
    ref, q, T, kind, Qc, Vc, Qn, Vn = ur5_solutions
    Tq = ref.fk(np.where(Vc[..., None], Qc, 0.0).reshape(-1, 6)).reshape(*Vc.shape, 4, 4)
    err = np.abs(Tq - T[:, None]).max(axis=(-1, -2))
    assert err[Vc & (kind != 1)[:, None]].max() < 1e-10
    assert err[Vc].max() < 1.01e-8
    assert np.median(err[Vc]) < 1e-14
    # near the wrist singularity both solvers' residuals sit at the check's 1e-8 (q5 from
    # its cosine: an ulp of it is 1.5e-8 rad there), so each misses a few poses the other
    # meets (11 and 6 of 1500 when this was written); C does as well as numpy
    wrist = kind == 1
    assert Vc[wrist].any(-1).mean() >= Vn[wrist].any(-1).mean() - 0.01
    close = np.where(Vc, _wrapped(Qc - q[:, None]).max(-1), np.inf).min(-1)
    assert (close[kind == 0] < 1e-7).all()
    # near the elbow and shoulder singularities the joints are good to ~sqrt(eps)
    assert (close[(kind == 2) | (kind == 3)] < 1e-4).all()


def _fit_general(a, lo, hi, lo_tol, hi_tol):
    """deltagen_fit_angle's general path (deltagen_limits.h), operation for operation in
    numpy (IEEE double, no FMA: the C test build is -std=c99 -O2 without -march)."""
    two_pi = 2 * 3.141592653589793
    inv = (1.0 / 2.0) / 3.141592653589793
    x0 = a - two_pi * np.floor(inv * (a + 3.141592653589793))
    fits = (x0 >= lo_tol) & (x0 <= hi_tol)
    x = x0.copy()
    for shift in (two_pi, -two_pi, 4 * 3.141592653589793, -(4 * 3.141592653589793)):
        y = x0 + shift
        fy = (y >= lo_tol) & (y <= hi_tol) & ~fits
        x = np.where(fy, y, x)
        fits = fits | fy
    return np.where(fits, np.fmin(hi, np.fmax(lo, x)), x)


@pytest.mark.parametrize("limit", [2 * math.pi, 3.2, 10.0, 3.14, 1.0])
def test_fit_shortcut_is_the_general_path_bit_for_bit(tmp_path, limit):
    """The shortcut (lo <= -3.2, hi >= 3.2, |a| <= 2^20) against the general path on
    random angles, the wrap's boundaries (odd multiples of pi and their neighbours),
    +-2^20 and beyond, signed zeros, infinities and NaN; limits that do and do not take it."""

    fit = compiled_fit_angle(tmp_path)
    rng = np.random.default_rng(5)
    odd_pi = np.arange(-41, 42, 2) * math.pi
    edges = np.concatenate([odd_pi, np.nextafter(odd_pi, np.inf), np.nextafter(odd_pi, -np.inf)])
    big = np.array([2.0**20, -(2.0**20), np.nextafter(2.0**20, np.inf), 1e7, -1e17, 1e300])
    a = np.concatenate(
        [
            rng.uniform(-12, 12, 20_000),
            rng.uniform(-(2.0**20), 2.0**20, 2000),
            edges,
            big,
            [0.0, -0.0, np.inf, -np.inf, np.nan],
        ]
    )
    lo, hi = -limit, limit
    lo_tol, hi_tol = lo - 1e-10, hi + 1e-10
    got = fit(a, lo, hi, lo_tol, hi_tol)
    want = _fit_general(a, lo, hi, lo_tol, hi_tol)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    ok = ~np.isnan(want)
    assert np.array_equal(got[ok].view(np.int64), want[ok].view(np.int64))


def _skewed(rows, **change):
    out = [dict(r) for r in rows]
    for key, (joint, value) in change.items():
        out[joint][key] = value
    return out


def _flip_decision(desc):
    from deltagen.derive.serial.ik_closed_form import IKKernelBuilder
    from deltagen.model.structure import detect

    s = detect(desc)
    assert s is not None and s.kind == "parallel_triple_6r"
    b = IKKernelBuilder(s, None)
    K, ax = b.const, s.axes
    w = [K.vec(x) for x in ax.directions]
    B = K(np.cross(ax.directions[4], ax.directions[5]) @ s.u)
    return b.ops.wrist_flip(w[4], w[5], K.vec(s.u), K.vec(s.ref), B)


def _flip_holds_in_numpy(arm):
    """Whether the numpy solver's wrist branches are q5 -> -q5, q6 -> q6 + pi,
    q2 + q3 + q4 -> + pi on random poses (to 1e-9)."""
    q = np.random.default_rng(9).uniform(-3, 3, (300, 6))
    Q, V = analytic_solver(arm.description).solve(arm.fk(q), limits=False)
    gaps = []
    for p in range(0, 8, 2):  # configs: ..._wristp, ..._wristm in pairs
        both = V[:, p] & V[:, p + 1]
        a, b = Q[both, p], Q[both, p + 1]
        gaps += [
            _wrapped(a[:, 4] + b[:, 4]),
            _wrapped(b[:, 5] - a[:, 5] - math.pi),
            _wrapped(b[:, 1:4].sum(-1) - a[:, 1:4].sum(-1) - math.pi),
        ]
    return bool(max(g.max() for g in gaps) < 1e-9)


def test_wrist_flip_shortcut_is_taken_exactly_where_the_numpy_branches_show_it():
    """The SymPy back end's wrist_flip (ik_closed_form._SymPyOps: a symbolic identity on
    the arm's constants) against the numpy solver's own wrist branches: the UR3 / UR5 /
    UR10 have the symmetry and the shortcut; the same arms with a skewed wrist twist or a
    q5 offset have neither."""
    rtb = pytest.importorskip("roboticstoolbox", reason="roboticstoolbox (test extra) is missing")

    for name in ("UR3", "UR5", "UR10"):
        rows = rtb_dh_rows(getattr(rtb.models.DH, name)())
        for variant, expected in (
            (rows, True),
            (_skewed(rows, alpha=(4, 1.2)), False),
            (_skewed(rows, alpha=(3, 1.3)), False),
            (_skewed(rows, offset=(4, 0.4)), False),
        ):
            arm = SerialRobot.from_dh(variant, "standard", name="ur_x", backend="reference")
            assert _flip_decision(arm.description) is expected, (name, variant)
            assert _flip_holds_in_numpy(arm) is expected, (name, variant)
    assert _flip_decision(SerialRobot.load("ur5", backend="reference").description)


@pytest.mark.slow
def test_compiled_kernel_without_the_shortcut_matches_the_numpy_solver():
    """A UR5 with a skewed wrist (alpha5 = 1.2 rad): no wrist-flip shortcut; its C ik_all,
    built here, against the numpy solver."""
    rtb = pytest.importorskip("roboticstoolbox", reason="roboticstoolbox (test extra) is missing")

    rows = _skewed(rtb_dh_rows(rtb.models.DH.UR5()), alpha=(4, 1.2))
    for row in rows:
        row["qlim"] = [-6.2, 6.2]
    arm = SerialRobot.from_dh(rows, "standard", name="ur5_skewed_c")
    assert arm._core.has_ik_all and not _flip_decision(arm.description)
    q = np.random.default_rng(4).uniform(-3, 3, (3000, 6))
    T = arm.fk(q)
    Qc, Vc = arm.ik_all(T)
    Qn, Vn = analytic_solver(arm.description).solve(T)
    assert np.array_equal(Vc, Vn)
    assert (
        _wrapped(Qc - Qn)[Vc].max() < 1e-10
    )  # as for the UR5 (solve/test_analytic_parallel_triple)
    assert (np.where(Vc, _wrapped(Qc - q[:, None]).max(-1), np.inf).min(-1) < 1e-7).all()
