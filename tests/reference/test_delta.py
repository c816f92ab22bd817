"""Tests of the independent numpy reference kinematics (deltagen.reference.delta).

Expected values come from the geometry (report eq. (1)), hand derivations or
finite differences, never from what the code prints.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from delta_oracles import DEFAULT, GEOMETRIES, KLIPPER, geometry
from hypothesis import example, given, settings
from hypothesis import strategies as st

from deltagen.reference import delta as ref
from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy must never warn


geometries = pytest.mark.parametrize("geom", list(GEOMETRIES.values()), ids=list(GEOMETRIES))


# ----------------------------------------------------- independent test-side geometry


def centres(geom, q):
    """S_i straight from report eq. (3)-(5), as (N, 3, 3); plus dS/dq."""
    q = np.asarray(q, dtype=float)[:, :3]
    th = np.asarray(geom.theta)
    rho = geom.r + geom.l_a * np.cos(q)
    S = np.empty(q.shape + (3,))
    S[..., 0] = rho * np.cos(th)
    S[..., 1] = rho * np.sin(th)
    S[..., 2] = -geom.l_a * np.sin(q)
    dS = np.empty_like(S)
    dS[..., 0] = -geom.l_a * np.sin(q) * np.cos(th)
    dS[..., 1] = -geom.l_a * np.sin(q) * np.sin(th)
    dS[..., 2] = -geom.l_a * np.cos(q)
    return S, dS


def well_conditioned(geom, q, p, margin=0.05):
    """Rows far from every singularity: |det(p - S_i)| / l_b^3 and each
    |(p - S_i) . dS_i| / (l_a l_b) above ``margin``, with the elbow-out sign (> 0)."""
    S, dS = centres(geom, q)
    D = p[:, None, :3] - S
    finite = np.all(np.isfinite(D), axis=(1, 2))
    det = np.zeros(len(D))
    det[finite] = np.linalg.det(D[finite])
    j = np.where(finite[:, None], np.einsum("nci,nci->nc", D, dS), 0.0)
    return (np.abs(det) / geom.l_b**3 > margin) & np.all(j / (geom.l_a * geom.l_b) > margin, axis=1)


def random_q(rng, n):
    return rng.uniform(-0.6, 1.3, size=(n, 3))


def random_p(rng, geom, n):
    x = rng.uniform(-0.3, 0.3, n)
    y = rng.uniform(-0.3, 0.3, n)
    z = rng.uniform(-1.2 * geom.l_b, -0.5 * geom.l_b, n)
    return np.column_stack([x, y, z])


# ----------------------------------------------------------------- hand-checked values


@pytest.mark.parametrize("geom", [DEFAULT, KLIPPER], ids=["default", "klipper"])
def test_home_pose_by_hand(geom):
    # q = 0: cranks horizontal, all S_i on the circle of radius r + l_a in z = 0, so by
    # symmetry p is on the axis, l_b below that circle: z = -sqrt(l_b^2 - (r + l_a)^2).
    z0 = -math.sqrt(geom.l_b**2 - (geom.r + geom.l_a) ** 2)
    p, status = ref.fk(geom, np.zeros((1, 3)))
    assert status.tolist() == [OK]
    np.testing.assert_allclose(p[0], [0.0, 0.0, z0], atol=1e-14)
    q, status = ref.ik(geom, np.array([[0.0, 0.0, z0]]))
    assert status.tolist() == [OK]
    np.testing.assert_allclose(q[0], [0.0, 0.0, 0.0], atol=1e-12)


def test_default_home_number():
    # r = 0.155, r + l_a = 0.505: z = -sqrt(0.64 - 0.255025) = -sqrt(0.384975)
    p, _ = ref.fk(DEFAULT, np.zeros((1, 3)))
    assert abs(p[0, 2] - (-0.6204635363983930)) < 1e-13


def test_ik_on_axis_matches_scalar_bisection():
    # p = (0, 0, -0.75): every chain sees the same planar problem
    # (r + l_a cos q)^2 + (z + l_a sin q)^2 = l_b^2; solve it by bisection on (0, pi/2).
    g, z = DEFAULT, -0.75

    def f(q):
        return (g.r + g.l_a * math.cos(q)) ** 2 + (z + g.l_a * math.sin(q)) ** 2 - g.l_b**2

    lo, hi = 0.0, math.pi / 2
    assert f(lo) * f(hi) < 0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(lo) * f(mid) <= 0:
            hi = mid
        else:
            lo = mid
    q, status = ref.ik(g, np.array([[0.0, 0.0, z]]))
    assert status.tolist() == [OK]
    np.testing.assert_allclose(q[0], [lo] * 3, atol=1e-12)
    assert 0.3 < lo < 0.4  # elbow-out: crank slightly below horizontal


# ------------------------------------------------------------------------ round trips


@geometries
def test_fk_of_ik_round_trip(geom):
    rng = np.random.default_rng(12)
    p = random_p(rng, geom, 500)
    q, s1 = ref.ik(geom, p)
    p2, s2 = ref.fk(geom, q)
    ok = (s1 == OK) & (s2 == OK)
    ok &= well_conditioned(geom, q, p)
    assert ok.sum() > 300
    np.testing.assert_allclose(p2[ok], p[ok], rtol=0, atol=1e-12 * geom.size)


@geometries
def test_ik_of_fk_round_trip(geom):
    rng = np.random.default_rng(34)
    q = random_q(rng, 500)
    p, s1 = ref.fk(geom, q)
    q2, s2 = ref.ik(geom, p)
    ok = (s1 == OK) & (s2 == OK) & well_conditioned(geom, q, p)
    assert ok.sum() > 300
    np.testing.assert_allclose(q2[ok], q[ok], rtol=0, atol=1e-12 * geom.size)


@geometries
def test_ik_of_fk_round_trip_full_circle(geom):
    # Drive angles anywhere in (-pi, pi]: wherever fk is well conditioned and q is on the
    # elbow-out branch (checked by well_conditioned), ik must return q itself, wrapped
    # into (-pi, pi] (cranks pointing up and inward have q near -pi).
    rng = np.random.default_rng(35)
    q = rng.uniform(-math.pi, math.pi, size=(1500, 3))
    p, s1 = ref.fk(geom, q)
    ok = (s1 == OK) & well_conditioned(geom, q, p)
    assert ok.sum() > 200
    assert (q[ok] < -2.0).sum() > 20
    q2, s2 = ref.ik(geom, p[ok])
    assert np.all(s2 == OK)
    np.testing.assert_allclose(q2, q[ok], rtol=0, atol=1e-12 * geom.size)


@settings(max_examples=150, deadline=None)
@example(geom_name=sorted(GEOMETRIES)[0], q=[3.0, -1.75, -math.pi])
@given(
    geom_name=st.sampled_from(sorted(GEOMETRIES)),
    q=st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3),
)
def test_round_trip_property(geom_name, q):
    geom = GEOMETRIES[geom_name]
    q = np.array([q])
    p, s1 = ref.fk(geom, q)
    assert s1[0] in (OK, SINGULAR, UNREACHABLE)
    if s1[0] != OK or not well_conditioned(geom, q, p, margin=0.02)[0]:
        return
    q2, s2 = ref.ik(geom, p)
    assert s2[0] == OK
    # angles compare modulo 2 pi: q = -pi comes back as +pi (ik returns (-pi, pi])
    wrapped = np.remainder(q2 - q + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(wrapped, 0.0, rtol=0, atol=1e-11 * geom.size)
    assert np.all((q2 > -math.pi) & (q2 <= math.pi))
    p2, s3 = ref.fk(geom, q2)
    assert s3[0] == OK
    np.testing.assert_allclose(p2, p, rtol=0, atol=1e-12 * geom.size)


# --------------------------------------------------------------- position properties


@geometries
def test_fk_satisfies_constraints_and_is_lower_solution(geom):
    rng = np.random.default_rng(56)
    q = random_q(rng, 400)
    p, status = ref.fk(geom, q)
    ok = status == OK
    assert ok.sum() > 300
    S, _ = centres(geom, q[ok])
    dist = np.linalg.norm(p[ok][:, None, :] - S, axis=2)
    np.testing.assert_allclose(dist, geom.l_b, rtol=0, atol=1e-13)
    # the other intersection is the mirror image of p in the plane of the centres
    n = np.cross(S[:, 1] - S[:, 0], S[:, 2] - S[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    mirror = p[ok] - 2.0 * np.einsum("ni,ni->n", p[ok] - S[:, 0], n)[:, None] * n
    assert np.all(p[ok][:, 2] <= mirror[:, 2] + 1e-15)
    np.testing.assert_allclose(np.linalg.norm(mirror[:, None, :] - S, axis=2), geom.l_b, atol=1e-12)


@geometries
def test_ik_satisfies_constraints_and_range(geom):
    rng = np.random.default_rng(78)
    p = random_p(rng, geom, 400)
    q, status = ref.ik(geom, p)
    ok = status == OK
    assert ok.sum() > 300
    assert np.all(q[ok] > -math.pi) and np.all(q[ok] <= math.pi)
    S, dS = centres(geom, q[ok])
    D = p[ok][:, None, :] - S
    np.testing.assert_allclose(np.linalg.norm(D, axis=2), geom.l_b, rtol=0, atol=1e-13)
    # elbow-out branch: (p - S_i) . dS_i/dq_i > 0 (the cranks point outward/down)
    assert np.all(np.einsum("nci,nci->nc", D, dS) > 0)


# --------------------------------------------------------------------- differential


def _fd5(f, h):
    return (f(-2 * h) - 8 * f(-h) + 8 * f(h) - f(2 * h)) / (12 * h)


@geometries
def test_fk_vel_matches_finite_differences(geom):
    rng = np.random.default_rng(90)
    q0 = random_q(rng, 200)
    qd = rng.uniform(-3, 3, size=q0.shape)
    p, pd, status = ref.fk_vel(geom, q0, qd)
    ok = (status == OK) & well_conditioned(geom, q0, p)
    assert ok.sum() > 100
    fd = _fd5(lambda t: ref.fk(geom, q0 + qd * t)[0], 1e-3)
    np.testing.assert_allclose(pd[ok], fd[ok], rtol=0, atol=1e-9 * np.abs(fd[ok]).max())
    np.testing.assert_array_equal(p, ref.fk(geom, q0)[0])
    # velocity constraint (p - S_i) . (pd - dS_i qd_i) = 0
    S, dS = centres(geom, q0[ok])
    rel = pd[ok][:, None, :] - dS * qd[ok][:, :, None]
    res = np.einsum("nci,nci->nc", p[ok][:, None, :] - S, rel)
    assert np.abs(res).max() < 1e-13


@geometries
def test_fk_acc_matches_finite_differences_along_trajectory(geom):
    rng = np.random.default_rng(91)
    q0 = random_q(rng, 200)
    qd = rng.uniform(-3, 3, size=q0.shape)
    qdd = rng.uniform(-20, 20, size=q0.shape)
    p, pd, pdd, status = ref.fk_acc(geom, q0, qd, qdd)
    ok = (status == OK) & well_conditioned(geom, q0, p)
    assert ok.sum() > 100

    def vel_at(t):  # q(t) = q0 + qd t + qdd t^2 / 2, qd(t) = qd + qdd t
        return ref.fk_vel(geom, q0 + qd * t + 0.5 * qdd * t * t, qd + qdd * t)[1]

    fd = _fd5(vel_at, 1e-4)
    np.testing.assert_allclose(pdd[ok], fd[ok], rtol=0, atol=1e-7 * np.abs(fd[ok]).max())
    p_v, pd_v, _ = ref.fk_vel(geom, q0, qd)
    np.testing.assert_array_equal(pd, pd_v)
    np.testing.assert_array_equal(p, p_v)

    def pos_at(t):
        return ref.fk(geom, q0 + qd * t + 0.5 * qdd * t * t)[0]

    # an independent check on the whole trajectory: second difference of position
    h = 1e-3
    fd2 = (-pos_at(2 * h) + 16 * pos_at(h) - 30 * pos_at(0) + 16 * pos_at(-h) - pos_at(-2 * h)) / (
        12 * h * h
    )
    np.testing.assert_allclose(pdd[ok], fd2[ok], rtol=0, atol=1e-5 * np.abs(fd2[ok]).max())


@geometries
def test_jacobian_times_qd_is_pd(geom):
    rng = np.random.default_rng(92)
    q = random_q(rng, 200)
    qd = rng.normal(size=q.shape)
    J, status = ref.jacobian(geom, q)
    assert J.shape == (200, 3, 3)
    _, pd, status_v = ref.fk_vel(geom, q, qd)
    np.testing.assert_array_equal(status, status_v)
    ok = status == OK
    assert ok.sum() > 150
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J[ok], qd[ok]), pd[ok], rtol=0, atol=1e-13)
    # columns are finite differences of fk along each drive axis
    q0 = q[ok]
    for k in range(3):
        step = np.zeros(3)
        step[k] = 1.0
        fd = _fd5(lambda t, step=step: ref.fk(geom, q0 + step * t)[0], 1e-3)
        np.testing.assert_allclose(J[ok][:, :, k], fd, rtol=0, atol=1e-9)


def test_jacobian_at_home_by_hand():
    # q = 0, p = (0, 0, z0): chain i has p - S_i = (-rho c_i, -rho s_i, z0), rho = r + l_a,
    # dS_i/dq_i = (0, 0, -l_a) so J_q,ii = -l_a z0; a pure vertical move of all cranks
    # (qd = (1, 1, 1)) moves p straight down with zd = J_q,ii / z0 = -l_a.
    g = DEFAULT
    J, status = ref.jacobian(g, np.zeros((1, 3)))
    assert status.tolist() == [OK]
    np.testing.assert_allclose(J[0] @ np.ones(3), [0.0, 0.0, -g.l_a], atol=1e-14)


# ------------------------------------------------------------------------ fourth axis


def test_fourth_axis_passes_through():
    rng = np.random.default_rng(5)
    q = np.column_stack([random_q(rng, 20), rng.uniform(-3, 3, 20)])
    qd = rng.normal(size=(20, 4))
    qdd = rng.normal(size=(20, 4))
    p4, s4 = ref.fk(DEFAULT, q)
    p3, s3 = ref.fk(DEFAULT, q[:, :3].copy())
    assert p4.shape == (20, 4) and p4.flags.c_contiguous
    np.testing.assert_array_equal(s4, s3)
    np.testing.assert_array_equal(p4[:, :3], p3)
    np.testing.assert_array_equal(p4[:, 3], q[:, 3])

    p, pd, pdd, s = ref.fk_acc(DEFAULT, q, qd, qdd)
    assert np.all(s == OK)
    np.testing.assert_array_equal(pd[:, 3], qd[:, 3])
    np.testing.assert_array_equal(pdd[:, 3], qdd[:, 3])
    _, pd3, pdd3, _ = ref.fk_acc(DEFAULT, q[:, :3].copy(), qd[:, :3].copy(), qdd[:, :3].copy())
    np.testing.assert_array_equal(pdd[:, :3], pdd3)
    _, pdv, _ = ref.fk_vel(DEFAULT, q, qd)
    np.testing.assert_array_equal(pdv[:, 3], qd[:, 3])

    J4, _ = ref.jacobian(DEFAULT, q)
    J3, _ = ref.jacobian(DEFAULT, q[:, :3].copy())
    assert J4.shape == (20, 3, 3)
    np.testing.assert_array_equal(J4, J3)

    qi, si = ref.ik(DEFAULT, p4)
    assert qi.shape == (20, 4) and np.all(si == OK)
    np.testing.assert_array_equal(qi[:, 3], q[:, 3])
    np.testing.assert_allclose(qi[:, :3], q[:, :3], atol=1e-12)


# -------------------------------------------------------------------------- statuses


def test_unreachable_fk_default_geometry():
    # q = (pi, 0, 0): crank 1 points inward; the three centres lie in z = 0 with a
    # circumradius (computed here independently) larger than l_b, so no point is l_b
    # from all three.
    g = DEFAULT
    q = np.array([[math.pi, 0.0, 0.0], [0.2, 0.3, 0.4]])
    S, _ = centres(g, q[:1])
    a, b, c = (np.linalg.norm(S[0, i] - S[0, j]) for i, j in ((0, 1), (1, 2), (2, 0)))
    area = 0.5 * np.linalg.norm(np.cross(S[0, 1] - S[0, 0], S[0, 2] - S[0, 0]))
    assert a * b * c / (4 * area) > g.l_b
    p, status = ref.fk(g, q)
    assert status.tolist() == [UNREACHABLE, OK]
    assert np.all(np.isnan(p[0])) and np.all(np.isfinite(p[1]))
    _, pd, pdd, status = ref.fk_acc(g, q, np.ones_like(q), np.ones_like(q))
    assert status.tolist() == [UNREACHABLE, OK]
    assert np.all(np.isnan(pd[0])) and np.all(np.isnan(pdd[0]))
    J, status = ref.jacobian(g, q)
    assert status.tolist() == [UNREACHABLE, OK] and np.all(np.isnan(J[0]))


def test_unreachable_fk_short_rods():
    # l_b = 0.4 < r + l_a = 0.505: at q = 0 the centres' circle is wider than a rod.
    g = geometry(0.2, 0.045, 0.35, 0.4, (0, 120, 240))
    p, status = ref.fk(g, np.array([[0.0, 0.0, 0.0], [1.2, 1.2, 1.2]]))
    # q = 1.2: circle radius 0.155 + 0.35 cos 1.2 = 0.282 < 0.4, reachable
    assert status.tolist() == [UNREACHABLE, OK]
    assert np.all(np.isnan(p[0]))
    np.testing.assert_allclose(p[1, :2], 0.0, atol=1e-14)


def test_unreachable_ik():
    g = DEFAULT
    pts = np.array([[0.0, 0.0, -3.0], [2.0, 0.0, -0.7], [0.0, 0.0, -0.75]])
    q, status = ref.ik(g, pts)
    # |p| = 3 > r_a + l_a + l_b and a point 2 m off axis: out of reach of every crank
    assert status.tolist() == [UNREACHABLE, UNREACHABLE, OK]
    assert np.all(np.isnan(q[:2])) and np.all(np.isfinite(q[2]))


def test_invalid_rows_are_isolated():
    g = DEFAULT
    q = np.array([[0.1, 0.2, 0.3], [np.nan, 0.2, 0.3], [0.1, np.inf, 0.3], [0.3, 0.2, 0.1]])
    p, status = ref.fk(g, q)
    assert status.tolist() == [OK, INVALID, INVALID, OK]
    assert np.all(np.isnan(p[1:3]))
    np.testing.assert_array_equal(p[[0, 3]], ref.fk(g, q[[0, 3]])[0])

    qd = np.ones_like(q)
    qd[0, 1] = np.nan  # a bad velocity alone invalidates its row
    qdd = np.ones_like(q)
    qdd[3, 2] = -np.inf
    p, pd, pdd, status = ref.fk_acc(g, q, qd, qdd)
    assert status.tolist() == [INVALID, INVALID, INVALID, INVALID]
    assert np.all(np.isnan(p)) and np.all(np.isnan(pd)) and np.all(np.isnan(pdd))
    p, pd, status = ref.fk_vel(g, q, qd)
    assert status.tolist() == [INVALID, INVALID, INVALID, OK]
    assert np.all(np.isfinite(pd[3]))

    J, status = ref.jacobian(g, q)
    assert status.tolist() == [OK, INVALID, INVALID, OK]
    assert np.all(np.isnan(J[1:3])) and np.all(np.isfinite(J[[0, 3]]))

    pts = np.array([[0.0, 0.0, -0.75, 0.0], [0.0, 0.0, -0.75, np.nan], [0.1, 0.0, -0.7, 1.0]])
    q, status = ref.ik(g, pts)
    assert status.tolist() == [OK, INVALID, OK]
    assert np.all(np.isnan(q[1])) and np.all(np.isfinite(q[[0, 2]]))


def test_det_singular_pose_by_hand():
    # l_b barely longer than r + l_a: at q = 0, p = (0, 0, z0) with small |z0| and
    # D rows (-rho cos th_i, -rho sin th_i, z0), det D = -z0 rho^2 * det[c_i, s_i, 1]
    # = |z0| rho^2 * 3 sqrt(3) / 2 for 0/120/240 deg.
    rho, l_b = 0.505, 0.51
    z0 = -math.sqrt(l_b**2 - rho**2)
    ratio = abs(z0) * rho**2 * 1.5 * math.sqrt(3) / l_b**3
    assert 0.2 < ratio < 0.5
    q = np.zeros((1, 3))
    qd = np.ones((1, 3))
    for tol, expected in ((0.5, SINGULAR), (0.2, OK)):
        g = geometry(0.2, 0.045, 0.35, l_b, (0, 120, 240), singular_tol=tol)
        p, status = ref.fk(g, q)
        assert status.tolist() == [expected]
        np.testing.assert_allclose(p[0], [0, 0, z0], atol=1e-14)  # p is always returned
        p, pd, pdd, status = ref.fk_acc(g, q, qd, qd)
        assert status.tolist() == [expected]
        assert np.all(np.isfinite(p))
        assert np.all(np.isnan(pd)) == (expected == SINGULAR)
        assert np.all(np.isnan(pdd)) == (expected == SINGULAR)
        J, status = ref.jacobian(g, q)
        assert status.tolist() == [expected]
        assert np.all(np.isnan(J)) == (expected == SINGULAR)


def test_ik_singular_folded_chain():
    # Chain 1 (theta = 0) folded: rod lying back along its crank u (unit crank direction),
    # p = S_1 - (l_b + eps) u, so |p - A_1| = l_b - l_a + eps (A_1 shifted by r_b).
    # Law of cosines: 2 (l_b - l_a) eps ~ l_a l_b beta^2 for the angle beta between rod
    # and crank, and |J_q,11| / (l_a l_b) = sin(beta) ~ sqrt(2 (l_b - l_a) eps / (l_a l_b)).
    g = DEFAULT
    q1, eps = -1.3, 1e-8
    u = np.array([math.cos(q1), 0.0, -math.sin(q1)])
    S1 = np.array([g.r + g.l_a * math.cos(q1), 0.0, -g.l_a * math.sin(q1)])
    beta = math.sqrt(2 * (g.l_b - g.l_a) * eps / (g.l_a * g.l_b))
    assert 1e-5 < beta < 1e-3
    p = (S1 - (g.l_b + eps) * u)[None, :]
    for tol, expected in ((1e-3, SINGULAR), (1e-5, OK), (g.singular_tol, OK)):
        gt = geometry(0.2, 0.045, 0.35, 0.8, (0, 120, 240), singular_tol=tol)
        q, status = ref.ik(gt, p)
        assert status.tolist() == [expected]
        assert np.all(np.isfinite(q))  # q is returned either way
        assert abs(q[0, 0] - q1) < 1e-3
    # folded a little further, |p - A_1| < l_b - l_a: chain 1 cannot reach
    q, status = ref.ik(g, (S1 - (g.l_b - eps) * u)[None, :])
    assert status.tolist() == [UNREACHABLE]
    assert np.all(np.isnan(q))


def test_collinear_centres_are_singular():
    # r_a = r_b and q_i = pi/2: every crank points straight down, all three centres
    # coincide at (0, 0, -l_a) (collinear in the degenerate sense)
    g = geometry(0.1, 0.1, 0.3, 0.6, (0, 120, 240))
    q = np.array([[math.pi / 2] * 3, [0.5, 0.5, 0.5]])
    p, status = ref.fk(g, q)
    assert status.tolist() == [SINGULAR, OK]
    assert np.all(np.isnan(p[0])) and np.all(np.isfinite(p[1]))
    J, status = ref.jacobian(g, q)
    assert status.tolist() == [SINGULAR, OK]


def test_empty_batch_and_output_types():
    for cols in (3, 4):
        z = np.zeros((0, cols))
        p, s = ref.fk(DEFAULT, z)
        assert p.shape == (0, cols) and s.shape == (0,) and s.dtype == np.int8
        p, pd, s = ref.fk_vel(DEFAULT, z, z)
        assert pd.shape == (0, cols)
        p, pd, pdd, s = ref.fk_acc(DEFAULT, z, z, z)
        assert pdd.shape == (0, cols)
        J, s = ref.jacobian(DEFAULT, z)
        assert J.shape == (0, 3, 3)
        q, s = ref.ik(DEFAULT, z)
        assert q.shape == (0, cols) and s.dtype == np.int8
    q, s = ref.ik(DEFAULT, np.array([[0.0, 0.0, -0.75]]))
    assert q.dtype == np.float64 and q.flags.c_contiguous and s.dtype == np.int8


def test_inputs_not_modified():
    q = np.array([[np.nan, 0.0, 0.0], [0.1, 0.2, 0.3]])
    q_copy = q.copy()
    ref.fk_acc(DEFAULT, q, q, q)
    ref.ik(DEFAULT, q)
    np.testing.assert_array_equal(q, q_copy)
