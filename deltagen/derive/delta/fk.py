"""Direct kinematics at position level: the intersection of three spheres, eqs. (2)-(27).

Two derivations live here:

* :func:`report_elimination` follows the report literally (u, v of eqs. (6)-(15), the
  elimination (16)-(21) and the quadratic (22)-(25)); tests compare it with the printed
  equations. Its eqs. (20)/(21) divide by v_2, which vanishes for some drive arrangements.
* :func:`fk_stages` is what the C core evaluates: the same sphere subtraction, but in
  coordinates centred on S_1, with the two planes and their line solved as a 3x3 system
  by adjugate/determinant (Cramer). The only divisor is |e|^2, e = (S_2-S_1) x (S_3-S_1),
  which vanishes only when the three sphere centres are collinear - a genuine singularity.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.functions import CopySign
from deltagen.derive.kernel import Stage


def spheres(px=s.x, py=s.y, pz=s.z, centres=None, radii=(s.l_b, s.l_b, s.l_b)):
    """varsigma_i of eq. (2) about the centres S_i (symbols S_x_i... if not given), radius
    l_b (the report's equal rods) or the given per-chain radii."""
    if centres is None:
        centres = [sp.Matrix(sp.symbols(f"S_x{i} S_y{i} S_z{i}", real=True)) for i in (1, 2, 3)]
    return [
        (px - c[0]) ** 2 + (py - c[1]) ** 2 + (pz - c[2]) ** 2 - rad**2
        for c, rad in zip(centres, radii)
    ], centres


def report_linear_coefficients():
    """u_1..u_4 and v_1..v_4 of eqs. (6)-(15), read off varsigma_1 - varsigma_2 and
    varsigma_1 - varsigma_3 with SymPy."""
    sig, centres = spheres()
    out = []
    for other in (1, 2):
        plane = sp.Poly(sp.expand(sig[0] - sig[other]), s.x, s.y, s.z)
        out.append(
            (
                plane.coeff_monomial(s.x),
                plane.coeff_monomial(s.y),
                plane.coeff_monomial(s.z),
                plane.coeff_monomial(1),
            )
        )
    return out[0], out[1], centres


def report_elimination():
    """w_1..w_7 of eqs. (16)-(25) as SymPy derives them from the planes (6), (7) and the
    sphere varsigma_3, in terms of symbols u_k, v_k and S_k3."""
    u = sp.symbols("u1:5", real=True)
    v = sp.symbols("v1:5", real=True)
    sol = sp.solve(
        [u[0] * s.x + u[1] * s.y + u[2] * s.z + u[3], v[0] * s.x + v[1] * s.y + v[2] * s.z + v[3]],
        [s.x, s.y],
        dict=True,
    )[0]
    xs, ys = sp.expand(sol[s.x]), sp.expand(sol[s.y])
    w1, w2 = sp.factor(xs.coeff(s.z, 1)), sp.factor(xs.coeff(s.z, 0))
    w3, w4 = sp.factor(ys.coeff(s.z, 1)), sp.factor(ys.coeff(s.z, 0))
    ws = sp.symbols("w1:5", real=True)
    sig, centres = spheres()
    quad = sp.Poly(
        sp.expand(sig[2].subs({s.x: ws[0] * s.z + ws[1], s.y: ws[2] * s.z + ws[3]})), s.z
    )
    w5, w6, w7 = (quad.coeff_monomial(s.z**k) for k in (2, 1, 0))
    return dict(u=u, v=v, w=ws, S3=centres[2], w1=w1, w2=w2, w3=w3, w4=w4, w5=w5, w6=w6, w7=w7)


# Symbols of the staged derivation (names become C identifiers).
S = [sp.Matrix(sp.symbols(f"S_x{i} S_y{i} S_z{i}", real=True)) for i in (1, 2, 3)]
a = sp.Matrix(sp.symbols("a_x a_y a_z", real=True))  # S_2 - S_1
b = sp.Matrix(sp.symbols("b_x b_y b_z", real=True))  # S_3 - S_1
e = sp.Matrix(sp.symbols("e_x e_y e_z", real=True))  # a x b, direction of the planes' line
x0 = sp.Matrix(sp.symbols("x0_x x0_y x0_z", real=True))  # foot point of the line, from S_1
xi = sp.Matrix(sp.symbols("xi_x xi_y xi_z", real=True))  # p - S_1: rod 1 (row 1 of J_p / 2)
e_sq, inv_e_sq, h_sq, lam = sp.symbols("e_sq inv_e_sq h_sq lambda_", real=True)
det_D = sp.Symbol("det_D", real=True)  # det of the rows p - S_i (= det J_p / 8)
# l_a,i cos q_i: crank i's reach along its drive's radial direction (the centre's height,
# -l_a,i sin q_i, is S_z,i)
la_cos_q = sp.symbols("la_cos_q1:4", real=True)


def crank_stage() -> Stage:
    """l_a,i cos q_i named: the sphere centres' radius r_i + l_a,i cos q_i uses it, and so
    do the rate kernels' dS_i/dq_i and d^2S_i/dq_i^2 (derive/delta/velocity.py
    ``staged_centre_rates``): the product is evaluated once per point, as a C compiler
    without -ffast-math does not regroup (-D_i3 l_a,i) cos q_i into -D_i3 (l_a,i cos q_i)."""
    return Stage(
        "crank reach l_a,i cos q_i",
        tuple((la_cos_q[i], s.chain_l_a[i] * s.cos_q[i]) for i in range(3)),
    )


def staged_centre(i: int) -> sp.Matrix:
    """S_i of eqs. (3)-(5) (symbols.sphere_centre) with l_a,i cos q_i as its symbol."""
    centre = s.sphere_centre(i).subs(s.chain_l_a[i] * s.cos_q[i], la_cos_q[i])
    back = {la_cos_q[i]: s.chain_l_a[i] * s.cos_q[i]}
    assert sp.expand(centre.subs(back) - s.sphere_centre(i)) == sp.zeros(3, 1)
    assert s.cos_q[i] not in centre.free_symbols
    return centre


def _centred_planes(radii=s.chain_l_b):
    """Planes of eqs. (6), (7) in coordinates xi = p - S_1: subtracting sphere 1 from
    spheres 2, 3 leaves 2 a.xi = |a|^2 + l_b1^2 - l_b2^2 and 2 b.xi = |b|^2 + l_b1^2 - l_b3^2
    (derived, not asserted; the rod terms cancel for equal rods). ``radii``: the three
    spheres' radii (the rods l_b,i of the rotary delta; a linear delta's arms, a tripod's
    struts)."""
    sig, _ = spheres(*xi, centres=[sp.zeros(3, 1), a, b], radii=radii)
    planes = []
    for other in (1, 2):
        plane = sp.Poly(sp.expand(sig[0] - sig[other]), *xi)
        normal = sp.Matrix([plane.coeff_monomial(c) for c in xi])
        planes.append((normal, -plane.coeff_monomial(1)))
    return planes


def fk_stages():
    """Stages computing p = (x, y, z) from cos q_i, sin q_i; also e_sq, h_sq and det_D for
    the status. The lower of the two intersections is chosen (z points up, eq. (26)). The
    first two stages (:func:`crank_stage`, the centres S_i) are the crank geometry the
    inverse rates reuse (derive/delta/inverse_rates.py)."""
    centres = [staged_centre(i) for i in range(3)]
    return [
        crank_stage(),
        *intersection_stages(centres, s.chain_l_b, -1, "sphere centres S_i, eqs. (3)-(5)"),
    ]


def intersection_stages(centres, radii, side, centre_comment):
    """The intersection of three spheres (the delta report's method, eqs. (6)-(27), solved
    as described in the module docstring): one copy of the math for every machine whose
    direct kinematics is a trilateration (the rotary delta, the linear delta, the tripod).

    ``centres``: three 3-vectors (expressions) assigned to S_1..S_3 in the first stage,
    whose comment is ``centre_comment``; ``radii``: the three radii (expressions);
    ``side``: -1 for the intersection below the plane of the centres (lambda e_z < 0, eq.
    (26)'s minimum z), +1 for the one above, or a symbol holding +-1 (a run-time choice).
    Assigns S, a, b, e, e_sq, inv_e_sq, x0, h_sq, lambda_, xi, p = (x, y, z) and det_D
    (det of the rows p - S_i)."""
    centre_pairs = []
    for i in range(3):
        centre_pairs += list(zip(S[i], centres[i]))
    edges = list(zip(a, S[1] - S[0])) + list(zip(b, S[2] - S[0]))
    (n1, d1), (n2, d2) = _centred_planes(radii)
    # the radii's share of the planes' right-hand sides (l_b1^2 - l_b2^2, l_b1^2 - l_b3^2)
    # named on its own: it depends on the parameters only, so the compiler computes it once
    # per call instead of adding the radii's squares at every point
    radii_terms, sides = [], []
    for k, d in enumerate((d1, d2)):
        constant = sp.expand(d).subs({**dict.fromkeys(a, 0), **dict.fromkeys(b, 0)})
        if constant != 0:
            term = sp.Symbol(f"radii_term{k + 2}", real=True)
            radii_terms.append((term, constant))
            d = sp.expand(d - constant) + term
        sides.append(d)
    d1, d2 = sides
    cross = list(zip(e, a.cross(b))) + [(e_sq, e.dot(e))]
    reciprocal = [(inv_e_sq, 1 / e_sq)]  # one division, used twice
    # Rows: plane 1, plane 2, and e.xi = 0 (the foot point of the line nearest S_1).
    M = sp.Matrix.vstack(n1.T, n2.T, e.T)
    rhs = sp.Matrix([d1, d2, 0])
    # det M = 4 e.(a x b) = 4 |e|^2: Cramer's rule with the adjugate.
    det_M = sp.factor(M.det().subs({e[0]: a.cross(b)[0], e[1]: a.cross(b)[1], e[2]: a.cross(b)[2]}))
    assert sp.simplify(det_M - 4 * (a.cross(b)).dot(a.cross(b))) == 0
    foot = M.adjugate() * rhs * inv_e_sq / 4
    foot_point = radii_terms + list(zip(x0, foot)) + [(h_sq, radii[0] ** 2 - x0.dot(x0))]
    # xi = x0 + lambda e with |xi| = radius_1 and e.x0 = 0  =>  lambda^2 |e|^2 = h_sq.
    # side -1: the lower intersection, lambda * e_z < 0 (eq. (26) takes the minimum z).
    line = [(lam, side * CopySign(sp.sqrt(h_sq * inv_e_sq), e[2]))]
    # xi = p - S_1 is rod 1's vector C_1 - B_1; the rate kernels build J_p's rows from it
    rod = [(xi[k], x0[k] + lam * e[k]) for k in range(3)]
    position = rod + [(sym, S[0][k] + xi[k]) for k, sym in enumerate((s.x, s.y, s.z))]
    # det of rows (p - S_i) = xi.(a x b) = lambda |e|^2 (rows xi, xi - a, xi - b).
    det_rows = [(det_D, lam * e_sq)]
    return [
        Stage(centre_comment, tuple(centre_pairs)),
        Stage("edges a = S_2 - S_1, b = S_3 - S_1 of the centre triangle", tuple(edges)),
        Stage("e = a x b, normal of the centre plane; its squared length", tuple(cross)),
        Stage("1 / |e|^2 (|e| = 0 only for collinear centres)", tuple(reciprocal)),
        Stage(
            "foot point x0 of the planes' line, eqs. (6)-(7), by Cramer's rule", tuple(foot_point)
        ),
        Stage(
            "lower intersection with sphere 1, eqs. (22)-(26)"
            if side == -1
            else "chosen intersection with sphere 1 (side), eqs. (22)-(26)",
            tuple(line),
        ),
        Stage("platform position p, eq. (27)", tuple(position) + tuple(det_rows)),
    ]
