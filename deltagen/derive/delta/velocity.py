"""Velocity level, eqs. (28)-(35): differentiate the constraint (1) in time.

d f_i / dt is linear in pdot and qdot_i (eq. (28)); collecting the coefficients gives
J_p pdot = J_q qdot (eq. (30)) with the rows of J_p = 2 (p - S_i)^T (eqs. (31)-(33)) and
the diagonal J_q (eqs. (34), (35)). SymPy's result differs from the printed (28)/(34) in
the sign of the r term (docs/errata.md).

The C core divides both sides by 2 and solves with the adjugate of D (rows p - S_i):
pdot = adj(D) (J_q / 2) qdot / det D. The Jacobian is J = D^-1 J_q / 2 (pdot = J qdot).
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.fk import S, det_D
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
inv_det = sp.Symbol("inv_det_D", real=True)
adjD = sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"adjD{i + 1}{j + 1}", real=True))
J = sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"J{i + 1}{j + 1}", real=True))


def rows_stage() -> Stage:
    """D = rows (p - S_i): eqs. (31)-(33) divided by 2."""
    pairs = []
    for i in range(3):
        for k, pk in enumerate((s.x, s.y, s.z)):
            pairs.append((D[i, k], pk - S[i][k]))
    return Stage("D = J_p / 2: rows p - S_i, eqs. (31)-(33)", tuple(pairs))


def jq_stage() -> Stage:
    """J_q,ii / 2 from SymPy's derivative of eq. (1) (corrected eq. (34))."""
    return Stage(
        "J_q,ii / 2, eq. (34) corrected (sign of the r term)",
        tuple((jq[i], constraint_rate(i)[1] / 2) for i in range(3)),
    )


def inverse_stage() -> Stage:
    """adj(D) and 1/det D (det D itself comes from the position stage: lambda |e|^2)."""
    adj = D.adjugate()
    pairs = [(adjD[i, j], adj[i, j]) for i in range(3) for j in range(3)]
    pairs.append((inv_det, 1 / det_D))
    return Stage("adjugate of D and 1 / det D for Cramer's rule, eq. (30)", tuple(pairs))


def jacobian_stage() -> Stage:
    """J = D^-1 diag(J_q / 2): pdot = J qdot."""
    pairs = [(J[i, j], adjD[i, j] * jq[j] * inv_det) for i in range(3) for j in range(3)]
    return Stage("Jacobian J = J_p^-1 J_q, eq. (30)", tuple(pairs))


def velocity_stage() -> Stage:
    """pdot = adj(D) (J_q / 2 qdot) / det D, without forming J."""
    rhs = sp.Matrix([jq[i] * s.qd[i] for i in range(3)])
    return Stage(
        "platform velocity pdot = J_p^-1 J_q qdot, eq. (30)",
        tuple((v, (adjD * rhs)[k] * inv_det) for k, v in enumerate((s.xd, s.yd, s.zd))),
    )
