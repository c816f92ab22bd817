"""Inverse rates, the report's IKM at velocity and acceleration level (eqs. (28)-(39)):
(p, pdot, pddot) -> (q, qdot, qddot).

J_q is diagonal (eq. (34)), so qdot = J_q^-1 J_p pdot needs no matrix inverse: row i of
J_p pdot = J_q qdot reads D_i . pdot = (J_q,ii / 2) qdot_i with D_i = p - S_i. The
acceleration comes from the same second time derivative of constraint (1) that gives
eqs. (36)-(39): d^2 f_i / dt^2 = 0 is linear in qddot_i with coefficient -J_q,ii
(derived below, not assumed), so qddot_i = (d^2 f_i / dt^2 at qddot_i = 0) / J_q,ii.

The crank angles come from the closed-form inverse (derive/delta/ik.py); their cos and
sin are read off that solution's atan2 arguments (X, Y) = rho^2 (cos q, sin q) (both
angles of the atan2 sum have radius rho, so |(X, Y)| = rho^2): no trigonometric call.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import ik as ikd
from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.acceleration import constraint_acceleration
from deltagen.derive.delta.fk import fk_stages
from deltagen.derive.delta.velocity import D, constraint_rate, jq, jq_stage, rows_stage
from deltagen.derive.kernel import Stage

ik_x = sp.symbols("ik_x1:4", real=True)  # rho^2 cos q_i
ik_y = sp.symbols("ik_y1:4", real=True)  # rho^2 sin q_i
inv_rho_sq = sp.symbols("inv_rho_sq1:4", real=True)
inv_jq = sp.symbols("inv_jq1:4", real=True)  # 2 / J_q,ii


def ik_stages_with_trig() -> list:
    """The closed-form inverse of derive/delta/ik.py with the atan2 arguments named, and
    cos q_i, sin q_i from them."""
    coeffs, discs, _ = ikd.ik_stages()
    args, trig, angles = [], [], []
    for i in range(3):
        root = sp.sqrt(ikd.disc[i])
        E, F, G = ikd.E[i], ikd.F[i], ikd.G[i]
        args += [(ik_x[i], -E * G - F * root), (ik_y[i], -F * G + E * root)]
        trig += [
            (inv_rho_sq[i], 1 / ikd.rho_sq[i]),
        ]
        angles.append((s.q[i], sp.atan2(ik_y[i], ik_x[i])))
    unit = []
    for i in range(3):
        unit += [(s.cos_q[i], ik_x[i] * inv_rho_sq[i]), (s.sin_q[i], ik_y[i] * inv_rho_sq[i])]
    return [
        coeffs,
        discs,
        Stage("elbow-out atan2 arguments (X, Y) = rho^2 (cos q, sin q), eq. (1)", tuple(args)),
        Stage("crank angles q = atan2(Y, X) in (-pi, pi]", tuple(angles)),
        Stage("cos q_i, sin q_i = (X, Y) / rho^2", tuple(trig) + tuple(unit)),
    ]


def centres_stages() -> list:
    """l_a,i cos q_i and the sphere centres S_i of eqs. (3)-(5) (the first two stages of
    the direct kinematics: jq_stage reads both)."""
    return fk_stages()[:2]


def qd_stage() -> Stage:
    """qdot_i = D_i . pdot / (J_q,ii / 2), eq. (30) solved for qdot (J_q diagonal)."""
    pairs = [(inv_jq[i], 1 / jq[i]) for i in range(3)]
    pd = (s.xd, s.yd, s.zd)
    for i in range(3):
        pairs.append((s.qd[i], sum(D[i, k] * pd[k] for k in range(3)) * inv_jq[i]))
    return Stage("crank rates qdot = J_q^-1 J_p pdot, eq. (30), J_q diagonal", tuple(pairs))


def qdd_expression(i: int):
    """qddot_i from d^2 f_i / dt^2 = 0 (eq. (36)), in terms of p, pdot, pddot, cos q_i,
    sin q_i, qdot_i and the staged D_i, jq_i: d^2 f_i / dt^2 = J_p,i pddot - h_i, and h_i
    holds qddot_i with the coefficient J_q,ii (asserted)."""
    _, h = constraint_acceleration(i)  # J_p,i pddot = h_i (eqs. (38), (39))
    h = sp.expand(h)
    coeff = h.coeff(s.qdd[i])
    assert s.on_unit_circle(coeff - constraint_rate(i)[1]) == 0, "h_i must hold J_q,ii qddot_i"
    rest = sp.expand(h - coeff * s.qdd[i])
    # J_p,i pddot = 2 D_i . pddot  =>  J_q,ii qddot_i = 2 D_i . pddot - rest, J_q,ii = 2 jq_i
    pdd = (s.xdd, s.ydd, s.zdd)
    return (sum(D[i, k] * pdd[k] for k in range(3)) - rest / 2) * inv_jq[i]


def qdd_stage() -> Stage:
    return Stage(
        "crank accelerations qddot_i = (d^2 f_i / dt^2 at qddot_i = 0) / J_q,ii, eqs. (36)-(39)",
        tuple((s.qdd[i], qdd_expression(i)) for i in range(3)),
    )


def rate_stages(with_acceleration: bool) -> list:
    stages = [*ik_stages_with_trig(), *centres_stages(), rows_stage(), jq_stage(), qd_stage()]
    return stages + ([qdd_stage()] if with_acceleration else [])
