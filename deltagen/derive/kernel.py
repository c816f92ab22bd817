"""A kernel is one batched C function: its ports, its staged SymPy assignments and its
per-point status. Derivation modules build kernels; lowering turns them into C statements."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


@dataclass(frozen=True)
class Port:
    """One array argument of a kernel.

    ``symbols`` are the per-point scalars it carries, in column order. ``width`` is
    ``"axes"`` for arrays whose row length is the caller's axis count (3, or 4 with the
    fourth axis in the last column), otherwise the fixed row length.
    """

    name: str
    symbols: tuple
    doc: str
    unit: str
    width: object = "axes"
    fourth: sp.Symbol | None = None  # column 4 when axes == 4 (the fourth axis, eq. (43))
    ctype: str = "double"  # C element type; "uint8_t" for 0/1 flags (symbols are 0/1 ints)
    # the shape of the row-major array carried in the ``width`` values of a point (the
    # callers' shape of the output: (3, 3) for a Jacobian, (count, 4, 4) for a stack of
    # frames); None: a plain row
    matrix: tuple | None = None

    @property
    def shape(self) -> str:
        return "n x axes" if self.width == "axes" else f"n x {self.width}"


@dataclass(frozen=True)
class Angle:
    """An input angle whose cos and sin the kernel needs; evaluated in separate loops."""

    angle: sp.Symbol
    cos: sp.Symbol
    sin: sp.Symbol


@dataclass(frozen=True)
class Parameter:
    """A geometry value the kernel reads from the parameter struct (``index`` for arrays)."""

    symbol: sp.Symbol
    field: str
    index: int | None = None


@dataclass(frozen=True)
class Stage:
    """Assignments that depend only on inputs, parameters and earlier stages."""

    comment: str
    assignments: tuple  # ((Symbol, Expr), ...)


@dataclass(frozen=True)
class Kernel:
    name: str
    doc: str
    inputs: tuple  # (Port, ...)
    outputs: tuple  # (Port, ...); output symbols are assigned in the stages
    stages: tuple  # (Stage, ...)
    # integer-valued expression (Piecewise) of earlier symbols; lowering adds the
    # finite-output rule (codegen.lowering.guard_outputs): INVALID where an output is not
    # finite beyond the NaNs of a Piecewise (NaN, condition) branch, which the status explains
    status: sp.Expr
    parameters: tuple = ()  # (Parameter, ...)
    setup: tuple = ()  # (Stage, ...) evaluated once per call from the parameters
    angles: tuple = ()  # (Angle, ...)
    status_doc: str = ""
