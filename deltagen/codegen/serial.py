"""Emission of one serial arm's C module (generated/serial_<name>.{c,h,cdef.h})."""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import TYPE_CHECKING

from deltagen.status import MASS_MATRIX_TOL

if TYPE_CHECKING:
    from deltagen.codegen.render import Unit

# lowering, render and the derivation import SymPy (about 1 s): they are imported where a
# module is rendered, so loading an arm whose module is already built does not pay for them


def base_name(desc) -> str:
    return f"serial_{desc.name}"


def c_prefix(desc) -> str:
    """The prefix of the arm's C functions: ``deltagen_<name>``, so that two arms, the delta
    core (``deltagen_delta_*``) and a user's own code do not clash. An arm named ``delta``
    (in any case) becomes ``deltagen_<name>_arm``: its fk and jacobian would be the core's."""
    if desc.name.lower() == "delta":
        return f"deltagen_{desc.name}_arm"
    return f"deltagen_{desc.name}"


def description_fingerprint(desc) -> str:
    """Hash of everything in the description that shapes the generated code."""
    return hashlib.sha256(desc.key().encode()).hexdigest()[:16]


# What the generated text can depend on, by the layering rule (codegen imports only these
# stages and the foundation modules; tests/test_layering.py holds the rule): every file in
# them is hashed, so no hand-kept list can miss one.
_GENERATOR_PACKAGES = ("model", "geometry", "derive", "codegen")
_FOUNDATION = ("errors.py", "status.py", "inputs.py", "paths.py")


def generator_files() -> list[Path]:
    """Every file whose content can shape a generated module: the Python of the stages
    codegen may import, its templates and runtime C."""
    package = Path(__file__).resolve().parent.parent
    files = [package / name for name in _FOUNDATION]
    for stage in _GENERATOR_PACKAGES:
        files += [
            f
            for f in (package / stage).rglob("*")
            if f.is_file() and f.suffix in (".py", ".j2", ".c", ".h")
        ]
    return sorted(files)


@functools.lru_cache(maxsize=1)
def generator_fingerprint() -> str:
    """Hash of the code, templates and runtime C that turn a description into C: a user
    robot's cached sources are keyed by it, so a changed generator never reuses stale
    sources. Computed once per process (the Python of the generator is loaded once too;
    a warm load asks for it up to three times, 10 ms each)."""
    package = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for path in generator_files():
        digest.update(path.relative_to(package).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def arm_unit(desc, first: bool = False) -> Unit:
    """The module's frame; ``first``: the module a new arm loads with (ArmKernels.first:
    fk, frames, jacobian, fk_jacobian and the numerical IK, no dynamics)."""
    from deltagen.codegen.render import Unit

    joints = ", ".join(f"{'R' if j.revolute else 'P'}" for j in desc.joints)
    title = "kinematics" + (" and dynamics" if desc.has_inertia and not first else "")
    if first:
        title = "first-load kinematics (fk, frames, jacobian, fk_jacobian, ik_newton)"
    return Unit(
        prefix=c_prefix(desc),
        base_name=base_name(desc),
        title=f"{title} of the serial arm '{desc.name}' ({desc.n} joints: {joints}; "
        f"{desc.convention} convention)",
        source="its robot description (deltagen/model/serial.py)",
        struct_name=None,
        struct_fields=(),
        conventions=(
            "Conventions: SI units (m, rad, s). Arrays are row-major and contiguous, one row per",
            f"point: q and qd hold {desc.n} values per point; matrices are stored row-major.",
            "The geometry is compiled in (exact where a value is a multiple of 15 deg or zero).",
            *(
                (
                    "Dynamics: masses in kg, torques in N m (forces in N for prismatic joints);",
                    f"gravity {list(desc.gravity)} m/s^2 in the base frame; inertial parameters",
                    "compiled in (link frame i = the frame after A_i).",
                )
                if desc.has_inertia and not first
                else ()
            ),
            f"Description fingerprint: {description_fingerprint(desc)}",
        ),
        newton=dict(n=desc.n, revolute=[int(j.revolute) for j in desc.joints]),
        dynamics=(
            dict(n=desc.n, tol=repr(MASS_MATRIX_TOL)) if desc.has_inertia and not first else None
        ),
    )


def arm_sources(desc, first: bool = False) -> dict[str, str]:
    """The arm's C module: every kernel (what `deltagen generate` writes), or with
    ``first`` only those a new arm loads with (ArmKernels.first; native/serial.py builds
    the complete module on the first call of another kernel)."""
    from deltagen.codegen.lowering import lower
    from deltagen.codegen.render import render
    from deltagen.derive.serial.kernels import ArmKernels

    kernels = ArmKernels(desc)
    chosen = kernels.first() if first else kernels.all()
    return render(arm_unit(desc, first), [lower(k) for k in chosen])
