"""The damped least-squares step shared by the Levenberg-Marquardt loops of the numeric
inverse kinematics (solve/numeric.py, the numpy engine) and the delta calibration
(solve/calibration.py): from the thin SVD J = U diag(s) V^T of a Jacobian and a residual r,

    dx = V diag(f) U^T r,   f_i = s_i / (s_i^2 + lambda^2) for s_i > rcond * s_1, else 0

(Tikhonov's filter factors; Nocedal & Wright, Numerical Optimization, 2nd ed., sec. 10.3,
the Levenberg-Marquardt step through the SVD; singular values below ``rcond`` of the
largest are left out: the minimum-norm step leaves directions the data cannot see alone).
Each loop keeps its own damping schedule, acceptance test and stopping rules (they differ:
a batched non-monotone search with restarts against a bounded, projected fit), and its own
per-use residual.

The path follower's Newton steps (plan/trajectory.py ``_solve``) solve the same damped
problem by the normal equations J^T (J J^T + lambda^2 I)^-1 e: the same step in exact
arithmetic, other bits in floating point, so it is not folded here.
"""

from __future__ import annotations

import numpy as np


def kept(s: np.ndarray, rcond: float) -> np.ndarray:
    """The singular values (..., r) (descending, as numpy.linalg.svd returns them) the step
    uses: those above ``rcond`` times the largest of their row (none when it is 0)."""
    return s > rcond * s[..., :1]


def damped_step(
    U: np.ndarray,
    s: np.ndarray,
    Vt: np.ndarray,
    r: np.ndarray,
    lam2: float | np.ndarray,
    keep: np.ndarray,
) -> np.ndarray:
    """dx = V diag(f) U^T r with f = s / (s^2 + lam2) on ``keep`` and 0 elsewhere (module
    doc). Batched: U (k, m, p), s and keep (k, p), Vt (k, p, n), r (k, m), lam2 (k,) ->
    (k, n); single: U (m, p), s and keep (p,), Vt (p, n), r (m,), lam2 a scalar -> (n,)
    (contracted by matrix products, as a single fit has always been)."""
    lam2 = np.asarray(lam2, dtype=float)
    f = np.where(keep, s / np.where(keep, s * s + lam2[..., None], 1.0), 0.0)
    if np.ndim(r) == 1:
        return Vt.T @ (f * (U.T @ r))
    return np.einsum("kri,kr->ki", Vt, f * np.einsum("kmr,km->kr", U, r))
