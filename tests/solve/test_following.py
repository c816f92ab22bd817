"""Path following (deltagen.plan.following): per-sample Newton IK without branch flips, exact
vs numerical joint rates, tasks, the lecture's Jacobian path following. Expected values
come from the 2R law of cosines typed in here and from finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.api.serial import SerialRobot
from deltagen.geometry import rotations as rot
from deltagen.plan import cartesian, following, scaling


@pytest.fixture(scope="module")
def scara():
    return SerialRobot.load("lecture_scara")


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560")


# ------------------------------------------------------------------ numerical differentiation


def test_numerical_rates_exact_for_quadratics_and_second_order():
    t = np.linspace(0, 2, 41)
    q = np.column_stack([3 - 2 * t + 0.7 * t**2, 0.5 * t**2])
    qd, qdd = following.numerical_rates(t, q)
    np.testing.assert_allclose(qd, np.column_stack([-2 + 1.4 * t, t]), atol=1e-12)
    np.testing.assert_allclose(
        qdd, np.column_stack([np.full_like(t, 1.4), np.ones_like(t)]), atol=1e-9
    )
    errs = []
    for n in (101, 201, 401):
        t = np.linspace(0, 3, n)
        qd, qdd = following.numerical_rates(t, np.sin(2 * t))
        errs.append(
            (
                np.abs(qd[:, 0] - 2 * np.cos(2 * t)).max(),
                np.abs(qdd[:, 0] + 4 * np.sin(2 * t)).max(),
            )
        )
    errs = np.array(errs)
    ratios = errs[:-1] / errs[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios


def test_numerical_rates_breaks_split_the_signal():
    t = np.linspace(0, 2, 201)
    q = np.where(t < 1, t**3, 1 + 3 * (t - 1))  # C1 at t = 1, the second derivative jumps
    qd, qdd = following.numerical_rates(t, q, breaks=[1.0])
    exact_qdd = np.where(t < 1, 6 * t, 0.0)
    inner = np.abs(t - 1) > 1e-9
    np.testing.assert_allclose(qdd[inner, 0], exact_qdd[inner], atol=1e-9)
    np.testing.assert_allclose(qd[:, 0], np.where(t < 1, 3 * t**2, 3.0), atol=1e-3)
    with pytest.raises(ValueError):
        following.numerical_rates(np.array([0, 1, 3, 4.0]), np.zeros(4))


# ------------------------------------------------------------------ IK along paths


def _scara_ik_elbow(x, y, sign, L1=4.0, L2=3.0):
    """2R law of cosines, typed in: q2 = sign * acos(D), q1 = atan2(y, x) - atan2(L2 s2, L1 + L2 c2)."""
    D = (x * x + y * y - L1 * L1 - L2 * L2) / (2 * L1 * L2)
    q2 = sign * np.arccos(np.clip(D, -1, 1))
    q1 = np.arctan2(y, x) - np.arctan2(L2 * np.sin(q2), L1 + L2 * np.cos(q2))
    return np.column_stack([q1, q2])


@pytest.mark.parametrize("sign, q0", [(+1, (10.0, 30.0)), (-1, (50.0, -30.0))])
def test_scara_line_stays_on_its_branch(scara, sign, q0):
    """The lecture's straight line as a timed trajectory, from either elbow configuration:
    the IK follows the branch of the start (q2 keeps its sign) and equals the closed-form
    solution of that branch at every sample."""
    q0 = np.radians(q0)
    p0 = scara.fk(q0)[:3, 3]
    traj = cartesian.PathBuilder(p0).line([4.0, 3.0, 0.0], 2.0).build()
    jt = following.to_joint_trajectory(scara, traj, following.Task("xy"), q0, dt=0.01)
    assert np.all(np.sign(jt.q[:, 1]) == sign)
    np.testing.assert_allclose(
        jt.q, _scara_ik_elbow(jt.cartesian.p[:, 0], jt.cartesian.p[:, 1], sign), atol=1e-10
    )
    # joint steps bounded: no jumps, at most the peak rate times h (plus a little)
    assert jt.max_joint_step <= np.abs(jt.qd).max() * jt.dt * 1.01
    assert jt.task_error.max() < 1e-12
    # exact rates reproduce the Cartesian velocity: J qd = v
    J = scara.jacobian(jt.q)[:, :2]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, jt.qd), jt.cartesian.v[:, :2], atol=1e-12)


def test_joint_limits_are_enforced():
    """Miskolc RRRR: a straight line in towards the shoulder needs q3 < -90 deg (beyond the
    robot file's range, elbow up): refused with the samples named, followed with limits off."""
    arm = SerialRobot.load("miskolc_rrrr")
    q0 = arm.configuration("ready")
    p0 = arm.fk(q0)[:3, 3]
    traj = cartesian.PathBuilder(p0, joints=[0.0]).line([0.70, 0.0, 0.55], 1.0).build()
    task = following.Task("xyz", joints=(3,))
    with pytest.raises(following.TrajectoryError, match="limits") as exc:
        following.to_joint_trajectory(arm, traj, task, q0, dt=0.01)
    assert exc.value.rows.size > 0 and exc.value.rows[-1] == 100
    jt = following.to_joint_trajectory(arm, traj, task, q0, dt=0.01, limits="ignore")
    assert jt.q[-1, 2] < -math.pi / 2 and np.all(jt.q[:, 2] < 0)


def test_branch_flip_and_bad_paths_are_detected(scara):
    q0 = np.radians([10.0, 30.0])
    p0 = scara.fk(q0)[:3, 3]
    traj = cartesian.PathBuilder(p0).line([4.0, 3.0, 0.0], 2.0).build()
    with pytest.raises(following.TrajectoryError, match="max_step"):
        following.to_joint_trajectory(scara, traj, following.Task("xy"), q0, dt=0.01, max_step=1e-4)
    with pytest.raises(following.TrajectoryError, match="branch"):
        following.to_joint_trajectory(
            scara,
            traj,
            following.Task("xy"),
            q0,
            dt=0.01,
            branch=lambda q: q[:, 1] < math.radians(60),
        )
    # a start guess on the other branch is followed there, not flipped back
    q_other = _scara_ik_elbow(np.array([p0[0]]), np.array([p0[1]]), -1)[0]
    jt = following.to_joint_trajectory(scara, traj, following.Task("xy"), q_other, dt=0.01)
    assert np.all(jt.q[:, 1] < 0)
    # a point out of reach: no convergence, the sample is named
    far = cartesian.PathBuilder(p0).line([8.0, 0.0, 0.0], 1.0).build()
    with pytest.raises(following.TrajectoryError, match="sample"):
        following.to_joint_trajectory(scara, far, following.Task("xy"), q0, dt=0.01)


def test_task_validation(scara, puma):
    with pytest.raises(ValueError):
        following.Task("xyz").check(scara)  # 3 rows, 2 joints
    with pytest.raises(ValueError, match="q_init"):
        following.solve_ik(scara, following.Task("xy"), [6.0, 2.0, 0.0])
    with pytest.raises(ValueError):
        following.Task("xw")
    with pytest.raises(ValueError):
        following.Task("xy", joints=(5,)).check(scara)
    traj = cartesian.PathBuilder([6, 2, 0]).line([5, 2, 0], 1.0).build()
    with pytest.raises(ValueError, match="orientation"):
        following.to_joint_trajectory(
            puma, traj, following.Task("xyz", orientation=True), puma.configuration("qn")
        )


def _puma_trajectory(puma, time_scaling="quintic"):
    q0 = puma.configuration("qn")
    T0 = puma.fk(q0)
    p0, R0 = T0[:3, 3], T0[:3, :3]
    R1 = R0 @ rot.rot_exp([0.3, -0.2, 0.5])
    R2 = R1 @ rot.rot_exp([-0.2, 0.4, 0.0])
    b = cartesian.PathBuilder(p0, R=R0, scaling=time_scaling)
    b.line(p0 + [0.1, -0.15, 0.1], 1.5, R=R1)
    b.arc(p0 + [0.0, -0.25, 0.15], p0 + [-0.1, -0.2, 0.1], 2.0, R=R2)
    return q0, b.build()


def test_six_axis_pose_trajectory_exact_vs_numerical_rates_second_order(puma):
    q0, traj = _puma_trajectory(puma)
    task = following.Task("xyz", orientation=True)
    runs = [
        following.to_joint_trajectory(puma, traj, task, q0, dt=dt) for dt in (0.01, 0.005, 0.0025)
    ]
    for jt in runs:
        # the IK really tracks the pose
        T = puma.fk(jt.q)
        np.testing.assert_allclose(T[:, :3, 3], jt.cartesian.p, atol=1e-12)
        R_err = rot.rot_log(T[:, :3, :3] @ np.swapaxes(jt.cartesian.R, 1, 2))
        assert np.abs(R_err).max() < 1e-12
        # the exact rates satisfy J qd = (v, w) and J qdd + Jdot qd = (a, wd)
        J = puma.jacobian(jt.q)
        twist = np.einsum("nij,nj->ni", J, jt.qd)
        np.testing.assert_allclose(
            twist, np.column_stack([jt.cartesian.v, jt.cartesian.w]), atol=1e-12
        )
        acc = np.einsum("nij,nj->ni", J, jt.qdd) + np.einsum(
            "nij,nj->ni", puma.jacobian_dot(jt.q, jt.qd), jt.qd
        )
        np.testing.assert_allclose(
            acc, np.column_stack([jt.cartesian.a, jt.cartesian.wd]), atol=1e-11
        )
    e = np.array([[r.rate_errors()["qd"], r.rate_errors()["qdd"]] for r in runs])
    ratios = e[:-1] / e[1:]
    assert np.all((ratios > 3.6) & (ratios < 4.4)), ratios  # O(h^2)
    peak = runs[-1].rate_errors()
    assert e[-1, 0] < 1e-4 * peak["qd_peak"] and e[-1, 1] < 1e-3 * peak["qdd_peak"]


def test_unsplit_differentiation_is_first_order_at_segment_joints(puma):
    """Differentiating across a quintic stop: the jerk jumps, the second difference is O(h)
    there (the reason for the per-segment differentiation)."""
    q0, traj = _puma_trajectory(puma)
    task = following.Task("xyz", orientation=True)
    errs = []
    for dt in (0.01, 0.005):
        jt = following.to_joint_trajectory(puma, traj, task, q0, dt=dt)
        errs.append(np.abs(jt.numerical_rates_unsplit()[1] - jt.qdd).max())
    assert 1.6 < errs[0] / errs[1] < 2.4


def test_trapezoid_profile_trajectory(puma):
    """LSPB: the acceleration jumps at the blend corners, so central differences of the
    joint angles are only O(h) for qd there and O(1) wrong for qdd (half the jump); the
    exact rates have no such problem (they still satisfy J qd = v)."""
    q0, traj = _puma_trajectory(puma, time_scaling=scaling.Trapezoid(0.2))
    errs = []
    for dt in (0.005, 0.0025):
        jt = following.to_joint_trajectory(
            puma, traj, following.Task("xyz", orientation=True), q0, dt=dt
        )
        errs.append((jt.rate_errors()["qd"], jt.rate_errors()["qdd"]))
        J = puma.jacobian(jt.q)[:, :3]
        np.testing.assert_allclose(np.einsum("nij,nj->ni", J, jt.qd), jt.cartesian.v, atol=1e-12)
    (d1, a1), (d2, a2) = errs
    assert 1.7 < d1 / d2 < 2.3  # first order at the corners
    assert 0.9 < a1 / a2 < 1.1 and a1 > 0.1 * np.abs(jt.qdd).max()  # does not shrink
    assert np.abs(np.diff(jt.qdd, axis=0)).max() > 0.1 * np.abs(jt.qdd).max()  # real jumps


def test_redundant_task_minimum_norm_rates(puma):
    """Position only on a six-axis arm (3 rows, 6 joints): the IK converges and the exact
    minimum-norm rates reproduce the Cartesian velocity."""
    q0 = puma.configuration("qn")
    p0 = puma.fk(q0)[:3, 3]
    traj = cartesian.PathBuilder(p0).line(p0 + [0.05, 0.1, -0.05], 1.0).build()
    jt = following.to_joint_trajectory(puma, traj, following.Task("xyz"), q0, dt=0.01)
    np.testing.assert_allclose(puma.fk(jt.q)[:, :3, 3], jt.cartesian.p, atol=1e-12)
    J = puma.jacobian(jt.q)[:, :3]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, jt.qd), jt.cartesian.v, atol=1e-12)


def test_solve_ik_converges_quadratically(scara):
    q_true = np.radians([25.0, 70.0])
    p = scara.fk(q_true)[:3, 3]
    q, err, it = following.solve_ik(scara, following.Task("xy"), p, q_init=q_true + 0.05)
    np.testing.assert_allclose(q, q_true, atol=1e-12)
    assert err < 1e-13 and it <= 5


def test_jacobian_path_following_is_slide_algorithm(scara):
    """One step per sub-point, inverse Jacobian at the current q, dP = P_soll - f(q):
    re-done here by hand with the 2x2 matrices typed from slide 108."""
    L1, L2 = 4.0, 3.0
    q = np.radians([10.0, 30.0])

    def f(q):
        return np.array(
            [
                L1 * math.cos(q[0]) + L2 * math.cos(q[0] + q[1]),
                L1 * math.sin(q[0]) + L2 * math.sin(q[0] + q[1]),
            ]
        )

    def J(q):
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s12, c12 = math.sin(q[0] + q[1]), math.cos(q[0] + q[1])
        return np.array([[-L1 * s1 - L2 * s12, -L2 * s12], [L1 * c1 + L2 * c12, L2 * c12]])

    P0, target = f(q), np.array([4.0, 3.0])
    table = following.jacobian_path_following(scara, q, target, steps=10)
    for k in range(1, 11):
        q = q + np.linalg.solve(J(q), P0 + (target - P0) * k / 10 - f(q))
        np.testing.assert_allclose(table.ist[k], f(q), atol=1e-13)
        np.testing.assert_allclose(table.q[k], q, atol=1e-13)
    assert table.final_error < 1e-12
