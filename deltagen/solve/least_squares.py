"""The one damped least-squares core of the Newton and Levenberg-Marquardt loops: the
numeric inverse kinematics (solve/numeric.py, the numpy engine), the delta calibration
(solve/calibration.py), the path follower (plan/following.py ``solve_ik``,
``newton_step``) and the nearest-arm polish (solve/nearest.py ``polish``). For a Jacobian
J (m, n), a residual r (m,) and a damping lambda^2 >= 0 the step

    dx = argmin |J dx - r|^2 + lambda^2 |dx|^2  =  V diag(f) U^T r,
    f_i = s_i / (s_i^2 + lambda^2) for s_i > rcond * s_1, else 0,

from the thin SVD J = U diag(s) V^T (Tikhonov's filter factors; Nocedal & Wright,
Numerical Optimization, 2nd ed., sec. 10.3, the Levenberg-Marquardt step through the SVD;
singular values below ``rcond`` of the largest are left out: the minimum-norm step leaves
directions the data cannot see alone). With lambda = 0 it is the pseudo-inverse's
minimum-norm least-squares step, and J^-1 r for a regular square J.

Through the SVD, not the normal equations J^T (J J^T + lambda^2 I)^-1 r: the same step in
exact arithmetic, but the normal equations square J's condition number.

The loops keep their own damping schedules, acceptance tests and stopping rules (a
batched non-monotone search with restarts, a bounded projected fit, Newton with retries);
the schedule's scale is an option here (``lambda2``: lambda^2 = damping times 1, s_1^2 or
the mean eigenvalue of J J^T), so the same option means the same step in every loop.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

#: what a damping factor multiplies to give lambda^2: nothing ("absolute"), the largest
#: singular value squared ("largest"), or the mean eigenvalue of J J^T, trace(J J^T) / m
#: ("mean")
Scale = Literal["absolute", "largest", "mean"]
SCALES: tuple[Scale, ...] = ("absolute", "largest", "mean")


def kept(s: np.ndarray, rcond: float) -> np.ndarray:
    """The singular values (..., r) (descending, as numpy.linalg.svd returns them) the step
    uses: those above ``rcond`` times the largest of their row (none when it is 0)."""
    return s > rcond * s[..., :1]


def lambda2(s: np.ndarray, damping: float | np.ndarray, scale: Scale, m: int) -> np.ndarray:
    """lambda^2 of a damping factor on the singular values s (..., r) of a Jacobian with m
    rows, by ``scale`` (SCALES): damping, damping s_1^2 or damping sum(s_i^2) / m."""
    damping = np.asarray(damping, dtype=float)
    if scale == "absolute":
        return damping
    if scale == "largest":
        return damping * s[..., 0] ** 2
    if scale == "mean":
        return damping * (np.sum(s * s, axis=-1) / m)
    raise ValueError(f"scale must be one of {SCALES}, got {scale!r}")


def damped_step(
    U: np.ndarray,
    s: np.ndarray,
    Vt: np.ndarray,
    r: np.ndarray,
    lam2: float | np.ndarray,
    keep: np.ndarray,
) -> np.ndarray:
    """dx = V diag(f) U^T r with f = s / (s^2 + lam2) on ``keep`` and 0 elsewhere (module
    doc), from an SVD the caller made (a loop that retries several dampings on one
    Jacobian decomposes it once). Batched: U (k, m, p), s and keep (k, p), Vt (k, p, n),
    r (k, m), lam2 (k,) -> (k, n); single: U (m, p), s and keep (p,), Vt (p, n), r (m,),
    lam2 a scalar -> (n,) (contracted by matrix products, as a single fit has always been)."""
    lam2 = np.asarray(lam2, dtype=float)
    f = np.where(keep, s / np.where(keep, s * s + lam2[..., None], 1.0), 0.0)
    if np.ndim(r) == 1:
        return Vt.T @ (f * (U.T @ r))
    return np.einsum("kri,kr->ki", Vt, f * np.einsum("kmr,km->kr", U, r))


def solve(
    J: np.ndarray,
    r: np.ndarray,
    damping: float | np.ndarray = 0.0,
    *,
    scale: Scale = "absolute",
    rcond: float | None = None,
    lu: bool = True,
) -> np.ndarray:
    """The damped least-squares step dx of J (m, n) or (k, m, n) and r (m,) or (k, m)
    (module doc), lambda^2 = lambda2(s, damping, scale, m). ``rcond``: the singular values
    left out (None: machine epsilon times max(m, n), numpy.linalg.lstsq's default).
    ``lu``: an undamped square J is solved by LU (one factorisation, the usual Newton step),
    and through the SVD only when LU finds it exactly singular (then every row of a batch:
    the minimum-norm step)."""
    J = np.asarray(J, dtype=float)
    r = np.asarray(r, dtype=float)
    m, n = J.shape[-2:]
    if lu and m == n and not np.any(damping):
        try:
            return np.linalg.solve(J, r[..., None])[..., 0]
        except np.linalg.LinAlgError:  # an exactly singular J: the pseudo-inverse below
            pass
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    keep = kept(s, np.finfo(float).eps * max(m, n) if rcond is None else rcond)
    return damped_step(U, s, Vt, r, lambda2(s, damping, scale, m), keep)
