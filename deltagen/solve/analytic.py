"""Closed-form (analytic) inverse kinematics of serial arms, all branches at once, batched.

``analytic_solver(desc)`` looks at a :class:`~deltagen.model.serial.SerialDescription`
and returns an :class:`AnalyticSolver` when the arm has one of the structures below, or
``None``. Nothing is keyed on robot names: the structure is read from the joint axes of the
description (any convention: standard DH, modified DH, universal coordinates; base and tool
transforms included), and the solution is written in terms of those axes.

Method (geometric, product of exponentials). The structure and every constant of the closed
form come from :func:`deltagen.model.structure.detect` (the joint axes at q = 0 -- unit
direction ``w_i`` and a point ``o_i`` in the world frame, composed from the description's own
transforms; the joint offsets are part of the q = 0 pose -- and the frames, plane vectors and
branch signs of each structure). The steps are the structure's recipe in
:mod:`deltagen.derive.serial.ik_recipes`, written once: run here on numpy arrays
(``_NumpyOps``) and by the C kernel emitter (:mod:`deltagen.derive.serial.ik_closed_form`)
as SymPy statements. Every arm satisfies

    T(q) = exp(xi_1 q_1) ... exp(xi_n q_n) T(0)

(a revolute joint turns about its axis by q_i, a prismatic one slides along it). Base and
tool transforms are inside T(0) and the world-frame axes, so they need no special case.
``G = T_target T(0)^-1`` is the motion the joints must produce. The structure is checked
numerically (parallel / intersecting axes to 1e-9 of the arm's size, the tolerances of
:mod:`deltagen.geometry.axes`) and the product-of-exponentials model is compared with the
description's composed forward kinematics at a few random configurations; any mismatch
gives ``None``. ``solver_for(detect(desc))`` builds the solver of a detected structure.

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

``gantry_wrist_3r`` / ``gantry_head_2r`` / ``gantry_rotary_1r`` -- gantry ("Portal") robots:
    three prismatic joints with independent directions (the Cartesian slides) and a 3R wrist,
    a 2R head (A/C, B/C) or one rotary axis (a palletiser); model/structure.py
    :class:`~deltagen.model.structure.GantryArm`. The slides turn nothing, so the wrist alone
    makes the rotation (the central wrist's subproblems for the 3R wrist, branches
    ``noflip`` / ``flip``; for the 2R head the tool z axis only, subproblem 2, the same two
    branch names; the angle about the rotary axis for the 1R, branch ``single``), and the
    slides then reach the tool point by a 3 x 3 linear solve. The 5-axis head's ``valid``
    checks the tool point and the tool z axis: the rotation about the tool axis is free.

``parallel_triple_6r`` -- the UR family: axes 2, 3, 4 parallel, axes 5 and 6 meeting
    (``ik_recipes.parallel_triple``: q1 and q5 from A cos x + B sin x = C, q6 and the sum
    phi of joints 2-4 by subproblem 1, the elbow by the law of cosines); eight branches
    ``shoulder{p|m}_elbow{p|m}_wrist{p|m}``.

``stanford_rrp_6`` -- R R P and a central wrist (``ik_recipes.stanford``: q3 from a
    quadratic, q1 and q2 by subproblem 2, the central wrist); eight branches
    ``reach{p|m}_shoulder{p|m}_{noflip|flip}``.

``reversed_spherical_wrist_6r`` / ``reversed_parallel_triple_6r`` -- a 6R chain whose first
    three axes meet (a humanoid's hip) or whose first two meet and axes 3, 4, 5 are parallel:
    read backwards (model/structure.py ``reversed_description``: T'(q_6, ..., q_1) = T(q)^-1)
    it is one of the structures above, solved for T^-1 (:class:`ReversedSolver`); its joints
    read backwards are the solutions for T, as many as the reversed closed form has (all of
    them). Branch names are those of the reversed chain, whose base is this chain's tool.

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
them fit (into [-pi, pi) otherwise; :func:`deltagen.geometry.limits.fit_limits`). ``valid`` =
a real solution exists, it is finite, it reproduces the target (forward kinematics within
``tol``: rotation entries and position / arm size) and it lies within the joint limits.
Branches without a real solution (target out of reach, or a pose the arm cannot take: a
4-DOF arm's target with the wrong tilt) are NaN; solutions that only violate joint limits
keep their values with ``valid`` False.
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

import functools
import math

import numpy as np

from deltagen.derive.serial.ik_recipes import RECIPES, SLACK, TINY, WRIST_SINGULAR, Angle
from deltagen.geometry.limits import fit_limits
from deltagen.inputs import InputError, as_float_array, check_real
from deltagen.model.serial import SerialDescription
from deltagen.model.structure import (
    GantryArm,
    ReversedChain,
    Structure,
    detect,
)

__all__ = ["AnalyticSolver", "ReversedSolver", "analytic_solver", "solver_for", "WRIST_SINGULAR"]

_CHUNK = 8192  # poses per pass (keeps the temporaries in cache)


# ------------------------------------------------------------------------ small helpers


def _cross(a, b) -> np.ndarray:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


# ----------------------------------------------------------------------- the solvers


class AnalyticSolver:
    """All closed-form inverse-kinematics branches of one arm (see the module docstring).

    Built from a detected structure (:mod:`deltagen.model.structure`). Attributes:
    ``description``, ``detected`` (the structure object: its joint axes and every constant
    of the closed form), ``structure`` (its name), ``configs`` (branch names, k of them),
    ``n`` (joints).
    """

    def __init__(self, detected: Structure, description: SerialDescription | None = None):
        self.detected = detected
        self.description = description
        self.axes = detected.axes
        self.n = detected.axes.n
        self.structure = detected.kind
        self.configs = tuple(detected.configs)

    def __repr__(self):
        return (
            f"AnalyticSolver({self.axes.name!r}, {self.structure}, "
            f"{len(self.configs)} configurations)"
        )

    # -- public ------------------------------------------------------------------------

    def solve(
        self,
        T,
        *,
        position_only: bool = False,
        limits: bool = True,
        tol: float = 1e-8,
        check: bool = True,
    ):
        """All branches for poses T (..., 4, 4) -> (q (..., k, n), valid (..., k)).

        ``tol``: accepted forward-kinematics residual (rotation entries; position divided by
        the arm's size, at least 1 m). ``limits=False`` ignores the joint limits in
        ``valid`` (angles are still wrapped into the ranges where possible).
        ``check=False`` skips the forward-kinematics verification (about 2/3 of the time
        for a 6R arm): ``valid`` then only says that the closed form had a real solution,
        which for a 6R arm and a rigid T means the pose is reached, but for the arms with
        fewer joints does not confirm the part of the pose they cannot choose.
        """
        T = as_float_array(T, "T", "(..., 4, 4)")
        if T.ndim < 2 or T.shape[-2:] != (4, 4):
            raise InputError(f"T must have shape (..., 4, 4), got {T.shape}")
        tol = check_real(tol, "tol", low=0.0, low_open=True)
        if position_only and not self.detected.position_only_ok:
            raise InputError(
                f"{self.axes.name}: position_only needs the tool point on the last "
                "joint axis (it would move with the last joint otherwise)"
            )
        lead = T.shape[:-2]
        Tf = T.reshape(-1, 4, 4)
        N, k, n = Tf.shape[0], len(self.configs), self.n
        q = np.empty((N, k, n))
        valid = np.empty((N, k), dtype=bool)
        for a in range(0, N, _CHUNK):
            b = min(N, a + _CHUNK)
            q[a:b], valid[a:b] = self._solve_chunk(
                Tf[a:b], bool(position_only), bool(limits), float(tol), bool(check)
            )
        return q.reshape(lead + (k, n)), valid.reshape(lead + (k,))

    def closed_form(self, R_t, p_t, position_only: bool = False):
        """The raw closed form for target rotations R_t (N, 3, 3) and points p_t (N, 3):
        (q (N, k, n), ok (N, k): a real solution exists). No wrapping, no limits, no
        forward-kinematics check; where the elbow's law of cosines has no real solution the
        angles are those of the nearest real elbow (ok False)."""
        return self._solve(R_t, p_t, position_only)

    def _solve_chunk(self, Tf, position_only, limits, tol, check):
        with np.errstate(all="ignore"):
            finite = np.all(np.isfinite(Tf), axis=(1, 2))
            Tc = np.where(finite[:, None, None], Tf, np.eye(4))
            q, ok = self._solve(Tc[:, :3, :3], Tc[:, :3, 3], position_only)
            ok = ok & finite[:, None]
            q, inside = fit_limits(q, self.axes.qlim, self.axes.revolute)
            ok &= np.all(np.isfinite(q), axis=-1)
            if check:
                ok &= self._reproduces(Tc, q, ok, position_only, tol)
            valid = ok & inside if limits else ok.copy()
            q[~ok] = np.nan
        return q, valid

    # -- shared steps --------------------------------------------------------------------

    def _fk_at_solutions(self, T, q, ok):
        """(good, idx, rows, R, err_p) for the forward-kinematics check of the branches
        ``ok`` marks: an all-False (N, k) result to fill, the flat indices of those branches,
        their pose rows, their tool rotations and their position errors relative to the arm's
        size."""
        N, k, n = q.shape
        good = np.zeros((N, k), dtype=bool)
        idx = np.flatnonzero(ok.reshape(-1))
        rows = idx // k
        if idx.size == 0:
            return good, idx, rows, np.zeros((0, 3, 3)), np.zeros(0)
        R, p = self.axes.fk(q.reshape(-1, n)[idx])
        err_p = np.max(np.abs(p - T[rows, :3, 3]), axis=-1) / self.axes.scale
        return good, idx, rows, R, err_p

    def _reproduces(self, T, q, ok, position_only, tol):
        good, idx, rows, R, err_p = self._fk_at_solutions(T, q, ok)
        if idx.size == 0:
            return good
        passed = err_p <= tol
        if not position_only:
            passed &= np.max(np.abs(R - T[rows, :3, :3]), axis=(1, 2)) <= tol
        good.reshape(-1)[idx] = passed
        return good

    def _goal(self, R_t, p_t):
        """The targets (N, 3, 3), (N, 3) as the joints must move the home pose (R0, p0, the
        tool pose at q = 0): the rotation R_G = R_t R0^T and the point p_G = p_t - R_G p0
        the chain's origin goes to (the product of exponentials, exp(...) = T_t T0^-1)."""
        R_G = R_t @ self.axes.R0.T
        return R_G, p_t - np.einsum("nij,j->ni", R_G, self.axes.p0)

    def _solve(self, R_t, p_t, position_only):  # pragma: no cover - abstract
        raise NotImplementedError


class _NumpyOps:
    """The numpy back end of the recipes (derive/serial/ik_recipes.py): a value is an array
    over the poses of a chunk (one per branch), names and stages are dropped, the
    structure's constants are used as they are."""

    true = True
    pi = math.pi
    slack = SLACK
    tiny = TINY
    sqrt = staticmethod(np.sqrt)
    number = staticmethod(float)
    atan2 = staticmethod(np.arctan2)
    abs = staticmethod(np.abs)
    fmax = staticmethod(np.fmax)
    select = staticmethod(np.where)
    ge, le, gt, lt = (
        staticmethod(f) for f in (np.greater_equal, np.less_equal, np.greater, np.less)
    )
    not_ = staticmethod(np.logical_not)

    def __init__(self, R_t, p_t):
        self.R_t = [[R_t[:, r, c] for c in range(3)] for r in range(3)]
        self.p_t = tuple(p_t[:, r] for r in range(3))

    @staticmethod
    def const(x):
        return float(x)

    @staticmethod
    def vconst(v):
        return tuple(float(x) for x in v)

    def stage(self, comment):
        pass

    @staticmethod
    def let(name, value):
        return value

    @staticmethod
    def vec(name, v):
        return tuple(v)

    @staticmethod
    def at_least(x, c):
        return np.where(x > c, x, c)

    @staticmethod
    def at_most(x, c):
        return np.where(x < c, x, c)

    @staticmethod
    def all(*conds):
        return functools.reduce(np.logical_and, conds)

    @staticmethod
    def rigid_target():
        return True  # the 2R head's rigidity is checked with its forward kinematics

    @staticmethod
    def wrist_flip(*constants):
        return False  # every wrist branch takes its own angles


class _RecipeSolver(AnalyticSolver):
    """A structure whose closed form is a recipe of derive/serial/ik_recipes.py (RECIPES),
    run on numpy arrays, one branch after another."""

    def _solve(self, R_t, p_t, position_only):
        N, k, n = R_t.shape[0], len(self.configs), self.n
        recipe = RECIPES[type(self.detected)]
        with np.errstate(all="ignore"):
            branches = recipe(_NumpyOps(R_t, p_t), self.detected, position_only)
        q = np.empty((N, k, n))
        ok = np.empty((N, k), dtype=bool)
        for j, name in enumerate(self.configs):
            branch = branches[name]
            for i, value in enumerate(branch.values):
                q[:, j, i] = value.theta if isinstance(value, Angle) else value
            ok[:, j] = branch.ok
            if branch.empty is not None:
                q[branch.empty, j] = np.nan
        return q, ok


class _GantrySolver(_RecipeSolver):
    """model.structure.GantryArm (the recipe ik_recipes.gantry). ``valid`` checks the whole
    pose for the 3R wrist and the 1R (a tilted target is not reachable by the palletiser),
    the tool point and the tool z axis for the 2R head."""

    def _reproduces(self, T, q, ok, position_only, tol):
        if self.detected.full_pose or position_only:
            return super()._reproduces(T, q, ok, position_only, tol)
        # the 2R head: the tool point and the tool z axis (the rotation about it is free)
        good, idx, rows, R, err_p = self._fk_at_solutions(T, q, ok)
        if idx.size == 0:
            return good
        err_z = np.max(np.abs(R[:, :, 2] - T[rows, :3, 2]), axis=-1)
        # the other columns are not compared: the target must still be a rotation
        # (orthonormal, right-handed), or a matrix that is none would pass
        Rt = T[rows, :3, :3]
        gram = np.max(np.abs(np.swapaxes(Rt, 1, 2) @ Rt - np.eye(3)), axis=(1, 2))
        hand = np.max(np.abs(_cross(Rt[:, :, 0], Rt[:, :, 1]) - Rt[:, :, 2]), axis=-1)
        good.reshape(-1)[idx] = (err_p <= tol) & (err_z <= tol) & (gram <= tol) & (hand <= tol)
        return good


class ReversedSolver(AnalyticSolver):
    """The closed form of a chain read backwards (``reversed_*`` structures; model/structure.py
    :class:`~deltagen.model.structure.ReversedChain`: the first three axes meet, as in a
    humanoid's hip): the reversed chain's solver for T^-1, its joints read backwards. Branch
    names are the reversed chain's (its base is this chain's tool). ``inner``: that solver;
    its forward-kinematics check is of the reversed chain, T'(q_6, ..., q_1) = T(q)^-1."""

    def __init__(self, detected: ReversedChain, description: SerialDescription | None = None):
        super().__init__(detected, description)
        inner = solver_for(detected.inner, detected.description)
        assert inner is not None
        self.inner = inner
        self.reversed_description = detected.description
        self.structure = f"reversed_{inner.structure}"

    def solve(self, T, *, position_only=False, limits=True, tol=1e-8, check=True):
        if position_only:
            raise InputError(
                f"{self.axes.name}: position_only does not apply to a 6R chain solved backwards"
            )
        T = as_float_array(T, "T", "(..., 4, 4)")
        if T.ndim < 2 or T.shape[-2:] != (4, 4):
            raise InputError(f"T must have shape (..., 4, 4), got {T.shape}")
        q, valid = self.inner.solve(invert(T), limits=limits, tol=tol, check=check)
        return np.ascontiguousarray(q[..., ::-1]), valid

    def closed_form(self, R_t, p_t, position_only: bool = False):
        R_b = np.swapaxes(R_t, -1, -2)
        p_b = -np.einsum("...ij,...j->...i", R_b, p_t)
        q, ok = self.inner.closed_form(R_b, p_b)
        return np.ascontiguousarray(q[..., ::-1]), ok


def invert(T):
    """T^-1 of homogeneous transforms (..., 4, 4) taken as rigid: [R^T, -R^T p] (a row that
    is not a rigid transform stays one that is not: its R^T is not orthonormal either)."""
    out = np.zeros_like(T)
    R = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = R
    with np.errstate(all="ignore"):
        out[..., :3, 3] = -np.einsum("...ij,...j->...i", R, T[..., :3, 3])
    out[..., 3, :3] = T[..., 3, :3]  # a bottom row that is not [0 0 0 1] stays so
    out[..., 3, 3] = T[..., 3, 3]
    return out


def solver_for(
    detected: Structure | None, description: SerialDescription | None = None
) -> AnalyticSolver | None:
    """The closed-form solver of a detected structure (None for None)."""
    if detected is None:
        return None
    if isinstance(detected, ReversedChain):
        return ReversedSolver(detected, description)
    if isinstance(detected, GantryArm):
        cls: type[AnalyticSolver] = _GantrySolver
    else:
        cls = _RecipeSolver
    return cls(detected, description)


def analytic_solver(desc: SerialDescription) -> AnalyticSolver | None:
    """The closed-form solver for ``desc``'s structure, or None when no supported structure
    applies (a 6R chain that is one only up to the rounding of its file:
    deltagen.solve.nearest.closed_form_solver)."""
    if not isinstance(desc, SerialDescription):
        raise InputError("analytic_solver needs a SerialDescription")
    return solver_for(detect(desc), desc)
