"""Structure detection of a serial chain: which closed forms its joint axes allow.

Read from the description alone (any convention: standard DH, modified DH, universal
coordinates; base and tool transforms included) -- nothing is keyed on robot names. Both the
numpy closed-form solver (:mod:`deltagen.solve.analytic`) and the C kernel emitter
(:mod:`deltagen.derive.serial.ik_closed_form`) are written in terms of the objects made here,
so they share one set of precomputed constants; the singularity report
(:mod:`deltagen.solve.singularity`) reads the same detection.

Joint axes and the product of exponentials
------------------------------------------
:func:`joint_axes` composes the description's own link transforms
(:func:`deltagen.model.serial.frames`) at q = 0 and returns :class:`JointAxes`: for every
joint the unit direction ``w_i`` and a point ``o_i`` of its motion axis in the world (base)
frame, the tool pose ``T(0)`` and the arm's length scale. The joint offsets are part of the
q = 0 pose. Every arm then satisfies

    T(q) = exp(xi_1 q_1) ... exp(xi_n q_n) T(0)

(a revolute joint turns about its axis by q_i, a prismatic one slides along it), so base and
tool transforms need no special case. :meth:`JointAxes.fk` evaluates this model and
:meth:`JointAxes.matches` compares it with the composed transforms at a few random
configurations; :func:`detect` returns None on a mismatch.

Structures (tolerances of :mod:`deltagen.geometry.axes`: parallel when ``|w_i x w_j| <=
1e-9``, not parallel when ``>= 1e-6``, points within 1e-9 of the arm's scale)
--------------------------------------------------------------------------------------------
:class:`PlanarArm` (``planar``) -- 2 or 3 revolute joints with parallel axes (direction u,
    either sign) and at most one prismatic joint along u (SCARAs).
:class:`Elbow4R` (``elbow_4r``) -- 4 revolute joints: axis 1 not parallel to axis 2, axes 2
    and 3 parallel and distinct, axis 4 not parallel to axis 2 (a roll joint; Miskolc RRRR).
:class:`SphericalWrist6R` (``spherical_wrist_6r``) -- 6 revolute joints: axis 1 not parallel
    to axis 2, axes 2 and 3 parallel and distinct, axes 4, 5, 6 through one point W (central
    wrist), 4 not parallel to 5, 5 not parallel to 6 (Puma 560, Motoman UP6, Manutec r15).

:class:`ParallelTriple6R` (``parallel_triple_6r``) -- 6 revolute joints: axes 2, 3, 4 parallel
    and distinct, axis 1 and axis 5 not parallel to them, axes 5 and 6 meet in one point and
    are not parallel (UR3/5/10: shoulder, elbow and wrist 1 parallel, offset wrist).
:class:`StanfordArm` (``stanford_rrp_6``) -- joints R R P R R R: axes 1 and 2 meet, joint 3
    prismatic, axes 4, 5, 6 meet (central wrist): the Stanford arm.
:class:`GantryArm` (``gantry_wrist_3r``, ``gantry_head_2r``, ``gantry_rotary_1r``) -- a
    gantry ("Portal") robot: joints 1-3 prismatic with linearly independent directions (the
    Cartesian XYZ axes, in any order and sign, mutually orthogonal on a true gantry) followed
    by 3, 2 or 1 revolute joints: a 3R wrist (4 not parallel to 5, 5 not parallel to 6), a
    2R head (4 not parallel to 5, the tool z axis not parallel to 5) or one rotary axis (the
    palletiser). The slides do not turn anything, so the tool rotation is the wrist's alone
    and the slides then place the tool point by a linear solve: neither mutually orthogonal
    slides nor wrist axes through one point are needed for the closed form (a squareness
    error or a wrist offset keeps it exact).
:class:`ReversedChain` (``reversed``) -- 6 revolute joints whose chain read backwards
    (:func:`reversed_description`, T'(q_6, ..., q_1) = T(q)^-1) is a ``spherical_wrist_6r``
    or a ``parallel_triple_6r``: Pieper's other case, the first three axes meeting in a point
    (a humanoid's hip; TALOS' legs), solved backwards.

Each is a frozen dataclass of the precomputed quantities (arrays are read-only); the meaning
of the branch names and the solution method are in :mod:`deltagen.solve.analytic`.

Predicates of general use (UR-type arms have three consecutive parallel axes):
:func:`parallel_pairs`, :func:`parallel_runs`, :func:`common_point_of`,
:func:`central_wrist`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from deltagen.geometry import axes as geo
from deltagen.geometry.axes import LENGTH_TOL, NONPARALLEL_TOL, PARALLEL_TOL
from deltagen.geometry.rotations import rotate
from deltagen.model.serial import SerialDescription, axis_frame, frames

__all__ = [
    "JointAxes",
    "PlanarArm",
    "ElbowArm",
    "Elbow4R",
    "SphericalWrist6R",
    "ParallelTriple6R",
    "StanfordArm",
    "ReversedChain",
    "GantryArm",
    "GANTRY_KINDS",
    "Structure",
    "joint_axes",
    "detect",
    "detect_planar",
    "detect_elbow",
    "detect_parallel_triple",
    "detect_stanford",
    "detect_reversed",
    "detect_gantry",
    "reversed_description",
    "parallel_pairs",
    "parallel_runs",
    "common_point_of",
    "central_wrist",
    "ARM_BRANCHES",
]

_CHECK_SEED = 20140101  # the random configurations of JointAxes.matches
_ELBOW_CONFIGS = ("front_up", "front_down", "back_up", "back_down")
# The four arm branches of the elbow arms, in the order of _ELBOW_CONFIGS: shoulder sign
# (front = +1) and the factor of the elbow bend sign (see ElbowArm.bend).
ARM_BRANCHES = ((1.0, -1.0), (1.0, 1.0), (-1.0, -1.0), (-1.0, 1.0))


def _frozen(a: Any) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def _cross(a: Any, b: Any) -> np.ndarray:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


# ------------------------------------------------------------------------ joint axes


@dataclass(frozen=True, eq=False, repr=False)
class JointAxes:
    """The joint axes of a chain at q = 0 in the world (base) frame, and T(0).

    ``T(q) = exp(xi_1 q_1) ... exp(xi_n q_n) T(0)`` (module docstring).
    """

    name: str  # the arm's name (for messages)
    revolute: np.ndarray  # (n,) bool: revolute (True) or prismatic joint
    points: np.ndarray  # (n, 3) [m] o_i, a point of joint i's axis
    directions: np.ndarray  # (n, 3) w_i, unit direction of joint i's axis (motion sign)
    T0: np.ndarray  # (4, 4) tool pose at q = 0 [m]
    qlim: np.ndarray  # (n, 2) joint limits [rad or m], +-inf where a joint has none
    scale: float  # [m] the arm's size: max(1, largest distance of an o_i or p0 from o_1)

    def __repr__(self):
        return f"JointAxes({self.name!r}, {self.n} joints)"

    @property
    def n(self) -> int:
        return len(self.revolute)

    @property
    def R0(self) -> np.ndarray:
        """(3, 3) tool rotation at q = 0."""
        return self.T0[:3, :3]

    @property
    def p0(self) -> np.ndarray:
        """(3,) [m] tool point at q = 0."""
        return self.T0[:3, 3]

    def fk(self, q):
        """(R (M, 3, 3), p (M, 3) [m]) for q (M, n): the product of exponentials (the tool
        point and two axes of T(0) carried through exp(xi_n q_n), ..., exp(xi_1 q_1),
        Rodrigues on vectors)."""
        q = np.asarray(q, dtype=float)
        M = q.shape[0]
        V = np.empty((M, 3, 3))
        V[:, 0] = self.p0
        V[:, 1:] = self.R0[:, :2].T
        for i in range(self.n - 1, -1, -1):
            w, o = self.directions[i], self.points[i]
            if self.revolute[i]:
                V[:, 0] -= o
                V = rotate(w, q[:, i, None], V)
                V[:, 0] += o
            else:
                V[:, 0] += w * q[:, i, None]
        R = np.stack([V[:, 1], V[:, 2], _cross(V[:, 1], V[:, 2])], axis=-1)
        return R, V[:, 0]

    def matches(self, desc: SerialDescription) -> bool:
        """The product of exponentials agrees with the description's composed transforms
        (model.serial.frames) at 8 random configurations: rotation entries to 1e-9,
        position to 1e-9 of the scale."""
        rng = np.random.default_rng(_CHECK_SEED)
        q = rng.uniform(-2.0, 2.0, size=(8, self.n))
        T = frames(desc, q)[:, -1]
        R, p = self.fk(q)
        return (
            np.max(np.abs(R - T[:, :3, :3])) < 1e-9
            and np.max(np.abs(p - T[:, :3, 3])) < 1e-9 * self.scale
        )


def joint_axes(desc: SerialDescription) -> JointAxes:
    """The joint axes at q = 0 of ``desc`` (module docstring)."""
    n = desc.n
    F = frames(desc, np.zeros((1, n)))
    o = np.empty((n, 3))
    w = np.empty((n, 3))
    for i in range(n):
        k, c = axis_frame(desc, i)
        o[i] = F[0, k, :3, 3]
        w[i] = desc.joints[i].sign * F[0, k, :3, c]
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    T0 = np.ascontiguousarray(F[:, -1])[0].copy()
    pts = np.vstack([o, T0[:3, 3]])
    scale = max(1.0, float(np.max(np.linalg.norm(pts - pts[0], axis=1))))
    return JointAxes(
        name=desc.name,
        revolute=np.array([j.revolute for j in desc.joints], dtype=bool),
        points=_frozen(o),
        directions=_frozen(w),
        T0=_frozen(T0),
        qlim=_frozen(desc.qlim),
        scale=scale,
    )


# ------------------------------------------------------------------- the structures


class _Structure:
    """What every structure object offers: its axes' name in the repr, the joint limits."""

    axes: JointAxes

    def __repr__(self):
        return f"{type(self).__name__}({self.axes.name!r})"

    @property
    def qlim(self) -> np.ndarray:
        """(n, 2) joint limits [rad or m] (+-inf where a joint has none)."""
        return self.axes.qlim


@dataclass(frozen=True, eq=False, repr=False)
class PlanarArm(_Structure):
    """2-3 revolute joints with parallel axes (direction u) and at most one prismatic joint
    along u. The first two revolute joints form a planar 2R arm for the point P: the tool
    point (2R) or the point of the last revolute axis (3R: that joint is a roll about u).
    Plane coordinates: (x . e1, x . e2) with e1, e2 = ``plane``.
    """

    kind: ClassVar[str] = "planar"
    configs: ClassVar[tuple] = ("elbow_up", "elbow_down")
    bend_signs: ClassVar[tuple] = (-1.0, 1.0)  # sign of the elbow bend of each config

    axes: JointAxes
    u: np.ndarray  # (3,) unit direction shared by all axes (that of the first revolute one)
    signs: np.ndarray  # (n,) +-1: joint i's axis direction is signs[i] * u
    first: int  # index of the first revolute joint (the 2R arm's shoulder)
    second: int  # index of the second revolute joint (its elbow)
    roll: int | None  # index of the third revolute joint, or None (2R arm)
    lift: int | None  # index of the prismatic joint, or None
    plane: np.ndarray  # (2, 3) e1 (from the first towards the second axis, normal to u), u x e1
    first_xy: np.ndarray  # (2,) [m] the first axis in plane coordinates
    second_xy: np.ndarray  # (2,) [m] the second axis in plane coordinates
    point: np.ndarray  # (3,) [m] P at q = 0: the tool point, or its foot on the roll axis
    upper: np.ndarray  # (2,) [m] plane vector first axis -> second axis (q = 0)
    lower: np.ndarray  # (2,) [m] plane vector second axis -> P (q = 0)
    position_only_ok: bool  # the tool point is P (no roll, or the tool point on its axis)


@dataclass(frozen=True, eq=False, repr=False)
class ElbowArm(_Structure):
    """Joints 1-3 of an elbow arm: axis 1 not parallel to axis 2, axes 2 and 3 parallel and
    distinct; they place a point W (the wrist point) of the forearm.

    Arm frame (ex, ey, ez): ez = w1, ey = the part of w2 normal to w1, ex = ey x ez, oriented
    so that W at q = 0 lies at ex >= 0 ("front"). Elbow plane: normal to w2, coordinates
    (x . ex, x . et), et = w2 x ex, positive rotation about w2 counter-clockwise.
    Branch k of the arm (``ARM_BRANCHES`` order: front_up, front_down, back_up, back_down)
    has the shoulder sign ``front[k]`` and the elbow bend sign ``bend[k]`` of the planar 2R
    arm of joints 2 and 3 ("up" <=> bend = -up_sign * front, up_sign = sign(w1 . et)).
    """

    kind: ClassVar[str] = ""
    configs: ClassVar[tuple] = ()

    axes: JointAxes
    wrist: np.ndarray  # (3,) [m] W at q = 0
    ex: np.ndarray  # (3,) arm frame, unit
    ey: np.ndarray  # (3,)
    ez: np.ndarray  # (3,) = w1
    w2_offset: float  # [m] w2 . (W - o1): W's offset from axis 1 along w2 (the shoulder offset)
    cos_12: float  # w2 . ez (cosine of the angle between axes 1 and 2)
    sin_12: float  # w2 . ey (its sine, signed by the arm frame's orientation; not 0)
    plane: np.ndarray  # (2, 3) rows ex, et: coordinates in the plane normal to w2
    shoulder_xy: np.ndarray  # (2,) [m] axis 2 in plane coordinates
    upper: np.ndarray  # (2,) [m] plane vector axis 2 -> axis 3 (upper arm, q = 0)
    lower: np.ndarray  # (2,) [m] plane vector axis 3 -> W (forearm, q = 0)
    sign3: float  # +-1: w3 = sign3 * w2
    front: np.ndarray  # (4,) shoulder sign of each arm branch
    bend: np.ndarray  # (4,) elbow bend sign of each arm branch
    position_only_ok: bool  # the tool point is W (always for the central wrist)


@dataclass(frozen=True, eq=False, repr=False)
class Elbow4R(ElbowArm):
    """An elbow arm with a fourth revolute joint, a roll whose axis is not parallel to axis
    2; W is the point of axis 4 nearest the tool point."""

    kind: ClassVar[str] = "elbow_4r"
    configs: ClassVar[tuple] = _ELBOW_CONFIGS

    roll_ref: np.ndarray  # (3,) unit vector normal to w4: the roll angle's reference


@dataclass(frozen=True, eq=False, repr=False)
class _CentralWrist:
    """The central wrist of a six-axis arm: axes 4, 5, 6 meeting in one point, 4 not
    parallel to 5, 5 not parallel to 6 (the Puma's and the Stanford arm's), with the
    constants its Paden-Kahan subproblems 2 and 1 read (solve/analytic.py,
    derive/serial/ik_recipes.py); made by :func:`_central_wrist`."""

    wrist_ref: np.ndarray  # (3,) unit vector normal to w6: q6's reference
    cos_45: float  # w4 . w5
    cos_56: float  # w5 . w6
    normal_45: np.ndarray  # (3,) w4 x w5


@dataclass(frozen=True, eq=False, repr=False)
class SphericalWrist6R(ElbowArm, _CentralWrist):
    """An elbow arm with a central wrist: axes 4, 5, 6 through W (the wrist centre)."""

    kind: ClassVar[str] = "spherical_wrist_6r"
    configs: ClassVar[tuple] = tuple(
        f"{s}_{e}_{f}"
        for s in ("front", "back")
        for e in ("up", "down")
        for f in ("noflip", "flip")
    )


@dataclass(frozen=True, eq=False, repr=False)
class ParallelTriple6R(_Structure):
    """6 revolute joints with axes 2, 3, 4 parallel (direction u; distinct lines), axis 1 not
    parallel to u, axis 5 not parallel to u, axes 5 and 6 meeting in one point P5 and not
    parallel: the UR family (UR3/5/10, their offset wrist included). Pieper's class of three
    consecutive axes meeting at infinity; the closed form is in solve/analytic.py."""

    kind: ClassVar[str] = "parallel_triple_6r"
    configs: ClassVar[tuple] = tuple(
        f"shoulder{a}_elbow{b}_wrist{c}" for a in "pm" for b in "pm" for c in "pm"
    )

    axes: JointAxes
    u: np.ndarray  # (3,) unit direction of axis 2; w_i = signs[i] u for i = 1, 2, 3 (0-based)
    signs: np.ndarray  # (3,) +-1 of axes 2, 3, 4
    wrist: np.ndarray  # (3,) [m] P5: the common point of axes 5 and 6 (q = 0)
    plane: np.ndarray  # (2, 3) e1, e2 = u x e1: coordinates normal to u
    upper: np.ndarray  # (2,) [m] plane vector axis 2 -> axis 3
    lower: np.ndarray  # (2,) [m] plane vector axis 3 -> axis 4
    ref: np.ndarray  # (3,) unit vector normal to u (the reference of the angle about u)
    position_only_ok: ClassVar[bool] = False


@dataclass(frozen=True, eq=False, repr=False)
class StanfordArm(_Structure, _CentralWrist):
    """6 joints R R P R R R: axes 1 and 2 meet in a point c (not parallel), joint 3 slides
    along w3, axes 4, 5, 6 meet in W (central wrist; 4 not parallel to 5, 5 not parallel to
    6): the Stanford arm (Scheinman). The closed form is in solve/analytic.py."""

    kind: ClassVar[str] = "stanford_rrp_6"
    configs: ClassVar[tuple] = tuple(
        f"reach{a}_shoulder{b}_{c}" for a in "pm" for b in "pm" for c in ("noflip", "flip")
    )
    position_only_ok: ClassVar[bool] = False

    axes: JointAxes
    shoulder: np.ndarray  # (3,) [m] c, the common point of axes 1 and 2
    wrist: np.ndarray  # (3,) [m] W at q = 0


@dataclass(frozen=True, eq=False, repr=False)
class ReversedChain(_Structure):
    """A 6R chain whose reversed chain has a closed form: Pieper's other case, the first
    three axes meeting in a point (a humanoid's hip), or the first two meeting and axes 3, 4,
    5 parallel. Read backwards -- the tool frame as the base, joint 6 first -- the chain has
    its three meeting axes at the end (a central wrist) and ``inner`` is that chain's
    structure. Since T(q)^-1 = T'(q_6, ..., q_1) (:func:`reversed_description`), every
    solution of the reversed chain for T^-1, its joints read backwards, is one of the chain
    for T, and the reversed closed form is complete, so is this one (solve/analytic.py)."""

    kind: ClassVar[str] = "reversed"
    position_only_ok: ClassVar[bool] = False

    axes: JointAxes  # the chain's own axes (its limits, its name)
    inner: Any  # the reversed chain's structure (SphericalWrist6R, ParallelTriple6R, ...)
    description: SerialDescription  # the reversed chain (reversed_description)

    @property
    def configs(self) -> tuple:
        """The branch names of the reversed chain's closed form."""
        return tuple(self.inner.configs)


@dataclass(frozen=True, eq=False, repr=False)
class GantryArm(_Structure):
    """Three prismatic joints (directions w1, w2, w3 linearly independent) followed by 3, 2
    or 1 revolute joints 4..n (n = 6, 5, 4): a gantry robot.

    T(q) = Trans(q1 w1 + q2 w2 + q3 w3) exp(xi_4 q4) ... exp(xi_n q_n) T(0) (module
    docstring): the rotation R(q) = Rot(w4, q4) ... Rot(w_n, q_n) R(0) is the wrist's alone,
    and the tool point p(q) = q1 w1 + q2 w2 + q3 w3 + g(q4, ..., q_n), g the tool point at
    q = 0 turned by the wrist, so (q1, q2, q3) = ``slide_inverse`` (p - g). What is solved:

    * ``gantry_wrist_3r`` (6 axes): the whole pose; the wrist rotation R_t R(0)^T is split
      into q4, q5, q6 as the central wrist's (Paden-Kahan subproblem 2 and 1; branches
      ``noflip`` / ``flip``);
    * ``gantry_head_2r`` (5 axes: an A/C or B/C head): the tool point and the tool z axis
      (``carried``, the tool frame's z axis at q = 0): Rot(w4, q4) Rot(w5, q5) z(0) = z_t by
      subproblem 2 (``noflip`` / ``flip``); the rotation about the tool axis is not the
      head's to choose and is not checked;
    * ``gantry_rotary_1r`` (4 axes: the palletiser): the tool point and the angle about w4
      (``single``); a target tilted away from Rot(w4, .) R(0) is not reachable.
    """

    kind: str  # gantry_wrist_3r, gantry_head_2r or gantry_rotary_1r
    configs: tuple  # branch names
    axes: JointAxes
    slide_inverse: np.ndarray  # (3, 3) [w1 w2 w3]^-1: slide travel from a displacement
    carried: np.ndarray  # (3,) the vector the last wrist joint turns: w6 (3R), z(0) (2R), ref (1R)
    wrist_ref: np.ndarray  # (3,) unit vector normal to the last axis: its angle's reference
    cos_45: float  # w4 . w5 (0 for the 1R)
    cos_56: float  # w5 . carried (0 for the 1R)
    normal_45: np.ndarray  # (3,) w4 x w5 (zeros for the 1R)
    full_pose: bool  # the closed form reaches the whole rotation (False: the tool axis only)
    position_only_ok: ClassVar[bool] = True


Structure = (
    PlanarArm
    | Elbow4R
    | SphericalWrist6R
    | ParallelTriple6R
    | StanfordArm
    | ReversedChain
    | GantryArm
)


# ------------------------------------------------------------------------- detection


def _clearly_skew(a: Any, b: Any) -> bool:
    return geo.not_parallel(a, b, NONPARALLEL_TOL)


def detect_planar(ax: JointAxes) -> PlanarArm | None:
    """A :class:`PlanarArm` when the axes have that structure, else None."""
    rev = np.flatnonzero(ax.revolute)
    pri = np.flatnonzero(~ax.revolute)
    if len(rev) not in (2, 3) or len(pri) > 1:
        return None
    w, o = ax.directions, ax.points
    u = w[rev[0]]
    if not all(geo.parallel(w[i], u, PARALLEL_TOL) for i in range(ax.n)):
        return None
    tol = LENGTH_TOL * ax.scale
    ia, ib = int(rev[0]), int(rev[1])
    if geo.line_distance(o[ia], u, o[ib], u) < tol:
        return None
    ic = int(rev[2]) if len(rev) == 3 else None
    e1 = o[ib] - o[ia]
    e1 = geo.unit(e1 - (e1 @ u) * u)
    E = np.stack([e1, np.cross(u, e1)])
    A, B = E @ o[ia], E @ o[ib]
    if ic is None:
        P = ax.p0.copy()
        position_only_ok = True
    else:
        P = geo.foot(ax.p0, o[ic], u)
        position_only_ok = bool(np.linalg.norm(ax.p0 - P) < tol)
    vv = E @ P - B
    if np.hypot(*vv) < tol:
        return None
    return PlanarArm(
        axes=ax,
        u=_frozen(u),
        signs=_frozen(np.sign(w @ u)),
        first=ia,
        second=ib,
        roll=ic,
        lift=int(pri[0]) if len(pri) else None,
        plane=_frozen(E),
        first_xy=_frozen(A),
        second_xy=_frozen(B),
        point=_frozen(P),
        upper=_frozen(B - A),
        lower=_frozen(vv),
        position_only_ok=position_only_ok,
    )


def _central_wrist(w: np.ndarray, ex: Any, ey: Any) -> dict[str, Any]:
    """The fields of :class:`_CentralWrist` from the joint directions ``w`` (n, 3) of a
    six-axis arm; q6's reference is normal to w6, w6 x ex or w6 x ey (_reference_normal)."""
    return dict(
        wrist_ref=_frozen(_reference_normal(w[5], ex, ey)),
        cos_45=float(w[3] @ w[4]),
        cos_56=float(w[4] @ w[5]),
        normal_45=_frozen(np.cross(w[3], w[4])),
    )


def _reference_normal(w: Any, ex: Any, ey: Any) -> np.ndarray:
    """A unit vector normal to w: w x ex, or w x ey where w is nearly along ex."""
    return geo.unit(np.cross(w, ex if np.linalg.norm(np.cross(w, ex)) > 0.1 else ey))


def detect_elbow(ax: JointAxes) -> Elbow4R | SphericalWrist6R | None:
    """An :class:`Elbow4R` or a :class:`SphericalWrist6R` when the axes have that structure,
    else None."""
    n = ax.n
    if n not in (4, 6) or not ax.revolute.all():
        return None
    w, o = ax.directions, ax.points
    tol = LENGTH_TOL * ax.scale
    if not _clearly_skew(w[0], w[1]):
        return None
    if not geo.parallel(w[1], w[2], PARALLEL_TOL):
        return None
    if geo.line_distance(o[1], w[1], o[2], w[2]) < tol:
        return None
    if n == 6:
        if not (_clearly_skew(w[3], w[4]) and _clearly_skew(w[4], w[5])):
            return None
        W, dist = geo.common_point(o[3:6], w[3:6])
        if dist > tol:
            return None
        position_only_ok = True
    else:
        if not _clearly_skew(w[3], w[1]):
            return None
        W = geo.foot(ax.p0, o[3], w[3])
        position_only_ok = bool(np.linalg.norm(ax.p0 - W) < tol)
    ez = w[0]
    ey = geo.unit(w[1] - (w[1] @ ez) * ez)
    ex = np.cross(ey, ez)
    if ex @ (W - o[0]) < 0:
        ex, ey = -ex, -ey
    et = np.cross(w[1], ex)
    P2 = np.stack([ex, et])
    S, E, Wp = P2 @ o[1], P2 @ o[2], P2 @ W
    uu, vv = E - S, Wp - E
    if np.hypot(*uu) < tol or np.hypot(*vv) < tol:
        return None
    up_sign = float(np.sign(w[0] @ et))
    front = np.array([b[0] for b in ARM_BRANCHES])
    bend = np.array([b[1] for b in ARM_BRANCHES]) * up_sign * front
    common: dict[str, Any] = dict(
        axes=ax,
        wrist=_frozen(W),
        ex=_frozen(ex),
        ey=_frozen(ey),
        ez=_frozen(ez),
        w2_offset=float(w[1] @ (W - o[0])),
        cos_12=float(w[1] @ ez),
        sin_12=float(w[1] @ ey),
        plane=_frozen(P2),
        shoulder_xy=_frozen(S),
        upper=_frozen(uu),
        lower=_frozen(vv),
        sign3=float(np.sign(w[2] @ w[1])),
        front=_frozen(front),
        bend=_frozen(bend),
        position_only_ok=position_only_ok,
    )
    if n == 6:
        return SphericalWrist6R(
            **common,
            **_central_wrist(w, ex, ey),
        )
    return Elbow4R(**common, roll_ref=_frozen(_reference_normal(w[3], ex, ey)))


def detect_parallel_triple(ax: JointAxes) -> ParallelTriple6R | None:
    """A :class:`ParallelTriple6R` when the axes have that structure, else None."""
    if ax.n != 6 or not ax.revolute.all():
        return None
    w, o = ax.directions, ax.points
    tol = LENGTH_TOL * ax.scale
    u = w[1]
    if not (geo.parallel(w[2], u, PARALLEL_TOL) and geo.parallel(w[3], u, PARALLEL_TOL)):
        return None
    if not (_clearly_skew(w[0], u) and _clearly_skew(w[4], u) and _clearly_skew(w[4], w[5])):
        return None
    if geo.line_distance(o[1], u, o[2], u) < tol or geo.line_distance(o[2], u, o[3], u) < tol:
        return None
    P5, dist = geo.common_point(o[4:6], w[4:6])
    if dist > tol:
        return None
    e1 = geo.unit((o[2] - o[1]) - ((o[2] - o[1]) @ u) * u)
    E = np.stack([e1, np.cross(u, e1)])
    return ParallelTriple6R(
        axes=ax,
        u=_frozen(u),
        signs=_frozen(np.sign(w[1:4] @ u)),
        wrist=_frozen(P5),
        plane=_frozen(E),
        upper=_frozen(E @ (o[2] - o[1])),
        lower=_frozen(E @ (o[3] - o[2])),
        ref=_frozen(e1),
    )


def detect_stanford(ax: JointAxes) -> StanfordArm | None:
    """A :class:`StanfordArm` when the axes have that structure, else None."""
    if ax.n != 6 or ax.revolute.tolist() != [True, True, False, True, True, True]:
        return None
    w, o = ax.directions, ax.points
    tol = LENGTH_TOL * ax.scale
    if not _clearly_skew(w[0], w[1]):
        return None
    c, dist = geo.common_point(o[0:2], w[0:2])
    if dist > tol:
        return None
    if not (_clearly_skew(w[3], w[4]) and _clearly_skew(w[4], w[5])):
        return None
    W, dist = geo.common_point(o[3:6], w[3:6])
    if dist > tol:
        return None
    ex = np.array([1.0, 0.0, 0.0])
    ey = np.array([0.0, 1.0, 0.0])
    return StanfordArm(
        axes=ax,
        shoulder=_frozen(c),
        wrist=_frozen(W),
        **_central_wrist(w, ex, ey),
    )


GANTRY_KINDS = {6: "gantry_wrist_3r", 5: "gantry_head_2r", 4: "gantry_rotary_1r"}


def detect_gantry(ax: JointAxes) -> GantryArm | None:
    """A :class:`GantryArm` when joints 1-3 are prismatic with clearly independent directions
    (|det [w1 w2 w3]| >= NONPARALLEL_TOL) and joints 4..n (n = 4, 5, 6) revolute, the wrist
    axes clearly skew where the closed form needs it (3R: 4 to 5 and 5 to 6; 2R: 4 to 5 and
    the tool z axis to 5), else None."""
    n = ax.n
    if n not in GANTRY_KINDS or ax.revolute[:3].any() or not ax.revolute[3:].all():
        return None
    w = ax.directions
    slides = w[:3].T  # columns w1, w2, w3
    if abs(float(np.linalg.det(slides))) < NONPARALLEL_TOL:
        return None
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    zero3 = np.zeros(3)
    configs: tuple[str, ...]
    if n == 6:
        if not (_clearly_skew(w[3], w[4]) and _clearly_skew(w[4], w[5])):
            return None
        carried, configs, full = w[5], ("noflip", "flip"), True
    elif n == 5:
        z0 = ax.R0[:, 2]
        if not (_clearly_skew(w[3], w[4]) and _clearly_skew(z0, w[4])):
            return None
        carried, configs, full = z0, ("noflip", "flip"), False
    else:
        carried, configs, full = zero3, ("single",), True
    last = w[5] if n == 6 else (carried if n == 5 else w[3])
    ref = _reference_normal(last, ex, ey)
    if n == 4:
        carried = ref
    return GantryArm(
        kind=GANTRY_KINDS[n],
        configs=configs,
        axes=ax,
        slide_inverse=_frozen(np.linalg.inv(slides)),
        carried=_frozen(carried),
        wrist_ref=_frozen(ref),
        cos_45=float(w[3] @ w[4]) if n > 4 else 0.0,
        cos_56=float(w[4] @ carried) if n > 4 else 0.0,
        normal_45=_frozen(np.cross(w[3], w[4]) if n > 4 else zero3),
        full_pose=full,
    )


def detect(desc: SerialDescription) -> Structure | None:
    """The structure of ``desc`` with a closed form (:class:`PlanarArm`, :class:`Elbow4R`,
    :class:`SphericalWrist6R`, :class:`ParallelTriple6R`, :class:`StanfordArm`,
    :class:`GantryArm`, :class:`ReversedChain`), or None (no supported structure, or a description whose
    product-of-exponentials model does not match its transforms)."""
    try:
        ax = joint_axes(desc)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):  # pragma: no cover
        return None
    if not ax.matches(desc):  # pragma: no cover - a convention the model misses
        return None
    for find in (
        detect_planar,
        detect_elbow,
        detect_parallel_triple,
        detect_stanford,
        detect_gantry,
    ):
        found = find(ax)
        if found is not None:
            return found
    return detect_reversed(ax, desc)


def detect_reversed(ax: JointAxes, desc: SerialDescription) -> ReversedChain | None:
    """A :class:`ReversedChain` when ``desc`` is a 6R chain whose reversed chain has a 6R
    closed form (detected like any arm), else None."""
    if ax.n != 6 or not ax.revolute.all():
        return None
    back = reversed_description(desc, ax)
    back_axes = joint_axes(back)
    if not back_axes.matches(back):  # pragma: no cover - the reversal is exact algebra
        return None
    for find in (detect_elbow, detect_parallel_triple):
        inner = find(back_axes)
        if inner is not None and inner.axes.n == 6:
            return ReversedChain(axes=ax, inner=inner, description=back)
    return None


def reversed_description(desc: SerialDescription, ax: JointAxes | None = None) -> SerialDescription:
    """The chain read backwards, T'(q_n, ..., q_1) = T(q)^-1, as universal coordinates.

    From the product of exponentials (module docstring),
    T(q)^-1 = T(0)^-1 exp(-xi_n q_n) ... exp(-xi_1 q_1) = exp(-xi'_n q_n) ... exp(-xi'_1 q_1)
    T(0)^-1 with xi' = Ad(T(0)^-1) xi: joint k of the reversed chain is joint n + 1 - k,
    its axis carried into the tool frame (point T(0)^-1 o, direction -R(0)^T w), its variable
    the same q, its limits the same; the zero pose is T(0)^-1. Each joint gets a frame F_k
    (origin on its axis, z along it), and D_k = Rot_z(q_k) C_k with C_k = F_k^-1 F_{k+1}
    (C_n = identity), base = F_1, tool = F_n^-1 T(0)^-1 (model/serial.py's universal form)."""
    from dataclasses import replace

    from deltagen.geometry.rotations import xyz_angles

    ax = joint_axes(desc) if ax is None else ax
    n = ax.n
    T0 = np.asarray(ax.T0, dtype=float)
    inv = np.eye(4)
    inv[:3, :3] = T0[:3, :3].T
    inv[:3, 3] = -T0[:3, :3].T @ T0[:3, 3]
    frames_k = []
    for k in range(n):
        i = n - 1 - k
        w = -(inv[:3, :3] @ ax.directions[i])
        o = inv[:3, :3] @ ax.points[i] + inv[:3, 3]
        helper = np.eye(3)[int(np.argmin(np.abs(w)))]
        x = geo.unit(np.cross(helper, w))
        F = np.eye(4)
        F[:3, :3] = np.column_stack([x, np.cross(w, x), w])
        F[:3, 3] = o
        frames_k.append(F)
    joints = []
    for k in range(n):
        C = np.linalg.solve(frames_k[k], frames_k[k + 1]) if k + 1 < n else np.eye(4)
        rx, ry, rz = xyz_angles(C[:3, :3])
        original = desc.joints[n - 1 - k]
        joints.append(
            replace(
                original,
                a=0.0,
                alpha=0.0,
                d=0.0,
                theta=0.0,
                offset=0.0,
                tx=float(C[0, 3]),
                ty=float(C[1, 3]),
                tz=float(C[2, 3]),
                rx=rx,
                ry=ry,
                rz=rz,
                axis="z",
                sign=1.0,
                qlim=None if not np.all(np.isfinite(ax.qlim[n - 1 - k])) else original.qlim,
                inertial=None,
            )
        )
    tool = np.asarray(np.linalg.solve(frames_k[-1], inv), dtype=np.float64)
    return SerialDescription(
        name=f"{desc.name}_reversed"[:64],
        convention="universal",
        joints=tuple(joints),
        base=frames_k[0],
        tool=tool,
        doc=f"{desc.name} read backwards: T'(q_n, ..., q_1) = T(q)^-1",
    )


# -------------------------------------------------------------- general predicates


def parallel_pairs(ax: JointAxes, tol: float = PARALLEL_TOL) -> list:
    """(i, j), 0-based i < j, of the joints whose axes are parallel (either sign)."""
    w = ax.directions
    return [
        (i, j) for i in range(ax.n) for j in range(i + 1, ax.n) if geo.parallel(w[i], w[j], tol)
    ]


def parallel_runs(ax: JointAxes, length: int = 3, tol: float = PARALLEL_TOL) -> list:
    """Indices i where the revolute joints i, ..., i + length - 1 have parallel axes (three
    consecutive parallel axes: the UR-type shoulder-elbow-wrist 1 group)."""
    w, rev = ax.directions, ax.revolute
    return [
        i
        for i in range(ax.n - length + 1)
        if rev[i : i + length].all()
        and all(geo.parallel(w[i], w[j], tol) for j in range(i + 1, i + length))
    ]


def common_point_of(ax: JointAxes, joints: Any, tol: float = LENGTH_TOL) -> Any:
    """The point [m] all axes of ``joints`` (0-based indices) pass through, within ``tol``
    times the arm's scale, or None. Two parallel axes have no single common point (None)."""
    joints = list(joints)
    w = ax.directions[joints]
    if all(geo.parallel(w[0], x, PARALLEL_TOL) for x in w[1:]):
        return None
    return geo.meet(ax.points[joints], w, tol * ax.scale)


def central_wrist(ax: JointAxes) -> Any:
    """The wrist centre [m] when the last three joints are revolute with axes through one
    point (4 not parallel to 5, 5 not parallel to 6), else None."""
    if ax.n < 3 or not ax.revolute[-3:].all():
        return None
    w = ax.directions
    if not (_clearly_skew(w[-3], w[-2]) and _clearly_skew(w[-2], w[-1])):
        return None
    return common_point_of(ax, range(ax.n - 3, ax.n))
