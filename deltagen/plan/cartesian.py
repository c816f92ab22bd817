"""Cartesian trajectories: paths in space, the orientation along them, and the segments
that run them in time with a time scaling (:mod:`deltagen.plan.scaling`);
:mod:`deltagen.plan.following` turns them into joint trajectories.

* **Paths** in space, parameterised by ``s`` in [0, 1]: :class:`Line` ``p0 -> p1`` and
  :class:`Arc` (a circular arc by centre, start point, axis and signed angle, or
  :meth:`Arc.from_three_points`). Each gives the point and its first and second
  derivatives with respect to ``s``; the chain rule with the time scaling gives the
  Cartesian velocity and acceleration (``v = p' sd``, ``a = p'' sd^2 + p' sdd``).

* **Orientation** is interpolated by slerp on SO(3) with the same ``s``:
  ``R(s) = R0 exp(s log(R0^T R1))`` (the shortest rotation, constant axis
  ``k = R0 log(R0^T R1) / theta`` in the base frame), so the angular velocity is
  ``w = theta sd k`` and the angular acceleration ``wd = theta sdd k``. The same
  interpolation on unit quaternions is :func:`deltagen.geometry.rotations.quat_slerp`; both
  agree (tested).

* **Segments and trajectories**: a :class:`Segment` runs one path in ``duration``
  seconds with a time scaling, slerps the orientation and interpolates prescribed joint
  values; a :class:`CartesianTrajectory` runs segments one after the other (continuity
  checked) and samples them (:class:`CartesianSamples`); :class:`PathBuilder` chains
  them from a start pose.

Units: as the robot (metres, radians); time in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from deltagen.geometry.rotations import as_rotation, rot_exp, rot_log
from deltagen.inputs import InputError
from deltagen.plan.scaling import Quintic, _scaling

# =========================================================================== checked inputs


def _vec3(v, name):
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be 3 finite numbers, got {v!r}")
    return a


def _rotation(R, name="R"):
    """One rotation matrix (3, 3) (or the rotation block of a 4x4 pose), checked."""
    R = as_rotation(R, name)
    if R.shape != (3, 3):
        raise InputError(f"{name} must be a 3x3 rotation matrix (or a 4x4 pose)")
    return R


# =========================================================================== paths


@dataclass(frozen=True)
class Line:
    """The straight line p(s) = p0 + s (p1 - p0), s in [0, 1]."""

    p0: np.ndarray
    p1: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "p0", _vec3(self.p0, "Line p0"))
        object.__setattr__(self, "p1", _vec3(self.p1, "Line p1"))

    @property
    def start(self):
        return self.p0

    @property
    def end(self):
        return self.p1

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.p1 - self.p0))

    def evaluate(self, s):
        """p, dp/ds, d2p/ds2 at s (N,) -> three (N, 3) arrays."""
        s = np.asarray(s, dtype=float).reshape(-1)
        d = self.p1 - self.p0
        p = self.p0 + s[:, None] * d
        return p, np.broadcast_to(d, p.shape).copy(), np.zeros_like(p)


@dataclass(frozen=True)
class Arc:
    """A circular arc in space: centre ``center``, starting at ``start``, turning by the signed
    ``angle`` [rad] about the unit ``axis`` through the centre (right-hand rule); the axis
    must be perpendicular to ``start - center``.

    p(s) = c + cos(s Phi) u + sin(s Phi) (n x u), u = start - c, Phi = angle.
    """

    center: np.ndarray
    start_point: np.ndarray
    axis: np.ndarray
    angle: float

    def __post_init__(self):
        c = _vec3(self.center, "Arc center")
        p0 = _vec3(self.start_point, "Arc start")
        n = _vec3(self.axis, "Arc axis")
        if np.linalg.norm(n) < 1e-12:
            raise InputError("Arc axis must not be zero")
        n = n / np.linalg.norm(n)
        u = p0 - c
        r = np.linalg.norm(u)
        if r < 1e-12:
            raise InputError("Arc start coincides with its centre (radius 0)")
        if abs(np.dot(u, n)) > 1e-9 * max(1.0, r):
            raise InputError("Arc axis must be perpendicular to start - center")
        angle = float(self.angle)
        if not math.isfinite(angle) or angle == 0.0:
            raise InputError(f"Arc angle must be finite and non-zero, got {self.angle!r}")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "start_point", p0)
        object.__setattr__(self, "axis", n)
        object.__setattr__(self, "angle", angle)

    @classmethod
    def from_three_points(cls, p0, via, p1) -> Arc:
        """The arc of the circle through three points from p0 through ``via`` to p1."""
        a, m, b = _vec3(p0, "arc start"), _vec3(via, "arc via point"), _vec3(p1, "arc end")
        e1, e2 = m - a, b - a
        nvec = np.cross(e1, e2)
        nn = float(np.dot(nvec, nvec))
        scale = max(np.dot(e1, e1), np.dot(e2, e2))
        if nn <= 1e-18 * scale * scale or scale == 0.0:
            raise InputError("arc points are collinear or coincide: no unique circle")
        # circumcentre: a + ((|e1|^2 e2 - |e2|^2 e1) x (e1 x e2)) / (2 |e1 x e2|^2)
        c = a + np.cross(np.dot(e1, e1) * e2 - np.dot(e2, e2) * e1, nvec) / (2.0 * nn)
        # a -> m -> b counter-clockwise about n (an inscribed triangle in circular order is
        # positively oriented), so the arc from a to b about n passes through m
        n = nvec / math.sqrt(nn)
        u, w = a - c, b - c
        phi = math.atan2(float(np.dot(np.cross(u, w), n)), float(np.dot(u, w)))
        if phi <= 0.0:
            phi += 2.0 * math.pi
        return cls(c, a, n, phi)

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.start_point - self.center))

    @property
    def start(self):
        return self.start_point

    @property
    def end(self):
        return self.evaluate(np.array([1.0]))[0][0]

    @property
    def length(self) -> float:
        return self.radius * abs(self.angle)

    def evaluate(self, s):
        s = np.asarray(s, dtype=float).reshape(-1)
        u = self.start_point - self.center
        w = np.cross(self.axis, u)
        ph = s * self.angle
        c, sn = np.cos(ph)[:, None], np.sin(ph)[:, None]
        p = self.center + c * u + sn * w
        dp = self.angle * (-sn * u + c * w)
        ddp = -(self.angle**2) * (c * u + sn * w)
        return p, dp, ddp


# =========================================================================== segments


@dataclass(frozen=True)
class Segment:
    """One piece of a trajectory: a path run through in ``duration`` seconds with a time
    scaling; orientation slerped from R0 to R1 (None: no orientation); prescribed joint
    values interpolated from j0 to j1 (empty arrays: none)."""

    path: object
    duration: float
    scaling: object = field(default_factory=Quintic)
    R0: np.ndarray | None = None
    R1: np.ndarray | None = None
    j0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    j1: np.ndarray = field(default_factory=lambda: np.zeros(0))
    label: str = ""

    def __post_init__(self):
        T = float(self.duration)
        if not (math.isfinite(T) and T > 0.0):
            raise InputError(f"segment duration must be positive, got {self.duration!r}")
        object.__setattr__(self, "duration", T)
        object.__setattr__(self, "scaling", _scaling(self.scaling))
        if (self.R0 is None) != (self.R1 is None):
            raise InputError("give both R0 and R1 or neither")
        if self.R0 is not None:
            object.__setattr__(self, "R0", _rotation(self.R0, "R0"))
            object.__setattr__(self, "R1", _rotation(self.R1, "R1"))
            object.__setattr__(self, "_k", rot_log(self.R0.T @ self.R1))
        j0 = np.atleast_1d(np.asarray(self.j0, dtype=float))
        j1 = np.atleast_1d(np.asarray(self.j1, dtype=float))
        if j0.shape != j1.shape or j0.ndim != 1:
            raise InputError("prescribed joint values j0 and j1 must be vectors of one length")
        object.__setattr__(self, "j0", j0)
        object.__setattr__(self, "j1", j1)

    @property
    def rotation_angle(self) -> float:
        return 0.0 if self.R0 is None else float(np.linalg.norm(self._k))

    def evaluate(self, t_local):
        """Everything at local times t_local (N,) in [0, duration]: a dict of arrays."""
        t_local = np.asarray(t_local, dtype=float).reshape(-1)
        T = self.duration
        s, sd, sdd = self.scaling(t_local / T)
        sd, sdd = sd / T, sdd / T**2
        p, dp, ddp = self.path.evaluate(s)
        out = {
            "s": s,
            "sd": sd,
            "sdd": sdd,
            "p": p,
            "v": dp * sd[:, None],
            "a": ddp * (sd**2)[:, None] + dp * sdd[:, None],
        }
        if self.R0 is not None:
            out["R"] = self.R0 @ rot_exp(s[:, None] * self._k)
            k_base = self.R0 @ self._k  # the slerp axis (times angle) in the base frame
            out["w"] = sd[:, None] * k_base
            out["wd"] = sdd[:, None] * k_base
        dj = self.j1 - self.j0
        out["qj"] = self.j0 + s[:, None] * dj
        out["qjd"] = sd[:, None] * dj
        out["qjdd"] = sdd[:, None] * dj
        return out


@dataclass
class CartesianSamples:
    """A trajectory sampled at times t (N,): position p, velocity v, acceleration a (N, 3);
    orientation R (N, 3, 3), angular velocity w and acceleration wd (N, 3) (None without
    orientation); prescribed joints qj, qjd, qjdd (N, k); segment index (N,)."""

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    R: np.ndarray | None
    w: np.ndarray | None
    wd: np.ndarray | None
    qj: np.ndarray
    qjd: np.ndarray
    qjdd: np.ndarray
    segment: np.ndarray


class CartesianTrajectory:
    """Segments run one after the other (each starts where the previous one ended: position,
    orientation and prescribed joints continuous; checked). Built directly from
    :class:`Segment` objects or with :class:`PathBuilder`."""

    def __init__(self, segments):
        segments = list(segments)
        if not segments:
            raise InputError("a trajectory needs at least one segment")
        has_R = {s.R0 is not None for s in segments}
        if len(has_R) != 1:
            raise InputError("either every segment has an orientation or none does")
        nj = {s.j0.size for s in segments}
        if len(nj) != 1:
            raise InputError("every segment must prescribe the same number of joints")
        for k in range(1, len(segments)):
            a, b = segments[k - 1], segments[k]
            scale = max(1.0, float(np.max(np.abs(a.path.end))))
            if np.linalg.norm(a.path.end - b.path.start) > 1e-9 * scale:
                raise InputError(
                    f"segment {k} starts at {b.path.start}, segment {k - 1} ends at "
                    f"{a.path.end}: the path must be continuous"
                )
            if a.R1 is not None and np.max(np.abs(a.R1 - b.R0)) > 1e-9:
                raise InputError(
                    f"segment {k} starts with another orientation than segment {k - 1} ends with"
                )
            if np.max(np.abs(a.j1 - b.j0), initial=0.0) > 1e-12:
                raise InputError(f"segment {k}: prescribed joints jump at the start")
        self.segments = segments
        self.has_orientation = segments[0].R0 is not None
        self.n_joints_prescribed = segments[0].j0.size
        self.starts = np.concatenate([[0.0], np.cumsum([s.duration for s in segments])])

    @property
    def duration(self) -> float:
        return float(self.starts[-1])

    @property
    def breaks(self) -> np.ndarray:
        """Times where one segment ends and the next starts."""
        return self.starts[1:-1].copy()

    def sample_times(self, dt: float) -> np.ndarray:
        """A uniform grid from 0 to the duration with a step <= dt (exactly dt when the
        duration is a multiple of dt)."""
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise InputError(f"time step must be positive, got {dt!r}")
        n = int(math.ceil(self.duration / dt - 1e-9)) + 1
        return np.linspace(0.0, self.duration, max(n, 2))

    def evaluate(self, t) -> CartesianSamples:
        t = np.asarray(t, dtype=float).reshape(-1)
        seg = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.segments) - 1)
        N, k = t.size, self.n_joints_prescribed
        p, v, a = np.empty((N, 3)), np.empty((N, 3)), np.empty((N, 3))
        R = np.empty((N, 3, 3)) if self.has_orientation else None
        w = np.empty((N, 3)) if self.has_orientation else None
        wd = np.empty((N, 3)) if self.has_orientation else None
        qj, qjd, qjdd = np.empty((N, k)), np.empty((N, k)), np.empty((N, k))
        for i, s in enumerate(self.segments):
            sel = seg == i
            if not sel.any():
                continue
            out = s.evaluate(np.clip(t[sel] - self.starts[i], 0.0, s.duration))
            p[sel], v[sel], a[sel] = out["p"], out["v"], out["a"]
            if R is not None:
                R[sel], w[sel], wd[sel] = out["R"], out["w"], out["wd"]
            qj[sel], qjd[sel], qjdd[sel] = out["qj"], out["qjd"], out["qjdd"]
        return CartesianSamples(t, p, v, a, R, w, wd, qj, qjd, qjdd, seg)


class PathBuilder:
    """Chain segments from a start pose::

        b = PathBuilder([0.9, 0, 0.9], R=None, joints=[0.0])
        b.line([0.6, 0.5, 0.6], 2.0).line([0.6, 0.5, 0.35], 1.0, joints=[1.57])
        b.arc(via, end, 3.0).dwell(0.5)
        traj = b.build()

    ``R=None`` / ``joints=None`` in a step keep the current orientation / joint values."""

    def __init__(self, start, R=None, joints=(), scaling="quintic"):
        self.p = _vec3(start, "start")
        self.R = None if R is None else _rotation(R)
        self.j = np.atleast_1d(np.asarray(joints, dtype=float)).reshape(-1)
        self.scaling = _scaling(scaling)
        self.segments: list[Segment] = []

    def _add(self, path, duration, R, joints, scaling, label):
        if R is not None and self.R is None:
            raise InputError(
                "this path has no orientation: give R at the start (PathBuilder(R=...))"
            )
        R1 = self.R if R is None else _rotation(R)
        j1 = (
            self.j if joints is None else np.atleast_1d(np.asarray(joints, dtype=float)).reshape(-1)
        )
        if j1.shape != self.j.shape:
            raise InputError(f"joints must have {self.j.size} values")
        self.segments.append(
            Segment(
                path,
                duration,
                self.scaling if scaling is None else scaling,
                self.R,
                R1,
                self.j,
                j1,
                label,
            )
        )
        self.p, self.R, self.j = path.end.copy(), R1, j1
        return self

    def line(self, end, duration, R=None, joints=None, scaling=None, label=""):
        return self._add(Line(self.p, end), duration, R, joints, scaling, label or "line")

    def arc(self, via, end, duration, R=None, joints=None, scaling=None, label=""):
        """Through ``via`` to ``end`` on the circle through the current point, via and end."""
        arc = Arc.from_three_points(self.p, via, end)
        return self._add(arc, duration, R, joints, scaling, label or "arc")

    def arc_about(self, center, axis, angle, duration, R=None, joints=None, scaling=None, label=""):
        """Turn by ``angle`` about ``axis`` through ``center`` (the axis is moved along
        itself to the current point's plane)."""
        c = _vec3(center, "center")
        n = _vec3(axis, "axis")
        n = n / np.linalg.norm(n)
        c = c + np.dot(self.p - c, n) * n
        return self._add(Arc(c, self.p, n, angle), duration, R, joints, scaling, label or "arc")

    def dwell(self, duration, label=""):
        return self._add(Line(self.p, self.p), duration, None, None, None, label or "dwell")

    def build(self) -> CartesianTrajectory:
        return CartesianTrajectory(self.segments)
