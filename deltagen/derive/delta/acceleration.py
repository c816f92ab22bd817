"""Acceleration level, eqs. (36)-(39): differentiate the constraint (1) twice in time.

d^2 f_i / dt^2 = J_p,i pddot + (terms in pdot, qdot_i, qddot_i) (eq. (36)), so
J_p pddot = h with h_i = -(those terms) (eqs. (38), (39)). The C core solves
D pddot = h / 2 with the adjugate of D already formed for the velocity level.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.velocity import adjD, inv_det, time_functions
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


def h_stage() -> Stage:
    return Stage(
        "right-hand side h / 2 of J_p pddot = h, eqs. (38)-(39)",
        tuple((hh[i], constraint_acceleration(i)[1] / 2) for i in range(3)),
    )


def acceleration_stage() -> Stage:
    adj = sp.Matrix(adjD)
    h = sp.Matrix(hh)
    return Stage(
        "platform acceleration pddot = J_p^-1 h, eq. (38)",
        tuple((v, (adj * h)[k] * inv_det) for k, v in enumerate((s.xdd, s.ydd, s.zdd))),
    )
