"""The generated ik_vel / ik_acc kernels (delta report eqs. (28)-(39)): against the numpy
reference, against the Jacobian route (qdot = J^-1 pdot, qddot = J^-1 (pddot - Jdot qdot)),
against finite differences of the inverse kinematics along a path, and their status rules
(J_q singular -> SINGULAR with q still given; J_p singular alone is no error)."""

from __future__ import annotations

import numpy as np
import pytest
from delta_oracles import GEOMETRIES, random_q, singular_band_pose, well_conditioned, with_tol

from deltagen import DeltaRobot, SingularityError
from deltagen import status as st
from deltagen.native.delta import CompiledDelta
from deltagen.reference import delta as reference


@pytest.fixture(scope="module", params=sorted(GEOMETRIES))
def geom(request):
    return GEOMETRIES[request.param]


def _poses(geom, n, seed):
    rng = np.random.default_rng(seed)
    q = random_q(rng, n)
    robot = DeltaRobot.from_geometry(geom)
    p, valid = robot.fk(q, errors="nan")
    keep = valid & well_conditioned(geom, q, p)
    pd = rng.normal(scale=0.5, size=p.shape)
    pdd = rng.normal(scale=5.0, size=p.shape)
    return p[keep], pd[keep], pdd[keep]


def test_compiled_kernels_match_the_reference(geom):
    p, pd, pdd = _poses(geom, 5000, 1)
    core = CompiledDelta(geom)
    q_c, qd_c, qdd_c, s_c = core.ik_acc(p, pd, pdd)
    q_r, qd_r, qdd_r, s_r = reference.ik_acc(geom, p, pd, pdd)
    np.testing.assert_array_equal(s_c, s_r)
    assert (s_c == st.OK).all()
    scale = geom.size
    np.testing.assert_allclose(q_c, q_r, rtol=0, atol=1e-12)
    rate = 1.0 + np.abs(qd_r).max(axis=1, keepdims=True)
    np.testing.assert_allclose(qd_c / rate, qd_r / rate, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(qdd_c / rate**2, qdd_r / rate**2, rtol=0, atol=1e-10 * scale)
    q_v, qd_v, s_v = core.ik_vel(p, pd)
    np.testing.assert_array_equal(q_v, q_c)  # same stages, same numbers
    np.testing.assert_array_equal(qd_v, qd_c)
    np.testing.assert_array_equal(s_v, s_c)


def test_kernels_match_the_jacobian_route(geom):
    """The route the Python API took before: J = J_p^-1 J_q from the jacobian kernel,
    qddot = J^-1 (pddot - [pddot of fk_acc at qddot = 0])."""
    p, pd, pdd = _poses(geom, 2000, 2)
    robot = DeltaRobot.from_geometry(geom)
    q, qd, qdd = robot.ik_acc(p, pd, pdd)
    J = robot.jacobian(q)
    qd_j = np.linalg.solve(J, pd[..., None])[..., 0]
    _, _, pdd0 = robot.fk_acc(q, qd_j, np.zeros_like(q))
    qdd_j = np.linalg.solve(J, (pdd - pdd0)[..., None])[..., 0]
    rate = 1.0 + np.abs(qd_j).max(axis=1, keepdims=True)
    np.testing.assert_allclose(qd / rate, qd_j / rate, rtol=0, atol=1e-10)
    np.testing.assert_allclose(qdd / rate**2, qdd_j / rate**2, rtol=0, atol=1e-9)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_rates_are_the_time_derivatives_of_ik_along_a_path(geom, backend):
    """p(t) = p0 + v t + a t^2 / 2: central differences of q(t) = ik(p(t)) give qdot and
    qddot at t = 0."""
    p0, v, a = _poses(geom, 200, 3)
    robot = DeltaRobot.from_geometry(geom, backend=backend)
    h = 1e-4
    q_m, q_0, q_p = (robot.ik(p0 + v * t + a * t * t / 2) for t in (-h, 0.0, h))
    qd_fd = (q_p - q_m) / (2 * h)
    qdd_fd = (q_p - 2 * q_0 + q_m) / h**2
    q, qd, qdd = robot.ik_acc(p0, v, a)
    np.testing.assert_array_equal(q, q_0)
    scale = 1.0 + np.abs(qd_fd).max(axis=1, keepdims=True)
    np.testing.assert_allclose(qd / scale, qd_fd / scale, rtol=0, atol=1e-6)
    np.testing.assert_allclose(qdd / scale**2, qdd_fd / scale**2, rtol=0, atol=1e-4)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_a_j_p_singular_pose_has_inverse_rates(backend):
    """Near |det J_p| = 0 the platform gains a freedom (fk_vel refuses), but
    qdot = J_q^-1 J_p pdot stays defined: ik_vel returns it, equal to the central
    difference of ik."""
    geom = with_tol(GEOMETRIES["default"], 1e-6)
    robot = DeltaRobot.from_geometry(geom, backend=backend)
    q_sing = singular_band_pose(geom)
    p = robot.fk(q_sing)
    with pytest.raises(SingularityError):
        robot.fk_vel(q_sing, np.ones_like(q_sing))
    pd = np.array([[0.1, 0.2, -0.3]])
    q, qd = robot.ik_vel(p, pd)
    np.testing.assert_allclose(robot.fk(q), p, rtol=0, atol=1e-9)  # (ik's own branch)
    h = 1e-7
    qd_fd = (robot.ik(p + h * pd) - robot.ik(p - h * pd)) / (2 * h)
    np.testing.assert_allclose(qd, qd_fd, rtol=1e-5, atol=1e-6)


def test_status_rules_of_the_kernels():
    geom = GEOMETRIES["default"]
    core = CompiledDelta(geom)
    p = np.array(
        [
            [0.0, 0.0, -0.7],  # OK
            [0.0, 0.0, -5.0],  # unreachable
            [np.nan, 0.0, -0.7],  # invalid position
            [0.0, 0.0, -0.7],  # invalid rate (below)
        ]
    )
    pd = np.zeros_like(p)
    pd[3, 1] = np.inf
    for fn, args in ((core.ik_vel, (p, pd)), (core.ik_acc, (p, pd, pd))):
        *outs, status = fn(*args)
        _, *_, ref_status = (reference.ik_vel if len(args) == 2 else reference.ik_acc)(geom, *args)
        np.testing.assert_array_equal(status, [st.OK, st.UNREACHABLE, st.INVALID, st.INVALID])
        np.testing.assert_array_equal(ref_status, status)
        for o in outs:
            assert np.isfinite(o[0]).all() and np.isnan(o[1:]).all()
