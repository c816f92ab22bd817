"""Lines in space (joint axes): the parallel test, the common point of several axes, the
distance of two axes, with the tolerances the structure detection uses. One copy, read by
the structure detection of :mod:`deltagen.model.structure` and by the singularity report of
:mod:`deltagen.solve.singularity`.

An axis is a point ``o`` [m] and a unit direction ``w``; its sign does not matter here.

Tolerances (the structure detection reads them; a caller may pass its own):

* ``PARALLEL_TOL`` -- two axes are parallel when ``|w_i x w_j| <= PARALLEL_TOL`` (the sine of
  the angle between them);
* ``NONPARALLEL_TOL`` -- they are clearly *not* parallel when ``|w_i x w_j| >=
  NONPARALLEL_TOL``. Between the two a structure that needs either answer is refused, so a
  nearly parallel pair is never taken for a crossing one (the closed forms divide by that
  sine);
* ``LENGTH_TOL`` -- lines meet (or coincide) when their distance is below ``LENGTH_TOL`` times
  the arm's size (a relative tolerance: the caller multiplies it by the size in metres).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "PARALLEL_TOL",
    "NONPARALLEL_TOL",
    "LENGTH_TOL",
    "unit",
    "parallel",
    "not_parallel",
    "line_distance",
    "foot",
    "common_point",
    "meet",
    "common_points",
]

PARALLEL_TOL = 1e-9  # |w_i x w_j| at or below this: parallel
NONPARALLEL_TOL = 1e-6  # |w_i x w_j| at or above this: not parallel
LENGTH_TOL = 1e-9  # distances: relative to the arm's size


def unit(v) -> np.ndarray:
    """v / |v| of a vector (3,) or of each row of (..., 3) (NaN rows for zero vectors)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def parallel(w1, w2, tol: float = PARALLEL_TOL) -> bool:
    """Unit directions w1, w2 parallel (either sign): ``|w1 x w2| <= tol``."""
    return bool(np.linalg.norm(np.cross(w1, w2)) <= tol)


def not_parallel(w1, w2, tol: float = NONPARALLEL_TOL) -> bool:
    """Unit directions w1, w2 clearly not parallel: ``|w1 x w2| >= tol``."""
    return bool(np.linalg.norm(np.cross(w1, w2)) >= tol)


def line_distance(o1, w1, o2, w2) -> float:
    """Distance [m] of the lines (o1, w1) and (o2, w2) (unit directions); for parallel lines
    (``|w1 x w2| < NONPARALLEL_TOL``) the distance of o2 from line 1."""
    n = np.cross(w1, w2)
    if np.linalg.norm(n) < NONPARALLEL_TOL:  # parallel: distance of o2 from line 1
        d = o2 - o1
        return float(np.linalg.norm(d - (d @ w1) * w1))
    return float(abs((o2 - o1) @ unit(n)))


def foot(p, o, w) -> np.ndarray:
    """The point of the line (o, w) nearest p."""
    return o + ((p - o) @ w) * w


def common_point(points, dirs):
    """Least-squares intersection of lines (o_k, w_k): (the point x, the largest distance [m]
    of a line from x). Minimises sum_k |(I - w_k w_k^T)(x - o_k)|^2."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for o, w in zip(points, dirs):
        P = np.eye(3) - np.outer(w, w)
        A += P
        b += P @ o
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    dist = max(
        float(np.linalg.norm((np.eye(3) - np.outer(w, w)) @ (x - o))) for o, w in zip(points, dirs)
    )
    return x, dist


def meet(points, dirs, tol: float):
    """The common point of the lines when all pass within ``tol`` [m] of it, else None."""
    x, dist = common_point(points, dirs)
    return x if dist <= tol else None


def common_points(o, w) -> np.ndarray:
    """Batched :func:`common_point` without the residual: o, w (N, k, 3) -> (N, 3), the
    least-squares common point of the k lines of each row (the k directions must not all be
    parallel)."""
    P = np.eye(3) - w[..., :, None] * w[..., None, :]  # (N, k, 3, 3)
    A = P.sum(axis=1)
    b = np.einsum("nkij,nkj->ni", P, o)
    return np.linalg.solve(A, b[..., None])[..., 0]
