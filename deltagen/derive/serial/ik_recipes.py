"""The closed-form inverse kinematics of serial arms, written once and run by two back ends.

A *recipe* is the sequence of steps of one structure of :mod:`deltagen.model.structure`
(Paden-Kahan subproblems, the law of cosines, the wrist angles, the branches and their
conditions), written against a small back end ``ops`` and nothing else: no SymPy, no
array shapes. Two back ends run it:

* the SymPy back end of :mod:`deltagen.derive.serial.ik_closed_form` records every step as a
  named statement (``let``) in a stage (``stage``) of the ``ik_all`` kernel, with the
  structure's constants rounded (that module's docstring);
* the numpy back end of :mod:`deltagen.solve.analytic` evaluates the same steps on arrays
  over a batch of poses (one array per value and branch); names and stages are dropped and
  the constants are used as they are.

A value is whatever the back end's arithmetic works on (a SymPy expression, a numpy array, a
Python number); recipes combine values with ``+ - * /`` and call ``ops`` for the rest:

* ``const(x)``, ``vconst(v)``: a constant of the structure (a float, a 3-vector);
* ``R_t`` (3 x 3, row-major nested), ``p_t`` (3): the target rotation and point;
* ``stage(comment)``, ``let(name, value)``, ``vec(name, v)``: name an intermediate value
  (``vec``: the three components ``name_x``, ``name_y``, ``name_z``);
* ``sqrt``, ``atan2(y, x)``, ``abs``, ``fmax(x, 0)``, ``at_least(x, c)``, ``at_most(x, c)``
  (fmax / fmin against a nonzero constant), ``select(cond, a, b)`` (a where cond, else b);
* conditions: ``ge``, ``le``, ``gt``, ``lt``, ``all(*conds)``, ``not_(c)``, ``true``;
* the named constants ``slack`` (how far a cosine may pass +-1, a square 0: 1e-9) and
  ``tiny`` (the floor of a divisor that may vanish);
* ``rigid_target()``: whether the target rotation is orthonormal and right-handed (the 2R
  gantry head's check; the kernel tests it with the closed form, the numpy solver in its
  forward-kinematics check).

An angle is an :class:`Angle`: its value with its cosine and sine. Each angle comes from
``atan2(y, x)`` with cosine x / h and sine y / h (h = hypot(x, y); 1 and 0 where x = y = 0,
and the angle 0 there), and sums and differences use the addition theorems, so no step
calls cos or sin.

A recipe returns ``{config name: Branch}``: the joint values in joint order (an
:class:`Angle` for a revolute joint, a value for a prismatic one) and the condition that
the closed form has a real solution. The forward-kinematics check and the joint-limit fit
are the back ends' own (the kernel evaluates the symbolic chain, the numpy solver the
product of exponentials).

Ported: ``gantry`` (model.structure.GantryArm) and ``planar`` (PlanarArm). The elbow arms,
the UR family and the Stanford arm still have their steps written in both back-end modules
(docs/architecture.md, "The closed-form inverse kinematics"); the helpers below
(``cosine_law``, ``elbow``, ``wrist_angles``, ``sp1``) already serve the kernel's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from deltagen.model.structure import GantryArm, PlanarArm

WRIST_SINGULAR = 1e-12  # wrist singular when |(R_w w6) x w4| is below this


@dataclass(frozen=True)
class Angle:
    """An angle with its cosine and sine (values of the back end)."""

    theta: Any
    c: Any
    s: Any

    def __add__(self, other):
        return Angle(
            self.theta + other.theta,
            self.c * other.c - self.s * other.s,
            self.s * other.c + self.c * other.s,
        )

    def __sub__(self, other):
        return Angle(
            self.theta - other.theta,
            self.c * other.c + self.s * other.s,
            self.s * other.c - self.c * other.s,
        )

    def scaled(self, sign):
        """sign * angle for sign = +-1."""
        return Angle(sign * self.theta, self.c, sign * self.s)


@dataclass(frozen=True)
class Branch:
    """One configuration's joint values (joint order; Angle for a revolute joint) and the
    condition that the closed form has a real solution. ``fixed``: the pose fixes this
    branch (Paul's method), so where ``ok`` is false it has no value at all (the numpy
    solver's closed_form gives NaN there, not the nearest real solution)."""

    values: tuple
    ok: Any
    fixed: bool = False


# ------------------------------------------------------------------ vectors (3-tuples)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def scale(k, a):
    return tuple(k * x for x in a)


def rotate(w, c, s, v):
    """Rodrigues: v turned about the unit axis w by the angle with cosine c and sine s."""
    wv = dot(w, v)
    wxv = cross(w, v)
    return tuple(v[i] * c + wxv[i] * s + w[i] * wv * (1 - c) for i in range(3))


# ------------------------------------------------------------------------ angles


def direction(ops, name, y, x, with_h=False):
    """cos and sin of atan2(y, x): x / h and y / h (1 and 0 where x = y = 0); with
    ``with_h`` also h = hypot(x, y)."""
    h = ops.let(f"{name}_h", ops.sqrt(x * x + y * y))
    # the division is done whatever h is, so the selection below is a plain blend (a
    # division inside a ternary would be a branch)
    inv = ops.let(f"{name}_inv", 1 / ops.let(f"{name}_den", ops.at_least(h, ops.tiny)))
    c = ops.let(f"{name}_c", ops.select(ops.gt(h, 0), x * inv, 1))
    s = ops.let(f"{name}_s", ops.select(ops.gt(h, 0), y * inv, 0))
    return (c, s, h) if with_h else (c, s)


def atan2(ops, name, y, x) -> Angle:
    """atan2(y, x) with its cosine and sine (direction). Where x = y = 0 the angle is 0,
    as its cosine and sine (1, 0) say: atan2 of signed zeros gives 0 or +-pi, and at
    the UR's exact wrist singularity (q6 from two zero components) an output of pi with
    the cosine and sine of 0 used by the rest of the branch and its check was returned
    as valid while missing the pose by up to 2 m."""
    c, s, h = direction(ops, name, y, x, with_h=True)
    return Angle(ops.let(name, ops.select(ops.gt(h, 0), ops.atan2(y, x), 0)), c, s)


def named(ops, name, a: Angle) -> Angle:
    return Angle(ops.let(name, a.theta), ops.let(f"{name}_c", a.c), ops.let(f"{name}_s", a.s))


def constant_angle(ops, a: float) -> Angle:
    return Angle(ops.const(a), ops.const(math.cos(a)), ops.const(math.sin(a)))


def sp1(ops, name, w, a, b) -> Angle:
    """Paden-Kahan subproblem 1: the angle about the unit axis w turning the part of a
    normal to w into the direction of that of b (0 where either part is 0)."""
    a = add(a, scale(-dot(a, w), w))
    b = add(b, scale(-dot(b, w), w))
    return atan2(ops, name, dot(cross(a, b), w), dot(a, b))


# ------------------------------------------------------------------------ the target


def rotate_target(ops, axes, v):
    """R_G v = R_t R0^T v for a constant vector v (G = T_target T(0)^-1, the motion the
    joints must produce)."""
    u = ops.vconst(axes.R0.T @ np.asarray(v, dtype=float))
    return tuple(dot(ops.R_t[r], u) for r in range(3))


def move_point(ops, axes, x):
    """G x = R_t R0^T (x - p0) + p_t for a constant point x: where G carries it."""
    return add(rotate_target(ops, axes, np.asarray(x, dtype=float) - axes.p0), ops.p_t)


# ------------------------------------------------------------- planar 2R arm, wrist


def cosine_law(ops, tag, t, uu, vv):
    """The elbow of a planar 2R arm (first axis at the origin, second at uu, the point at
    uu + vv at q = 0) reaching t: cos and sin of the bend, its angle, and whether the law
    of cosines is met (to 1e-9; clipped onto the nearest real solution otherwise)."""
    K = ops.const
    lu, lv = float(np.hypot(*uu)), float(np.hypot(*vv))
    kappa = ops.let(
        f"kappa_{tag}", (t[0] * t[0] + t[1] * t[1] - K(lu * lu) - K(lv * lv)) / K(2 * lu * lv)
    )
    ok2 = ops.let(f"ok_elbow_{tag}", ops.le(ops.abs(kappa), 1 + ops.slack))
    kc = ops.let(f"kc_{tag}", ops.at_most(ops.let(f"kc0_{tag}", ops.at_least(kappa, -1)), 1))
    ks = ops.let(f"ks_{tag}", ops.sqrt(1 - kc * kc))
    bend = ops.let(f"bend_{tag}", ops.atan2(ks, kc))
    return kc, ks, bend, ok2


def elbow(ops, tag, t, kc, ks, bend, sigma, uu, vv):
    """First-axis and elbow angles (th1, th2) of the planar 2R arm for the bend sign sigma
    (sin of th2 + angle(vv) - angle(uu) has the sign of sigma): R(th1) (uu + R(th2) vv)
    = t."""
    K = ops.const
    a = math.atan2(uu[1], uu[0]) - math.atan2(vv[1], vv[0])
    bent = constant_angle(ops, a) + Angle(sigma * bend, kc, sigma * ks)
    th2 = named(ops, f"th3_{tag}", bent)
    m = (
        K(uu[0]) + th2.c * K(vv[0]) - th2.s * K(vv[1]),
        K(uu[1]) + th2.s * K(vv[0]) + th2.c * K(vv[1]),
    )
    th1 = atan2(ops, f"th2_{tag}", m[0] * t[1] - m[1] * t[0], m[0] * t[0] + m[1] * t[1])
    return th1, th2


def wrist_angles(ops, s, tag, qv, qx, w6, with_q6=True):
    """q4, q5 (Paden-Kahan subproblem 2) and q6 (subproblem 1) of a central wrist whose
    rotation takes the vector w6 (the last axis; a 2R head's tool axis) to qv and
    s.wrist_ref to qx, for both wrist solutions: a list of (name, ok, q4, q5, q6 or None),
    ``noflip`` (sin(q5 - q5s) <= 0) first. Where qv lies along w4 (the wrist singularity)
    q4 is 0 and q6 takes the whole turn."""
    K = ops.const
    w = [ops.vconst(x) for x in s.axes.directions]
    w4, w5 = w[3], w[4]
    c12 = s.cos_45
    s2 = 1.0 - c12 * c12
    b_p = s.cos_56
    a_q = dot(qv, w4)
    alpha = ops.let(f"alpha_{tag}", (a_q - K(c12 * b_p)) / K(s2))
    beta = ops.let(f"beta_{tag}", (K(b_p) - K(c12) * a_q) / K(s2))
    perp = cross(qv, w4)
    perp2 = ops.let(f"perp2_{tag}", dot(perp, perp))
    gam2 = ops.let(f"gam2_{tag}", perp2 / K(s2) - beta * beta)
    okw = ops.let(f"ok_wrist_{tag}", ops.ge(gam2, -ops.slack))
    gam = ops.let(f"gam_{tag}", ops.sqrt(ops.fmax(gam2, 0)))
    singular = ops.let(f"wrist_singular_{tag}", ops.lt(perp2, WRIST_SINGULAR**2))
    n45 = ops.vconst(s.normal_45)
    out = []
    for sig, flip in ((1, "noflip"), (-1, "flip")):
        name = f"{tag}_{flip}"
        ops.stage(f"wrist, branch {name}: q5, q4 (Paden-Kahan 2), q6")
        cvec = ops.vec(
            f"cw_{name}", add(add(scale(alpha, w4), scale(beta, w5)), scale(sig * gam, n45))
        )
        q5 = sp1(ops, f"q5_{name}", w5, w6, cvec)
        q4 = sp1(ops, f"q4r_{name}", w4, cvec, qv)
        q4 = named(
            ops,
            f"q4_{name}",
            Angle(
                ops.select(singular, 0, q4.theta),
                ops.select(singular, 1, q4.c),
                ops.select(singular, 0, q4.s),
            ),
        )
        q6 = None
        if with_q6:
            y = rotate(w5, q5.c, -q5.s, rotate(w4, q4.c, -q4.s, qx))
            q6 = sp1(ops, f"q6_{name}", w6, ops.vconst(s.wrist_ref), y)
        out.append((name, okw, q4, q5, q6))
    return out


# ------------------------------------------------------------------------ the recipes


def planar(ops, s: PlanarArm, position_only=False) -> dict:
    """model.structure.PlanarArm: a planar 2R arm for the point P in the plane normal to u
    (law of cosines, both elbows), the roll of a third revolute joint from the target yaw
    about u, a prismatic joint from the travel along u. With two revolute joints and the
    pose given, Paul's method (lecture slides 103-105): psi = q1 + q2 from the target
    rotation, q1 from the point of joint 2, q2 = psi - q1; the pose fixes the elbow, so
    only that branch is filled. ``position_only``: P is the target point, the law of
    cosines for both elbows."""
    K, axes = ops.const, s.axes
    u, E, A = s.u, s.plane, s.first_xy
    uu, vv = s.upper, s.lower
    ops.stage("planar arm: the point P, the travel along u and the yaw about u")
    P_t = ops.vec("P_t", ops.p_t if position_only else move_point(ops, axes, s.point))
    h = ops.let("travel", dot(add(P_t, scale(-1, ops.vconst(s.point))), ops.vconst(u)))
    t = tuple(ops.let(f"t{j + 1}", dot(ops.vconst(E[j]), P_t) - K(A[j])) for j in range(2))
    g1 = rotate_target(ops, axes, E[0])
    yaw = atan2(ops, "yaw", dot(g1, ops.vconst(E[1])), dot(g1, ops.vconst(E[0])))
    a_uu = math.atan2(uu[1], uu[0])
    c_uv = math.atan2(vv[1], vv[0]) - a_uu
    branches = {}
    if s.roll is None and not position_only:
        ops.stage("Paul's method (slides 103-105): psi from the rotation, q1 from joint 2")
        B_t = move_point(ops, axes, axes.points[s.second])
        tb = [dot(ops.vconst(E[j]), B_t) - K(A[j]) for j in range(2)]
        p1 = named(ops, "paul1", atan2(ops, "phi_b", tb[1], tb[0]) - constant_angle(ops, a_uu))
        p2 = named(ops, "paul2", yaw - p1)
        down = ops.let("elbow_down", ops.ge(p2.s * K(math.cos(c_uv)) + p2.c * K(math.sin(c_uv)), 0))
        for config, sigma in zip(s.configs, s.bend_signs):
            mine = down if sigma > 0 else ops.not_(down)
            branches[config] = (p1, p2, None, mine, True)
    else:
        ops.stage("planar arm: law of cosines")
        kc, ks, bend, ok2 = cosine_law(ops, "planar", t, uu, vv)
        for config, sigma in zip(s.configs, s.bend_signs):
            ops.stage(f"planar arm, {config}")
            th1, th2 = elbow(ops, config, t, kc, ks, bend, sigma, uu, vv)
            roll = None if s.roll is None else named(ops, f"roll_{config}", yaw - th1 - th2)
            branches[config] = (th1, th2, roll, ok2, False)
    solutions = {}
    sign = s.signs
    for config, (th1, th2, roll, ok, fixed) in branches.items():
        q: list = [None] * axes.n
        q[s.first] = th1.scaled(float(sign[s.first]))
        q[s.second] = th2.scaled(float(sign[s.second]))
        if roll is not None:
            q[s.roll] = roll.scaled(float(sign[s.roll]))
        if s.lift is not None:
            q[s.lift] = K(float(sign[s.lift])) * h
        solutions[config] = Branch(tuple(q), ok, fixed)
    return solutions


def gantry(ops, s: GantryArm, position_only=False) -> dict:
    """model.structure.GantryArm: slides 1-3, then a 3R wrist, a 2R head or one rotary
    axis (G = Trans(q1 w1 + q2 w2 + q3 w3) e4 ... en). The wrist from the target rotation
    alone (the slides turn nothing): the 3R wrist's q4, q5, q6 (``noflip`` / ``flip``), the
    2R head's q4, q5 for the tool axis (the same step with w6 replaced by the carried tool
    axis, the same two names), the rotary's q4 by subproblem 1 (``single``); then the tool
    point carried by the wrist (e_n first, then ... e4) and the slides by the 3 x 3
    inverse. ``position_only``: the head's tool axis as near as it goes (every branch
    counts as solved)."""
    axes = s.axes
    w = [ops.vconst(x) for x in axes.directions]
    o = [ops.vconst(x) for x in axes.points]
    n = axes.n
    ops.stage("gantry: the wrist rotation R_G = R_t R0^T on the carried vectors")
    branches = []
    if n == 4:
        y = ops.vec("qx_g", rotate_target(ops, axes, s.wrist_ref))
        q4 = sp1(ops, "q4_single", w[3], ops.vconst(s.wrist_ref), y)
        branches.append(("single", ops.true, (q4,)))
    else:
        qv = ops.vec("qv_g", rotate_target(ops, axes, s.carried))
        qx = ops.vec("qx_g", rotate_target(ops, axes, s.wrist_ref)) if n == 6 else None
        found = wrist_angles(ops, s, "g", qv, qx, ops.vconst(s.carried), with_q6=n == 6)
        rigid = ops.true if s.full_pose else ops.rigid_target()
        for name, okw, q4, q5, q6 in found:
            angles = (q4, q5) if q6 is None else (q4, q5, q6)
            ok = ops.true if position_only else ops.all(okw, rigid)
            branches.append((name[2:], ok, angles))
    solutions = {}
    for name, ok, angles in branches:
        ops.stage(f"gantry, branch {name}: the tool point carried by the wrist, the slides")
        g = ops.vconst(axes.p0)
        for i in range(n - 1, 2, -1):
            a = angles[i - 3]
            g = add(rotate(w[i], a.c, a.s, add(g, scale(-1, o[i]))), o[i])
        g = ops.vec(f"g_{name}", g)
        d = add(ops.p_t, scale(-1, g))
        slides = tuple(
            ops.let(f"slide{j + 1}_{name}", dot(ops.vconst(s.slide_inverse[j]), d))
            for j in range(3)
        )
        solutions[name] = Branch(slides + tuple(angles), ok)
    return solutions


RECIPES = {PlanarArm: planar, GantryArm: gantry}
