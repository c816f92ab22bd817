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
# stages and the foundation modules; tests/integration/test_layering.py holds the rule):
# every file in them is hashed, so no hand-kept list can miss one.
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


def arm_unit(desc, part: str = "all") -> Unit:
    """The module's frame; ``part``: "all" (every kernel) or one of the parts a new arm's
    module is built in (derive.serial.parts.PARTS): "first" (fk, frames, jacobian,
    fk_jacobian and the numerical IK), "later" (jacobian_dot, ik_all), "dynamics" (inverse
    dynamics, g), "mass" (M, h and the forward dynamics), "coriolis"."""
    from deltagen.codegen.render import Unit

    joints = ", ".join(f"{'R' if j.revolute else 'P'}" for j in desc.joints)
    dynamics = desc.has_inertia and part in ("all", "dynamics", "mass", "coriolis")
    title = {
        "all": "kinematics" + (" and dynamics" if desc.has_inertia else ""),
        "first": "first-load kinematics (fk, frames, jacobian, fk_jacobian, ik_newton)",
        "later": "deferred kinematics (jacobian_dot, closed-form ik_all)",
        "dynamics": "inverse dynamics and gravity torque",
        "mass": "mass matrix, nonlinear effects and forward dynamics",
        "coriolis": "Coriolis matrix",
    }[part]
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
                if dynamics
                else ()
            ),
            f"Description fingerprint: {description_fingerprint(desc)}",
        ),
        newton=(
            dict(n=desc.n, revolute=[int(j.revolute) for j in desc.joints])
            if part in ("all", "first")
            else None
        ),
        dynamics=(
            dict(n=desc.n, tol=repr(MASS_MATRIX_TOL))
            if desc.has_inertia and part in ("all", "mass")
            else None
        ),
        packed_blocks=True,
        # 16 points per block, not 64: a block's arrays (the Jacobian's 36 output columns,
        # 6 angles, their cosines and sines: 28 KB at 64) then stay well inside L1 beside
        # the rows being written. Measured on 100000 rows (Zen 4, in-process A/B, thread
        # CPU time, min of 30): Puma fk 32.0 -> 19.6 ns per point, jacobian 44.9 -> 28.9,
        # inverse dynamics 41.0 -> 28.7; on 1024 rows the same or 2-7 % less; 8 points
        # was slower at 1024 rows (one vector per loop: the loop overheads show)
        block=16,
    )


def arm_sources(desc, part: str = "all") -> dict[str, str]:
    """The arm's C module: every kernel (``part="all"``: what `deltagen generate` writes),
    or one part of it (derive.serial.parts.PARTS; native/serial.py builds a new arm's
    module part by part, each on the first call of one of its kernels): only that part's
    kernels are derived, lowered and compiled."""
    from deltagen.codegen.lowering import lower
    from deltagen.codegen.render import render
    from deltagen.derive.serial.kernels import ArmKernels

    chosen = ArmKernels(desc).part(part)
    return render(arm_unit(desc, part), [lower(k) for k in chosen])
