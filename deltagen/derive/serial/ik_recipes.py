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
  ``number(x)``: a number taken as it is (a tolerance's scale);
* ``R_t`` (3 x 3, row-major nested), ``p_t`` (3): the target rotation and point;
* ``stage(comment)``, ``let(name, value)``, ``vec(name, v)``: name an intermediate value
  (``vec``: the three components ``name_x``, ``name_y``, ``name_z``);
* ``sqrt``, ``atan2(y, x)``, ``abs``, ``fmax(x, 0)``, ``at_least(x, c)``, ``at_most(x, c)``
  (fmax / fmin against a nonzero constant), ``select(cond, a, b)`` (a where cond, else b);
* conditions: ``ge``, ``le``, ``gt``, ``lt``, ``all(*conds)``, ``not_(c)``, ``true``;
* the named constants ``pi``, ``slack`` (how far a cosine may pass +-1, a square 0: 1e-9)
  and ``tiny`` (the floor of a divisor that may vanish);
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

Every structure of model.structure with a closed form has its recipe here (``RECIPES``):
``planar``, ``gantry``, ``stanford``, ``elbow_arm`` (4R and 6R) and ``parallel_triple``
(the UR family); docs/architecture.md, "The closed-form inverse kinematics". Two hooks let
a back end differ where the other has no use for a step: ``rigid_target`` (above) and
``wrist_flip(w5, w6, u, ref, B)``, whether the UR wrist's second branch may be taken as the
first turned by pi (the SymPy back end proves it from the constants to save atan2 calls;
the numpy back end computes every branch).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from deltagen.model.structure import (
    Elbow4R,
    GantryArm,
    ParallelTriple6R,
    PlanarArm,
    SphericalWrist6R,
    StanfordArm,
)

WRIST_SINGULAR = 1e-12  # wrist singular when |(R_w w6) x w4| is below this
SLACK = 1e-9  # ops.slack: how far a cosine may pass +-1 (a square 0) and still count as met
TINY = 1e-300  # ops.tiny: the floor of a divisor that may vanish


@dataclass(frozen=True)
class Angle:
    """An angle with its cosine and sine (values of the back end); ``h``: for an angle
    straight from atan2(y, x), hypot(x, y) (0 where the angle is undetermined)."""

    theta: Any
    c: Any
    s: Any
    h: Any = None

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
    condition that the closed form has a real solution. ``empty``: where the pose fixes
    the other branch (Paul's method), this one has no value at all (the numpy solver's
    closed_form gives NaN there, not the nearest real solution; None: never)."""

    values: tuple
    ok: Any
    empty: Any = None


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
    return Angle(ops.let(name, ops.select(ops.gt(h, 0), ops.atan2(y, x), 0)), c, s, h)


def named(ops, name, a: Angle) -> Angle:
    return Angle(ops.let(name, a.theta), ops.let(f"{name}_c", a.c), ops.let(f"{name}_s", a.s))


def constant_angle(ops, a: float) -> Angle:
    return Angle(ops.const(a), ops.const(math.cos(a)), ops.const(math.sin(a)))


def cos_sin_eq(ops, name, A, B, C):
    """A cos x + B sin x = C: the base angle atan2(B, A) and arccos(C / hypot(A, B)) as
    Angles (the roots are base +- arccos), and whether a real root exists (to 1e-9; the
    ratio clipped onto +-1 otherwise). A = B = 0 gives the ratio 0."""
    base = atan2(ops, f"{name}_base", B, A)
    r = ops.let(f"{name}_r", ops.sqrt(A * A + B * B))
    ratio = ops.let(
        f"{name}_ratio",
        ops.select(ops.gt(r, 0), C / ops.let(f"{name}_den", ops.at_least(r, ops.tiny)), 0),
    )
    ok = ops.let(f"ok_{name}", ops.le(ops.abs(ratio), 1 + ops.slack))
    kc = ops.let(f"{name}_kc", ops.at_most(ops.let(f"{name}_kc0", ops.at_least(ratio, -1)), 1))
    ks = ops.let(f"{name}_ks", ops.sqrt(1 - kc * kc))
    return base, Angle(ops.let(f"{name}_acos", ops.atan2(ks, kc)), kc, ks), ok


def turned_by_pi(ops, name, a: Angle, turned) -> Angle:
    """a + pi where ``turned`` holds, else a: the angle, cosine and sine negated, with no
    atan2, sqrt or division (the joint-limit fit wraps the angle). For a subproblem-1
    angle whose two components the caller has shown to be negated, atan2(-y, -x) =
    atan2(y, x) + pi."""
    return Angle(
        ops.let(f"{name}_pi", ops.select(turned, a.theta + ops.pi, a.theta)),
        ops.let(f"{name}_pi_c", ops.select(turned, -a.c, a.c)),
        ops.let(f"{name}_pi_s", ops.select(turned, -a.s, a.s)),
    )


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


def rotate_target_values(ops, axes, v):
    """R_G v = R_t R0^T v for a vector v of values."""
    u = [sum(ops.const(axes.R0[r, c]) * v[r] for r in range(3)) for c in range(3)]
    return tuple(dot(ops.R_t[r], u) for r in range(3))


def unrotate_target_values(ops, axes, v):
    """R_G^T v = R0 R_t^T v for a vector v of values."""
    y = [sum(ops.R_t[r][c] * v[r] for r in range(3)) for c in range(3)]
    return tuple(sum(ops.const(axes.R0[r, c]) * y[c] for c in range(3)) for r in range(3))


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


def undo(ops, axes, q1, tot, v):
    """(R1 R2)^T v: turned about w1 by -q1, then about w2 by -tot (joint 2's angle; for
    the elbow arms, whose axes 2 and 3 are parallel, q2 + q3)."""
    w = [ops.vconst(x) for x in axes.directions]
    v = rotate(w[0], q1.c, -q1.s, v)
    return rotate(w[1], tot.c, -tot.s, v)


def central_wrist(ops, s, tag, q1, th2, th3=None):
    """q4, q5, q6 for both wrist solutions (wrist_angles) of the rotation left after
    turning about axis 1 by q1 and about axis 2 by th2 + th3 (the elbow arm's parallel axes
    2 and 3) or, without th3, by th2 (the Stanford arm's joint 2): R_w = (R1 R2)^T R_G
    applied to w6 and the reference (eq. 13 of the EASY-ROB paper)."""
    axes = s.axes
    ops.stage(f"wrist, branch {tag}: the rotation left for joints 4-6 (eq. 13)")
    tot = th2 if th3 is None else named(ops, f"tot_{tag}", th2 + th3)
    qv = ops.vec(
        f"qv_{tag}", undo(ops, axes, q1, tot, rotate_target(ops, axes, axes.directions[5]))
    )
    qx = ops.vec(f"qx_{tag}", undo(ops, axes, q1, tot, rotate_target(ops, axes, s.wrist_ref)))
    return wrist_angles(ops, s, tag, qv, qx, ops.vconst(axes.directions[5]))


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
            branches[config] = (p1, p2, None, mine, ops.not_(mine))
    else:
        ops.stage("planar arm: law of cosines")
        kc, ks, bend, ok2 = cosine_law(ops, "planar", t, uu, vv)
        for config, sigma in zip(s.configs, s.bend_signs):
            ops.stage(f"planar arm, {config}")
            th1, th2 = elbow(ops, config, t, kc, ks, bend, sigma, uu, vv)
            roll = None if s.roll is None else named(ops, f"roll_{config}", yaw - th1 - th2)
            branches[config] = (th1, th2, roll, ok2, None)
    solutions = {}
    sign = s.signs
    for config, (th1, th2, roll, ok, empty) in branches.items():
        q: list = [None] * axes.n
        q[s.first] = th1.scaled(float(sign[s.first]))
        q[s.second] = th2.scaled(float(sign[s.second]))
        if roll is not None:
            q[s.roll] = roll.scaled(float(sign[s.roll]))
        if s.lift is not None:
            q[s.lift] = K(float(sign[s.lift])) * h
        solutions[config] = Branch(tuple(q), ok, empty)
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


def stanford(ops, s: StanfordArm, position_only=False) -> dict:
    """model.structure.StanfordArm: R R P and a central wrist W (G = e1 e2 e3 e4 e5 e6).
    e4 e5 e6 fix W and e3 slides it by q3 w3, so G W = e1 e2 (W + q3 w3); e1, e2 turn about
    axes through the shoulder point c and keep distances to c:

    1. q3: |W + q3 w3 - c|^2 = |G W - c|^2, a quadratic (``reach{p|m}``: + / - root);
    2. q1, q2: e1 e2 u = v, u = W + q3 w3 - c, v = G W - c (Paden-Kahan subproblem 2 about
       the meeting axes 1 and 2: z = alpha w1 + beta w2 +- g (w1 x w2), ``shoulder{p|m}``;
       q2 turns u into z, q1 z into v, subproblem 1 each);
    3. q4, q5, q6: the central wrist for R_w = (R1 R2)^T R_G (``noflip`` / ``flip``).

    2 x 2 x 2 = 8 branches. ``position_only`` does not apply (a 6R arm)."""
    axes, K = s.axes, ops.const
    w = [ops.vconst(x) for x in axes.directions]
    w1, w2, w3 = w[0], w[1], w[2]
    c = ops.vconst(s.shoulder)
    W0 = np.asarray(s.wrist, dtype=float) - np.asarray(s.shoulder, dtype=float)
    ops.stage("Stanford: wrist centre W_t = G W, v = W_t - c; q3 from |W + q3 w3 - c| = |v|")
    v = ops.vec("v_wc", add(move_point(ops, axes, s.wrist), scale(-1, c)))
    b = float(axes.directions[2] @ W0)
    disc = ops.let("disc3", K(b * b - W0 @ W0) + dot(v, v))
    ok3 = ops.let("ok_reach", ops.ge(disc, -ops.slack * ops.number(axes.scale**2)))
    root = ops.let("root3", ops.sqrt(ops.fmax(disc, 0)))
    c12 = float(axes.directions[0] @ axes.directions[1])
    n12 = np.cross(axes.directions[0], axes.directions[1])
    n12v, den, nn = ops.vconst(n12), K(c12 * c12 - 1.0), K(float(n12 @ n12))
    vw1 = ops.let("v_w1", dot(v, w1))
    solutions = {}
    for sg3, a in ((1, "p"), (-1, "m")):
        ops.stage(f"Stanford: reach{a}: q3, then subproblem 2 about axes 1 and 2")
        q3 = ops.let(f"q3_reach{a}", K(-b) + sg3 * root)
        u = ops.vec(f"u_reach{a}", add(ops.vconst(W0), scale(q3, w3)))
        w2u = dot(w2, u)
        alpha = ops.let(f"alpha12_reach{a}", (K(c12) * w2u - vw1) / den)
        beta = ops.let(f"beta12_reach{a}", (K(c12) * vw1 - w2u) / den)
        g2 = ops.let(
            f"g2_reach{a}",
            (dot(u, u) - alpha * alpha - beta * beta - 2 * K(c12) * alpha * beta) / nn,
        )
        ok2 = ops.let(f"ok_shoulder_reach{a}", ops.ge(g2, -ops.slack))
        g = ops.let(f"g_reach{a}", ops.sqrt(ops.fmax(g2, 0)))
        for sg2, e in ((1, "p"), (-1, "m")):
            tag = f"reach{a}_shoulder{e}"
            ops.stage(f"Stanford: {tag}: q2, q1 (Paden-Kahan 1 each)")
            z = ops.vec(
                f"z_{tag}", add(add(scale(alpha, w1), scale(beta, w2)), scale(sg2 * g, n12v))
            )
            q2 = sp1(ops, f"q2_{tag}", w2, u, z)
            q1 = sp1(ops, f"q1_{tag}", w1, z, v)
            for name, okw, q4, q5, q6 in central_wrist(ops, s, tag, q1, q2):
                solutions[name] = Branch((q1, q2, q3, q4, q5, q6), ops.all(ok3, ok2, okw))
    return solutions


def _arm(ops, s, W_t):
    """Joints 1-3 of an elbow arm placing the wrist point at W_t for the four arm branches
    (Miskolc paper eqs. 4-9): in the arm frame (ex, ey normal to axis 1, ez along it) the
    wrist point's height above axis 2's plane fixes yV, so xV = +-sqrt(px^2 + py^2 - yV^2)
    (``front`` / ``back``) and q1 = atan2(py, px) - atan2(yV, xV) (0 for the front branches,
    -pi for the back ones where the point lies on axis 1); then the planar 2R arm of axes 2
    and 3 (law of cosines, the bend of each branch). A list of (tag, q1, th2, th3, ok, t,
    ok1, sigma) per arm branch: th2, th3 the angles about axis 2, t the point in its plane,
    ok1 the reach of q1, sigma the bend sign."""
    axes, K = s.axes, ops.const
    n, configs = axes.n, tuple(s.configs)
    ops.stage("arm: the wrist point in the arm frame (ex, ey along axis 1's normal plane)")
    d = add(W_t, scale(-1, ops.vconst(axes.points[0])))
    px = ops.let("px", dot(d, ops.vconst(s.ex)))
    py = ops.let("py", dot(d, ops.vconst(s.ey)))
    pz = ops.let("pz", dot(d, ops.vconst(s.ez)))
    yV = ops.let("yV", (K(s.w2_offset) - K(s.cos_12) * pz) / K(s.sin_12))
    rad = ops.let("rad", px * px + py * py - yV * yV)
    ok1 = ops.let("ok_reach", ops.ge(rad, -ops.slack * ops.number(axes.scale**2)))
    r = ops.let("xV", ops.sqrt(ops.fmax(rad, 0)))
    on_axis = ops.let("on_axis", ops.lt(px * px + py * py, (1e-12 * axes.scale) ** 2))
    a = Angle(0, *direction(ops, "phi_p", py, px))
    uu, vv = s.upper, s.lower
    shoulders = {}
    for f in sorted(set(s.front.tolist()), reverse=True):
        tag = "front" if f > 0 else "back"
        ops.stage(f"shoulder q1, {tag} branches")
        xV = f * r
        # q1 = atan2(py, px) - atan2(yV, xV), one atan2 of the difference's cos and sin
        q1 = a - Angle(0, *direction(ops, f"phi_{tag}", yV, xV))
        home = 0.0 if f > 0 else -math.pi
        c1 = ops.let(f"q1_{tag}_c", ops.select(on_axis, K(math.cos(home)), q1.c))
        s1 = ops.let(f"q1_{tag}_s", ops.select(on_axis, 0, q1.s))
        q1 = Angle(ops.let(f"q1_{tag}", ops.select(on_axis, K(home), ops.atan2(s1, c1))), c1, s1)
        V = add(
            add(ops.vconst(axes.points[0]), scale(xV, ops.vconst(s.ex))),
            add(scale(yV, ops.vconst(s.ey)), scale(pz, ops.vconst(s.ez))),
        )
        t = tuple(
            ops.let(f"t{j + 1}_{tag}", dot(ops.vconst(s.plane[j]), V) - K(s.shoulder_xy[j]))
            for j in range(2)
        )
        kc, ks, bend, ok2 = cosine_law(ops, tag, t, uu, vv)
        shoulders[f] = (q1, t, kc, ks, bend, ok2)
    branches = []
    for index, config in enumerate(configs[:: len(configs) // 4]):
        f, sigma = float(s.front[index]), float(s.bend[index])
        q1, t, kc, ks, bend, ok2 = shoulders[f]
        tag = config.rsplit("_", 1)[0] if n == 6 else config
        ops.stage(f"elbow, branch {tag}: law of cosines, then q2 (ik_analytic._two_link)")
        th2, th3 = elbow(ops, tag, t, kc, ks, bend, sigma, uu, vv)
        ok = ops.let(f"ok_arm_{tag}", ops.all(ok1, ok2))
        branches.append((tag, q1, th2, th3, ok, t, ok1, sigma))
    return branches


def _roll(ops, s, tag, q1, tot):
    """The 4R arm's roll q4 about axis 4: (R1 R23)^T R_G x4 = Rot(w4, q4) x4."""
    ops.stage(f"roll, branch {tag}: q4 about axis 4")
    y = ops.vec(f"y4_{tag}", undo(ops, s.axes, q1, tot, rotate_target(ops, s.axes, s.roll_ref)))
    w4 = ops.vconst(s.axes.directions[3])
    return sp1(ops, f"q4_{tag}", w4, ops.vconst(s.roll_ref), y)


def _paul_4r(ops, s, tag, q1, t, ok1, sigma):
    """The 4R arm with the pose given: q2 + q3 from the direction of axis 4 (Paul's method),
    which fixes the elbow of the shoulder branch (the other elbow branch stays empty), then
    the roll q4."""
    K = ops.const
    w = [ops.vconst(x) for x in s.axes.directions]
    uu, vv = s.upper, s.lower
    ops.stage(f"arm, branch {tag}: q2 + q3 from the direction of axis 4 (Paul's method)")
    d4 = rotate(w[0], q1.c, -q1.s, rotate_target(ops, s.axes, s.axes.directions[3]))
    tot = sp1(ops, f"tot_{tag}", w[1], w[3], d4)
    z = (
        t[0] - (tot.c * K(vv[0]) - tot.s * K(vv[1])),
        t[1] - (tot.s * K(vv[0]) + tot.c * K(vv[1])),
    )
    a_uu = math.atan2(uu[1], uu[0])
    th2 = named(
        ops, f"paul2_{tag}", atan2(ops, f"phi2_{tag}", z[1], z[0]) - constant_angle(ops, a_uu)
    )
    th3 = named(ops, f"paul3_{tag}", tot - th2)
    c = math.atan2(vv[1], vv[0]) - a_uu
    sin_bend = th3.s * K(math.cos(c)) + th3.c * K(math.sin(c))
    mine = ops.let(f"mine_{tag}", ops.ge(sin_bend, 0) if sigma > 0 else ops.lt(sin_bend, 0))
    ok = ops.let(f"ok_paul_{tag}", ops.all(ok1, mine))
    q4 = _roll(ops, s, tag, q1, tot)
    return Branch((q1, th2, th3.scaled(s.sign3), q4), ok, ops.not_(mine))


def elbow_arm(ops, s: Elbow4R | SphericalWrist6R, position_only=False) -> dict:
    """model.structure.Elbow4R and SphericalWrist6R: joints 1-3 place the wrist point W
    (_arm), then the 6R arm's central wrist (central_wrist, ``noflip`` / ``flip``) or the 4R
    arm's roll; for the 4R arm with the pose given, q2 + q3 from the direction of axis 4
    (Paul's method, _paul_4r). ``position_only`` (4R): W is the target point, both elbows,
    the roll as near to the target's rotation as the arm allows."""
    axes = s.axes
    point_only = position_only and axes.n == 4
    ops.stage("wrist centre W_t = R_t R0^T (W - p0) + p_t")
    W_t = ops.vec("W_t", ops.p_t if point_only else move_point(ops, axes, s.wrist))
    solutions = {}
    for tag, q1, th2, th3, ok_arm, t, ok1, sigma in _arm(ops, s, W_t):
        if isinstance(s, Elbow4R):
            if point_only:
                q4 = _roll(ops, s, tag, q1, named(ops, f"tot_{tag}", th2 + th3))
                solutions[tag] = Branch((q1, th2, th3.scaled(s.sign3), q4), ok_arm)
            else:
                solutions[tag] = _paul_4r(ops, s, tag, q1, t, ok1, sigma)
            continue
        q3 = th3.scaled(s.sign3)
        for name, okw, q4, q5, q6 in central_wrist(ops, s, tag, q1, th2, th3):
            solutions[name] = Branch((q1, th2, q3, q4, q5, q6), ops.all(ok_arm, okw))
    return solutions


def parallel_triple(ops, s: ParallelTriple6R, position_only=False) -> dict:
    """model.structure.ParallelTriple6R: axes 2, 3, 4 parallel (direction u), axes 5 and 6
    meeting in P5 (the UR family; Pieper's class of three consecutive axes meeting at
    infinity), G = e1 e2 e3 e4 e5 e6. Rotations about axes parallel to u keep the u
    component of every point and vector and turn directions by the sum phi of their
    angles about u. With M = e1^-1 G:

    1. q1: P5 is fixed by e5 and e6, so u . (Rot(w1, -q1) (G P5 - o1)) = u . (P5 - o1):
       A cos q1 + B sin q1 = C, two roots (``shoulder{p|m}``: + / - arccos);
    2. q5: R_M w6 = Rot(u, phi) R5 w6, so u . Rot(w5, q5) w6 = u . R_M w6: two roots
       (``wrist{p|m}``);
    3. q6: Rot(w6, -q6) Rot(w5, -q5) u = R_M^T u (Paden-Kahan subproblem 1; 0 where both
       sides lie along w6: the wrist singularity);
    4. phi = angle about u of R_M R6^T R5^T; N = M e6^-1 e5^-1 = e2 e3 e4;
    5. elbow: e2 e3 carry the point o4 of axis 4 to N o4 (planar 2R arm normal to u, law of
       cosines, ``elbow{p|m}``); joint 4's angle about u is phi minus those of joints 2
       and 3. Joint i's angle is its angle about u times signs[i].

    2 x 2 x 2 = 8 branches. Where the back end shows the wrist flip from the constants
    (``ops.wrist_flip``), the second wrist branch's q6 and phi are the first's turned by
    pi, with no atan2 of their own. ``position_only`` does not apply (a 6R arm)."""
    axes, K = s.axes, ops.const
    d = axes.directions
    w = [ops.vconst(x) for x in d]
    o = [ops.vconst(x) for x in axes.points]
    u, w1, w5, w6 = ops.vconst(s.u), w[0], w[4], w[5]
    ops.stage("UR: q1 from u . Rot(w1, -q1) (G P5 - o1) = u . (P5 - o1)")
    v = ops.vec("v_p5", add(move_point(ops, axes, s.wrist), scale(-1, o[0])))
    w1v = ops.let("w1v", dot(w1, v))
    A = dot(add(v, scale(-w1v, w1)), u)
    B = -dot(cross(w1, v), u)
    C = K(s.u @ (s.wrist - axes.points[0])) - K(s.u @ d[0]) * w1v
    base1, acos1, ok1 = cos_sin_eq(ops, "q1eq", A, B, C)
    w6n = d[5] - (d[5] @ d[4]) * d[4]
    RGw6 = rotate_target(ops, axes, d[5])
    flip = ops.wrist_flip(w5, w6, u, ops.vconst(s.ref), K(np.cross(d[4], d[5]) @ s.u))
    sign = [float(x) for x in s.signs]
    solutions = {}
    for sg1, a in ((1, "p"), (-1, "m")):
        tag1 = f"s{a}"
        ops.stage(f"UR: shoulder{a}: q1, and q5 from u . Rot(w5, q5) w6 = u . R_M w6")
        q1 = named(ops, f"q1_{tag1}", base1 + acos1.scaled(sg1))
        h = dot(u, rotate(w1, q1.c, -q1.s, RGw6))
        base5, acos5, ok5 = cos_sin_eq(
            ops,
            f"q5eq_{tag1}",
            K(w6n @ s.u),
            K(np.cross(d[4], d[5]) @ s.u),
            h - K((s.u @ d[4]) * (d[4] @ d[5])),
        )
        b = ops.vec(f"b_{tag1}", unrotate_target_values(ops, axes, rotate(w1, q1.c, q1.s, u)))
        ref = ops.vconst(s.ref)
        first = None
        for sg5, c5 in ((1, "p"), (-1, "m")):
            tag = f"{tag1}w{c5}"
            ops.stage(f"UR: shoulder{a} wrist{c5}: q5, q6 (Paden-Kahan 1), phi, N o4")
            q5 = named(ops, f"q5_{tag}", base5 + acos5.scaled(sg5))
            if first is not None and flip:
                # the wrist flip (q5 -> -q5) turns q6 and phi by pi; where q6's two
                # components vanish (the exact wrist singularity, sin q5 = 0) atan2 gives
                # (0, 1, 0) for either sign and the vector phi is taken from is the same
                # for both q5: neither is turned, as the second branch's own atan2 calls
                # would have had it
                first_tag, first_mq6, first_phi = first
                turned = ops.gt(first_mq6.h, 0)
                mq6 = turned_by_pi(ops, f"mq6_{first_tag}", first_mq6, turned)
                q6 = mq6.scaled(-1)
                phi = turned_by_pi(ops, f"phi_{first_tag}", first_phi, turned)
            else:
                avec = ops.vec(f"a_{tag}", rotate(w5, q5.c, -q5.s, u))
                mq6 = sp1(ops, f"mq6_{tag}", w6, avec, b)
                q6 = mq6.scaled(-1)
                x = rotate(w6, q6.c, -q6.s, rotate(w5, q5.c, -q5.s, ref))
                x = ops.vec(f"x_{tag}", rotate(w1, q1.c, -q1.s, rotate_target_values(ops, axes, x)))
                phi = sp1(ops, f"phi_{tag}", u, ref, x)
                first = (tag, mq6, phi)
            y = add(rotate(w5, q5.c, -q5.s, add(o[3], scale(-1, o[4]))), o[4])
            y = add(rotate(w6, q6.c, -q6.s, add(y, scale(-1, o[5]))), o[5])
            y = ops.vec(f"y_{tag}", y)
            Gy = add(
                rotate_target_values(ops, axes, add(y, scale(-1, ops.vconst(axes.p0)))), ops.p_t
            )
            Ny = add(rotate(w1, q1.c, -q1.s, add(Gy, scale(-1, o[0]))), o[0])
            dy = add(Ny, scale(-1, o[1]))
            t = (
                ops.let(f"t1_{tag}", dot(dy, ops.vconst(s.plane[0]))),
                ops.let(f"t2_{tag}", dot(dy, ops.vconst(s.plane[1]))),
            )
            kc, ks, bend, ok2 = cosine_law(ops, tag, t, s.upper, s.lower)
            for sg2, e in ((1, "p"), (-1, "m")):
                etag = f"{tag}e{e}"
                ops.stage(f"UR: shoulder{a} elbow{e} wrist{c5}: joints 2, 3, 4")
                th2, th3 = elbow(ops, etag, t, kc, ks, bend, sg2, s.upper, s.lower)
                th4 = named(ops, f"th4_{etag}", phi - th2 - th3)
                angles = (
                    q1,
                    th2.scaled(sign[0]),
                    th3.scaled(sign[1]),
                    th4.scaled(sign[2]),
                    q5,
                    q6,
                )
                ok = ops.all(ok1, ok5, ok2)
                solutions[f"shoulder{a}_elbow{e}_wrist{c5}"] = Branch(angles, ok)
    return solutions


RECIPES = {
    PlanarArm: planar,
    GantryArm: gantry,
    StanfordArm: stanford,
    Elbow4R: elbow_arm,
    SphericalWrist6R: elbow_arm,
    ParallelTriple6R: parallel_triple,
}
