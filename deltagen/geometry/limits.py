"""Joint values and their limits: the 2 pi fit of revolute joints, one copy.

Two rules, each used where its callers need it:

:func:`fit_limits` -- the closed-form solvers' rule (an angle computed by atan2 has no
    preferred turn): a revolute value is wrapped into [-pi, pi) and then shifted by
    ``SHIFTS`` (+2 pi, -2 pi, +4 pi, -4 pi, the first that fits) into its limits where that
    fits; otherwise it stays in [-pi, pi) and is reported outside. A prismatic value is only
    checked. A value within ``LIMIT_TOL`` outside a limit counts as inside and is clipped onto
    it. Used by :mod:`deltagen.solve.analytic`, :mod:`deltagen.solve.combined`; the C kernel
    ``ik_all`` (:mod:`deltagen.derive.serial.ik_closed_form`) writes the same steps in SymPy
    with these constants, so the numpy and C results agree to the bit.

:func:`shift_into_limits` -- the numerical solver's rule (a Newton iterate is near its start
    and must not jump by a turn when it is already inside): a revolute value *outside* its
    finite limits is shifted by the smallest multiple of 2 pi that reaches the range, where
    one exists; values inside, and values no shift brings in, are left as they are. Used by
    :mod:`deltagen.solve.numeric`; the C Newton engine (codegen/templates/ik_newton.c.j2,
    ``_ikn_wrap``) is the same rule in C.

:func:`wrap_to_pi` -- an angle (or an angle difference) into [-pi, pi).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["TWO_PI", "LIMIT_TOL", "SHIFTS", "wrap_to_pi", "fit_limits", "shift_into_limits"]

TWO_PI = 2.0 * math.pi
# [rad or m] a value this close outside a limit is clipped onto it: above the closed forms'
# rounding near a singular pose (a Puma pose with q4 exactly at its limit came back 1.04e-12
# below it and lost its branch), far below any joint's travel
LIMIT_TOL = 1e-10
SHIFTS = (1, -1, 2, -2)  # multiples of 2 pi tried by fit_limits, in this order


def wrap_to_pi(x):
    """x (rad, any shape) wrapped into [-pi, pi): ``mod(x + pi, 2 pi) - pi``."""
    return np.mod(x + math.pi, TWO_PI) - math.pi


def fit_limits(q, qlim, revolute):
    """The closed-form solvers' fit (module docstring) of q (..., n) into the limits qlim
    (n, 2) (+-inf where a joint has none); ``revolute`` (n,) bools.
    Returns (q fitted (a copy), inside (...,): every joint within its limits)."""
    q = np.array(q, dtype=float, copy=True)
    inside = np.ones(q.shape[:-1], dtype=bool)
    for i in range(q.shape[-1]):
        lo, hi = qlim[i]
        x = q[..., i]
        if revolute[i]:
            x = wrap_to_pi(x)
            fits = (x >= lo - LIMIT_TOL) & (x <= hi + LIMIT_TOL)
            for k in SHIFTS:
                y = x + k * TWO_PI
                fy = (y >= lo - LIMIT_TOL) & (y <= hi + LIMIT_TOL) & ~fits
                x = np.where(fy, y, x)
                fits |= fy
        else:
            fits = (x >= lo - LIMIT_TOL) & (x <= hi + LIMIT_TOL)
        q[..., i] = np.where(fits, np.clip(x, lo, hi), x)
        inside &= fits
    return q, inside


def shift_into_limits(q, lo, hi, wraps):
    """The numerical solver's rule (module docstring): q (..., n) with every joint i where
    ``wraps[i]`` (revolute with finite limits lo[i], hi[i]) that lies outside [lo, hi]
    shifted by the smallest multiple of 2 pi that brings it in, where one does."""
    below, above = q < lo, q > hi
    if not (below.any() or above.any()):
        return q
    k = np.where(below, np.ceil((lo - q) / TWO_PI), 0.0)
    k = np.where(above, -np.ceil((q - hi) / TWO_PI), k)
    q2 = q + TWO_PI * k
    use = (below | above) & wraps & (q2 >= lo) & (q2 <= hi)
    return np.where(use, q2, q)
