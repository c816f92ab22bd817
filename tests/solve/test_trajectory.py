"""Cartesian trajectories and their joint-space conversion (deltagen.plan.trajectory):
time scalings, line and arc geometry, slerp, per-sample Newton IK without branch flips,
exact vs numerical joint rates.

Expected values come from closed forms typed in here (polynomials, circle geometry, the
2R law of cosines) and from finite differences, not from the module's own output."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.api.serial import SerialRobot
from deltagen.plan import trajectory as tr


@pytest.fixture(scope="module")
def scara():
    return SerialRobot.load("lecture_scara")


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560")


# ------------------------------------------------------------------ time scaling


def test_quintic_boundary_conditions_and_shape():
    s, sd, sdd = tr.Quintic()(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(s, [0.0, 0.5, 1.0], atol=1e-15)
    np.testing.assert_allclose(sd[[0, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(sdd, 0.0, atol=1e-14)  # also 0 at tau = 1/2 (inflection)
    assert sd[1] == pytest.approx(15.0 / 8.0)
    tau = np.linspace(0, 1, 2001)
    s, sd, sdd = tr.Quintic()(tau)
    assert np.all(np.diff(s) >= 0) and sd.max() == pytest.approx(15 / 8)
    assert np.abs(sdd).max() == pytest.approx(10 / math.sqrt(3), rel=1e-5)
    # the polynomial typed in: 10 t^3 - 15 t^4 + 6 t^5
    np.testing.assert_allclose(s, 10 * tau**3 - 15 * tau**4 + 6 * tau**5, atol=1e-15)


@pytest.mark.parametrize(
    "scaling", [tr.Quintic(), tr.Trapezoid(0.25), tr.Trapezoid(0.5), tr.Trapezoid(0.1)], ids=repr
)
def test_scaling_derivatives_match_finite_differences(scaling):
    h = 1e-6
    tau = np.linspace(0.013, 0.987, 301)
    s, sd, sdd = scaling(tau)
    sp, sdp, _ = scaling(tau + h)
    sm, sdm, _ = scaling(tau - h)
    if isinstance(scaling, tr.Trapezoid):  # sdd jumps at the blend corners: skip those
        b = scaling.blend
        keep = (np.abs(tau - b) > 2 * h) & (np.abs(tau - (1 - b)) > 2 * h)
    else:
        keep = np.ones_like(tau, dtype=bool)
    np.testing.assert_allclose(sd[keep], ((sp - sm) / (2 * h))[keep], atol=1e-7)
    np.testing.assert_allclose(sdd[keep], ((sdp - sdm) / (2 * h))[keep], atol=1e-6)


@pytest.mark.parametrize("blend", [0.1, 0.25, 0.4, 0.5])
def test_trapezoid_boundary_conditions_and_plateau(blend):
    prof = tr.Trapezoid(blend)
    s, sd, sdd = prof(np.array([0.0, 1.0]))
    np.testing.assert_allclose(s, [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(sd, [0.0, 0.0], atol=1e-15)
    assert prof(0.5)[0] == pytest.approx(0.5)
    vmax = 1.0 / (1.0 - blend)
    assert prof(0.5)[1] == pytest.approx(vmax)
    # continuity of s and s' at the blend corners
    for corner in (blend, 1 - blend):
        lo, hi = prof(corner - 1e-12), prof(corner + 1e-12)
        assert lo[0] == pytest.approx(hi[0], abs=1e-10)
        assert lo[1] == pytest.approx(hi[1], abs=1e-9)
    # accelerations +a, 0, -a
    assert prof(blend / 2)[2] == pytest.approx(vmax / blend)
    assert prof(1 - blend / 2)[2] == pytest.approx(-vmax / blend)
    if blend < 0.5:
        assert prof(0.5)[2] == 0.0


@pytest.mark.parametrize("blend", [0.0, -0.1, 0.6, float("nan")])
def test_trapezoid_rejects_bad_blend(blend):
    with pytest.raises(ValueError):
        tr.Trapezoid(blend)


def test_segment_time_scaling_in_seconds():
    seg = tr.Segment(tr.Line([0, 0, 0], [2, 0, 0]), 4.0)
    out = seg.evaluate(np.array([0.0, 2.0, 4.0]))
    np.testing.assert_allclose(out["p"][:, 0], [0, 1, 2], atol=1e-15)
    # peak speed of the quintic: 15/8 * length / T
    assert out["v"][1, 0] == pytest.approx(15 / 8 * 2 / 4)
    np.testing.assert_allclose(out["v"][[0, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(out["a"][[0, 2]], 0.0, atol=1e-15)


# ------------------------------------------------------------------ paths


def _circle(center, normal, radius):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    return lambda ang: np.asarray(center) + radius * (math.cos(ang) * u + math.sin(ang) * w), n


@pytest.mark.parametrize("a0, a1, a2", [(0.1, 0.9, 1.7), (0.0, 2.0, 4.0), (-0.5, 2.5, 5.5)])
def test_arc_through_three_points_geometry(a0, a1, a2):
    """Points at angles a0 < a1 < a2 on a tilted circle (including sweeps above pi)."""
    c, r = np.array([0.3, -0.2, 0.7]), 0.45
    point, n = _circle(c, [0.3, -0.5, 0.8], r)
    arc = tr.Arc.from_three_points(point(a0), point(a1), point(a2))
    np.testing.assert_allclose(arc.center, c, atol=1e-12)
    assert arc.radius == pytest.approx(r, abs=1e-12)
    np.testing.assert_allclose(arc.axis, n, atol=1e-12)
    assert arc.angle == pytest.approx(a2 - a0, abs=1e-12)
    assert arc.length == pytest.approx(r * (a2 - a0), abs=1e-12)
    np.testing.assert_allclose(arc.start, point(a0), atol=1e-13)
    np.testing.assert_allclose(arc.end, point(a2), atol=1e-12)
    s = np.linspace(0, 1, 401)
    p, dp, ddp = arc.evaluate(s)
    # every point on the circle: distance r from the centre, in the plane
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), r, atol=1e-12)
    np.testing.assert_allclose((p - c) @ n, 0.0, atol=1e-12)
    # the via point is passed through, at s = (a1 - a0) / (a2 - a0)
    p_via = arc.evaluate(np.array([(a1 - a0) / (a2 - a0)]))[0][0]
    np.testing.assert_allclose(p_via, point(a1), atol=1e-12)
    # constant speed r * angle along s; acceleration centripetal
    np.testing.assert_allclose(np.linalg.norm(dp, axis=1), r * arc.angle, rtol=1e-12)
    np.testing.assert_allclose(ddp, -(arc.angle**2) * (p - c), atol=1e-12)
    # derivatives vs central differences
    h = 1e-6
    pp, _, _ = arc.evaluate(s + h)
    pm, _, _ = arc.evaluate(s - h)
    np.testing.assert_allclose(dp, (pp - pm) / (2 * h), atol=1e-8)


def test_arc_by_centre_axis_angle_and_direction():
    arc = tr.Arc([0, 0, 0.5], [1, 0, 0.5], [0, 0, 1], math.pi / 2)
    p, dp, _ = arc.evaluate(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(
        p, [[1, 0, 0.5], [math.sqrt(0.5), math.sqrt(0.5), 0.5], [0, 1, 0.5]], atol=1e-15
    )
    assert dp[0, 1] > 0  # counter-clockwise about +z
    cw = tr.Arc([0, 0, 0.5], [1, 0, 0.5], [0, 0, 1], -math.pi / 2)
    np.testing.assert_allclose(cw.end, [0, -1, 0.5], atol=1e-15)


def test_arc_rejects_bad_input():
    with pytest.raises(ValueError):
        tr.Arc([0, 0, 0], [1, 0, 0], [1, 1, 0], 1.0)  # axis not perpendicular
    with pytest.raises(ValueError):
        tr.Arc([0, 0, 0], [0, 0, 0], [0, 0, 1], 1.0)  # radius 0
    with pytest.raises(ValueError):
        tr.Arc.from_three_points([0, 0, 0], [1, 1, 1], [2, 2, 2])  # collinear


def test_line_geometry():
    line = tr.Line([1, 2, 3], [4, 6, 3])
    p, dp, ddp = line.evaluate(np.array([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(p, [[1, 2, 3], [1.75, 3, 3], [4, 6, 3]])
    np.testing.assert_allclose(dp, [[3, 4, 0]] * 3)
    assert not ddp.any() and line.length == 5.0


# ------------------------------------------------------------------ rotations


def _rand_rot(rng):
    return tr.rot_exp(rng.normal(size=3))


def test_rot_exp_log_roundtrip_including_small_and_near_pi(rng):
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.r_[
        np.geomspace(1e-12, 1e-3, 10),
        rng.uniform(0, math.pi, 20),
        math.pi - np.geomspace(1e-3, 1e-9, 10),
    ]
    v = axes * angles[:, None]
    R = tr.rot_exp(v)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14
    )
    np.testing.assert_allclose(tr.rot_log(R), v, atol=2e-8)  # near pi: sqrt(eps)-limited sign
    np.testing.assert_allclose(tr.rot_log(R[:30]), v[:30], atol=1e-13)
    for k in range(40):  # the single-matrix path agrees with the batch path
        np.testing.assert_allclose(tr.rot_log(R[k]), tr.rot_log(R[k : k + 1])[0], atol=1e-12)
    # Rodrigues typed in for one case: 90 deg about z
    np.testing.assert_allclose(
        tr.rot_exp([0, 0, math.pi / 2]), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15
    )


def test_quaternion_roundtrip(rng):
    R = np.stack([_rand_rot(rng) for _ in range(50)])
    q = tr.quat_from_matrix(R)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(tr.matrix_from_quat(q), R, atol=1e-14)
    # 180 deg about x: (w, x, y, z) = (0, 1, 0, 0)
    np.testing.assert_allclose(
        np.abs(tr.quat_from_matrix(np.diag([1.0, -1, -1]))), [0, 1, 0, 0], atol=1e-15
    )


def test_slerp_endpoints_agrees_with_quaternion_slerp_and_constant_rate(rng):
    for _ in range(10):
        R0, R1 = _rand_rot(rng), _rand_rot(rng)
        s = np.linspace(0, 1, 11)
        Rs = tr.slerp(R0, R1, s)
        np.testing.assert_allclose(Rs[0], R0, atol=1e-14)
        np.testing.assert_allclose(Rs[-1], R1, atol=1e-12)
        qs = tr.quat_slerp(tr.quat_from_matrix(R0), tr.quat_from_matrix(R1), s)
        np.testing.assert_allclose(tr.matrix_from_quat(qs), Rs, atol=1e-12)
        # equal angles between consecutive samples (constant angular velocity)
        steps = np.linalg.norm(tr.rot_log(Rs[1:] @ np.swapaxes(Rs[:-1], 1, 2)), axis=1)
        total = np.linalg.norm(tr.rot_log(R1 @ R0.T))
        np.testing.assert_allclose(steps, total / 10, atol=1e-12)


def test_segment_angular_velocity_matches_finite_differences(rng):
    R0, R1 = _rand_rot(rng), _rand_rot(rng)
    seg = tr.Segment(tr.Line([0, 0, 0], [1, 0, 0]), 2.0, R0=R0, R1=R1)
    t = np.linspace(0.05, 1.95, 39)
    h = 1e-5
    out, plus, minus = seg.evaluate(t), seg.evaluate(t + h), seg.evaluate(t - h)
    # w = vee(Rdot R^T); central difference of log(R(t+h) R(t-h)^T) / 2h
    w_fd = tr.rot_log(plus["R"] @ np.swapaxes(minus["R"], 1, 2)) / (2 * h)
    np.testing.assert_allclose(out["w"], w_fd, atol=1e-8)
    np.testing.assert_allclose(out["wd"], (plus["w"] - minus["w"]) / (2 * h), atol=1e-6)


# ------------------------------------------------------------------ trajectories


def test_path_builder_continuity_and_sampling():
    b = tr.PathBuilder([1.0, 0, 0], joints=[0.0])
    b.line([1.0, 0, 0.5], 1.0).arc_about([0, 0, 0], [0, 0, 1], math.pi / 2, 2.0, joints=[1.0])
    b.dwell(0.5).line([0, 0, 0.5], 1.5)
    traj = b.build()
    assert traj.duration == 5.0
    np.testing.assert_allclose(traj.breaks, [1.0, 3.0, 3.5])
    t = traj.sample_times(0.01)
    assert t.size == 501 and t[-1] == 5.0
    cs = traj.evaluate(t)
    # continuous position; zero velocity at every segment joint (quintic stops)
    assert np.max(np.linalg.norm(np.diff(cs.p, axis=0), axis=1)) < 0.02
    for tb in traj.breaks:
        k = int(round(tb / 0.01))
        np.testing.assert_allclose(cs.v[k], 0.0, atol=1e-12)
        np.testing.assert_allclose(cs.a[k], 0.0, atol=1e-12)
    np.testing.assert_allclose(cs.p[-1], [0, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(cs.qj[[0, -1], 0], [0.0, 1.0])
    # the arc keeps radius 1 about the z axis at z = 0.5
    arc = cs.segment == 1
    np.testing.assert_allclose(np.hypot(cs.p[arc, 0], cs.p[arc, 1]), 1.0, atol=1e-12)
    np.testing.assert_allclose(cs.p[arc, 2], 0.5, atol=1e-12)


def test_trajectory_rejects_gaps():
    with pytest.raises(ValueError, match="continuous"):
        tr.CartesianTrajectory(
            [
                tr.Segment(tr.Line([0, 0, 0], [1, 0, 0]), 1.0),
                tr.Segment(tr.Line([1, 0, 0.1], [1, 1, 0]), 1.0),
            ]
        )
    with pytest.raises(ValueError):
        tr.Segment(tr.Line([0, 0, 0], [1, 0, 0]), 0.0)


# ------------------------------------------------------------------ numerical differentiation


def test_numerical_rates_exact_for_quadratics_and_second_order():
    t = np.linspace(0, 2, 41)
    q = np.column_stack([3 - 2 * t + 0.7 * t**2, 0.5 * t**2])
    qd, qdd = tr.numerical_rates(t, q)
    np.testing.assert_allclose(qd, np.column_stack([-2 + 1.4 * t, t]), atol=1e-12)
    np.testing.assert_allclose(
        qdd, np.column_stack([np.full_like(t, 1.4), np.ones_like(t)]), atol=1e-9
    )
    errs = []
    for n in (101, 201, 401):
        t = np.linspace(0, 3, n)
        qd, qdd = tr.numerical_rates(t, np.sin(2 * t))
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
    qd, qdd = tr.numerical_rates(t, q, breaks=[1.0])
    exact_qdd = np.where(t < 1, 6 * t, 0.0)
    inner = np.abs(t - 1) > 1e-9
    np.testing.assert_allclose(qdd[inner, 0], exact_qdd[inner], atol=1e-9)
    np.testing.assert_allclose(qd[:, 0], np.where(t < 1, 3 * t**2, 3.0), atol=1e-3)
    with pytest.raises(ValueError):
        tr.numerical_rates(np.array([0, 1, 3, 4.0]), np.zeros(4))


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
    traj = tr.PathBuilder(p0).line([4.0, 3.0, 0.0], 2.0).build()
    jt = tr.to_joint_trajectory(scara, traj, tr.Task("xy"), q0, dt=0.01)
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
    traj = tr.PathBuilder(p0, joints=[0.0]).line([0.70, 0.0, 0.55], 1.0).build()
    task = tr.Task("xyz", joints=(3,))
    with pytest.raises(tr.TrajectoryError, match="limits") as exc:
        tr.to_joint_trajectory(arm, traj, task, q0, dt=0.01)
    assert exc.value.rows.size > 0 and exc.value.rows[-1] == 100
    jt = tr.to_joint_trajectory(arm, traj, task, q0, dt=0.01, limits="ignore")
    assert jt.q[-1, 2] < -math.pi / 2 and np.all(jt.q[:, 2] < 0)


def test_branch_flip_and_bad_paths_are_detected(scara):
    q0 = np.radians([10.0, 30.0])
    p0 = scara.fk(q0)[:3, 3]
    traj = tr.PathBuilder(p0).line([4.0, 3.0, 0.0], 2.0).build()
    with pytest.raises(tr.TrajectoryError, match="max_step"):
        tr.to_joint_trajectory(scara, traj, tr.Task("xy"), q0, dt=0.01, max_step=1e-4)
    with pytest.raises(tr.TrajectoryError, match="branch"):
        tr.to_joint_trajectory(
            scara, traj, tr.Task("xy"), q0, dt=0.01, branch=lambda q: q[:, 1] < math.radians(60)
        )
    # a start guess on the other branch is followed there, not flipped back
    q_other = _scara_ik_elbow(np.array([p0[0]]), np.array([p0[1]]), -1)[0]
    jt = tr.to_joint_trajectory(scara, traj, tr.Task("xy"), q_other, dt=0.01)
    assert np.all(jt.q[:, 1] < 0)
    # a point out of reach: no convergence, the sample is named
    far = tr.PathBuilder(p0).line([8.0, 0.0, 0.0], 1.0).build()
    with pytest.raises(tr.TrajectoryError, match="sample"):
        tr.to_joint_trajectory(scara, far, tr.Task("xy"), q0, dt=0.01)


def test_task_validation(scara, puma):
    with pytest.raises(ValueError):
        tr.Task("xyz").check(scara)  # 3 rows, 2 joints
    with pytest.raises(ValueError, match="q_init"):
        tr.solve_ik(scara, tr.Task("xy"), [6.0, 2.0, 0.0])
    with pytest.raises(ValueError):
        tr.Task("xw")
    with pytest.raises(ValueError):
        tr.Task("xy", joints=(5,)).check(scara)
    traj = tr.PathBuilder([6, 2, 0]).line([5, 2, 0], 1.0).build()
    with pytest.raises(ValueError, match="orientation"):
        tr.to_joint_trajectory(
            puma, traj, tr.Task("xyz", orientation=True), puma.configuration("qn")
        )


def _puma_trajectory(puma, scaling="quintic"):
    q0 = puma.configuration("qn")
    T0 = puma.fk(q0)
    p0, R0 = T0[:3, 3], T0[:3, :3]
    R1 = R0 @ tr.rot_exp([0.3, -0.2, 0.5])
    R2 = R1 @ tr.rot_exp([-0.2, 0.4, 0.0])
    b = tr.PathBuilder(p0, R=R0, scaling=scaling)
    b.line(p0 + [0.1, -0.15, 0.1], 1.5, R=R1)
    b.arc(p0 + [0.0, -0.25, 0.15], p0 + [-0.1, -0.2, 0.1], 2.0, R=R2)
    return q0, b.build()


def test_six_axis_pose_trajectory_exact_vs_numerical_rates_second_order(puma):
    q0, traj = _puma_trajectory(puma)
    task = tr.Task("xyz", orientation=True)
    runs = [tr.to_joint_trajectory(puma, traj, task, q0, dt=dt) for dt in (0.01, 0.005, 0.0025)]
    for jt in runs:
        # the IK really tracks the pose
        T = puma.fk(jt.q)
        np.testing.assert_allclose(T[:, :3, 3], jt.cartesian.p, atol=1e-12)
        R_err = tr.rot_log(T[:, :3, :3] @ np.swapaxes(jt.cartesian.R, 1, 2))
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
    task = tr.Task("xyz", orientation=True)
    errs = []
    for dt in (0.01, 0.005):
        jt = tr.to_joint_trajectory(puma, traj, task, q0, dt=dt)
        errs.append(np.abs(jt.numerical_rates_unsplit()[1] - jt.qdd).max())
    assert 1.6 < errs[0] / errs[1] < 2.4


def test_trapezoid_profile_trajectory(puma):
    """LSPB: the acceleration jumps at the blend corners, so central differences of the
    joint angles are only O(h) for qd there and O(1) wrong for qdd (half the jump); the
    exact rates have no such problem (they still satisfy J qd = v)."""
    q0, traj = _puma_trajectory(puma, scaling=tr.Trapezoid(0.2))
    errs = []
    for dt in (0.005, 0.0025):
        jt = tr.to_joint_trajectory(puma, traj, tr.Task("xyz", orientation=True), q0, dt=dt)
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
    traj = tr.PathBuilder(p0).line(p0 + [0.05, 0.1, -0.05], 1.0).build()
    jt = tr.to_joint_trajectory(puma, traj, tr.Task("xyz"), q0, dt=0.01)
    np.testing.assert_allclose(puma.fk(jt.q)[:, :3, 3], jt.cartesian.p, atol=1e-12)
    J = puma.jacobian(jt.q)[:, :3]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, jt.qd), jt.cartesian.v, atol=1e-12)


def test_solve_ik_converges_quadratically(scara):
    q_true = np.radians([25.0, 70.0])
    p = scara.fk(q_true)[:3, 3]
    q, err, it = tr.solve_ik(scara, tr.Task("xy"), p, q_init=q_true + 0.05)
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
    table = tr.jacobian_path_following(scara, q, target, steps=10)
    for k in range(1, 11):
        q = q + np.linalg.solve(J(q), P0 + (target - P0) * k / 10 - f(q))
        np.testing.assert_allclose(table.ist[k], f(q), atol=1e-13)
        np.testing.assert_allclose(table.q[k], q, atol=1e-13)
    assert table.final_error < 1e-12
