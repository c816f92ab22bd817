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
