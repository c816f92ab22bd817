"""SymPy's C99 printer, extended with the few constructs the kernels need.

* ``AllFinite(a, b, ...)`` prints ``(isfinite(a) & isfinite(b) ...)``: SymPy would
  rewrite ``Not(Abs(a) <= big)`` to ``Abs(a) > big``, which is false for NaN.
* ``CopySign(a, b)`` prints C99 ``copysign(a, b)``.
* Piecewise prints as one-line nested ternaries (the stock printer spreads them over lines),
  or, when every branch is an integer constant, as branch-free 0/1 arithmetic.
* derive.functions' unevaluated Ge, Le, Gt, Lt, Fmax, Fmin, Fabs, Floor print as
  SymPy's relationals, Max, Min, Abs and floor.
* ``NearestInteger(x)`` prints C99 ``rint(x)`` (``rintf`` in float).
* ``FitAngle(a, lo, hi, lo_tol, hi_tol)`` prints the runtime's ``deltagen_fit_angle`` (its
  float twin ``deltagen_fit_anglef`` in float).
* Small integer powers are expanded to products (``pow(x, 3)`` is not folded by gcc
  without -ffast-math).
"""

from __future__ import annotations

import threading

import sympy as sp
from sympy.codegen.ast import float32, real
from sympy.codegen.rewriting import create_expand_pow_optimization
from sympy.printing.c import C99CodePrinter

expand_small_powers = create_expand_pow_optimization(4)

FLT_MIN = 1.1754943508222875e-38  # smallest normal binary32 (float.h's FLT_MIN)
FLT_MAX = 3.4028234663852886e38


class KernelPrinter(C99CodePrinter):
    # No math macros (M_SQRT2 and friends are POSIX, not C99). Set on the class: SymPy's
    # __init__ builds its table of macros (get_math_macros, 0.04 ms) for every printer
    # unless the class has one, even when the settings give {} (0.1 s of a 20-joint arm).
    math_macros: dict = {}

    def __init__(self, settings=None):
        super().__init__(settings)
        # derive.functions' unevaluated Max, Min, Abs, floor print as SymPy's own (the C
        # printer looks math functions, and which take a float suffix, up by class name)
        self._kf = dict(self._kf)
        for name, parent in (("Fmax", "Max"), ("Fmin", "Min"), ("Fabs", "Abs"), ("Floor", "floor")):
            self.known_functions[name] = self.known_functions[parent]
            self._kf[name] = self._kf[parent]

    def _print_Fabs(self, expr):
        return self._print_math_func(expr)

    def _print_Floor(self, expr):
        return self._print_math_func(expr)

    def _print_NearestInteger(self, expr):
        return "rint" + self._get_func_suffix(real) + "(" + self._print(expr.args[0]) + ")"

    def _print_FitAngle(self, expr):
        name = "deltagen_fit_angle" + self._get_func_suffix(real)  # deltagen_fit_anglef in float
        return name + "(" + ", ".join(self._print(a) for a in expr.args) + ")"

    def _print_AllFinite(self, expr):
        return "(" + " & ".join(f"isfinite({self._print(a)})" for a in expr.args) + ")"

    # Conditions combine 0/1 ints with bitwise operators: no short-circuit branches in the
    # per-point loop. (gcc 12 still does not vectorise that loop, -fopt-info-vec: "control
    # flow in loop", from the NaN-masking selects; clang 14 does. The cos/sin loops are the
    # vectorised ones.)
    def _print_Or(self, expr):
        return "(" + " | ".join(f"({self._print(a)})" for a in expr.args) + ")"

    def _print_And(self, expr):
        return "(" + " & ".join(f"({self._print(a)})" for a in expr.args) + ")"

    def _print_CopySign(self, expr):
        name = "copysign" + self._get_func_suffix(real)
        return f"{name}({self._print(expr.args[0])}, {self._print(expr.args[1])})"

    def _print_Not(self, expr):
        return f"!{self.parenthesize(expr.args[0], 100)}"

    def _print_Piecewise(self, expr):
        if expr.args[-1].cond != sp.true:
            raise ValueError("kernel Piecewise needs a final (value, True) branch")
        text = self._print(expr.args[-1].expr)
        if all(arg.expr.is_Integer for arg in expr.args):
            # Integer codes (statuses): first matching condition wins, written with 0/1
            # arithmetic instead of nested ternaries, which gcc turns into branches.
            for value, cond in reversed(expr.args[:-1]):
                c = self._print(cond)
                v = "" if value == 1 else f"{self._print(value)}*"
                rest = "" if text == "0" else f" + (1 - {c})*({text})"
                text = f"{v}{c}{rest}"
            return f"({text})"
        for value, cond in reversed(expr.args[:-1]):
            text = f"(({self._print(cond)}) ? {self._print(value)} : {text})"
        return text

    def _print_Relational(self, expr):
        # Relationals inside ternaries: always parenthesised, IEEE-faithful operators.
        return f"({self._print(expr.lhs)} {expr.rel_op} {self._print(expr.rhs)})"

    def _print_Pi(self, expr):
        # M_PI is POSIX, not C99: print the double nearest to pi (float: with its suffix).
        return "3.141592653589793" + self._get_literal_suffix(real)

    def _print_Exp1(self, expr):
        return "2.718281828459045" + self._get_literal_suffix(real)

    def _print_Float(self, expr):
        # float: a constant below the smallest normal float (the 1e-300 floor of a
        # division, derive/serial/ik_closed_form.py) would round to 0 (gcc: "floating
        # constant truncated to zero"); it becomes FLT_MIN, the same floor in float.
        if self._get_literal_suffix(real) and expr != 0:
            if abs(float(expr)) < FLT_MIN:
                return ("-" if expr < 0 else "") + "1.17549435e-38F"
            if abs(float(expr)) > FLT_MAX:
                raise ValueError(f"constant {expr} overflows float")
        return super()._print_Float(expr)

    def _print_Integer(self, expr):
        return str(int(expr))


#: The C floating types a kernel can be printed in: "double" (the generated modules) or
#: "float" (`deltagen export --float32`: sinf/cosf/sqrtf and F-suffixed literals, SymPy's
#: own float32 printing).
REAL_TYPES = ("double", "float")


#: one printer per real type and thread: a printer keeps no state between statements (SymPy's
#: doprint starts each with empty sets of what it could not print), and making one per
#: statement cost ~5 % of the lowering of an export (SymPy builds its tables in __init__)
_PRINTERS = threading.local()


def _printer(real_type: str) -> KernelPrinter:
    printers = _PRINTERS.__dict__
    if real_type not in printers:
        settings: dict = {}  # no math macros: KernelPrinter.math_macros
        if real_type == "float":
            settings["type_aliases"] = {real: float32}
        printers[real_type] = KernelPrinter(settings)
    return printers[real_type]


def to_c(expr, real_type: str = "double") -> str:
    """C99 text of one SymPy expression (small powers expanded first). No math macros
    (M_SQRT2 and friends are POSIX, not C99): constants print as expressions gcc folds."""
    if real_type not in REAL_TYPES:
        raise ValueError(f"real_type must be one of {REAL_TYPES}, not {real_type!r}")
    return _printer(real_type).doprint(expand_small_powers(sp.sympify(expr)))
