"""Lowered kernels → C source, header and cffi declarations through the Jinja templates.

Python decides what goes where (which parameters a function reads, which columns it loads
and stores); the templates only lay it out.
"""

from __future__ import annotations

import functools
import json
import re
from dataclasses import dataclass

import jinja2
import sympy as sp

from deltagen import status as st
from deltagen.codegen.layout import wrap_c
from deltagen.codegen.lowering import (
    LoweredKernel,
    LoweredStage,
    Statement,
    keep_needed,
    lower_stage,
)
from deltagen.derive.kernel import Stage
from deltagen.paths import runtime_dir, template_dir

#: Per real type: (bytes, zero literal, cos, sin) as the templates print them.
REAL_LAYOUT = {"double": (8, "0.0", "cos", "sin"), "float": (4, "0.0F", "cosf", "sinf")}


class _CTemplate(jinja2.Template):
    """A template whose C output (``*.c.j2``, ``*.h.j2``) is laid out by ``layout.wrap_c``;
    other files (Makefile, CMakeLists.txt, README) are returned as rendered."""

    def render(self, *args, **kwargs) -> str:
        text = super().render(*args, **kwargs)
        return wrap_c(text) if (self.name or "").endswith((".c.j2", ".h.j2")) else text


def environment(real_type: str = "double") -> jinja2.Environment:
    """The template environment; its ``ctype`` filter maps a port's or statement's
    "double" to the real type of the build (uint8_t flags and ints stay). C output is
    wrapped to ``layout.WIDTH`` columns (``_CTemplate``). One per real type and template
    folder, shared: each parses a template once (Jinja's own cache; an edited file is
    read again), where an environment per module parsed them for every module."""
    return _environment(real_type, str(template_dir()))


@functools.lru_cache(maxsize=4)  # double and float, and a test's own template folder
def _environment(real_type: str, folder: str) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(folder),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        autoescape=False,
    )
    env.template_class = _CTemplate
    env.filters["ctype"] = lambda ctype: real_type if ctype == "double" else ctype
    return env


@dataclass(frozen=True)
class Unit:
    """What one generated C module needs besides its kernels."""

    prefix: str  # C prefix of functions and types, e.g. "deltagen_delta"
    base_name: str  # file stem, e.g. "delta_kinematics"
    title: str
    source: str  # where the equations come from
    struct_name: str | None  # None: the geometry is compiled in, no parameter struct
    # the family's parameter table (model/parameters.py: RobotParameter, ...), the struct's
    # one declaration; () without a struct
    struct_fields: tuple
    struct_doc: str = ""
    conventions: tuple = ()  # lines of the header's conventions paragraph
    axes_choices: tuple = ()  # e.g. (3, 4): a run-time row length; () for fixed widths
    axes_doc: str = ""
    block: int = 64
    newton: dict | None = (
        None  # {n, revolute}: emit <prefix>_ik_newton, the wrapper of runtime/deltagen_ik_newton.c
    )
    dynamics: dict | None = None  # {n}: emit <prefix>_forward_dynamics (runtime Cholesky)
    # further functions of the module, each from the templates <name>.c.j2 and <name>.h.j2
    # (the hexapod's fk wrapper of its runtime solver)
    extras: tuple = ()
    # packed block arrays (pack_block_arrays): the block's angles end to end, one cos and
    # one sin loop for all of them instead of one per angle; the outputs in one 2-D array
    packed_blocks: bool = False
    # direct stores (direct_stores): the per-point loop writes the caller's rows itself, one
    # loop per row length of axes_choices; no output block arrays and no scatter loop
    direct_stores: bool = False
    # atan2 loops (atan2_loops): a kernel's atan2 calls in padded loops of their own between
    # the per-point loop and a second one that finishes the point (a lone point gets the
    # bits of any batch row)
    atan2_loops: bool = False


def _columns(port):
    """(column, symbol) pairs of a port, the fourth-axis column 3 included."""
    cols = list(enumerate(port.symbols))
    if port.fourth is not None:
        cols.append((len(port.symbols), port.fourth))
    return cols


def _kib(nbytes: int) -> str:
    return f"{nbytes} bytes ({nbytes / 1024:.1f} KiB)"


#: The margin the stack figures state for what they leave out (scalars, register spills):
#: a frame is at least its block arrays and, with gcc -O2 on x86-64, at most this much more
#: (measured 2-15 % on the bundled robots; tests/codegen/test_render_stack.py checks every
#: checked-in module).
STACK_MARGIN_PERCENT = 25


#: Block arrays smaller than this (bytes) state the larger margin: the spills do not shrink
#: with the arrays (the delta's ik, 2304 bytes of arrays in two per-point loops, one per row
#: length: its frame is the arrays + 27 %).
SMALL_ARRAYS = 3072


def stack_margin_percent(block: int, nbytes: int | None = None) -> int:
    """The margin a function's stack figure states: :data:`STACK_MARGIN_PERCENT` at 64
    points and more, 40 % below (the spills do not shrink with the block: the Panda's
    Coriolis frame at 16 points is its arrays + 33 %) or where the block arrays take
    fewer than :data:`SMALL_ARRAYS` bytes (``nbytes``)."""
    small = nbytes is not None and nbytes < SMALL_ARRAYS
    return STACK_MARGIN_PERCENT if block >= 64 and not small else 40


def stack_use(fn: dict, block: int, block_macro: str, real_bytes: int = 8) -> tuple[int, str]:
    """(bytes, text) of a function's block arrays: the columns it gathers, the cosines and
    sines, the status and the outputs, each of ``block`` points (8-byte double or 4-byte
    float, 4-byte int)."""
    real = "double" if real_bytes == 8 else "float"
    doubles = sum(1 for load in fn["loads"] if load["gathered"])
    if fn.get("flat_trig"):  # cos_b and sin_b: a column of every angle each
        angles = len(fn["angles"])
        doubles += angles * (
            int(any(a["cos_used"] for a in fn["angles"]))
            + int(any(a["sin_used"] for a in fn["angles"]))
        )
    else:
        doubles += sum(int(a["cos_used"]) + int(a["sin_used"]) for a in fn["angles"])
    ints = 1 + sum(1 for store in fn["stores"] if store["ctype"] != "double")
    for part in fn.get("parts", ()):  # atan2_loops: the columns between the loops
        doubles += len(part["atan2_in"]) + sum(1 for c in part["carry_out"] if c.ctype == "double")
        ints += sum(1 for c in part["carry_out"] if c.ctype != "double")
    if not fn.get("direct"):  # direct stores: the outputs have no block arrays
        doubles += sum(1 for store in fn["stores"] if store["ctype"] == "double")
    nbytes = block * (real_bytes * doubles + 4 * ints)
    return nbytes, (
        f"{doubles + ints} block arrays ({doubles} {real}, {ints} int) of "
        f"{block_macro} points,\n * {_kib(nbytes)} at {block}, plus scalars and spills: "
        f"allow {stack_margin_percent(block, nbytes)} % more"
    )


def runtime_macro(name: str, **values) -> int:
    """The value of a size macro of the runtime headers (e.g. DELTAGEN_IK_NEWTON_WORK_DOUBLES)
    for the given arguments: the C header is the one definition."""
    for header in sorted(runtime_dir().glob("*.h")):
        found = re.search(rf"#define {name}\((\w+)\) ([0-9a-z()+* ]+)\n", header.read_text())
        if found:
            arg, body = found.groups()
            return int(eval(body, {"__builtins__": {}}, {arg: values[arg]}))  # digits, + * ( )
    raise KeyError(f"no macro {name} in {runtime_dir()}")


#: a function the runtime headers declare or define: return type, then the name at the start
#: of a line (``int deltagen_cholesky(``, ``static inline double deltagen_fit_angle(``)
_RUNTIME_FUNCTION = re.compile(r"^[A-Za-z_][\w \t]*?[ \t*](deltagen_\w+)\s*\(", re.MULTILINE)
_CALL = re.compile(r"\b(deltagen_\w+)\s*\(")


@functools.lru_cache(maxsize=1)
def runtime_functions() -> dict[str, str]:
    """{function: header} of the hand-written runtime (codegen/runtime/*.h): the headers are
    the one list of what the runtime offers, and of where each function is declared."""
    found: dict[str, str] = {}
    for header in sorted(runtime_dir().glob("*.h")):
        for name in _RUNTIME_FUNCTION.findall(header.read_text()):
            found.setdefault(name, header.name)
    return found


def runtime_includes(functions: list) -> list[dict]:
    """The runtime headers the lowered statements of ``functions`` (function contexts) call
    into, each with the runtime functions called and the kernels calling them: a file
    that prints those statements includes exactly these (a template cannot forget one)."""
    table = runtime_functions()
    used: dict[str, dict] = {}
    for fn in functions:
        texts = [st.expr for stage in [*fn["setup"], *fn["stages"]] for st in stage.statements]
        for text in [*texts, fn["status"]]:
            for name in _CALL.findall(text):
                if name in table:
                    entry = used.setdefault(table[name], {"symbols": {}, "kernels": {}})
                    entry["symbols"][name] = None
                    entry["kernels"][fn["name"]] = None
    return [
        dict(header=header, symbols=list(entry["symbols"]), kernels=list(entry["kernels"]))
        for header, entry in sorted(used.items())
    ]


def function_context(lk: LoweredKernel) -> dict:
    k = lk.kernel
    body_symbols = set(sp.sympify(k.status).free_symbols)
    for stage in k.stages:
        for _, expr in stage.assignments:
            body_symbols |= sp.sympify(expr).free_symbols
    setup_assignments = [a for stage in k.setup for a in stage.assignments]
    needed = set(body_symbols)
    kept = keep_needed(needed, setup_assignments)
    setup = []
    if kept:
        lowered, _ = lower_stage(
            0, Stage(k.setup[0].comment, tuple(kept)), prefix="g", real_type=lk.real_type
        )
        setup = [lowered]
    parameters = [
        dict(name=str(p.symbol), field=p.field, index="" if p.index is None else f"[{p.index}]")
        for p in k.parameters
        if p.symbol in needed
    ]
    angles = [
        dict(
            angle=str(a.angle),
            cos=str(a.cos),
            sin=str(a.sin),
            cos_used=a.cos in body_symbols,
            sin_used=a.sin in body_symbols,
        )
        for a in k.angles
        if a.cos in body_symbols or a.sin in body_symbols
    ]
    loads = [
        dict(
            name=str(sym),
            port=port.name,
            column=col,
            width=port.width,
            used=sym in body_symbols,
            gathered=sym in body_symbols,  # copied into the block (pack_block_arrays: angles too)
            ref=f"{sym}_b[k]",  # where the block holds it
        )
        for port in k.inputs
        for col, sym in _columns(port)
    ]
    stores = [
        dict(
            name=str(sym),
            port=port.name,
            column=col,
            width=port.width,
            ctype=port.ctype,
            ref=f"{sym}_b[k]",  # where the block holds it
        )
        for port in k.outputs
        for col, sym in _columns(port)
    ]
    return dict(
        name=k.name,
        doc=k.doc,
        inputs=k.inputs,
        outputs=k.outputs,
        status_doc=k.status_doc,
        parameters=parameters,
        setup=setup,
        angles=angles,
        loads=loads,
        stages=lk.stages,
        stores=stores,
        flag_outputs=any(port.ctype != "double" for port in k.outputs),
        status=lk.status,
        operation_count=lk.operation_count,
    )


def pack_block_arrays(fn: dict) -> None:
    """Pack a function's block arrays (``unit.packed_blocks``).

    Outputs: the real outputs of a block in one array ``out_b[outputs][block]``: the
    per-point loop and the scatter address every column from one base at a constant offset,
    where one array per output needed a pointer each (spilled to the stack and reloaded per
    point beyond the registers: the Puma's Jacobian, 36 outputs, scattered about 10 %
    slower, callgrind on x86-64-v3).

    Angles: laid out end to end, the gather writing angle ``i`` of point ``k`` of a block of
    ``m`` points to ``angle_b[i * m + k]``, and one cos loop and one sin loop run over all
    of them (``cos_b``, ``sin_b``, the same layout). A single point then costs one vector
    cos and one vector sin (its angles padded to whole vectors), not one of each per angle
    (the Puma's fk of one pose: 1598 instructions -> 691), and every value still comes from
    a vector lane whatever the point's place in the batch (the same bits alone as in any
    batch). Sin and cos of one angle stay in separate loops: in one loop gcc 12 fuses them
    into a scalar sincos call and the loop no longer vectorises (4x slower)."""
    reals = [store for store in fn["stores"] if store["ctype"] == "double"]
    for i, store in enumerate(reals):
        store["ref"] = f"out_b[{i}][k]"
    fn["packed_outputs"] = len(reals)
    index = {a["angle"]: i for i, a in enumerate(fn["angles"])}
    if not index or not set(index) <= {load["name"] for load in fn["loads"]}:
        return  # no angles, or one that is not an input (computed in a setup stage)
    fn["flat_trig"] = True
    fn["any_cos"] = any(a["cos_used"] for a in fn["angles"])
    fn["any_sin"] = any(a["sin_used"] for a in fn["angles"])
    for i, a in enumerate(fn["angles"]):
        a["flat"] = f"{i} * m + k"
    for load in fn["loads"]:
        if load["name"] in index:
            load["gathered"] = True
            load["ref"] = f"angle_b[{index[load['name']]} * m + k]"


#: A statement that may be one atan2 call (:func:`_call_arguments` splits its arguments).
_ATAN2_CALL = re.compile(r"(atan2f?)\((.*)\)")


def _call_arguments(expr: str) -> tuple[str, str, str] | None:
    """(function, y, x) of ``expr`` when it is one atan2 call, its arguments split at the
    comma outside their parentheses; None otherwise."""
    found = _ATAN2_CALL.fullmatch(expr)
    if not found:
        return None
    depth, cut = 0, None
    for i, char in enumerate(found.group(2)):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if depth < 0:
            return None  # "atan2(a, b) + atan2(c, d)": not one call
        if char == "," and depth == 0:
            if cut is not None:
                return None
            cut = i
    if depth != 0 or cut is None:
        return None
    args = found.group(2)
    return found.group(1), args[:cut].strip(), args[cut + 1 :].strip()


def _named_atan2_arguments(stages: list) -> list:
    """The stages with each atan2 whose argument is not a value of the loop (an input, an
    expression: the five-axis ik's ``atan2(ex, -ey)``) given a statement of its own for
    that argument, ``<angle>_y`` / ``<angle>_x`` just before the call, so that every
    atan2 reads two named values the first loop can keep in columns."""
    defined = {st.name for stage in stages for st in stage.statements}
    out = []
    for stage in stages:
        statements = []
        for statement in stage.statements:
            call = _call_arguments(statement.expr)
            if call is not None:
                function, y, x = call
                named = []
                for arg, suffix in ((y, "y"), (x, "x")):
                    if arg in defined:
                        named.append(arg)
                        continue
                    name = f"{statement.name}_{suffix}"
                    if name in defined:
                        return stages  # no free name: left as it is (then whole)
                    defined.add(name)
                    statements.append(Statement(name, arg, statement.ctype))
                    named.append(name)
                statement = Statement(
                    statement.name, f"{function}({named[0]}, {named[1]})", statement.ctype
                )
            statements.append(statement)
        out.append(LoweredStage(stage.comment, tuple(statements)))
    return out


def _names(expr: str) -> set:
    return set(re.findall(r"\w+", expr))


def whole_loop(fn: dict) -> None:
    """The one per-point loop of a function: every used input, cosine and sine, every stage,
    store and the status (the template's ``points`` macro renders ``fn["parts"]``)."""
    fn["parts"] = [
        dict(
            names=None,  # every used load, cosine and sine
            short_names=None,
            stages=fn["stages"],
            stores=fn["stores"],
            status=True,
            carry_in=[],
            carry_out=[],
            atan2_in=[],
        )
    ]


def atan2_loops(fn: dict) -> None:
    """Split a function's per-point loop at its atan2 calls (``unit.atan2_loops``): the first
    loop computes everything that does not depend on an angle from atan2 and keeps the
    atan2 arguments and the values the rest needs in block columns; one loop per atan2,
    padded to whole vectors of TRIG_LANES like the cos/sin loops, evaluates it; a second
    per-point loop finishes the point (the output checks, the stores, the status).

    In a vectorised per-point loop a point in the batch's scalar remainder (and a point
    alone) took the scalar atan2, a point in a vector lane the vector one: the delta's
    ik_acc of one point differed from the same point in a batch in the last bits (910 of
    9216 values of 1024 random poses). Split, every angle comes from a vector lane wherever
    the point stands (0 of 9216), rows in vector lanes keep their bits, and the first loop
    has no calls to spill registers around: ik of 1024 points in cache 10.2 -> 10.3-10.5 ns
    per point, of 1021 points (a remainder) 12.2 -> 10.6, of 10^5 rows 10.37 -> 10.48
    (gcc 12, AVX-512, both builds in one process called alternately, thread CPU time,
    minimum of 21 repeats, load ~3).

    An argument that is not a value of the loop (an input, an expression) becomes one
    first (:func:`_named_atan2_arguments`). Left whole (the function keeps
    :func:`whole_loop`): an atan2 whose argument depends on another atan2 (one split would
    not do), an atan2 inside a larger expression, and a fourth-axis output the finishing
    loop would need from the first."""
    stages = _named_atan2_arguments(fn["stages"])
    statements = [statement for stage in stages for statement in stage.statements]
    calls = {statement.name: _call_arguments(statement.expr) for statement in statements}
    calls = {name: call for name, call in calls.items() if call is not None}
    if not calls or any(
        "atan2" in statement.expr and statement.name not in calls for statement in statements
    ):
        return  # none, or one this split would leave in the first loop
    defined = {statement.name: statement for statement in statements}
    late = set(calls)  # the atan2 angles and what depends on them
    for statement in statements:
        if statement.name not in calls and _names(statement.expr) & late:
            late.add(statement.name)
    arguments = {arg for _, y, x in calls.values() for arg in (y, x)}
    if arguments & late or not arguments <= set(defined):
        return
    late_stores = [store for store in fn["stores"] if store["name"] in late]
    status_late = bool(_names(fn["status"]) & late)
    late_reads = set()  # what the finishing loop reads
    for statement in statements:
        if statement.name in late and statement.name not in calls:
            late_reads |= _names(statement.expr)
    late_reads |= {store["name"] for store in late_stores}
    if status_late:
        late_reads |= _names(fn["status"])
    carried = [defined[name] for name in defined if name in late_reads and name not in late]
    if {c.name for c in carried} & set(fn["fourth_outputs"]):
        return
    kept = arguments | {c.name for c in carried}
    columns = [defined[name] for name in defined if name in kept]
    early_stages = [
        LoweredStage(
            stage.comment,
            tuple(statement for statement in stage.statements if statement.name not in late),
        )
        for stage in stages
    ]
    late_stages = [
        LoweredStage(
            stage.comment,
            tuple(
                statement
                for statement in stage.statements
                if statement.name in late and statement.name not in calls
            ),
        )
        for stage in stages
    ]
    early_stores = [store for store in fn["stores"] if store["name"] not in late]

    def read(stages, stores, status, skip=frozenset()):
        """The names a loop reads: its statements', its stores' and the status's (``skip``:
        the fourth-axis outputs, which the loop of the shortest rows does not compute)."""
        return set().union(
            *(
                _names(statement.expr)
                for stage in stages
                for statement in stage.statements
                if statement.name not in skip
            ),
            *({store["name"]} for store in stores if store["name"] not in skip),
            _names(fn["status"]) if status else set(),
        )

    fourth = frozenset(fn["fourth_outputs"])
    early = (early_stages, early_stores, not status_late)
    late_part = (late_stages, late_stores, status_late)
    fn["atan2"] = [
        dict(name=name, function=function, y=y, x=x) for name, (function, y, x) in calls.items()
    ]
    fn["atan2_arguments"] = sorted(arguments, key=list(defined).index)
    fn["parts"] = [
        dict(
            names=read(*early),
            short_names=read(*early, skip=fourth),
            stages=[stage for stage in early_stages if stage.statements],
            stores=early_stores,
            status=not status_late,
            carry_in=[],
            carry_out=columns,
            atan2_in=[],
        ),
        dict(
            names=read(*late_part),
            short_names=read(*late_part, skip=fourth),
            stages=[stage for stage in late_stages if stage.statements],
            stores=late_stores,
            status=status_late,
            carry_in=carried,
            carry_out=[],
            atan2_in=list(calls),
        ),
    ]


def direct_stores(fn: dict, axes_choices: tuple) -> None:
    """Let a function's per-point loop store its results into the caller's rows
    (``unit.direct_stores``), one copy of the loop per row length in ``axes_choices``.

    Each copy has constant strides (gcc vectorises the strided stores by permutes, as it
    did the scatter loop's), and where the row has no fourth-axis column the copy takes
    that input as the constant zero the gather used to write and stores nothing for it:
    the always-zero columns are neither gathered, loaded, checked nor stored. Against the
    block arrays and the scatter loop, the delta's fk / fk_vel / fk_acc / ik of 1024 points
    went 8.9 / 12.4 / 17.8 / 10.6 -> 8.5 / 12.2 / 15.6 / 10.2 ns per point (gcc 12,
    AVX-512, the two builds called alternately in one process, thread CPU time, minimum of
    120 repeats) and 134 / 183 / 243 / 149 -> 130 / 179 / 231 / 144 instructions per point
    (callgrind, x86-64-v3). The same arithmetic in the same order: the bits do not change.
    Flag outputs (uint8_t) keep their block arrays: a narrow store in the loop costs more
    than the scatter; so do outputs of fixed widths (the delta's 3 x 3 Jacobian, its 3 x 15
    parameter Jacobian): stored from the loop at strides of 9 or 45 they took 2.2x the
    instructions per point (callgrind)."""
    if not axes_choices or any(
        store["ctype"] != "double" or store["width"] != "axes" for store in fn["stores"]
    ):
        return
    fn["direct"] = True
    # the fourth-axis outputs: not computed in the loop of the shortest rows (no other
    # statement reads them)
    fourth = {
        store["name"]
        for store in fn["stores"]
        if store["width"] == "axes" and store["column"] >= min(axes_choices)
    }
    for stage in fn["stages"]:
        for statement in stage.statements:
            if fourth & _names(statement.expr):
                raise ValueError(f"{fn['name']}: {statement.name} reads a fourth-axis output")
    fn["fourth_outputs"] = sorted(fourth)


def render(unit: Unit, lowered: list) -> dict[str, str]:
    """Return {file name: text} for the C source, the header and the cffi declarations, in
    the real type the kernels were lowered for (float: no ik_newton or forward_dynamics,
    whose runtime C is double)."""
    env, context = render_context(unit, lowered)
    header_name = context["header_name"]
    files = {
        header_name: ("header.h.j2", "restrict "),
        f"{unit.base_name}.c": ("source.c.j2", "restrict "),
        f"{unit.base_name}.cdef.h": ("cdef.h.j2", ""),
    }
    rendered = {
        name: env.get_template(template).render(template=template, restrict=restrict, **context)
        for name, (template, restrict) in files.items()
    }
    rendered[manifest_name(unit.base_name)] = kernel_manifest(unit, lowered)
    return rendered


def manifest_name(base_name: str) -> str:
    """The file of a module's kernel manifest: ``<base_name>.kernels.json``."""
    return f"{base_name}.kernels.json"


def _port_entry(port) -> dict:
    return dict(
        name=port.name,
        width=port.width,
        ctype=port.ctype,
        unit=port.unit,
        doc=port.doc,
        fourth=port.fourth is not None,
        matrix=None if port.matrix is None else list(port.matrix),
    )


def _check_parameters(unit: Unit, kernel) -> None:
    """Every struct field a kernel reads is a field of the unit's parameter table, its index
    within the field's length: the derivation and the table name the same struct."""
    fields = {p.name: p for p in unit.struct_fields}
    for parameter in kernel.parameters:
        field = fields.get(parameter.field)
        count = None if field is None else field.count
        if (
            field is None
            or (parameter.index is None) != (count is None)
            or (parameter.index is not None and not 0 <= parameter.index < count)
        ):
            raise ValueError(
                f"kernel {kernel.name} reads {parameter.field}"
                f"{'' if parameter.index is None else f'[{parameter.index}]'}, which the "
                f"parameter table of {unit.struct_name} does not declare"
            )


def kernel_manifest(unit: Unit, lowered: list) -> str:
    """The module's kernel manifest (JSON text, sorted keys, deterministic): the C prefix,
    the parameter struct (each field's name, C type, length, unit, per-chain flag and doc,
    from the family's parameter table) and, per C function, its ports (name, width, C type,
    unit, doc, matrix shape) and status doc, from the derivation's ``Kernel`` objects. The
    native backends read their widths from it (deltagen.native.manifest); it is written
    beside the C by `deltagen generate`, which checks it with the C."""
    functions = []
    for lk in lowered:
        k = lk.kernel
        _check_parameters(unit, k)
        functions.append(
            dict(
                name=k.name,
                function=f"{unit.prefix}_{k.name}",
                kind="kernel",
                doc=k.doc,
                inputs=[_port_entry(p) for p in k.inputs],
                outputs=[_port_entry(p) for p in k.outputs],
                status_doc=k.status_doc,
            )
        )
    wrappers = []
    if unit.newton:
        wrappers.append("ik_newton")
    if unit.dynamics:
        n = unit.dynamics["n"]
        # the ports of forward_dynamics.h.j2 (M^-1 (tau - h) of the runtime's Cholesky)
        ports = [
            dict(name=name, width=n, ctype="double", unit=u, doc=doc, fourth=False, matrix=None)
            for name, u, doc in (
                ("q", "rad|m", "joint coordinates"),
                ("qd", "rad/s|m/s", "joint rates"),
                ("tau", "N m|N", "joint torques"),
                ("qdd", "rad/s^2|m/s^2", "joint accelerations"),
            )
        ]
        functions.append(
            dict(
                name="forward_dynamics",
                function=f"{unit.prefix}_forward_dynamics",
                kind="wrapper",
                doc="qdd = M(q)^-1 (tau - h(q, qd)) by the runtime's Cholesky factorisation",
                inputs=ports[:3],
                outputs=ports[3:],
                status_doc="OK; INVALID; SINGULAR (M not positive definite)",
            )
        )
    wrappers += list(unit.extras)
    manifest = dict(
        generated="by deltagen from deltagen/codegen/render.py (kernel_manifest); do not edit",
        module=unit.base_name,
        prefix=unit.prefix,
        real=lowered[0].real_type if lowered else "double",
        axes=list(unit.axes_choices),
        struct=None
        if unit.struct_name is None
        else dict(name=unit.struct_name, fields=[p.manifest() for p in unit.struct_fields]),
        functions=functions,
        # the templates of the module's functions whose arguments are not rows of points
        # (an options struct, a solver's scratch): declared and documented in the header only
        wrapper_templates=wrappers,
    )
    return json.dumps(manifest, indent=1, sort_keys=True) + "\n"


def render_context(unit: Unit, lowered: list) -> tuple[jinja2.Environment, dict]:
    """The template environment (for the kernels' real type) and the context every module
    template gets: the unit's layout facts and one dict per function."""
    real_type = lowered[0].real_type if lowered else "double"
    if real_type != "double" and (unit.newton or unit.dynamics):
        raise ValueError("the runtime C (ik_newton, forward_dynamics) is double only")
    real_bytes, zero, cos_name, sin_name = REAL_LAYOUT[real_type]
    env = environment(real_type)
    header_name = f"{unit.base_name}.h"
    block_macro = f"{unit.prefix.upper()}_BLOCK"
    functions = [function_context(lk) for lk in lowered]
    for fn in functions:
        fn["flat_trig"] = False
        fn["packed_outputs"] = 0
        fn["direct"] = False
        fn["fourth_outputs"] = []
        if unit.packed_blocks:
            pack_block_arrays(fn)
        if unit.direct_stores:
            direct_stores(fn, unit.axes_choices)
        whole_loop(fn)
        if unit.atan2_loops:
            atan2_loops(fn)
        fn["stack_bytes"], fn["stack_doc"] = stack_use(fn, unit.block, block_macro, real_bytes)
    newton = None
    if unit.newton:
        n = unit.newton["n"]
        doubles = runtime_macro("DELTAGEN_IK_NEWTON_WORK_DOUBLES", n=n)
        ints = runtime_macro("DELTAGEN_IK_NEWTON_WORK_INTS", n=n)
        work = 8 * doubles + 4 * ints
        fkj = next(fn for fn in functions if fn["name"] == "fk_jacobian")
        newton = dict(
            unit.newton,
            stack_doc=(
                f"{work} bytes of solver scratch memory in this frame ({doubles} doubles, {ints} "
                f"ints),\n * plus fk_jacobian's {_kib(fkj['stack_bytes'])} at {unit.block} points "
                "and the runtime's frames\n * (scalars and 3x3 blocks)"
            ),
        )
    dynamics = None
    if unit.dynamics:
        n = unit.dynamics["n"]
        nbytes = unit.block * (8 * (n * n + n) + 2)
        dynamics = dict(
            unit.dynamics,
            stack_doc=(
                f"{_kib(nbytes)} at {unit.block} points (M and h of a block), plus "
                f"{16 * n} bytes per point and the stack of mass_matrix and nonlinear_effects"
            ),
        )
    context = dict(
        prefix=unit.prefix,
        macro_prefix=unit.prefix.upper(),
        block_macro=block_macro,
        title=unit.title,
        source=unit.source,
        template_dir="deltagen/codegen/templates",
        header_name=header_name,
        source_name=f"{unit.base_name}.c",
        cdef_name=f"{unit.base_name}.cdef.h",
        guard=f"DELTAGEN_{unit.base_name.upper()}_H",
        struct_name=unit.struct_name,
        struct_fields=unit.struct_fields,
        struct_doc=unit.struct_doc,
        conventions=unit.conventions,
        axes_choices=unit.axes_choices,
        axes_doc=unit.axes_doc,
        status_codes=sorted(st.STATUS_NAMES.items()),
        functions=functions,
        runtime_includes=runtime_includes(functions),
        largest=max(functions, key=lambda fn: fn["stack_bytes"]),
        block=unit.block,
        newton=newton,
        dynamics=dynamics,
        extras=unit.extras,
        atan2_loops=unit.atan2_loops,
        real=real_type,
        real_bytes=real_bytes,
        zero=zero,
        cos=cos_name,
        sin=sin_name,
    )
    return env, context
