"""Command line: deltagen generate | validate | fk | ik | bench."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np


def _robot(args):
    """'default' (the delta robot), a bundled serial arm's name, or a robot TOML file."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.serial import SerialRobot, bundled_robots

    name = args.robot
    if name in (None, "default"):
        return DeltaRobot.default(backend=args.backend)
    if name in bundled_robots():
        return SerialRobot.load(name, backend=args.backend)
    path = Path(name)
    if path.suffix != ".toml" and not path.exists():
        raise ValueError(f"unknown robot {name!r}: use 'default', a bundled arm "
                         f"({', '.join(bundled_robots())}) or a robot .toml file")
    text = path.read_text() if path.is_file() else ""
    if "convention" in text:
        return SerialRobot.from_toml(path, backend=args.backend)
    return DeltaRobot.from_toml(path, backend=args.backend)


def cmd_generate(args) -> int:
    from deltagen.apps import generate

    if args.robot_file:
        folder = generate.generate_robot_file(args.robot_file)
        from deltagen.paths import runtime_dir

        print(f"generated and compiled {args.robot_file}: C sources in {folder} "
              f"(compile them with the runtime C in {runtime_dir()})")
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
        print(f"warning: generated/{name} is not produced by the generator; delete it "
              "(`deltagen generate --check` fails while it is there)", file=sys.stderr)
    return 0


def _read_batch(path: Path) -> np.ndarray:
    if path.suffix == ".npy":
        return np.load(path, allow_pickle=False)
    return np.loadtxt(path, delimiter=",", ndmin=2, comments="#")


def _write_batch(path: Path, data: np.ndarray, header: str) -> None:
    if path.suffix == ".npy":
        np.save(path, data)
    else:
        np.savetxt(path, data, delimiter=",", header=header, fmt="%.17g")


def _evaluate_serial(args, arm, forward: bool) -> int:
    from deltagen.geometry.rotations import euler_zyx

    if not forward:
        print("inverse kinematics of serial arms is not available yet (issue 4)", file=sys.stderr)
        return 2
    if args.input:
        data = _read_batch(Path(args.input))
        if args.degrees:
            data = np.radians(data)
        T, valid = arm.fk(data, errors="nan")
        table = np.column_stack([T[..., :3, 3], euler_zyx(T[..., :3, :3]), T.reshape(-1, 16),
                                 valid.astype(float)])
        names = "x,y,z,psi,theta,phi," + ",".join(f"T{r}{c}" for r in range(1, 5)
                                                  for c in range(1, 5)) + ",valid"
        if args.output:
            _write_batch(Path(args.output), table, names)
        else:
            np.savetxt(sys.stdout, table, delimiter=",", header=names, fmt="%.17g")
        return 0
    if not args.values and args.config:
        values = arm.configuration(args.config)
    else:
        values = np.array(args.values, dtype=float)
        if args.degrees:
            values = np.radians(values)
    if values.shape != (arm.n,):
        print(f"{arm.name} has {arm.n} joints: give {arm.n} values (or --config NAME)", file=sys.stderr)
        return 2
    T = arm.fk(values)
    psi, theta, phi = euler_zyx(T[:3, :3])
    np.set_printoptions(precision=6, suppress=True)
    print(f"{arm.name}: T =\n{T}")
    print("position  x, y, z = [" + ", ".join(f"{v:.9g}" for v in T[:3, 3]) + "] m")
    print(f"Euler (Vukobratovic, R = Rz(psi) Ry(theta) Rx(phi)): psi = {np.degrees(psi):.6g} deg, "
          f"theta = {np.degrees(theta):.6g} deg, phi = {np.degrees(phi):.6g} deg")
    return 0


def _evaluate(args, forward: bool) -> int:
    robot = _robot(args)
    from deltagen.api.serial import SerialRobot

    if isinstance(robot, SerialRobot):
        return _evaluate_serial(args, robot, forward)
    fn = robot.fk if forward else robot.ik
    if args.input:
        data = _read_batch(Path(args.input))
        if args.degrees and forward:
            data = np.radians(data)
        out, valid = fn(data, errors="nan")
        if args.degrees and not forward:
            out = np.degrees(out)
        table = np.column_stack([out, valid.astype(float)])
        names = ("x,y,z" if forward else "q1,q2,q3") + (",q4" if out.shape[1] == 4 else "") + ",valid"
        if args.output:
            _write_batch(Path(args.output), table, names)
        else:
            np.savetxt(sys.stdout, table, delimiter=",", header=names, fmt="%.17g")
        bad = int((~valid).sum())
        if bad:
            print(f"{bad} of {len(valid)} rows failed (NaN, valid = 0)", file=sys.stderr)
        return 0
    if len(args.values) not in (3, 4):
        print("give 3 values (or 4 with the fourth axis), or --input FILE", file=sys.stderr)
        return 2
    values = np.array(args.values, dtype=float)
    if args.degrees and forward:
        values = np.radians(values)
    out = fn(values)
    if forward:
        print("p = [" + ", ".join(f"{v:.12g}" for v in out[:3]) + "] m"
              + (f", phi = {out[3]:.12g} rad" if out.size == 4 else ""))
    else:
        shown = np.degrees(out) if args.degrees else out
        unit = "deg" if args.degrees else "rad"
        print("q = [" + ", ".join(f"{v:.12g}" for v in shown) + f"] {unit}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="deltagen", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="regenerate generated/ (deterministic)")
    g.add_argument("robot_file", nargs="?", help="a serial-arm TOML: generate, compile and cache its module")
    g.add_argument("--check", action="store_true", help="fail and show a diff if generated/ is stale")
    g.set_defaults(func=cmd_generate)

    evaluators = {}
    for name, forward in (("fk", True), ("ik", False)):
        e = evaluators[name] = sub.add_parser(name, help=("direct" if forward else "inverse") + " kinematics of one pose or a CSV/NPY batch")
        e.add_argument("robot", nargs="?", default="default",
                       help="'default' (delta), a bundled arm name, or a robot TOML file")
        e.add_argument("values", nargs="*", type=float,
                       help="q1 q2 q3 [q4] in rad" if forward else "x y z [phi] in m (rad)")
        e.add_argument("--input", help="CSV or NPY file with one pose per row")
        e.add_argument("--output", help="write the batch result here (CSV or NPY)")
        e.add_argument("--degrees", action="store_true", help="joint angles in degrees")
        e.add_argument("--config", help="a serial arm's named configuration (e.g. qr)")
        e.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
        e.set_defaults(func=lambda a, f=forward: _evaluate(a, f))

    v = sub.add_parser("validate", help="the report's validation trajectory, eqs. (40)-(42)")
    v.add_argument("--robot", default="default", help="'default' or a robot TOML file")
    v.add_argument("--rate", type=float, default=1000.0, help="sample rate [Hz] (default 1000)")
    v.add_argument("--duration", type=float, default=10.0, help="duration [s] (default 10)")
    v.add_argument("--out", default="validation", help="folder for the CSV and PNG")
    v.add_argument("--no-plot", action="store_true", help="skip the PNG figure")
    v.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    v.add_argument("--quiet", action="store_true", help="no progress output")
    v.set_defaults(func=lambda a: _lazy("deltagen.apps.validate", a))

    d = sub.add_parser("demo", help="worked examples: the lecture's SCARA table, the Miskolc pick and place")
    d.add_argument("name", choices=("lecture-scara", "miskolc-pick-and-place"))
    d.add_argument("--out", default=None,
                   help="folder for PNG/CSV output (miskolc default: miskolc_pick_and_place; "
                        "lecture-scara writes its plot only when given)")
    d.set_defaults(func=lambda a: _lazy("deltagen.apps.demos", a))

    b = sub.add_parser("bench", help="throughput and latency, compiled vs reference")
    b.add_argument("--n", type=int, default=1_000_000, help="batch size (default 10^6)")
    b.add_argument("--repeats", type=int, default=7, help="repeats per measurement (median)")
    b.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    b.set_defaults(func=lambda a: _lazy("deltagen.apps.bench", a))

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in evaluators:
        # options may come between the values (`fk default --degrees 20 20 20`); argparse
        # cannot intermix with subparsers, so the evaluating subcommands parse themselves
        args = evaluators[argv[0]].parse_intermixed_args(argv[1:])
        args.command = argv[0]
    else:
        args = parser.parse_args(argv)
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


def _lazy(module: str, args) -> int:
    import importlib

    return importlib.import_module(module).main(args)


if __name__ == "__main__":
    sys.exit(main())
