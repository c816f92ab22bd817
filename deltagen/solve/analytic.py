"""Closed-form (analytic) inverse kinematics of serial arms, all branches at once, batched.

``analytic_solver(desc)`` looks at a :class:`~deltagen.model.serial.SerialDescription`
and returns an :class:`AnalyticSolver` when the arm has one of the structures below, or
``None``. Nothing is keyed on robot names: the structure is read from the joint axes of the
description (any convention: standard DH, modified DH, universal coordinates; base and tool
transforms included), and the solution is written in terms of those axes.

Method (geometric, product of exponentials). With the joint axes at q = 0 (unit direction
``w_i`` and a point ``o_i`` in the world frame, from :func:`reference.joint_axes`; the joint
offsets are part of the q = 0 pose) every arm satisfies

    T(q) = exp(xi_1 q_1) ... exp(xi_n q_n) T(0)

(a revolute joint turns about its axis by q_i, a prismatic one slides along it). Base and
tool transforms are inside T(0) and the world-frame axes, so they need no special case.
``G = T_target T(0)^-1`` is the motion the joints must produce. The structure is checked
numerically when the solver is built (parallel / intersecting axes to 1e-9 of the arm's
size) and the product-of-exponentials model is compared with the reference forward
kinematics at a few random configurations; any mismatch gives ``None``.

Supported structures
--------------------

``planar`` -- 2 or 3 revolute joints with parallel axes (direction u, either sign) and at most
    one prismatic joint along u: the lecture's planar 2R SCARA, the 4-axis SCARAs (Manutec h5,
    Bosch SR800 with its lift). The first two revolute joints form a planar 2R arm for the
    point P: the tool point (2R arm) or the point of the last revolute axis (3R: its roll
    joint takes up the yaw). Law of cosines for both elbows; the prismatic joint from the
    component along u; the roll joint from the target yaw psi (rotation about u).
    For the 2R arm with the full pose given, Paul's method (lecture slides 103-105) is used:
    psi = q1 + q2 from the target rotation, q1 = atan2(y - L2 sin psi, x - L2 cos psi),
    q2 = psi - q1 (written for the axes of the description); it is well conditioned also at
    the stretched arm, and the pose fixes the elbow: only that branch is filled.
    Configurations ``("elbow_up", "elbow_down")``: seen from the tip of the first axis
    direction u, the elbow (second axis) lies to the left (counter-clockwise) of the line
    from the first axis to P for ``elbow_up`` and to the right for ``elbow_down`` (slide 95,
    alpha = beta = 30 deg, is ``elbow_down``: the elbow lies below the line).

``elbow_4r`` -- 4 revolute joints: axis 1 not parallel to axis 2, axes 2 and 3 parallel
    (distinct), axis 4 not parallel to axis 2 (a roll joint): the Miskolc paper's RRRR robot.
    The point W of axis 4 nearest the tool point is positioned by joints 1-3 (paper eqs. 4-9:
    q1 from atan2, the elbow from the law of cosines), q4 is the remaining roll about axis 4.
    With the full pose given, joints 2+3 are taken from the direction of axis 4 in the target
    (Paul's method again), which fixes the elbow of each shoulder branch.
    Configurations ``front_up, front_down, back_up, back_down`` (see below).

``spherical_wrist_6r`` -- 6 revolute joints: axis 1 not parallel to axis 2, axes 2 and 3
    parallel (distinct), axes 4, 5, 6 through one point W (central wrist), 4 not parallel to
    5, 5 not parallel to 6: Puma 560, MOTOMAN UP6 (universal coordinates), Manutec r15. This
    is the ortho-parallel class of Brandstoetter, Angerer and Hofbaur (2014), without their
    restriction to an orthogonal axis 1 / axis 2 pair and to a fixed zero pose: the wrist
    centre W_t = G W fixes q1 (two solutions), the elbow q3 (two, law of cosines, eqs. (7)-(12)
    of the EASY-ROB paper with the cosine law in place of its eq. (9)) and q2; the wrist
    rotation (R1 R2 R3)^T R_G (eq. 13) gives q4, q5 (Paden-Kahan subproblem 2, two solutions:
    the wrist flip) and q6. Eight configurations ``{front|back}_{up|down}_{noflip|flip}``.

Configuration names of the elbow arms: ``front`` has the wrist centre in front of axis 1 in
the arm's own frame (same side as at q = 0), ``back`` reaches over behind it (for the Puma 560
with Corke's parameters, front = "right-handed", back = "left-handed"). ``up``: the elbow lies
on the side of the shoulder-wrist line towards the direction of axis 1 ("above" it for an
upward axis 1) when the wrist is reached outwards, in the arm's own frame; ``down`` bends the
other way (the name is the bend direction and stays with its branch when the wrist centre
goes over the top or behind the shoulder). ``noflip``: sin(q5 - q5s) <= 0, q5s being the value
of q5 at which axis 6 lines up with axis 4 (0 for all bundled arms), i.e. q5 <= 0 near the
straight wrist as the industrial "N" (non-flip) setting; ``flip`` the other wrist solution
(q4 + pi, -q5, q6 + pi for an orthogonal wrist). For the Puma 560 the eight names are exactly
those of Corke's ``ikine_a``: front/back = r/l, up/down = u/d, noflip/flip = n/f.

Results
-------

``solve(T)`` takes poses (..., 4, 4) and returns ``q`` (..., k, n) and ``valid`` (..., k),
k = len(configs). Revolute angles are wrapped into the joint range where a 2 pi shift makes
them fit (into [-pi, pi) otherwise). ``valid`` = a real solution exists, it is finite, it
reproduces the target (forward kinematics within ``tol``: rotation entries and position /
arm size) and it lies within the joint limits. Branches without a real solution (target out
of reach, or a pose the arm cannot take: a 4-DOF arm's target with the wrong tilt) are NaN;
solutions that only violate joint limits keep their values with ``valid`` False.
Nothing raises or warns for unreachable, singular or non-finite targets.

Singularities: at a wrist singularity (axis 6 in line with axis 4) q4 is set to 0 and q6
takes the whole turn about the common axis; the flip branch then coincides. At the shoulder
singularity (wrist centre on axis 1, possible without a shoulder offset) any q1 reaches the
pose; the front branches take q1 = 0, the back ones q1 = -pi. At
the stretched or folded elbow the two elbow branches coincide (the joint angles there are
good to about 1e-8 rad, the ill-conditioned arccos, while the pose is still met to rounding).

``position_only=True`` asks for the tool point only (arms with fewer than 6 joints; no effect
on 6R arms): both elbows of the planar 2R, the SCARA roll / the 4R roll set as near to the
target's rotation as the arm allows; valid then checks the position alone. It needs the tool
point on the last axis for the 3R SCARA and the 4R arm (raises InputError otherwise).
"""

from __future__ import annotations

import math

import numpy as np

from deltagen.inputs import InputError, as_float_array
from deltagen.reference import serial as reference
from deltagen.model.serial import SerialDescription

__all__ = ["AnalyticSolver", "analytic_solver"]

_GEO_TOL = 1e-9  # structure checks: relative to the arm's size
_NONPAR = 1e-6  # |w_i x w_j| above this: "not parallel"
_LIMIT_TOL = 1e-12  # a joint value this close outside a limit is clipped onto it
_SING = 1e-12  # wrist singular when |(R_w w6) x w4| is below this
_TWO_PI = 2.0 * math.pi
_CHUNK = 8192  # poses per pass (keeps the temporaries in cache)


# ------------------------------------------------------------------------ small helpers


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _skew(w) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _rotv(w, th, v) -> np.ndarray:
    """Rotate vectors v (..., 3) about the unit axis w (3,) by th (...) (Rodrigues)."""
    th = np.asarray(th, dtype=float)[..., None]
    c, s = np.cos(th), np.sin(th)
    return v * c + (v @ _skew(w).T) * s + np.multiply.outer(v @ w, w) * (1.0 - c)


def _cross(a, b) -> np.ndarray:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _sp1(w, a, b) -> np.ndarray:
    """Paden-Kahan subproblem 1: the angle about the unit axis w that turns the component
    of a normal to w into the direction of that of b (atan2(0, 0) = 0 if either is 0)."""
    a = a - (a @ w)[..., None] * w
    b = b - (b @ w)[..., None] * w
    return np.arctan2(_cross(a, b) @ w, np.sum(a * b, axis=-1))


def _cross2(a, b) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _rot2(th, v) -> np.ndarray:
    """Rotate 2D vectors v (..., 2) by th (...)."""
    c, s = np.cos(th), np.sin(th)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _angle2(v) -> np.ndarray:
    return np.arctan2(v[..., 1], v[..., 0])


def _two_link(uu, vv, t, sigma):
    """Planar 2R arm: first axis at the origin, second at uu, the point at uu + vv (q = 0).
    Find (th1, th2) with R(th1) (uu + R(th2) vv) = t; sigma = +-1 picks the branch
    (sin of the bend angle th2 + angle(vv) - angle(uu) has the sign of sigma).
    t (..., 2), sigma broadcastable to t[..., 0]. Returns th1, th2, ok (law of cosines met
    to 1e-9; th values clipped onto the nearest real solution otherwise)."""
    lu, lv = float(np.hypot(*uu)), float(np.hypot(*vv))
    kappa = (np.sum(t * t, axis=-1) - lu * lu - lv * lv) / (2.0 * lu * lv)
    ok = np.abs(kappa) <= 1.0 + 1e-9
    kc = np.clip(kappa, -1.0, 1.0)
    bend = sigma * np.arctan2(np.sqrt(1.0 - kc * kc), kc)
    th2 = _angle2(uu) - _angle2(vv) + bend
    m = uu + _rot2(th2, np.broadcast_to(vv, th2.shape + (2,)))
    th1 = np.arctan2(_cross2(m, t), np.sum(m * t, axis=-1))
    return th1, th2, ok


def _line_distance(o1, w1, o2, w2) -> float:
    n = np.cross(w1, w2)
    if np.linalg.norm(n) < _NONPAR:  # parallel: distance of o2 from line 1
        d = o2 - o1
        return float(np.linalg.norm(d - (d @ w1) * w1))
    return float(abs((o2 - o1) @ _unit(n)))


def _foot(p, o, w) -> np.ndarray:
    """Point of the line (o, w) nearest p."""
    return o + ((p - o) @ w) * w


def _common_point(points, dirs):
    """Least-squares intersection of lines; (point, max distance of the lines from it)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for o, w in zip(points, dirs):
        P = np.eye(3) - np.outer(w, w)
        A += P
        b += P @ o
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    dist = max(float(np.linalg.norm((np.eye(3) - np.outer(w, w)) @ (x - o)))
               for o, w in zip(points, dirs))
    return x, dist


# ------------------------------------------------------------------- screw-axis model


class _Chain:
    """Joint axes at q = 0 in the world frame and T(0): T(q) = prod exp(xi_i q_i) T(0)."""

    def __init__(self, desc: SerialDescription):
        n = desc.n
        zero = np.zeros((1, n))
        o, w = reference.joint_axes(desc, zero)
        self.n = n
        self.o = o[0].copy()
        self.w = w[0] / np.linalg.norm(w[0], axis=1, keepdims=True)
        self.T0 = reference.fk(desc, zero)[0][0].copy()
        self.R0 = self.T0[:3, :3]
        self.p0 = self.T0[:3, 3]
        self.revolute = np.array([j.revolute for j in desc.joints], dtype=bool)
        pts = np.vstack([self.o, self.p0])
        self.scale = max(1.0, float(np.max(np.linalg.norm(pts - pts[0], axis=1))))

    def fk(self, q: np.ndarray):
        """(R (M, 3, 3), p (M, 3)) for q (M, n): the flange point and two axes of T(0)
        carried through exp(xi_n q_n), ..., exp(xi_1 q_1) (Rodrigues on vectors)."""
        M = q.shape[0]
        V = np.empty((M, 3, 3))
        V[:, 0] = self.p0
        V[:, 1:] = self.R0[:, :2].T
        for i in range(self.n - 1, -1, -1):
            w, o = self.w[i], self.o[i]
            if self.revolute[i]:
                V[:, 0] -= o
                V = _rotv(w, q[:, i, None], V)
                V[:, 0] += o
            else:
                V[:, 0] += w * q[:, i, None]
        R = np.stack([V[:, 1], V[:, 2], _cross(V[:, 1], V[:, 2])], axis=-1)
        return R, V[:, 0]

    def matches_reference(self, desc) -> bool:
        rng = np.random.default_rng(20140101)
        q = rng.uniform(-2.0, 2.0, size=(8, self.n))
        T, _ = reference.fk(desc, q)
        R, p = self.fk(q)
        return (np.max(np.abs(R - T[:, :3, :3])) < 1e-9
                and np.max(np.abs(p - T[:, :3, 3])) < 1e-9 * self.scale)


# ----------------------------------------------------------------------- the solvers


class AnalyticSolver:
    """All closed-form inverse-kinematics branches of one arm (see the module docstring).

    Attributes: ``description``, ``structure`` (name of the recognised structure),
    ``configs`` (branch names, k of them), ``n`` (joints).
    """

    structure = ""
    configs: tuple = ()

    def __init__(self, desc: SerialDescription, chain: _Chain):
        self.description = desc
        self.n = desc.n
        self._ch = chain
        self._qlim = desc.qlim
        self._position_only_ok = True

    def __repr__(self):
        return (f"AnalyticSolver({self.description.name!r}, {self.structure}, "
                f"{len(self.configs)} configurations)")

    # -- public ------------------------------------------------------------------------

    def solve(self, T, *, position_only: bool = False, limits: bool = True, tol: float = 1e-8,
              check: bool = True):
        """All branches for poses T (..., 4, 4) -> (q (..., k, n), valid (..., k)).

        ``tol``: accepted forward-kinematics residual (rotation entries; position divided by
        the arm's size, at least 1 m). ``limits=False`` ignores the joint limits in
        ``valid`` (angles are still wrapped into the ranges where possible).
        ``check=False`` skips the forward-kinematics verification (about 2/3 of the time
        for a 6R arm): ``valid`` then only says that the closed form had a real solution,
        which for a 6R arm and a rigid T means the pose is reached, but for the arms with
        fewer joints does not confirm the part of the pose they cannot choose.
        """
        T = as_float_array(T, "T")
        if T.ndim < 2 or T.shape[-2:] != (4, 4):
            raise InputError(f"T must have shape (..., 4, 4), got {T.shape}")
        if position_only and not self._position_only_ok:
            raise InputError(
                f"{self.description.name}: position_only needs the tool point on the last "
                "joint axis (it would move with the last joint otherwise)")
        lead = T.shape[:-2]
        Tf = T.reshape(-1, 4, 4)
        N, k, n = Tf.shape[0], len(self.configs), self.n
        q = np.empty((N, k, n))
        valid = np.empty((N, k), dtype=bool)
        for a in range(0, N, _CHUNK):
            b = min(N, a + _CHUNK)
            q[a:b], valid[a:b] = self._solve_chunk(Tf[a:b], bool(position_only), bool(limits),
                                                   float(tol), bool(check))
        return q.reshape(lead + (k, n)), valid.reshape(lead + (k,))

    def _solve_chunk(self, Tf, position_only, limits, tol, check):
        with np.errstate(all="ignore"):
            finite = np.all(np.isfinite(Tf), axis=(1, 2))
            Tc = np.where(finite[:, None, None], Tf, np.eye(4))
            q, ok = self._solve(Tc[:, :3, :3], Tc[:, :3, 3], position_only)
            ok = ok & finite[:, None]
            q, inside = self._fit_limits(q)
            ok &= np.all(np.isfinite(q), axis=-1)
            if check:
                ok &= self._reproduces(Tc, q, ok, position_only, tol)
            valid = ok & inside if limits else ok.copy()
            q[~ok] = np.nan
        return q, valid

    # -- shared steps --------------------------------------------------------------------

    def _fit_limits(self, q):
        q = q.copy()
        inside = np.ones(q.shape[:-1], dtype=bool)
        for i in range(self.n):
            lo, hi = self._qlim[i]
            x = q[..., i]
            if self._ch.revolute[i]:
                x = np.mod(x + math.pi, _TWO_PI) - math.pi  # [-pi, pi)
                fits = (x >= lo - _LIMIT_TOL) & (x <= hi + _LIMIT_TOL)
                for shift in (_TWO_PI, -_TWO_PI, 2 * _TWO_PI, -2 * _TWO_PI):
                    y = x + shift
                    fy = (y >= lo - _LIMIT_TOL) & (y <= hi + _LIMIT_TOL) & ~fits
                    x = np.where(fy, y, x)
                    fits |= fy
            else:
                fits = (x >= lo - _LIMIT_TOL) & (x <= hi + _LIMIT_TOL)
            q[..., i] = np.where(fits, np.clip(x, lo, hi), x)
            inside &= fits
        return q, inside

    def _reproduces(self, T, q, ok, position_only, tol):
        N, k, n = q.shape
        good = np.zeros((N, k), dtype=bool)
        idx = np.flatnonzero(ok.reshape(-1))
        if idx.size == 0:
            return good
        rows = idx // k
        R, p = self._ch.fk(q.reshape(-1, n)[idx])
        err_p = np.max(np.abs(p - T[rows, :3, 3]), axis=-1) / self._ch.scale
        passed = err_p <= tol
        if not position_only:
            passed &= np.max(np.abs(R - T[rows, :3, :3]), axis=(1, 2)) <= tol
        good.reshape(-1)[idx] = passed
        return good

    def _solve(self, R_t, p_t, position_only):  # pragma: no cover - abstract
        raise NotImplementedError


class _PlanarSolver(AnalyticSolver):
    configs = ("elbow_up", "elbow_down")
    _SIGMA = (-1.0, 1.0)  # bend sign of each configuration (see _two_link)

    @classmethod
    def detect(cls, desc, ch: _Chain):
        rev = np.flatnonzero(ch.revolute)
        pri = np.flatnonzero(~ch.revolute)
        if len(rev) not in (2, 3) or len(pri) > 1:
            return None
        u = ch.w[rev[0]]
        if any(np.linalg.norm(np.cross(ch.w[i], u)) > _GEO_TOL for i in range(ch.n)):
            return None
        tol = _GEO_TOL * ch.scale
        ia, ib = rev[0], rev[1]
        if _line_distance(ch.o[ia], u, ch.o[ib], u) < tol:
            return None
        self = cls(desc, ch)
        self.structure = "planar"
        self._u = u
        self._sign = np.sign(ch.w @ u)  # each joint's axis = sign * u
        self._ia, self._ib = ia, ib
        self._ic = rev[2] if len(rev) == 3 else None
        self._ip = pri[0] if len(pri) else None
        e1 = ch.o[ib] - ch.o[ia]
        e1 = _unit(e1 - (e1 @ u) * u)
        self._E = np.stack([e1, np.cross(u, e1)])  # (2, 3): plane coordinates
        self._A = self._E @ ch.o[ia]
        self._B = self._E @ ch.o[ib]
        if self._ic is None:
            self._P = ch.p0.copy()
        else:
            self._P = _foot(ch.p0, ch.o[self._ic], u)
            self._position_only_ok = bool(np.linalg.norm(ch.p0 - self._P) < tol)
        self._uu = self._B - self._A
        self._vv = self._E @ self._P - self._B
        if np.hypot(*self._vv) < tol:
            return None
        return self

    def _solve(self, R_t, p_t, position_only):
        ch = self._ch
        N = R_t.shape[0]
        R_G = R_t @ ch.R0.T
        p_G = p_t - np.einsum("nij,j->ni", R_G, ch.p0)
        P_t = p_t if position_only else np.einsum("nij,j->ni", R_G, self._P) + p_G
        h = (P_t - self._P) @ self._u  # travel along u
        t = P_t @ self._E.T - self._A  # (N, 2)
        g1 = R_G @ self._E[0]
        yaw = np.arctan2(g1 @ self._E[1], g1 @ self._E[0])  # rotation about u
        sigma = np.array(self._SIGMA)
        th1, th2, ok = _two_link(self._uu, self._vv, t[:, None, :], sigma[None, :])
        ok = np.broadcast_to(ok, th1.shape)
        if self._ic is None and not position_only:
            # Paul's method (slides 103-105): psi from the target rotation, the second axis
            # from the target pose; the pose fixes the elbow, the other branch stays empty.
            B_t = np.einsum("nij,j->ni", R_G, ch.o[self._ib]) + p_G
            tb = B_t @ self._E.T - self._A
            p1 = _angle2(tb) - _angle2(self._uu)
            p2 = yaw - p1
            bend = np.sin(p2 + _angle2(self._vv) - _angle2(self._uu))
            down = bend >= 0.0
            th1 = np.stack([np.where(down, np.nan, p1), np.where(down, p1, np.nan)], axis=1)
            th2 = np.stack([np.where(down, np.nan, p2), np.where(down, p2, np.nan)], axis=1)
            ok = np.isfinite(th1)
        q = np.zeros((N, 2, self.n))
        s = self._sign
        q[:, :, self._ia] = s[self._ia] * th1
        q[:, :, self._ib] = s[self._ib] * th2
        if self._ic is not None:
            q[:, :, self._ic] = s[self._ic] * (yaw[:, None] - th1 - th2)
        if self._ip is not None:
            q[:, :, self._ip] = s[self._ip] * h[:, None]
        return q, ok


class _ElbowSolver(AnalyticSolver):
    @classmethod
    def detect(cls, desc, ch: _Chain):
        n = ch.n
        if n not in (4, 6) or not ch.revolute.all():
            return None
        w, o = ch.w, ch.o
        tol = _GEO_TOL * ch.scale
        if np.linalg.norm(np.cross(w[0], w[1])) < _NONPAR:
            return None
        if np.linalg.norm(np.cross(w[1], w[2])) > _GEO_TOL:
            return None
        if _line_distance(o[1], w[1], o[2], w[2]) < tol:
            return None
        self = cls(desc, ch)
        if n == 6:
            if (np.linalg.norm(np.cross(w[3], w[4])) < _NONPAR
                    or np.linalg.norm(np.cross(w[4], w[5])) < _NONPAR):
                return None
            W, dist = _common_point(o[3:6], w[3:6])
            if dist > tol:
                return None
            self.structure = "spherical_wrist_6r"
            self.configs = tuple(f"{s}_{e}_{f}" for s in ("front", "back")
                                 for e in ("up", "down") for f in ("noflip", "flip"))
        else:
            if np.linalg.norm(np.cross(w[3], w[1])) < _NONPAR:
                return None
            W = _foot(ch.p0, o[3], w[3])
            self._position_only_ok = bool(np.linalg.norm(ch.p0 - W) < tol)
            self.structure = "elbow_4r"
            self.configs = ("front_up", "front_down", "back_up", "back_down")
        self._W = W
        # Arm frame: ez = w1, ey = part of w2 normal to w1, ex = ey x ez, oriented so that the
        # wrist centre at q = 0 lies at ex >= 0 ("front").
        ez = w[0]
        ey = _unit(w[1] - (w[1] @ ez) * ez)
        ex = np.cross(ey, ez)
        if ex @ (W - o[0]) < 0:
            ex, ey = -ex, -ey
        self._ex, self._ey, self._ez = ex, ey, ez
        self._cw = float(w[1] @ (W - o[0]))
        self._cb, self._sb = float(w[1] @ ez), float(w[1] @ ey)
        # Plane normal to w2: coordinates (.ex, .et), positive rotation about w2 = CCW.
        et = np.cross(w[1], ex)
        self._P2 = np.stack([ex, et])
        S, E, Wp = self._P2 @ o[1], self._P2 @ o[2], self._P2 @ W
        self._S, self._uu, self._vv = S, E - S, Wp - E
        if np.hypot(*self._uu) < tol or np.hypot(*self._vv) < tol:
            return None
        self._s3 = float(np.sign(w[2] @ w[1]))
        up_sign = float(np.sign(w[0] @ et))
        # branches: (shoulder sign, elbow bend sign); "up" <=> bend = -up_sign * shoulder
        front = np.array([1.0, 1.0, -1.0, -1.0])
        self._front = front
        self._bend = np.array([-1.0, 1.0, -1.0, 1.0]) * up_sign * front
        if n == 6:
            x6 = np.cross(w[5], ex if np.linalg.norm(np.cross(w[5], ex)) > 0.1 else ey)
            self._x6 = _unit(x6)
        else:
            self._x4 = _unit(np.cross(w[3], ex if np.linalg.norm(np.cross(w[3], ex)) > 0.1
                                      else ey))
        return self

    def _arm(self, W_t, R_G=None, position_only=True):
        """Joints 1-3 placing the point W at W_t (N, 3) for the 4 arm branches:
        (q1, th2, th3 (rotation angles about w2), ok), each (N, 4)."""
        ch = self._ch
        o1 = ch.o[0]
        d = W_t - o1
        px, py, pz = d @ self._ex, d @ self._ey, d @ self._ez
        yV = (self._cw - self._cb * pz) / self._sb
        rad = px * px + py * py - yV * yV
        ok1 = rad >= -1e-9 * ch.scale ** 2
        xV = self._front[None, :] * np.sqrt(np.maximum(rad, 0.0))[:, None]  # (N, 4)
        yVb = np.broadcast_to(yV[:, None], xV.shape)
        q1 = np.arctan2(py, px)[:, None] - np.arctan2(yVb, xV)
        # wrist point on axis 1 (shoulder singularity, no shoulder offset): any q1 serves;
        # take 0 for the front branches and -pi for the back ones
        on_axis = px * px + py * py < (1e-12 * ch.scale) ** 2
        q1 = np.where(on_axis[:, None], np.where(self._front > 0, 0.0, -math.pi), q1)
        # wrist target in the arm frame (q1 undone), in plane coordinates
        V = (o1 + xV[..., None] * self._ex + yVb[..., None] * self._ey
             + pz[:, None, None] * self._ez)
        t = V @ self._P2.T - self._S
        th2, th3, ok2 = _two_link(self._uu, self._vv, t, self._bend[None, :])
        ok = ok1[:, None] & np.broadcast_to(ok2, th2.shape)
        if R_G is not None and not position_only:
            # 4R with the pose given: th2 + th3 from the direction of axis 4 (Paul's method).
            w1, w2, w4 = ch.w[0], ch.w[1], ch.w[3]
            d4 = np.broadcast_to((R_G @ w4)[:, None, :], xV.shape + (3,))
            d4 = _rotv(w1, -q1, d4)
            tot = _sp1(w2, w4, d4)
            p2 = _angle2(t - _rot2(tot, np.broadcast_to(self._vv, t.shape))) - _angle2(self._uu)
            p3 = tot - p2
            bend = np.sign(np.sin(p3 + _angle2(self._vv) - _angle2(self._uu)))
            bend = np.where(bend == 0.0, 1.0, bend)
            mine = bend == self._bend[None, :]
            th2 = np.where(mine, p2, np.nan)
            th3 = np.where(mine, p3, np.nan)
            # a branch whose twin took the solution stays empty; keep the other shoulder
            ok = ok1[:, None] & mine
        return q1, th2, th3, ok

    def _solve(self, R_t, p_t, position_only):
        ch = self._ch
        w = ch.w
        N = R_t.shape[0]
        R_G = R_t @ ch.R0.T
        p_G = p_t - np.einsum("nij,j->ni", R_G, ch.p0)
        if self.n == 4:
            W_t = p_t if position_only else np.einsum("nij,j->ni", R_G, self._W) + p_G
            q1, th2, th3, ok = self._arm(W_t, R_G, position_only)
            tot = th2 + th3
            # roll: (R1 R23)^T R_G x4 = Rot(w4, q4) x4
            y = np.broadcast_to((R_G @ self._x4)[:, None, :], q1.shape + (3,))
            y = _rotv(w[1], -tot, _rotv(w[0], -q1, y))
            q4 = _sp1(w[3], self._x4, y)
            q = np.stack([q1, th2, self._s3 * th3, q4], axis=-1)
            return q, ok
        W_t = np.einsum("nij,j->ni", R_G, self._W) + p_G
        q1, th2, th3, ok = self._arm(W_t)
        tot = th2 + th3
        # wrist rotation R_w = (R1 R23)^T R_G, applied to w6 and x6
        def undo(v):
            v = np.broadcast_to(v[:, None, :], q1.shape + (3,))
            return _rotv(w[1], -tot, _rotv(w[0], -q1, v))

        qv = undo(R_G @ w[5])  # R_w w6           (N, 4, 3)
        qx = undo(R_G @ self._x6)  # R_w x6
        w4, w5, w6 = w[3], w[4], w[5]
        c12 = float(w4 @ w5)
        s2 = 1.0 - c12 * c12
        a_q = qv @ w4
        b_p = float(w5 @ w6)
        alpha = (a_q - c12 * b_p) / s2
        beta = (b_p - c12 * a_q) / s2
        perp = _cross(qv, w4)
        gam2 = np.sum(perp * perp, axis=-1) / s2 - beta * beta
        okw = gam2 >= -1e-9
        gam = np.sqrt(np.maximum(gam2, 0.0))
        n45 = np.cross(w4, w5)
        sig = np.array([1.0, -1.0])  # noflip, flip: sin(q5 - q5s) has the sign of -sig
        c = (alpha[..., None, None] * w4 + beta[..., None, None] * w5
             + (sig[:, None] * gam[..., None, None]) * n45)  # (N, 4, 2, 3)
        q5 = _sp1(w5, w6, c)
        qv2 = np.broadcast_to(qv[:, :, None, :], c.shape)
        q4 = _sp1(w4, c, qv2)
        singular = np.linalg.norm(perp, axis=-1) < _SING
        q4 = np.where(singular[..., None], 0.0, q4)
        # q6: Rot(w6, q6) x6 = Rot(w5, -q5) Rot(w4, -q4) R_w x6
        y = _rotv(w5, -q5, _rotv(w4, -q4, np.broadcast_to(qx[:, :, None, :], c.shape)))
        q6 = _sp1(w6, self._x6, y)
        rep = lambda a: np.broadcast_to(a[..., None], q5.shape)  # noqa: E731
        q = np.stack([rep(q1), rep(th2), rep(self._s3 * th3), q4, q5, q6], axis=-1)
        q = q.reshape(N, 8, 6)
        okk = (ok & okw)[..., None] & np.ones(2, dtype=bool)
        return q, okk.reshape(N, 8)


def analytic_solver(desc: SerialDescription) -> AnalyticSolver | None:
    """The closed-form solver for ``desc``, or None when no supported structure applies."""
    if not isinstance(desc, SerialDescription):
        raise InputError("analytic_solver needs a SerialDescription")
    try:
        ch = _Chain(desc)
    except Exception:  # pragma: no cover - degenerate descriptions
        return None
    if not ch.matches_reference(desc):  # pragma: no cover - a convention the model misses
        return None
    for cls in (_PlanarSolver, _ElbowSolver):
        solver = cls.detect(desc, ch)
        if solver is not None:
            return solver
    return None
