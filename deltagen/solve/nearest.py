"""Closed forms of 6R chains that are a closed-form structure only up to the rounding of their
file: the closed form of the *nearest exact arm*, each branch polished by Newton's method on
the true chain.

Why. A file that prints pi/2 as 1.5708 turns an axis by 3.7e-6 rad: iCub's legs (hip pitch,
roll and yaw meeting in the hip, knee and ankle pitch parallel by design) have their knee and
ankle pitch axes 3.7e-6 rad from parallel and the hip yaw axis 0.8 micrometres from the knee's.
The structure detection (model/structure.py, parallel at |w_i x w_j| <= 1e-9) rightly finds no
closed form, and the general 6R solver's elimination (solve/general6r.py) is singular for such
a nearly special arm, so ik_all had only a best effort (64 of 100 random poses).

Method (the standard one for a nearly special arm; the EASY-ROB paper's "combined explicit and
numerical method" is the same idea for a nearly central wrist, solve/combined.py):

1. :func:`nearest_exact` moves the joint axes by at most ``SNAP_SINE`` rad and ``SNAP_LENGTH``
   times the arm's size onto exact relations -- the three axes at either end of the chain
   that nearly meet through their least-squares common point, the two at either end that
   nearly meet likewise, axes nearly parallel (|w_i x w_j| < ``SNAP_SINE``) onto their mean
   direction, each turned about its own point (so a meeting point stays met) -- and keeps the
   zero pose T(0). The chain of the moved axes (model/structure.py ``reversed_description``
   read twice: the product of exponentials of the moved axes as universal coordinates) must
   then have a closed form (``detect``), else there is no nearest exact arm (None).
2. :class:`NearestSolver` solves that arm in closed form for the target (every branch; where
   the exact arm just misses the pose, the elbow's law of cosines is clipped onto the nearest
   real elbow, as solve/combined.py does), and polishes every branch by Newton's method on the
   true chain's product of exponentials (batched, :func:`polish`: the tool-point Jacobian,
   the rotation error as the vector part of R_t R^T). A branch is a solution when Newton
   converges to ``POLISH_TOL`` (position / arm size and rotation); AnalyticSolver then wraps
   it into the limits and checks its forward kinematics like any closed form.

Completeness. The exact arm is complete (its closed form), and its pose differs from the true
chain's by at most ``eps`` (``NearestArm.deviation``, the largest difference over sampled
configurations, position and rotation entries times the arm's size; 1.5e-5 for iCub's legs,
whose axes are turned by at most 3.7e-6 and 5.2e-6 rad). Let q* be any solution of the true
chain for T where the Jacobian's smallest singular value is sigma. The exact arm misses T at
q* by at most eps, so by the Newton-Kantorovich theorem it has a solution q_e within about
2 eps / sigma of q* when K eps / sigma^2 <= 1/2 (K: the Jacobian's Lipschitz constant, of the
order of the arm's size); the closed form returns q_e, and Newton on the true chain started
there converges to the one solution in that neighbourhood, q*. So every solution with sigma >=
sqrt(2 K eps) is found: for iCub's legs (K about 1 m, sigma_max 1.5 to 1.8) sigma >= 5.5e-3,
sigma_min / sigma_max >= about 4e-3. A solution nearer a singularity than that is not covered
by this argument (within about eps of the workspace's boundary the true chain may reach a pose
the exact arm just misses: the clipped elbow start then serves, as in solve/combined.py), and
two branches may converge to one solution there, as at any singularity. Between that margin
and the 1e-3 the completeness target asks for, the evidence is measured
(tests/solve/test_ik_completeness.py: the original q among the valid solutions on 1000 of 1000
random poses of each leg, and an independent numeric multi-start finds no solution that
ik_all misses). ik_all reports such a chain as complete, with this margin stated in the
README.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any, ClassVar, cast

import numpy as np

from deltagen.geometry import axes as geo
from deltagen.geometry.axes import NONPARALLEL_TOL
from deltagen.geometry.rotations import rot_exp
from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription
from deltagen.model.structure import JointAxes, detect, joint_axes, reversed_description
from deltagen.solve import least_squares
from deltagen.solve.analytic import AnalyticSolver, analytic_solver, solver_for

__all__ = [
    "SNAP_SINE",
    "SNAP_LENGTH",
    "POLISH_TOL",
    "NearestArm",
    "NearestSolver",
    "closed_form_solver",
    "nearest_exact",
    "polish",
]

SNAP_SINE = 1e-4  # axes this near parallel (sine of the angle) are made parallel
SNAP_LENGTH = 1e-4  # axes this near meeting (times the arm's size) are made to meet
POLISH_TOL = 1e-13  # Newton's convergence: position / arm size and rotation error norms
POLISH_STEPS = 12  # Newton steps at most
_SAMPLES = 256  # configurations over which the deviation of the exact arm is measured
_SEED = 20261203


@dataclass(frozen=True, eq=False, repr=False)
class NearestArm:
    """A chain (``axes``: its own joint axes), the nearest exact arm (``description``, its
    structure ``inner``), how far the axes were moved (``moved_angle`` [rad], ``moved_length``
    [m], largest over the axes) and ``deviation`` [m]: the largest difference of the two arms'
    tool poses (position, and rotation entries times the arm's size) over sampled
    configurations."""

    kind: ClassVar[str] = "nearest"
    position_only_ok: ClassVar[bool] = False

    axes: JointAxes
    inner: Any
    description: SerialDescription
    moved_angle: float
    moved_length: float
    deviation: float

    def __repr__(self):
        return f"NearestArm({self.axes.name!r}, {self.inner.kind}, deviation {self.deviation:.1e})"

    @property
    def configs(self) -> tuple:
        return tuple(self.inner.configs)

    @property
    def qlim(self) -> np.ndarray:
        return self.axes.qlim


def _snap_meeting(ax: JointAxes, o: np.ndarray, groups: Iterable[tuple[int, ...]]) -> None:
    """Move the points of each group of axes that nearly meet (pairwise clearly skew,
    within SNAP_LENGTH of the arm's size of their common point) onto that point."""
    w = ax.directions
    done: set = set()
    for group in groups:
        if done & set(group):
            continue
        if not all(
            geo.not_parallel(w[i], w[j], NONPARALLEL_TOL) for i in group for j in group if i < j
        ):
            continue
        x, dist = geo.common_point(o[list(group)], w[list(group)])
        if dist <= SNAP_LENGTH * ax.scale:
            for i in group:
                o[i] = x
            done |= set(group)


def _snap_parallel(w: np.ndarray) -> None:
    """Turn each cluster of nearly parallel axes (|w_i x w_j| < SNAP_SINE, either sign) onto
    its mean direction (each axis keeps its sign and its point)."""
    n = len(w)
    cluster = list(range(n))
    for i in range(n):
        for j in range(i + 1, n):
            if np.linalg.norm(np.cross(w[i], w[j])) < SNAP_SINE:
                a, b = cluster[i], cluster[j]
                cluster = [a if c == b else c for c in cluster]
    for c in set(cluster):
        members = [i for i in range(n) if cluster[i] == c]
        if len(members) < 2:
            continue
        signs = [1.0 if w[i] @ w[members[0]] > 0 else -1.0 for i in members]
        mean = geo.unit(sum(s * w[i] for s, i in zip(signs, members)))
        for s, i in zip(signs, members):
            w[i] = s * mean


def nearest_exact(desc: SerialDescription) -> NearestArm | None:
    """The nearest exact arm of a 6R chain without a closed form of its own (module
    docstring), or None (not 6R, a closed form of its own, nothing within the snap
    tolerances, or no closed form after snapping)."""
    if desc.n != 6 or not all(j.revolute for j in desc.joints) or detect(desc) is not None:
        return None
    ax = joint_axes(desc)
    if not ax.matches(desc):  # pragma: no cover - a convention the model misses
        return None
    o = np.array(ax.points, dtype=float)
    w = np.array(ax.directions, dtype=float)
    _snap_meeting(ax, o, ((0, 1, 2), (3, 4, 5), (0, 1), (4, 5)))
    _snap_parallel(w)
    moved_angle = float(np.max(np.linalg.norm(np.cross(w, ax.directions), axis=1)))
    shift = o - ax.points
    shift -= np.sum(shift * w, axis=1, keepdims=True) * w  # along the axis moves nothing
    moved_length = float(np.max(np.linalg.norm(shift, axis=1)))
    if moved_angle == 0.0 and moved_length == 0.0:
        return None
    moved = replace(ax, points=o, directions=w)
    back = reversed_description(desc, moved)  # the moved axes as universal coordinates ...
    exact = reversed_description(back)  # ... read forwards again
    exact = replace(
        exact,
        name=f"{desc.name}_exact"[:64],
        joints=tuple(replace(e, name=j.name) for e, j in zip(exact.joints, desc.joints)),
        doc=f"{desc.name} with its axes moved onto the nearest closed-form structure",
    )
    inner = detect(exact)
    if inner is None:
        return None
    q = np.random.default_rng(_SEED).uniform(-np.pi, np.pi, (_SAMPLES, 6))
    R1, p1 = ax.fk(q)
    R2, p2 = joint_axes(exact).fk(q)
    deviation = max(float(np.max(np.abs(p1 - p2))), float(np.max(np.abs(R1 - R2))) * ax.scale)
    return NearestArm(
        axes=ax,
        inner=inner,
        description=exact,
        moved_angle=moved_angle,
        moved_length=moved_length,
        deviation=deviation,
    )


def polish(
    ax: JointAxes,
    R_t: np.ndarray,
    p_t: np.ndarray,
    q0: np.ndarray,
    steps: int = POLISH_STEPS,
    tol: float = POLISH_TOL,
) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method on the product of exponentials of ``ax`` (revolute joints) for target
    rotations R_t (M, 3, 3) and points p_t (M, 3) from starts q0 (M, n): (q (M, n), converged
    (M,)). Each step solves J dq = e (J: the spatial Jacobian about the tool point, columns
    [w_i x (p - o_i); w_i] of the moved axes; e: the position error and the vector part of
    R_t R^T) by an LU solve, or by least squares when a row's J is singular; a row converges when both error norms are within ``tol``
    (position divided by the arm's size); rows without a finite start stay unconverged."""
    q = np.array(q0, dtype=float)
    M, n = q.shape
    start = np.all(np.isfinite(q), axis=1)
    q[~start] = 0.0
    converged = np.zeros(M, dtype=bool)
    active = start.copy()
    W0, O0 = ax.directions, ax.points
    for _ in range(steps + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        qa = q[idx]
        R, p = ax.fk(qa)
        E = R_t[idx] @ np.swapaxes(R, 1, 2)
        e_w = 0.5 * np.stack(
            [E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], axis=1
        )
        e_p = p_t[idx] - p
        err_p = np.linalg.norm(e_p, axis=1) / ax.scale
        err_w = np.linalg.norm(e_w, axis=1) + np.maximum(
            0.0, 1.0 - np.trace(E, axis1=1, axis2=2) / 3.0
        )
        done = (err_p <= tol) & (err_w <= tol)
        converged[idx[done]] = True
        active[idx[done]] = False
        keep = ~done
        if not keep.any():
            break
        idx, qa, p, e_p, e_w = idx[keep], qa[keep], p[keep], e_p[keep], e_w[keep]
        J = np.empty((idx.size, 6, n))
        # the axes at qa: carried by the joints before them, exp(xi_1 q_1) ... exp(xi_{i-1} q_{i-1})
        Racc = np.broadcast_to(np.eye(3), (idx.size, 3, 3)).copy()
        tacc = np.zeros((idx.size, 3))
        for i in range(n):
            wi = Racc @ W0[i]
            oi = np.einsum("mij,j->mi", Racc, O0[i]) + tacc
            J[:, :3, i] = np.cross(wi, p - oi)
            J[:, 3:, i] = wi
            Ri = rot_exp(np.multiply.outer(qa[:, i], W0[i]))  # about the unit axis W0[i]
            ti = O0[i] - Ri @ O0[i]
            tacc = np.einsum("mij,mj->mi", Racc, ti) + tacc
            Racc = Racc @ Ri
        e = np.concatenate([e_p, e_w], axis=1)
        # undamped: one batched LU solve (square and regular, the usual case), the
        # pseudo-inverse by SVD for the batch when a row's J is singular
        dq = least_squares.solve(J, e, rcond=1e-12)
        q[idx] = qa + dq
    q[~start] = np.nan
    return q, converged & start


class NearestSolver(AnalyticSolver):
    """ik_all of a chain through its nearest exact arm (module docstring): that arm's closed
    form, every branch polished by Newton on the true chain. Branch names are the exact
    arm's; ``exact`` is its solver, ``nearest`` the :class:`NearestArm`."""

    def __init__(self, nearest: NearestArm, description: SerialDescription | None = None):
        super().__init__(cast(Any, nearest), description)  # a structure-like record
        exact = solver_for(nearest.inner, nearest.description)
        assert exact is not None
        self.exact = exact
        self.nearest = nearest
        self.structure = f"nearest_{exact.structure}"

    def solve(self, T, *, position_only=False, limits=True, tol=1e-8, check=True):
        if position_only:
            raise InputError(
                f"{self.axes.name}: position_only does not apply to a 6R chain solved through "
                "its nearest exact arm"
            )
        return super().solve(T, limits=limits, tol=tol, check=check)

    def _solve(self, R_t, p_t, position_only):
        q0, _ = self.exact.closed_form(R_t, p_t)  # every branch, clipped where just missed
        N, k, n = q0.shape
        q, ok = polish(
            self.axes, np.repeat(R_t, k, axis=0), np.repeat(p_t, k, axis=0), q0.reshape(N * k, n)
        )
        q = q.reshape(N, k, n)
        ok = ok.reshape(N, k)
        q[~ok] = np.nan
        return q, ok


def closed_form_solver(desc: SerialDescription) -> AnalyticSolver | None:
    """The closed-form solver for ``desc``: its structure's own (solve/analytic.py), or for a
    6R chain that is one only up to the rounding of its file, the nearest exact arm's closed
    form polished by Newton on the chain; None when neither applies."""
    solver = analytic_solver(desc)
    if solver is None:
        nearest = nearest_exact(desc)
        if nearest is not None:
            return NearestSolver(nearest, desc)
    return solver
