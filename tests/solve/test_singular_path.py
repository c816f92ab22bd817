"""Cartesian path following through singular regions (deltagen.plan.singular_path; lecture
slides 112-114: stop, "SingArea/Wrist", freeze an axis).

The paths are built from a chosen singular configuration (q5 = 0: axes 4 and 6 parallel,
read off the numpy reference's joint axes), so where the singularity lies is known without
the planner. The evidence for the returned motion is independent of it: the TCP position
and orientation from the numpy reference kinematics (backend="reference") against the path
written out here (the quintic s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 on the straight line,
constant orientation), joint speeds from central differences of the returned joints, and
the naive 6-D path following (plan.following.to_joint_trajectory), which needs joint speeds
far above the limits on the same path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from deltagen import SerialRobot
from deltagen.inputs import InputError
from deltagen.plan import singular_path as sp
from deltagen.plan.cartesian import PathBuilder
from deltagen.plan.following import Task, solve_ik, to_joint_trajectory
from deltagen.reference import serial as reference

POSE = Task("xyz", orientation=True)
DT = 0.005
# The robot files carry no speed limits (robots/ur5.urdf has <limit velocity="3.15"/> for
# joints 1-3 and 3.2 rad/s for 4-6, read but not kept); the planner takes them as
# arguments. Here limits low enough that the 1 s lines must be slowed down.
QD_MAX = np.array([0.5, 0.5, 0.5, 0.6, 0.6, 0.6])
QDD_MAX = 4.0


def _line_through(arm, q_mid, direction, half=0.15, offset=0.0):
    """A straight line of 1 s with the orientation of fk(q_mid) held, through the TCP of
    q_mid (moved by ``offset`` m across the line), and the start joints on q_mid's branch
    (reached by continuation from a sample next to the middle)."""
    T = arm.fk(np.asarray(q_mid, dtype=float))
    R, pm = T[:3, :3], T[:3, 3]
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    side = np.cross(d, [0.0, 0.0, 1.0])
    pm = pm + offset * side / np.linalg.norm(side)
    p0, p1 = pm - half * d, pm + half * d
    near = pm + 0.03 * (p0 - pm)
    g = np.array(q_mid, dtype=float)
    g[4] = 0.05
    g = solve_ik(arm, POSE, near, R, np.zeros(0), g)[0]
    back = PathBuilder(near, R=R).line(p0, 1.0).build()
    q0 = to_joint_trajectory(arm, back, POSE, g, dt=0.01, limits="ignore").q[-1]
    return PathBuilder(p0, R=R).line(p1, 1.0, label="through the wrist").build(), q0, p0, p1, R


def _puma_direction(arm, q_mid):
    """Across the forearm (axis 4), so that the wrist centre's motion turns axis 4."""
    _, w = reference.joint_axes(arm.description, np.asarray(q_mid, dtype=float)[None])
    return np.cross(w[0, 3], [0.3, 0.2, 1.0])


PUMA_MID = [0.2, 0.7, -2.9, 0.4, 0.0, -0.3]  # q5 = 0: wrist singular
UR5_MID = [0.3, -1.2, 1.6, -0.8, 0.0, 0.4]


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560")


@pytest.fixture(scope="module")
def ur5():
    return SerialRobot.load("ur5")


@pytest.fixture(scope="module")
def puma_ref():
    return SerialRobot.load("puma560", backend="reference")


@pytest.fixture(scope="module")
def ur5_ref():
    return SerialRobot.load("ur5", backend="reference")


@pytest.fixture(scope="module")
def puma_line(puma):
    return _line_through(puma, PUMA_MID, _puma_direction(puma, PUMA_MID))


@pytest.fixture(scope="module")
def puma_near(puma):
    """3 mm beside the singular pose: the naive wrist has to turn fast."""
    return _line_through(puma, PUMA_MID, _puma_direction(puma, PUMA_MID), offset=0.003)


@pytest.fixture(scope="module")
def ur5_line(ur5):
    T = ur5.fk(np.array(UR5_MID))
    # around the base axis: the UR's axes 2, 3, 4 turn with q1, axis 6 keeps its direction
    d = np.cross([0.0, 0.0, 1.0], T[:3, 3]) + [0.0, 0.0, 0.3 * np.linalg.norm(T[:3, 3])]
    return _line_through(ur5, UR5_MID, d)


def test_the_chosen_poses_are_wrist_singular(puma, ur5):
    """The construction's premise, from the reference's joint axes: w4 parallel to w6."""
    for arm, q in ((puma, PUMA_MID), (ur5, UR5_MID)):
        _, w = reference.joint_axes(arm.description, np.array(q)[None])
        assert np.linalg.norm(np.cross(w[0, 3], w[0, 5])) < 1e-12
        assert np.linalg.svd(arm.jacobian(np.array(q)), compute_uv=False)[-1] < 1e-12


# ------------------------------------------------------------------ independent evidence


def _path_at(t, duration, p0, p1):
    """The straight line with the rest-to-rest quintic, written out (trajectory docstring)."""
    tau = np.clip(t / duration, 0.0, 1.0)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    return p0 + s[:, None] * (p1 - p0)


def _angle(R, Rq):
    """Angle of R^T Rq per sample, by the trace (arccos), near 0 by the skew part."""
    M = np.einsum("ji,njk->nik", R, Rq)
    c = (np.trace(M, axis1=1, axis2=2) - 1.0) / 2.0
    s = 0.5 * np.linalg.norm(
        np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], 1),
        axis=1,
    )
    return np.arctan2(s, c)


def _central(t, q):
    return (q[2:] - q[:-2]) / (t[2:, None] - t[:-2, None])


def _check_motion(res, ref_arm, p0, p1, R, qd_max, qdd_max):
    T = ref_arm.fk(res.q)  # numpy reference: not the compiled core the planner used
    duration = res.trajectory.duration
    p = _path_at(res.t, duration, p0, p1)
    pos = np.linalg.norm(T[:, :3, 3] - p, axis=1)
    assert pos.max() < 1e-9  # the TCP on the path, in every mode
    ang = _angle(R, T[:, :3, :3])
    np.testing.assert_allclose(res.orientation_deviation, ang, atol=1e-9)
    # the reported speeds and accelerations within the limits ...
    assert np.all(np.abs(res.qd) <= qd_max * (1 + 1e-12))
    assert np.all(np.abs(res.qdd) <= qdd_max * (1 + 1e-12))
    # ... and the joints' own speeds (central differences) within them to O(h^2): h^2 / 6
    # times the jerk, which jumps where a region's quintics start and end
    qd_fd = _central(res.t, res.q)
    assert np.all(np.abs(qd_fd) <= qd_max * 1.02)
    np.testing.assert_allclose(qd_fd, res.qd[1:-1], atol=1e-2)
    assert np.max(np.abs(np.diff(res.q, axis=0))) < 0.05  # no jumps anywhere
    return pos, ang


# ------------------------------------------------------------------ the default: stop


@pytest.mark.parametrize("which", ["puma", "ur5"])
def test_default_stops_and_names_the_singularity(which, request):
    arm = request.getfixturevalue(which)
    traj, q0, *_ = request.getfixturevalue(f"{which}_line")
    with pytest.raises(sp.SingularPathError) as info:
        arm.follow_path(traj, q0, dt=DT)
    msg = str(info.value)
    assert "wrist singularity" in msg and "axes 4, 6" in msg
    assert "segment 0 ('through the wrist')" in msg
    region = info.value.region
    assert region.kind == "wrist" and region.axes == (4, 6)
    # the singular pose is the middle of the line: s = 1/2 at t = 1/2 of the quintic
    assert abs(region.t_closest - 0.5) <= DT
    assert region.t_entry < 0.5 < region.t_exit
    assert region.sigma_ratio_min < 1e-10
    assert info.value.rows.size > 0


def test_naive_following_needs_speeds_far_above_the_limits(puma, puma_near):
    """Why the remedy: the 6-D path solution turns the wrist about half a revolution within
    the region (q4 and q6 over 10 rad/s on a 1 s line)."""
    traj, q0, *_ = puma_near
    jt = to_joint_trajectory(puma, traj, POSE, q0, dt=DT, max_step=10.0, limits="ignore")
    assert np.abs(jt.qd[:, 3]).max() > 10 * QD_MAX[3]
    assert np.abs(jt.qd[:, 5]).max() > 10 * QD_MAX[5]


# ------------------------------------------------------------------ SingArea/Wrist


@pytest.mark.parametrize(
    "which, ref, case",
    [
        ("puma", "puma_ref", "puma_line"),
        ("puma", "puma_ref", "puma_near"),
        ("ur5", "ur5_ref", "ur5_line"),
    ],
)
def test_wrist_remedy(which, ref, case, request):
    arm, ref_arm = request.getfixturevalue(which), request.getfixturevalue(ref)
    traj, q0, p0, p1, R = request.getfixturevalue(case)
    res = arm.follow_path(traj, q0, remedy="wrist", qd_max=QD_MAX, qdd_max=QDD_MAX, dt=DT)
    pos, ang = _check_motion(res, ref_arm, p0, p1, R, QD_MAX, QDD_MAX)
    (region,) = res.regions
    assert region.kind == "wrist" and region.remedy == "wrist"
    inside = (res.t >= region.t_start) & (res.t <= region.t_end)
    assert np.array_equal(
        res.mode == sp.WRIST_PTP, inside & (res.t > region.t_start) & (res.t < region.t_end)
    )
    # the deviation is reported where it happens, and nowhere else
    assert region.max_orientation_deviation == pytest.approx(ang[inside].max(), abs=1e-9)
    assert res.report.max_orientation_deviation == pytest.approx(ang.max(), abs=1e-9)
    assert ang[~inside].max() < 1e-9
    assert region.max_orientation_deviation < math.radians(2.0)
    assert region.max_position_deviation < 1e-9
    # the wrist crossed without half a revolution (exit branch nearest the entry)
    q_in = res.q[inside]
    assert np.ptp(q_in[:, 3]) < 1.0 and np.ptp(q_in[:, 5]) < 1.0
    # q5 changes sign across the region: the wrist passes through the aligned pose
    assert q_in[0, 4] * q_in[-1, 4] < 0
    # slowed so that some limit binds
    rep = res.report
    assert rep.time_scale > 1.0
    binding = max(np.max(rep.peak_qd / QD_MAX), np.max(rep.peak_qdd / QDD_MAX))
    assert binding == pytest.approx(1.0, abs=1e-9)
    assert res.trajectory.duration == pytest.approx(rep.time_scale * traj.duration)


def test_wrist_joints_are_the_quintic_between_entry_and_exit(puma, puma_near):
    """Inside the region joints 4-6 follow a polynomial of degree 5 in time (a 6th
    difference vanishes); at the entry and exit position and speed are continuous."""
    traj, q0, *_ = puma_near
    res = puma.follow_path(traj, q0, remedy="wrist", dt=DT)
    (region,) = res.regions
    sel = (res.t >= region.t_entry - 1e-12) & (res.t <= region.t_exit + 1e-12)
    w = res.q[sel][:, 3:]
    d6 = np.diff(w, n=6, axis=0)
    assert np.abs(d6).max() < 1e-9
    assert res.report.time_scale == 1.0  # no limits given


def test_quintic_hermite_end_conditions():
    T = 0.7
    ends = [np.array([0.3, -1.0]), np.array([2.0, 0.5]), np.array([-4.0, 1.0])]
    ends1 = [np.array([1.1, 0.2]), np.array([-0.5, 0.0]), np.array([3.0, -2.0])]
    x, xd, xdd = sp.quintic_hermite(T, *ends, *ends1, np.array([0.0, T]))
    for got, want in zip((x, xd, xdd), zip(ends, ends1)):
        np.testing.assert_allclose(got[0], want[0], atol=1e-12)
        np.testing.assert_allclose(got[1], want[1], atol=1e-12)
    # derivatives by central differences
    t = np.linspace(0.1, 0.6, 11)
    h = 1e-5
    xp = sp.quintic_hermite(T, *ends, *ends1, t + h)[0]
    xm = sp.quintic_hermite(T, *ends, *ends1, t - h)[0]
    x0, xd0, xdd0 = sp.quintic_hermite(T, *ends, *ends1, t)
    np.testing.assert_allclose((xp - xm) / (2 * h), xd0, atol=1e-7)
    np.testing.assert_allclose((xp - 2 * x0 + xm) / h**2, xdd0, atol=1e-3)


# ------------------------------------------------------------------ freeze


@pytest.mark.parametrize(
    "which, ref, case, axis",
    [
        ("puma", "puma_ref", "puma_near", 4),
        ("puma", "puma_ref", "puma_line", 6),
        ("ur5", "ur5_ref", "ur5_line", 4),
    ],
)
def test_freeze_remedy(which, ref, case, axis, request):
    arm, ref_arm = request.getfixturevalue(which), request.getfixturevalue(ref)
    traj, q0, p0, p1, R = request.getfixturevalue(case)
    res = arm.follow_path(
        traj, q0, remedy="freeze", freeze_axis=axis, qd_max=QD_MAX, qdd_max=QDD_MAX, dt=DT
    )
    pos, ang = _check_motion(res, ref_arm, p0, p1, R, QD_MAX, QDD_MAX)
    (region,) = res.regions
    assert region.frozen_axis == axis
    core = (res.t >= region.t_entry - 1e-12) & (res.t <= region.t_exit + 1e-12)
    frozen = res.q[core, axis - 1]
    assert np.ptp(frozen) == 0.0  # held, exactly
    partner = 6 if axis == 4 else 4
    assert np.ptp(res.q[core, partner - 1]) > 1e-3  # the partner takes the motion
    span = (res.t >= region.t_start) & (res.t <= region.t_end)
    assert region.t_start < region.t_entry and region.t_end > region.t_exit  # the ramps
    assert region.max_orientation_deviation == pytest.approx(ang[span].max(), abs=1e-9)
    assert ang[~span].max() < 1e-9
    assert region.max_orientation_deviation < math.radians(3.0)


# ------------------------------------------------------------------ away from singularities


def test_line_away_from_singularities(puma, puma_ref):
    q_mid = np.array([0.2, 0.7, -2.9, 0.4, 0.9, -0.3])  # q5 = 0.9: far from the wrist case
    T = puma.fk(q_mid)
    R, pm = T[:3, :3], T[:3, 3]
    d = np.array([0.05, 0.1, -0.05])
    traj = PathBuilder(pm - d, R=R).line(pm + d, 1.0).build()
    q0 = solve_ik(puma, POSE, pm - d, R, np.zeros(0), q_mid)[0]
    for remedy in sp.REMEDIES:
        res = puma.follow_path(traj, q0, remedy=remedy, dt=DT)
        assert res.regions == [] and np.all(res.mode == sp.PATH)
        Tq = puma_ref.fk(res.q)
        assert (
            np.linalg.norm(Tq[:, :3, 3] - _path_at(res.t, 1.0, pm - d, pm + d), axis=1).max() < 1e-9
        )
        assert _angle(R, Tq[:, :3, :3]).max() < 1e-9
        assert res.report.time_scale == 1.0


# ------------------------------------------------------------------ kinds and bad input


def _det(arm, q):
    return float(np.linalg.det(arm.jacobian(np.asarray(q, dtype=float))))


def test_classify_shoulder_and_elbow(puma):
    """Roots of det J (its sign changes; found without the planner) away from q5 = 0 are
    named shoulder or elbow by the axes."""
    base = np.array([0.3, 0.6, -2.5, 0.4, 0.8, 0.1])

    def with_(i, v):
        q = base.copy()
        q[i] = v
        return q

    # elbow: the wrist centre in the plane of axes 2 and 3, d4 cos q3 + a3 sin q3 = 0 for
    # this DH table (a3 = 0.0203, d4 = 0.4318), i.e. q3 = -atan2(d4, a3)
    q3 = brentq(lambda v: _det(puma, with_(2, v)), -2.0, -1.2, xtol=1e-14)
    assert abs(q3 + math.atan2(0.4318, 0.0203)) < 1e-9
    kind, _ = sp._classify(puma, with_(2, q3))
    assert kind == "elbow"
    # shoulder: scan q2 for a sign change of det J
    grid = np.linspace(-0.7, 3.9, 93)
    dets = [_det(puma, with_(1, v)) for v in grid]
    i = next(k for k in range(len(grid) - 1) if dets[k] * dets[k + 1] < 0)
    q2 = brentq(lambda v: _det(puma, with_(1, v)), grid[i], grid[i + 1], xtol=1e-14)
    kind, _ = sp._classify(puma, with_(1, q2))
    assert kind == "shoulder"
    assert sp._classify(puma, with_(4, 0.0))[0] == "wrist"


def test_wrist_remedies_refuse_other_kinds(puma, puma_line, monkeypatch):
    traj, q0, *_ = puma_line
    monkeypatch.setattr(sp, "_classify", lambda robot, q: ("elbow", (2, 3)))
    for remedy in ("wrist", "freeze"):
        with pytest.raises(
            sp.SingularPathError, match="elbow singularity.*wrist singularities only"
        ):
            puma.follow_path(traj, q0, remedy=remedy, dt=DT)


@pytest.mark.parametrize(
    "options, match",
    [
        ({"remedy": "ptp"}, "remedy must be one of"),
        ({"qd_max": -1.0}, "qd_max must be"),
        ({"qdd_max": [1.0, 2.0]}, "qdd_max must be"),
        ({"threshold": 0.0}, "threshold"),
        ({"freeze_axis": 5}, "freeze_axis must be 4 or 6"),
        ({"limits": "maybe"}, "limits must be"),
        ({"ramp": -0.1}, "ramp must be"),
        ({"ramp": float("nan")}, "ramp must be"),
        ({"max_step": 0}, "max_step must be"),
        ({"dt": 0.0}, "time step must be positive"),
    ],
)
def test_bad_options(puma, puma_line, options, match):
    traj, q0, *_ = puma_line
    with pytest.raises(InputError, match=match):
        puma.follow_path(traj, q0, **options)


def test_bad_arm_and_path(puma, puma_line):
    traj, q0, p0, p1, _ = puma_line
    with pytest.raises(InputError, match="needs an orientation"):
        puma.follow_path(PathBuilder(p0).line(p1, 1.0).build(), q0)
    with pytest.raises(InputError, match="six-axis arms"):
        SerialRobot.load("lecture_scara").follow_path(traj, [0.1, 0.2])
    with pytest.raises(InputError, match="q0"):
        puma.follow_path(traj, [0.0] * 5)


def test_a_path_that_starts_or_ends_in_a_singular_region(puma, puma_line):
    """Nothing to enter from or exit to: a clear error whatever the remedy."""
    q_mid = np.array(PUMA_MID)
    T = puma.fk(q_mid)
    R, pm = T[:3, :3], T[:3, 3]
    d = _puma_direction(puma, PUMA_MID)
    away = PathBuilder(pm, R=R).line(pm + 0.1 * d / np.linalg.norm(d), 1.0).build()
    with pytest.raises(sp.SingularPathError, match="starts in a singular region"):
        puma.follow_path(away, q_mid, remedy="wrist", dt=DT)
    _, q0, p0, p1, _ = puma_line
    to_middle = PathBuilder(p0, R=R).line((p0 + p1) / 2, 1.0).build()  # ends at q5 = 0
    with pytest.raises(sp.SingularPathError, match="ends in a singular region"):
        puma.follow_path(to_middle, q0, remedy="wrist", dt=DT)


def test_follow_is_follow_path_with_the_design_names(puma, puma_near):
    """SerialRobot.follow(path, singularity="stop" | "joint" | "freeze"): the same planner;
    q0 None starts from the arm's ik at the start pose."""
    traj, q0, *_ = puma_near
    a = puma.follow(traj, q0, singularity="joint", dt=DT)
    b = puma.follow_path(traj, q0, remedy="wrist", dt=DT)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.report.remedy == "wrist"
    with pytest.raises(sp.SingularPathError, match="wrist singularity"):
        puma.follow(traj, dt=DT)
    start = puma.ik(puma.fk(q0))
    c = puma.follow(traj, singularity="freeze", dt=DT)
    np.testing.assert_allclose(c.q[0], start, atol=1e-9)


@pytest.mark.parametrize("remedy", ["wrist", "freeze"])
def test_there_and_back_two_regions(puma, puma_ref, puma_near, remedy):
    """Past the wrist and back on a second segment: two regions, each named by its segment,
    each passed; the TCP on both lines."""
    _, q0, p0, p1, R = puma_near
    traj = PathBuilder(p0, R=R).line(p1, 1.0, label="there").line(p0, 1.0, label="back").build()
    res = puma.follow_path(traj, q0, remedy=remedy, qd_max=QD_MAX, qdd_max=QDD_MAX, dt=DT)
    assert [(r.segment, r.segment_label, r.kind) for r in res.regions] == [
        (0, "there", "wrist"),
        (1, "back", "wrist"),
    ]
    scale = res.report.time_scale
    first = _path_at(res.t, scale, p0, p1)
    second = _path_at(res.t - scale, scale, p1, p0)
    p = np.where((res.t <= scale)[:, None], first, second)
    Tq = puma_ref.fk(res.q)
    assert np.linalg.norm(Tq[:, :3, 3] - p, axis=1).max() < 1e-9
    np.testing.assert_allclose(res.orientation_deviation, _angle(R, Tq[:, :3, :3]), atol=1e-9)
    assert np.all(np.abs(res.qd) <= QD_MAX * (1 + 1e-12))
    assert np.max(np.abs(np.diff(res.q, axis=0))) < 0.05
    # the arm comes back to where it started (same branch, no wrist turn left over)
    np.testing.assert_allclose(res.q[-1], res.q[0], atol=1e-9)
