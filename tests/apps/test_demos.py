"""`deltagen demo`: the lecture's Matlab table (lecture slide 111, footed "Folie 111")
reproduced digit for digit, and the Miskolc paper's pick-and-place with its figures.

The independent evidence for the lecture demo is the table AS PRINTED on the slide, typed
in below; the algorithm is the slides' (106-110), never tuned to the numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen import cli
from deltagen.api.serial import SerialRobot
from deltagen.apps import demos

# Slide "Folie 111", "Ergebnisse einer Naeherungsrechnung mit Matlab", columns
# X-Soll, X-Ist, Y-Soll, Y-Ist, as printed (L1 = 4, L2 = 3, q10 = 10 deg, q20 = 30 deg,
# target x = 4.0, y = 3.0, 10 equal sub-steps along each axis).
SLIDE_TABLE = """\
6.2374 6.2374 2.6230 2.6230
6.0136 5.9806 2.6607 2.6384
5.7899 5.7801 2.6984 2.6887
5.5662 5.5571 2.7361 2.7255
5.3424 5.3361 2.7738 2.7643
5.1187 5.1140 2.8115 2.8025
4.8949 4.8915 2.8492 2.8405
4.6712 4.6687 2.8869 2.8784
4.4475 4.4458 2.9246 2.9162
4.2237 4.2227 2.9623 2.9539
4.0000 3.9995 3.0000 2.9917"""
# ... and the last printed row, the target reached (one further step at the target)
SLIDE_LAST_ROW = "4.0000 4.0000 3.0000 3.0000"
# the start position printed under the table: "Startposition: x = 6,2374, y = 2,6230"
SLIDE_START = ("6.2374", "2.6230")


def _rows(text):
    return [line.split() for line in text.splitlines()]


@pytest.fixture(scope="module")
def table():
    return demos.lecture_table()


def test_slide_table_reproduced_digit_for_digit(table):
    ours = [[f"{v:.4f}" for v in (s[0], i[0], s[1], i[1])] for s, i in zip(table.soll, table.ist)]
    assert ours == _rows(SLIDE_TABLE)
    assert [f"{v:.4f}" for v in table.soll[0]] == list(SLIDE_START)


def test_slide_table_with_the_reference_backend():
    """The numpy reference kinematics give the same printed table."""
    from deltagen.plan.following import Task, jacobian_path_following

    arm = SerialRobot.load("lecture_scara", backend="reference")
    t = jacobian_path_following(
        arm, np.radians([10.0, 30.0]), [4.0, 3.0], steps=10, task=Task("xy")
    )
    ours = [[f"{v:.4f}" for v in (s[0], i[0], s[1], i[1])] for s, i in zip(t.soll, t.ist)]
    assert ours == _rows(SLIDE_TABLE)


def test_slide_last_row_is_one_further_step(table):
    first = table.converge_ist[0]
    assert " ".join(f"{v:.4f}" for v in (4.0, first[0], 3.0, first[1])) == SLIDE_LAST_ROW
    assert table.final_error < 1e-12
    # the target (4, 3) is q = (0, 90 deg): 4 cos 0 + 3 cos 90 = 4, 4 sin 0 + 3 sin 90 = 3
    np.testing.assert_allclose(table.converge_q[-1], [0.0, math.pi / 2], atol=1e-12)


def test_slide_jacobian_and_inverse_formulas():
    """Slide 108: J of the planar SCARA and JD = L1 L2 sin q2; slide 110: the (homogeneous)
    inverse 1/JD [[L2 c12, L2 s12], [-L1 c1 - L2 c12, -L1 s1 - L2 s12]] -- the geometric
    Jacobian's x, y rows are that matrix."""
    arm = SerialRobot.load("lecture_scara")
    L1, L2 = 4.0, 3.0
    for q1, q2 in np.radians([[10, 30], [-40, 75], [120, -20]]):
        s1, c1, s12, c12 = math.sin(q1), math.cos(q1), math.sin(q1 + q2), math.cos(q1 + q2)
        J = np.array([[-L1 * s1 - L2 * s12, -L2 * s12], [L1 * c1 + L2 * c12, L2 * c12]])
        np.testing.assert_allclose(arm.jacobian([q1, q2])[:2], J, atol=1e-14)
        JD = L1 * L2 * math.sin(q2)
        assert np.linalg.det(J) == pytest.approx(JD, rel=1e-12)
        Jinv = np.array([[L2 * c12, L2 * s12], [-L1 * c1 - L2 * c12, -L1 * s1 - L2 * s12]]) / JD
        np.testing.assert_allclose(Jinv @ J, np.eye(2), atol=1e-12)


def test_demo_lecture_prints_the_slide_layout(capsys):
    assert cli.main(["demo", "lecture-scara"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    header = lines.index(
        next(line for line in lines if line.split() == ["X-Soll", "X-Ist", "Y-Soll", "Y-Ist"])
    )
    assert [line.split() for line in lines[header + 1 : header + 12]] == _rows(SLIDE_TABLE)
    assert lines[header + 14].split()[:4] == SLIDE_LAST_ROW.split()
    assert "Naeherungsrechnung fuer planaren SCARA" in out
    assert "final error" in out


def test_demo_lecture_plot(tmp_path, capsys):
    assert cli.main(["demo", "lecture-scara", "--out", str(tmp_path)]) == 0
    png = tmp_path / "lecture_scara.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_unknown_name_is_rejected(capsys):
    assert cli.main(["demo", "no-such-demo"]) == 2  # a usage error: exit status 2
    assert "invalid choice" in capsys.readouterr().err


# ------------------------------------------------------------------ Miskolc


@pytest.fixture(scope="module")
def miskolc_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("miskolc")
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli.main(["demo", "miskolc-pick-and-place", "--out", str(out)])
    return code, out, buf.getvalue()


def test_demo_miskolc_exits_0_and_writes_pngs(miskolc_run):
    code, out, text = miskolc_run
    assert code == 0
    for name in (
        "miskolc_joint_angles.png",
        "miskolc_arm_poses.png",
        "miskolc_rates.png",
        "miskolc_torques.png",
    ):
        data = (out / name).read_bytes()
        assert len(data) > 20_000 and data[:8] == b"\x89PNG\r\n\x1a\n", name
    csv = np.loadtxt(out / "miskolc_joint_trajectory.csv", delimiter=",", skiprows=1)
    assert csv.shape[1] == 1 + 5 * 4 + 4 + 4 and csv.shape[0] > 1000
    assert "elbow up" in text and "O(h²)" in text


def test_demo_miskolc_torques_are_the_arms_inverse_dynamics(miskolc_run):
    """The CSV's tau1..tau4 are the inverse dynamics of the CSV's own q, qd, qdd (the numpy
    reference backend, a second implementation), qd and qdd are the time derivatives of q
    and qd (central differences), and the printed peak / RMS are those of the columns."""
    code, out, text = miskolc_run
    path = out / "miskolc_joint_trajectory.csv"
    names = path.read_text().splitlines()[0].split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    col = {name: data[:, k] for k, name in enumerate(names)}

    def block(prefix):
        return np.column_stack([col[f"{prefix}{i}"] for i in range(1, 5)])

    t, q, qd, qdd, tau = col["t"], block("q"), block("qd"), block("qdd"), block("tau")
    arm = SerialRobot.load("miskolc_rrrr").with_backend("reference")
    want = arm.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(tau, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    assert np.abs(tau[:, 1]).max() > 5.0  # the shoulder carries the arm: torques not zero
    # the rates fed to the dynamics are those of q (second-order central differences)
    h = np.diff(t)
    assert np.allclose(h, h[0], rtol=1e-6)
    qd_fd = (q[2:] - q[:-2]) / (2 * h[0])
    qdd_fd = (qd[2:] - qd[:-2]) / (2 * h[0])
    # not across a segment joint, where the quintic's jerk jumps (O(h) there)
    starts = demos.miskolc_trajectory(arm).starts
    smooth = np.abs(t[1:-1, None] - np.asarray(starts)[None, :]).min(axis=1) > 1.5 * h[0]
    assert smooth.sum() > 0.9 * smooth.size
    assert np.abs(qd_fd - qd[1:-1])[smooth].max() < 1e-3 * np.abs(qd).max()
    assert np.abs(qdd_fd - qdd[1:-1])[smooth].max() < 2e-3 * np.abs(qdd).max()
    # printed peak and RMS per joint (3 significant digits)
    line = next(line for line in text.splitlines() if "joint torques" in line)
    for i in range(4):
        peak = float(line.split(f"tau{i + 1} peak ")[1].split()[0])
        rms = float(line.split(f"tau{i + 1} peak ")[1].split("RMS ")[1].split()[0].rstrip(","))
        assert peak == pytest.approx(np.abs(tau[:, i]).max(), rel=5e-3, abs=1e-12)
        assert rms == pytest.approx(np.sqrt((tau[:, i] ** 2).mean()), rel=5e-3, abs=1e-12)


def test_miskolc_inertials_hold_the_arm_by_hand():
    """The chosen aluminium links (robots/miskolc_rrrr.toml): at qz, both arms horizontal,
    the static moments by hand: joint 2 holds m2 a2/2 + m3 (a2 + s4/2) + m4 (a2 + s4),
    joint 3 holds m3 s4/2 + m4 s4 (times g)."""
    arm = SerialRobot.load("miskolc_rrrr")
    g = 9.81
    m2, m3, m4, a2, s4 = 1.14, 0.95, 0.40, 0.60, 0.50
    tau = arm.inverse_dynamics(np.zeros(4), np.zeros(4), np.zeros(4))
    want = [
        0.0,
        g * (m2 * a2 / 2 + m3 * (a2 + s4 / 2) + m4 * (a2 + s4)),
        g * (m3 * s4 / 2 + m4 * s4),
        0.0,
    ]
    np.testing.assert_allclose(tau, want, atol=1e-9)


@pytest.fixture(scope="module")
def miskolc_jt():
    return demos.miskolc_joint_trajectory()


def test_miskolc_path_elbow_up_within_limits_no_jumps(miskolc_jt):
    jt = miskolc_jt
    arm = jt.robot
    assert np.all(jt.q[:, 2] < 0)  # elbow up (q3 <= 0) at every sample, never a flip
    assert np.all(arm.within_limits(jt.q))
    # joint steps bounded by the peak joint speed times h (smooth, no jumps)
    assert jt.max_joint_step <= np.abs(jt.qd).max() * jt.dt * 1.01
    assert jt.task_error.max() < 1e-12
    # starts and ends in the ready pose; the gripper visits the stations
    np.testing.assert_allclose(jt.q[0], arm.configuration("ready"), atol=1e-12)
    np.testing.assert_allclose(jt.q[-1], arm.configuration("ready"), atol=1e-9)
    p = arm.fk(jt.q)[:, :3, 3]
    for station in demos.STATIONS.values():
        assert np.min(np.linalg.norm(p - station, axis=1)) < 1e-9
    # the prescribed gripper roll q4 reaches 90 deg at the machine
    assert np.degrees(jt.q[:, 3].max()) == pytest.approx(90.0, abs=1e-9)


def test_miskolc_gripper_z_moves_are_vertical(miskolc_jt):
    """The grasp and release are pure z motions (the paper: 'z tengelyiranyu mozgassal')."""
    jt = miskolc_jt
    for i, seg in enumerate(jt.trajectory.segments):
        if seg.label.startswith(("down", "up")):
            sel = jt.cartesian.segment == i
            p = jt.robot.fk(jt.q[sel])[:, :3, 3]
            np.testing.assert_allclose(
                p[:, :2], np.broadcast_to(p[0, :2], p[:, :2].shape), atol=1e-12
            )
            assert np.ptp(p[:, 2]) > 0.2  # 0.25 m down or up


def test_miskolc_exact_vs_numerical_rates_second_order(miskolc_jt):
    jt = miskolc_jt
    half = demos.miskolc_joint_trajectory(dt=jt.dt / 2)
    e1, e2 = jt.rate_errors(), half.rate_errors()
    assert 3.6 < e1["qd"] / e2["qd"] < 4.4
    assert 3.6 < e1["qdd"] / e2["qdd"] < 4.4
    assert e1["qd"] < 1e-3 * e1["qd_peak"] and e1["qdd"] < 2e-3 * e1["qdd_peak"]


def test_miskolc_ik_is_the_papers_elbow_up_solution(miskolc_jt):
    """At every sample the per-sample Newton IK equals the paper's closed form, eqs. (4)-(9)
    with the upper elbow Theta3 = atan2(-sqrt(1 - D^2), D), typed in here (s1 = 0.5,
    a2 = 0.6, s4 = 0.5 of robots/miskolc_rrrr.toml); q4 is the prescribed roll."""
    jt = miskolc_jt
    s1, a2, s4 = 0.50, 0.60, 0.50
    x, y, z = jt.cartesian.p.T
    th1 = np.arctan2(y, x)  # (4)
    r, s = np.hypot(x, y), z - s1
    D = (r**2 + s**2 - a2**2 - s4**2) / (2 * a2 * s4)  # (6)
    th3 = np.arctan2(-np.sqrt(1 - D**2), D)  # (7), upper elbow
    th2 = np.arctan2(s, r) - np.arctan2(s4 * np.sin(th3), a2 + s4 * np.cos(th3))  # (9)
    np.testing.assert_allclose(jt.q[:, :3], np.column_stack([th1, th2, th3]), atol=1e-9)
    np.testing.assert_allclose(jt.q[:, 3], jt.cartesian.qj[:, 0], atol=1e-13)


def test_demo_singular_path_writes_the_speed_plot(tmp_path, capsys):
    """`deltagen demo singular-path`: the default stops, the naive following needs wrist
    speeds far above the limit, SingArea/Wrist stays within it; a PNG is written."""
    assert cli.main(["demo", "singular-path", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "remedy='stop' (default): segment 0 ('past the wrist')" in out
    assert "wrist singularity" in out and "axes 4, 6" in out
    naive = out.split("followed as programmed: peak |qd| per joint ")[1].split(" rad/s")[0]
    assert max(float(v) for v in naive.split(", ")) > 10 * demos.SINGULAR_QD_MAX
    fixed = out.split("  peak |qd| per joint ")[1].split(" rad/s")[0]
    assert max(float(v) for v in fixed.split(", ")) <= demos.SINGULAR_QD_MAX
    png = tmp_path / "singular_path_speeds.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
