"""Emission of the 5-axis machine module (generated/five_axis_kinematics.{c,h,cdef.h}).

One module for every layout: the geometry is symbolic (the parameter struct), so one
compiled core serves every machine, as the delta core does; each layout and rotary pair
has its own fk, ik and ik_all (a few dozen operations each), named
``deltagen_five_axis_<layout>_<rotary>_<quantity>``, and all of them share one struct.
"""

from __future__ import annotations

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import Unit, render
from deltagen.derive.five_axis.kernels import all_kernels
from deltagen.model.five_axis import FIVE_AXIS_PARAMETERS

UNIT = Unit(
    prefix="deltagen_five_axis",
    base_name="five_axis_kinematics",
    title="kinematics of 5-axis NC machines (table-table, head-head, table-head; AC and BC)",
    source="the chain of deltagen/model/five_axis.py (LinuxCNC's xyzac-trt, xyzbc-trt, "
    "5axiskins and maxkins layouts, docs/sources.md)",
    struct_name="deltagen_five_axis_geometry",
    struct_doc="Geometry of the machine (deltagen/model/five_axis.py): the points are in "
    "metres with every axis at zero; a layout reads only the fields that act in it.",
    conventions=(
        "Conventions: SI units (m, rad). Arrays are row-major and contiguous, one row per",
        "point. Joints are x, y, z, tilt (A or B), C; a rotary axis turns by the right-hand",
        "rule as the tool's motion relative to the workpiece (ISO 841). The tool axis d",
        "points from the tool tip into the spindle.",
    ),
    struct_fields=FIVE_AXIS_PARAMETERS,
    atan2_loops=True,
)


def five_axis_sources() -> dict[str, str]:
    return render(UNIT, [lower(k) for k in all_kernels()])
