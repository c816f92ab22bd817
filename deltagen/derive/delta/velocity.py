"""Velocity level, eqs. (28)-(35): differentiate the constraint (1) in time.

d f_i / dt is linear in pdot and qdot_i (eq. (28)); collecting the coefficients gives
J_p pdot = J_q qdot (eq. (30)) with the rows of J_p = 2 (p - S_i)^T (eqs. (31)-(33)) and
the diagonal J_q (eqs. (34), (35)). SymPy's result differs from the printed (28)/(34) in
the sign of the r term (docs/errata.md).

The C core divides both sides by 2 and solves with the adjugate of D (rows p - S_i):
pdot = adj(D) (J_q / 2) qdot / det D. The Jacobian is J = D^-1 J_q / 2 (pdot = J qdot).

Cost (one copy of the math, fewer operations): the direct kinematics already has the rod
vector xi = p - S_1 and the centre-triangle edges a, b with e = a x b (derive/delta/fk.py),
so the rows are xi, xi - a, xi - b, and adj(D)'s columns, the cross products of the rows
D_2 x D_3, D_3 x D_1, D_1 x D_2, are e - xi x b - a x xi, xi x b and a x xi (two cross
products; det D = lambda |e|^2 comes from the position stage). J_q,ii / 2 is
D_i . dS_i/dq_i (the rate of eq. (1) is 2 D_i . (pdot - dS_i/dq_i qdot_i)), evaluated
through rho_i, the rod's radial component, with dS_i/dq_i read off the position stage's
S_z,i and l_a,i cos q_i (:func:`staged_centre_rates`: two products per chain, not four).
Each identity is asserted symbolically where the stage is built.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.fk import S, a, b, det_D, e, la_cos_q, xi
from deltagen.derive.kernel import Stage


def time_functions():
    """x(t), y(t), z(t), q_i(t) and the substitution of their derivatives by symbols."""
    X, Y, Z, Q = (sp.Function(n)(s.t) for n in ("X", "Y", "Z", "Q"))
    return X, Y, Z, Q


def constraint_rate(i: int):
    """(J_p row i, J_q,ii) as coefficients of d f_i / dt, eq. (28), in terms of x, y, z,
    cos q_i, sin q_i. Derived by differentiating eq. (1), not copied from the report."""
    X, Y, Z, Q = time_functions()
    f = s.constraint(i, X, Y, Z, Q)
    df = sp.expand(sp.diff(f, s.t))
    rates = sp.symbols("Xd Yd Zd Qd", real=True)
    df = df.subs({sp.Derivative(v, s.t): r for v, r in zip((X, Y, Z, Q), rates)})
    back = {X: s.x, Y: s.y, Z: s.z, sp.cos(Q): s.cos_q[i], sp.sin(Q): s.sin_q[i]}
    coeff = [s.on_unit_circle(df.coeff(r).subs(back)) for r in rates]
    assert (
        sp.expand(df - sum(c * r for c, r in zip([sp.expand(df.coeff(r)) for r in rates], rates)))
        == 0
    )
    jp_row = sp.Matrix(coeff[:3]).T
    jq_ii = -coeff[3]  # J_p pdot + c qdot = 0  =>  J_p pdot = (-c) qdot
    return jp_row, jq_ii


# staged symbols
D = sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"D{i + 1}{j + 1}", real=True))  # rows p - S_i
jq = sp.symbols("jq1:4", real=True)  # J_q,ii / 2
rho = sp.symbols("rho1:4", real=True)  # radial component (cos theta_i, sin theta_i, 0) . D_i
inv_det = sp.Symbol("inv_det_D", real=True)
adjD = sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"adjD{i + 1}{j + 1}", real=True))
J = sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"J{i + 1}{j + 1}", real=True))


def rows_stage() -> Stage:
    """D = rows (p - S_i): eqs. (31)-(33) divided by 2 (from p: the inverse kinematics)."""
    pairs = []
    for i in range(3):
        for k, pk in enumerate((s.x, s.y, s.z)):
            pairs.append((D[i, k], pk - S[i][k]))
    return Stage("D = J_p / 2: rows p - S_i, eqs. (31)-(33)", tuple(pairs))


def _rows_from_rod() -> list:
    """The rows p - S_i as xi, xi - a, xi - b (p = S_1 + xi, a = S_2 - S_1, b = S_3 - S_1)."""
    return [xi, xi - a, xi - b]


def rod_rows_stage() -> Stage:
    """D = J_p / 2 from the direct kinematics' rod vector xi = p - S_1 (no p - S_i)."""
    p = sp.Matrix(S[0]) + xi
    shift = {**dict(zip(a, S[1] - S[0])), **dict(zip(b, S[2] - S[0]))}
    rows = _rows_from_rod()
    pairs = []
    for i in range(3):
        assert sp.expand(rows[i].subs(shift) - (p - S[i])) == sp.zeros(3, 1)
        pairs += [(D[i, k], rows[i][k]) for k in range(3)]
    return Stage("D = J_p / 2: rows p - S_i = xi, xi - a, xi - b, eqs. (31)-(33)", tuple(pairs))


def centre_path(i: int, qi):
    """S_i(q_i) of eqs. (3)-(5) as radius(q_i) along the drive's radial direction
    (cos theta_i, sin theta_i, 0) plus height(q_i) along z: (radius, height)."""
    centre = s.sphere_centre(i, sp.cos(qi), sp.sin(qi))
    radius, height = s.chain_r[i] + s.chain_l_a[i] * sp.cos(qi), centre[2]
    radial = sp.Matrix([s.cos_theta[i], s.sin_theta[i], 0])
    assert sp.expand(centre - radius * radial - height * sp.Matrix([0, 0, 1])) == sp.zeros(3, 1)
    return radius, height


def centre_rates(i: int):
    """(d radius/d q_i, d height/d q_i, d^2 radius/d q_i^2, d^2 height/d q_i^2) of
    :func:`centre_path`, in terms of cos q_i, sin q_i."""
    Q = sp.Symbol("Q", real=True)
    radius, height = centre_path(i, Q)
    back = {sp.cos(Q): s.cos_q[i], sp.sin(Q): s.sin_q[i]}
    return tuple(sp.diff(f, Q, n).subs(back) for n in (1, 2) for f in (radius, height))


def staged_centre_rates(i: int):
    """:func:`centre_rates` in the direct kinematics' staged symbols (derive/delta/fk.py):
    d radius/d q_i = -l_a,i sin q_i = S_z,i (the centre's height), d height/d q_i =
    d^2 radius/d q_i^2 = -l_a,i cos q_i, d^2 height/d q_i^2 = l_a,i sin q_i = -S_z,i. The
    kernels already hold S_z,i and l_a,i cos q_i (the centres): J_q,ii / 2 and h_i / 2
    then cost two products each, not four."""
    height, reach = S[i][2], la_cos_q[i]
    staged = (height, -reach, -reach, -height)
    back = {height: -s.chain_l_a[i] * s.sin_q[i], reach: s.chain_l_a[i] * s.cos_q[i]}
    for mine, derived in zip(staged, centre_rates(i)):
        assert sp.expand(mine.subs(back) - derived) == 0
    return staged


def on_centres(i: int) -> dict:
    """The staged centre S_i and l_a,i cos q_i -> their expressions in cos q_i, sin q_i."""
    return {**dict(zip(S[i], s.sphere_centre(i))), la_cos_q[i]: s.chain_l_a[i] * s.cos_q[i]}


def jq_stage() -> Stage:
    """J_q,ii / 2 = D_i . dS_i/dq_i (corrected eq. (34)), through rho_i and the staged
    centre rates (:func:`staged_centre_rates`); checked against the coefficient SymPy reads
    off the derivative of eq. (1) (:func:`constraint_rate`)."""
    pairs = []
    for i in range(3):
        d_radius, d_height, _, _ = staged_centre_rates(i)
        rho_i = s.cos_theta[i] * D[i, 0] + s.sin_theta[i] * D[i, 1]
        jq_i = d_radius * rho[i] + d_height * D[i, 2]
        on_p = {D[i, k]: (s.x, s.y, s.z)[k] - S[i][k] for k in range(3)}
        derived = jq_i.subs(rho[i], rho_i).subs(on_p).subs(on_centres(i))
        assert s.on_unit_circle(derived - constraint_rate(i)[1] / 2) == 0, "J_q,ii / 2"
        pairs += [(rho[i], rho_i), (jq[i], jq_i)]
    return Stage(
        "J_q,ii / 2 = D_i . dS_i/dq_i, eq. (34) corrected (sign of the r term)", tuple(pairs)
    )


def inverse_stage() -> Stage:
    """adj(D) and 1/det D (det D itself comes from the position stage: lambda |e|^2).
    adj(D)'s columns are the cross products D_2 x D_3, D_3 x D_1, D_1 x D_2 of the rows;
    with the rows xi, xi - a, xi - b they are e - xi x b - a x xi, xi x b, a x xi."""
    cols = [sp.Matrix(adjD[:, j]) for j in range(3)]
    second, third = xi.cross(b), a.cross(xi)
    first = e - cols[1] - cols[2]
    rows = _rows_from_rod()
    adj = sp.Matrix.vstack(*(r.T for r in rows)).adjugate()
    crosses = {**dict(zip(cols[1], second)), **dict(zip(cols[2], third))}
    assert sp.expand(first.subs(crosses).subs(dict(zip(e, a.cross(b)))) - adj[:, 0]) == sp.zeros(
        3, 1
    )
    assert sp.expand(second - adj[:, 1]) == sp.zeros(3, 1)
    assert sp.expand(third - adj[:, 2]) == sp.zeros(3, 1)
    pairs = [(cols[1][k], second[k]) for k in range(3)]
    pairs += [(cols[2][k], third[k]) for k in range(3)]
    pairs += [(cols[0][k], first[k]) for k in range(3)]
    pairs.append((inv_det, 1 / det_D))
    return Stage(
        "adjugate of D (columns: cross products of the rows) and 1 / det D, Cramer's rule "
        "for eq. (30)",
        tuple(pairs),
    )


def jacobian_stage() -> Stage:
    """J = D^-1 diag(J_q / 2): pdot = J qdot."""
    pairs = [(J[i, j], adjD[i, j] * jq[j] * inv_det) for i in range(3) for j in range(3)]
    return Stage("Jacobian J = J_p^-1 J_q, eq. (30)", tuple(pairs))


def solve(rhs) -> sp.Matrix:
    """D^-1 rhs = adj(D) rhs / det D with adj(D)'s first column written as
    e - (second) - (third) (:func:`inverse_stage`): the first column is never formed."""
    second, third = sp.Matrix(adjD[:, 1]), sp.Matrix(adjD[:, 2])
    return inv_det * (rhs[0] * e + (rhs[1] - rhs[0]) * second + (rhs[2] - rhs[0]) * third)


def velocity_stage() -> Stage:
    """pdot = adj(D) (J_q / 2 qdot) / det D, without forming J."""
    rhs = [jq[i] * s.qd[i] for i in range(3)]
    return Stage(
        "platform velocity pdot = J_p^-1 J_q qdot, eq. (30)",
        tuple((v, solve(rhs)[k]) for k, v in enumerate((s.xd, s.yd, s.zd))),
    )
