"""The hexapod's (Stewart-Gough platform) jobs of the commands: `deltagen fk | ik HEXAPOD.toml
...` (:func:`evaluate`: one pose as values or a batch, ``--input`` CSV/NPY,
:mod:`deltagen.apps.tables`) and `deltagen workspace` (:func:`write_workspace`); its export
is apps/export.py's (the example pose below).

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

from deltagen.apps.kinematics import SERIAL_ONLY, refuse_options
from deltagen.apps.tables import Columns, output_format, read_table, write_table
from deltagen.errors import DeltagenError
from deltagen.geometry.rotations import rpy
from deltagen.inputs import InputError, check_memory

LENGTHS = tuple(f"l{i + 1}" for i in range(6))
#: Bytes a point of the position workspace's grid takes at the peak (Hexapod.position_workspace
#: and limits, float64): the grid and its positions (3 + 3), the pose and its masked copies
#: (3 x 16), lengths (6), joint angles (12), the Jacobian with its singular values (36 + 6)
#: and the condition numbers (2), plus the masks.
BYTES_PER_POINT = 8 * (3 + 3 + 3 * 16 + 6 + 12 + 36 + 6 + 2) + 8
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


def evaluate(robot, forward: bool, args) -> int:
    """The job of `deltagen fk|ik` for a hexapod; returns the exit status."""
    refuse_options(args, SERIAL_ONLY, "applies to serial arms, not to a hexapod")
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


def write_workspace(robot, out, step=None, quiet=False) -> list:
    """`deltagen workspace HEXAPOD.toml`: the position workspace at R = I over a box around
    the home position (edge ``step``, default size / 20) and the orientation workspace
    (roll x pitch, yaw 0, +-45 deg) at the home position, drawn as PNG slices coloured by the
    condition number of J (grey: not reachable), the position workspace as the 3D page
    (apps/workspace.py write_page: the reachable positions and the hexapod moving on a
    slider), and the summary numbers as CSV. Returns the files written."""
    import csv
    from pathlib import Path

    from deltagen.apps.plotting import pyplot
    from deltagen.apps.workspace import write_page

    g = robot.geometry
    size = g.size
    step = size / 20 if step is None else step
    if not (math.isfinite(step) and step > 0):
        raise InputError(f"--step must be a positive length [m], got {step}")
    half = 0.6 * size
    hz = np.array(g.home_position)
    z_low = max(hz[2] - half, step)
    nx = math.floor(2 * half / step + 0.5) + 1.0  # the lengths of the aranges below, as floats
    nz = max(math.floor((hz[2] + half - z_low) / step + 0.5) + 1.0, 0.0)
    check_memory(
        nx * nx * nz * BYTES_PER_POINT,
        f"the hexapod's position grid at --step = {step:g} m ({nx:.0f} x {nx:.0f} x {nz:.0f} = "
        f"{nx * nx * nz:.3g} points)",
        "choose a larger --step (each halving needs 8 times the memory)",
    )
    x = np.arange(-half, half + step / 2, step)
    z = np.arange(z_low, hz[2] + half + step / 2, step)
    ws = robot.position_workspace(x + hz[0], x + hz[1], z)
    angles = np.radians(np.linspace(-45, 45, 61))
    ows = robot.orientation_workspace(angles, angles, [0.0])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plt = pyplot()
    zi = np.flatnonzero(ws.reachable.any(axis=(0, 1)))
    if zi.size == 0:
        raise DeltagenError("no pose of the grid is reachable: no slices to draw")
    levels = np.unique(np.linspace(zi.min(), zi.max(), 5).round().astype(int)[1:-1])
    finite = ws.condition[np.isfinite(ws.condition)]
    vmax = float(finite.max()) if finite.size else 2.0
    fig, axes = plt.subplots(
        1, len(levels) + 1, figsize=(3.6 * (len(levels) + 1) + 1, 3.8), layout="constrained"
    )
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")  # grey: not reachable
    im = None
    for ax, k in zip(axes[:-1], levels):
        im = ax.imshow(
            ws.condition[:, :, k].T,
            origin="lower",
            cmap=cmap,
            vmin=1,
            vmax=vmax,
            extent=(ws.axes[0][0], ws.axes[0][-1], ws.axes[1][0], ws.axes[1][-1]),
        )
        ax.set_title(f"z = {ws.axes[2][k]:.3f} m, R = I")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    deg = np.degrees(angles)
    im = axes[-1].imshow(
        ows.condition[:, :, 0].T,
        origin="lower",
        cmap=cmap,
        vmin=1,
        vmax=vmax,
        extent=(deg[0], deg[-1], deg[0], deg[-1]),
    )
    axes[-1].set_title("orientations at home, yaw = 0")
    axes[-1].set_xlabel("roll [deg]")
    axes[-1].set_ylabel("pitch [deg]")
    fig.colorbar(im, ax=axes, label="condition number of J (grey: not reachable)")
    fig.suptitle(f"deltagen workspace: hexapod {g.name} (leg limits, joint cones, cond(J))")
    slices = out / "workspace_slices.png"
    fig.savefig(slices, dpi=110)
    plt.close(fig)
    page = write_page(
        robot,
        ws,
        out / "workspace.html",
        trajectory=_demo_poses(robot),
        title=f"deltagen workspace: hexapod {g.name} (positions at R = I, cond(J))",
        skeleton=hexapod_skeleton,
    )
    summary = {
        "grid_step_m": step,
        "position_points": ws.reachable.size,
        "position_reachable_fraction": ws.fraction,
        "position_reachable_volume_m3": float(ws.reachable.sum()) * step**3,
        "orientation_reachable_fraction": ows.fraction,
        "best_condition": float(np.nanmin(ws.condition)) if finite.size else math.nan,
    }
    table = out / "workspace_summary.csv"
    with table.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["quantity", "value"])
        for key, value in summary.items():
            w.writerow([key, repr(float(value))])
    if not quiet:
        for key, value in summary.items():
            print(f"{key:>32}  {value:.6g}")
        for p in (slices, page, table):
            print(f"wrote {p}")
    return [slices, page, table]


def hexapod_skeleton(robot, T) -> np.ndarray:
    """Polyline points (K, 3) [m] of the hexapod at pose T (4, 4): the base hexagon, the
    platform hexagon and the six legs, NaN rows between the pieces."""
    g = robot.geometry
    a = np.asarray(g.base_joints, dtype=float)
    b = np.asarray(T, dtype=float)[:3, :3] @ np.asarray(g.platform_joints, dtype=float).T
    b = b.T + np.asarray(T, dtype=float)[:3, 3]
    gap = np.full((1, 3), np.nan)
    ring = [0, 1, 2, 3, 4, 5, 0]
    parts = [a[ring], gap, b[ring], gap]
    for i in range(6):
        parts += [np.stack([a[i], b[i]]), gap]
    return np.concatenate(parts[:-1])


def _demo_poses(robot, n: int = 24) -> np.ndarray:
    """Poses (n, 4, 4) for the page's slider: a circle of 0.05 x the robot's size about the
    home position, the platform rolling and pitching by 0.1 rad with it."""
    t = np.linspace(0.0, 2 * math.pi, n)
    r = 0.05 * robot.geometry.size
    home = np.asarray(robot.geometry.home_position, dtype=float)
    p = home + np.stack([r * np.cos(t), r * np.sin(t), np.zeros(n)], axis=-1)
    rpy = np.stack([0.1 * np.sin(t), 0.1 * np.cos(t), np.zeros(n)], axis=-1)
    return robot.pose(p, rpy=rpy)


#: the pose of the exported example (`deltagen export`, apps/export.py): a shifted, tilted
#: platform [m, rad]
EXAMPLE_POSITION = (0.01, -0.02, 0.0)  # added to the home position
EXAMPLE_RPY = (0.05, 0.02, -0.1)
