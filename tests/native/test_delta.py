"""The compiled C core (generated/delta_kinematics.c via cffi) against independent evidence:
the numpy reference (deltagen.reference.delta) on large random batches, hand-derived
values, symmetry, central finite differences and round trips.

The low-level backends are called directly here (``robot._core.fk(q) -> (p, status)``);
the public API is covered in tests/api/test_delta.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from delta_oracles import (
    DEFAULT,
    GEOMETRIES,
    IRREGULAR,
    KLIPPER,
    centres,
    det_rel,
    elbow_terms,
    geometry,
    max_rel_err,
    random_p,
    random_q,
    rod_condition,
    rod_residual,
    rot_z,
    singular_band_pose,
    stretched_chain_pose,
    symmetric_dz_dq,
    symmetric_fk,
    well_conditioned,
    with_tol,
)
from hypothesis import assume, given, settings
from hypothesis import strategies as hs

from deltagen import DeltaRobot
from deltagen.reference import delta as ref
from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

N_LARGE = 100_000
RTOL = 1e-12

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")


def _core(geom):
    return DeltaRobot.from_geometry(geom, backend="compiled")._core


def _cond_factor(kappa, knee):
    """Tolerance multiplier of an ill-conditioned row: 1 up to condition ``knee``, then
    proportional to the condition number (a backward-stable solve loses ~eps * kappa)."""
    return np.maximum(1.0, kappa / knee)


def _rate_scales(geom, q, qd, qdd, J):
    """Magnitudes pd and pdd are made of (from reference values): |J| |qd| for pd and
    |J| |qdd| + |pdd(qdd = 0)| for pdd, so that cancellations do not shrink the scale."""
    nJ = np.linalg.norm(J, axis=(1, 2))
    _, _, quad, _ = ref.fk_acc(geom, q, qd, np.zeros_like(qdd))
    s_pd = nJ * np.linalg.norm(qd[:, :3], axis=1)
    s_pdd = nJ * np.linalg.norm(qdd[:, :3], axis=1) + np.linalg.norm(quad[:, :3], axis=1)
    return s_pd, s_pdd, nJ


# ------------------------------------------------- compiled vs reference, large batches


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_core_matches_reference_on_reachable_poses(geom, rng):
    """10^5 random poses in the working range: every row OK in both, and p, pd, pdd, J
    equal to 1e-12 (p relative to the robot size, the rates relative to their magnitude)."""
    core = _core(geom)
    q = random_q(rng, N_LARGE)
    qd = rng.normal(scale=2.0, size=q.shape)
    qdd = rng.normal(scale=10.0, size=q.shape)

    p_r, pd_r, pdd_r, s_r = ref.fk_acc(geom, q, qd, qdd)
    J_r, sj_r = ref.jacobian(geom, q)
    assert np.all(s_r == OK) and np.all(sj_r == OK)  # the sample really is reachable
    assert np.all(rod_residual(geom, q, p_r) < 1e-12)  # and the reference closes the chains

    p, s = core.fk(q)
    p_v, pd_v, s_v = core.fk_vel(q, qd)
    p_a, pd_a, pdd_a, s_a = core.fk_acc(q, qd, qdd)
    J, s_j = core.jacobian(q)
    for status in (s, s_v, s_a, s_j):
        assert status.dtype == np.int8
        np.testing.assert_array_equal(status, s_r)

    size = np.full(N_LARGE, geom.size)
    for name, got in (("fk", p), ("fk_vel", p_v), ("fk_acc", p_a)):
        err, row = max_rel_err(got, p_r, size)
        assert err <= RTOL, f"{name}: p differs by {err:.3g} * size at row {row}: q={q[row]}"

    s_pd, s_pdd, nJ = _rate_scales(geom, q, qd, qdd, J_r)
    checks = (
        ("fk_vel pd", pd_v, pd_r, s_pd),
        ("fk_acc pd", pd_a, pd_r, s_pd),
        ("fk_acc pdd", pdd_a, pdd_r, s_pdd),
        ("jacobian", J, J_r, nJ),
    )
    for name, got, want, scale in checks:
        err, row = max_rel_err(got, want, scale)
        assert err <= RTOL, f"{name}: relative error {err:.3g} at row {row}: q={q[row]}"


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_core_matches_reference_over_all_angles(geom, rng):
    """10^5 crank angles anywhere in [-pi, pi]^3 (unreachable, singular, elbow-in poses
    included): identical statuses and NaN patterns; values agree to 1e-12, relaxed in
    proportion to the rod matrix's condition number only near singularities."""
    core = _core(geom)
    q = rng.uniform(-math.pi, math.pi, size=(N_LARGE, 3))
    qd = rng.normal(size=q.shape)
    qdd = rng.normal(size=q.shape)

    p_r, pd_r, pdd_r, s_r = ref.fk_acc(geom, q, qd, qdd)
    J_r, sj_r = ref.jacobian(geom, q)
    p, s = core.fk(q)
    p_a, pd_a, pdd_a, s_a = core.fk_acc(q, qd, qdd)
    p_v, pd_v, s_v = core.fk_vel(q, qd)
    J, s_j = core.jacobian(q)

    assert np.any(s_r == UNREACHABLE), "sample should contain unreachable poses"
    for name, status in (("fk", s), ("fk_vel", s_v), ("fk_acc", s_a), ("jacobian", s_j)):
        mismatch = np.flatnonzero(status != s_r)
        assert mismatch.size == 0, (
            f"{name}: {mismatch.size} statuses differ, e.g. row {mismatch[0]}: "
            f"q={q[mismatch[0]]}, core {status[mismatch[0]]}, reference {s_r[mismatch[0]]}"
        )
    np.testing.assert_array_equal(sj_r, s_r)
    for name, got, want in (
        ("p", p, p_r),
        ("pd", pd_a, pd_r),
        ("pdd", pdd_a, pdd_r),
        ("J", J, J_r),
        ("p (fk_vel)", p_v, p_r),
        ("pd (fk_vel)", pd_v, pd_r),
    ):
        np.testing.assert_array_equal(np.isfinite(got), np.isfinite(want), err_msg=name)

    has_p = np.isfinite(p_r[:, 0])
    kappa = rod_condition(geom, q[has_p], p_r[has_p])
    err = np.linalg.norm(p[has_p] - p_r[has_p], axis=1) / geom.size
    ratio = err / (RTOL * _cond_factor(kappa, 100.0))
    assert ratio.max() <= 1.0, f"p: worst row {np.flatnonzero(has_p)[ratio.argmax()]}"

    ok = s_r == OK
    kappa = rod_condition(geom, q[ok], p_r[ok])
    s_pd, s_pdd, nJ = _rate_scales(geom, q[ok], qd[ok], qdd[ok], J_r[ok])
    for name, got, want, scale in (
        ("pd", pd_a, pd_r, s_pd),
        ("pdd", pdd_a, pdd_r, s_pdd),
        ("J", J, J_r, nJ),
    ):
        e = np.linalg.norm((got[ok] - want[ok]).reshape(ok.sum(), -1), axis=1) / scale
        ratio = e / (RTOL * _cond_factor(kappa, 10.0))
        assert ratio.max() <= 1.0, (
            f"{name}: error {e[ratio.argmax()]:.3g} at condition {kappa[ratio.argmax()]:.3g}"
        )


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_core_ik_matches_reference(geom, rng):
    """10^5 platform positions inside and outside the workspace: identical statuses; on OK
    rows q agrees to 1e-12 rad (relaxed as 1 / j near the elbow singularity), and q closes
    every chain (|p - S_i(q_i)| = l_b)."""
    core = _core(geom)
    p = random_p(rng, geom, N_LARGE)
    q, s = core.ik(p)
    q_r, s_r = ref.ik(geom, p)
    assert np.any(s_r == OK) and np.any(s_r == UNREACHABLE)
    mismatch = np.flatnonzero(s != s_r)
    assert mismatch.size == 0, f"statuses differ, e.g. p={p[mismatch[0]]}"
    np.testing.assert_array_equal(np.isnan(q), np.isnan(q_r))

    ok = s_r == OK
    j = elbow_terms(geom, q_r[ok], p[ok]).min(axis=1)
    assert np.all(j > 0)  # the elbow-out branch
    dq = np.abs(q[ok] - q_r[ok]).max(axis=1)
    ratio = dq / (RTOL * np.maximum(1.0, 0.1 / j))
    assert ratio.max() <= 1.0, f"q differs by {dq[ratio.argmax()]:.3g} rad"
    assert np.all((q[ok] > -math.pi) & (q[ok] <= math.pi))
    assert rod_residual(geom, q[ok], p[ok]).max() < RTOL


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_ik_solves_only_what_fk_returns(geom, rng):
    """Every row ik marks OK is solved: fk(ik(p)) = p, both backends, over a box reaching
    far above the plane of the rods' sphere centres. There every crank still reaches the
    target, but only in the other assembly mode (fk returns the mirror point below the
    plane): such rows are UNREACHABLE with NaN q, not a q for another point."""
    lb = geom.l_b
    p = np.column_stack(
        (
            rng.uniform(-0.6, 0.6, N_LARGE) * lb,
            rng.uniform(-0.6, 0.6, N_LARGE) * lb,
            rng.uniform(-1.3, 1.3, N_LARGE) * lb,
        )
    )
    for backend in ("compiled", "reference"):
        robot = DeltaRobot.from_geometry(geom, backend=backend)
        q, ok = robot.ik(p, errors="nan")
        assert ok.sum() > 1000
        _, status = robot._core.ik(p)
        solved = status == OK
        p_back, status_back = robot._core.fk(q[solved])
        err = np.linalg.norm(p_back - p[solved], axis=1)
        assert err.max() < 1e-9 * lb, (backend, p[solved][err.argmax()])
        assert np.all(status_back == OK), backend
        # a valid SINGULAR row (q given) carries p back where fk has one (not with collinear
        # sphere centres, a parallel singularity where fk is SINGULAR without a position)
        singular = ok & (status == SINGULAR)
        p_back, status_back = robot._core.fk(q[singular])
        assert np.all((status_back == OK) | (status_back == SINGULAR)), backend
        has_p = np.all(np.isfinite(p_back), axis=1)
        err = np.linalg.norm(p_back[has_p] - p[singular][has_p], axis=1)
        assert not has_p.any() or err.max() < 1e-9 * lb, backend
        # and some rows are unreachable only by the assembly mode: every crank reaches them
        c, s = np.cos(geom.theta), np.sin(geom.theta)
        x_i = p[:, :1] * c + p[:, 1:2] * s
        r = geom.r_a - geom.r_b
        E = 2.0 * geom.l_a * (r - x_i)
        F = 2.0 * geom.l_a * p[:, 2:3]
        G = r * r + geom.l_a**2 - 2.0 * r * x_i + (p * p).sum(axis=1)[:, None] - lb * lb
        cranks_reach = np.all(E * E + F * F - G * G > 0.0, axis=1)
        assert np.sum(cranks_reach & ~ok) > 100, backend
    q_c, s_c = _core(geom).ik(p)
    q_r, s_r = ref.ik(geom, p)
    np.testing.assert_array_equal(s_c, s_r)


def test_core_four_axis_batches_match_reference(rng):
    """(N, 4) batches: the first three columns as for (N, 3), column 4 copied."""
    geom = IRREGULAR
    core = _core(geom)
    q = np.column_stack([random_q(rng, 1000), rng.uniform(-10, 10, 1000)])
    qd, qdd = rng.normal(size=(2, 1000, 4))
    p, pd, pdd, s = core.fk_acc(q, qd, qdd)
    p3, pd3, pdd3, s3 = core.fk_acc(q[:, :3].copy(), qd[:, :3].copy(), qdd[:, :3].copy())
    np.testing.assert_array_equal(s, s3)
    np.testing.assert_array_equal(p[:, :3], p3)
    np.testing.assert_array_equal(pd[:, :3], pd3)
    np.testing.assert_array_equal(pdd[:, :3], pdd3)
    np.testing.assert_array_equal(p[:, 3], q[:, 3])
    np.testing.assert_array_equal(pd[:, 3], qd[:, 3])
    np.testing.assert_array_equal(pdd[:, 3], qdd[:, 3])
    back, s_ik = core.ik(p)
    assert np.all(s_ik == OK)
    np.testing.assert_array_equal(back[:, 3], q[:, 3])
    J4, _ = core.jacobian(q)
    J3, _ = core.jacobian(q[:, :3].copy())
    np.testing.assert_array_equal(J4, J3)


# ------------------------------------------------------------------- status handling


def test_core_invalid_rows_in_first_three_columns():
    core = _core(DEFAULT)
    q = np.zeros((6, 3))
    q[1, 0] = np.nan
    q[3, 2] = np.inf
    q[4, 1] = -np.inf
    for fn, args in ((core.fk, (q,)), (core.jacobian, (q,)), (core.ik, (q + [0, 0, -0.7],))):
        out = fn(*args)
        status = out[-1]
        np.testing.assert_array_equal(status, [OK, INVALID, OK, INVALID, INVALID, OK])
        assert np.all(np.isnan(out[0][[1, 3, 4]]))
        assert np.all(np.isfinite(out[0][[0, 2, 5]]))
    qd = np.zeros((6, 3))
    qd[2, 1] = np.nan  # a NaN rate alone invalidates the row, p included
    p, pd, pdd, s = core.fk_acc(np.zeros((6, 3)), qd, np.zeros((6, 3)))
    np.testing.assert_array_equal(s, [OK, OK, INVALID, OK, OK, OK])
    assert np.all(np.isnan(pd[2])) and np.all(np.isnan(pdd[2]))


@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
def test_non_finite_fourth_axis_is_invalid(backend, bad):
    """The header promises INVALID for any non-finite input; column 4 is an input."""
    core = DeltaRobot.default(backend=backend)._core
    q = np.array([[0.0, 0.0, 0.0, 0.5], [0.0, 0.0, 0.0, bad]])
    p, s = core.fk(q)
    np.testing.assert_array_equal(s, [OK, INVALID])
    assert np.all(np.isnan(p[1]))
    pd_in = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, bad]])
    _, pd, s_v = core.fk_vel(np.zeros((2, 4)), pd_in)
    np.testing.assert_array_equal(s_v, [OK, INVALID])
    target = np.array([[0.0, 0.0, -0.7, 0.5], [0.0, 0.0, -0.7, bad]])
    q_back, s_ik = core.ik(target)
    np.testing.assert_array_equal(s_ik, [OK, INVALID])
    assert np.all(np.isnan(q_back[1]))


def test_failed_rows_fourth_column_agrees_with_reference(rng):
    """Failed rows are NaN as a whole, fourth column included, in both backends."""
    geom = DEFAULT
    core = _core(geom)
    q = np.column_stack([rng.uniform(-math.pi, math.pi, (2000, 3)), rng.uniform(-1, 1, 2000)])
    p, s = core.fk(q)
    p_r, s_r = ref.fk(geom, q)
    assert np.any(s_r == UNREACHABLE)
    np.testing.assert_array_equal(s, s_r)
    np.testing.assert_array_equal(np.isnan(p), np.isnan(p_r))
    target = np.array([[0.0, 0.0, -5.0, 0.25]])  # far out of reach
    q_c, s_c = core.ik(target)
    q_ref, s_ref = ref.ik(geom, target)
    assert s_c[0] == s_ref[0] == UNREACHABLE
    np.testing.assert_array_equal(np.isnan(q_c), np.isnan(q_ref))


def test_core_collinear_centres_are_singular_without_position():
    """r + l_a cos q_i = 0 puts all three sphere centres on the base axis: collinear."""
    core = _core(DEFAULT)
    a = math.acos(-DEFAULT.r / DEFAULT.l_a)
    q = np.array([[a, -a, a], [a, a, a]])
    S, _, _ = centres(DEFAULT, q)
    assert np.allclose(S[..., :2], 0.0, atol=1e-15)
    for fn in (core.fk, core.jacobian):
        out, status = fn(q)
        np.testing.assert_array_equal(status, [SINGULAR, SINGULAR])
        assert np.all(np.isnan(out))


def test_core_singular_tolerance_classifies_by_det():
    """Walk from a reachable pose towards an unreachable one: just before the workspace
    boundary (where the platform reaches the plane of the sphere centres) lies a band
    where |det D| / l_b^3 < singular_tol. With singular_tol = 1e-6 a pose in the middle of
    that band is SINGULAR (p given, J NaN) in both backends, as the test-side det confirms;
    with the default tolerance the same pose is OK."""
    geom = with_tol(DEFAULT, 1e-6)
    core = _core(geom)
    q = singular_band_pose(geom)
    p, s = core.fk(q)
    p_r, s_r = ref.fk(geom, q)
    assert s[0] == s_r[0] == SINGULAR
    assert np.all(np.isfinite(p))
    np.testing.assert_allclose(p, p_r, rtol=0, atol=1e-9 * geom.size)
    assert 0.0 < det_rel(geom, q, p_r)[0] < geom.singular_tol
    assert rod_residual(geom, q, p)[0] < 1e-9
    J, sj = core.jacobian(q)
    assert sj[0] == SINGULAR and np.all(np.isnan(J))
    _, pd, s_v = core.fk_vel(q, np.ones((1, 3)))
    assert s_v[0] == SINGULAR and np.all(np.isnan(pd))
    p_default, s_default = _core(DEFAULT).fk(q)
    assert s_default[0] == OK
    np.testing.assert_array_equal(p_default, p)


def test_core_ik_singular_where_crank_and_rod_align():
    """Chain 1 stretched out (crank and rod in line, 1e-10 short of full reach): the
    elbow term j_1 / (l_a l_b) is ~1e-5, so with singular_tol = 1e-3 ik reports SINGULAR
    and still gives q; with the default 1e-9 the same pose is OK."""
    geom = with_tol(DEFAULT, 1e-3)
    target = stretched_chain_pose(geom, 2.0)[None]
    q, s = _core(geom).ik(target)
    q_r, s_r = ref.ik(geom, target)
    assert s[0] == s_r[0] == SINGULAR
    assert np.all(np.isfinite(q))
    np.testing.assert_allclose(q, q_r, rtol=0, atol=1e-6)
    assert abs(q[0, 0] - 2.0) < 1e-4  # chain 1's crank points where the rod points
    assert rod_residual(geom, q, target)[0] < 1e-12
    j = elbow_terms(geom, q, target)[0]
    assert abs(j[0]) < geom.singular_tol and np.all(j[1:] > geom.singular_tol)
    q_default, s_default = _core(DEFAULT).ik(target)
    assert s_default[0] == OK


def test_core_handles_batches_around_the_block_size(rng):
    """The C works in blocks of 64 points: results must not depend on the batch size."""
    core = _core(KLIPPER)
    q = random_q(rng, 300)
    q[[0, 63, 64, 65, 128, 200, 299], 1] = np.nan
    p_all, s_all = core.fk(q)
    # (bitwise equality is not promised: vectorised and scalar cos/sin may differ by an ulp)
    for n in (0, 1, 63, 64, 65, 127, 129, 300):
        p, s = core.fk(q[:n].copy())
        assert p.shape == (n, 3) and s.shape == (n,)
        np.testing.assert_array_equal(s, s_all[:n])
        np.testing.assert_array_equal(np.isnan(p), np.isnan(p_all[:n]))
        np.testing.assert_allclose(p, p_all[:n], rtol=0, atol=1e-14 * KLIPPER.size)
    for start in (1, 63, 64, 100):
        p, s = core.fk(q[start:].copy())
        np.testing.assert_array_equal(s, s_all[start:])
        np.testing.assert_allclose(p, p_all[start:], rtol=0, atol=1e-14 * KLIPPER.size)


# ---------------------------------------------------------------- hand-derived values


@pytest.mark.parametrize("geom", [DEFAULT, KLIPPER], ids=["default", "klipper"])
def test_fk_at_symmetric_poses_by_hand(geom):
    """q = (a, a, a) on 120-deg-spaced drives: x = y = 0, z from the crank/rod triangle;
    at a = 0, z = -sqrt(l_b^2 - (r_a - r_b + l_a)^2)."""
    core = _core(geom)
    z0 = -math.sqrt(geom.l_b**2 - (geom.r_a - geom.r_b + geom.l_a) ** 2)
    p, s = core.fk(np.zeros((1, 3)))
    assert s[0] == OK
    np.testing.assert_allclose(p[0], [0.0, 0.0, z0], rtol=0, atol=1e-15 * geom.size)
    angles = np.linspace(-0.5, 1.2, 18)
    p, s = core.fk(np.repeat(angles[:, None], 3, axis=1))
    expected = np.array([symmetric_fk(geom, a) for a in angles])
    assert np.all(s == OK)
    np.testing.assert_allclose(p, expected, rtol=0, atol=1e-14 * geom.size)
    # all three cranks together move the platform straight down the axis
    J, _ = core.jacobian(np.repeat(angles[:, None], 3, axis=1))
    vertical = J @ np.ones(3)
    expected_v = np.array([[0.0, 0.0, symmetric_dz_dq(geom, a)] for a in angles])
    np.testing.assert_allclose(vertical, expected_v, rtol=0, atol=1e-13 * geom.size)
    q, s_ik = core.ik(expected)
    assert np.all(s_ik == OK)
    np.testing.assert_allclose(q, np.repeat(angles[:, None], 3, axis=1), rtol=0, atol=1e-13)


def test_rotating_the_drives_rotates_the_platform(rng):
    """Turning every theta_i by the same angle turns the whole robot about z."""
    base = geometry(0.2, 0.045, 0.35, 0.8, (10, 100, 250))
    turned = geometry(0.2, 0.045, 0.35, 0.8, (10 + 37, 100 + 37, 250 + 37))
    R = rot_z(math.radians(37))
    q = random_q(rng, 5000)
    qd = rng.normal(size=q.shape)
    p0, pd0, s0 = _core(base).fk_vel(q, qd)
    p1, pd1, s1 = _core(turned).fk_vel(q, qd)
    np.testing.assert_array_equal(s0, s1)
    np.testing.assert_allclose(p1, p0 @ R.T, rtol=0, atol=1e-14 * base.size)
    np.testing.assert_allclose(pd1, pd0 @ R.T, rtol=0, atol=1e-13 * np.abs(pd0).max())
    target = p0 @ R.T
    q1, _ = _core(turned).ik(target)
    np.testing.assert_allclose(q1, q, rtol=0, atol=1e-12)


def test_permuting_the_chains_permutes_the_angles(rng):
    g = IRREGULAR
    perm = [2, 0, 1]
    permuted = geometry(g.r_a, g.r_b, g.l_a, g.l_b, [math.degrees(g.theta[i]) for i in perm])
    q = random_q(rng, 5000)
    p0, _ = _core(g).fk(q)
    p1, _ = _core(permuted).fk(q[:, perm].copy())
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-14 * g.size)
    J0, _ = _core(g).jacobian(q)
    J1, _ = _core(permuted).jacobian(q[:, perm].copy())
    np.testing.assert_allclose(J1, J0[:, :, perm], rtol=0, atol=1e-13 * np.abs(J0).max())


# ------------------------------------------------------------- finite differences


def _trajectory(core, q0, qd, qdd, t):
    p, s = core.fk(q0 + qd * t + 0.5 * qdd * t * t)
    assert np.all(s == OK)
    return p


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_fk_vel_and_fk_acc_match_finite_differences(geom, rng):
    """Along q(t) = q0 + qd t + qdd t^2 / 2, pd = dp/dt and pdd = d^2p/dt^2 at t = 0,
    estimated by Richardson-extrapolated central differences of the compiled fk."""
    core = _core(geom)
    q0 = random_q(rng, 3000)
    qd = rng.normal(scale=2.0, size=q0.shape)
    qdd = rng.normal(scale=5.0, size=q0.shape)
    p, pd, pdd, s = core.fk_acc(q0, qd, qdd)
    assert np.all(s == OK)
    f = {t: _trajectory(core, q0, qd, qdd, t) for t in (-2e-3, -1e-3, 0.0, 1e-3, 2e-3)}
    h = 1e-3
    d1 = lambda k: (f[k * h] - f[-k * h]) / (2 * k * h)  # noqa: E731
    d2 = lambda k: (f[k * h] - 2 * f[0.0] + f[-k * h]) / (k * h) ** 2  # noqa: E731
    pd_fd = (4 * d1(1) - d1(2)) / 3
    pdd_fd = (4 * d2(1) - d2(2)) / 3
    np.testing.assert_array_equal(p, f[0.0])
    s_pd = np.linalg.norm(pd, axis=1) + geom.size * np.linalg.norm(qd, axis=1)
    s_pdd = np.linalg.norm(pdd, axis=1) + geom.size * (
        np.linalg.norm(qdd, axis=1) + np.linalg.norm(qd, axis=1) ** 2
    )
    err, row = max_rel_err(pd, pd_fd, s_pd)
    assert err < 1e-8, f"pd vs finite differences: {err:.3g} at q={q0[row]}"
    err, row = max_rel_err(pdd, pdd_fd, s_pdd)
    assert err < 1e-6, f"pdd vs finite differences: {err:.3g} at q={q0[row]}"


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_jacobian_columns_match_finite_differences(geom, rng):
    core = _core(geom)
    q = random_q(rng, 3000)
    J, s = core.jacobian(q)
    assert np.all(s == OK)
    h = 1e-4
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        plus, _ = core.fk(q + e)
        minus, _ = core.fk(q - e)
        plus2, _ = core.fk(q + 2 * e)
        minus2, _ = core.fk(q - 2 * e)
        column = (8 * (plus - minus) - (plus2 - minus2)) / (12 * h)
        err, row = max_rel_err(J[:, :, k], column, np.full(len(q), geom.size))
        assert err < 1e-9, f"column {k}: {err:.3g} at q={q[row]}"


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_jacobian_times_rates_is_fk_vel(geom, rng):
    core = _core(geom)
    q = random_q(rng, 20_000)
    qd = rng.normal(size=q.shape)
    J, _ = core.jacobian(q)
    _, pd, _ = core.fk_vel(q, qd)
    scale = np.linalg.norm(J, axis=(1, 2)) * np.linalg.norm(qd, axis=1)
    err, row = max_rel_err(np.einsum("nij,nj->ni", J, qd), pd, scale)
    assert err <= RTOL


# ---------------------------------------------------------------------- round trips


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_ik_of_fk_returns_q(geom, rng):
    """10^5 elbow-out, well-conditioned crank angles: ik(fk(q)) == q to 1e-12 rad."""
    core = _core(geom)
    q = rng.uniform(-1.0, 1.6, size=(N_LARGE, 3))
    p, s = core.fk(q)
    keep = (s == OK) & well_conditioned(geom, q, p)
    assert keep.sum() > N_LARGE // 2
    back, s_ik = core.ik(p[keep])
    assert np.all(s_ik == OK)
    err = np.abs(back - q[keep]).max(axis=1)
    assert err.max() <= RTOL, f"worst: q={q[keep][err.argmax()]}, error {err.max():.3g}"


@pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))
def test_fk_of_ik_returns_p(geom, rng):
    """10^5 positions under the base: fk(ik(p)) == p to 1e-12 of the size wherever ik
    succeeds and the pose is well-conditioned."""
    core = _core(geom)
    p = np.column_stack(
        [
            rng.uniform(-0.35, 0.35, N_LARGE),
            rng.uniform(-0.35, 0.35, N_LARGE),
            rng.uniform(-1.2 * geom.l_b, -0.4 * geom.l_b, N_LARGE),
        ]
    )
    q, s = core.ik(p)
    keep = (s == OK) & well_conditioned(geom, q, p)
    assert keep.sum() > N_LARGE // 4
    back, s_fk = core.fk(q[keep])
    assert np.all(s_fk == OK)
    err, row = max_rel_err(back, p[keep], np.full(keep.sum(), geom.size))
    assert err <= RTOL, f"worst p={p[keep][row]}"


# ------------------------------------------------------------- hypothesis properties


_angle = hs.floats(-0.6, 1.3, allow_nan=False)
_rate = hs.floats(-10.0, 10.0, allow_nan=False)
_fourth = hs.floats(allow_nan=False, allow_infinity=False)
_geom_name = hs.sampled_from(list(GEOMETRIES))


@settings(max_examples=150, deadline=None)
@given(_geom_name, hs.tuples(_angle, _angle, _angle))
def test_property_round_trip(name, q):
    geom = GEOMETRIES[name]
    q = np.array([q])
    core = _core(geom)
    p, s = core.fk(q)
    assume(s[0] == OK and well_conditioned(geom, q, p)[0])
    back, s_ik = core.ik(p)
    assert s_ik[0] == OK
    np.testing.assert_allclose(back, q, rtol=0, atol=RTOL)


@settings(max_examples=150, deadline=None)
@given(_geom_name, hs.tuples(_angle, _angle, _angle), hs.tuples(_rate, _rate, _rate))
def test_property_jacobian_times_qd_is_pd(name, q, qd):
    geom = GEOMETRIES[name]
    core = _core(geom)
    q, qd = np.array([q]), np.array([qd])
    J, s = core.jacobian(q)
    _, pd, s_v = core.fk_vel(q, qd)
    assert s[0] == s_v[0] == OK
    scale = np.linalg.norm(J) * np.linalg.norm(qd) + 1e-300
    assert np.linalg.norm(J[0] @ qd[0] - pd[0]) <= RTOL * scale


@settings(max_examples=150, deadline=None)
@given(_geom_name, hs.tuples(_angle, _angle, _angle), _fourth, _fourth, _fourth)
def test_property_fourth_axis_passes_through(name, q, phi, phid, phidd):
    """Report eq. (43): phi = q_4 and its derivatives are copied bit for bit."""
    core = _core(GEOMETRIES[name])
    q4 = np.array([[*q, phi]])
    qd = np.array([[0.1, -0.2, 0.3, phid]])
    qdd = np.array([[0.0, 1.0, -1.0, phidd]])
    p, pd, pdd, s = core.fk_acc(q4, qd, qdd)
    assert s[0] == OK
    assert (p[0, 3], pd[0, 3], pdd[0, 3]) == (phi, phid, phidd)
    back, _ = core.ik(p)
    assert back[0, 3] == phi


def test_ik_at_collinear_centres_is_singular_not_ok():
    """ik's status agrees with fk's at the parallel singularity. With every crank at
    a = acos(-r / l_a) the three sphere centres coincide on the base axis and any point at
    l_b from them is reached: ik finds those q, but fk(q) has no position (collinear
    centres), so ik must not call the row OK (a random draw of
    test_ik_solves_only_what_fk_returns found p = (-0.024, 0.078, 0.482) m marked OK)."""
    a = math.acos(-DEFAULT.r / DEFAULT.l_a)
    S, _, _ = centres(DEFAULT, np.array([[a, a, a]]))
    assert np.allclose(S[0, :, :2], 0.0, atol=1e-15) and np.ptp(S[0, :, 2]) < 1e-15
    tilt = np.linspace(0.02, 0.6, 30)  # directions from the common centre, up and tilted
    u = np.column_stack((np.sin(tilt) * 0.3, np.sin(tilt), np.cos(tilt)))
    u /= np.linalg.norm(u, axis=1)[:, None]
    p = S[0, 0] + DEFAULT.l_b * u
    hit = 0
    for backend in ("compiled", "reference"):
        robot = DeltaRobot.from_geometry(DEFAULT, backend=backend)
        q, status = robot._core.ik(np.ascontiguousarray(p))
        at_a = np.all(np.abs(q - a) < 1e-6, axis=1)
        hit += int(at_a.sum())
        assert np.all(status[at_a] == SINGULAR), (backend, status[at_a])
        _, fk_status = robot._core.fk(np.ascontiguousarray(q[at_a]))
        assert np.all(fk_status == SINGULAR)
    assert hit > 0  # the case was exercised
