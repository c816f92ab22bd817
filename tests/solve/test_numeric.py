"""Numerical inverse kinematics of serial arms (deltagen.solve.numeric).

Evidence is independent of the solver: every solution is checked with the pure-numpy
reference kinematics (deltagen.reference.serial, which shares nothing with the generated C
the solver iterates on), pose errors are recomputed here with their own formulas (rotation
angle from the Frobenius distance of the rotation matrices), the Jacobian sources are
compared with each other and with the reference, and single steps are compared with
np.linalg.solve / np.linalg.pinv applied to the reference Jacobian.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from helpers import random_q, reference_fk, rotation_angle

from deltagen.api.serial import SerialRobot, bundled_robots
from deltagen.inputs import InputError
from deltagen.reference import serial as reference
from deltagen.solve import numeric as ikn

SIX_AXIS = ("puma560", "manutec_r15", "motoman_up6")
TOL = 1e-10


@pytest.fixture(scope="module")
def arms(serial_arms):
    return serial_arms


# ------------------------------------------------------------------ independent helpers


def _perturbed(arm, q, rng, sigma=0.1):
    lo, hi = arm.qlim.T
    return np.clip(q + rng.normal(0.0, sigma, q.shape), lo, hi)


def _check_solution(arm, res, T, tol=TOL):
    """Converged rows: within limits, and the reference fk reproduces T to tol."""
    c = res.converged
    assert arm.within_limits(res.q[c]).all()
    Tq = reference_fk(arm, res.q[c])
    dp = np.linalg.norm(Tq[:, :3, 3] - T[c][:, :3, 3], axis=1)
    dr = rotation_angle(Tq[:, :3, :3], T[c][:, :3, :3])
    # the solver's tol plus a few ulps of the two fk implementations
    assert dp.max(initial=0) <= tol + 1e-13, dp.max()
    assert dr.max(initial=0) <= tol + 1e-13, dr.max()
    assert np.all(res.position_error[c] <= tol) and np.all(res.rotation_error[c] <= tol)


def _rodrigues(axis, theta):
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    K = np.zeros(axis.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -axis[..., 2], axis[..., 1]
    K[..., 1, 0], K[..., 1, 2] = axis[..., 2], -axis[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -axis[..., 1], axis[..., 0]
    th = np.asarray(theta)[..., None, None]
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def _small_rotvec(R):
    """Rotation vector of rotations below ~90 deg: vee(R - R^T)/2 rescaled by theta/sin."""
    v = 0.5 * np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    th = np.arcsin(np.clip(s, 0, 1))
    return v * np.where(s > 0, th / np.where(s > 0, s, 1), 1.0)


# ------------------------------------------------------------------------- orientation


def test_rotation_vector_inverts_rodrigues(rng):
    N = 4000
    axis = rng.normal(size=(N, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    theta = np.concatenate(
        [
            rng.uniform(0, np.pi, N - 400),
            10.0 ** rng.uniform(-14, -2, 100),  # tiny
            np.pi / 2 + rng.uniform(-1e-6, 1e-6, 100),  # branch switch
            np.pi - 10.0 ** rng.uniform(-12, -3, 100),  # near pi
            np.full(100, np.pi),
        ]
    )
    R = _rodrigues(axis, theta)
    w = ikn.rotation_vector(R)
    # theta <= pi: the vector is theta * axis; at exactly pi the sign is free
    ang = np.linalg.norm(w, axis=1)
    assert np.allclose(ang, theta, rtol=1e-12, atol=1e-7)
    not_pi = theta < np.pi - 1e-6
    assert np.allclose(w[not_pi], (axis * theta[:, None])[not_pi], rtol=1e-9, atol=1e-12)
    # and exp(w) reproduces R everywhere (both signs at pi are right)
    back = _rodrigues(np.where(ang[:, None] > 0, w, [[1.0, 0, 0]]), ang)
    assert np.abs(back - R).max() < 1e-7
    tiny = theta < 1e-6
    assert np.allclose(w[tiny], (axis * theta[:, None])[tiny], rtol=1e-9, atol=1e-20)


# ---------------------------------------------------------------------------- Jacobians


@pytest.mark.parametrize("name", bundled_robots())
def test_jacobian_sources_agree(arms, name, rng):
    arm = arms(name)
    q = random_q(arm, rng, 300)
    Js = ikn.jacobian(arm, q, "symbolic")
    Jg = ikn.jacobian(arm, q, "geometric")
    Jf = ikn.jacobian(arm, q, "fd")
    Jr, _ = reference.jacobian(arm.description, q)  # numpy reference, independent of C
    scale = np.abs(Jr).max(axis=(1, 2), keepdims=True)
    assert np.abs(Js - Jg).max() <= 1e-12 * scale.max()
    assert np.all(np.abs(Jg - Jr) <= 1e-12 * scale)
    assert np.all(np.abs(Js - Jr) <= 1e-12 * scale)
    assert np.all(np.abs(Jf - Jr) <= 1e-6 * scale)


def test_fd_jacobian_is_a_derivative_of_fk(arms, rng):
    """The fd source against an own one-sided difference of the reference fk."""
    arm = arms("motoman_up6")
    q = random_q(arm, rng, 20)
    Jf = ikn.jacobian(arm, q, "fd")
    h = 1e-7
    T0 = reference_fk(arm, q)
    for i in range(arm.n):
        dq = np.zeros(arm.n)
        dq[i] = h
        T1 = reference_fk(arm, q + dq)
        v = (T1[:, :3, 3] - T0[:, :3, 3]) / h
        w = _small_rotvec(T1[:, :3, :3] @ np.swapaxes(T0[:, :3, :3], 1, 2)) / h
        assert np.allclose(Jf[:, :3, i], v, atol=1e-5)
        assert np.allclose(Jf[:, 3:, i], w, atol=1e-5)


def test_modified_dh_on_the_reference_backend(rng):
    """Modified (Craig) DH, incl. a prismatic joint, on the numpy reference backend (no C):
    the cross-product Jacobian built here from the frames equals the reference's own
    Jacobian, fd agrees, and the solver converges. Craig's Puma 560 table (a_{i-1},
    alpha_{i-1}, d_i) plus a 5 cm tool."""
    craig = [
        dict(a=0.0, alpha=0.0, d=0.0, qlim_deg=[-160, 160]),
        dict(a=0.0, alpha_deg=-90, d=0.0, qlim_deg=[-225, 45]),
        dict(a=0.4318, alpha=0.0, d=0.15005, qlim_deg=[-45, 225]),
        dict(a=0.0203, alpha_deg=-90, d=0.4318, qlim_deg=[-110, 170]),
        dict(a=0.0, alpha_deg=90, d=0.0, qlim_deg=[-100, 100]),
        dict(a=0.0, alpha_deg=-90, d=0.0, qlim_deg=[-266, 266]),
    ]
    tool = np.eye(4)
    tool[2, 3] = 0.05
    arm = SerialRobot.from_dh(craig, "modified", name="craig_puma", tool=tool, backend="reference")
    rpr = [
        dict(type="revolute", a=0.0, alpha=0.0, d=0.3),
        dict(type="prismatic", a=0.2, alpha_deg=90, theta=0.3, qlim=[0.0, 0.5]),
        dict(type="revolute", a=0.1, alpha_deg=-90, d=0.05),
    ]
    arm2 = SerialRobot.from_dh(rpr, "modified", name="rpr_modified", backend="reference")
    for a in (arm, arm2):
        q = random_q(a, rng, 100)
        Jr, _ = reference.jacobian(a.description, q)
        assert np.abs(ikn.jacobian(a, q, "geometric") - Jr).max() <= 1e-12
        assert np.abs(ikn.jacobian(a, q, "fd") - Jr).max() <= 1e-6
    q_true = random_q(arm, rng, 100)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), jacobian="geometric", restarts=10)
    assert res.converged.all()
    _check_solution(arm, res, T)
    q_true = random_q(arm2, rng, 100)
    T = reference_fk(arm2, q_true)
    res = ikn.solve(
        arm2, T, _perturbed(arm2, q_true, rng, 0.05), mask=[1, 1, 1, 0, 0, 0], restarts=10
    )
    assert res.converged.all() and arm2.within_limits(res.q).all()
    assert np.abs(reference_fk(arm2, res.q)[:, :3, 3] - T[:, :3, 3]).max() <= 1e-10


# ------------------------------------------------------------------ six-axis arms


@pytest.mark.parametrize("name", SIX_AXIS)
def test_six_axis_random_targets(arms, name, rng):
    arm = arms(name)
    q_true = random_q(arm, rng, 1000)
    T = reference_fk(arm, q_true)
    q0 = _perturbed(arm, q_true, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, q0, tol=TOL, restarts=30, seed=1)
    assert res.converged.all(), np.flatnonzero(~res.converged)
    assert res.q.shape == (1000, 6) and res.iterations.shape == (1000,)
    _check_solution(arm, res, T)
    # from a near start Newton's basin is the start's: most rows return q_true itself
    assert np.median(res.iterations) <= 6
    assert np.mean(np.abs(res.q - q_true).max(axis=1) < 1e-6) > 0.95


@pytest.mark.parametrize("name", SIX_AXIS)
def test_six_axis_from_named_configuration(arms, name, rng):
    """Cold start from "qz" (the Puma's is wrist-singular): restarts bring it to 100 %."""
    arm = arms(name)
    q_true = random_q(arm, rng, 200)
    T = reference_fk(arm, q_true)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, arm.configuration("qz"), restarts=100, seed=2)
    assert res.converged.all(), np.flatnonzero(~res.converged)
    _check_solution(arm, res, T)


@pytest.mark.parametrize("source", ikn.JACOBIANS)
@pytest.mark.parametrize("name", SIX_AXIS)
def test_every_jacobian_source_converges(arms, name, source, rng):
    arm = arms(name)
    q_true = random_q(arm, rng, 200)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), jacobian=source, restarts=30)
    assert res.converged.all()
    _check_solution(arm, res, T)


def test_single_step_is_gauss_elimination(arms, rng):
    """damping=None, one step, no step limit: dq = J^-1 dx with J and dx computed here."""
    arm = arms("puma560")
    q_true = random_q(arm, rng, 50, margin=0.6)
    q0 = q_true + rng.uniform(-0.05, 0.05, q_true.shape)
    T = reference_fk(arm, q_true)
    J, _ = reference.jacobian(arm.description, q0)
    well = np.linalg.cond(J) < 100  # the step stays small: no limit or 2 pi shift involved
    q0, T, J = q0[well], T[well], J[well]
    assert len(q0) > 10
    res = ikn.solve(arm, T, q0, max_iter=1, restarts=0, damping=None, step_limit=None)
    T0 = reference_fk(arm, q0)
    dx = np.concatenate(
        [
            T[:, :3, 3] - T0[:, :3, 3],
            _small_rotvec(T[:, :3, :3] @ np.swapaxes(T0[:, :3, :3], 1, 2)),
        ],
        axis=1,
    )
    assert np.allclose(res.q - q0, np.linalg.solve(J, dx[:, :, None])[:, :, 0], atol=1e-12)
    assert np.all(res.iterations == 1)


def test_solve_is_reproducible(arms, rng):
    arm = arms("manutec_r15")
    T = reference_fk(arm, random_q(arm, rng, 100))
    a = ikn.solve(arm, T, arm.configuration("qz"), restarts=5, seed=3)
    b = ikn.solve(arm, T, arm.configuration("qz"), restarts=5, seed=3)
    assert np.array_equal(a.q, b.q, equal_nan=True) and np.array_equal(a.iterations, b.iterations)


# ------------------------------------------------------------------- redundant arm


def test_redundant_arm_svd_pseudo_inverse(puma7, rng):
    arm = puma7
    q_true = random_q(arm, rng, 500)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), restarts=30)
    assert res.converged.all()
    _check_solution(arm, res, T)
    # with the null-space pull towards mid-range as well
    res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), restarts=30, null_space=0.5)
    assert res.converged.all()
    _check_solution(arm, res, T)
    # and from a cold start
    res = ikn.solve(arm, T[:100], np.zeros(7), restarts=100)
    assert res.converged.all()
    _check_solution(arm, res, T[:100])


def test_redundant_step_is_minimum_norm(puma7, rng):
    """One undamped step of the 7-axis arm is the Moore-Penrose step pinv(J) dx."""
    arm = puma7
    q_true = random_q(arm, rng, 50, margin=0.6)
    q0 = q_true + rng.uniform(-0.05, 0.05, q_true.shape)
    T = reference_fk(arm, q_true)
    J, _ = reference.jacobian(arm.description, q0)
    well = np.linalg.cond(J) < 100
    q0, T, J = q0[well], T[well], J[well]
    assert len(q0) > 10
    res = ikn.solve(arm, T, q0, max_iter=1, restarts=0, damping=None, step_limit=None)
    T0 = reference_fk(arm, q0)
    dx = np.concatenate(
        [
            T[:, :3, 3] - T0[:, :3, 3],
            _small_rotvec(T[:, :3, :3] @ np.swapaxes(T0[:, :3, :3], 1, 2)),
        ],
        axis=1,
    )
    expected = np.einsum("nij,nj->ni", np.linalg.pinv(J), dx)
    assert np.allclose(res.q - q0, expected, atol=1e-12)


# ------------------------------------------------------ fewer than six axes: tool fitting


def test_default_masks():
    get = SerialRobot.load
    assert ikn.default_mask(get("manutec_h5")).tolist() == [1, 1, 1, 0, 0, 1]
    assert ikn.default_mask(get("bosch_sr800")).tolist() == [1, 1, 1, 0, 0, 1]
    assert ikn.default_mask(get("lecture_scara")).tolist() == [1, 1, 0, 0, 0, 1]
    assert ikn.default_mask(get("puma560")).all()


@pytest.mark.parametrize("name", ["manutec_h5", "bosch_sr800"])
def test_scara_tool_fitting(arms, name, rng):
    """ "Tool fitting": a SCARA matches the position and the rotation about the vertical.
    The target's tool axis is tilted about a random horizontal axis (unreachable for a
    SCARA); the fit must ignore the tilt and return exactly the untilted pose: R* = R_t Q
    with Q a rotation about a horizontal axis u gives R* R_t^T = Rot(R_t u), whose rotation
    vector is horizontal, i.e. the matched wz component vanishes at R = R_t."""
    arm = arms(name)
    N = 300
    q_true = random_q(arm, rng, N, margin=0.05)
    T_true = reference_fk(arm, q_true)
    assert np.allclose(np.abs(T_true[:, 2, 2]), 1.0)  # the tool z axis is vertical
    u = np.concatenate([rng.normal(size=(N, 2)), np.zeros((N, 1))], axis=1)
    T = T_true.copy()
    T[:, :3, :3] = T_true[:, :3, :3] @ _rodrigues(u, rng.uniform(0.05, 0.5, N))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), restarts=10)
    assert res.mask.tolist() == [1, 1, 1, 0, 0, 1]
    assert res.converged.all()
    assert arm.within_limits(res.q).all()
    Tq = reference_fk(arm, res.q)
    assert np.abs(Tq[:, :3, 3] - T_true[:, :3, 3]).max() <= 1e-10
    assert rotation_angle(Tq[:, :3, :3], T_true[:, :3, :3]).max() <= 1e-9
    # untilted targets: the exact pose
    res2 = ikn.solve(arm, T_true, _perturbed(arm, q_true, rng), restarts=10)
    assert res2.converged.all()
    _check_solution(arm, res2, T_true)


def test_planar_scara_position_only(arms, rng):
    """lecture_scara (2R, L1 = 4, L2 = 3): position-only fitting inside the annulus
    1 < r < 7, checked against the law of cosines; the default 3-component mask on fk
    targets is a consistent least-squares problem and converges too."""
    arm = arms("lecture_scara")
    N = 300
    r = rng.uniform(1.2, 6.8, N)
    phi = rng.uniform(-np.pi, np.pi, N)
    T = np.tile(np.eye(4), (N, 1, 1))
    T[:, 0, 3], T[:, 1, 3] = r * np.cos(phi), r * np.sin(phi)
    T[:, 2, 3] = 0.5  # out of the arm's plane: ignored by the mask
    res = ikn.solve(arm, T, [0.3, 0.3], mask=[True, True, False, False, False, False], restarts=5)
    assert res.converged.all()
    Tq = reference_fk(arm, res.q)
    assert np.abs(Tq[:, :2, 3] - T[:, :2, 3]).max() <= 1e-10
    cos_q2 = (r**2 - 16 - 9) / (2 * 4 * 3)  # law of cosines, L1 = 4, L2 = 3
    assert np.allclose(np.cos(res.q[:, 1]), cos_q2, atol=1e-9)
    q_true = random_q(arm, rng, N)
    T2 = reference_fk(arm, q_true)
    res2 = ikn.solve(arm, T2, _perturbed(arm, q_true, rng), restarts=5)
    assert res2.mask.tolist() == [1, 1, 0, 0, 0, 1]
    assert res2.converged.all()
    _check_solution(arm, res2, T2)


# --------------------------------------------------------------------- singularities


@pytest.mark.parametrize("q5", [0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2])
def test_puma_wrist_singularity(arms, q5, rng):
    """Targets at and near the wrist singularity q5 = 0, starts perturbed by 0.1 rad (so
    q5 often starts on the other side). Restarts are allowed: near q5 = 0 the two wrist
    branches (q4, q5, q6) and (q4 -+ pi, -q5, q6 +- pi) are close in the pose, and when
    the one reached first is out of the q4 range the limited phase can stall."""
    arm = arms("puma560")
    N = 200
    q_true = random_q(arm, rng, N)
    q_true[:, 4] = q5 * rng.choice([-1.0, 1.0], N)
    T = reference_fk(arm, q_true)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, _perturbed(arm, q_true, rng), damping="auto", restarts=30)
    assert res.converged.all()
    _check_solution(arm, res, T)


def test_damped_start_at_singularity(arms, rng):
    """From qz (q5 = 0: J singular) towards targets around it. The damped iteration leaves
    the singular start; which wrist branch (q4, q5, q6) or (q4 - pi, -q5, q6 + pi) it
    takes from there is arbitrary, and when the first one is out of range the limited
    phase can get stuck at the q4 limit (rare), so restarts make it 100 %."""
    arm = arms("puma560")
    lo, hi = arm.qlim.T
    q_true = np.clip(rng.normal(0.0, 0.3, (300, 6)), lo, hi)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, arm.configuration("qz"), damping="auto")
    assert res.converged.mean() >= 0.98
    _check_solution(arm, res, T)
    res = ikn.solve(arm, T, arm.configuration("qz"), damping="auto", restarts=5)
    assert res.converged.all()
    _check_solution(arm, res, T)


# ------------------------------------------------------------------- failure modes


def test_unreachable_targets(arms, rng):
    arm = arms("puma560")
    T = np.tile(np.eye(4), (20, 1, 1))
    T[:, :3, 3] = rng.normal(size=(20, 3))
    T[:, :3, 3] *= (5.0 / np.linalg.norm(T[:, :3, 3], axis=1))[:, None]  # 5 m away
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, arm.configuration("qn"), max_iter=50, restarts=2)
    start = np.linalg.norm(
        reference_fk(arm, arm.configuration("qn"))[0, :3, 3] - T[:, :3, 3], axis=1
    )
    assert not res.converged.any()
    assert np.all(np.isfinite(res.q)) and arm.within_limits(res.q).all()
    assert np.all(res.iterations <= 3 * 50)
    # the reported errors are those of the returned q (recomputed here)
    Tq = reference_fk(arm, res.q)
    assert np.allclose(
        res.position_error, np.linalg.norm(Tq[:, :3, 3] - T[:, :3, 3], axis=1), rtol=1e-9
    )
    assert np.allclose(res.rotation_error, rotation_angle(Tq[:, :3, :3], T[:, :3, :3]), atol=1e-6)
    # the returned q is the best found: closer than the start, and 5 m minus the reach
    # (shoulder 0.67 m high, arm ~0.9 m) is the least possible distance
    assert np.all(res.position_error < start)
    assert np.all(res.position_error > 5.0 - 0.6718 - 0.95)


def test_orientation_unreachable_for_scara_without_mask_fit(arms, rng):
    """All six components demanded of a 4-axis SCARA with a tilted target: no exact
    solution, converged False, best least-squares q returned, no warnings."""
    arm = arms("manutec_h5")
    q_true = random_q(arm, rng, 20, margin=0.05)
    T = reference_fk(arm, q_true).copy()
    T[:, :3, :3] = T[:, :3, :3] @ _rodrigues(np.array([1.0, 0, 0]), 0.3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, q_true, mask=[1] * 6, max_iter=30)
    assert not res.converged.any()
    assert np.all(np.isfinite(res.q)) and arm.within_limits(res.q).all()


def test_nan_targets_and_starts(arms, rng):
    arm = arms("manutec_r15")
    q_true = random_q(arm, rng, 10)
    T = reference_fk(arm, q_true).copy()
    q0 = _perturbed(arm, q_true, rng)
    T[2, 0, 3] = np.nan
    T[5] = np.nan
    T[7, 1, 1] = np.inf
    q0[8, 3] = np.nan
    bad = np.zeros(10, dtype=bool)
    bad[[2, 5, 7, 8]] = True
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ikn.solve(arm, T, q0, restarts=3)
    assert not res.converged[bad].any()
    assert np.all(np.isnan(res.q[bad])) and np.all(res.iterations[bad] == 0)
    assert np.all(np.isnan(res.position_error[bad])) and np.all(np.isnan(res.rotation_error[bad]))
    assert res.converged[~bad].all()
    T_good = T[~bad]
    sub = ikn.IKResult(
        res.q[~bad],
        res.converged[~bad],
        res.iterations[~bad],
        res.position_error[~bad],
        res.rotation_error[~bad],
        res.mask,
    )
    _check_solution(arm, sub, T_good)


def test_all_nan_and_empty_batches(arms):
    arm = arms("puma560")
    res = ikn.solve(arm, np.full((3, 4, 4), np.nan), np.zeros(6))
    assert not res.converged.any() and np.isnan(res.q).all()
    res = ikn.solve(arm, np.zeros((0, 4, 4)), np.zeros(6))
    assert res.q.shape == (0, 6) and res.converged.shape == (0,)


# ------------------------------------------------------------------- shapes, arguments


def test_shapes(arms, rng):
    arm = arms("puma560")
    q_true = random_q(arm, rng, 6)
    T = reference_fk(arm, q_true)
    one = ikn.solve(arm, T[0], _perturbed(arm, q_true[0], rng))
    assert one.q.shape == (6,) and one.converged.shape == () and bool(one.converged)
    grid = ikn.solve(arm, T.reshape(2, 3, 4, 4), _perturbed(arm, q_true, rng).reshape(2, 3, 6))
    assert grid.q.shape == (2, 3, 6) and grid.position_error.shape == (2, 3)
    assert grid.converged.all()
    # default start: the arm's qz; tol as a (position, rotation) pair
    res = ikn.solve(arm, T, None, tol=(1e-6, 1e-4), restarts=20)
    assert res.converged.all()
    assert np.all(res.position_error <= 1e-6) and np.all(res.rotation_error <= 1e-4)


def test_respect_limits_false_may_leave_the_range(arms):
    """q4 = 175 deg is beyond the Puma's +170 deg; the flipped wrist (q4 - pi, -q5,
    q6 + pi) reaches the same pose inside the limits. Without limits Newton returns the
    nearby out-of-range solution; with limits a restart finds an in-range one."""
    arm = arms("puma560")
    q_out = np.array([0.3, 0.5, -0.5, math.radians(175), 0.5, 0.1])
    assert not arm.within_limits(q_out)
    T = reference_fk(arm, q_out)
    free = ikn.solve(arm, T, q_out + 0.01, respect_limits=False)
    assert free.converged and np.allclose(free.q, q_out, atol=1e-8)
    kept = ikn.solve(arm, T[0], q_out + 0.01, restarts=20)
    assert kept.converged and arm.within_limits(kept.q)
    one = ikn.IKResult(
        kept.q[None],
        kept.converged[None],
        kept.iterations[None],
        kept.position_error[None],
        kept.rotation_error[None],
        kept.mask,
    )
    _check_solution(arm, one, T)


def test_start_outside_the_limits(arms, rng):
    """q0 beyond the limits (q2 = 250 deg > 225 deg, q6 = 400 deg = 40 deg + 360 deg):
    solutions and, for an unreachable target, the best q are inside the limits."""
    arm = arms("puma560")
    q_true = random_q(arm, rng, 100)
    T = reference_fk(arm, q_true)
    q0 = np.radians([0.0, 250.0, -90.0, 0.0, 30.0, 400.0])
    res = ikn.solve(arm, T, q0, restarts=100)
    assert res.converged.all()
    _check_solution(arm, res, T)
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.0]
    res = ikn.solve(arm, far, q0, max_iter=20)
    assert not res.converged and arm.within_limits(res.q)


def test_zero_tolerance_and_zero_iterations(arms):
    """tol = 0 cannot be met in floating point in general: the solver stops (stuck or
    max_iter), returns the best q; max_iter = 0 only checks the start."""
    arm = arms("puma560")
    qn = arm.configuration("qn")
    T = reference_fk(arm, qn)[0]
    res = ikn.solve(arm, T, qn + 0.05, tol=0.0, restarts=0)
    assert res.position_error < 1e-14 and res.rotation_error < 1e-14
    assert res.iterations <= 100
    res = ikn.solve(arm, T, qn, max_iter=0)
    assert res.iterations == 0 and res.converged  # fk(qn) = T exactly
    res = ikn.solve(arm, T, qn + 0.05, max_iter=0, restarts=3)
    assert res.iterations == 0 and not res.converged and np.allclose(res.q, qn + 0.05)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(jacobian="analytic"),
        dict(damping="lots"),
        dict(damping=-1.0),
        dict(mask=[1, 1, 1]),
        dict(mask=[0] * 6),
        dict(mask=[2, 0, 0, 0, 0, 0]),
        dict(tol=-1.0),
        dict(tol="small"),
        dict(max_iter=-1),
        dict(max_iter=2.5),
        dict(restarts=-2),
        dict(step_limit=0.0),
        dict(step_limit="big"),
        dict(null_space=-0.1),
    ],
)
def test_bad_arguments(arms, kwargs):
    arm = arms("puma560")
    with pytest.raises(InputError):
        ikn.solve(arm, np.eye(4), np.zeros(6), **kwargs)


def test_bad_shapes(arms):
    arm = arms("puma560")
    with pytest.raises(InputError):
        ikn.solve(arm, np.eye(3), np.zeros(6))
    with pytest.raises(InputError):
        ikn.solve(arm, np.eye(4), np.zeros(5))
    with pytest.raises(InputError):
        ikn.solve(arm, np.tile(np.eye(4), (3, 1, 1)), np.zeros((2, 6)))
    with pytest.raises(InputError):
        ikn.solve(arm, "pose", np.zeros(6))
