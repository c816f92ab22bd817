"""`deltagen fk | ik ROBOT ...`: kinematics of one pose (positional values) or of a batch
(``--input`` CSV/NPY, read and written by :mod:`deltagen.apps.tables`).

What each command reads and writes, by column name (a command reads the other's output):

==============  ===================================  ===========================================
robot, command  reads                                writes
==============  ===================================  ===========================================
delta fk        q1,q2,q3[,q4]                        x,y,z[,phi],valid
delta ik        x,y,z[,phi]                          q1,q2,q3[,q4],valid
serial fk       q1 .. qn                             x,y,z,psi,theta,phi,T11 .. T44,valid
serial ik       T11 .. T34 (T41 .. T44 optional),    q1 .. qn,valid
                else x,y,z,psi,theta,phi
machine fk      x,y,z,a|b,c                          px,py,pz,dx,dy,dz,valid
machine ik      px,py,pz,dx,dy,dz                    x,y,z,a|b,c,valid
==============  ===================================  ===========================================

A 5-axis machine (model/five_axis.py): p the tool tip, d the tool axis in the workpiece
frame; the rows of an ik file are a path, each solved from the joints of the row before
(the first from ``--q0``, default zeros), so C does not jump by 2 pi (FiveAxisMachine.ik_path).

q4 is the delta's fourth axis and phi the platform's turn about z that it gives (delta report
eq. (43)); psi, theta, phi of a serial arm are the Euler angles after Vukobratovic,
R = Rz(psi) Ry(theta) Rx(phi). A serial ik reads the full transform when the file has it (it
is exact even where the Euler angles are singular, theta = +-90 deg).

Units: m and rad. ``--degrees`` gives and prints *revolute joint coordinates* in degrees (fk
input, ik output, ``--q0``); prismatic joints stay in m, and poses (x, y, z and the angles
of the pose) are always in m and rad, so the files of a round trip never change units.

Exit status: 0 every pose computed; 1 computed, but some rows have no valid result (NaN
and valid = 0 in the output, and a message naming the rows); 2 usage or input error.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

import numpy as np

from deltagen.apps import robots
from deltagen.apps.tables import Columns, output_format, read_table, write_table
from deltagen.errors import DeltagenError
from deltagen.geometry.rotations import matrix_from_euler_zyx
from deltagen.inputs import InputError

EXIT_OK, EXIT_INVALID, EXIT_USAGE = 0, 1, 2

SERIAL_POSE = ("x", "y", "z", "psi", "theta", "phi")
TRANSFORM = tuple(f"T{r}{c}" for r in range(1, 4) for c in range(1, 5))
TRANSFORM_LAST = ("T41", "T42", "T43", "T44")


def euler_to_matrix(psi, theta, phi) -> np.ndarray:
    """R = Rz(psi) Ry(theta) Rx(phi) (..., 3, 3), the inverse of euler_zyx."""
    return matrix_from_euler_zyx(np.stack(np.broadcast_arrays(psi, theta, phi), axis=-1))


@dataclass
class Job:
    """One command (fk or ik) on one robot: the layouts it reads, the columns it writes."""

    robot: object
    serial: bool
    forward: bool
    degrees: bool
    layouts: list
    out_names: tuple = ()
    revolute: np.ndarray = field(default=None)  # per joint: convert with --degrees
    options: dict = field(default_factory=dict)  # serial ik: config, q0, method, restarts

    @property
    def what(self) -> str:
        name = self.robot.name if self.serial else getattr(self.robot, "name", "the delta robot")
        return f"{'fk' if self.forward else 'ik'} of {name}"

    # -- input -> the API's arguments -------------------------------------------------

    def prepare(self, data, layout):
        """Table columns (N, k) of ``layouts[layout]`` -> the API's input (radians, 4x4)."""
        if self.forward:
            q = data.copy()
            if self.degrees:
                conv = self.revolute[: q.shape[1]]
                q[:, conv] = np.radians(q[:, conv])
            return q
        if not self.serial:
            return data
        T = np.zeros((data.shape[0], 4, 4))
        if self.layouts[layout].required == TRANSFORM:
            T[:, :3, :] = data[:, :12].reshape(-1, 3, 4)
            T[:, 3, :] = data[:, 12:16] if data.shape[1] == 16 else (0.0, 0.0, 0.0, 1.0)
        else:
            T[:, :3, :3] = euler_to_matrix(data[:, 3], data[:, 4], data[:, 5])
            T[:, :3, 3] = data[:, :3]
            T[:, 3, 3] = 1.0
        return T

    # -- the computation --------------------------------------------------------------

    def compute(self, x):
        """(table (N, m) of ``names``, valid (N,), names) for the API input x."""
        robot = self.robot
        with np.errstate(all="ignore"):
            if self.forward and self.serial:
                from deltagen.api.serial import euler_zyx

                T, valid = robot.fk(x, errors="nan")
                out = np.column_stack([T[:, :3, 3], euler_zyx(T[:, :3, :3]), T.reshape(-1, 16)])
                names = SERIAL_POSE + tuple(f"T{r}{c}" for r in range(1, 5) for c in range(1, 5))
            elif self.forward:
                out, valid = robot.fk(x, errors="nan")
                names = ("x", "y", "z", "phi")[: out.shape[1]]
            else:
                if self.serial:
                    out, valid = robot.ik(x, errors="nan", **self.api_options())
                else:
                    out, valid = robot.ik(x, errors="nan")
                out = out.copy()
                if self.degrees:
                    conv = self.revolute[: out.shape[1]]
                    out[:, conv] = np.degrees(out[:, conv])
                names = tuple(f"q{i + 1}" for i in range(out.shape[1]))
        out = np.asarray(out, dtype=np.float64).reshape(len(valid), -1)
        # a result that is not finite is never valid, whatever the kernel's status says
        valid = np.asarray(valid, dtype=bool).reshape(-1) & np.all(np.isfinite(out), axis=1)
        out[~valid] = np.nan
        return out, valid, names

    def api_options(self) -> dict:
        return dict(self.options)

    def explain(self, x) -> str:
        """Why the single input row x has no valid result (the raising API's message)."""
        try:
            with np.errstate(all="ignore"):
                if self.forward or not self.serial:
                    (self.robot.fk if self.forward else self.robot.ik)(x[0])
                else:
                    self.robot.ik(x[0], **self.api_options())
        except DeltagenError as exc:
            return str(exc)
        return "the result is not finite (the input is too large to evaluate)"


#: The ik options only a serial arm's solvers take (argparse names).
SERIAL_ONLY = ("config", "q0", "method", "restarts")


def refuse_options(args, flags, reason: str) -> None:
    """InputError "--<flag> <reason>" for the first of ``flags`` (argparse names) that
    ``args`` gives (a value other than None)."""
    for flag in flags:
        if getattr(args, flag, None) is not None:
            raise InputError(f"--{flag} {reason}")


def make_job(robot, forward: bool, args) -> Job:
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.linear_delta import LinearDelta, Tripod

    if isinstance(robot, (LinearDelta, Tripod)):  # joints in m (carriages or struts)
        refuse_options(args, SERIAL_ONLY, f"applies to serial arms, not to {robot.name}")
        columns = Columns(("q1", "q2", "q3")) if forward else Columns(("x", "y", "z"))
        return Job(robot, False, forward, args.degrees, [columns], revolute=np.zeros(3, dtype=bool))
    serial = not isinstance(robot, DeltaRobot)  # a SerialRobot or a CoupledArm
    if not serial:
        refuse_options(args, SERIAL_ONLY, "applies to serial arms, not to the delta robot")
        joints = Columns(("q1", "q2", "q3"), ("q4",))
        pose = Columns(("x", "y", "z"), ("phi",))
        return Job(
            robot,
            False,
            forward,
            args.degrees,
            [joints if forward else pose],
            revolute=np.ones(4, dtype=bool),
        )
    revolute = _revolute(robot)
    joints = Columns(tuple(f"q{i + 1}" for i in range(robot.n)))
    if forward:
        refuse_options(args, ("q0", "method", "restarts"), "applies to ik, not to fk")
        return Job(robot, True, True, args.degrees, [joints], revolute=revolute)
    layouts = [Columns(TRANSFORM, TRANSFORM_LAST, positional=False), Columns(SERIAL_POSE)]
    options = {}
    if args.config is not None:
        configs = robot.analytic_configs() if hasattr(robot, "analytic_configs") else ()
        if args.config not in configs:
            known = ", ".join(configs) if configs else "none: it has no closed-form inverse"
            raise InputError(
                f"--config {args.config!r} is not a branch of {robot.name}'s "
                f"closed-form ik (branches: {known})"
            )
        options["config"] = args.config
    if args.q0 is not None:
        options["q0"] = _parse_q0(robot, args.q0, args.degrees, revolute)
    if args.method is not None:
        options["method"] = args.method
    if args.restarts is not None:
        if args.method != "numeric":
            raise InputError("--restarts applies to --method numeric")
        if args.restarts < 0:
            raise InputError(f"--restarts must be >= 0, got {args.restarts}")
        options["restarts"] = args.restarts
    if args.config is not None and args.method == "numeric":
        raise InputError(
            "--config picks a closed-form branch; it does not apply to "
            "--method numeric (give --q0 to choose where the solver starts)"
        )
    return Job(robot, True, False, args.degrees, layouts, revolute=revolute, options=options)


def _revolute(robot) -> np.ndarray:
    """Per joint variable of a serial arm: revolute (converted by --degrees)? A CoupledArm's
    variables are its independent joints."""
    if hasattr(robot, "coupling"):
        joints = robot.full.description.joints
        return np.array([joints[i].revolute for i in robot.coupling.independent])
    return np.array([j.revolute for j in robot.description.joints])


def _configurations(robot) -> dict:
    """The named joint configurations of a serial arm's robot file (none for a CoupledArm)."""
    return getattr(robot, "configurations", {})


def _configuration(robot, name) -> np.ndarray:
    if hasattr(robot, "configuration"):
        return robot.configuration(name)
    raise InputError(f"{robot.name} has no configuration {name!r} (known: none)")


def _parse_q0(robot, text, degrees, revolute) -> np.ndarray:
    if text in _configurations(robot):
        return _configuration(robot, text)
    try:
        values = [float(t) for t in text.replace(",", " ").split()]
    except ValueError:
        known = ", ".join(_configurations(robot)) or "none"
        raise InputError(
            f"--q0 {text!r}: give {robot.n} numbers separated by commas, or a "
            f"configuration of {robot.name} (known: {known})"
        ) from None
    q0 = np.array(values)
    if q0.shape != (robot.n,):
        raise InputError(f"--q0 has {q0.size} values; {robot.name} has {robot.n} joints")
    if not np.all(np.isfinite(q0)):
        raise InputError(f"--q0 must be finite, got {text!r}")
    if degrees:
        q0[revolute] = np.radians(q0[revolute])
    return q0


def evaluate(robot, forward: bool, args) -> int:
    """The job of `deltagen fk|ik` for a delta robot, a linear delta, a tripod or a serial
    arm; returns the exit status."""
    job = make_job(robot, forward, args)
    if args.output is not None:
        output_format(args.output)  # a bad file name fails before any work
    if args.input is not None:
        if args.values:
            raise InputError(
                f"give the poses either as values or with --input, not both "
                f"(got {len(args.values)} values and --input {args.input})"
            )
        if forward and job.serial and args.config is not None:
            raise InputError("give either --config NAME or --input FILE, not both")
        data, layout, _ = read_table(args.input, job.layouts, job.what)
        return _batch(job, job.prepare(data, layout), args.output)
    return _single(job, args)


def _batch(job, x, output) -> int:
    out, valid, names = job.compute(x)
    write_table(output if output is not None else sys.stdout, names, out, valid)
    bad = np.flatnonzero(~valid)
    if bad.size:
        shown = ", ".join(str(r) for r in bad[:10]) + (", ..." if bad.size > 10 else "")
        print(
            f"{bad.size} of {len(valid)} rows failed (NaN, valid = 0): data rows {shown} "
            "(counted from 0)",
            file=sys.stderr,
        )
        return EXIT_INVALID
    return EXIT_OK


def _single(job, args) -> int:
    robot = job.robot
    values = list(args.values)
    if job.forward and job.serial and args.config is not None:
        if values:
            raise InputError("give either joint values or --config NAME, not both")
        q = _configuration(robot, args.config)[None]  # radians, as in the robot file
        x = q
    else:
        if not values:
            raise InputError(f"give the {_expected(job)} (or --input FILE)")
        width = [lay for lay in job.layouts if lay.positional and len(values) in lay.widths()]
        if not width:
            raise InputError(f"{job.what}: give {_expected(job)}; got {len(values)} values")
        for v in values:
            if not math.isfinite(v):
                raise InputError(f"{job.what}: every value must be a finite number, got {v!r}")
        data = np.array([values], dtype=np.float64)
        x = job.prepare(data, job.layouts.index(width[0]))
    out, valid, names = job.compute(x)
    if args.output is not None:
        write_table(args.output, names, out, valid)
    if not valid[0]:
        print(
            f"deltagen {'fk' if job.forward else 'ik'}: no valid result: {job.explain(x)}",
            file=sys.stderr,
        )
        return EXIT_INVALID
    if args.output is None:
        _show(job, x, out[0])
    return EXIT_OK


def _expected(job) -> str:
    if not job.serial:
        return (
            "3 joint angles q1 q2 q3 (or 4 with the fourth axis q4)"
            if job.forward
            else "3 coordinates x y z (or 4 with the fourth axis phi)"
        )
    if job.forward:
        return f"{job.robot.n} joint values q1 .. q{job.robot.n} (or --config NAME)"
    return "the pose as 6 values x y z psi theta phi (m, rad)"


def _units(job) -> str:
    units = ["deg" if (job.degrees and r) else ("rad" if r else "m") for r in job.revolute]
    if not job.serial:
        units = units[:3]
    return units[0] if len(set(units)) == 1 else "(" + ", ".join(units) + ")"


def _show(job, x, row) -> None:
    robot = job.robot
    if job.forward and job.serial:
        T = row[6:].reshape(4, 4)
        psi, theta, phi = row[3:6]
        with np.printoptions(precision=6, suppress=True):
            print(f"{robot.name}: T =\n{T}")
        print("position  x, y, z = [" + ", ".join(f"{v:.9g}" for v in row[:3]) + "] m")
        print(
            f"Euler (Vukobratovic, R = Rz(psi) Ry(theta) Rx(phi)): psi = "
            f"{np.degrees(psi):.6g} deg, theta = {np.degrees(theta):.6g} deg, "
            f"phi = {np.degrees(phi):.6g} deg"
        )
    elif job.forward:
        print(
            "p = ["
            + ", ".join(f"{v:.12g}" for v in row[:3])
            + "] m"
            + (f", phi = {row[3]:.12g} rad" if row.size == 4 else "")
        )
    else:
        print("q = [" + ", ".join(f"{v:.12g}" for v in row) + f"] {_units(job)}")


MACHINE_POSE = ("px", "py", "pz", "dx", "dy", "dz")


def evaluate_machine(machine, forward: bool, args) -> int:
    """`deltagen fk|ik` of a 5-axis machine: joints x, y, z, tilt, C <-> tool tip and axis."""
    refuse_options(
        args, ("config", "method", "restarts"), "applies to serial arms, not to a 5-axis machine"
    )
    if forward and args.q0 is not None:
        raise InputError("--q0 applies to ik (the joints the path starts from), not to fk")
    joints = ("x", "y", "z", machine.description.tilt_axis.lower(), "c")
    what = f"{'fk' if forward else 'ik'} of {machine.name}"
    previous = None
    if args.q0 is not None:
        try:
            previous = np.array([float(t) for t in args.q0.replace(",", " ").split()])
        except ValueError:
            previous = np.array([])
        if previous.shape != (5,) or not np.all(np.isfinite(previous)):
            raise InputError(f"--q0 {args.q0!r}: give 5 finite numbers x,y,z,{joints[3]},c")
        if args.degrees:
            previous[3:] = np.radians(previous[3:])
    if args.output is not None:
        output_format(args.output)
    wanted = joints if forward else MACHINE_POSE
    if args.input is not None:
        if args.values:
            raise InputError("give the poses either as values or with --input, not both")
        x, _, _ = read_table(args.input, [Columns(wanted)], what)
    else:
        values = list(args.values)
        if len(values) != len(wanted):
            raise InputError(
                f"{what}: give {len(wanted)} values {' '.join(wanted)}; got {len(values)}"
            )
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{what}: every value must be a finite number")
        x = np.array([values], dtype=np.float64)
    with np.errstate(all="ignore"):
        if forward:
            q = x.copy()
            if args.degrees:
                q[:, 3:] = np.radians(q[:, 3:])
            p, d, valid = machine.fk(q, errors="nan")
            out, names = np.column_stack([p, d]), MACHINE_POSE
        else:
            out, valid = machine.ik_path(x[:, :3], x[:, 3:], previous, errors="nan")
            if args.degrees:
                out[:, 3:] = np.degrees(out[:, 3:])
            names = joints
    valid = np.asarray(valid, dtype=bool) & np.all(np.isfinite(out), axis=1)
    out[~valid] = np.nan
    if args.input is not None or args.output is not None:
        write_table(args.output if args.output is not None else sys.stdout, names, out, valid)
    bad = np.flatnonzero(~valid)
    if bad.size:
        print(
            f"deltagen {'fk' if forward else 'ik'}: {bad.size} of {len(valid)} rows have no valid "
            f"result (NaN, valid = 0): a non-finite value, a zero tool axis d, or (ik) the tilt "
            "beyond its travel on both branches",
            file=sys.stderr,
        )
        return EXIT_INVALID
    if args.input is None and args.output is None:
        unit = "deg" if args.degrees else "rad"
        if forward:
            print("p = [" + ", ".join(f"{v:.12g}" for v in out[0, :3]) + "] m")
            print("d = [" + ", ".join(f"{v:.12g}" for v in out[0, 3:]) + "]")
        else:
            print(
                "j = ["
                + ", ".join(f"{v:.12g}" for v in out[0])
                + f"] (x, y, z m; {joints[3].upper()}, C {unit})"
            )
    return EXIT_OK


# ---------------------------------------------------------------- the commands


def _evaluate_hexapod(robot, forward: bool, args) -> int:
    from deltagen.apps.hexapod import evaluate as hexapod_evaluate  # it imports this module

    return hexapod_evaluate(robot, forward, args)


#: The job of fk and ik for each robot kind they serve (apps/robots.py): the 5-axis machine
#: and the hexapod have their own columns, the other kinds the general job (make_job).
JOBS = {
    robots.DELTA: evaluate,
    robots.SERIAL: evaluate,
    robots.COUPLED: evaluate,
    robots.LINEAR_DELTA: evaluate,
    robots.TRIPOD: evaluate,
    robots.HEXAPOD: _evaluate_hexapod,
    robots.MACHINE: evaluate_machine,
}

EXIT_STATUS = """\
exit status:
  0  success: every pose computed
  1  computed, but some rows have no valid result (unreachable, singular, outside the
     joint limits, or a row of the input file with NaN/inf); those rows are NaN with
     valid = 0 in the output, and a message on stderr names them
  2  usage or input error: bad arguments, an unreadable or malformed file, missing columns"""

FILES = """\
files (--input, --output): CSV or NPY, one pose per row, columns matched by name:
  CSV  a header line names the columns, plain (q1,q2,q3) or numpy's (# q1,q2,q3); without
       one the columns are positional
  NPY  a structured array whose field names are the column names (what deltagen writes:
       float64 fields, valid as bool); a plain 2-D array is positional
  Other columns (valid, ...) are ignored, so ik reads what fk writes and the other way round.
  Delta: q1,q2,q3[,q4] <-> x,y,z[,phi] (q4 the fourth axis, phi the platform's turn it
  gives, delta report eq. (43)). Serial arm: q1..qn <-> x,y,z,psi,theta,phi (Euler angles
  after Vukobratovic, R = Rz(psi) Ry(theta) Rx(phi)), T11..T44; ik uses T11..T34 when present.
  --output: the extension (.csv, .txt or .npy, any case) picks the format."""


def add_parser(subparsers) -> None:
    """`deltagen fk` and `deltagen ik` (their values and options may be intermixed: the
    command line parses them with parse_intermixed_args)."""
    import argparse

    for name, forward in (("fk", True), ("ik", False)):
        what = "direct" if forward else "inverse"
        e = subparsers.add_parser(
            name,
            help=f"{what} kinematics of one pose or of a CSV/NPY batch",
            description=f"{what.capitalize()} kinematics of the delta robot or a serial arm: "
            "one pose from the values, or a batch with --input.",
            epilog=FILES + "\n\n" + EXIT_STATUS,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        e.add_argument("robot", nargs="?", default="default", help=robots.ROBOT_HELP)
        e.add_argument(
            "values",
            nargs="*",
            type=float,
            help=(
                "joint coordinates q1 .. qn: delta q1 q2 q3 [q4, the fourth axis]; serial arm one "
                "per joint (rad, m for prismatic joints)"
                if forward
                else "the pose: delta x y z [phi] (m, rad); serial arm x y z psi theta phi (m, rad)"
            ),
        )
        e.add_argument("--input", help="CSV or NPY file with one pose per row (see below)")
        e.add_argument(
            "--output", help="write the result here (.csv, .txt or .npy), also for a single pose"
        )
        e.add_argument(
            "--degrees",
            action="store_true",
            help="revolute joint coordinates in degrees (prismatic stay in m; "
            + ("the input q" if forward else "the output q and --q0")
            + "; poses are always m and rad)",
        )
        if forward:
            e.add_argument(
                "--config",
                help="serial arm: a named joint configuration of its "
                "robot file (e.g. qr) instead of values",
            )
        else:
            e.add_argument(
                "--config", help="serial arm: the closed-form branch by name (e.g. front_up_noflip)"
            )
            e.add_argument(
                "--q0",
                help="serial arm: start of the numeric solver, or with a "
                "closed form the branch nearest it: n numbers "
                "(--q0=-0.1,0.2,...) or a configuration name (e.g. qn)",
            )
            e.add_argument(
                "--method",
                choices=("auto", "analytic", "numeric"),
                help="serial arm: auto (default: closed form if the arm has one), "
                "analytic, or numeric (damped Newton)",
            )
            e.add_argument(
                "--restarts",
                type=int,
                help="serial arm, --method numeric: random restarts when a start does not converge",
            )
        e.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
        robots.add_urdf_options(e)
        e.set_defaults(command=name, q0=None, method=None, restarts=None)


def run(args) -> int:
    """`deltagen fk|ik`: the job of the robot's kind (JOBS); returns the exit status."""
    return robots.run_job(args, JOBS, args.command == "fk")
