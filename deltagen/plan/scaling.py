"""Time scaling of a trajectory segment: its path parameter as a function of time. The
plan modules build on each other in one direction: ``scaling`` <- ``cartesian`` <-
``following``.

* **Time scaling** ``s(tau)``, ``tau = (t - t_start) / T`` in [0, 1], maps the time of a
  segment onto its path parameter ``s`` in [0, 1]:

  - :class:`Quintic` (default): ``s = 10 tau^3 - 15 tau^4 + 6 tau^5``, the rest-to-rest
    polynomial with ``s' = s'' = 0`` at both ends. Velocity and acceleration are continuous
    (also across segments that stop at their joints); the jerk jumps at the segment ends.
    Peak ``ds/dtau = 15/8``, peak ``|d2s/dtau2| = 10/sqrt(3)``.
  - :class:`Trapezoid` (linear segment with parabolic blends, LSPB): constant acceleration
    for the blend fraction ``b`` of the time at each end, constant velocity
    ``1 / (1 - b)`` in between; ``b = 1/2`` is the triangular (bang-bang) profile. The
    velocity is continuous, the acceleration jumps at the four blend corners (so there a
    numerical first derivative is only O(h) and a second derivative O(1) wrong).

Units: the scalings are dimensionless (a segment divides by its duration in seconds).
"""

from __future__ import annotations

import numpy as np

from deltagen.inputs import InputError


class Quintic:
    """Rest-to-rest quintic ``s = 10 tau^3 - 15 tau^4 + 6 tau^5`` (s' = s'' = 0 at both ends)."""

    name = "quintic"

    def __call__(self, tau):
        tau = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
        t2 = tau * tau
        s = t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau))
        sd = 30.0 * t2 * (1.0 - tau) ** 2
        sdd = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)
        return s, sd, sdd

    def __repr__(self):
        return "Quintic()"


class Trapezoid:
    """Trapezoidal velocity (LSPB): blends of constant acceleration for the fraction ``blend``
    of the segment time at each end (0 < blend <= 1/2), constant velocity 1 / (1 - blend)
    in between (in units of the path parameter per segment time)."""

    name = "trapezoid"

    def __init__(self, blend: float = 0.25):
        blend = float(blend)
        if not (0.0 < blend <= 0.5):
            raise InputError(f"Trapezoid blend must be in (0, 0.5], got {blend}")
        self.blend = blend
        self.vmax = 1.0 / (1.0 - blend)
        self.amax = self.vmax / blend

    def __call__(self, tau):
        tau = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
        b, v, a = self.blend, self.vmax, self.amax
        rise, fall = tau < b, tau > 1.0 - b
        u = 1.0 - tau
        s = np.where(
            rise,
            0.5 * a * tau**2,
            np.where(fall, 1.0 - 0.5 * a * u**2, 0.5 * a * b**2 + v * (tau - b)),
        )
        sd = np.where(rise, a * tau, np.where(fall, a * u, v))
        sdd = np.where(rise, a, np.where(fall, -a, 0.0))
        return s, sd, sdd

    def __repr__(self):
        return f"Trapezoid(blend={self.blend:g})"


def _scaling(scaling):
    if scaling is None or scaling == "quintic":
        return Quintic()
    if scaling == "trapezoid":
        return Trapezoid()
    if callable(scaling):
        return scaling
    raise InputError(
        f"time scaling must be 'quintic', 'trapezoid' or a scaling object, got {scaling!r}"
    )
