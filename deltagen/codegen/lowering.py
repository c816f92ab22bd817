"""Kernel → C statements: common-subexpression elimination per stage (sympy.cse) and
printing (SymPy's C99 printer). The result is plain data for the Jinja templates."""

from __future__ import annotations

from dataclasses import dataclass, replace

import sympy as sp
from sympy.core.relational import Relational
from sympy.logic.boolalg import BooleanFunction

from deltagen.codegen.printer import to_c
from deltagen.derive.kernel import Kernel, Stage


@dataclass(frozen=True)
class Statement:
    name: str
    expr: str
    ctype: str = "double"


def _is_integer_code(expr) -> bool:
    """A Piecewise whose every branch is an integer (a flag or code, printed as 0/1
    arithmetic): an int in C."""
    return isinstance(expr, sp.Piecewise) and all(arg.expr.is_Integer for arg in expr.args)


def _statement(sym, expr) -> Statement:
    boolean = isinstance(expr, (Relational, BooleanFunction)) or _is_integer_code(expr)
    return Statement(str(sym), to_c(expr), "int" if boolean else "double")


@dataclass(frozen=True)
class LoweredStage:
    comment: str
    statements: tuple  # (Statement, ...): temporaries first, then the stage's own symbols


@dataclass(frozen=True)
class LoweredKernel:
    kernel: Kernel
    stages: tuple
    status: str
    operation_count: int


def _dependency_order(assignments) -> list:
    """Temporaries first, then the stage's own symbols, except that a statement using a
    symbol of the same stage waits until that symbol is assigned (stages built step by
    step, like the closed-form IK, name intermediate values and use them at once)."""
    own = {sym for sym, _ in assignments}
    defined, ordered, pending = set(), [], list(assignments)
    while pending:
        waiting = []
        for sym, expr in pending:
            if (sp.sympify(expr).free_symbols & own) <= defined:
                ordered.append((sym, expr))
                defined.add(sym)
            else:
                waiting.append((sym, expr))
        if len(waiting) == len(pending):
            raise ValueError("circular assignments in a kernel stage")
        pending = waiting
    return ordered


def lower_stage(index: int, stage, prefix: str) -> tuple[LoweredStage, int]:
    names = [sym for sym, _ in stage.assignments]
    exprs = [sp.sympify(e) for _, e in stage.assignments]
    temporaries = sp.numbered_symbols(f"{prefix}{index}_")
    replacements, reduced = sp.cse(exprs, symbols=temporaries, order="canonical")
    ordered = _dependency_order(list(replacements) + list(zip(names, reduced)))
    statements = [_statement(s, e) for s, e in ordered]
    ops = sum(sp.count_ops(e) for _, e in replacements) + sum(sp.count_ops(e) for e in reduced)
    return LoweredStage(stage.comment, tuple(statements)), int(ops)


def keep_needed(needed: set, assignments) -> list:
    """The assignments that ``needed`` depends on, transitively, in their order; ``needed``
    grows by the symbols they use."""
    kept = []
    for sym, expr in reversed(assignments):
        if sym in needed:
            kept.append((sym, expr))
            needed |= sp.sympify(expr).free_symbols
    return list(reversed(kept))


def prune(kernel: Kernel) -> Kernel:
    """Drop assignments nothing needs (transitively from the outputs and the status)."""
    needed = set(sp.sympify(kernel.status).free_symbols)
    for port in kernel.outputs:
        needed |= set(port.symbols)
        if port.fourth is not None:
            needed.add(port.fourth)
    kept_stages = []
    for stage in reversed(kernel.stages):
        kept = keep_needed(needed, stage.assignments)
        if kept:
            kept_stages.append(Stage(stage.comment, tuple(kept)))
    return replace(kernel, stages=tuple(reversed(kept_stages)))


def lower(kernel: Kernel) -> LoweredKernel:
    kernel = prune(kernel)
    stages, total = [], 0
    for index, stage in enumerate(kernel.stages):
        lowered, ops = lower_stage(index, stage, prefix="t")
        stages.append(lowered)
        total += ops
    return LoweredKernel(kernel, tuple(stages), to_c(kernel.status), total)
