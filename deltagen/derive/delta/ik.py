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
rho_sq = sp.symbols("rho_sq1:4", real=True)  # E^2 + F^2
disc = sp.symbols("disc1:4", real=True)  # rho^2 - G^2
# the part of G_i free of p, r_i^2 + l_a,i^2 - l_b,i^2
G0 = sp.symbols("G0_1:4", real=True)
_MONOMIALS = {(1, 0, 0): "x", (0, 1, 0): "y", (0, 0, 1): "z"}


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


def _split(i: int):
    """E_i, F_i, G_i as polynomials in p whose coefficients free of p are named: (the
    three polynomials in those names, setup pairs name -> coefficient). A coefficient
    that is a number (the 1 of x^2 in G_i) stays in the polynomial."""
    polys, pairs = [], []
    for letter, expr in zip("EFG", crank_equation(i)):
        poly = sp.Poly(sp.expand(expr), s.x, s.y, s.z)
        assert poly.total_degree() <= 2
        terms = []
        for monomial, coeff in poly.as_dict().items():
            power = sp.Mul(*(v**k for v, k in zip((s.x, s.y, s.z), monomial)))
            if coeff.is_Number:
                terms.append(coeff * power)
                continue
            name = G0[i] if (letter, monomial) == ("G", (0, 0, 0)) else None
            if name is None:
                tag = _MONOMIALS.get(monomial, "0")
                name = sp.Symbol(f"{letter}{tag}_{i + 1}", real=True)
            pairs.append((name, coeff))
            terms.append(name * power)
        polys.append(sp.Add(*terms))
    return polys, pairs


def crank_constants() -> tuple:
    """Setup pairs: the coefficients of E_i, F_i, G_i as polynomials in the platform
    position p (r_i, l_a,i, l_b,i and theta_i only), each a constant of the robot
    evaluated once per call instead of at every point (per-chain geometry costs nothing
    per point then)."""
    return tuple(pair for i in range(3) for pair in _split(i)[1])


def ik_stages():
    coeffs, discs, angles = [], [], []
    for i in range(3):
        (Ei, Fi, Gi), _ = _split(i)
        coeffs += [(E[i], Ei), (F[i], Fi), (G[i], Gi)]
        discs += [(rho_sq[i], E[i] ** 2 + F[i] ** 2), (disc[i], rho_sq[i] - G[i] ** 2)]
        root = sp.sqrt(disc[i])
        angles.append((s.q[i], sp.atan2(-F[i] * G[i] + E[i] * root, -E[i] * G[i] - F[i] * root)))
    return [
        Stage("crank equation E cos q + F sin q + G = 0 from eq. (1), per chain", tuple(coeffs)),
        Stage(
            "rho^2 = E^2 + F^2 and the discriminant rho^2 - G^2 (< 0: unreachable, ~0: J_q "
            "singular)",
            tuple(discs),
        ),
        Stage(
            "elbow-out crank angles atan2(F) + atan2(sqrt(disc), -G) as one atan2", tuple(angles)
        ),
    ]
