"""Emission of the hexapod core: its three kernels (ik, jacobian, joint_angles), lowered
and rendered to generated/, and the fk wrapper of the runtime's damped Newton
(templates/hexapod_fk.c.j2, runtime/deltagen_hexapod_fk.c)."""

from __future__ import annotations

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import Unit, render
from deltagen.derive.hexapod.kernels import all_kernels
from deltagen.model.hexapod import HEXAPOD_PARAMETERS

UNIT = Unit(
    prefix="deltagen_hexapod",
    base_name="hexapod_kinematics",
    title="kinematics of the hexapod (Stewart-Gough platform)",
    source="the leg-vector closure l_i = |p + R b_i - a_i| (derive/hexapod/legs.py)",
    struct_name="deltagen_hexapod_geometry",
    struct_doc="Geometry of the hexapod: the joints of the six legs, the axes of the joints' "
    "cones, the robot's size and the singularity threshold.",
    conventions=(
        "Conventions: SI units (m, rad, s). Arrays are row-major and contiguous, one row per",
        "point. A pose is the 4x4 homogeneous transform of the platform frame in the base",
        "frame, row-major (16 values); twists are (vx, vy, vz, wx, wy, wz) in the base frame.",
    ),
    struct_fields=HEXAPOD_PARAMETERS,
    extras=("hexapod_fk",),
)


def hexapod_sources() -> dict[str, str]:
    return render(UNIT, [lower(k) for k in all_kernels()])
