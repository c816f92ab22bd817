"""Emission of the delta core: the five kernels, lowered and rendered to generated/."""

from __future__ import annotations

from ..codegen.lowering import lower
from ..codegen.render import StructField, Unit, render
from .kernels import all_kernels

UNIT = Unit(
    prefix="delta",
    base_name="delta_kinematics",
    title="kinematics of the rotary delta robot",
    source="the 2008 report on the direct kinematics of a delta robot (seed 000)",
    struct_name="delta_geometry",
    struct_fields=(
        StructField("r_a", "double", "", "base radius, O to a drive axis [m]"),
        StructField("r_b", "double", "", "platform radius, P to a joint C_i [m]"),
        StructField("l_a", "double", "", "crank length [m]"),
        StructField("l_b", "double", "", "parallelogram rod length [m]"),
        StructField("cos_theta", "double", "[3]", "cos of the drive positions theta_i"),
        StructField("sin_theta", "double", "[3]", "sin of the drive positions theta_i"),
        StructField("singular_tol", "double", "", "relative singularity threshold, e.g. 1e-9"),
    ),
)


def delta_sources() -> dict[str, str]:
    return render(UNIT, [lower(k) for k in all_kernels()])
