"""Acceleration level, eqs. (36)-(39): differentiate the constraint (1) twice in time.

d^2 f_i / dt^2 = J_p,i pddot + (terms in pdot, qdot_i, qddot_i) (eq. (36)), so
J_p pddot = h with h_i = -(those terms) (eqs. (38), (39)). The C core solves
D pddot = h / 2 with the adjugate of D already formed for the velocity level.

Evaluated as h_i / 2 = D_i . Sddot_i - |pdot - Sdot_i|^2 (the second time derivative of
|p - S_i|^2 = l_b^2), with Sddot_i = dS_i/dq_i qddot_i + d^2S_i/dq_i^2 qdot_i^2, so that
D_i . dS_i/dq_i = J_q,ii / 2 and the rod's radial component rho_i come from the velocity
level; checked against the coefficients SymPy reads off eq. (36) where the stage is built.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.fk import S
from deltagen.derive.delta.velocity import (
    D,
    constraint_rate,
    jq,
    on_centres,
    rho,
    solve,
    staged_centre_rates,
    time_functions,
)
from deltagen.derive.kernel import Stage

hh = sp.symbols("h1:4", real=True)  # h_i / 2


def constraint_acceleration(i: int):
    """(J_p row i, h_i) from d^2 f_i / dt^2, eq. (36), in terms of p, pdot, cos q_i,
    sin q_i, qdot_i, qddot_i."""
    X, Y, Z, Q = time_functions()
    f = s.constraint(i, X, Y, Z, Q)
    d2f = sp.expand(sp.diff(f, s.t, 2))
    acc = (s.xdd, s.ydd, s.zdd, s.qdd[i])
    vel = (s.xd, s.yd, s.zd, s.qd[i])
    subs = {}
    for v, a_, _d in zip((X, Y, Z, Q), acc, vel):
        subs[sp.Derivative(v, (s.t, 2))] = a_
    d2f = d2f.subs(subs)
    d2f = d2f.subs({sp.Derivative(v, s.t): d for v, d in zip((X, Y, Z, Q), vel)})
    back = {X: s.x, Y: s.y, Z: s.z, sp.cos(Q): s.cos_q[i], sp.sin(Q): s.sin_q[i]}
    d2f = s.on_unit_circle(d2f.subs(back))
    jp_row = sp.Matrix([[d2f.coeff(c) for c in (s.xdd, s.ydd, s.zdd)]])
    rest = sp.expand(d2f - sum(jp_row[k] * c for k, c in enumerate((s.xdd, s.ydd, s.zdd))))
    return jp_row, -rest


def half_h(i: int) -> sp.Expr:
    """h_i / 2 = D_i . Sddot_i - |pdot - Sdot_i|^2 in terms of the staged D_i, rho_i, jq_i."""
    d_radius, d_height, dd_radius, dd_height = staged_centre_rates(i)
    radial = sp.Matrix([s.cos_theta[i], s.sin_theta[i], 0])
    rel = s.pd - s.qd[i] * (d_radius * radial + d_height * sp.Matrix([0, 0, 1]))
    curvature = dd_radius * rho[i] + dd_height * D[i, 2]  # D_i . d^2 S_i / dq_i^2
    # -curvature as one product with its sign outside: no negation per point
    bend = sp.expand(-curvature)
    return jq[i] * s.qdd[i] - sp.Mul(s.qd[i] ** 2, bend, evaluate=False) - rel.dot(rel)


def _check_half_h(i: int) -> None:
    """half_h(i) with D_i = p - S_i, rho_i, jq_i substituted equals eq. (36)'s h_i / 2."""
    on_p = {D[i, k]: (s.x, s.y, s.z)[k] - S[i][k] for k in range(3)}
    rho_i = s.cos_theta[i] * D[i, 0] + s.sin_theta[i] * D[i, 1]
    expr = half_h(i).subs(jq[i], constraint_rate(i)[1] / 2).subs(rho[i], rho_i).subs(on_p)
    expr = expr.subs(on_centres(i))
    assert s.on_unit_circle(expr - constraint_acceleration(i)[1] / 2) == 0, "h_i / 2"


def h_stage() -> Stage:
    for i in range(3):
        _check_half_h(i)
    return Stage(
        "right-hand side h / 2 of J_p pddot = h, eqs. (38)-(39): D_i . Sddot_i - |pdot - Sdot_i|^2",
        tuple((hh[i], half_h(i)) for i in range(3)),
    )


def acceleration_stage() -> Stage:
    return Stage(
        "platform acceleration pddot = J_p^-1 h, eq. (38)",
        tuple((v, solve(hh)[k]) for k, v in enumerate((s.xdd, s.ydd, s.zdd))),
    )
