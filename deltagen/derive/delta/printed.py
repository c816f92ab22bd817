"""The delta report's PRINTED equations, transcribed literally as SymPy expressions.

Nothing here is derived: every expression is copied from the printed text, errors
included, so that tests/derive/test_printed.py can compare it with what deltagen derives
(deltagen.derive.delta.*) and docs/errata.md can list the disagreements. Do not "fix"
anything in this module; corrections live in the derivation modules.

Conventions of the transcription:

* Chain indices are 0-based in function arguments (``i = 0, 1, 2`` is the report's
  ``i = 1, 2, 3``), as in deltagen.derive.delta.symbols.
* Symbols are deltagen's (deltagen.derive.delta.symbols): cos q_i, sin q_i, cos theta_i,
  sin theta_i are separate symbols unless angles are passed in explicitly; the sphere
  centres, u, v and w are the same symbols as in deltagen.derive.delta.fk
  (``S_x1 ..``, ``u1 ..``, ``v1 ..``, ``w1 ..``, all real).
* Decimal commas of the report are written as exact rationals (0,25 -> 1/4).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from deltagen.derive.delta import symbols as s

# Symbols of section 2.2 (identical to those of derive_fk.spheres / report_elimination).
S = [sp.Matrix(sp.symbols(f"S_x{i} S_y{i} S_z{i}", real=True)) for i in (1, 2, 3)]
Sx = [c[0] for c in S]
Sy = [c[1] for c in S]
Sz = [c[2] for c in S]
u = sp.symbols("u1:5", real=True)
v = sp.symbols("v1:5", real=True)
w = sp.symbols("w1:8", real=True)  # w1 .. w7 as names; w[0] is the report's w_1


def _trig(i, cq, sq):
    cq = s.cos_q[i] if cq is None else cq
    sq = s.sin_q[i] if sq is None else sq
    return cq, sq, s.cos_theta[i], s.sin_theta[i]


# ----------------------------------------------------------------- 2.1 constraints


def vector_CB(i, cq=None, sq=None, first_form=False) -> sp.Matrix:
    """C_i B_i as printed before eq. (1); ``first_form`` uses r_a, r_b, else r."""
    cq, sq, ct, st = _trig(i, cq, sq)
    x, y, z, la = s.x, s.y, s.z, s.l_a
    if first_form:
        return sp.Matrix(
            [
                (s.r_a + la * cq) * ct - s.r_b * ct - x,
                (s.r_a + la * cq) * st - s.r_b * st - y,
                -la * sq - z,
            ]
        )
    return sp.Matrix([(s.r + la * cq) * ct - x, (s.r + la * cq) * st - y, -la * sq - z])


def eq1_constraint(i, cq=None, sq=None) -> sp.Expr:
    """(1)  f_i = [(r + l_a cos q_i) cos th_i - x]^2 + [(r + l_a cos q_i) sin th_i - y]^2
    + [-l_a sin q_i - z]^2 - l_b^2."""
    cq, sq, ct, st = _trig(i, cq, sq)
    x, y, z, la = s.x, s.y, s.z, s.l_a
    return (
        ((s.r + la * cq) * ct - x) ** 2
        + ((s.r + la * cq) * st - y) ** 2
        + (-la * sq - z) ** 2
        - s.l_b**2
    )


# ------------------------------------------------------- 2.2 direct kinematic problem


def eq2_sphere(i, px=s.x, py=s.y, pz=s.z) -> sp.Expr:
    """(2)  varsigma_i = (x - S_xi)^2 + (y - S_yi)^2 + (z - S_zi)^2 - l_b^2."""
    return (px - Sx[i]) ** 2 + (py - Sy[i]) ** 2 + (pz - Sz[i]) ** 2 - s.l_b**2


def eq3_5_centre(i, cq=None, sq=None) -> sp.Matrix:
    """(3) S_xi = (r + l_a cos q_i) cos th_i, (4) S_yi = (r + l_a cos q_i) sin th_i,
    (5) S_zi = -l_a sin q_i."""
    cq, sq, ct, st = _trig(i, cq, sq)
    return sp.Matrix(
        [
            (s.r + s.l_a * cq) * ct,  # (3)
            (s.r + s.l_a * cq) * st,  # (4)
            -s.l_a * sq,  # (5)
        ]
    )


def eq6_7_planes():
    """(6) eps_1: varsigma_1 - varsigma_2 = u1 x + u2 y + u3 z + u4,
    (7) eps_2: varsigma_1 - varsigma_3 = v1 x + v2 y + v3 z + v4."""
    x, y, z = s.x, s.y, s.z
    return (
        u[0] * x + u[1] * y + u[2] * z + u[3],  # (6)
        v[0] * x + v[1] * y + v[2] * z + v[3],  # (7)
    )


def eq8_15_uv():
    """(8)-(15): u_1..u_4 and v_1..v_4 in terms of the sphere centres."""
    U = (
        2 * Sx[1] - 2 * Sx[0],  # (8)
        2 * Sy[1] - 2 * Sy[0],  # (9)
        2 * Sz[1] - 2 * Sz[0],  # (10)
        -(Sz[1] ** 2) - Sy[1] ** 2 - Sx[1] ** 2 + Sz[0] ** 2 + Sy[0] ** 2 + Sx[0] ** 2,  # (11)
    )
    V = (
        2 * Sx[2] - 2 * Sx[0],  # (12)
        2 * Sy[2] - 2 * Sy[0],  # (13)
        2 * Sz[2] - 2 * Sz[0],  # (14)
        -(Sz[2] ** 2) - Sy[2] ** 2 - Sx[2] ** 2 + Sz[0] ** 2 + Sy[0] ** 2 + Sx[0] ** 2,  # (15)
    )
    return U, V


def eq16_17_line(zz=s.z):
    """(16) x = w1 z + w2, (17) y = w3 z + w4."""
    return w[0] * zz + w[1], w[2] * zz + w[3]


def eq18_21_w():
    """(18)-(21) as printed; (20), (21) are written with the symbols w1, w2 (not their
    values) and divide by v2."""
    u1, u2, u3, u4 = u
    v1, v2, v3, v4 = v
    w1, w2 = w[0], w[1]
    return (
        (v2 * u3 - u2 * v3) / (v1 * u2 - u1 * v2),  # (18)
        (v2 * u4 - u2 * v4) / (v1 * u2 - u1 * v2),  # (19)
        (-v3 - v1 * w1) / v2,  # (20)
        (-v4 - v1 * w2) / v2,  # (21)
    )


def eq18_21_w_substituted():
    """(18)-(21) with w1, w2 of (18), (19) inserted into (20), (21) (no simplification)."""
    w1, w2, w3, w4 = eq18_21_w()
    return w1, w2, w3.subs({w[0]: w1, w[1]: w2}), w4.subs({w[0]: w1, w[1]: w2})


def eq22_quadratic(zz=s.z):
    """(22), first line: (w3 z + w4 - S_y3)^2 + (w1 z - S_x3 + w2)^2 + (z - S_z3)^2 - l_b^2."""
    w1, w2, w3, w4 = w[:4]
    return (w3 * zz + w4 - Sy[2]) ** 2 + (w1 * zz - Sx[2] + w2) ** 2 + (zz - Sz[2]) ** 2 - s.l_b**2


def eq23_25_w():
    """(23) w5, (24) w6, (25) w7 (coefficients of w5 z^2 + w6 z + w7 = 0, eq. (22))."""
    w1, w2, w3, w4 = w[:4]
    return (
        w3**2 + w1**2 + 1,  # (23)
        2 * w3 * w4 - 2 * Sy[2] * w3 - 2 * Sz[2] - 2 * w1 * Sx[2] + 2 * w1 * w2,  # (24)
        -(s.l_b**2)
        + w4**2
        - 2 * Sy[2] * w4
        + Sz[2] ** 2
        + Sy[2] ** 2
        + Sx[2] ** 2
        - 2 * w2 * Sx[2]
        + w2**2,  # (25)
    )


def eq26_roots():
    """(26) z_w = min( -(w6 +- sqrt(w6^2 - 4 w5 w7)) / (2 w5) ): the two candidates, in
    the printed form (the minus sign stands in front of the whole fraction)."""
    w5, w6, w7 = w[4:7]
    root = sp.sqrt(w6**2 - 4 * w5 * w7)
    return (-(w6 + root) / (2 * w5), -(w6 - root) / (2 * w5))


def eq27_position(z_w):
    """(27) p = [w1 z_w + w2, w3 z_w + w4, z_w]."""
    return sp.Matrix([w[0] * z_w + w[1], w[2] * z_w + w[3], z_w])


def evaluate_fk(r, l_a, l_b, theta, q):
    """The printed chain (3)-(27) evaluated literally in float64 for one pose:
    returns (p, details). No guard against v2 = 0 or a negative discriminant, as printed."""
    th = np.asarray(theta, dtype=float)
    q = np.asarray(q, dtype=float)[:3]
    R = r + l_a * np.cos(q)
    Sn = np.column_stack([R * np.cos(th), R * np.sin(th), -l_a * np.sin(q)])  # (3)-(5)
    (sx1, sy1, sz1), (sx2, sy2, sz2), (sx3, sy3, sz3) = Sn
    u1, u2, u3 = 2 * sx2 - 2 * sx1, 2 * sy2 - 2 * sy1, 2 * sz2 - 2 * sz1  # (8)-(10)
    u4 = -(sz2**2) - sy2**2 - sx2**2 + sz1**2 + sy1**2 + sx1**2  # (11)
    v1, v2, v3 = 2 * sx3 - 2 * sx1, 2 * sy3 - 2 * sy1, 2 * sz3 - 2 * sz1  # (12)-(14)
    v4 = -(sz3**2) - sy3**2 - sx3**2 + sz1**2 + sy1**2 + sx1**2  # (15)
    with np.errstate(all="ignore"):
        den = np.float64(v1 * u2 - u1 * v2)
        w1 = (v2 * u3 - u2 * v3) / den  # (18)
        w2 = (v2 * u4 - u2 * v4) / den  # (19)
        w3 = (-v3 - v1 * w1) / np.float64(v2)  # (20)
        w4 = (-v4 - v1 * w2) / np.float64(v2)  # (21)
        w5 = w3**2 + w1**2 + 1  # (23)
        w6 = 2 * w3 * w4 - 2 * sy3 * w3 - 2 * sz3 - 2 * w1 * sx3 + 2 * w1 * w2  # (24)
        w7 = (
            -(l_b**2) + w4**2 - 2 * sy3 * w4 + sz3**2 + sy3**2 + sx3**2 - 2 * w2 * sx3 + w2**2
        )  # (25)
        root = np.sqrt(w6**2 - 4 * w5 * w7)
        zw = min(-(w6 + root) / (2 * w5), -(w6 - root) / (2 * w5))  # (26)
    p = np.array([w1 * zw + w2, w3 * zw + w4, zw])  # (27)
    return p, dict(S=Sn, u=(u1, u2, u3, u4), v=(v1, v2, v3, v4), w=(w1, w2, w3, w4, w5, w6, w7))


# ------------------------------------------------------ 3 differential kinematics


def eq28_df_dt(i, cq=None, sq=None) -> sp.Expr:
    """(28) df_i/dt as printed (the r term of the qdot_i coefficient reads + 2 l_a r sin q_i).
    (29) of the extracted text is only the last line of (28) repeated by the PDF
    extraction: '+ 2 l_a sin q_i cos th_i x + 2 l_a r sin q_i) qdot_i'."""
    cq, sq, ct, st = _trig(i, cq, sq)
    x, y, z, la, r = s.x, s.y, s.z, s.l_a, s.r
    return (
        (2 * x - (2 * r + 2 * la * cq) * ct) * s.xd
        + (2 * y - (2 * r + 2 * la * cq) * st) * s.yd
        + (2 * z + 2 * la * sq) * s.zd
        + (2 * la * cq * z + 2 * la * sq * st * y + 2 * la * sq * ct * x + 2 * la * r * sq)
        * s.qd[i]
    )


def eq31_33_Jp_row(i, cq=None, sq=None) -> sp.Matrix:
    """(31)-(33): row i of J_p."""
    cq, sq, ct, st = _trig(i, cq, sq)
    la, r = s.l_a, s.r
    return sp.Matrix(
        [
            [
                2 * s.x - (2 * r + 2 * la * cq) * ct,  # (31)
                2 * s.y - (2 * r + 2 * la * cq) * st,  # (32)
                2 * s.z + 2 * la * sq,  # (33)
            ]
        ]
    )


def eq34_Jq_ii(i, cq=None, sq=None) -> sp.Expr:
    """(34) J_q,ii = -2 l_a (cos q_i z + sin q_i sin th_i y + sin q_i cos th_i x + r sin q_i)."""
    cq, sq, ct, st = _trig(i, cq, sq)
    return -2 * s.l_a * (cq * s.z + sq * st * s.y + sq * ct * s.x + s.r * sq)


def eq35_Jq(cq=None, sq=None) -> sp.Matrix:
    """(35) J_q,ij = 0 for i != j, with the diagonal of (34)."""
    return sp.diag(
        *[
            eq34_Jq_ii(i, None if cq is None else cq[i], None if sq is None else sq[i])
            for i in range(3)
        ]
    )


def eq37_s(i, cq=None, sq=None) -> sp.Expr:
    """(37) s_i := 2 l_a (sin q_i qddot_i + cos q_i qdot_i^2)."""
    cq, sq, _, _ = _trig(i, cq, sq)
    return 2 * s.l_a * (sq * s.qdd[i] + cq * s.qd[i] ** 2)


def _acc_bracket(i, cq, sq):
    """The terms of (36) after the J_p pddot part (= the bracket of (39))."""
    cq, sq, ct, st = _trig(i, cq, sq)
    la, r = s.l_a, s.r
    x, y, z, xd, yd, zd = s.x, s.y, s.z, s.xd, s.yd, s.zd
    qd, qdd = s.qd[i], s.qdd[i]
    si = eq37_s(i, cq, sq)
    return (
        2 * zd**2
        + 4 * la * cq * qd * zd
        + 2 * la * (cq * qdd - sq * qd**2) * z
        + 2 * yd**2
        + 4 * la * sq * st * qd * yd
        + si * st * y
        + 2 * xd**2
        + 4 * la * sq * ct * qd * xd
        + si * ct * x
        - si * r
    )


def eq36_d2f_dt2(i, cq=None, sq=None) -> sp.Expr:
    """(36) d^2 f_i / dt^2 as printed (with s_i of (37))."""
    row = eq31_33_Jp_row(i, cq, sq)
    return (row * s.pdd)[0] + _acc_bracket(i, cq, sq)


def eq39_h(i, cq=None, sq=None) -> sp.Expr:
    """(39) h_i = -[ ... ] (right-hand side of J_p pddot = h, eq. (38))."""
    return -_acc_bracket(i, cq, sq)


# ------------------------------------------------ 4 validation trajectory (40)-(42)

T = s.t  # seconds; lengths in metres
_PI = sp.pi
eq40_x = sp.Rational(1, 4) * sp.sin(
    sp.Rational(1, 2) * (5 - sp.Rational(1, 10)) * 2 * _PI / 10 * T**2
    + sp.Rational(1, 10) * 2 * _PI * T
)  # (40)
eq41_y = sp.Rational(1, 4) * sp.sin(
    sp.Rational(1, 2) * (sp.Rational(1, 10) - 5) * 2 * _PI / 10 * T**2 + 5 * 2 * _PI * T
)  # (41)
eq42_z = sp.Rational(1, 10) * sp.sin(5 * 2 * _PI * T + _PI / 2) - sp.Rational(7556, 10000)  # (42)
TRAJECTORY_DURATION = 10.0  # s (Figure 6 and the chirp 0.1 -> 5 Hz over 10 s)

#: "recht hohe Geschwindigkeiten (bis zu 8 m/s) und Beschleunigungen (bis 24 m/s^2)"
CLAIMED_MAX_SPEED = 8.0  # m/s
CLAIMED_MAX_ACCELERATION = 24.0  # m/s^2
#: "Differenzen zwischen inverser und direkter Kinematik im Rahmen der numerischen
#: Genauigkeit des verwendeten Rechners"
CLAIM_ROUND_TRIP = "within the numerical precision of the computer"

# ------------------------------------------------------------- A fourth axis (43)

eq43_identity = sp.eye(3)  # (43) [phi, phid, phidd]^T = I_3x3 [q4, q4d, q4dd]^T

# ------------------------------------------------- B MAXIMA script (direct kinematics)

#: the script's lines `x: w[1]*z + w[2];` and `y: w[2]*z + w[3];` (w[k] is w_k)
maxima_x = w[0] * s.z + w[1]
maxima_y = w[1] * s.z + w[2]
