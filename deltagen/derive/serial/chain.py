"""Symbolic derivation of a serial arm's kinematics with SymPy.

T(q) = base . A_1(q_1) ... A_n(q_n) . tool (lecture slide 88, EASY-ROB eq. (1)), with the
link transforms of the description's convention (see description.py). The geometry is
compiled in as exact numbers where it is one: angles that are multiples of 15 degrees (up to
the rounding of a float, not of a file's printed digits) become exact multiples of pi, so
alpha = 0 / +-90 deg and zero lengths drop out of the
products before CSE sees them. Joint angles enter only through cos q_i and sin q_i
(cos(q + offset) is expanded with the offset's exact cosine and sine).

Staging keeps the expressions small: each frame F_i = F_{i-1} A_i is formed from the
symbols of F_{i-1}, and the Jacobian and its derivative are built from the joint axes
w_i, their points o_i and the tool point p (vector formulas, not symbolic derivatives):

  revolute i:  J_i = [w_i x (p - o_i); w_i]      prismatic i:  J_i = [w_i; 0]
  Jdot:  d/dt w_i = Omega_i x w_i,  Omega_i = sum_{j<i, revolute} w_j qd_j
         d/dt o_i = sum_{j<i} (revolute: w_j x (o_i - o_j); prismatic: w_j) qd_j
         d/dt p   = sum_j J_v,j qd_j
"""

from __future__ import annotations

import math
import sys

import sympy as sp

from deltagen.derive.kernel import Stage

# A constant is replaced by an exact value only when it is that value up to the rounding of
# a float (a few units in the last place): the float math.pi / 2, or cos(pi / 2) = 6e-17
# left by turning a frame in floats, is exact by construction. A file's rounded digits are
# kept as written: pi printed as 3.14159265359 (2e-13 from pi) stays that number, so that
# the compiled core computes what the reference backend and other libraries compute from
# the same file. The structure detection (model/structure.py) never relied on this: it
# reads the geometry with its own tolerances.
_ROUNDING = 4 * sys.float_info.epsilon


def _is(value: float, exact: float) -> bool:
    """``value`` equals the float ``exact`` up to a few units in the last place."""
    return abs(value - exact) <= _ROUNDING * max(1.0, abs(exact))


def exact_angle(value: float) -> sp.Expr:
    """Multiples of pi/12 (15 deg) become exact when ``value`` is one up to float rounding;
    other angles stay floats."""
    k = round(value / (math.pi / 12))
    if _is(value, k * math.pi / 12):
        return sp.pi * sp.Rational(k, 12)
    return sp.Float(repr(value), 17)


def exact_length(value: float) -> sp.Expr:
    if value == 0.0:
        return sp.S.Zero
    return sp.Float(repr(value), 17)


def exact_number(value: float) -> sp.Expr:
    """Entries of base/tool matrices: 0, +-1 and +-1/2 exact up to float rounding, else
    floats."""
    for candidate in (0, 1, -1, sp.Rational(1, 2), -sp.Rational(1, 2)):
        if _is(value, float(candidate)):
            return sp.sympify(candidate)
    return sp.Float(repr(float(value)), 17)


def cos_sin(angle: sp.Expr):
    return sp.cos(angle), sp.sin(angle)


def rot(axis: str, c, s) -> sp.Matrix:
    """Homogeneous rotation about x, y or z given its cosine c and sine s."""
    if axis == "x":
        R = [[1, 0, 0], [0, c, -s], [0, s, c]]
    elif axis == "y":
        R = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    else:
        R = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    M = sp.eye(4)
    M[:3, :3] = sp.Matrix(R)
    return M


def trans(x=0, y=0, z=0) -> sp.Matrix:
    M = sp.eye(4)
    M[0, 3], M[1, 3], M[2, 3] = x, y, z
    return M


class ArmSymbols:
    """Per-point symbols of an n-joint arm."""

    def __init__(self, n: int):
        self.n = n
        self.q = sp.symbols(f"q1:{n + 1}", real=True)
        self.qd = sp.symbols(f"qd1:{n + 1}", real=True)
        self.cos = sp.symbols(f"cos_q1:{n + 1}", real=True)
        self.sin = sp.symbols(f"sin_q1:{n + 1}", real=True)


def joint_motion(joint, i: int, sym: ArmSymbols):
    """(cos, sin) of the joint angle (revolute) or the displacement (prismatic) of joint i,
    with its offset folded in exactly; a reversed joint (sign -1) enters as -q_i + offset_i
    (cos(-q) = cos q, sin(-q) = -sin q)."""
    if joint.revolute:
        co, so = cos_sin(exact_angle(joint.offset))
        c, s = sym.cos[i], sym.sin[i] * int(joint.sign)
        return (sp.expand(c * co - s * so), sp.expand(s * co + c * so)), None
    return None, int(joint.sign) * sym.q[i] + exact_length(joint.offset)


def link_transform(desc, i: int, sym: ArmSymbols):
    """(A_i, P_i, axis): the link transform of joint i, the part P_i of A_i before the
    joint's motion (its axis lives in frame F_{i-1} P_i) and that axis ('x', 'y', 'z')."""
    j = desc.joints[i]
    cs, disp = joint_motion(j, i, sym)
    conv = desc.convention
    if conv == "universal":
        motion = rot(j.axis, *cs) if j.revolute else trans(**{j.axis: disp})
        fixed = (
            trans(exact_length(j.tx), exact_length(j.ty), exact_length(j.tz))
            * rot("x", *cos_sin(exact_angle(j.rx)))
            * rot("y", *cos_sin(exact_angle(j.ry)))
            * rot("z", *cos_sin(exact_angle(j.rz)))
        )
        return motion * fixed, sp.eye(4), j.axis
    if j.revolute:
        rz = rot("z", *cs)
        tz = trans(z=exact_length(j.d))
    else:
        rz = rot("z", *cos_sin(exact_angle(j.theta)))
        tz = trans(z=disp)
    tx = trans(x=exact_length(j.a))
    rx = rot("x", *cos_sin(exact_angle(j.alpha)))
    if conv == "standard":  # Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha)
        return rz * tz * tx * rx, sp.eye(4), "z"
    # modified (Craig): Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i) Trans_z(d_i)
    pre = rx * tx
    return pre * rz * tz, pre, "z"


def _symbolic_frame(name: str, M: sp.Matrix):
    """Replace the non-constant entries of a 4x4 frame by symbols; return (frame of
    symbols/constants, assignments)."""
    F = sp.zeros(4, 4)
    assignments = []
    for r in range(3):
        for c in range(4):
            value = sp.expand(M[r, c])
            if value.is_Symbol or (-value).is_Symbol:  # a copy: no new variable
                F[r, c] = value
            elif value.free_symbols:
                sym = sp.Symbol(f"{name}_{r + 1}{c + 1}", real=True)
                assignments.append((sym, value))
                F[r, c] = sym
            else:
                F[r, c] = value
    F[3, :] = sp.Matrix([[0, 0, 0, 1]])
    return F, assignments


def numeric_matrix(M) -> sp.Matrix:
    return sp.Matrix(4, 4, lambda r, c: exact_number(float(M[r][c])))


class Chain:
    """The staged derivation of one arm: frames, joint axes, tool point."""

    def __init__(self, desc):
        self.desc = desc
        n = desc.n
        self.sym = ArmSymbols(n)
        self.stages = []
        self.frames = [numeric_matrix(desc.base)]  # F_0 = base
        self.axes, self.points = [], []
        for i in range(n):
            A, P, axis = link_transform(desc, i, self.sym)
            prev = self.frames[-1]
            pre = prev * P
            col = "xyz".index(axis)
            # joint axis w_i and a point o_i on it, in the base frame
            # (a reversed joint moves about / along minus that column)
            w = sp.Matrix([sp.expand(int(desc.joints[i].sign) * pre[r, col]) for r in range(3)])
            o = sp.Matrix([sp.expand(pre[r, 3]) for r in range(3)])
            self.axes.append(w)
            self.points.append(o)
            F, assignments = _symbolic_frame(f"F{i + 1}", prev * A)
            self.stages.append(
                Stage(
                    f"frame {i + 1}: F_{i + 1} = F_{i} A_{i + 1} ({desc.convention} convention)",
                    tuple(assignments),
                )
            )
            self.frames.append(F)
        T, assignments = _symbolic_frame("T", self.frames[-1] * numeric_matrix(desc.tool))
        self.stages.append(Stage("tool frame T = F_n . tool", tuple(assignments)))
        self.frames.append(T)
        self.T = T
        self.p = sp.Matrix([T[r, 3] for r in range(3)])

    def jacobian(self) -> sp.Matrix:
        """Geometric Jacobian in the base frame, rows vx vy vz wx wy wz."""
        n = self.desc.n
        J = sp.zeros(6, n)
        for i, joint in enumerate(self.desc.joints):
            w, o = self.axes[i], self.points[i]
            if joint.revolute:
                v = w.cross(self.p - o)
                J[:3, i], J[3:, i] = v, w
            else:
                J[:3, i] = w
        return J

    def jacobian_dot(self, J_symbols: sp.Matrix) -> sp.Matrix:
        """dJ/dt along qd from the vector formulas (module docstring); J_symbols holds the
        symbols of J's entries so the tool velocity can reuse them."""
        n, qd = self.desc.n, self.sym.qd
        p_dot = sp.zeros(3, 1)
        for j in range(n):
            p_dot += J_symbols[:3, j] * qd[j]
        Jd = sp.zeros(6, n)
        omega = sp.zeros(3, 1)  # angular velocity of the frame carrying joint i's axis
        for i, joint in enumerate(self.desc.joints):
            w, o = self.axes[i], self.points[i]
            o_dot = sp.zeros(3, 1)
            for j in range(i):
                if self.desc.joints[j].revolute:
                    o_dot += self.axes[j].cross(o - self.points[j]) * qd[j]
                else:
                    o_dot += self.axes[j] * qd[j]
            w_dot = omega.cross(w)
            if joint.revolute:
                Jd[:3, i] = w_dot.cross(self.p - o) + w.cross(p_dot - o_dot)
                Jd[3:, i] = w_dot
                omega = omega + w * qd[i]
            else:
                Jd[:3, i] = w_dot
        return Jd
