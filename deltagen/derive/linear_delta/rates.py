"""Velocity and acceleration level of the linear delta and the tripod: the sphere
constraints |p - S_i|^2 = r_i^2 differentiated in time (the delta report's eqs. (28)-(39)
for the rotary delta, here with a carriage moving along z or a strut changing length).

Each constraint's rate is D_i . pdot = g_i qdot_i + (nothing else) with D_i = p - S_i (the
rows of derive/delta/velocity.py's D, built from the direct kinematics' rod vector), so
pdot = D^-1 diag(g) qdot = J qdot, and its second derivative D_i . pddot = g_i qddot_i + c_i:

  linear delta  S_i = (tower_x_i, tower_y_i, h_i), r_i = arm_i:
                g_i = D_i,z,  c_i = -|pdot - hdot_i z|^2
  tripod        S_i fixed (A, B, C), r_i = l_i:
                g_i = l_i,    c_i = ldot_i^2 - |pdot|^2

SymPy differentiates the constraints and the staged forms are asserted against the result
where they are built (derived, not copied). D^-1 is the rotary delta's adjugate stage
(derive/delta/velocity.py: ``inverse_stage``, ``solve``): one copy of the math.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as ds
from deltagen.derive.delta import velocity as vel
from deltagen.derive.kernel import Stage
from deltagen.derive.linear_delta import symbols as s

g = sp.symbols("g1:4", real=True)  # the diagonal of D pdot = diag(g) qdot
c = sp.symbols("c1:4", real=True)  # the velocity-product term of the acceleration level

_t = ds.t


def _machine(kind: str, i: int):
    """(joint, rate, acceleration symbols of chain i, centre S_i(t), radius r_i(t), Q(t))."""
    Q = sp.Function("Q")(_t)
    if kind == "linear_delta":
        return (s.h[i], s.hd[i], s.hdd[i]), s.carriage(i, Q), s.arm[i], Q
    return (s.strut[i], s.ld[i], s.ldd[i]), s.tripod_base(i), Q, Q


def _differentiated(kind: str, i: int):
    """(d f_i/dt / 2, d^2 f_i/dt^2 / 2) in p, pdot, pddot and the joint's value and rates."""
    (q, qd, qdd), centre, radius, Q = _machine(kind, i)
    P = sp.Matrix([sp.Function(n)(_t) for n in ("X", "Y", "Z")])
    f = (P - centre).dot(P - centre) - radius**2
    subs = {}
    for fun, rate, accel in zip([*P, Q], [ds.xd, ds.yd, ds.zd, qd], [ds.xdd, ds.ydd, ds.zdd, qdd]):
        subs[sp.Derivative(fun, (_t, 2))] = accel
        subs[sp.Derivative(fun, _t)] = rate
    out = []
    for order in (1, 2):
        d = sp.diff(f, _t, order) / 2
        d = d.subs({k: v for k, v in subs.items() if k.derivative_count == 2})
        d = d.subs({k: v for k, v in subs.items() if k.derivative_count == 1})
        d = d.subs({P[0]: ds.x, P[1]: ds.y, P[2]: ds.z, Q: q})
        out.append(sp.expand(d))
    return out


def _row(kind: str, i: int) -> sp.Matrix:
    """D_i = p - S_i in terms of p and the joint value."""
    (q, _, _), centre, _, Q = _machine(kind, i)
    return ds.p - (centre.subs(Q, q) if hasattr(centre, "subs") else centre)


def g_value(kind: str, i: int) -> sp.Expr:
    """g_i in terms of the staged row D_i (linear delta) or the strut length (tripod)."""
    return vel.D[i, 2] if kind == "linear_delta" else s.strut[i]


def c_value(kind: str, i: int) -> sp.Expr:
    if kind == "linear_delta":
        rel = ds.pd - s.hd[i] * sp.Matrix([0, 0, 1])
        return -rel.dot(rel)
    return s.ld[i] ** 2 - ds.pd.dot(ds.pd)


def _check(kind: str, i: int) -> None:
    """The staged g_i and c_i equal what SymPy reads off the differentiated constraint."""
    (q, qd, qdd), *_ = _machine(kind, i)
    first, second = _differentiated(kind, i)
    row = _row(kind, i)
    on_p = {vel.D[i, k]: row[k] for k in range(3)}
    # first: D_i . pdot - g_i qdot_i = 0
    assert sp.expand(first - (row.dot(ds.pd) - g_value(kind, i).subs(on_p) * qd)) == 0, "g_i"
    # second: D_i . pddot - g_i qddot_i - c_i = 0
    rest = row.dot(ds.pdd) - g_value(kind, i).subs(on_p) * qdd - c_value(kind, i)
    assert sp.expand(second - rest) == 0, "c_i"


def g_stage(kind: str) -> Stage:
    for i in range(3):
        _check(kind, i)
    what = "D_i,z (carriage along z)" if kind == "linear_delta" else "l_i (strut length)"
    return Stage(
        f"diagonal g of D pdot = diag(g) qdot: g_i = {what}",
        tuple((g[i], g_value(kind, i)) for i in range(3)),
    )


def jacobian_stage() -> Stage:
    """J = D^-1 diag(g): pdot = J qdot."""
    pairs = [(vel.J[i, j], vel.adjD[i, j] * g[j] * vel.inv_det) for i in range(3) for j in range(3)]
    return Stage("Jacobian J = D^-1 diag(g)", tuple(pairs))


def velocity_stage(kind: str) -> Stage:
    rates = s.hd if kind == "linear_delta" else s.ld
    rhs = [g[i] * rates[i] for i in range(3)]
    solved = vel.solve(rhs)
    return Stage(
        "velocity pdot = D^-1 diag(g) qdot",
        tuple((v, solved[k]) for k, v in enumerate((ds.xd, ds.yd, ds.zd))),
    )


def acceleration_stage(kind: str) -> Stage:
    accels = s.hdd if kind == "linear_delta" else s.ldd
    terms = [(c[i], c_value(kind, i)) for i in range(3)]
    solved = vel.solve([g[i] * accels[i] + c[i] for i in range(3)])
    return Stage(
        "acceleration pddot = D^-1 (diag(g) qddot + c), c from the constraints' second rate",
        tuple(terms) + tuple((v, solved[k]) for k, v in enumerate((ds.xdd, ds.ydd, ds.zdd))),
    )


def rate_stages(kind: str, with_jacobian: bool = False) -> tuple:
    """D (rows from the rod vector), adj(D) and 1/det D, g (and J)."""
    stages = (vel.rod_rows_stage(), vel.inverse_stage(), g_stage(kind))
    return stages + ((jacobian_stage(),) if with_jacobian else ())
