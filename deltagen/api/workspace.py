"""Workspace and dexterity of a delta robot and a serial arm: the numbers.

The numbers live here, beside the robots whose methods they use (``DeltaRobot.workspace``,
``SerialRobot.workspace`` delegate to :func:`delta_workspace` and :func:`serial_workspace`);
the pictures (PNG slices, the 3D page) are drawn by deltagen.apps.workspace.

Delta (the report's geometry, Figure 4): a point p of a box is *usable* when

* the inverse kinematics (elbow-out branch) reaches it and the forward kinematics of that
  q gives p back (the platform below the crank tips, the report's assembly mode),
* every crank angle lies in ``q_limits`` [rad], and
* the condition number of J = J_p^-1 J_q (pdot = J qdot, report eq. (30)) is at most
  ``max_condition`` (the transmission bound: near a singularity a small joint error gives
  a large platform error, or a small platform force a large torque).

The box is sampled on a voxel grid by ik (every voxel centre tested), never by scattering
fk points. Over the usable voxels the result holds the condition number, the velocity
amplification sigma_max(J) [m/rad] (platform speed per unit crank speed, worst direction)
and the force amplification 1/sigma_min(J) [N/(N m)] (platform force per unit torque,
worst direction: tau = J^T F), and with inertia the peak torque needed for a given
platform acceleration in the six axis directions (inverse_dynamics_from_platform).

The usable envelope a builder quotes is the largest upright cylinder (and square box) centred
on the base z axis that lies inside the usable set: per height z, rays from the axis find
the first unusable radius (bisection to ``tol``), the smallest over all directions (refined
around every local minimum) is the inscribed radius r(z); the cylinder maximises
pi r^2 h over intervals of the heights, with r the least r(z) in the interval. It is
reported a margin ``tol`` inside, so it lies inside the usable set, and no larger radius
(by more than 2 tol) or longer interval (by one height step) would.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from deltagen.inputs import InputError, check_integer, check_memory, check_real

FloatArray = np.ndarray

#: Default crank range of the delta workspace [rad]: from horizontal-up to straight down.
DEFAULT_Q_LIMITS = (-math.pi / 2, math.pi / 2)
#: Default bound on the condition number of J (sigma_max / sigma_min).
DEFAULT_MAX_CONDITION = 10.0
#: Fewest heights of the envelope search: its first and last lie a voxel outside the usable
#: heights, so with fewer than four at most one usable height remains and no interval (no
#: cylinder of non-zero height) could be found.
MIN_ENVELOPE_LEVELS = 4
#: Bytes a delta workspace holds per voxel: the result arrays (usable, condition, the two
#: gains, q (3), peak torque), the voxel centres and their meshgrid (3 + 3 each), and the
#: centres and condition numbers the pictures draw (4).
DELTA_BYTES_PER_VOXEL = 8 * (1 + 1 + 2 + 3 + 1 + 6 + 4) + 1
#: Bytes per joint sample of a serial workspace (besides 8 per joint and per Jacobian entry):
#: the tool pose (4x4), position, condition number, manipulability and their flags.
SERIAL_BYTES_PER_SAMPLE = 8 * (16 + 3 + 4) + 4
#: Bytes per voxel of a serial workspace grid: with a tool orientation the target poses
#: (4x4), voxel centres and their meshgrid, the condition and manipulability maps.
SERIAL_BYTES_PER_TARGET = 8 * (16 + 3 + 3 + 6) + 4
SERIAL_BYTES_PER_VOXEL = 8 * 6 + 4


def _progress(total: int, desc: str, show: bool | None) -> Any:
    """A tqdm bar (or a silent stand-in): shown when ``show`` is True, or when None and
    stderr is a terminal; it appears only once the job has run for a second."""
    import sys

    if show is None:
        show = sys.stderr.isatty()
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm is in the design extra; without it, no bar
        show = False
    if not show:
        return _Silent()
    return tqdm(total=total, desc=desc, unit="pt", unit_scale=True, leave=False, delay=1.0)


class _Silent:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


@dataclass
class Envelope:
    """An upright body centred on the base z axis: a cylinder (``radius``) or a square box
    (``half_width``, sides parallel to x and y), between heights z_min and z_max [m]."""

    kind: str
    size: float  # cylinder radius or box half width [m]
    z_min: float
    z_max: float
    dz: float = 0.0  # spacing of the heights searched [m]: the interval's resolution

    @property
    def height(self) -> float:
        return self.z_max - self.z_min

    @property
    def volume(self) -> float:
        area = math.pi * self.size**2 if self.kind == "cylinder" else 4.0 * self.size**2
        return area * self.height


@dataclass
class DeltaWorkspace:
    """The usable workspace of a delta robot on a voxel grid (see the module docstring).

    x, y, z        (nx,), (ny,), (nz,) voxel centres [m]; spacing ``step`` [m]
    usable         (nx, ny, nz) bool
    condition      (nx, ny, nz) condition number of J, NaN where ik fails
    velocity_gain  (nx, ny, nz) sigma_max(J) [m/rad]
    force_gain     (nx, ny, nz) 1/sigma_min(J) [N/(N m)]
    peak_torque    (nx, ny, nz) max |tau_i| over the six +-axis accelerations [N m], or None
    q              (nx, ny, nz, 3) crank angles of the voxel centres [rad]
    cylinder, box  the largest inscribed upright envelopes (Envelope), None if none fits
    """

    x: FloatArray
    y: FloatArray
    z: FloatArray
    step: float
    usable: FloatArray
    condition: FloatArray
    velocity_gain: FloatArray
    force_gain: FloatArray
    q: FloatArray
    cylinder: Envelope | None
    box: Envelope | None
    q_limits: tuple[float, float]
    max_condition: float
    tol: float
    peak_torque: FloatArray | None = None
    acceleration: float | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def volume(self) -> float:
        """Usable volume [m^3]: the usable voxels times the voxel volume."""
        return float(np.count_nonzero(self.usable)) * self.step**3

    @property
    def z_range(self) -> tuple[float, float]:
        """Lowest and highest usable voxel centre [m] (NaN, NaN when nothing is usable)."""
        zs = self.z[np.any(self.usable, axis=(0, 1))]
        if zs.size == 0:
            return (math.nan, math.nan)
        return (float(zs.min()), float(zs.max()))

    @property
    def worst_condition(self) -> float:
        """Largest condition number over the usable voxels (NaN if none)."""
        c = self.condition[self.usable]
        return float(c.max()) if c.size else math.nan

    def points(self) -> tuple[FloatArray, FloatArray]:
        """(centres (M, 3) of the usable voxels [m], their condition numbers (M,))."""
        ix = np.nonzero(self.usable)
        X, Y, Z = np.meshgrid(self.x, self.y, self.z, indexing="ij")
        return np.stack([X[ix], Y[ix], Z[ix]], axis=-1), self.condition[ix]

    def summary(self) -> dict[str, float]:
        """The numbers a builder quotes. The envelopes are 0.0 when the search found none
        (nothing fits), NaN when it did not run (``envelope=False``)."""
        zlo, zhi = self.z_range
        searched = self.settings.get("envelope", True)
        out = {
            "volume_m3": self.volume,
            "z_min_m": zlo,
            "z_max_m": zhi,
            "worst_condition": self.worst_condition,
            "cylinder_radius_m": self.cylinder.size if self.cylinder else 0.0,
            "cylinder_height_m": self.cylinder.height if self.cylinder else 0.0,
            "cylinder_volume_m3": self.cylinder.volume if self.cylinder else 0.0,
            "box_half_width_m": self.box.size if self.box else 0.0,
            "box_height_m": self.box.height if self.box else 0.0,
        }
        if not searched:
            for key in ("cylinder", "box"):
                for name in out:
                    if name.startswith(key):
                        out[name] = math.nan
        if self.peak_torque is not None:
            t = self.peak_torque[self.usable]
            out["peak_torque_Nm"] = float(t.max()) if t.size else math.nan
        return out


def singular_values3(J):
    """Singular values (..., 3), largest first, of 3x3 matrices J (..., 3, 3): the square
    roots of the eigenvalues of J^T J by the closed form for symmetric 3x3 matrices (Smith
    1961), several times faster than numpy's batched SVD; accurate to ~1e-10 relative for
    the condition numbers of interest here (<= 1e3)."""
    c = [np.ascontiguousarray(J[..., :, i]) for i in range(3)]

    def dot(u, v):
        return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] + u[..., 2] * v[..., 2]

    a00, a11, a22 = dot(c[0], c[0]), dot(c[1], c[1]), dot(c[2], c[2])
    a01, a02, a12 = dot(c[0], c[1]), dot(c[0], c[2]), dot(c[1], c[2])
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    d0, d1, d2 = a00 - q, a11 - q, a22 - q
    p2 = d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        b00, b11, b22 = d0 / p, d1 / p, d2 / p
        b01, b02, b12 = a01 / p, a02 / p, a12 / p
    det_b = (
        b00 * (b11 * b22 - b12 * b12)
        - b01 * (b01 * b22 - b12 * b02)
        + b02 * (b01 * b12 - b11 * b02)
    )
    r = np.clip(det_b / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    e1 = q + 2.0 * p * np.cos(phi)
    e3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    e2 = 3.0 * q - e1 - e3
    small = p == 0.0
    e = np.stack([e1, e2, e3], axis=-1)
    e = np.where(small[..., None], q[..., None], e)
    return np.sqrt(np.maximum(e, 0.0))


def delta_usable(
    robot, p, q_limits=DEFAULT_Q_LIMITS, max_condition=DEFAULT_MAX_CONDITION, size=None
):
    """(usable (N,), q (N, 3), J (N, 3, 3), condition (N,)) of points p (N, 3) [m]: the
    three conditions of the module docstring. NaN q/J/condition where ik or J fails.
    ``size``: the robot's length scale for the round-trip check (default l_a + l_b of a
    rotary delta; a linear delta's or a tripod's from its workspace_extent)."""
    p = np.ascontiguousarray(np.asarray(p, dtype=float).reshape(-1, 3))
    q, ok = robot.ik(p, errors="nan")
    back, ok_fk = robot.fk(np.where(ok[:, None], q, 0.0), errors="nan")
    if size is None:
        size = robot.geometry.l_a + robot.geometry.l_b
    same = ok & ok_fk & (np.linalg.norm(back - p, axis=-1) <= 1e-9 * size)
    lo, hi = q_limits
    inside = same & np.all((q >= lo) & (q <= hi), axis=-1)
    J, ok_j = robot.jacobian(np.where(inside[:, None], q, 0.0), errors="nan")
    ok_j &= inside
    sv = np.full((p.shape[0], 3), np.nan)
    if np.any(ok_j):
        sv[ok_j] = singular_values3(J[ok_j])
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = sv[:, 0] / sv[:, 2]
    usable = ok_j & np.isfinite(cond) & (cond <= max_condition)
    q = np.where(same[:, None], q, np.nan)
    J = np.where(ok_j[:, None, None], J, np.nan)
    return usable, q, J, np.where(ok_j, cond, np.nan), sv


def _radial_limit(usable_fn, z, theta, r_max, n_r, tol):
    """First unusable radius along rays from the axis at heights z (M,), directions theta
    (M,): marched on n_r radii up to r_max, then bisected to tol. 0 where the axis point
    itself is unusable; r_max where the whole ray is usable."""
    m = z.size
    radii = np.linspace(0.0, r_max, n_r)
    c, s = np.cos(theta), np.sin(theta)
    pts = np.stack(
        [
            c[:, None] * radii[None, :],
            s[:, None] * radii[None, :],
            np.broadcast_to(z[:, None], (m, n_r)),
        ],
        axis=-1,
    )
    ok = usable_fn(pts.reshape(-1, 3)).reshape(m, n_r)
    first_bad = np.where(~ok.all(axis=1), np.argmin(ok, axis=1), n_r)
    r = np.where(first_bad >= n_r, r_max, 0.0)
    mid = (first_bad > 0) & (first_bad < n_r)
    if np.any(mid):
        lo = radii[first_bad[mid] - 1].copy()
        hi = radii[first_bad[mid]].copy()
        cm, sm, zm = c[mid], s[mid], z[mid]
        while np.max(hi - lo) > tol:
            rr = 0.5 * (lo + hi)
            good = usable_fn(np.stack([cm * rr, sm * rr, zm], axis=-1))
            lo = np.where(good, rr, lo)
            hi = np.where(good, hi, rr)
        r[mid] = lo
    return r


def _inscribed_per_level(usable_fn, z, r_max, n_theta, n_r, tol, kinds):
    """Per kind ("cylinder", "box"): the largest radius (box: half width) of a disc (square)
    centred on the axis inside the usable set at each height z (nz,): the least over
    directions of r(theta) (box: r(theta) max(|cos|, |sin|)), refined around each local
    minimum. One fan of rays serves both kinds."""
    nz = z.size
    theta = np.linspace(0.0, 2 * math.pi, n_theta, endpoint=False)
    dtheta = 2 * math.pi / n_theta

    def weight(kind, tt):
        return np.maximum(np.abs(np.cos(tt)), np.abs(np.sin(tt))) if kind == "box" else 1.0

    r_grid = _radial_limit(usable_fn, np.repeat(z, n_theta), np.tile(theta, nz), r_max, n_r, tol)
    out = {}
    for kind in kinds:
        f = (r_grid * weight(kind, np.tile(theta, nz))).reshape(nz, n_theta)
        best = f.min(axis=1)
        # kinks of the boundary (one chain's limit handing over to another's) lie between
        # rays: refine around every local minimum near the least one, twice, in finer fans
        slack = 2.0 * r_max * dtheta + tol
        is_min = (f < np.roll(f, 1, axis=1)) & (f <= np.roll(f, -1, axis=1))
        is_min &= (f <= best[:, None] + slack) & (best[:, None] > 0.0)
        lev, idx = np.nonzero(is_min)
        centres, width = theta[idx], dtheta
        fan = np.linspace(-1.0, 1.0, 17)
        for _ in range(2):
            if lev.size == 0:
                break
            tt = (centres[:, None] + width * fan[None, :]).reshape(-1)
            r = _radial_limit(usable_fn, np.repeat(z[lev], fan.size), tt, r_max, n_r, tol)
            g = (r * weight(kind, tt)).reshape(lev.size, fan.size)
            np.minimum.at(best, lev, g.min(axis=1))
            centres = tt.reshape(lev.size, fan.size)[np.arange(lev.size), g.argmin(axis=1)]
            width /= 8.0
        out[kind] = best
    return out


def _best_interval(z, size, kind):
    """The interval [z_i, z_j] of consecutive heights maximising area(min size) * (z_j - z_i)."""
    nz = z.size
    best = (0.0, -1, -1, 0.0)
    for i in range(nz):
        m = math.inf
        for j in range(i, nz):
            m = min(m, size[j])
            if m <= 0.0:
                break
            area = math.pi * m * m if kind == "cylinder" else 4.0 * m * m
            vol = area * (z[j] - z[i])
            if vol > best[0]:
                best = (vol, i, j, m)
    return best


def inscribed_envelopes(
    usable_fn: Callable[[FloatArray], FloatArray],
    z: FloatArray,
    r_max: float,
    kinds: tuple[str, ...] = ("cylinder", "box"),
    n_theta: int = 120,
    n_r: int = 40,
    tol: float = 1e-4,
) -> dict[str, tuple[Envelope | None, FloatArray]]:
    """Per kind, the largest upright cylinder ("cylinder") or square box ("box") centred on
    the z axis whose heights span consecutive levels of z and which lies inside
    ``usable_fn(points (N, 3)) -> (N,) bool``, reported ``tol`` inside (module docstring):
    kind -> (envelope or None, the inscribed size per level (nz,))."""
    for kind in kinds:
        if kind not in ("cylinder", "box"):
            raise InputError(f"kind must be 'cylinder' or 'box', got {kind!r}")
    z = np.asarray(z, dtype=float)
    sizes = _inscribed_per_level(usable_fn, z, r_max, n_theta, n_r, tol, kinds)
    out: dict[str, tuple[Envelope | None, FloatArray]] = {}
    for kind, size in sizes.items():
        _, i, j, m = _best_interval(z, size, kind)
        dz = float(z[1] - z[0]) if z.size > 1 else 0.0
        env = None
        if i >= 0 and m - tol > 0.0:
            env = Envelope(kind, float(m - tol), float(z[i]), float(z[j]), dz)
        out[kind] = (env, size)
    return out


def delta_default_box(
    r_a: float, r_b: float, l_a: float, l_b: float
) -> tuple[tuple[float, float], ...]:
    """The box a delta workspace samples by default: every point the chains could reach,
    ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)) [m]."""
    size = l_a + l_b
    reach = max(abs(r_a - r_b) + size, 1e-9)
    return ((-reach, reach), (-reach, reach), (-size - l_a, l_a))


def voxel_counts(box: Any, step: float) -> tuple[float, float, float]:
    """Voxels per axis of ``box`` at edge ``step`` (floats, so that a tiny step gives a
    huge count rather than an allocation)."""
    nx, ny, nz = (max(float(math.floor((b - a) / step)), 1.0) for a, b in box)
    return nx, ny, nz


def check_delta_grid(box: Any, step: float, option: str = "step", source: str = "") -> float:
    """The voxel count of a delta workspace grid; InputError (naming ``option``, after
    ``source``) when its arrays would exceed the memory budget (deltagen.inputs.memory_limit)."""
    nx, ny, nz = voxel_counts(box, step)
    voxels = nx * ny * nz
    check_memory(
        voxels * DELTA_BYTES_PER_VOXEL,
        f"{source + ': ' if source else ''}the workspace grid at {option} = {step:g} m ({nx:.0f} x {ny:.0f} x {nz:.0f} = "
        f"{voxels:.3g} voxels)",
        f"choose a larger {option} (each halving needs 8 times the memory)",
    )
    return voxels


def delta_workspace(
    robot: Any,
    step: float | None = None,
    *,
    box: tuple[tuple[float, float], ...] | None = None,
    q_limits: tuple[float, float] | None = None,
    max_condition: float = DEFAULT_MAX_CONDITION,
    envelope: bool = True,
    envelope_levels: int = 40,
    acceleration: float | None = None,
    payload: float = 0.0,
    progress: bool | None = None,
) -> DeltaWorkspace:
    """The usable workspace of a DeltaRobot (module docstring). step: voxel edge [m]
    (default (l_a + l_b) / 40); box: ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)) [m], by
    default every point the chains could reach; q_limits [rad]; max_condition >= 1;
    acceleration [m/s^2]: also the peak torque map (the robot needs inertia); progress:
    a tqdm bar (None: when stderr is a terminal).

    A LinearDelta or a Tripod (deltagen.api.linear_delta) works the same way: q are its
    carriage heights or strut lengths, ``q_limits`` their travel [m] (default: the
    geometry's carriage_range or strut_range), and its ``workspace_extent()`` gives the
    length scale, the reach and the default box."""
    g = robot.geometry
    extent = getattr(robot, "workspace_extent", None)
    if extent is not None:
        size, reach, default_box, default_limits = extent()
    else:
        size = g.l_a + g.l_b
        reach = max(abs(g.r_a - g.r_b) + size, 1e-9)
        default_box = delta_default_box(g.r_a, g.r_b, g.l_a, g.l_b)
        default_limits = DEFAULT_Q_LIMITS
    if q_limits is None:
        q_limits = default_limits
    if step is None:
        step = size / 40.0
    step = check_real(step, "step", low=0.0, low_open=True, unit="m")
    if isinstance(q_limits, (str, bytes)) or not hasattr(q_limits, "__len__") or len(q_limits) != 2:
        raise InputError(f"q_limits must be (low, high) radians with low < high, got {q_limits!r}")
    lo_q = check_real(q_limits[0], "q_limits[0]", unit="rad")
    hi_q = check_real(q_limits[1], "q_limits[1]", unit="rad")
    if not lo_q < hi_q:
        raise InputError(f"q_limits must be (low, high) radians with low < high, got {q_limits!r}")
    max_condition = check_real(max_condition, "max_condition", low=1.0)
    if not isinstance(envelope, (bool, np.bool_)):
        raise InputError(f"envelope must be True or False, got {envelope!r}")
    envelope_levels = check_integer(envelope_levels, "envelope_levels", low=MIN_ENVELOPE_LEVELS)
    payload = check_real(payload, "payload", low=0.0, unit="kg")
    if acceleration is not None:
        acceleration = check_real(acceleration, "acceleration", low=0.0, unit="m/s^2")
    if acceleration is not None and getattr(g, "inertia", None) is None:
        from deltagen.errors import GeometryError

        raise GeometryError("the peak torque map needs the robot's inertia (DeltaInertia)")
    if box is None:
        box = default_box
    try:
        (x0, x1), (y0, y1), (z0, z1) = ((float(a), float(b)) for a, b in box)
    except (TypeError, ValueError):
        raise InputError(
            f"box must be ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)), got {box!r}"
        ) from None
    if (
        not all(math.isfinite(v) for v in (x0, x1, y0, y1, z0, z1))
        or x0 >= x1
        or y0 >= y1
        or z0 >= z1
    ):
        raise InputError(f"box must hold finite (low, high) pairs with low < high, got {box!r}")
    check_delta_grid(((x0, x1), (y0, y1), (z0, z1)), step)

    def centres(a, b):
        n = max(int(math.floor((b - a) / step)), 1)
        return a + (np.arange(n) + 0.5) * (b - a) / n

    xs, ys, zs = centres(x0, x1), centres(y0, y1), centres(z0, z1)
    # the voxel grid's own spacing per axis may differ slightly from step; use the mean
    step_eff = float(
        np.cbrt(
            (xs[1] - xs[0] if xs.size > 1 else x1 - x0)
            * (ys[1] - ys[0] if ys.size > 1 else y1 - y0)
            * (zs[1] - zs[0] if zs.size > 1 else z1 - z0)
        )
    )
    shape = (xs.size, ys.size, zs.size)
    n = xs.size * ys.size * zs.size
    usable = np.zeros(n, bool)
    cond = np.full(n, np.nan)
    vgain = np.full(n, np.nan)
    fgain = np.full(n, np.nan)
    qall = np.full((n, 3), np.nan)
    peak = np.full(n, np.nan) if acceleration is not None else None
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    P = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=-1)
    bar = _progress(n, "workspace", progress)
    chunk = 1 << 16
    for a in range(0, n, chunk):
        b = min(a + chunk, n)
        ok, q, _J, c, sv = delta_usable(robot, P[a:b], (lo_q, hi_q), max_condition, size)
        usable[a:b], cond[a:b], qall[a:b] = ok, c, q
        vgain[a:b] = sv[:, 0]
        with np.errstate(divide="ignore"):
            fgain[a:b] = 1.0 / sv[:, 2]
        if peak is not None and acceleration is not None and np.any(ok):
            peak[a:b] = _peak_torque(robot, P[a:b], ok, float(acceleration), payload)
        bar.update(b - a)
    bar.close()
    cyl = boxe = None
    counted = [n]  # poses tested (voxels, then the envelope's rays)
    if envelope and np.any(usable):
        zu = zs[np.any(usable.reshape(shape), axis=(0, 1))]
        levels = np.linspace(zu.min() - step_eff, zu.max() + step_eff, envelope_levels)
        tol = 1e-4 * size

        def fn(pts):
            counted[0] += len(pts)
            return delta_usable(robot, pts, (lo_q, hi_q), max_condition, size)[0]

        env = inscribed_envelopes(fn, levels, reach, tol=tol)
        cyl, boxe = env["cylinder"][0], env["box"][0]
    return DeltaWorkspace(
        x=xs,
        y=ys,
        z=zs,
        step=step_eff,
        usable=usable.reshape(shape),
        condition=cond.reshape(shape),
        velocity_gain=vgain.reshape(shape),
        force_gain=fgain.reshape(shape),
        q=qall.reshape(shape + (3,)),
        cylinder=cyl,
        box=boxe,
        q_limits=(lo_q, hi_q),
        max_condition=float(max_condition),
        tol=1e-4 * size,
        peak_torque=None if peak is None else peak.reshape(shape),
        acceleration=acceleration,
        settings={
            "step": step,
            "box": ((x0, x1), (y0, y1), (z0, z1)),
            "poses": counted[0],
            "envelope": bool(envelope),
        },
    )


def _peak_torque(robot, p, ok, acceleration, payload):
    """max over the six +-axis platform accelerations of max_i |tau_i| [N m], from rest."""
    pts = p[ok]
    m = pts.shape[0]
    out = np.full(p.shape[0], np.nan)
    worst = np.zeros(m)
    for axis in range(3):
        for sign in (1.0, -1.0):
            pdd = np.zeros((m, 3))
            pdd[:, axis] = sign * acceleration
            tau, valid = robot.inverse_dynamics_from_platform(
                pts, np.zeros((m, 3)), pdd, payload, errors="nan"
            )
            worst = np.maximum(worst, np.where(valid, np.max(np.abs(tau[:, :3]), axis=-1), np.inf))
    out[ok] = worst
    return out


@dataclass
class SerialWorkspace:
    """Reachability and dexterity of a serial arm on a voxel grid of tool positions.

    x, y, z          (nx,), (ny,), (nz,) voxel centres [m] (base frame); spacing ``step``
    reachable        (nx, ny, nz) bool
    manipulability   (nx, ny, nz) Yoshikawa's measure, the best found in the voxel
    condition        (nx, ny, nz) condition number of the geometric Jacobian, the best found
    singular         (nx, ny, nz) bool: reachable, but 1/condition < singular_tol there
    singular_points  (M, 3) tool positions of near-singular configurations found [m]
    orientation      the tool rotation (3, 3) asked for, or None (orientation-free)
    """

    x: FloatArray
    y: FloatArray
    z: FloatArray
    step: float
    reachable: FloatArray
    manipulability: FloatArray
    condition: FloatArray
    singular: FloatArray
    singular_points: FloatArray
    orientation: FloatArray | None
    singular_tol: float

    @property
    def volume(self) -> float:
        """Reachable volume [m^3]: reachable voxels times the voxel volume."""
        return float(np.count_nonzero(self.reachable)) * self.step**3

    @property
    def reach(self) -> float:
        """Largest distance of a reachable voxel centre from the base origin [m]."""
        ix = np.nonzero(self.reachable)
        if ix[0].size == 0:
            return math.nan
        d = np.sqrt(self.x[ix[0]] ** 2 + self.y[ix[1]] ** 2 + self.z[ix[2]] ** 2)
        return float(d.max())

    def points(self) -> tuple[FloatArray, FloatArray]:
        """(centres (M, 3) of the reachable voxels [m], their condition numbers (M,))."""
        ix = np.nonzero(self.reachable)
        X, Y, Z = np.meshgrid(self.x, self.y, self.z, indexing="ij")
        return np.stack([X[ix], Y[ix], Z[ix]], axis=-1), self.condition[ix]

    def summary(self) -> dict[str, float]:
        c = self.condition[self.reachable]
        return {
            "volume_m3": self.volume,
            "reach_m": self.reach,
            "best_condition": float(np.nanmin(c)) if c.size else math.nan,
            "singular_voxels": float(np.count_nonzero(self.singular)),
        }


def _joint_box(arm):
    """Sampling range per joint: the limits, or (-pi, pi] for an unlimited revolute joint."""
    lim = np.array(arm.qlim, dtype=float)
    kinds = [j.type for j in arm.description.joints]
    for i, kind in enumerate(kinds):
        if not np.all(np.isfinite(lim[i])):
            if kind == "prismatic":
                raise InputError(
                    f"joint {i} is prismatic without limits: the workspace needs its range"
                )
            lim[i] = (-math.pi, math.pi)
    return lim


def serial_workspace(
    arm: Any,
    step: float | None = None,
    *,
    orientation: Any = None,
    samples: int = 200_000,
    seed: int = 0,
    singular_tol: float = 1e-2,
    progress: bool | None = None,
) -> SerialWorkspace:
    """Reachability and dexterity of a SerialRobot over a voxel grid of tool positions.

    Orientation-free (``orientation=None``): position-only reach, by ``samples`` joint
    configurations drawn uniformly in the joint limits (seeded), their tool positions binned
    into voxels; each voxel keeps the best manipulability and condition number found there.
    With a tool rotation (3, 3): every voxel centre is a target pose solved by ik (analytic
    where the structure allows), reachable when a solution within the limits exists.
    step: voxel edge [m] (default: the sampled reach / 25). Singular surfaces: the tool
    positions of configurations with 1/condition < singular_tol (``singular_points``), and
    the voxels where only such configurations reach (``singular``)."""
    samples = check_integer(samples, "samples", low=1)
    singular_tol = check_real(singular_tol, "singular_tol", low=0.0)
    check_memory(
        samples * (SERIAL_BYTES_PER_SAMPLE + 8 * arm.n * 8),
        f"the workspace's {samples} joint samples",
        "choose fewer samples",
    )
    rng = np.random.default_rng(seed)
    lim = _joint_box(arm)
    q = rng.uniform(lim[:, 0], lim[:, 1], size=(samples, arm.n))
    bar = _progress(samples, "joint samples", progress)
    T, ok = arm.fk(q, errors="nan")
    pos = T[:, :3, 3]
    cond, okc = arm.condition_number(q, errors="nan")
    manip, okm = arm.manipulability(q, errors="nan")
    bar.update(samples)
    bar.close()
    pos_ok = pos[ok]
    reach = float(np.max(np.linalg.norm(pos_ok, axis=1))) if pos_ok.size else 1.0
    if step is None:
        step = max(reach, 1e-6) / 25.0
    step = check_real(step, "step", low=0.0, low_open=True, unit="m")
    lo = pos_ok.min(axis=0) - step
    hi = pos_ok.max(axis=0) + step
    counts = [max(math.ceil((float(b) - float(a)) / step), 1) for a, b in zip(lo, hi)]
    voxels = float(counts[0]) * counts[1] * counts[2]
    per_voxel = SERIAL_BYTES_PER_VOXEL
    if orientation is not None:
        per_voxel += SERIAL_BYTES_PER_TARGET + 8 * arm.n
    check_memory(
        voxels * per_voxel,
        f"the workspace grid at step = {step:g} m ({counts[0]} x {counts[1]} x {counts[2]} = "
        f"{voxels:.3g} voxels)",
        "choose a larger step (each halving needs 8 times the memory)",
    )
    n = np.array(counts, dtype=int)
    axes = [lo[k] + (np.arange(n[k]) + 0.5) * step for k in range(3)]
    shape = tuple(int(v) for v in n)
    reachable = np.zeros(shape, bool)
    best_m = np.full(shape, np.nan)
    best_c = np.full(shape, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_cond = np.where(okc, 1.0 / cond, 0.0)
    singular_points = pos[ok & (inv_cond < singular_tol)]
    R = None
    if orientation is None:
        idx = np.floor((pos_ok - lo) / step).astype(int)
        idx = np.clip(idx, 0, np.array(shape) - 1)
        flat = np.ravel_multi_index(idx.T, shape)
        reachable.reshape(-1)[flat] = True
        m_ok = np.where(okm[ok], manip[ok], -np.inf)
        c_ok = np.where(okc[ok], cond[ok], np.inf)
        bm = np.full(reachable.size, -np.inf)
        bc = np.full(reachable.size, np.inf)
        np.maximum.at(bm, flat, m_ok)
        np.minimum.at(bc, flat, c_ok)
        best_m = np.where(np.isfinite(bm), bm, np.nan).reshape(shape)
        best_c = np.where(np.isfinite(bc), bc, np.nan).reshape(shape)
    else:
        R = np.asarray(orientation, dtype=float)
        if (
            R.shape != (3, 3)
            or not np.all(np.isfinite(R))
            or not np.allclose(R @ R.T, np.eye(3), atol=1e-9)
        ):
            raise InputError("orientation must be a finite 3x3 rotation matrix")
        X, Y, Z = np.meshgrid(*axes, indexing="ij")
        P = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=-1)
        Tt = np.broadcast_to(np.eye(4), (P.shape[0], 4, 4)).copy()
        Tt[:, :3, :3] = R
        Tt[:, :3, 3] = P
        # targets beyond the sampled reach cannot be reached: skip them
        near = np.linalg.norm(P, axis=1) <= reach + step
        bar = _progress(int(near.sum()), "ik over the grid", progress)
        qs = np.full((P.shape[0], arm.n), np.nan)
        okq = np.zeros(P.shape[0], bool)
        where = np.flatnonzero(near)
        chunk = 4096
        for a in range(0, where.size, chunk):
            rows = where[a : a + chunk]
            qq, vv = arm.ik(Tt[rows], errors="nan", singular="allow")
            qs[rows], okq[rows] = qq, vv
            bar.update(rows.size)
        bar.close()
        c2, okc2 = arm.condition_number(np.where(okq[:, None], qs, 0.0), errors="nan")
        m2, okm2 = arm.manipulability(np.where(okq[:, None], qs, 0.0), errors="nan")
        reachable = okq.reshape(shape)
        best_c = np.where(okq & okc2, c2, np.where(okq, np.inf, np.nan)).reshape(shape)
        best_m = np.where(okq & okm2, m2, np.where(okq, 0.0, np.nan)).reshape(shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        singular = reachable & ~(1.0 / best_c >= singular_tol)
    return SerialWorkspace(
        x=axes[0],
        y=axes[1],
        z=axes[2],
        step=float(step),
        reachable=reachable,
        manipulability=best_m,
        condition=best_c,
        singular=singular,
        singular_points=singular_points,
        orientation=R,
        singular_tol=singular_tol,
    )
