"""`deltagen fk | ik HEXAPOD.toml ...` for a hexapod (Stewart-Gough platform): one pose as
values or a batch (``--input`` CSV/NPY, :mod:`deltagen.apps.tables`).

==============  ============================  ==============================================
command         reads                         writes
==============  ============================  ==============================================
hexapod fk      l1 .. l6                      x,y,z,roll,pitch,yaw,T11 .. T44,valid
hexapod ik      x,y,z,roll,pitch,yaw          l1 .. l6,valid
==============  ============================  ==============================================

Units: m and rad; R = Rz(yaw) Ry(pitch) Rx(roll). fk starts from the robot file's home
pose (damped Newton, deltagen.api.hexapod). Exit status: 0 every pose computed; 1 some rows
have no valid result (NaN, valid = 0); 2 usage or input error.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from deltagen.apps.tables import Columns, output_format, read_table, write_table
from deltagen.errors import DeltagenError
from deltagen.geometry.rotations import rpy
from deltagen.inputs import InputError

LENGTHS = tuple(f"l{i + 1}" for i in range(6))
POSE = ("x", "y", "z", "roll", "pitch", "yaw")
TRANSFORM = tuple(f"T{r}{c}" for r in range(1, 5) for c in range(1, 5))


def _compute(robot, forward: bool, x: np.ndarray):
    with np.errstate(all="ignore"):
        if forward:
            T, valid = robot.fk(x, errors="nan")
            out = np.column_stack([T[:, :3, 3], rpy(T[:, :3, :3]), T.reshape(-1, 16)])
            names = POSE + TRANSFORM
        else:
            out, valid = robot.ik(robot.pose(x[:, :3], rpy=x[:, 3:]), errors="nan")
            names = LENGTHS
    valid = np.asarray(valid, dtype=bool) & np.all(np.isfinite(out), axis=1)
    out[~valid] = np.nan
    return out, valid, names


def run(robot, forward: bool, args) -> int:
    """The job of `deltagen fk|ik` for a hexapod; returns the exit status."""
    for flag in ("config", "q0", "method", "restarts"):
        if getattr(args, flag, None) is not None:
            raise InputError(f"--{flag} applies to serial arms, not to a hexapod")
    if getattr(args, "degrees", False):
        raise InputError("--degrees applies to joint angles; a hexapod's joints are lengths [m]")
    what = f"{'fk' if forward else 'ik'} of the hexapod {robot.geometry.name}"
    layout = Columns(LENGTHS if forward else POSE)
    if args.output is not None:
        output_format(args.output)
    if args.input is not None:
        if args.values:
            raise InputError("give the poses either as values or with --input, not both")
        x, _, _ = read_table(args.input, [layout], what)
    else:
        values = list(args.values)
        if len(values) != 6:
            expected = "6 leg lengths l1 .. l6 [m]" if forward else "x y z roll pitch yaw (m, rad)"
            raise InputError(f"{what}: give {expected}; got {len(values)} values")
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{what}: every value must be a finite number")
        x = np.array([values], dtype=np.float64)
    out, valid, names = _compute(robot, forward, x)
    if args.input is not None or args.output is not None:
        write_table(args.output if args.output is not None else sys.stdout, names, out, valid)
    bad = np.flatnonzero(~valid)
    if bad.size:
        try:
            (
                robot.fk(x[bad[:1]])
                if forward
                else robot.ik(robot.pose(x[bad[:1], :3], rpy=x[bad[:1], 3:]))
            )
            why = "the result is not finite"
        except DeltagenError as exc:
            why = str(exc)
        print(
            f"deltagen {'fk' if forward else 'ik'}: {bad.size} of {len(valid)} rows have no "
            f"valid result (first: row {bad[0]}): {why}",
            file=sys.stderr,
        )
        return 1
    if args.input is None and args.output is None:
        row = out[0]
        if forward:
            with np.printoptions(precision=9, suppress=True):
                print(f"{robot.geometry.name}: T =\n{row[6:].reshape(4, 4)}")
            print("roll, pitch, yaw = [" + ", ".join(f"{v:.12g}" for v in row[3:6]) + "] rad")
        else:
            print("l = [" + ", ".join(f"{v:.12g}" for v in row) + "] m")
    return 0
