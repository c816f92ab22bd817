"""`deltagen demo NAME`: worked examples of the serial-arm trajectory tools.

* ``lecture-scara`` -- the numerical inverse of the lecture "Robotertechnik" (lecture
  slides 106-111; the Matlab table is on the slide footed "Folie 111", the one after the
  homogeneous J^-1 of "Folie 110"). Planar SCARA L1 = 4, L2 = 3, start q = (10 deg, 30 deg),
  i.e. P0 = (6.2374, 2.6230); target (4, 3); the straight line split along each axis into
  10 equal parts ("Strecken entlang der Achsen in 10 gleiche Teilabschnitte zerlegt");
  per sub-point ONE step ``Q = Q0 + J^-1(Q0) (P_soll - P0)`` with the inverse of the
  2x2 Jacobian of slide 108 at the current joints and P0 = f(Q0) the direct transformation
  of the current joints (slide 107: "nach jedem Schritt eine direkte Transformation").
  Printed like the slide (Matlab ``format short``: four decimals), then Newton steps at
  the target until it converges, and the final error. With ``--out`` also a PNG of the
  Soll/Ist path like the slide's plot.

* ``miskolc-pick-and-place`` -- the pick-and-place task of the Miskolc paper
  (section 5) on the RRRR elbow robot (robots/miskolc_rrrr.toml), elbow up throughout.
  The paper's figure 7 (the path) is missing from the text, so the stations are CHOSEN
  (see :data:`STATIONS`): from home (the ``ready`` configuration) to the in-feed conveyor,
  down and up in z to grasp (the paper: "egy z tengelyiranyu mozgassal megfog"), a
  horizontal arc about the base axis to the machine tool, a radial insertion, machining
  dwell, retraction, a straight line to the out-feed conveyor, down and up to release,
  and a circular arc in a tilted plane (three points) back home. The gripper roll q4 is
  prescribed (0 -> 90 deg on the way to the machine, back to 0 on the way to the out-feed
  conveyor); q1..q3 follow from the position by per-sample Newton IK.
  Writes into ``--out`` (default ``miskolc_pick_and_place``): joint angles over time (like
  the paper's figure 8), arm poses along the path (stick figures from ``robot.frames``,
  like figure 9), exact vs numerical joint velocities and accelerations, the joint torques
  over time (inverse dynamics with the robot file's chosen aluminium-link masses and
  inertias, exact q, qd, qdd; the paper's program computes joint torques from link masses
  too) and a CSV of all of it (tau1..tau4 [N m] among its columns).

* ``singular-path`` -- a path through a wrist singularity (lecture slides 112-114) on the
  Puma 560: a straight line of 0.3 m in 1 s with the tool orientation held, passing 3 mm
  beside the pose with q5 = 0 (axes 4 and 6 in line; :data:`SINGULAR_Q`). Followed as
  programmed (6-D path following, plan.following) the wrist turns half a revolution in
  a fraction of a second; with ``remedy="wrist"`` ("SingArea/Wrist") the wrist joints move by
  joint interpolation across the region, the TCP stays on the line, and the motion is
  slowed uniformly into the joint limits :data:`SINGULAR_QD_MAX`, :data:`SINGULAR_QDD_MAX`
  (chosen). Prints the planner's report and writes ``singular_path_speeds.png`` (joint
  speeds with and without the remedy) into ``--out`` (default ``singular_path``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from deltagen.apps.plotting import pyplot

NAMES = ("lecture-scara", "miskolc-pick-and-place", "singular-path")

# ------------------------------------------------------------------ lecture

#: Slide "Folie 111": start joints, target, number of sub-steps.
LECTURE_Q0_DEG = (10.0, 30.0)
LECTURE_TARGET = (4.0, 3.0)
LECTURE_STEPS = 10


def lecture_table():
    """The lecture's path following on the bundled lecture_scara (L1 = 4, L2 = 3)."""
    from deltagen.api.serial import SerialRobot
    from deltagen.plan.following import Task, jacobian_path_following

    arm = SerialRobot.load("lecture_scara")
    return jacobian_path_following(
        arm, np.radians(LECTURE_Q0_DEG), LECTURE_TARGET, steps=LECTURE_STEPS, task=Task("xy")
    )


def _z(value, digits) -> str:
    """value with ``digits`` decimals, without a "-0.0"."""
    return f"{round(float(value), digits) + 0.0:.{digits}f}"


def format_row(values) -> str:
    """Matlab ``format short`` for numbers below 10: width 10, four decimals."""
    return "".join(f"{v:10.4f}" for v in values)


def lecture_lines(table=None) -> list[str]:
    table = lecture_table() if table is None else table
    x0, y0 = table.soll[0]
    out = [
        "Naeherungsrechnung fuer planaren SCARA",
        "(Linnemann, Robotertechnik, lecture slides 106-111; table of the slide 'Folie 111')",
        f"L1 = 4, L2 = 3, q10 = {LECTURE_Q0_DEG[0]:g}°, q20 = {LECTURE_Q0_DEG[1]:g}°",
        f"Startposition: x = {x0:.4f}, y = {y0:.4f}    "
        f"Gewaehlte Zielposition: x = {LECTURE_TARGET[0]:.1f}, y = {LECTURE_TARGET[1]:.1f}",
        f"Strecken entlang der Achsen in {LECTURE_STEPS} gleiche Teilabschnitte zerlegt;",
        "per Teilpunkt ein Schritt Q = Q0 + J^-1(Q0) (P_soll - f(Q0)), dann direkte Transformation",
        "",
        "".join(f"{h:>10}" for h in ("X-Soll", "X-Ist", "Y-Soll", "Y-Ist")),
    ]
    for soll, ist in zip(table.soll, table.ist):
        out.append(format_row((soll[0], ist[0], soll[1], ist[1])))
    out.append("")
    out.append("further Newton steps at the target, Q = Q0 + J^-1(Q0) (P_ziel - f(Q0)):")
    target = table.soll[-1]
    for ist in table.converge_ist:
        err = float(np.linalg.norm(ist - target))
        out.append(
            format_row((target[0], ist[0], target[1], ist[1])) + f"   |P_ist - P_ziel| = {err:.3g}"
        )
    q_end = table.converge_q[-1] if len(table.converge_q) else table.q[-1]
    err10 = float(np.linalg.norm(table.ist[-1] - target))
    out.append("")
    out.append(f"after the {LECTURE_STEPS} sub-steps: |P_ist - P_ziel| = {err10:.6g}")
    out.append(
        f"final error after {len(table.converge_ist)} further steps: |P_ist - P_ziel| = "
        f"{table.final_error:.3g}; q = ({_z(math.degrees(q_end[0]), 9)}°, "
        f"{_z(math.degrees(q_end[1]), 9)}°)"
    )
    return out


def _plot_lecture(table, path: Path) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 5.5), layout="constrained")
    ax.plot(table.soll[:, 0], table.soll[:, 1], "o-", color="tab:blue", ms=4, label="Soll")
    ax.plot(table.ist[:, 0], table.ist[:, 1], "s--", color="tab:red", ms=4, label="Ist")
    if len(table.converge_ist):
        ax.plot(
            table.converge_ist[:1, 0],
            table.converge_ist[:1, 1],
            "x",
            color="k",
            ms=8,
            label="1 further step",
        )
    ax.annotate("Start", table.soll[0], textcoords="offset points", xytext=(-10, 10))
    ax.annotate("Ziel", table.soll[-1], textcoords="offset points", xytext=(5, 5))
    ax.set_xlabel("x-Achse")
    ax.set_ylabel("y-Achse")
    ax.set_title(
        "Naeherungsrechnung fuer planaren SCARA (L1 = 4, L2 = 3, q0 = (10°, 30°), "
        "10 Teilabschnitte)",
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_lecture(out=None, stream=None) -> int:
    stream = sys.stdout if stream is None else stream
    table = lecture_table()
    for line in lecture_lines(table):
        print(line, file=stream)
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        path = _plot_lecture(table, folder / "lecture_scara.png")
        print(f"wrote {path}", file=stream)
    return 0


# ------------------------------------------------------------------ Miskolc paper


def _station(azimuth_deg, radius, z):
    a = math.radians(azimuth_deg)
    return np.array([radius * math.cos(a), radius * math.sin(a), z])


#: Chosen stations [m] (the paper's figure 7 is missing): azimuth about the base z axis,
#: horizontal distance from it, height. Reachable within the robot file's joint ranges
#: (elbow up, q3 >= -90 deg needs the gripper >= 0.78 m from the shoulder).
STATIONS = {
    "in-feed conveyor (above)": _station(60.0, 0.90, 0.60),
    "in-feed conveyor (grasp)": _station(60.0, 0.90, 0.35),
    "machine tool (above)": _station(0.0, 0.90, 0.60),
    "machine tool (inserted)": _station(0.0, 1.02, 0.60),
    "out-feed conveyor (above)": _station(-45.0, 0.90, 0.60),
    "out-feed conveyor (release)": _station(-45.0, 0.90, 0.35),
}
#: Sample time of the demo [s] and the finer one of the O(h^2) check.
DT = 0.005


def miskolc_trajectory(arm):
    """The pick-and-place path (segments with durations [s]) from the ready pose."""
    from deltagen.plan.cartesian import PathBuilder

    S = STATIONS
    home = arm.fk(arm.configuration("ready"))[:3, 3]
    b = PathBuilder(home, joints=[0.0], scaling="quintic")
    b.line(S["in-feed conveyor (above)"], 2.0, label="to in-feed")
    b.line(S["in-feed conveyor (grasp)"], 1.0, label="down (z)")
    b.dwell(0.5, label="grasp")
    b.line(S["in-feed conveyor (above)"], 1.0, label="up (z)")
    b.arc_about(
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        math.radians(-60.0),
        3.0,
        joints=[math.radians(90.0)],
        label="arc to machine",
    )
    b.line(S["machine tool (inserted)"], 1.0, label="insert")
    b.dwell(2.0, label="machining")
    b.line(S["machine tool (above)"], 1.0, label="retract")
    b.line(S["out-feed conveyor (above)"], 2.5, joints=[0.0], label="to out-feed")
    b.line(S["out-feed conveyor (release)"], 1.0, label="down (z)")
    b.dwell(0.5, label="release")
    b.line(S["out-feed conveyor (above)"], 1.0, label="up (z)")
    # back home on a circular arc in a tilted plane, through a raised via point
    via = 0.5 * (S["out-feed conveyor (above)"] + home) + np.array([0.0, 0.0, 0.12])
    b.arc(via, home, 2.5, label="arc home")
    return b.build()


def elbow_up(q):
    """The paper's elbow-up branch in the robot file's convention: q3 <= 0."""
    return np.asarray(q)[..., 2] <= 0.0


def miskolc_joint_trajectory(dt=DT, arm=None):
    from deltagen.api.serial import SerialRobot
    from deltagen.plan.following import Task, to_joint_trajectory

    arm = SerialRobot.load("miskolc_rrrr") if arm is None else arm
    traj = miskolc_trajectory(arm)
    return to_joint_trajectory(
        arm,
        traj,
        Task("xyz", joints=(3,)),
        arm.configuration("ready"),
        dt=dt,
        max_step=math.radians(2.0),
        branch=elbow_up,
    )


def _segment_marks(ax, traj, labels=True):
    for i, seg in enumerate(traj.segments):
        t0, t1 = traj.starts[i], traj.starts[i + 1]
        if i:
            ax.axvline(t0, color="0.75", lw=0.6, zorder=0)
        if seg.path.length == 0.0:
            ax.axvspan(t0, t1, color="0.93", zorder=-1)
        if labels:
            ax.text(
                0.5 * (t0 + t1),
                1.01,
                seg.label,
                transform=ax.get_xaxis_transform(),
                rotation=60,
                fontsize=7,
                ha="left",
                va="bottom",
            )


def _plot_joint_angles(jt, path):
    plt = pyplot()

    arm = jt.robot
    fig, ax = plt.subplots(figsize=(12, 6.2), layout="constrained")
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    for i in range(arm.n):
        ax.plot(jt.t, np.degrees(jt.q[:, i]), color=colors[i], lw=1.6, label=f"{i + 1}: q{i + 1}")
        lo, hi = np.degrees(arm.qlim[i])
        for v in (lo, hi):
            if -200 < v < 200:
                ax.axhline(v, color=colors[i], ls=":", lw=0.8)
    _segment_marks(ax, jt.trajectory)
    ax.set_xlim(jt.t[0], jt.t[-1])
    ax.set_xlabel("t [s]")
    ax.set_ylabel("joint angle [deg]")
    ax.set_title(
        "Miskolc RRRR robot, pick and place, elbow up: joint angles "
        "(cf. the paper's figure 8); dotted: joint limits of the robot file",
        pad=70,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower left", ncol=4)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


#: Short labels of the stations drawn in the pose figure.
_MARKS = {
    "in-feed conveyor (grasp)": "A: in-feed conveyor",
    "machine tool (inserted)": "M: machine tool",
    "out-feed conveyor (release)": "B: out-feed conveyor",
}


def _plot_arm_poses(jt, path, every=0.75):
    plt = pyplot()

    arm = jt.robot
    step = max(1, int(round(every / jt.dt)))
    idx = np.arange(0, jt.t.size, step)
    if idx[-1] != jt.t.size - 1:
        idx = np.r_[idx, jt.t.size - 1]
    F = arm.frames(jt.q[idx])  # (k, n + 2, 4, 4): base, after each joint, tool
    O = F[..., :3, 3]  # noqa: E741 - O_i, the frame origins
    p = jt.cartesian.p
    home = p[0]
    cmap = plt.get_cmap("viridis")
    colors = [cmap(j / max(1, len(idx) - 1)) for j in range(len(idx))]
    fig = plt.figure(figsize=(19, 7.5))
    gs = fig.add_gridspec(
        1,
        3,
        width_ratios=(1.3, 1.0, 1.0),
        left=0.01,
        right=0.98,
        bottom=0.08,
        top=0.88,
        wspace=0.18,
    )
    fig.suptitle(
        f"Miskolc RRRR robot, pick and place: arm poses every {every:g} s (colour: "
        f"time, dark = start), elbow up (cf. the paper's figure 9)",
        fontsize=13,
    )

    ax = fig.add_subplot(gs[:, 0], projection="3d")
    for j in range(len(idx)):
        ax.plot(O[j, :, 0], O[j, :, 1], O[j, :, 2], "-", color=colors[j], lw=1.3, alpha=0.85)
        ax.plot(O[j, 2, 0], O[j, 2, 1], O[j, 2, 2], "o", color=colors[j], ms=3)  # elbow
        ax.plot(O[j, -1, 0], O[j, -1, 1], O[j, -1, 2], "v", color=colors[j], ms=3)  # gripper
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color="k", lw=1.8, label="gripper path")
    for name, text in _MARKS.items():
        s = STATIONS[name]
        ax.scatter(*s, color="tab:red", s=30, depthshade=False)
        ax.text(
            s[0], s[1], s[2] - 0.09, text.split(":")[0], fontsize=10, color="tab:red", weight="bold"
        )
    ax.text(home[0], home[1], home[2] + 0.05, "home", fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]", labelpad=2)
    ax.set_xlim(-0.1, 1.1)
    ax.set_ylim(-0.8, 0.9)
    ax.set_zlim(0.0, 1.2)
    ax.set_box_aspect((1.2, 1.7, 1.2))
    ax.view_init(elev=24, azim=-35)
    ax.set_title("3D view (x, y, z [m])")
    ax.legend(loc="upper left", fontsize=8)

    ax2 = fig.add_subplot(gs[:, 1])
    for j in range(len(idx)):
        ax2.plot(O[j, :, 0], O[j, :, 1], "-", color=colors[j], lw=1.0, alpha=0.7)
    ax2.plot(p[:, 0], p[:, 1], color="k", lw=1.8, label="gripper path")
    ax2.plot(0, 0, "ks", ms=8)
    for name, text in _MARKS.items():
        s = STATIONS[name]
        ax2.plot(s[0], s[1], "o", color="tab:red")
        ax2.annotate(
            text, s[:2], textcoords="offset points", xytext=(8, -4), fontsize=9, color="tab:red"
        )
    ax2.annotate("home", home[:2], textcoords="offset points", xytext=(8, 6), fontsize=9)
    ax2.set_aspect("equal")
    ax2.set_xlim(-0.1, 1.45)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.grid(True, alpha=0.3)
    ax2.set_title("top view (x-y)")
    ax2.legend(loc="upper left", fontsize=8)

    # side view in the arm's own vertical plane: horizontal distance from the base axis
    ax3 = fig.add_subplot(gs[:, 2])
    rad = np.hypot(O[..., 0], O[..., 1])
    for j in range(len(idx)):
        ax3.plot(rad[j], O[j, :, 2], "-", color=colors[j], lw=1.2, alpha=0.8)
        ax3.plot(rad[j, 2], O[j, 2, 2], "o", color=colors[j], ms=3)
    ax3.plot(np.hypot(p[:, 0], p[:, 1]), p[:, 2], color="k", lw=1.8, label="gripper path")
    side = {}
    for name, text in _MARKS.items():
        s = STATIONS[name]
        key = (round(float(np.hypot(s[0], s[1])), 6), round(float(s[2]), 6))
        side[key] = side.get(key, []) + [text.split(":")[0]]
    for (r, z), letters in side.items():
        ax3.plot(r, z, "o", color="tab:red")
        ax3.annotate(
            ", ".join(letters),
            (r, z),
            textcoords="offset points",
            xytext=(6, -12),
            fontsize=9,
            color="tab:red",
            weight="bold",
        )
    ax3.set_aspect("equal")
    ax3.set_xlim(-0.1, 1.2)
    ax3.set_ylim(0.0, 1.25)
    ax3.set_xlabel("horizontal distance from the base axis sqrt(x² + y²) [m]")
    ax3.set_ylabel("z [m]")
    ax3.grid(True, alpha=0.3)
    ax3.set_title("side view in the arm plane: elbow up throughout")
    ax3.legend(loc="upper left", fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _plot_rates(jt, jt_half, path):
    plt = pyplot()

    from deltagen.plan.following import numerical_rates

    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    fig, axes = plt.subplots(2, 2, figsize=(15, 9), layout="constrained", sharex=True)
    qd_u, qdd_u = numerical_rates(jt.t, jt.q)  # whole signal, no breaks
    for col, (name, ex, num, ex2, num2, unsplit, unit) in enumerate(
        (
            ("velocity", jt.qd, jt.qd_num, jt_half.qd, jt_half.qd_num, qd_u, "rad/s"),
            ("acceleration", jt.qdd, jt.qdd_num, jt_half.qdd, jt_half.qdd_num, qdd_u, "rad/s²"),
        )
    ):
        ax = axes[0, col]
        for i in range(jt.q.shape[1]):
            ax.plot(jt.t, ex[:, i], color=colors[i], lw=1.4, label=f"q{i + 1} exact")
            ax.plot(
                jt.t[::8],
                num[::8, i],
                "o",
                color=colors[i],
                ms=2.5,
                mfc="none",
                label=f"q{i + 1} numerical",
            )
        _segment_marks(ax, jt.trajectory, labels=False)
        ax.set_ylabel(f"joint {name} [{unit}]")
        sym = "qd = J⁻¹ xd" if col == 0 else "qdd = J⁻¹ (xdd − J̇ qd)"
        ax.set_title(f"joint {name}: exact {sym} (lines), numerical (circles)")
        ax.legend(ncol=4, fontsize=7, loc="lower left")
        ax.grid(True, alpha=0.3)
        ax = axes[1, col]
        d = np.max(np.abs(ex - num), axis=1)
        d2 = np.max(np.abs(ex2 - num2), axis=1)
        du = np.max(np.abs(ex - unsplit), axis=1)
        tiny = 1e-16
        ax.semilogy(
            jt.t,
            np.maximum(du, tiny),
            color="0.7",
            lw=0.8,
            label=f"h = {jt.dt * 1e3:g} ms, whole signal (max {du.max():.2g})",
        )
        ax.semilogy(
            jt.t,
            np.maximum(d, tiny),
            color="tab:blue",
            lw=1.0,
            label=f"h = {jt.dt * 1e3:g} ms, per segment (max {d.max():.2g})",
        )
        ax.semilogy(
            jt_half.t,
            np.maximum(d2, tiny),
            color="tab:red",
            lw=1.0,
            label=f"h = {jt_half.dt * 1e3:g} ms, per segment (max {d2.max():.2g}; "
            f"ratio {d.max() / d2.max():.2f}, O(h²): 4)",
        )
        _segment_marks(ax, jt.trajectory, labels=False)
        ax.set_ylim(1e-9, None)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"max over joints |exact − numerical| [{unit}]")
        ax.set_title(f"|exact − numerical| of the {name}", fontsize=11)
        ax.text(
            0.99,
            0.98,
            "grey: differentiated across segment joints (O(h) there: the quintic's "
            "jerk jumps)\nflat bands in the dwells: IK residual / h²",
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize=8,
            color="0.3",
        )
        ax.legend(fontsize=8, loc="lower left")
        ax.grid(True, alpha=0.3, which="both")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def miskolc_torques(arm, jt):
    """Joint torques tau (N, 4) [N m] along the path: the arm's inverse dynamics at the
    exact joint rates (J^+, Jdot) of every sample."""
    return arm.inverse_dynamics(jt.q, jt.qd, jt.qdd)


def _write_csv(jt, tau, path):
    n = jt.q.shape[1]
    cols = (
        ["t"]
        + [f"q{i + 1}" for i in range(n)]
        + [f"qd{i + 1}" for i in range(n)]
        + [f"qdd{i + 1}" for i in range(n)]
        + [f"qd{i + 1}_num" for i in range(n)]
        + [f"qdd{i + 1}_num" for i in range(n)]
        + ["x", "y", "z", "task_error"]
        + [f"tau{i + 1}" for i in range(n)]
    )
    data = np.column_stack(
        [jt.t, jt.q, jt.qd, jt.qdd, jt.qd_num, jt.qdd_num, jt.cartesian.p, jt.task_error, tau]
    )
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.12g")
    return path


def _output(out, default: str, stream):
    """(stream, folder) of a demo that writes files: stdout unless given, and ``out`` (or the
    demo's default folder name) created."""
    folder = Path(default if out is None else out)
    folder.mkdir(parents=True, exist_ok=True)
    return (sys.stdout if stream is None else stream), folder


def run_miskolc(out=None, stream=None) -> int:
    pyplot()  # before the computation: without matplotlib, say so now
    from deltagen.api.serial import SerialRobot

    stream, folder = _output(out, "miskolc_pick_and_place", stream)
    arm = SerialRobot.load("miskolc_rrrr")
    jt = miskolc_joint_trajectory(DT, arm)
    jt_half = miskolc_joint_trajectory(DT / 2, arm)
    err, err2 = jt.rate_errors(), jt_half.rate_errors()
    qd_u, qdd_u = jt.numerical_rates_unsplit()
    deg = np.degrees
    print(
        "Miskolc RRRR robot (Miskolc paper): pick and place, elbow up (q3 <= 0 at every sample)",
        file=stream,
    )
    print(
        f"  path: {len(jt.trajectory.segments)} segments, {jt.trajectory.duration:g} s, "
        f"{jt.t.size} samples at h = {jt.dt * 1e3:g} ms",
        file=stream,
    )
    print(
        f"  IK: max task error {jt.task_error.max():.2g} m, Newton iterations per sample "
        f"<= {jt.iterations.max()}, max joint step {deg(jt.max_joint_step):.3f} deg",
        file=stream,
    )
    lo, hi = deg(jt.q.min(axis=0)), deg(jt.q.max(axis=0))
    print(
        "  joint ranges used [deg]: "
        + ", ".join(f"q{i + 1} {_z(a, 1)}..{_z(b, 1)}" for i, (a, b) in enumerate(zip(lo, hi))),
        file=stream,
    )
    print(
        f"  exact vs numerical (per segment): max |dqd| = {err['qd']:.3g} rad/s "
        f"(peak |qd| {err['qd_peak']:.3g}), max |dqdd| = {err['qdd']:.3g} rad/s² "
        f"(peak |qdd| {err['qdd_peak']:.3g})",
        file=stream,
    )
    print(
        f"  at h/2 = {jt_half.dt * 1e3:g} ms: max |dqd| = {err2['qd']:.3g}, max |dqdd| = "
        f"{err2['qdd']:.3g}; ratios {err['qd'] / err2['qd']:.2f}, {err['qdd'] / err2['qdd']:.2f} "
        f"(O(h²): 4)",
        file=stream,
    )
    print(
        f"  whole signal differentiated at once (paper): max |dqd| = "
        f"{np.abs(qd_u - jt.qd).max():.3g}, max |dqdd| = {np.abs(qdd_u - jt.qdd).max():.3g} "
        f"(O(h) at the segment joints, where the quintic's jerk jumps)",
        file=stream,
    )
    from deltagen.apps.dynamics import joint_table, serial_plot

    tau = miskolc_torques(arm, jt)
    table = joint_table(tau, jt.qd)
    print(
        "  joint torques (chosen aluminium links, robots/miskolc_rrrr.toml): "
        + ", ".join(
            f"tau{i + 1} peak {p:.3g} RMS {r:.3g}"
            for i, (p, r) in enumerate(zip(table["peak"], table["rms"]))
        )
        + " N m",
        file=stream,
    )
    written = [
        _plot_joint_angles(jt, folder / "miskolc_joint_angles.png"),
        _plot_arm_poses(jt, folder / "miskolc_arm_poses.png"),
        _plot_rates(jt, jt_half, folder / "miskolc_rates.png"),
        serial_plot(
            jt.t,
            jt.q,
            jt.qd,
            jt.qdd,
            tau,
            folder / "miskolc_torques.png",
            title="Miskolc RRRR pick and place: joint torques (chosen aluminium links, no payload)",
            marks=lambda ax: _segment_marks(ax, jt.trajectory, labels=False),
        ),
        _write_csv(jt, tau, folder / "miskolc_joint_trajectory.csv"),
    ]
    for path in written:
        print(f"wrote {path}", file=stream)
    return 0


# ------------------------------------------------------------------ singular path

#: The singular pose the line passes: q5 = 0 (Puma 560, axes 4 and 6 in line).
SINGULAR_Q = (0.2, 0.7, -2.9, 0.4, 0.0, -0.3)
#: How far beside it [m], the half length of the line [m], its duration [s].
SINGULAR_OFFSET, SINGULAR_HALF, SINGULAR_DURATION = 0.003, 0.15, 1.0
#: Chosen joint limits for the demo [rad/s], [rad/s^2].
SINGULAR_QD_MAX, SINGULAR_QDD_MAX = 1.0, 10.0


def singular_line(arm, offset=SINGULAR_OFFSET):
    """The demo's line (module docstring) and its start joints on SINGULAR_Q's branch:
    across the forearm (axis 4), so that the wrist centre's motion turns axis 4 past axis 6."""
    from deltagen.plan.cartesian import PathBuilder
    from deltagen.plan.following import Task, solve_ik, to_joint_trajectory
    from deltagen.reference import serial as reference

    pose = Task("xyz", orientation=True)
    q_mid = np.array(SINGULAR_Q)
    T = arm.fk(q_mid)
    R, pm = T[:3, :3], T[:3, 3]
    _, w = reference.joint_axes(arm.description, q_mid[None])
    d = np.cross(w[0, 3], [0.3, 0.2, 1.0])
    d /= np.linalg.norm(d)
    side = np.cross(d, [0.0, 0.0, 1.0])
    pm = pm + offset * side / np.linalg.norm(side)
    p0, p1 = pm - SINGULAR_HALF * d, pm + SINGULAR_HALF * d
    # start joints: continue from next to the middle (q5 small) back to the start
    near = pm + 0.03 * (p0 - pm)
    g = q_mid.copy()
    g[4] = 0.05
    g = solve_ik(arm, pose, near, R, np.zeros(0), g)[0]
    back = PathBuilder(near, R=R).line(p0, 1.0).build()
    q0 = to_joint_trajectory(arm, back, pose, g, dt=0.01, limits="ignore").q[-1]
    traj = PathBuilder(p0, R=R).line(p1, SINGULAR_DURATION, label="past the wrist").build()
    return traj, q0


def _plot_singular_speeds(naive, res, path: Path) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(9, 7), layout="constrained")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    panels = (
        (axes[0], naive.t, naive.qd, "followed as programmed (6-D path following)", None),
        (axes[1], res.t, res.qd, 'remedy="wrist" (SingArea/Wrist), time-scaled', res),
    )
    for ax, t, qd, title, r in panels:
        for i in range(qd.shape[1]):
            ax.plot(t, qd[:, i], color=colors[i % len(colors)], label=f"q{i + 1}")
        ax.axhline(SINGULAR_QD_MAX, color="k", ls="--", lw=0.8)
        ax.axhline(-SINGULAR_QD_MAX, color="k", ls="--", lw=0.8, label="limit")
        ax.set_ylabel("joint speed [rad/s]")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        if r is not None:
            for reg in r.regions:
                ax.axvspan(reg.t_entry, reg.t_exit, color="tab:orange", alpha=0.15)
        else:
            peak = float(np.abs(qd).max())
            ax.set_yscale("symlog", linthresh=1.0)
            ax.text(0.01, 0.92, f"peak |qd| = {peak:.3g} rad/s", transform=ax.transAxes)
    axes[1].set_xlabel("t [s]")
    axes[0].legend(ncol=7, fontsize=8, loc="lower right")
    fig.suptitle(
        "Puma 560: a line 3 mm beside q5 = 0 (axes 4 and 6 in line); shaded: the singular region"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_singular(out=None, stream=None) -> int:
    pyplot()  # before the computation: without matplotlib, say so now
    from deltagen.api.serial import SerialRobot
    from deltagen.plan.following import Task, to_joint_trajectory
    from deltagen.plan.singular_path import SingularPathError

    stream, folder = _output(out, "singular_path", stream)
    arm = SerialRobot.load("puma560")
    traj, q0 = singular_line(arm)
    print(
        "Puma 560: a straight line past the wrist singularity (lecture slides 112-114), "
        f"{SINGULAR_OFFSET * 1e3:g} mm beside q5 = 0, {2 * SINGULAR_HALF:g} m in "
        f"{SINGULAR_DURATION:g} s, orientation held; limits |qd| <= {SINGULAR_QD_MAX:g} rad/s, "
        f"|qdd| <= {SINGULAR_QDD_MAX:g} rad/s^2",
        file=stream,
    )
    try:
        arm.follow_path(traj, q0)
    except SingularPathError as exc:
        print(f"  remedy='stop' (default): {exc}", file=stream)
    naive = to_joint_trajectory(
        arm, traj, Task("xyz", orientation=True), q0, dt=0.005, max_step=10.0, limits="ignore"
    )
    peak = np.abs(naive.qd).max(axis=0)
    print(
        "  followed as programmed: peak |qd| per joint "
        + ", ".join(f"{v:.3g}" for v in peak)
        + " rad/s",
        file=stream,
    )
    res = arm.follow_path(
        traj, q0, remedy="wrist", qd_max=SINGULAR_QD_MAX, qdd_max=SINGULAR_QDD_MAX, dt=0.005
    )
    print("  remedy='wrist': " + res.report.lines()[0], file=stream)
    for line in res.report.lines()[1:]:
        print("  " + line, file=stream)
    print(
        "  peak |qd| per joint "
        + ", ".join(f"{v:.3g}" for v in res.report.peak_qd)
        + f" rad/s; TCP off the line by at most {res.report.max_position_error:.2g} m",
        file=stream,
    )
    written = _plot_singular_speeds(naive, res, folder / "singular_path_speeds.png")
    print(f"wrote {written}", file=stream)
    return 0


def add_parser(subparsers) -> None:
    """`deltagen demo NAME [--out DIR]`."""
    d = subparsers.add_parser(
        "demo",
        help="worked examples: the lecture's SCARA table, the Miskolc pick and place, a "
        "path past a wrist singularity",
    )
    d.add_argument("name", choices=("lecture-scara", "miskolc-pick-and-place", "singular-path"))
    d.add_argument(
        "--out",
        default=None,
        help="folder for PNG/CSV output (miskolc default: miskolc_pick_and_place; "
        "singular-path: singular_path; "
        "lecture-scara writes its plot only when given)",
    )


def run(args) -> int:
    """`deltagen demo NAME`: 0 when the demo ran."""
    name = args.name
    out = args.out
    if name == "singular-path":
        return run_singular(out)
    if name == "lecture-scara":
        return run_lecture(out)
    if name == "miskolc-pick-and-place":
        return run_miskolc(out)
    print(f"unknown demo {name!r}; choose one of {', '.join(NAMES)}", file=sys.stderr)
    return 2
