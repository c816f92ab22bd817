"""Inverse kinematics (the report's "IKM"): the closed-form delta inverse per chain.

Constraint (1), expanded with cos^2 + sin^2 = 1, is linear in cos q_i and sin q_i:

    E_i cos q_i + F_i sin q_i + G_i = 0.

With rho^2 = E^2 + F^2 and E = rho cos(phi), F = rho sin(phi) this reads
rho cos(q - phi) = -G, so q = phi +- beta with beta = atan2(sqrt(rho^2 - G^2), -G). The +
sign is the elbow-out branch (the crank points away from the base axis, cos q > 0 near
home). The angle sum is evaluated with one atan2 (addition theorems, both angles have
radius rho): q = atan2(F (-G) + E s, E (-G) - F s), s = sqrt(rho^2 - G^2), which also
lands in (-pi, pi] without wrapping.
rho^2 - G^2 < 0: the sphere of the rod misses the crank circle (unreachable).
At the solution |J_q,ii| / 2 = sqrt(rho^2 - G^2) / 2 (J_q,ii = -dF/dq), so a double root
(rho^2 = G^2) is exactly the J_q singularity.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.kernel import Stage

E = sp.symbols("E1:4", real=True)
F = sp.symbols("F1:4", real=True)
G = sp.symbols("G1:4", real=True)
disc = sp.symbols("disc1:4", real=True)  # rho^2 - G^2
# the part of G_i free of p, r_i^2 + l_a,i^2 - l_b,i^2: a constant of the robot, summed once
# per call (SETUP) instead of term by term at every point
G0 = sp.symbols("G0_1:4", real=True)


def crank_equation(i: int):
    """(E_i, F_i, G_i) read off eq. (1) by SymPy."""
    f = s.constraint(i).subs({sp.cos(s.q[i]): s.cos_q[i], sp.sin(s.q[i]): s.sin_q[i]})
    f = s.on_unit_circle(f)
    poly = sp.Poly(f, s.cos_q[i], s.sin_q[i])
    assert poly.total_degree() == 1, "eq. (1) must be linear in cos q, sin q"
    Ei = sp.factor(poly.coeff_monomial(s.cos_q[i]))
    Fi = sp.factor(poly.coeff_monomial(s.sin_q[i]))
    Gi = poly.coeff_monomial(1)
    return Ei, Fi, Gi


def crank_constants() -> tuple:
    """Setup pairs (G0_i, the terms of G_i free of the platform position p)."""
    pairs = []
    for i in range(3):
        Gi = crank_equation(i)[2]
        pairs.append((G0[i], Gi.subs({s.x: 0, s.y: 0, s.z: 0})))
    return tuple(pairs)


def ik_stages():
    coeffs, discs, angles = [], [], []
    for (g0, constant), i in zip(crank_constants(), range(3)):
        Ei, Fi, Gi = crank_equation(i)
        Gi = sp.expand(Gi - constant) + g0
        coeffs += [(E[i], Ei), (F[i], Fi), (G[i], Gi)]
        discs.append((disc[i], E[i] ** 2 + F[i] ** 2 - G[i] ** 2))
        root = sp.sqrt(disc[i])
        angles.append((s.q[i], sp.atan2(-F[i] * G[i] + E[i] * root, -E[i] * G[i] - F[i] * root)))
    return [
        Stage("crank equation E cos q + F sin q + G = 0 from eq. (1), per chain", tuple(coeffs)),
        Stage("discriminant rho^2 - G^2 (< 0: unreachable, ~0: J_q singular)", tuple(discs)),
        Stage(
            "elbow-out crank angles atan2(F) + atan2(sqrt(disc), -G) as one atan2", tuple(angles)
        ),
    ]
