"""The batched kernels of the 5-axis machine module: for each layout and rotary pair
(model/five_axis.py, ``config_name``) fk, ik and ik_all, built from ``chain``.

Status rules (identical in the numpy reference, reference/five_axis.py):
  INVALID   an input of the row is NaN or infinite, or (ik) the direction is zero; outputs NaN
  SINGULAR  the tool axis is parallel to the C axis: |sin tilt| <= singular_tol (fk), the
            horizontal part of the unit direction <= singular_tol (ik): C is undetermined
            and keeps the previous value; every output is still given (finite)
  INVALID   (every kernel, codegen.lowering.guard_outputs) finite inputs whose outputs
            overflow
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from deltagen import status as st
from deltagen.derive.five_axis import chain as ch
from deltagen.derive.functions import AllFinite, Ge, Le
from deltagen.derive.kernel import Angle, Kernel, Parameter, Port, Stage
from deltagen.model.five_axis import LAYOUTS, ROTARIES, config_name

PARAMETERS = (
    *(Parameter(ch.c_pivot[i], "c_pivot", i) for i in range(3)),
    *(Parameter(ch.tilt_pivot[i], "tilt_pivot", i) for i in range(3)),
    *(Parameter(ch.head_pivot[i], "head_pivot", i) for i in range(3)),
    *(Parameter(ch.spindle_offset[i], "spindle_offset", i) for i in range(3)),
    Parameter(ch.tool_length, "tool_length"),
    Parameter(ch.singular_tol, "singular_tol"),
    Parameter(ch.tilt_min, "tilt_min"),
    Parameter(ch.tilt_max, "tilt_max"),
)

invalid, singular, no_branch = sp.symbols("invalid singular no_branch")
within1, within2 = sp.symbols("within1 within2")

_LAYOUT_DOC = {
    "table-table": "trunnion table: the tilt axis carries the C table (LinuxCNC xyz?c-trt)",
    "head-head": "spindle head: C on the carrier, the head tilts (LinuxCNC 5axiskins)",
    "table-head": "C table, tilting head (LinuxCNC maxkins)",
}


def _joint_port(name, symbols, doc):
    return Port(name, tuple(symbols), doc, "m, m, m, rad, rad", width=5)


def _masked(names, values, bad):
    outs = sp.symbols(" ".join(f"out_{n}" for n in names), real=True)
    return outs, tuple((o, sp.Piecewise((sp.nan, bad), (v, True))) for o, v in zip(outs, values))


def _what(layout, rotary):
    return f"{layout} {rotary} machine ({_LAYOUT_DOC[layout].replace('?', rotary[0].lower())})"


@cache
def fk_kernel(layout: str, rotary: str) -> Kernel:
    joints = (ch.x, ch.y, ch.z, ch.tilt, ch.c)
    w, d = ch.forward(
        layout, rotary, (ch.x, ch.y, ch.z), ch.cos_tilt, ch.sin_tilt, ch.cos_c, ch.sin_c
    )
    flags = Stage(
        "status flags: non-finite input, tool axis parallel to the C axis",
        (
            (invalid, sp.Not(AllFinite(*joints))),
            (singular, Le(sp.Abs(ch.sin_tilt), ch.singular_tol)),
        ),
    )
    outs, out_stage = _masked(("px", "py", "pz", "dx", "dy", "dz"), (*w, *d), invalid)
    return Kernel(
        name=f"{config_name(layout, rotary)}_fk",
        doc=f"Direct kinematics of a {_what(layout, rotary)}: joints -> tool tip and tool "
        "axis in the workpiece frame.",
        inputs=(
            _joint_port(
                "j",
                joints,
                f"joints x, y, z [m], {rotary[0]} (tilt), C [rad] (machine axis positions)",
            ),
        ),
        outputs=(
            Port("p", outs[:3], "tool tip in the workpiece frame W [m]", "m", width=3),
            Port(
                "d",
                outs[3:],
                "tool axis in W, unit vector from the tip into the spindle",
                "1",
                width=3,
            ),
        ),
        stages=(flags, Stage("outputs (NaN on invalid rows)", out_stage)),
        status=sp.Piecewise((st.INVALID, invalid), (st.SINGULAR, singular), (st.OK, True)),
        parameters=PARAMETERS,
        angles=(
            Angle(ch.tilt, ch.cos_tilt, ch.sin_tilt),
            Angle(ch.c, ch.cos_c, ch.sin_c),
        ),
        status_doc="OK; INVALID (non-finite input); SINGULAR (|sin tilt| <= singular_tol: the "
        "tool axis is parallel to the C axis; p and d are still given)",
    )


def _inverse_stages(layout, rotary):
    """The stages both inverse kernels share and the two branches' joint symbols."""
    e, zero, unit = ch.unit_direction()
    rho = sp.Symbol("rho", real=True)
    flags = Stage(
        "status flags: non-finite input or zero direction; tool axis parallel to the C axis",
        (
            (
                invalid,
                sp.Or(sp.Not(AllFinite(ch.px, ch.py, ch.pz, ch.dx, ch.dy, ch.dz, *ch.prev)), zero),
            ),
            (singular, Le(rho, ch.singular_tol)),
        ),
    )
    first, j1 = ch.branch(layout, rotary, e, rho, singular, 1, "1")
    second, j2 = ch.branch(layout, rotary, e, rho, singular, -1, "2")
    travel = Stage(
        "each branch's tilt within its travel [tilt_min, tilt_max]",
        (
            (within1, sp.And(Ge(j1[3], ch.tilt_min), Le(j1[3], ch.tilt_max))),
            (within2, sp.And(Ge(j2[3], ch.tilt_min), Le(j2[3], ch.tilt_max))),
            (no_branch, sp.And(sp.Not(within1), sp.Not(within2))),
        ),
    )
    stages = (
        Stage(
            "unit tool axis (scaled by its largest component first) and its horizontal part",
            (*unit, (rho, sp.sqrt(e[0] ** 2 + e[1] ** 2))),
        ),
        flags,
        Stage("branch 1: sin(tilt) >= 0; C at the turn nearest the previous C", first),
        Stage("branch 2: sin(tilt) <= 0; C at the turn nearest the previous C", second),
        travel,
    )
    return stages, j1, j2


def _inverse_inputs(rotary):
    return (
        Port("p", (ch.px, ch.py, ch.pz), "tool tip in the workpiece frame W [m]", "m", width=3),
        Port(
            "d",
            (ch.dx, ch.dy, ch.dz),
            "tool axis in W, from the tip into the spindle (any length > 0)",
            "1",
            width=3,
        ),
        _joint_port(
            "j_prev",
            ch.prev,
            f"previous joints x, y, z [m], {rotary[0]}, C [rad]: C takes the turn nearest the "
            "previous C, and keeps it where the tool axis is parallel to the C axis",
        ),
    )


_INVERSE_STATUS = (
    "OK; INVALID (non-finite input, or d = 0); UNREACHABLE (neither branch's tilt lies "
    "within [tilt_min, tilt_max]); SINGULAR (the tool axis is parallel to the C axis within "
    "singular_tol: C keeps the previous value, the joints are still given)"
)

_INVERSE_RULE = sp.Piecewise(
    (st.INVALID, invalid), (st.UNREACHABLE, no_branch), (st.SINGULAR, singular), (st.OK, True)
)


@cache
def ik_all_kernel(layout: str, rotary: str) -> Kernel:
    stages, j1, j2 = _inverse_stages(layout, rotary)
    names = [f"{n}{b}" for b in (1, 2) for n in ("x", "y", "z", "tilt", "c")]
    outs, out_stage = _masked(names, (*j1, *j2), invalid)
    flags = sp.symbols("out_valid1 out_valid2")
    flag_stage = tuple(
        (f, sp.Piecewise((sp.Integer(1), sp.And(w, sp.Not(invalid))), (sp.Integer(0), True)))
        for f, w in zip(flags, (within1, within2))
    )
    return Kernel(
        name=f"{config_name(layout, rotary)}_ik_all",
        doc=f"Inverse kinematics of a {_what(layout, rotary)}, both rotary branches: "
        "(tool tip, tool axis, previous joints) -> joints.",
        inputs=_inverse_inputs(rotary),
        outputs=(
            Port(
                "j",
                outs,
                f"branch 1 (sin {rotary[0]} >= 0) then branch 2 (sin {rotary[0]} <= 0), each "
                f"x, y, z [m], {rotary[0]}, C [rad]",
                "m, rad",
                width=10,
                matrix=(2, 5),
            ),
            Port(
                "valid",
                flags,
                "2 flags per point: 1 where the branch's tilt lies within its travel, else 0",
                "-",
                width=2,
                ctype="uint8_t",
            ),
        ),
        stages=(*stages, Stage("outputs (NaN on invalid rows)", out_stage + flag_stage)),
        status=_INVERSE_RULE,
        parameters=PARAMETERS,
        angles=(Angle(ch.prev[4], ch.cos_c_prev, ch.sin_c_prev),),
        status_doc=_INVERSE_STATUS,
    )


@cache
def ik_kernel(layout: str, rotary: str) -> Kernel:
    stages, j1, j2 = _inverse_stages(layout, rotary)
    cost1, cost2, first = sp.symbols("cost1 cost2 take_first", real=True)
    t_prev, c_prev = ch.prev[3], ch.prev[4]
    choose = Stage(
        "the branch nearest the previous rotary angles",
        (
            (cost1, (j1[3] - t_prev) ** 2 + (j1[4] - c_prev) ** 2),
            (cost2, (j2[3] - t_prev) ** 2 + (j2[4] - c_prev) ** 2),
            (first, sp.And(within1, sp.Or(sp.Not(within2), Le(cost1, cost2)))),
        ),
    )
    chosen = [sp.Piecewise((a, first), (b, True)) for a, b in zip(j1, j2)]
    outs, out_stage = _masked(("x", "y", "z", "tilt", "c"), chosen, sp.Or(invalid, no_branch))
    return Kernel(
        name=f"{config_name(layout, rotary)}_ik",
        doc=f"Inverse kinematics of a {_what(layout, rotary)}: (tool tip, tool axis, previous "
        "joints) -> the joints of the branch nearest the previous ones (squared distance of "
        "the rotary angles, C at its nearest turn) among those within the tilt's travel.",
        inputs=_inverse_inputs(rotary),
        outputs=(_joint_port("j", outs, f"joints x, y, z [m], {rotary[0]}, C [rad]"),),
        stages=(*stages, choose, Stage("outputs (NaN on invalid or unreachable rows)", out_stage)),
        status=_INVERSE_RULE,
        parameters=PARAMETERS,
        angles=(Angle(ch.prev[4], ch.cos_c_prev, ch.sin_c_prev),),
        status_doc=_INVERSE_STATUS,
    )


def configs():
    """Every (layout, rotary) pair, in the module's order."""
    return tuple((layout, rotary) for layout in LAYOUTS for rotary in ROTARIES)


def all_kernels():
    return tuple(
        kernel
        for layout, rotary in configs()
        for kernel in (
            fk_kernel(layout, rotary),
            ik_kernel(layout, rotary),
            ik_all_kernel(layout, rotary),
        )
    )
