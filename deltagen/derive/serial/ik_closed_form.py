"""The closed-form inverse kinematics as a C kernel: ``ik_all``.

The arm's structure and every constant of its closed form come from
:func:`deltagen.model.structure.detect` (a :class:`~deltagen.model.structure.PlanarArm`,
:class:`~deltagen.model.structure.Elbow4R`, :class:`~deltagen.model.structure.SphericalWrist6R`
or, for the UR family, :class:`~deltagen.model.structure.ParallelTriple6R`, or the Stanford
arm's :class:`~deltagen.model.structure.StanfordArm`, or a gantry's
:class:`~deltagen.model.structure.GantryArm`); the numpy solver of
:mod:`deltagen.solve.analytic` is written on the same object. This module writes the same
closed forms as SymPy statements with the arm's constants compiled in, so the C core returns
every branch of a batch of poses in one call, like the forward kinematics. The steps of
each structure are its recipe in :mod:`deltagen.derive.serial.ik_recipes`, written once
for this module (the SymPy back end ``_SymPyOps``: each step a named statement) and the
numpy solver; that module and the numpy solver's docstring have the derivations. Here the
point is how they become straight-line code:

* every angle comes from ``atan2(y, x)``; its cosine and sine are taken as ``x / h`` and
  ``y / h`` (h = hypot(x, y)) instead of calling cos and sin on the result, and sums and
  differences of angles use the addition theorems. The rotations that undo q1 and q2 + q3,
  and the forward-kinematics check of every branch, then need no trigonometric calls.
  Where x = y = 0 the angle is 0 with cosine 1 and sine 0 (not atan2's 0 or +-pi of
  signed zeros), so that the value returned is the one the branch and its check used;
* each output angle takes one atan2 unless it is a sum, a negation or a turn by pi of
  others: for the UR family, where _SymPyOps.wrist_flip shows it from the arm's
  constants, the second wrist branch's q6 and phi (q2 + q3 + q4) are the first's + pi,
  so the UR5 kernel calls atan2 20 times per pose (q1 2, q5 2, q6 2, phi 2, the elbow
  bend 4 and q2 8; q3 = +-bend, q4 = phi - q2 - q3 and q5 = +-acos need none);
* the check evaluates the symbolic forward kinematics of the description (derive.Chain,
  not the product-of-exponentials model the solver is built on) with those cosines and
  sines, and compares it with the target: rotation entries and position / arm size within
  ``TOL`` (the numpy solver's default);
* the joint-limit fit is :func:`deltagen.geometry.limits.fit_limits` (for a revolute joint the
  runtime's deltagen_fit_angle, codegen/runtime/deltagen_limits.h), with
  its constants (``LIMIT_TOL``, ``SHIFTS``): wrap into [-pi, pi), shift by +-2 pi, +-4 pi
  where that fits the range, clip a value within LIMIT_TOL (1e-10) of a limit onto it.

Constants (joint axes, the wrist centre, the arm frame) are those of the structure object,
rounded to 13 significant digits, values below 1e-13 of the arm's size to zero, so that the
generated file does not depend on the last bit of a BLAS call (and exact zeros and ones
simplify the expressions).

Per pose: ``q`` (k x n, k branches in the order of the structure's ``configs``; NaN where the
branch has no real solution or misses the pose) and ``valid`` (k uint8 flags, 1 where the
branch is a solution inside the joint limits, else 0); status OK when some branch is
valid, UNREACHABLE when none is (out of reach, or only outside the limits), INVALID for a
non-finite input (all outputs NaN / 0).

Supported: every structure of model.structure with the full pose given (the numpy solver's
``solve`` default): ``spherical_wrist_6r``, ``parallel_triple_6r`` (the UR family) and
``stanford_rrp_6`` (8 branches each), ``elbow_4r`` (Paul's method for
q2 + q3, 4 branches), ``planar`` (2 branches; Paul's method for the 2R arm) and the
gantries ``gantry_wrist_3r`` (2 branches), ``gantry_head_2r`` (2 branches; the tool point
and the tool z axis are checked, with the target's rotation checked to be one) and
``gantry_rotary_1r`` (1 branch).
``position_only`` and other tolerances stay with the numpy solver.
"""

from __future__ import annotations

import math

import sympy as sp

from deltagen import status as st
from deltagen.derive.functions import AllFinite, Fabs, FitAngle, Floor, Fmax, Fmin, Ge, Gt, Le, Lt
from deltagen.derive.kernel import Kernel, Port, Stage
from deltagen.derive.serial.ik_recipes import (
    RECIPES,
    SLACK,
    TINY,
    Angle,
    add,
    cross,
    dot,
    rotate,
    scale,
)
from deltagen.geometry.limits import LIMIT_TOL, SHIFTS  # noqa: F401 (SHIFTS: in deltagen_limits.h)
from deltagen.model.structure import (
    GANTRY_KINDS,
    GantryArm,
    detect,
)

TOL = 1e-8  # accepted forward-kinematics residual (the numpy solver's default tol)
SUPPORTED = (
    "spherical_wrist_6r",
    "elbow_4r",
    "planar",
    "parallel_triple_6r",
    "stanford_rrp_6",
    *GANTRY_KINDS.values(),
)
_DIGITS = 13

#: The closed forms' named constants: in C, ``const double`` at the top of ik_all (the
#: ``setup`` of the kernel), so a statement reads ``<= ik_tol`` instead of a bare 1.0e-8.
ik_tol = sp.Symbol("ik_tol", positive=True)  # TOL: accepted forward-kinematics residual
ik_slack = sp.Symbol("ik_slack", positive=True)  # how far a cosine may pass +-1, a square 0
ik_tiny = sp.Symbol("ik_tiny", positive=True)  # the floor of a divisor that may vanish
_CONSTANTS = Stage(
    "named constants: ik_tol, the accepted forward-kinematics residual (relative to the "
    "arm's size for positions); ik_slack, how far a cosine may pass +-1 (or a square below "
    "0) and still count as met; ik_tiny, the floor of a divisor that may vanish",
    ((ik_tol, sp.Float(TOL)), (ik_slack, sp.Float(SLACK)), (ik_tiny, sp.Float(TINY))),
)


# Comparisons, Max, Min, Abs and floor of the kernel's values are derive.functions'
# unevaluated classes: the values are symbols SymPy cannot order, and asking it to try (on
# every construction, and again in every rebuild of the CSE) was most of the kernel's
# derivation and lowering time (cProfile, UR5: _fit_limits alone 16 s of 26). Same C.
_ge, _le, _gt, _lt, _max, _min = Ge, Le, Gt, Lt, Fmax, Fmin


# fmax / fmin against a nonzero constant as selects: the same value for every x (NaN
# gives the constant, as C99 fmax / fmin; x equal to the constant gives that value; the
# constant is nonzero, so no signed-zero choice arises), but gcc without -ffast-math calls
# libm's fmax / fmin for the functions (callgrind, UR5 ik_all: ~500 instructions per pose)
# and compiles the selects to maxsd / minsd.
def _at_least(x, c):
    """fmax(x, c) for a nonzero constant c."""
    return sp.Piecewise((x, _gt(x, c)), (c, True))


def _at_most(x, c):
    """fmin(x, c) for a nonzero constant c."""
    return sp.Piecewise((x, _lt(x, c)), (c, True))


def compiled_structure(desc):
    """The detected structure of ``desc`` (model.structure.detect) when it has a C kernel,
    else None."""
    found = detect(desc)
    if found is None or found.kind not in SUPPORTED:
        return None
    return found


# ------------------------------------------------------------------ building blocks


class _Tape:
    """Assignments recorded in stages; each ``let`` names a value (one C statement)."""

    def __init__(self):
        self.stages = []
        self._names = set()

    def stage(self, comment):
        self.stages.append((comment, []))

    def let(self, name, expr, alias=True):
        """A symbol for expr (a new statement), or with ``alias`` expr itself when it is
        already a symbol or true/false (a flag that simplified away needs no variable)."""
        expr = sp.sympify(expr)
        if alias and (isinstance(expr, sp.Symbol) or expr in (sp.true, sp.false)):
            return expr
        if name in self._names:  # one C variable per name
            raise ValueError(f"ik kernel: {name!r} assigned twice")
        self._names.add(name)
        sym = sp.Symbol(name, real=True)
        self.stages[-1][1].append((sym, expr))
        return sym

    def vec(self, name, v):
        return tuple(self.let(f"{name}_{axis}", e) for axis, e in zip("xyz", v))

    def as_stages(self):
        return [Stage(comment, tuple(a)) for comment, a in self.stages if a]


def _odd_under(vector, flip) -> bool:
    """Whether every component e of ``vector`` (polynomials in cosines and sines) has
    e(flip) = -e, coefficients equal to 1e-15 (the constants are rounded to 13 digits)."""
    for e in vector:
        total = sp.expand(e + sp.sympify(e).xreplace(flip))
        if total == 0:
            continue
        gens = sorted(total.free_symbols, key=str)
        if max(abs(float(c)) for c in sp.Poly(total, *gens).coeffs()) > 1e-15:
            return False
    return True


class _SymPyOps:
    """The SymPy back end of the recipes (derive/serial/ik_recipes.py): every ``let`` a
    statement on the tape, the constants rounded (_Constants), the target the kernel's
    input symbols."""

    true = sp.true
    pi = sp.Float(repr(math.pi), 17)
    slack = ik_slack
    tiny = ik_tiny
    sqrt = staticmethod(sp.sqrt)
    number = staticmethod(sp.Float)
    atan2 = staticmethod(sp.atan2)
    abs = staticmethod(Fabs)
    fmax = staticmethod(Fmax)
    at_least = staticmethod(_at_least)
    at_most = staticmethod(_at_most)
    ge, le, gt, lt = (staticmethod(f) for f in (Ge, Le, Gt, Lt))
    all = staticmethod(sp.And)
    not_ = staticmethod(sp.Not)

    def __init__(self, tape, const, R_t, p_t):
        self.tape, self.const, self.R_t, self.p_t = tape, const, R_t, p_t
        self.stage, self.let, self.vec, self.vconst = tape.stage, tape.let, tape.vec, const.vec

    @staticmethod
    def select(cond, a, b):
        return sp.Piecewise((a, cond), (b, True))

    @staticmethod
    def wrist_flip(w5, w6, u, ref, B) -> bool:
        """Whether the second wrist branch is the first turned by pi in q6 and phi, with
        no atan2 of its own (UR arms: 2 of the 4 q6 and 2 of the 4 phi atan2 calls per
        pose; ik_recipes.parallel_triple). Shown here, from the arm's constants, for every q5 and q6 at once:

        * B = u . (w5 x w6) = 0: the q5 equation's base angle is 0 or pi, so the second
          root has the cosine of the first and the sine negated (q5 -> -q5 about it);
        * the part of a = Rot(w5, -q5) u normal to w6 is odd in sin q5: then both vectors
          subproblem 1 turns into each other for q6 (a and b, b independent of q5) give
          negated components, and atan2(-y, -x) = atan2(y, x) + pi;
        * Rot(w6, -q6) Rot(w5, -q5) ref is odd under (sin q5, cos q6, sin q6) ->
          (-sin q5, -cos q6, -sin q6), i.e. under q5 -> -q5 with q6 -> q6 + pi: phi's
          subproblem 1 (about u, ref against that vector, rotated by constant and q1
          rotations, linear) gets negated components too.
        """
        if B != 0:
            return False
        c5, s5, c6, s6 = sp.symbols("c5 s5 c6 s6", real=True)
        a = rotate(w5, c5, -s5, u)
        normal = add(a, scale(-dot(a, w6), w6))
        if not _odd_under(normal, {s5: -s5}):
            return False
        x = rotate(w6, c6, -s6, rotate(w5, c5, -s5, ref))
        return _odd_under(x, {s5: -s5, c6: -c6, s6: -s6})

    def rigid_target(self):
        """The target's rotation is orthonormal and right-handed within TOL (x . x = y . y =
        z . z = 1, x . y = x . z = y . z = 0, x x y = z): the 2R head's check compares the
        tool axis only, so a target whose other columns are not a rotation's is refused
        here (solve.analytic._GantrySolver._reproduces)."""
        cols = [tuple(self.R_t[r][c] for r in range(3)) for c in range(3)]
        conds = []
        for i in range(3):
            for j in range(i, 3):
                target = 1 if i == j else 0
                conds.append(_le(Fabs(dot(cols[i], cols[j]) - target), ik_tol))
        xy = cross(cols[0], cols[1])
        conds.extend(_le(Fabs(xy[r] - cols[2][r]), ik_tol) for r in range(3))
        return self.tape.let("rigid_target", sp.And(*conds))


def _branch_legend(configs) -> str:
    """The key to the short branch tags of the C statement names, for arms whose configurations
    are named shoulder{p,m}_elbow{p,m}_wrist{p,m} (the UR solver: ``spwmep`` is shoulderp,
    wristm, elbowp)."""
    if not any(c.startswith("shoulderp") for c in configs):
        return ""
    return (
        " Statement names carry short branch tags: s, e, w = shoulder, elbow, wrist, each"
        " followed by p (the + root) or m (the - root); spwmep is shoulderp_elbowp_wristm."
    )


class _Constants:
    """Rounds the structure's numpy constants (module docstring)."""

    def __init__(self, scale):
        self.zero = 1e-13 * max(1.0, scale)

    def __call__(self, value):
        value = float(value)
        if abs(value) < self.zero:
            return sp.S.Zero
        for exact in (1, -1):
            if abs(value - exact) < 1e-13:
                return sp.Integer(exact)
        return sp.Float(f"{value:.{_DIGITS}g}", 17)

    def vec(self, v):
        return tuple(self(x) for x in v)


# ------------------------------------------------------------------------ the kernel


class IKKernelBuilder:
    """Builds the ``ik_all`` kernel of an arm from its detected structure
    (model.structure) and its Chain derivation."""

    def __init__(self, structure, chain):
        self.s = structure
        self.axes = structure.axes
        self.chain = chain
        self.n = structure.axes.n
        self.configs = tuple(structure.configs)
        self.const = _Constants(structure.axes.scale)
        self.tape = _Tape()
        self.T = tuple(
            sp.Symbol(f"Tt{r + 1}{c + 1}", real=True) for r in range(4) for c in range(4)
        )
        self.invalid = sp.Symbol("invalid")
        self.R_t = [[self.T[4 * r + c] for c in range(3)] for r in range(3)]
        self.p_t = tuple(self.T[4 * r + 3] for r in range(3))
        self.ops = _SymPyOps(self.tape, self.const, self.R_t, self.p_t)
        self._fits = {}  # (joint, value) -> _fit_limits' (value, inside)

    # -- shared steps --------------------------------------------------------------

    def _fit_limits(self, name, i, a):
        """geometry.limits.fit_limits for joint i: (value, inside). A revolute joint (a an
        Angle) is wrapped into [-pi, pi) and shifted by the multiples SHIFTS of 2 pi (+-2 pi,
        +-4 pi) where that fits its range: one call of the runtime's deltagen_fit_angle
        (codegen/runtime/deltagen_limits.h; 130 statements per branch of the UR5 when written
        out here, half of the kernel: its SymPy and compile time); a prismatic one (a its
        displacement) is only checked. Either is clipped onto a limit it passes by at most
        LIMIT_TOL."""
        lo, hi = (float(x) for x in self.s.qlim[i])
        revolute = isinstance(a, Angle)
        # branches sharing a joint value (the UR family's q1 in four branches, q5 and q6 in
        # two) share its fit: one deltagen_fit_angle call per distinct value
        key = (i, a.theta if revolute else sp.sympify(a))
        if key not in self._fits:
            self._fits[key] = self._fit_one(name, i, a, lo, hi, revolute)
        return self._fits[key]

    def _fit_one(self, name, i, a, lo, hi, revolute):
        tape = self.tape
        two_pi = 2 * sp.pi
        if not (math.isfinite(lo) or math.isfinite(hi)):
            if revolute:
                return tape.let(name, a.theta - two_pi * Floor((a.theta + sp.pi) / two_pi)), sp.true
            return tape.let(f"{name}_d", a), sp.true

        def const(v):
            return sp.Float(repr(v), 17) if math.isfinite(v) else (sp.oo if v > 0 else -sp.oo)

        lo_tol, hi_tol = lo - LIMIT_TOL, hi + LIMIT_TOL

        def inside(v):
            conds = []
            if math.isfinite(lo):
                conds.append(_ge(v, const(lo_tol)))
            if math.isfinite(hi):
                conds.append(_le(v, const(hi_tol)))
            return sp.And(*conds)

        if revolute:
            # the hand-written deltagen_fit_angle (codegen/runtime/deltagen_limits.h), the
            # statements below for one revolute joint; the value it returns is inside the
            # limits (to LIMIT_TOL) exactly when it fitted
            value = tape.let(
                name, FitAngle(a.theta, const(lo), const(hi), const(lo_tol), const(hi_tol))
            )
            return value, tape.let(f"{name}_in", inside(value))
        x = tape.let(f"{name}_d", a)
        fits = tape.let(f"{name}_in0", inside(x))
        clipped = x
        if math.isfinite(lo):
            clipped = _max(clipped, const(lo))
        if math.isfinite(hi):
            clipped = _min(clipped, const(hi))
        return tape.let(name, sp.Piecewise((clipped, fits), (x, True))), fits

    def _reproduces(self, name, angles):
        """Forward kinematics of the description at the branch's cosines and sines, compared
        with the target (solve.analytic.AnalyticSolver._reproduces)."""
        tape, chain = self.tape, self.chain
        sym = chain.sym
        mapping = {}
        for i, a in enumerate(angles):
            if isinstance(a, Angle):
                mapping[sym.cos[i]] = a.c
                mapping[sym.sin[i]] = a.s
            else:  # a prismatic joint's displacement
                mapping[sym.q[i]] = a
        tape.stage(f"check, branch {name}: forward kinematics at the solution")
        for stage in chain.stages:
            for s, expr in stage.assignments:
                mapping[s] = tape.let(f"{s}_{name}", sp.sympify(expr).xreplace(mapping))
        T = chain.T.xreplace(mapping)
        scale = self.axes.scale
        conds = []
        # a 2R gantry head reaches the tool z axis, not the rotation about it (GantryArm)
        columns = (2,) if getattr(self.s, "full_pose", True) is False else (0, 1, 2)
        for r in range(3):
            for c in columns:
                conds.append(_le(Fabs(T[r, c] - self.R_t[r][c]), ik_tol))
            conds.append(_le(Fabs(T[r, 3] - self.p_t[r]), ik_tol * sp.Float(scale)))
        return tape.let(f"hit_{name}", sp.And(*conds))

    # -- the kernel ----------------------------------------------------------------

    def build(self) -> Kernel:
        s, tape, n = self.s, self.tape, self.n
        tape.stage("status flag: a non-finite pose")
        invalid = tape.let("invalid", sp.Not(AllFinite(*self.T[:12])))
        solutions = RECIPES[type(s)](self.ops, s)
        q_out, valid_out, valid_flags = [], [], []
        for name in self.configs:
            angles, ok = solutions[name].values, solutions[name].ok
            hit = self._reproduces(name, angles)
            tape.stage(f"joint limits and outputs, branch {name}")
            values, inside = [], []
            for i, a in enumerate(angles):
                value, fits = self._fit_limits(f"fit_q{i + 1}_{name}", i, a)
                values.append(value)
                inside.append(fits)
            good = tape.let(f"ok_{name}", sp.And(ok, hit, AllFinite(*values), sp.Not(invalid)))
            valid = tape.let(f"valid_{name}", sp.And(good, *inside))
            valid_flags.append(valid)
            for i, v in enumerate(values):
                q_out.append(
                    tape.let(
                        f"out_q{i + 1}_{name}", sp.Piecewise((v, good), (sp.nan, True)), alias=False
                    )
                )
            valid_out.append(
                tape.let(
                    f"out_valid_{name}",
                    sp.Piecewise((sp.Integer(1), valid), (sp.Integer(0), True)),
                    alias=False,
                )
            )
        tape.stage("status")
        any_valid = tape.let("any_valid", sp.Or(*valid_flags))
        k = len(self.configs)
        doc = (
            f"Inverse kinematics in closed form, every branch: tool pose T -> q for the {k} "
            "configurations " + ", ".join(self.configs) + " (in this order)."
        ) + _branch_legend(self.configs)
        units, reaches = "[rad]", "reaches the pose"
        if isinstance(s, GantryArm):
            units = "[m for the slides 1-3, rad for the wrist]"
            if not s.full_pose:
                reaches = "reaches the tool point and the tool z axis"
                doc += (
                    " A 5-axis head: the tool point and the tool z axis are solved, the "
                    "rotation about the tool axis is free (not checked); T must be rigid."
                )
        return Kernel(
            name="ik_all",
            doc=doc,
            inputs=(
                Port(
                    "T", self.T, "tool pose, 4x4 row-major (rotation | position m)", "m", width=16
                ),
            ),
            outputs=(
                Port(
                    "q",
                    tuple(q_out),
                    f"{k} x {n} joint values per pose, branch after branch "
                    f"{units}; NaN where the branch has no real solution",
                    "rad",
                    width=k * n,
                    matrix=(k, n),
                ),
                Port(
                    "valid",
                    tuple(valid_out),
                    f"{k} flags per pose: 1 where the branch "
                    f"{reaches} within the joint limits, else 0",
                    "-",
                    width=k,
                    ctype="uint8_t",
                ),
            ),
            stages=tuple(tape.as_stages()),
            setup=(_CONSTANTS,),
            status=sp.Piecewise((st.INVALID, invalid), (st.OK, any_valid), (st.UNREACHABLE, True)),
            status_doc=(
                "OK (some branch is valid); UNREACHABLE (no branch reaches the pose "
                "within the joint limits); INVALID (a non-finite input; q NaN)"
            ),
        )


def ik_kernel(desc, chain) -> Kernel | None:
    """The ``ik_all`` kernel of ``desc``, or None when its structure has none in C."""
    found = compiled_structure(desc)
    if found is None:
        return None
    return IKKernelBuilder(found, chain).build()
