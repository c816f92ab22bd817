"""Lowered kernels → C source, header and cffi declarations through the Jinja templates.

Python decides what goes where (which parameters a function reads, which columns it loads
and stores); the templates only lay it out.
"""

from __future__ import annotations

from dataclasses import dataclass
import jinja2
import sympy as sp

from deltagen import status as st
from deltagen.paths import template_dir
from deltagen.derive.kernel import Stage
from deltagen.codegen.lowering import LoweredKernel, keep_needed, lower_stage


def environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=False,
        autoescape=False,
    )


@dataclass(frozen=True)
class StructField:
    name: str
    ctype: str
    suffix: str
    doc: str


@dataclass(frozen=True)
class Unit:
    """What one generated C module needs besides its kernels."""

    prefix: str  # C prefix of functions and constants, e.g. "delta"
    base_name: str  # file stem, e.g. "delta_kinematics"
    title: str
    source: str  # where the equations come from
    struct_name: str | None  # None: the geometry is compiled in, no parameter struct
    struct_fields: tuple  # (StructField, ...)
    struct_doc: str = ""
    conventions: tuple = ()  # lines of the header's conventions paragraph
    axes_choices: tuple = ()  # e.g. (3, 4): a run-time row length; () for fixed widths
    axes_doc: str = ""
    block: int = 64
    newton: dict | None = None  # {n, revolute}: emit <prefix>_ik_newton, the wrapper of runtime/deltagen_ik_newton.c


def _columns(port):
    """(column, symbol) pairs of a port, the fourth-axis column 3 included."""
    cols = list(enumerate(port.symbols))
    if port.fourth is not None:
        cols.append((len(port.symbols), port.fourth))
    return cols


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
        lowered, _ = lower_stage(0, Stage(k.setup[0].comment, tuple(kept)), prefix="g")
        setup = [lowered]
    parameters = [
        dict(name=str(p.symbol), field=p.field, index="" if p.index is None else f"[{p.index}]")
        for p in k.parameters
        if p.symbol in needed
    ]
    angles = [
        dict(angle=str(a.angle), cos=str(a.cos), sin=str(a.sin),
             cos_used=a.cos in body_symbols, sin_used=a.sin in body_symbols)
        for a in k.angles
        if a.cos in body_symbols or a.sin in body_symbols
    ]
    loads = [
        dict(name=str(sym), port=port.name, column=col, width=port.width, used=sym in body_symbols)
        for port in k.inputs
        for col, sym in _columns(port)
    ]
    stores = [
        dict(name=str(sym), port=port.name, column=col, width=port.width)
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
        status=lk.status,
    )


def render(unit: Unit, lowered: list) -> dict[str, str]:
    """Return {file name: text} for the C source, the header and the cffi declarations."""
    env = environment()
    header_name = f"{unit.base_name}.h"
    context = dict(
        prefix=unit.prefix,
        title=unit.title,
        source=unit.source,
        header_name=header_name,
        source_name=f"{unit.base_name}.c",
        guard=f"DELTAGEN_{unit.base_name.upper()}_H",
        struct_name=unit.struct_name,
        struct_fields=unit.struct_fields,
        struct_doc=unit.struct_doc,
        conventions=unit.conventions,
        axes_choices=unit.axes_choices,
        axes_doc=unit.axes_doc,
        status_codes=sorted(st.STATUS_NAMES.items()),
        functions=[function_context(lk) for lk in lowered],
        block=unit.block,
        newton=unit.newton,
    )
    return {
        header_name: env.get_template("header.h.j2").render(restrict="restrict ", **context),
        f"{unit.base_name}.c": env.get_template("source.c.j2").render(restrict="restrict ", **context),
        f"{unit.base_name}.cdef.h": env.get_template("cdef.h.j2").render(restrict="", **context),
    }
