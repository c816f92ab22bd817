"""Inverse dynamics of the rotary delta robot: motor torques tau for feed-forward control
(delta report, Figures 1-2: the kinematic models feed a dynamic model that computes tau).

The report prints no dynamic model; this one is derived here by the principle of virtual
work on the closed chain, with q (the crank angles) as generalized coordinates and the
constraint Jacobian J = J_p^-1 J_q of eq. (30) mapping crank rates to platform velocity.
For each body the virtual-work contribution to tau_k is

    d v / d qdot_k . m (a - g)        (translation of a body's centre of mass)
    d w / d qdot_k . (I alpha + w x I w)   (rotation)

with v, a the velocity and acceleration SymPy differentiates from the positions (crank
tips B_i from q_i(t); the platform from pdot = J qdot and pddot of eq. (38)).

Bodies (deltagen/model/delta.py, DeltaInertia):

* crank i turns about its fixed drive axis: I_a qddot_i; gravity of m_a at
  c_i = A_i + r_ca (cos q_i e_i - sin q_i e_z) (e_i the drive's radial unit vector).
* rod pair i (two slender rods of length l_b moving in parallel; the parallelogram keeps
  both rods parallel, so the pair moves like one rod): mass m_b at the midpoint of B_i and
  C_i; inertia m_b l_b^2 / 12 about axes perpendicular to the rods, none about them. With
  the rod direction u_i = (C_i - B_i) / l_b = (p - S_i) / l_b its angular velocity (the
  spin about u_i carries no energy) is w = u x udot, w . u = 0, so I w = I_r w,
  w x I w = 0, and since u . d udot / d qdot_k = 0 (|u| = 1):
  d w / d qdot_k . I_r (u x uddot) = I_r d udot / d qdot_k . uddot. This last form is
  what the kernel evaluates (exact wherever the constraint (1) holds).
* platform: translates only; mass m_p + payload at P.

The *simplified* model, common in delta-robot controllers, splits each rod pair's mass: m_b/2
as a point mass at the crank tip B_i, m_b/2 on the platform, and drops the rods' rotation.
Its kinetic energy per pair is m_b/4 (|v_B|^2 + |v_C|^2), the exact one
m_b/6 (|v_B|^2 + v_B . v_C + |v_C|^2), so they differ wherever crank tip and platform
move differently.

The fourth axis (eq. (43)) is decoupled: tau_4 = I_4 qddot_4 (its mass rides on the
platform, in m_p).
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.velocity import J
from deltagen.derive.kernel import Stage

# inertial parameters (run-time parameters of the C core)
I_a, m_a, r_ca, m_b, m_p, I_4 = sp.symbols("I_a m_a r_ca m_b m_p I_4", nonnegative=True)
gravity = sp.Matrix(sp.symbols("g_x g_y g_z", real=True))
# per point: the payload carried by the platform [kg]
payload = sp.Symbol("payload", real=True)

# staged symbols: crank-tip velocity per unit rate and acceleration (B_i and S_i move alike)
dB = [sp.Matrix(sp.symbols(f"dB_x{i} dB_y{i} dB_z{i}", real=True)) for i in (1, 2, 3)]
aB = [sp.Matrix(sp.symbols(f"aB_x{i} aB_y{i} aB_z{i}", real=True)) for i in (1, 2, 3)]
tau = sp.symbols("tau1:4", real=True)


def _radial(i: int) -> sp.Matrix:
    return sp.Matrix([s.cos_theta[i], s.sin_theta[i], 0])


def crank_point(i: int, distance, qi) -> sp.Matrix:
    """A point at ``distance`` from A_i along crank i at angle ``qi`` (positive = down):
    A_i = r_a e_i, B_i = crank_point(i, l_a, q_i) (report, Figure 4)."""
    return s.r_a * _radial(i) + distance * sp.Matrix(
        [sp.cos(qi) * s.cos_theta[i], sp.cos(qi) * s.sin_theta[i], -sp.sin(qi)]
    )


def _back(expr, i, Q):
    return expr.subs({sp.cos(Q): s.cos_q[i], sp.sin(Q): s.sin_q[i]})


def crank_tip_motion(i: int):
    """(dB_i/dq_i, a_B_i) derived by differentiating B_i(q_i(t)) in time."""
    Q = sp.Function("Q")(s.t)
    B = crank_point(i, s.l_a, Q)
    v = B.diff(s.t)
    a = v.diff(s.t)
    rules = {sp.Derivative(Q, (s.t, 2)): s.qdd[i], sp.Derivative(Q, s.t): s.qd[i]}
    a = a.subs(rules)
    v = v.subs(rules)
    per_rate = sp.Matrix([sp.expand(_back(c, i, Q)).coeff(s.qd[i]) for c in v])
    return per_rate, sp.Matrix([sp.expand(_back(c, i, Q)) for c in a])


def crank_tip_stage() -> Stage:
    pairs = []
    for i in range(3):
        per_rate, acc = crank_tip_motion(i)
        pairs += list(zip(dB[i], per_rate)) + list(zip(aB[i], acc))
    return Stage(
        "crank tips B_i: velocity per unit crank rate dB_i/dq_i and acceleration a_B_i",
        tuple(pairs),
    )


def _partial(v: sp.Matrix, k: int) -> sp.Matrix:
    return v.diff(s.qd[k])


def _body_terms():
    """Per body: (velocity, acceleration, mass) of points, in terms of staged symbols."""
    pd = J * sp.Matrix(s.qd)  # eq. (30)
    pdd = s.pdd  # eq. (38), from the acceleration stage
    vB = [dB[i] * s.qd[i] for i in range(3)]
    return pd, pdd, vB


def _crank_terms(k: int) -> sp.Expr:
    """Crank k: rotation about its axis and the gravity of its mass (the only crank whose
    rate qdot_k moves it)."""
    Q = s.q[k]
    c = crank_point(k, r_ca, Q)
    dc = _back(c.diff(Q), k, Q)
    return I_a * s.qdd[k] - (dc.T * gravity)[0] * m_a


def _tau_exact(k: int) -> sp.Expr:
    pd, pdd, vB = _body_terms()
    total = _crank_terms(k)
    total += (_partial(pd, k).T * (m_p + payload) * (pdd - gravity))[0]
    I_r = m_b * s.l_b**2 / 12
    for i in range(3):
        v_mid = (vB[i] + pd) / 2
        a_mid = (aB[i] + pdd) / 2
        total += (_partial(v_mid, k).T * m_b * (a_mid - gravity))[0]
        udot = (pd - vB[i]) / s.l_b
        uddot = (pdd - aB[i]) / s.l_b
        total += (_partial(udot, k).T * I_r * uddot)[0]
    return total


def _tau_simplified(k: int) -> sp.Expr:
    pd, pdd, vB = _body_terms()
    total = _crank_terms(k)
    total += (_partial(pd, k).T * (m_p + payload + 3 * m_b / 2) * (pdd - gravity))[0]
    for i in range(3):
        total += (_partial(vB[i], k).T * (m_b / 2) * (aB[i] - gravity))[0]
    return total


def _split(expr: sp.Expr, k: int):
    """tau_k (expanded) as (F, f, rest) with tau_k = J[:, k] . F + dB_k . f + rest: F is the
    force the platform needs (the same for every k: virtual work gives J^T F), f the force
    crank tip k needs. Coefficients collected by the accelerations and gravity."""
    motion = list(s.pdd) + list(gravity) + [c for v in aB for c in v]
    keys = list(J) + [c for v in dB for c in v]
    parts = sp.collect(sp.expand(expr), keys, evaluate=False)

    def tidy(value):
        return sp.collect(value, motion, func=sp.factor)

    F = [tidy(parts.pop(J[j, k], sp.S.Zero)) for j in range(3)]
    f = [tidy(parts.pop(dB[k][c], sp.S.Zero)) for c in range(3)]
    rest = parts.pop(sp.S.One, sp.S.Zero)
    assert not parts, f"tau_{k + 1} has terms in other chains' J columns or crank tips: {parts}"
    return F, f, tidy(rest)


# staged symbols of the generalized forces
F_platform = sp.Matrix(sp.symbols("F_x F_y F_z", real=True))
f_tip = [sp.Matrix(sp.symbols(f"f_x{i} f_y{i} f_z{i}", real=True)) for i in (1, 2, 3)]


def force_stage(model: str) -> Stage:
    """F (platform) and f_i (crank tips) of :func:`_split`, checked to be one F for all k."""
    term = {"exact": _tau_exact, "simplified": _tau_simplified}[model]
    pairs, F_first = [], None
    for k in range(3):
        F, f, _ = _split(term(k), k)
        if F_first is None:
            F_first = F
            pairs += list(zip(F_platform, F))
        else:
            assert all(sp.expand(a - b) == 0 for a, b in zip(F, F_first)), "not J^T F"
        pairs += list(zip(f_tip[k], f))
    what = "exact model" if model == "exact" else "simplified model (rod mass split)"
    return Stage(
        f"forces by virtual work, {what}: F on the platform (tau = J^T F + ...), f_i on the "
        "crank tips, from sum over bodies of (d v / d qdot)^T m (a - g) + rotation",
        tuple(pairs),
    )


def tau_stage(model: str, adjD, jq, inv_det) -> Stage:
    """tau_k = J[:, k] . F + dB_k . f_k + rest_k with J = adj(D) diag(J_q / 2) / det D
    (eq. (30)) applied without forming J: J[:, k] . F = (J_q,kk / 2) (adj(D)[:, k] . F) / det D."""
    term = {"exact": _tau_exact, "simplified": _tau_simplified}[model]
    pairs = []
    for k in range(3):
        _, _, rest = _split(term(k), k)
        JtF = jq[k] * inv_det * sum(adjD[j, k] * F_platform[j] for j in range(3))
        pairs.append((tau[k], JtF + (dB[k].T * f_tip[k])[0] + rest))
    return Stage("motor torques tau = J^T F + dB_i . f_i + crank terms, eq. (30)", tuple(pairs))
