"""Sensitivity of the platform position to the chain parameters, for calibration.

Each chain's closure f_i(p, q_i; r_i, l_a,i, l_b,i, theta_i) = 0 (eq. (1), with chain i's
own values) holds for every geometry, so for a parameter pi of chain i (implicit function
theorem, as eq. (30) for q):

    J_p dp/dpi = -e_i df_i/dpi   =>   dp/dpi = -D^-1 e_i (df_i/dpi) / 2,

D = J_p / 2 (rows p - S_i). The partial derivatives df_i/dpi are SymPy's; theta_i enters
through cos theta_i and sin theta_i. An encoder offset of q_i has the column of J
(df_i/dq_i = -J_q,ii): dp/dq_offset,i = J e_i.
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.velocity import adjD, inv_det, jq
from deltagen.derive.kernel import Stage

#: Per-chain parameters in the order of the kernel's columns (then the chain index).
PARAMETER_NAMES = ("r", "l_a", "l_b", "theta", "q")

dp = sp.Matrix(
    15, 3, lambda k, c: sp.Symbol(f"dp_{PARAMETER_NAMES[k // 3]}{k % 3 + 1}_{'xyz'[c]}", real=True)
)
df = sp.Matrix(4, 3, lambda k, i: sp.Symbol(f"df_{PARAMETER_NAMES[k]}{i + 1}", real=True))


def closure_partials(i: int):
    """(df_i/dr_i, df_i/dl_a,i, df_i/dl_b,i, df_i/dtheta_i) in terms of p, cos q_i, sin q_i."""
    f = s.constraint(i).subs({sp.cos(s.q[i]): s.cos_q[i], sp.sin(s.q[i]): s.sin_q[i]})
    ct, st_ = s.cos_theta[i], s.sin_theta[i]
    return (
        sp.expand(sp.diff(f, s.chain_r[i])),
        sp.expand(sp.diff(f, s.chain_l_a[i])),
        sp.expand(sp.diff(f, s.chain_l_b[i])),
        sp.expand(-st_ * sp.diff(f, ct) + ct * sp.diff(f, st_)),
    )


def partials_stage() -> Stage:
    pairs = []
    for i in range(3):
        for k, expr in enumerate(closure_partials(i)):
            pairs.append((df[k, i], expr))
    return Stage("closure partials df_i / d(r_i, l_a,i, l_b,i, theta_i) of eq. (1)", tuple(pairs))


def sensitivity_stage() -> Stage:
    pairs = []
    for kind in range(5):
        for i in range(3):
            col = kind * 3 + i
            # -D^-1 e_i df/2 for geometry; J e_i = D^-1 e_i jq_i for the offset
            factor = jq[i] if kind == 4 else -df[kind, i] / 2
            for c in range(3):
                pairs.append((dp[col, c], adjD[c, i] * inv_det * factor))
    return Stage(
        "dp / d(chain parameters) = -J_p^-1 e_i df_i/dpi (implicit function theorem)", tuple(pairs)
    )
