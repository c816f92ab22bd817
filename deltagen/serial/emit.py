"""Emission of one serial arm's C module (generated/serial_<name>.{c,h,cdef.h})."""

from __future__ import annotations

import hashlib
from pathlib import Path

from ..codegen.lowering import lower
from ..codegen.render import Unit, render
from ..paths import template_dir
from .kernels import ArmKernels


def base_name(desc) -> str:
    return f"serial_{desc.name}"


def description_fingerprint(desc) -> str:
    """Hash of everything in the description that shapes the generated code."""
    return hashlib.sha256(desc.key().encode()).hexdigest()[:16]


def generator_fingerprint() -> str:
    """Hash of the code and templates that turn a description into C: a user robot's cached
    sources are keyed by it, so a changed generator never reuses stale sources."""
    here = Path(__file__).resolve().parent
    files = sorted((here.parent / "codegen").glob("*.py")) + [
        here / "derive.py", here / "kernels.py", here / "emit.py", here / "ik_kernel.py",
        here / "ik_analytic.py"]
    files += sorted(template_dir().glob("*.j2"))
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


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
            f"Description fingerprint: {description_fingerprint(desc)}",
        ),
        newton=dict(n=desc.n, revolute=[int(j.revolute) for j in desc.joints]),
    )


def arm_sources(desc) -> dict[str, str]:
    return render(arm_unit(desc), [lower(k) for k in ArmKernels(desc).all()])
