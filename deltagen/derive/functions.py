"""The few SymPy functions the derivations use beyond SymPy's own, each of which the C
printer (codegen/printer.py) prints as one C99 construct."""

from __future__ import annotations

import sympy as sp
from sympy.logic.boolalg import BooleanFunction


class AllFinite(BooleanFunction):
    """True when every argument is finite (neither NaN nor infinite)."""

    @classmethod
    def eval(cls, *args):
        return None


class CopySign(sp.Function):
    """C99 copysign(magnitude, sign)."""

    nargs = 2


# -- SymPy's comparisons, max, min, abs and floor, never evaluated ------------------------
#
# The closed-form IK kernel (derive/serial/ik_closed_form.py) compares, clips and wraps
# values that are symbols SymPy cannot order. Built with SymPy's own classes, every
# construction -- in the derivation and again in every rebuild during the CSE of
# codegen/lowering.py -- asks the assumption system whether it can decide the comparison
# (Max and Min look for comparable arguments): cProfile of the UR5's kernel, 2/3 of its
# derivation and lowering time. These subclasses build the same expression without asking;
# the C printer prints them as their SymPy parent (same C text).


class _Unevaluated:
    """Relational methods that SymPy's own classes answer from a table keyed by class
    (reversed, reversedsign, negated), for the four subclasses below."""

    _REVERSED = _NEGATED = ""

    def __new__(cls, lhs, rhs, **options):
        options["evaluate"] = False
        return super().__new__(cls, lhs, rhs, **options)  # type: ignore[misc]

    @property
    def reversed(self):
        return _RELATIONS[self._REVERSED](self.rhs, self.lhs)

    @property
    def reversedsign(self):
        return _RELATIONS[self._REVERSED](-self.lhs, -self.rhs)

    @property
    def negated(self):
        return _RELATIONS[self._NEGATED](self.lhs, self.rhs)


class Ge(_Unevaluated, sp.GreaterThan):
    """a >= b, unevaluated."""

    _REVERSED, _NEGATED = "Le", "Lt"


class Le(_Unevaluated, sp.LessThan):
    """a <= b, unevaluated."""

    _REVERSED, _NEGATED = "Ge", "Gt"


class Gt(_Unevaluated, sp.StrictGreaterThan):
    """a > b, unevaluated."""

    _REVERSED, _NEGATED = "Lt", "Le"


class Lt(_Unevaluated, sp.StrictLessThan):
    """a < b, unevaluated."""

    _REVERSED, _NEGATED = "Gt", "Ge"


_RELATIONS = {"Ge": Ge, "Le": Le, "Gt": Gt, "Lt": Lt}


class Fmax(sp.Max):
    """C99 fmax(a, b), unevaluated."""

    def __new__(cls, *args, **assumptions):
        assumptions["evaluate"] = False
        return super().__new__(cls, *args, **assumptions)


class Fmin(sp.Min):
    """C99 fmin(a, b), unevaluated."""

    def __new__(cls, *args, **assumptions):
        assumptions["evaluate"] = False
        return super().__new__(cls, *args, **assumptions)


class Fabs(sp.Abs):
    """C99 fabs(x), unevaluated."""

    @classmethod
    def eval(cls, arg):
        return None


class Floor(sp.floor):
    """C99 floor(x), unevaluated."""

    @classmethod
    def eval(cls, arg):
        return None


class NearestInteger(sp.Function):
    """C99 rint(x): x rounded to an integer in the current rounding mode (to nearest, ties
    to even, unless a caller changed it); gcc vectorises it where floor under -std=c99
    stops the loop. Never evaluated."""

    nargs = 1

    @classmethod
    def eval(cls, arg):
        return None


class FitAngle(sp.Function):
    """A revolute joint's value fitted into its limits, (angle, lo, hi, lo - LIMIT_TOL,
    hi + LIMIT_TOL): the hand-written C deltagen_fit_angle (codegen/runtime/
    deltagen_limits.h; geometry.limits.fit_limits for one joint). Never evaluated."""

    nargs = 5

    @classmethod
    def eval(cls, *args):
        return None
