"""Emission of the delta core: the five kernels, lowered and rendered to generated/."""

from __future__ import annotations

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import StructField, Unit, render
from deltagen.derive.delta.kernels import all_kernels

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
    axes_doc="3, or 4 with the fourth axis in the last column",
    struct_fields=(
        StructField("r_a", "double", "", "base radius, O to a drive axis [m]"),
        StructField("r_b", "double", "", "platform radius, P to a joint C_i [m]"),
        StructField("l_a", "double", "", "crank length [m]"),
        StructField("l_b", "double", "", "parallelogram rod length [m]"),
        StructField(
            "chain_r", "double", "[3]", "per chain r_a,i - r_b,i [m] (symmetric: r_a - r_b)"
        ),
        StructField("chain_l_a", "double", "[3]", "per-chain crank length [m] (symmetric: l_a)"),
        StructField("chain_l_b", "double", "[3]", "per-chain rod length [m] (symmetric: l_b)"),
        StructField("cos_theta", "double", "[3]", "cos of the drive positions theta_i"),
        StructField("sin_theta", "double", "[3]", "sin of the drive positions theta_i"),
        StructField("singular_tol", "double", "", "relative singularity threshold, e.g. 1e-9"),
        StructField(
            "I_a", "double", "", "crank inertia about the drive axis, rotor + gearbox [kg m^2]"
        ),
        StructField("m_a", "double", "", "crank mass (gravity) [kg]"),
        StructField("r_ca", "double", "", "crank centre of mass from A_i along the crank [m]"),
        StructField("m_b", "double", "", "mass of one rod pair (parallelogram) [kg]"),
        StructField("m_p", "double", "", "platform mass without payload [kg]"),
        StructField("gravity", "double", "[3]", "gravity vector in the base frame [m/s^2]"),
        StructField("I_4", "double", "", "fourth-axis inertia about its axis [kg m^2]"),
    ),
)


def delta_sources() -> dict[str, str]:
    return render(UNIT, [lower(k) for k in all_kernels()])
