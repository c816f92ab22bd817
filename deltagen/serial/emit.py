"""Emission of one serial arm's C module (generated/serial_<name>.{c,h,cdef.h})."""

from __future__ import annotations

from ..codegen.lowering import lower
from ..codegen.render import Unit, render
from .kernels import ArmKernels


def base_name(desc) -> str:
    return f"serial_{desc.name}"


def arm_unit(desc) -> Unit:
    joints = ", ".join(f"{'R' if j.revolute else 'P'}" for j in desc.joints)
    return Unit(
        prefix=desc.name,
        base_name=base_name(desc),
        title=f"kinematics of the serial arm '{desc.name}' ({desc.n} joints: {joints}; "
              f"{desc.convention} convention)",
        source="its robot description (deltagen/serial/description.py)",
        struct_name=None,
        struct_fields=(),
        conventions=(
            "Conventions: SI units (m, rad, s). Arrays are row-major and contiguous, one row per",
            f"point: q and qd hold {desc.n} values per point; matrices are stored row-major.",
            "The geometry is compiled in (exact where a value is a multiple of 15 deg or zero).",
        ),
    )


def arm_sources(desc) -> dict[str, str]:
    return render(arm_unit(desc), [lower(k) for k in ArmKernels(desc).all()])
