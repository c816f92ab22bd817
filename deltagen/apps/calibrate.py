"""deltagen calibrate DATA.csv: identify the geometry of a built delta robot from measured
pairs (see deltagen.solve.calibration), print the report, optionally write the calibrated
robot file.

Exit status: 0 for a valid fit, 1 for a fit that is not valid (not converged, a parameter
the data cannot place or that ended on its bound, a residual that disagrees with the noise:
CalibrationResult.problems, printed with hints); then no robot file is written unless
``--force``. Bad input (unreadable file, empty data, too few points, bad sigma): exit 2.

DATA.csv: one measurement per row, columns q1, q2, q3 (encoder readings [rad], or deg
with --degrees) and x, y, z (measured platform position in the base frame [m]); an
optional header line.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from deltagen.errors import DeltagenError
from deltagen.inputs import InputError, read_regular_file


def read_measurements(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        lines = read_regular_file(path, "measurements").decode("utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise InputError(f"cannot read {path}: {exc}") from None
    rows = []
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = [f.strip() for f in text.replace(";", ",").split(",")]
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if not rows and number == 1:  # a header
                continue
            raise InputError(f"{path}: line {number} is not 6 numbers: {text!r}") from None
        if len(values) != 6:
            raise InputError(
                f"{path}: line {number} has {len(values)} values, expected 6 (q1 q2 q3 x y z)"
            )
        rows.append(values)
    if not rows:
        raise InputError(f"{path}: no measurements")
    data = np.array(rows)
    return data[:, :3], data[:, 3:]


def geometry_toml(g) -> str:
    """A robot file for the (possibly asymmetric) geometry, without the inertia."""

    def numbers(values):
        return "[" + ", ".join(repr(float(v)) for v in values) + "]"

    lines = [
        f'name = "{g.name}"',
        "[delta]",
        f"r_a = {g.r_a!r}",
        f"r_b = {g.r_b!r}",
        f"l_a = {g.l_a!r}",
        f"l_b = {g.l_b!r}",
        f"theta = {numbers(g.theta)}",
    ]
    for key in ("r_a", "r_b", "l_a", "l_b"):
        if getattr(g, f"chain_{key}") is not None:
            lines.append(f"chain_{key} = {numbers(g.chain(key))}")
    if any(g.q_offset):
        lines.append(f"q_offset = {numbers(g.q_offset)}")
    return "\n".join(lines) + "\n"


def add_parser(subparsers) -> None:
    """`deltagen calibrate DATA.csv [--robot DELTA] ...`."""
    from deltagen.apps.robots import ROBOT_HELP, add_urdf_options

    c = subparsers.add_parser(
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
    add_urdf_options(c)


def run(args) -> int:
    """`deltagen calibrate`: 0 a valid fit, 1 not valid (nothing written without --force)."""
    from deltagen.apps.robots import DELTA, robot_of

    robot = robot_of(args, kinds=(DELTA,))
    q, p = read_measurements(Path(args.data))
    if args.degrees:
        q = np.radians(q)
    params = tuple(s for s in args.params.split(",") if s.strip())
    result = robot.calibrate(q, p, params=params, sigma=args.sigma)
    print(f"deltagen calibrate: {len(q)} measurements, robot {robot.geometry.name!r}")
    print(result.report())
    if not math.isfinite(result.rms_after):
        raise DeltagenError("calibration failed: the residual is not finite")
    if args.out and (result.valid or args.force):
        Path(args.out).write_text(geometry_toml(result.geometry))
        print(f"wrote {args.out}{'' if result.valid else ' (--force: the fit is NOT valid)'}")
    if result.valid:
        return 0
    # the first problem (a residual far above the noise comes first) and the hints; the
    # report above lists every problem
    why = "; ".join(result.problems[:1] + tuple(f"hint: {h}" for h in result.hints))
    more = len(result.problems) - 1
    if more:
        why += f" (and {more} more: see FIT NOT VALID above)"
    unwritten = (
        f"; {args.out} not written (--force writes it)" if args.out and not args.force else ""
    )
    print(f"deltagen calibrate: the fit is not valid: {why}{unwritten}", file=sys.stderr)
    return 1
