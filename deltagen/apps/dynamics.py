"""Motor sizing along a trajectory: feed-forward torques of the delta robot (the purpose
of the delta report, Figures 1-2), their peaks, RMS and mechanical power, the simplified
model's difference from the exact one, and a plot of q, qdot, qddot and tau per drive;
the same for serial arms with inertial parameters (joint torques by recursive Newton-Euler).

Used by `deltagen validate` (the report's trajectory, eqs. (40)-(42)), `deltagen dynamics`
and the Miskolc demo.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from deltagen.apps.robots import COUPLED, DELTA, SERIAL


@dataclass
class TorqueProfile:
    """Torques along a sampled trajectory; arrays (N, 4) per drive (column 4: fourth axis)."""

    t: np.ndarray  # (N,) [s]
    q: np.ndarray  # [rad]
    qd: np.ndarray  # [rad/s]
    qdd: np.ndarray  # [rad/s^2]
    tau: np.ndarray  # exact model [N m]
    tau_simplified: np.ndarray  # simplified model (rod mass split) [N m]
    payload: float  # [kg]

    @property
    def ok(self) -> np.ndarray:
        return np.isfinite(self.tau[:, :3]).all(axis=1)

    def drive_table(self) -> dict:
        """Per drive (4 columns): peak |tau|, RMS tau, peak |tau qdot| over the valid samples."""
        ok = self.ok
        return joint_table(self.tau[ok], self.qd[ok])

    def model_difference(self) -> dict:
        """Simplified minus exact, per drive 1..3: peak and RMS of the difference [N m], and
        both relative to the exact model's peak torque of that drive."""
        ok = self.ok
        diff = (self.tau_simplified - self.tau)[ok, :3]
        peak = np.abs(diff).max(axis=0) if ok.any() else np.full(3, np.nan)
        rms = np.sqrt((diff**2).mean(axis=0)) if ok.any() else np.full(3, np.nan)
        ref = self.drive_table()["peak"][:3]
        return {"peak": peak, "rms": rms, "peak_rel": peak / ref, "rms_rel": rms / ref}


def joint_table(tau, qd) -> dict:
    """Per joint: peak |tau|, RMS tau and peak mechanical power |tau qdot| over the rows
    given (tau, qd (N, n)); NaN for no rows."""
    tau, qd = np.asarray(tau, dtype=float), np.asarray(qd, dtype=float)
    if tau.shape[0] == 0:
        nan = np.full(tau.shape[1], np.nan)
        return {"peak": nan, "rms": nan, "power": nan}
    return {
        "peak": np.abs(tau).max(axis=0),
        "rms": np.sqrt((tau**2).mean(axis=0)),
        "power": np.abs(tau * qd).max(axis=0),
    }


def torque_profile(robot, t, q, qd, qdd, payload: float = 0.0) -> TorqueProfile:
    """Both models' torques at the samples (NaN where the pose is singular or q is NaN)."""
    tau, _ = robot.inverse_dynamics(q, qd, qdd, payload, errors="nan")
    tau_s, _ = robot.inverse_dynamics(q, qd, qdd, payload, model="simplified", errors="nan")
    return TorqueProfile(np.asarray(t), q, qd, qdd, tau, tau_s, float(payload))


def report(profile: TorqueProfile, out=None, title="feed-forward torques") -> None:
    out = sys.stdout if out is None else out

    def w(text=""):
        print(text, file=out)

    table = profile.drive_table()
    n_ok = int(profile.ok.sum())
    w(
        f"{title} (exact rigid-body model, payload {profile.payload:g} kg, "
        f"{n_ok} of {profile.t.size} samples):"
    )
    w(
        "  drive          1          2          3"
        + ("     axis 4" if len(table["peak"]) == 4 else "")
    )
    w("  peak |tau| " + "".join(f"{v:10.4g} " for v in table["peak"]) + " N m")
    w("  RMS tau    " + "".join(f"{v:10.4g} " for v in table["rms"]) + " N m")
    w("  peak power " + "".join(f"{v:10.4g} " for v in table["power"]) + " W  (max |tau qdot|)")
    diff = profile.model_difference()
    w("simplified model (rod mass split 1/2 crank tip, 1/2 platform) minus exact:")
    w(
        "  peak |diff| "
        + "".join(f"{v:9.4g} " for v in diff["peak"])
        + "N m  ("
        + ", ".join(f"{100 * v:.2f} %" for v in diff["peak_rel"])
        + " of the drive's peak torque)"
    )
    w(
        "  RMS diff    "
        + "".join(f"{v:9.4g} " for v in diff["rms"])
        + "N m  ("
        + ", ".join(f"{100 * v:.2f} %" for v in diff["rms_rel"])
        + ")"
    )


def plot(profile: TorqueProfile, path, title: str = "") -> Path:
    """q, qdot, qddot and tau of each drive over time (one panel per quantity), with the
    simplified model's torque difference."""
    from deltagen.apps.plotting import pyplot

    plt = pyplot()
    path = Path(path)
    fig, axes = plt.subplots(5, 1, figsize=(13, 15), sharex=True, layout="constrained")
    fig.suptitle(title or "delta robot feed-forward torques", fontsize=13)
    t = profile.t
    colors = ("tab:blue", "tab:orange", "tab:green")
    series = [
        (profile.q, "q [deg]", 180.0 / math.pi),
        (profile.qd, "q̇ [rad/s]", 1.0),
        (profile.qdd, "q̈ [rad/s²]", 1.0),
        (profile.tau, "τ [N m] (exact)", 1.0),
        (profile.tau_simplified - profile.tau, "τ simplified − τ exact [N m]", 1.0),
    ]
    table = profile.drive_table()
    for ax, (values, label, scale) in zip(axes, series):
        for i in range(3):
            extra = ""
            if label.startswith("τ [N m]"):
                extra = f" (peak {table['peak'][i]:.3g}, RMS {table['rms'][i]:.3g} N m)"
            ax.plot(t, values[:, i] * scale, lw=0.5, color=colors[i], label=f"drive {i + 1}{extra}")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("t [s]")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# -- `deltagen dynamics ROBOT --input traj.csv` ---------------------------------------------

_Q = ("q1", "q2", "q3")
_QD = ("qd1", "qd2", "qd3")
_QDD = ("qdd1", "qdd2", "qdd3")
_P = ("x", "y", "z")
_PD = ("xd", "yd", "zd")
_PDD = ("xdd", "ydd", "zdd")


def _layouts():
    from deltagen.apps.tables import Columns

    return [
        Columns(("t", *_Q, *_QD, *_QDD), positional=False),  # crank motion with its rates
        Columns(("t", *_P, *_PD, *_PDD), positional=False),  # platform motion with rates
        Columns(("t", *_Q)),  # crank angles; rates by finite differences
        Columns(("t", *_P), positional=False),  # platform positions; rates by differences
    ]


def rates_by_differences(t, x):
    """First and second time derivatives of samples x(t) (N, k): second-order central
    differences (one-sided at the ends), on any increasing time grid."""
    xd = np.gradient(x, t, axis=0, edge_order=2)
    return xd, np.gradient(xd, t, axis=0, edge_order=2)


def load_trajectory(robot, path):
    """(t, q, qd, qdd, valid) of a trajectory file; platform motion goes through ik_acc."""
    from deltagen.apps.tables import read_table
    from deltagen.inputs import InputError

    data, layout, _ = read_table(path, _layouts(), "dynamics")
    t = data[:, 0]
    if t.size < 3 and layout >= 2:
        raise InputError(f"{path}: rates by finite differences need at least 3 samples")
    if not (np.isfinite(t).all() and (np.diff(t) > 0).all()):
        raise InputError(f"{path}: the t column must be finite and strictly increasing")
    x = data[:, 1:4]
    if layout in (0, 1):
        xd, xdd = data[:, 4:7], data[:, 7:10]
    else:
        xd, xdd = rates_by_differences(t, x)
    if layout in (0, 2):
        valid = np.isfinite(np.column_stack((x, xd, xdd))).all(axis=1)
        return t, x, xd, xdd, valid
    q, qd, qdd, valid = robot.ik_acc(x, xd, xdd, errors="nan")
    return t, q, qd, qdd, valid


def add_parser(subparsers) -> None:
    """`deltagen dynamics [ROBOT] --input TRAJECTORY ...`."""
    from deltagen.apps.robots import ROBOT_HELP, add_urdf_options

    y = subparsers.add_parser(
        "dynamics",
        help="motor / joint torques of a delta robot or serial arm along a trajectory file",
        description="Feed-forward motor torques along a trajectory (CSV or NPY, columns by "
        "name): t,q1,q2,q3,qd1..qd3,qdd1..qdd3 or t,x,y,z,xd,yd,zd,xdd,ydd,zdd (rates given), "
        "or t,q1,q2,q3 / t,x,y,z (rates by second-order finite differences). Prints peak and "
        "RMS torque and peak power per drive and the simplified model's difference; writes "
        "t,q..,qd..,qdd..,tau1..tau3,valid. A serial arm with inertial parameters reads "
        "t,q1..qn[,qd1..qdn,qdd1..qddn] and writes t,q..,qd..,qdd..,tau1..taun,valid "
        "(--payload and --model are for delta robots).",
    )
    y.add_argument("robot", nargs="?", default="default", help=ROBOT_HELP)
    y.add_argument("--input", required=True, help="trajectory file (CSV or NPY)")
    y.add_argument("--output", help="torque file (.csv or .npy; default: stdout)")
    y.add_argument("--payload", type=float, default=0.0, help="payload [kg] (default 0)")
    y.add_argument("--model", choices=("exact", "simplified"), default="exact")
    y.add_argument("--plot", help="PNG of q, qd, qdd and tau per drive")
    y.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    add_urdf_options(y)


def run(args) -> int:
    """`deltagen dynamics`: the job of the robot's kind (JOBS); returns the exit status."""
    from deltagen.apps.robots import run_job

    return run_job(args, JOBS)


def delta_main(robot, args) -> int:
    """`deltagen dynamics` of a delta robot: motor torques of both models."""
    from deltagen.apps.tables import write_table
    from deltagen.errors import rows_text
    from deltagen.inputs import InputError

    t, q, qd, qdd, valid = load_trajectory(robot, args.input)
    if args.payload < 0 or not math.isfinite(args.payload):
        raise InputError(f"--payload must be a non-negative mass in kg, got {args.payload!r}")
    profile = torque_profile(robot, t, q, qd, qdd, args.payload)
    tau = profile.tau if args.model == "exact" else profile.tau_simplified
    ok = valid & profile.ok
    report(profile, title=f"torques along {args.input}")
    names = ["t", *_Q, *_QD, *_QDD, "tau1", "tau2", "tau3"]
    table = np.column_stack((t, q[:, :3], qd[:, :3], qdd[:, :3], tau[:, :3]))
    table[~ok, 1:] = np.nan
    write_table(args.output if args.output else sys.stdout, names, table, ok)
    if args.output:
        print(f"wrote {args.output} ({args.model} model)")
    if args.plot:
        print(f"wrote {plot(profile, args.plot, title=f'torques along {args.input}')}")
    if not ok.all():
        bad = np.flatnonzero(~ok)
        print(
            f"deltagen dynamics: no torques (unreachable, singular or non-finite) in rows "
            f"{rows_text(bad)}",
            file=sys.stderr,
        )
        return 1
    return 0


# -- serial arms: `deltagen dynamics ARM --input traj.csv` ------------------------------------


def _serial_layouts(n: int):
    from deltagen.apps.tables import Columns

    q = tuple(f"q{i + 1}" for i in range(n))
    qd = tuple(f"qd{i + 1}" for i in range(n))
    qdd = tuple(f"qdd{i + 1}" for i in range(n))
    return [
        Columns(("t", *q, *qd, *qdd), positional=False),  # joint motion with its rates
        Columns(("t", *q)),  # joint angles; rates by finite differences
    ]


def load_serial_trajectory(arm, path):
    """(t, q, qd, qdd, valid) of a serial arm's trajectory file: columns t, q1..qn and
    optionally qd1..qdn, qdd1..qddn (else rates by :func:`rates_by_differences`)."""
    from deltagen.apps.tables import read_table
    from deltagen.inputs import InputError

    n = arm.n
    data, layout, _ = read_table(path, _serial_layouts(n), f"dynamics of {arm.name}")
    t = data[:, 0]
    if t.size < 3 and layout == 1:
        raise InputError(f"{path}: rates by finite differences need at least 3 samples")
    if not (np.isfinite(t).all() and (np.diff(t) > 0).all()):
        raise InputError(f"{path}: the t column must be finite and strictly increasing")
    q = data[:, 1 : 1 + n]
    if layout == 0:
        qd, qdd = data[:, 1 + n : 1 + 2 * n], data[:, 1 + 2 * n : 1 + 3 * n]
    else:
        qd, qdd = rates_by_differences(t, q)
    valid = np.isfinite(np.column_stack((q, qd, qdd))).all(axis=1)
    return t, q, qd, qdd, valid


def serial_torques(arm, q, qd, qdd):
    """tau (N, n) of the arm's inverse dynamics, NaN in the rows that are not finite, and
    the valid mask."""
    tau, valid = arm.inverse_dynamics(q, qd, qdd, errors="nan")
    valid = np.asarray(valid, dtype=bool) & np.isfinite(tau).all(axis=1)
    return tau, valid


def serial_report(t, qd, tau, valid, out=None, title="joint torques") -> dict:
    """Print peak |tau|, RMS tau and peak power per joint over the valid rows; returns the
    table."""
    out = sys.stdout if out is None else out
    table = joint_table(tau[valid], qd[valid])
    n = tau.shape[1]
    print(f"{title} ({int(valid.sum())} of {len(t)} samples):", file=out)
    print("  joint      " + "".join(f"{i + 1:>10d} " for i in range(n)), file=out)
    print("  peak |tau| " + "".join(f"{v:10.4g} " for v in table["peak"]) + " N m", file=out)
    print("  RMS tau    " + "".join(f"{v:10.4g} " for v in table["rms"]) + " N m", file=out)
    print(
        "  peak power " + "".join(f"{v:10.4g} " for v in table["power"]) + " W  (max |tau qdot|)",
        file=out,
    )
    return table


def serial_plot(t, q, qd, qdd, tau, path, title: str = "", marks=None) -> Path:
    """q, qdot, qddot and tau of each joint over time, one panel per quantity. ``marks``:
    optional callable(ax) drawing e.g. segment boundaries."""
    from deltagen.apps.plotting import pyplot

    plt = pyplot()
    path = Path(path)
    fig, axes = plt.subplots(4, 1, figsize=(15, 12), sharex=True, layout="constrained")
    fig.suptitle(title or "joint torques", fontsize=13)
    valid = np.isfinite(tau).all(axis=1)
    table = joint_table(tau[valid], qd[valid])
    series = [
        (q, "q [deg]", 180.0 / math.pi),
        (qd, "q̇ [rad/s]", 1.0),
        (qdd, "q̈ [rad/s²]", 1.0),
        (tau, "τ [N m]", 1.0),
    ]
    for ax, (values, label, scale) in zip(axes, series):
        for i in range(values.shape[1]):
            extra = ""
            if label.startswith("τ"):
                extra = f" (peak {table['peak'][i]:.3g}, RMS {table['rms'][i]:.3g} N m)"
            ax.plot(t, values[:, i] * scale, lw=0.7, label=f"joint {i + 1}{extra}")
        if marks is not None:
            marks(ax)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # beside, not over
    axes[-1].set_xlabel("t [s]")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def serial_main(arm, args) -> int:
    from deltagen.apps.tables import write_table
    from deltagen.errors import rows_text
    from deltagen.inputs import InputError

    if args.payload != 0.0:
        raise InputError(
            f"--payload is for delta robots; give a serial arm's payload as the last link's "
            f"mass in its robot file ({arm.name})"
        )
    if args.model != "exact":
        raise InputError(
            f"--model {args.model} is the delta robot's rod-mass split; a serial arm "
            f"({arm.name}) has one model (recursive Newton-Euler)"
        )
    t, q, qd, qdd, valid = load_serial_trajectory(arm, args.input)
    tau, ok = serial_torques(arm, q, qd, qdd)
    ok &= valid
    serial_report(t, qd, tau, ok, title=f"joint torques of {arm.name} along {args.input}")
    n = arm.n
    names = ["t", *(f"{p}{i + 1}" for p in ("q", "qd", "qdd", "tau") for i in range(n))]
    table = np.column_stack((t, q, qd, qdd, tau))
    table[~ok, 1:] = np.nan
    write_table(args.output if args.output else sys.stdout, names, table, ok)
    if args.output:
        print(f"wrote {args.output}")
    if args.plot:
        title = f"joint torques of {arm.name} along {args.input}"
        print(f"wrote {serial_plot(t, q, qd, qdd, tau, args.plot, title=title)}")
    if not ok.all():
        bad = np.flatnonzero(~ok)
        print(
            f"deltagen dynamics: no torques (non-finite) in rows {rows_text(bad)}", file=sys.stderr
        )
        return 1
    return 0


#: The job of `deltagen dynamics` for each robot kind it serves (apps/robots.py).
JOBS = {DELTA: delta_main, SERIAL: serial_main, COUPLED: serial_main}
