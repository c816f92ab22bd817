"""Command line: deltagen generate | validate | fk | ik | dynamics | workspace | sweep | demo |
export | calibrate | bench."""

from __future__ import annotations

import argparse
import os
import re
import sys


def _robot(args, spec=None, command=None, kinds=None):
    """The robot of a command (deltagen.apps.robots.load_robot: 'default', a bundled arm's
    name, a delta or serial-arm TOML, a Klipper printer.cfg or a URDF, with the URDF
    options --base, --tip, --locked); refused (exit status 2) when ``command`` serves only
    ``kinds``."""
    from deltagen.apps.robots import load_robot, parse_locked

    return load_robot(
        args.robot if spec is None else spec,
        getattr(args, "backend", None) or "compiled",
        base=getattr(args, "base", None),
        tip=getattr(args, "tip", None),
        locked=parse_locked(getattr(args, "locked", None)),
        command=command or args.command,
        kinds=kinds,
    )


def _add_urdf_options(p) -> None:
    """--base, --tip, --locked: the chain of a URDF robot (SerialRobot.from_urdf)."""
    p.add_argument(
        "--base", metavar="LINK", help="URDF: the chain's first link (default: the root)"
    )
    p.add_argument(
        "--tip",
        metavar="LINK",
        help="URDF: the chain's last link (default: the single leaf; needed when the tree "
        "branches, e.g. an arm with a two-finger gripper)",
    )
    p.add_argument(
        "--locked",
        metavar="NAME=VALUE",
        action="append",
        help="URDF: the value [rad or m] of a movable joint off the chain (or above --base), "
        "where its link's mass is folded in (default 0); repeatable",
    )


def cmd_generate(args) -> int:
    from deltagen.apps import generate
    from deltagen.inputs import InputError

    if args.robot_file:
        from deltagen.apps.robots import COUPLED, KIND_NAMES, MACHINE, SERIAL, kind_of

        args.backend = "reference"  # the module is built below, once
        robot = _robot(args, args.robot_file)
        if kind_of(robot) == MACHINE:
            raise InputError(
                f"`deltagen generate ROBOT_FILE` takes a serial arm; {args.robot_file} describes "
                "a 5-axis NC machine, whose core is generic (`deltagen generate` writes it; the "
                f"geometry is read at run time), so use the file directly: `deltagen fk "
                f"{args.robot_file} ...`"
            )
        if kind_of(robot) not in (SERIAL, COUPLED):
            raise InputError(
                "`deltagen generate ROBOT_FILE` takes a serial arm: a serial-arm file (a "
                "`convention` key and [[joint]] tables), a URDF or a bundled arm's name; "
                f"{args.robot_file} "
                f"describes {KIND_NAMES[kind_of(robot)]}, whose core is generic (`deltagen generate` writes it; "
                f"the geometry is read at run time), so use the file directly: "
                f"`deltagen fk {args.robot_file} ...`"
            )
        folder = generate.generate_robot(robot)
        from deltagen.paths import runtime_dir

        print(
            f"generated and compiled {args.robot_file}: C sources in {folder} "
            f"(compile them with the runtime C in {runtime_dir()})"
        )
        return 0
    if args.check:
        problems = generate.check()
        for text in problems:
            print(text, file=sys.stderr)
        if problems:
            print("generated/ is stale: run `deltagen generate`", file=sys.stderr)
            return 1
        print("generated/ is up to date")
        return 0
    written = generate.write()
    for path in written:
        print(f"wrote {path}")
    if not written:
        print("generated/ already up to date")
    for name in generate.stray():
        print(
            f"warning: generated/{name} is not produced by the generator; delete it "
            "(`deltagen generate --check` fails while it is there)",
            file=sys.stderr,
        )
    return 0


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

EXIT_STATUS_ALL = """\
exit status:
  0  success
  1  ran, but the result is not valid: fk/ik rows without a valid result, a stale
     generated/ (generate --check), a tolerance missed (validate)
  2  usage or input error (bad arguments, an unreadable or malformed file, a grid or
     sweep larger than DELTAGEN_MAX_MEMORY, an input file larger than DELTAGEN_MAX_INPUT)
  130  interrupted (Ctrl-C)"""

ROBOT_HELP = (
    "'default' (the delta robot), a bundled serial arm's or 5-axis machine's name, a robot "
    "TOML file, a URDF, or a Klipper printer.cfg (kinematics: rotary_delta)"
)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error (the usage is one `--help` away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


_NEGATIVE_NUMBER = re.compile(r"-(\d|\.\d|inf|nan)", re.IGNORECASE)


def _protect_negative_numbers(argv):
    """argparse takes '-1e+16', '-inf' or '--q0 -0.1,0.2' for options (it only knows
    '-1' and '-1.5' as numbers); a leading space keeps them values (float() ignores it)."""
    return [" " + a if _NEGATIVE_NUMBER.match(a) else a for a in argv]


def main(argv=None) -> int:
    try:
        return _main(argv)
    except KeyboardInterrupt:  # Ctrl-C: the shell's 128 + SIGINT, no traceback
        name = (list(sys.argv[1:] if argv is None else argv) or [""])[0]
        command = f"deltagen {name}" if not str(name).startswith("-") and name else "deltagen"
        print(f"{command}: interrupted", file=sys.stderr)
        return 130


def _main(argv=None) -> int:
    parser = _Parser(
        prog="deltagen",
        description=__doc__,
        epilog=EXIT_STATUS_ALL,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="regenerate generated/ (deterministic)")
    g.add_argument(
        "robot_file",
        nargs="?",
        help="a serial-arm TOML, a URDF or a bundled arm's name: generate, compile and "
        "cache its module",
    )
    _add_urdf_options(g)
    g.add_argument(
        "--check", action="store_true", help="fail and show a diff if generated/ is stale"
    )
    g.set_defaults(func=cmd_generate)

    evaluators = {}
    for name, forward in (("fk", True), ("ik", False)):
        what = "direct" if forward else "inverse"
        e = evaluators[name] = sub.add_parser(
            name,
            help=f"{what} kinematics of one pose or of a CSV/NPY batch",
            description=f"{what.capitalize()} kinematics of the delta robot or a serial arm: "
            "one pose from the values, or a batch with --input.",
            epilog=FILES + "\n\n" + EXIT_STATUS,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        e.add_argument("robot", nargs="?", default="default", help=ROBOT_HELP)
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
        _add_urdf_options(e)
        e.set_defaults(
            func=lambda a, f=forward: _evaluate(a, f), q0=None, method=None, restarts=None
        )

    v = sub.add_parser("validate", help="the report's validation trajectory, eqs. (40)-(42)")
    v.add_argument(
        "--robot", default="default", help="a delta robot: 'default', a TOML or a printer.cfg"
    )
    v.add_argument("--rate", type=float, default=1000.0, help="sample rate [Hz] (default 1000)")
    v.add_argument("--duration", type=float, default=10.0, help="duration [s] (default 10)")
    v.add_argument("--out", default="validation", help="folder for the CSV and PNG")
    v.add_argument("--no-plot", action="store_true", help="skip the PNG figure")
    v.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    v.add_argument("--quiet", action="store_true", help="no progress output")
    _add_urdf_options(v)
    v.set_defaults(func=_validate)

    d = sub.add_parser(
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
    d.set_defaults(func=lambda a: _lazy("deltagen.apps.demos", a))

    y = sub.add_parser(
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
    _add_urdf_options(y)
    y.set_defaults(func=_dynamics)

    w = sub.add_parser(
        "workspace",
        help="workspace and dexterity maps of a robot (PNG slices, 3D HTML page, summary)",
        description="Usable workspace on a voxel grid (delta: ik over a box, crank limits "
        "+-90 deg, condition number of J <= --max-condition; serial arm: position-only "
        "reach by joint sampling), the largest inscribed cylinder and box (delta), and "
        "pictures: workspace_slices.png, workspace.html (self-contained, plotly), "
        "workspace_summary.csv in --out.",
    )
    w.add_argument("robot", nargs="?", default="default", help=ROBOT_HELP)
    w.add_argument("--out", default="workspace", help="output folder (default: workspace)")
    w.add_argument("--step", type=float, default=None, help="voxel edge [m] (default: size/40)")
    w.add_argument(
        "--max-condition", type=float, default=10.0, help="delta: bound on cond(J) (default 10)"
    )
    w.add_argument("--quiet", action="store_true", help="no progress bars or summary")
    w.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    _add_urdf_options(w)
    w.set_defaults(func=_workspace)

    s = sub.add_parser(
        "sweep",
        help="geometry sweep of a delta robot on Dask (local cluster by default)",
        description="Score the designs of a sweep spec (TOML: design grid|sobol, n, seed, "
        "[ranges] r_a r_b l_a l_b, [score], [move], [constraints], [inertia]; see "
        "deltagen.api.sweep) by workspace volume, usable cylinder, worst condition number "
        "and peak torque; write sweep.csv and pareto.png to --out. Runs on a local Dask "
        "cluster (every core), or on the cluster at --scheduler / DASK_SCHEDULER_ADDRESS.",
    )
    s.add_argument("spec", help="sweep spec (TOML)")
    s.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler address (tcp://host:port); 'inprocess' runs without Dask; "
        "default: DASK_SCHEDULER_ADDRESS, else a local cluster",
    )
    s.add_argument("--workers", type=int, default=None, help="local cluster: worker processes")
    s.add_argument("--out", default="sweep", help="output folder (default: sweep)")
    s.add_argument("--no-plot", action="store_true", help="skip the Pareto plot")
    s.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    s.set_defaults(func=lambda a: _lazy("deltagen.apps.sweep", a))

    x = sub.add_parser(
        "export",
        help="standalone C package of a robot for a controller (CMake, Makefile, example)",
        description="Write a self-contained C99 package of the robot: its generated C "
        "(batched and single-point functions), the runtime C it needs, CMakeLists.txt, a "
        "Makefile, example.c and a README with units, status codes, cost, stack use and "
        "(--float32) the accuracy against double.",
    )
    x.add_argument("robot", help="'delta' or " + ROBOT_HELP)
    x.add_argument("--out", required=True, help="folder to write the package into")
    x.add_argument(
        "--float32",
        action="store_true",
        help="float arithmetic (sinf/cosf/sqrtf); the README states the accuracy against double",
    )
    x.add_argument("--prefix", help="C prefix of functions and files (default deltagen_<robot>)")
    x.add_argument(
        "--no-batch", action="store_true", help="single-point functions only (no batched ones)"
    )
    x.add_argument(
        "--force",
        action="store_true",
        help="overwrite files in --out that an earlier export did not write (e.g. your own "
        "Makefile); without it such a folder is refused",
    )
    _add_urdf_options(x)
    x.set_defaults(func=_export)

    c = sub.add_parser(
        "calibrate",
        help="identify a built delta robot's geometry from measured (q, p) pairs",
        description="Levenberg-Marquardt on fk(q) = p over per-chain parameters; prints "
        "values, 1-sigma uncertainty, residuals before/after and what the data cannot "
        "separate, and whether the fit is valid (exit 0; 1: not valid, no file written without "
        "--force; 2: bad input). DATA.csv: rows q1,q2,q3,x,y,z (rad, m), optional header.",
    )
    c.add_argument("data", help="CSV of measurements: q1,q2,q3,x,y,z")
    c.add_argument("--robot", default="default", help="the nominal robot: " + ROBOT_HELP)
    c.add_argument(
        "--params",
        default="r_a,l_a,l_b,theta,q_offset",
        help="comma-separated: r_a, r_b, l_a, l_b, theta, q_offset (each per chain) or single "
        "entries like l_a[0] (default r_a,l_a,l_b,theta,q_offset)",
    )
    c.add_argument(
        "--sigma",
        type=float,
        help="measurement noise per coordinate [m] if known: the residual is then "
        "chi-square tested against it (else sigma is estimated from the residual)",
    )
    c.add_argument("--degrees", action="store_true", help="q in the file in degrees")
    c.add_argument(
        "--out", help="write the calibrated robot file (TOML) here (only for a valid fit)"
    )
    c.add_argument(
        "--force",
        action="store_true",
        help="write --out even when the fit is not valid (the exit status stays 1)",
    )
    c.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    _add_urdf_options(c)
    c.set_defaults(func=_calibrate)

    b = sub.add_parser("bench", help="throughput and latency, compiled vs reference")
    b.add_argument("--n", type=int, default=1_000_000, help="batch size (default 10^6)")
    b.add_argument("--repeats", type=int, default=7, help="repeats per measurement (median)")
    b.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    b.add_argument("--json", metavar="FILE", help="write the whole result as JSON")
    b.add_argument(
        "--png", metavar="FILE", help="bar chart, deltagen vs peers, log ns per item (matplotlib)"
    )
    b.add_argument(
        "--readme",
        metavar="FILE",
        help="replace FILE's <!-- bench:begin --> ... <!-- bench:end --> section with the run",
    )
    b.add_argument(
        "--compare",
        metavar="REF",
        help="instead: this tree's batched throughput beside REF's, a git commit (measured "
        "from a temporary worktree, fresh processes, alternating rounds) or a `bench --json` "
        "file; prints measure / ref / this / this/ref",
    )
    b.add_argument(
        "--rounds", type=int, default=4, help="with --compare: processes per side (median)"
    )
    b.set_defaults(func=lambda a: _lazy("deltagen.apps.bench", a))

    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] in evaluators:
            # options may come between the values (`fk default --degrees 20 20 20`); argparse
            # cannot intermix with subparsers, so the evaluating subcommands parse themselves
            args = evaluators[argv[0]].parse_intermixed_args(_protect_negative_numbers(argv[1:]))
            args.command = argv[0]
        else:
            args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, argparse printed why)
        return exc.code if isinstance(exc.code, int) else 2
    from deltagen.errors import DeltagenError

    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # e.g. `deltagen validate | head`: the reader left, not an error
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except (DeltagenError, ValueError, OSError) as exc:
        print(f"deltagen {args.command}: error: {exc}", file=sys.stderr)
        return 2


def _evaluate(args, forward: bool) -> int:
    from deltagen.apps import kinematics
    from deltagen.apps.robots import (
        COUPLED,
        DELTA,
        HEXAPOD,
        LINEAR_DELTA,
        MACHINE,
        SERIAL,
        TRIPOD,
        kind_of,
    )

    robot = _robot(args, kinds=(DELTA, SERIAL, COUPLED, LINEAR_DELTA, TRIPOD, HEXAPOD, MACHINE))
    if kind_of(robot) == HEXAPOD:
        from deltagen.apps import hexapod

        return hexapod.run(robot, forward, args)
    return kinematics.run(robot, forward, args)


def _dynamics(args) -> int:
    from deltagen.apps import dynamics
    from deltagen.apps.robots import COUPLED, DELTA, SERIAL

    args.robot_object = _robot(args, kinds=(DELTA, SERIAL, COUPLED))
    return dynamics.main(args)


def _workspace(args) -> int:
    from deltagen.apps import workspace
    from deltagen.apps.robots import DELTA, HEXAPOD, LINEAR_DELTA, SERIAL, TRIPOD, kind_of

    args.robot_object = _robot(args, kinds=(DELTA, SERIAL, LINEAR_DELTA, TRIPOD, HEXAPOD))
    if kind_of(args.robot_object) == HEXAPOD:
        from deltagen.apps import hexapod

        hexapod.write_workspace(args.robot_object, args.out, args.step, args.quiet)
        return 0
    return workspace.main(args)


def _export(args) -> int:
    from deltagen.apps import export
    from deltagen.apps.robots import DELTA, HEXAPOD, LINEAR_DELTA, MACHINE, SERIAL, TRIPOD, kind_of
    from deltagen.inputs import InputError

    args.backend = "reference"  # only the description is needed: no compiled core
    name = args.robot
    kinds = (DELTA, SERIAL, LINEAR_DELTA, TRIPOD, HEXAPOD, MACHINE)
    args.robot_object = _robot(args, "default" if name == "delta" else name, kinds=kinds)
    if kind_of(args.robot_object) == HEXAPOD:
        from deltagen.apps import hexapod

        for flag, value in (
            ("--float32", args.float32),
            ("--prefix", args.prefix),
            ("--no-batch", args.no_batch),
        ):
            if value:
                raise InputError(f"{flag} is not available for a hexapod's export")
        files, output = hexapod.export_hexapod(args.robot_object, args.out, force=args.force)
        print(f"wrote {len(files)} files to {args.out}/: {', '.join(files)}")
        if output:
            print("example output:")
            print(output, end="")
        return 0
    return export.main(args)


def _calibrate(args) -> int:
    from deltagen.apps import calibrate
    from deltagen.apps.robots import DELTA

    args.robot_object = _robot(args, kinds=(DELTA,))
    return calibrate.main(args)


def _validate(args) -> int:
    from deltagen.apps import validate
    from deltagen.apps.robots import DELTA

    args.robot_object = _robot(args, kinds=(DELTA,))
    return validate.main(args)


def _lazy(module: str, args) -> int:
    import importlib

    return importlib.import_module(module).main(args)


if __name__ == "__main__":
    sys.exit(main())
