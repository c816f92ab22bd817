"""Emission of the linear delta's and the tripod's modules: the kernels of
derive/linear_delta/kernels.py, lowered and rendered to generated/ (the geometry in a C
struct: one compiled core for every linear delta, one for every tripod)."""

from __future__ import annotations

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import Unit, render
from deltagen.derive.linear_delta.kernels import LINEAR, TRIPOD, all_kernels
from deltagen.model.linear_delta import LINEAR_DELTA_PARAMETERS, TRIPOD_PARAMETERS

_CONVENTIONS = (
    "Conventions: SI units (m, s). Arrays are row-major and contiguous, one row of 3 per",
    "point.",
)

LINEAR_UNIT = Unit(
    prefix="deltagen_linear_delta",
    base_name="linear_delta_kinematics",
    title="kinematics of the linear delta (three vertical towers)",
    source="the delta report's three-sphere intersection (docs/sources.md) with the carriage "
    "joints as centres; the inverse as Klipper's delta kinematics",
    struct_name="deltagen_linear_delta_geometry",
    struct_doc="Tower positions (x, y) and arm lengths; the carriage of tower i rides at "
    "(tower_x[i], tower_y[i], h_i) and its arm reaches the effector point.",
    conventions=_CONVENTIONS,
    struct_fields=LINEAR_DELTA_PARAMETERS,
)

TRIPOD_UNIT = Unit(
    prefix="deltagen_tripod",
    base_name="tripod_kinematics",
    title="kinematics of the tripod of LinuxCNC's tripodkins (three struts to one point)",
    source="the delta report's three-sphere intersection (docs/sources.md) with the base "
    "points A, B, C as centres; the geometry as LinuxCNC's tripodkins defines it",
    struct_name="deltagen_tripod_geometry",
    struct_doc="Base points A = (0, 0, 0), B = (b_x, 0, 0), C = (c_x, c_y, 0) (tripodkins' "
    "Bx, Cx, Cy) and the side of the base plane the direct kinematics returns.",
    conventions=_CONVENTIONS,
    struct_fields=TRIPOD_PARAMETERS,
)


def linear_delta_sources() -> dict[str, str]:
    return render(LINEAR_UNIT, [lower(k) for k in all_kernels(LINEAR)])


def tripod_sources() -> dict[str, str]:
    return render(TRIPOD_UNIT, [lower(k) for k in all_kernels(TRIPOD)])
