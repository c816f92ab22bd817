"""``deltagen workspace ROBOT --out DIR``: workspace and dexterity pictures.

The numbers come from ``robot.workspace(...)`` (deltagen.api.workspace); this module draws

* ``workspace_slices.png``: x-y slices at several heights and the x-z slice through the
  base axis, coloured by the condition number of J (grey: not usable), with colour bars
  and axes in metres (matplotlib, the ``plot`` extra);
* ``workspace.html``: one self-contained interactive 3D page (plotly, the ``design`` extra;
  plotly.js is inlined, so nothing is fetched when it is viewed): the usable points
  coloured by the condition number, the largest inscribed cylinder (delta), and the robot
  drawn in a pose, with a slider that moves it along a trajectory;
* ``workspace_summary.csv``: the summary numbers, one per line.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from deltagen import __version__
from deltagen.apps import robots
from deltagen.apps.plotting import pyplot
from deltagen.errors import DeltagenError

if TYPE_CHECKING:  # the robot classes load when a job runs, not with the parser
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.workspace import DeltaWorkspace, SerialWorkspace

PLOTLY_HINT = "plotly is needed for the 3D page: pip install 'deltagen[design]'"
MAX_POINTS = 20_000  # points drawn in the 3D page (a random, seeded subset beyond that)


def _field(ws):
    """(mask (nx, ny, nz), colour values, colour-bar label) of a workspace result."""
    from deltagen.api.workspace import DeltaWorkspace

    if isinstance(ws, DeltaWorkspace):
        return ws.usable, ws.condition, "condition number of J (delta)"
    return ws.reachable, ws.condition, "condition number of J (best in voxel)"


def write_slices(ws: DeltaWorkspace | SerialWorkspace, path: str | Path, title: str = "") -> Path:
    """PNG of x-y slices at four heights and the x-z slice through the axis (y = 0)."""
    from deltagen.api.workspace import DeltaWorkspace

    plt = pyplot()
    mask, value, label = _field(ws)
    zi = np.flatnonzero(mask.any(axis=(0, 1)))
    if zi.size == 0:
        raise DeltagenError("nothing of the workspace is usable: no slices to draw")
    levels = np.unique(np.linspace(zi.min(), zi.max(), 6).round().astype(int)[1:-1])
    finite = value[mask & np.isfinite(value)]
    vmin, vmax = (1.0, float(finite.max())) if finite.size else (1.0, 2.0)
    fig, axes = plt.subplots(
        1, len(levels) + 1, figsize=(3.6 * (len(levels) + 1) + 1.0, 3.8), layout="constrained"
    )
    ext_xy = (ws.x[0], ws.x[-1], ws.y[0], ws.y[-1])
    ii, jj, kk = np.nonzero(mask)
    pad = 2 * ws.step
    xlim = (ws.x[ii.min()] - pad, ws.x[ii.max()] + pad)
    ylim = (ws.y[jj.min()] - pad, ws.y[jj.max()] + pad)
    zlim = (ws.z[kk.min()] - pad, ws.z[kk.max()] + pad)
    im = None
    for ax, k in zip(axes, levels):
        shown = np.where(mask[:, :, k], value[:, :, k], np.nan).T
        ax.imshow(~mask[:, :, k].T, origin="lower", extent=ext_xy, cmap="Greys", vmin=0, vmax=4)
        im = ax.imshow(shown, origin="lower", extent=ext_xy, cmap="viridis", vmin=vmin, vmax=vmax)
        ax.set_xlim(xlim)
        ax.set_ylim(ylim)
        ax.set_title(f"x-y at z = {ws.z[k]:.3f} m")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal")
    j = int(np.argmin(np.abs(ws.y)))
    ax = axes[-1]
    ext_xz = (ws.x[0], ws.x[-1], ws.z[0], ws.z[-1])
    ax.imshow(~mask[:, j, :].T, origin="lower", extent=ext_xz, cmap="Greys", vmin=0, vmax=4)
    im = ax.imshow(
        np.where(mask[:, j, :], value[:, j, :], np.nan).T,
        origin="lower",
        extent=ext_xz,
        cmap="viridis",
        vmin=vmin,
        vmax=vmax,
    )
    if isinstance(ws, DeltaWorkspace) and ws.cylinder is not None:
        c = ws.cylinder
        ax.plot(
            [-c.size, c.size, c.size, -c.size, -c.size],
            [c.z_min, c.z_min, c.z_max, c.z_max, c.z_min],
            "r-",
            lw=1.2,
            label=f"cylinder r = {c.size:.3f} m, h = {c.height:.3f} m",
        )
        ax.legend(loc="lower center", fontsize=7)
    ax.set_xlim(xlim)
    ax.set_ylim(zlim)
    ax.set_title(f"x-z at y = {ws.y[j]:.3f} m")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_aspect("equal")
    fig.colorbar(im, ax=list(axes), label=label + " [-]", shrink=0.9)
    if title:
        fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


# -- the robot drawn in a pose ---------------------------------------------------------


def delta_skeleton(robot: DeltaRobot, q: Any) -> np.ndarray:
    """Polyline points (K, 3) [m] of a delta robot at crank angles q (3,): base triangle,
    each crank A_i B_i and rod B_i C_i, platform triangle, NaN rows separating the pieces.
    A_i = r_a (cos theta_i, sin theta_i, 0), B_i = A_i + l_a (cos q_i radial, -sin q_i z)
    (report Figure 4, q_i > 0 down), C_i = p + r_b (cos theta_i, sin theta_i, 0)."""
    g = robot.geometry
    q = np.asarray(q, dtype=float)[:3]
    p = np.asarray(robot.fk(q), dtype=float)[:3]
    gap = np.full((1, 3), np.nan)
    u = np.array([[math.cos(t), math.sin(t), 0.0] for t in g.theta])
    A = g.r_a * u
    B = A + g.l_a * (np.cos(q)[:, None] * u + np.array([0, 0, -1.0]) * np.sin(q)[:, None])
    C = p + g.r_b * u
    parts = [A[[0, 1, 2, 0]], gap]
    for i in range(3):
        parts += [np.stack([A[i], B[i], C[i]]), gap]
    parts += [C[[0, 1, 2, 0]]]
    return np.concatenate(parts)


def three_sphere_skeleton(robot: Any, q: Any) -> np.ndarray:
    """Polyline points (K, 3) [m] of a LinearDelta or a Tripod at joint values q (3,): the
    towers (linear delta, over the carriage travel) or the base triangle A, B, C (tripod),
    each arm or strut from its sphere centre to the point, NaN rows between the pieces."""
    g = robot.geometry
    q = np.asarray(q, dtype=float)[:3]
    p = np.asarray(robot.fk(q), dtype=float)[:3]
    gap = np.full((1, 3), np.nan)
    if robot.kind == "linear_delta":
        lo, hi = g.carriage_range
        centres = np.c_[g.tower_x, g.tower_y, q]
        parts = []
        for i in range(3):
            tower = [[g.tower_x[i], g.tower_y[i], lo], [g.tower_x[i], g.tower_y[i], hi]]
            parts += [np.array(tower), gap]
    else:
        centres = np.array(g.base_points)
        parts = [centres[[0, 1, 2, 0]], gap]
    for i in range(3):
        parts += [np.stack([centres[i], p]), gap]
    return np.concatenate(parts[:-1])


def serial_skeleton(arm, q: Any) -> np.ndarray:
    """Polyline (n + 2, 3) [m] through the base origin, every joint frame and the tool."""
    frames = np.asarray(arm.frames(np.asarray(q, dtype=float)))
    pts = frames[..., :3, 3].reshape(-1, 3)
    tool = np.asarray(arm.fk(np.asarray(q, dtype=float)))[:3, 3]
    return np.concatenate([np.zeros((1, 3)), pts, tool[None]])


def default_trajectory(robot, ws, n: int = 24) -> np.ndarray:
    """Joint coordinates (n, k) of a move to show: delta, a circle of 0.8 x the inscribed
    cylinder's radius at its mid height; serial arm, a straight joint move between two
    reachable configurations within the limits."""
    from deltagen.api.workspace import DeltaWorkspace

    if isinstance(ws, DeltaWorkspace):
        c = ws.cylinder
        if c is None:
            pts, _ = ws.points()
            centre = pts.mean(axis=0)
            radius = 0.0
        else:
            centre = np.array([0.0, 0.0, 0.5 * (c.z_min + c.z_max)])
            radius = 0.8 * c.size
        t = np.linspace(0.0, 2 * math.pi, n)
        p = centre + radius * np.stack([np.cos(t), np.sin(t), np.zeros(n)], axis=-1)
        return np.asarray(robot.ik(p))
    lim = np.array(robot.qlim, dtype=float)
    lim = np.where(np.isfinite(lim), lim, np.array([-math.pi, math.pi]))
    a = lim[:, 0] + 0.3 * (lim[:, 1] - lim[:, 0])
    b = lim[:, 0] + 0.7 * (lim[:, 1] - lim[:, 0])
    s = np.linspace(0.0, 1.0, n)[:, None]
    return a + s * (b - a)


def write_page(
    robot,
    ws,
    path: str | Path,
    trajectory: Any = None,
    title: str = "",
    seed: int = 0,
    skeleton: Any = None,
) -> Path:
    """The self-contained 3D page (module docstring). trajectory: joint coordinates (n, k)
    for the slider (default: default_trajectory); skeleton(robot, q) -> (K, 3) polyline
    points of the robot at one trajectory entry (default: by the robot's kind). ``ws``
    needs ``points()`` -> (positions (M, 3), condition numbers (M,))."""
    try:
        import plotly.graph_objects as go
    except ImportError as exc:
        raise DeltagenError(PLOTLY_HINT) from exc
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.workspace import DeltaWorkspace

    is_delta = isinstance(ws, DeltaWorkspace)
    if skeleton is not None:
        pass
    elif isinstance(robot, DeltaRobot):
        skeleton = delta_skeleton
    elif is_delta:  # a LinearDelta or a Tripod: the same workspace result
        skeleton = three_sphere_skeleton
    else:
        skeleton = serial_skeleton
    traj = default_trajectory(robot, ws) if trajectory is None else np.asarray(trajectory)
    pts, cond = ws.points()
    if len(pts) > MAX_POINTS:
        pick = np.random.default_rng(seed).choice(len(pts), MAX_POINTS, replace=False)
        pts, cond = pts[pick], cond[pick]
    finite = np.isfinite(cond)
    cloud = go.Scatter3d(
        x=pts[:, 0],
        y=pts[:, 1],
        z=pts[:, 2],
        mode="markers",
        name="workspace",
        marker=dict(
            size=2,
            color=np.where(finite, cond, np.nanmax(cond[finite]) if finite.any() else 1.0),
            colorscale="Viridis",
            opacity=0.35,
            colorbar=dict(title="condition number of J"),
        ),
        hovertemplate="x %{x:.3f} m<br>y %{y:.3f} m<br>z %{z:.3f} m<br>cond %{marker.color:.2f}",
    )
    first = skeleton(robot, traj[0])
    arm_trace = go.Scatter3d(
        x=first[:, 0],
        y=first[:, 1],
        z=first[:, 2],
        mode="lines+markers",
        name="robot",
        line=dict(color="crimson", width=6),
        marker=dict(size=3, color="crimson"),
    )
    data = [cloud, arm_trace]
    if is_delta and ws.cylinder is not None:
        c = ws.cylinder
        t = np.linspace(0, 2 * math.pi, 61)
        ring = []
        for z in (c.z_min, c.z_max):
            ring.append(np.stack([c.size * np.cos(t), c.size * np.sin(t), np.full_like(t, z)], -1))
            ring.append(np.full((1, 3), np.nan))
        ring_pts = np.concatenate(ring)
        data.append(
            go.Scatter3d(
                x=ring_pts[:, 0],
                y=ring_pts[:, 1],
                z=ring_pts[:, 2],
                mode="lines",
                name=f"cylinder r={c.size:.3f} m h={c.height:.3f} m",
                line=dict(color="orange", width=4),
            )
        )
    frames, steps = [], []
    for k, q in enumerate(traj):
        s = skeleton(robot, q)
        frames.append(
            go.Frame(data=[go.Scatter3d(x=s[:, 0], y=s[:, 1], z=s[:, 2])], traces=[1], name=str(k))
        )
        steps.append(
            dict(
                method="animate",
                label=str(k),
                args=[[str(k)], dict(mode="immediate", frame=dict(duration=0, redraw=True))],
            )
        )
    fig = go.Figure(data=data, frames=frames)
    fig.update_layout(
        title=title or "workspace",
        scene=dict(
            xaxis_title="x [m]", yaxis_title="y [m]", zaxis_title="z [m]", aspectmode="data"
        ),
        sliders=[dict(active=0, steps=steps, currentvalue=dict(prefix="trajectory step "))],
        margin=dict(l=0, r=0, t=40, b=0),
        legend=dict(x=0.0, y=1.0, bgcolor="rgba(255,255,255,0.6)"),
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.write_html(path, include_plotlyjs=True, full_html=True, auto_play=False)
    return path


def write_summary(ws, path: str | Path, robot) -> Path:
    path = Path(path)
    with path.open("w", newline="") as fh:
        fh.write(f"# deltagen {__version__} workspace of {robot!r}\n")
        w = csv.writer(fh)
        w.writerow(["quantity", "value"])
        for key, value in ws.summary().items():
            w.writerow([key, repr(float(value))])
    return path


def add_parser(subparsers) -> None:
    """`deltagen workspace [ROBOT] ...`."""
    from deltagen.apps.robots import ROBOT_HELP, add_urdf_options

    w = subparsers.add_parser(
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
    add_urdf_options(w)


def run(args) -> int:
    """`deltagen workspace`: the job of the robot's kind (JOBS); returns the exit status."""
    from deltagen.apps.robots import run_job

    return run_job(args, JOBS)


def _hexapod_maps(robot, args) -> int:
    from deltagen.apps.hexapod import write_workspace

    write_workspace(robot, args.out, args.step, args.quiet)
    return 0


def write_maps(robot, args) -> int:
    """`deltagen workspace` of a delta robot, a linear delta, a tripod or a serial arm: the
    slices, the 3D page and the summary in ``args.out``."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    show = False if args.quiet else None
    from deltagen.api.delta import DeltaRobot

    if isinstance(robot, DeltaRobot) or hasattr(robot, "workspace_extent"):
        ws = robot.workspace(args.step, max_condition=args.max_condition, progress=show)
    else:
        ws = robot.workspace(args.step, progress=show)
    title = f"deltagen workspace: {robot!r}".replace(", backend='compiled'", "")
    written = [
        write_slices(ws, out / "workspace_slices.png", title=title),
        write_page(robot, ws, out / "workspace.html", title=title),
        write_summary(ws, out / "workspace_summary.csv", robot),
    ]
    if not args.quiet:
        for key, value in ws.summary().items():
            print(f"{key:>22}  {value:.6g}")
        for p in written:
            print(f"wrote {p}")
    return 0


#: The job of `deltagen workspace` for each robot kind it serves (apps/robots.py): the
#: hexapod's grid of positions and orientations (apps/hexapod.py), the robot's own
#: workspace for the others.
JOBS = {
    robots.DELTA: write_maps,
    robots.SERIAL: write_maps,
    robots.LINEAR_DELTA: write_maps,
    robots.TRIPOD: write_maps,
    robots.HEXAPOD: _hexapod_maps,
}
