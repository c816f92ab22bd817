"""Emission of the delta core: the five kernels, lowered and rendered to generated/."""

from __future__ import annotations

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import Unit, render
from deltagen.derive.delta.kernels import all_kernels
from deltagen.model.delta import DELTA_PARAMETERS

UNIT = Unit(
    prefix="deltagen_delta",
    base_name="delta_kinematics",
    title="kinematics of the rotary delta robot",
    source="the delta report of docs/sources.md (2008, direct kinematics of a delta robot)",
    struct_name="deltagen_delta_geometry",
    struct_doc="Geometry of the robot (report, Figure 4) and its inertia (for the dynamics). "
    "The kinematics use the per-chain chain_r, chain_l_a, chain_l_b (an asymmetric robot); "
    "r_a, r_b, l_a, l_b are the nominal values: they scale the singularity thresholds and "
    "enter the dynamics, derived for the symmetric robot.",
    conventions=(
        "Conventions: SI units (m, rad, s). Arrays are row-major and contiguous, one row per",
        "point. `axes` is 3, or 4 when the last column carries the independent fourth axis",
        "(report eq. (43): phi = q_4 and its derivatives pass through unchanged).",
    ),
    axes_choices=(3, 4),
    direct_stores=True,
    atan2_loops=True,
    axes_doc="3, or 4 with the fourth axis in the last column",
    struct_fields=DELTA_PARAMETERS,
)


def delta_sources() -> dict[str, str]:
    return render(UNIT, [lower(k) for k in all_kernels()])
