"""Kernel → C statements: the finite-output rule (:func:`guard_outputs`), common-subexpression
elimination per stage (sympy.cse) and printing (SymPy's C99 printer). The result is plain
data for the Jinja templates."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import sympy as sp
from sympy.core.relational import Relational
from sympy.logic.boolalg import BooleanFunction

from deltagen import status as st
from deltagen.codegen.printer import to_c
from deltagen.derive.functions import AllFinite
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


def _statement(sym, expr, real_type: str = "double") -> Statement:
    boolean = (
        isinstance(expr, (Relational, BooleanFunction))
        or _is_integer_code(expr)
        or bool(sym.is_integer)  # a symbol declared integer (a 0/1 flag output)
    )
    return Statement(str(sym), to_c(expr, real_type), "int" if boolean else "double")


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
    real_type: str = "double"  # the C type the statements were printed for


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


def _reduce(index: int, assignments: tuple, prefix: str) -> tuple[tuple, int]:
    """The stage's assignments after CSE, in dependency order, and their operation count."""
    names = [sym for sym, _ in assignments]
    exprs = [sp.sympify(e) for _, e in assignments]
    temporaries = sp.numbered_symbols(f"{prefix}{index}_")
    replacements, reduced = sp.cse(exprs, symbols=temporaries, order="canonical")
    ordered = _dependency_order(list(replacements) + list(zip(names, reduced)))
    ops = sum(sp.count_ops(e) for _, e in replacements) + sum(sp.count_ops(e) for e in reduced)
    return tuple(ordered), int(ops)


#: Stages whose CSE is kept (the SymPy expressions of each live as long as the process).
#: The same stages are lowered again for another real type (an export in double and then
#: in float: one CSE, only the printing differs) and by the kernels of one module that
#: share a stage. Counted: an export of the Puma 560 in double then float (the bundled
#: robot with the most stages) uses 77 distinct stages and reuses every one within them;
#: one `deltagen generate` run uses 636, and the 43 reuses this bound drops there (the
#: same chain in a TOML and a URDF arm, rendered 130+ stages apart) cost 0.1 s of its 40 s.
REDUCED_STAGES_KEPT = 128
_reduce_cached = lru_cache(maxsize=REDUCED_STAGES_KEPT)(_reduce)


def lower_stage(
    index: int, stage, prefix: str, real_type: str = "double"
) -> tuple[LoweredStage, int]:
    assignments = tuple(stage.assignments)
    try:
        ordered, ops = _reduce_cached(index, assignments, prefix)
    except TypeError:  # an unhashable expression: not cached
        ordered, ops = _reduce(index, assignments, prefix)
    statements = [_statement(s, e, real_type) for s, e in ordered]
    return LoweredStage(stage.comment, tuple(statements)), ops


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


#: Appended to every kernel's status documentation by :func:`guard_outputs`.
NONFINITE_DOC = (
    "; INVALID also where finite inputs give an output the status would return that is not "
    "finite (they are too large: the arithmetic overflows); all outputs of such a row are NaN "
    "(flags 0)"
)


def _split_nan(expr):
    """(mask, raw) of an output's assignment: ``mask`` is the condition under which its
    Piecewise takes a NaN branch (false when it has none) -- the NaNs the status explains,
    any other non-finite value is an overflow -- and ``raw`` the one value it takes
    elsewhere, or None where there is no NaN branch or several other branches."""
    if not isinstance(expr, sp.Piecewise):
        return sp.false, None
    earlier, conditions, kept = sp.false, [], []
    for value, cond in expr.args:
        if value is sp.nan:
            conditions.append(sp.And(cond, sp.Not(earlier)))
        else:
            kept.append(value)
        earlier = sp.Or(earlier, cond)
    return sp.Or(*conditions), (kept[0] if conditions and len(kept) == 1 else None)


def _finite_by_construction(expr) -> bool:
    """Every value the assignment can take is a finite number or NaN (e.g. the constant
    bottom row of a homogeneous matrix): no check needed."""
    values = [a.expr for a in expr.args] if isinstance(expr, sp.Piecewise) else [expr]
    return all(v is sp.nan or (v.is_Number and v.is_finite) for v in values)


def _finite_where_unmasked(raw, mask, assignments, inputs) -> bool:
    """``raw`` is an input passed through (the delta's fourth axis) and finite wherever
    ``mask`` is false, because the mask holds (as one of its Or terms) a flag assigned
    Not(AllFinite(..., raw, ...)), the INVALID flag: no second isfinite of it."""
    if raw not in inputs:
        return False
    for term in mask.args if isinstance(mask, sp.Or) else (mask,):
        flag = assignments.get(term)
        if (
            isinstance(flag, sp.Not)
            and isinstance(flag.args[0], AllFinite)
            and raw in flag.args[0].args
        ):
            return True
    return False


def guard_outputs(kernel: Kernel) -> Kernel:
    """The finite-output rule, applied to every kernel: a row whose outputs are not all
    finite, apart from the NaNs its status explains, gets status INVALID and NaN in every
    output (0 in every flag output). Finite but huge inputs (a target 1e155 m away, rates
    of 1e155) overflow inside the arithmetic; without this rule they came back OK.

    Implemented as one more stage after the kernel's own: ``nonfinite_output``, then a
    checked copy of every output; the status gets INVALID as its first branch. The NaN a
    status explains is recognised from the output's Piecewise (a NaN branch and its
    condition), so a kernel needs nothing to opt in.

    The form is chosen so that compilers vectorise the per-point loop: the finiteness test
    reads each output's raw value (its Piecewise without the NaN branches), never the
    NaN-selected one, and each checked output is one select, ``(mask | nonfinite_output) ?
    NAN : raw``. Testing the selected values (isfinite of ``c ? NAN : x``) or selecting twice
    made gcc 12 give up on the whole loop ("no vectype"): delta fk 13 -> 39 ns per point,
    ik 13 -> 94. The results are the same bits: where the mask holds the output was NaN
    either way, elsewhere raw is the output."""
    assignments = {sym: sp.sympify(e) for stage in kernel.stages for sym, e in stage.assignments}
    inputs = {
        sym
        for port in kernel.inputs
        for sym in (*port.symbols, *(() if port.fourth is None else (port.fourth,)))
    }
    by_mask: dict = {}
    split: dict = {}
    for port in kernel.outputs:
        if port.ctype != "double":
            continue
        for sym in (*port.symbols, *(() if port.fourth is None else (port.fourth,))):
            expr = assignments.get(sym, sym)
            mask, raw = _split_nan(expr)
            if raw is None:  # test the output itself where no NaN branch is taken, and
                # select from it (two selects where it has several other branches; no
                # bundled kernel has such an output)
                split[sym] = (sp.false, sym)
            else:
                split[sym] = (mask, raw)
            if _finite_by_construction(expr) or _finite_where_unmasked(
                raw, mask, assignments, inputs
            ):
                continue
            by_mask.setdefault(mask, []).append(sym if raw is None else raw)
    if not by_mask:
        return kernel
    nonfinite = sp.Symbol("nonfinite_output")
    overflow = sp.Or(
        *(sp.And(sp.Not(mask), sp.Not(AllFinite(*raws))) for mask, raws in by_mask.items())
    )
    checked = [(nonfinite, overflow)]

    def checked_symbol(sym, flag):
        if flag:
            new = sp.Symbol(f"{sym}_checked", integer=True)
            checked.append((new, sp.Piecewise((sp.Integer(0), nonfinite), (sym, True))))
            return new
        new = sp.Symbol(f"{sym}_checked")
        mask, raw = split.get(sym, (sp.false, sym))
        checked.append((new, sp.Piecewise((sp.nan, sp.Or(mask, nonfinite)), (raw, True))))
        return new

    outputs = []
    for port in kernel.outputs:
        flag = port.ctype != "double"
        outputs.append(
            replace(
                port,
                symbols=tuple(checked_symbol(sym, flag) for sym in port.symbols),
                fourth=None if port.fourth is None else checked_symbol(port.fourth, flag),
            )
        )
    old = sp.sympify(kernel.status)
    branches = old.args if isinstance(old, sp.Piecewise) else ((old, True),)
    status = sp.Piecewise((st.INVALID, nonfinite), *branches)
    stage = Stage(
        "finite outputs: a non-finite value the status does not explain makes the row INVALID, "
        "all NaN",
        tuple(checked),
    )
    return replace(
        kernel,
        outputs=tuple(outputs),
        stages=(*kernel.stages, stage),
        status=status,
        status_doc=kernel.status_doc + NONFINITE_DOC,
    )


def lower(kernel: Kernel, real_type: str = "double") -> LoweredKernel:
    """The kernel's C statements, printed for ``real_type`` ("double", or "float" for
    `deltagen export --float32`): the same CSE, only the printing differs. A statement's
    ``ctype`` stays "double" for a floating value; the templates map it to the real type."""
    kernel = prune(guard_outputs(kernel))
    stages, total = [], 0
    for index, stage in enumerate(kernel.stages):
        lowered, ops = lower_stage(index, stage, prefix="t", real_type=real_type)
        stages.append(lowered)
        total += ops
    return LoweredKernel(kernel, tuple(stages), to_c(kernel.status, real_type), total, real_type)
