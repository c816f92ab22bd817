"""The C of `deltagen export`: a robot's batched module (as in generated/), its single-point
functions and the files around them (example, CMakeLists.txt, Makefile, README), all through
the templates.

The single-point functions (``<prefix>_<kernel>_point``, templates/scalar.{c,h}.j2) print the
same lowered statements as the batched ones: the kernels are derived once, lowered once per
real type (codegen.lowering.lower), and both templates lay out those statements. In double
the two therefore compute the same bits (tests/apps/test_export.py holds them to it). Both
steps are remembered in the build cache (:class:`DiskMemo`): exporting a robot again, in
any process, unpickles them instead (a Puma: 1.8 s instead of 8.4 s).
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
from dataclasses import dataclass, replace

from deltagen.codegen.lowering import lower
from deltagen.codegen.render import Unit, environment, render, render_context
from deltagen.model.naming import check_identifier
from deltagen.paths import cache_dir


class DiskMemo(dict):
    """A memo of this process that is also kept in files of the build cache
    (``DELTAGEN_CACHE``/memo/, one pickle per key), so a later export of the same robot, in
    any process, skips its derivation and lowering (seconds of SymPy each: 4 s and 4 s for a
    Puma). A key missing here is looked for there; one stored here is written there (whole
    or absent: written aside, then renamed). The file names carry a digest of the generator
    (codegen.serial.generator_fingerprint: every file of the stages that shape a derivation
    and its printing) and of the SymPy and Python versions, so a cache kept across upgrades
    never serves a result of other code. A cache that cannot be read or written, or an
    entry that does not unpickle, is a miss, never an error: the memo only saves time."""

    def __init__(self, kind: str):
        super().__init__()
        self.kind = kind
        self._tag: str | None = None

    def _path(self, key):
        if self._tag is None:
            import sympy

            from deltagen.codegen.serial import generator_fingerprint

            words = (self.kind, generator_fingerprint(), sympy.__version__, sys.version)
            self._tag = hashlib.sha256(repr(words).encode()).hexdigest()[:16]
        name = hashlib.sha256(repr((self._tag, key)).encode()).hexdigest()[:24]
        return cache_dir() / "memo" / f"{self.kind}-{name}.pickle"

    def __contains__(self, key) -> bool:
        if super().__contains__(key):
            return True
        try:
            value = pickle.loads(self._path(key).read_bytes())
        except Exception:  # absent, unreadable, or written by an incompatible library
            return False
        super().__setitem__(key, value)
        return True

    def __setitem__(self, key, value) -> None:
        super().__setitem__(key, value)
        path = self._path(key)
        partial = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            partial.write_bytes(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
            os.replace(partial, path)
        except OSError:  # a read-only, full or missing cache: this process keeps it in memory
            try:
                partial.unlink()
            except OSError:
                pass


_KERNELS = DiskMemo("derivation")  # derivations (seconds each), by robot
_LOWERED = DiskMemo("lowered")  # their lowered statements, by robot and real type


def _derived(key, derive) -> tuple:
    """The kernels of ``key`` from the memo, derived (``derive()``) when it has none."""
    if key not in _KERNELS:
        _KERNELS[key] = tuple(derive())
    return _KERNELS[key]


def _derivation_key(kernels):
    """The memo's key of ``kernels`` when they are one of its entries (the very tuple), else
    None. The process holds a few robots' derivations: a scan, not a second index."""
    return next((key for key, value in _KERNELS.items() if value is kernels), None)


def delta_unit_kernels() -> tuple[Unit, tuple]:
    """The delta core's unit and its derived kernels (every kernel the core has)."""
    from deltagen.codegen.delta import UNIT
    from deltagen.derive.delta.kernels import all_kernels

    return UNIT, _derived("delta", all_kernels)


def trilateration_unit_kernels(kind: str) -> tuple[Unit, tuple]:
    """The linear delta's or the tripod's unit and its derived kernels."""
    from deltagen.codegen.linear_delta import LINEAR_UNIT, TRIPOD_UNIT
    from deltagen.derive.linear_delta.kernels import LINEAR, all_kernels

    kernels = _derived(kind, lambda: all_kernels(kind))
    return (LINEAR_UNIT if kind == LINEAR else TRIPOD_UNIT), kernels


def hexapod_unit_kernels() -> tuple[Unit, tuple]:
    """The hexapod core's unit (its extra: fk, the wrapper of the runtime's damped Newton)
    and its derived kernels (ik, jacobian, joint_angles)."""
    from deltagen.codegen.hexapod import UNIT
    from deltagen.derive.hexapod.kernels import all_kernels

    return UNIT, _derived("hexapod", all_kernels)


def machine_unit_kernels(desc) -> tuple[Unit, tuple]:
    """The 5-axis machine module's unit and the kernels of the machine's layout and rotary
    pair (fk, ik, ik_all): the geometry is read from the struct at run time."""
    from deltagen.codegen.five_axis import UNIT
    from deltagen.derive.five_axis.kernels import fk_kernel, ik_all_kernel, ik_kernel

    key = ("machine", desc.layout, desc.rotary)
    kernels = _derived(
        key, lambda: (f(desc.layout, desc.rotary) for f in (fk_kernel, ik_kernel, ik_all_kernel))
    )
    return UNIT, kernels


def arm_unit_kernels(desc) -> tuple[Unit, tuple]:
    """A serial arm's unit and its derived kernels."""
    from deltagen.codegen.serial import arm_unit
    from deltagen.derive.serial.kernels import ArmKernels

    return arm_unit(desc), _derived(("arm", desc.key()), lambda: ArmKernels(desc).all())


@dataclass(frozen=True)
class Package:
    """The C files of an export and what the rest of the package needs to know of them."""

    files: dict  # {file name: text}: module, single-point functions
    cdef: str  # cffi declarations of everything in files (for measurements and tests)
    unit: Unit  # the unit as exported (prefix, struct name, real type's omissions applied)
    functions: tuple  # the template context of each kernel (name, ports, cost, ...)
    real_type: str
    batch: bool
    header: str  # the header a user includes (the single-point one)
    robot_header: str | None  # the encoder wrappers' header, when there are wrappers
    sources: tuple  # the .c files of the package's library (runtime C not included)


def exported_unit(unit: Unit, prefix: str | None, real_type: str) -> Unit:
    """The unit under the user's prefix (functions <prefix>_*, files <prefix>.{c,h},
    struct <prefix>_geometry); in float without the runtime's double-only wrappers (the
    serial ik_newton and forward_dynamics, the hexapod's fk)."""
    if prefix is not None:
        check_identifier(prefix, "prefix")
        unit = replace(
            unit,
            prefix=prefix,
            base_name=prefix,
            struct_name=None if unit.struct_name is None else f"{prefix}_geometry",
        )
    if real_type != "double":  # the runtime's solvers behind these are double
        unit = replace(unit, newton=None, dynamics=None, extras=())
    return unit


def _point_width(width) -> int:
    return 3 if width == "axes" else int(width)


def _point_functions(functions: list, struct: bool) -> list:
    """The function contexts with the fixed row length of one point (3 for the axes ports:
    the single-point functions leave the fourth axis out)."""
    out = []
    for fn in functions:
        fn = dict(fn)
        fn["inputs"] = [
            dict(port.__dict__, point_width=_point_width(port.width), point_shape=_shape(port))
            for port in fn["inputs"]
        ]
        fn["outputs"] = [
            dict(port.__dict__, point_width=_point_width(port.width), point_shape=_shape(port))
            for port in fn["outputs"]
        ]
        pointers = ["geometry"] if struct else []
        pointers += [p["name"] for p in fn["inputs"] if p["point_width"] > 1]
        pointers += [p["name"] for p in fn["outputs"]]
        fn["null_check"] = " || ".join(f"{name} == NULL" for name in pointers)
        fn["loads"] = [dict(d, point_width=_point_width(d["width"])) for d in fn["loads"]]
        fn["stores"] = [dict(d, point_width=_point_width(d["width"])) for d in fn["stores"]]
        out.append(fn)
    return out


def _has_q(ports) -> bool:
    """A port of crank angles (named q, 3 per point) among ``ports`` (point contexts)."""
    return any(port["name"] == "q" and port["point_width"] == 3 for port in ports)


def _shape(port) -> str:
    width = _point_width(port.width)
    return "value" if width == 1 else f"[{width}]"


def package_sources(
    unit: Unit,
    kernels,
    *,
    real_type: str = "double",
    prefix: str | None = None,
    batch: bool = True,
    encoder: tuple = (),
) -> Package:
    """The C files of an export: the batched module (unless ``batch`` is false) and the
    single-point functions, in ``real_type`` ("double" or "float"); ``encoder``: the kernels
    (names) to wrap for a delta robot with encoder offsets (<prefix>_robot_<kernel>: readings
    in and out, templates/robot.{h,c}.j2), none by default."""
    unit = exported_unit(unit, prefix, real_type)
    derivation = _derivation_key(kernels)
    if derivation is None:  # kernels not from the memo: lowered for this call only
        lowered = [lower(k, real_type) for k in kernels]
    else:
        key = (derivation, real_type)
        if key not in _LOWERED:
            _LOWERED[key] = [lower(k, real_type) for k in kernels]
        lowered = _LOWERED[key]
    env, context = render_context(unit, lowered)
    module = render(unit, lowered)
    files: dict = {}
    cdef_parts = []
    if batch:
        files[context["header_name"]] = module[context["header_name"]]
        files[context["source_name"]] = module[context["source_name"]]
        cdef_parts.append(module[context["cdef_name"]])
    point = dict(
        context,
        functions=_point_functions(context["functions"], unit.struct_name is not None),
        batched=batch,
        scalar_header=f"{unit.base_name}_point.h",
        scalar_source=f"{unit.base_name}_point.c",
        scalar_guard=f"DELTAGEN_{unit.base_name.upper()}_POINT_H",
    )
    for name, template, cdef in (
        (point["scalar_header"], "scalar.h.j2", False),
        (point["scalar_source"], "scalar.c.j2", False),
        (None, "scalar.h.j2", True),
    ):
        text = env.get_template(template).render(
            template=template, restrict="", cdef=cdef, struct_in_cdef=not batch, **point
        )
        if name is None:
            cdef_parts.append(text)
        else:
            files[name] = text
    if encoder:
        if unit.struct_name is None:
            raise ValueError("encoder wrappers need a geometry struct (the delta robot)")
        robot = dict(
            point,
            functions=[
                dict(fn, q_in=_has_q(fn["inputs"]), q_out=_has_q(fn["outputs"]))
                for fn in point["functions"]
                if fn["name"] in encoder
            ],
            robot_struct=f"{unit.prefix}_robot",
            robot_header=f"{unit.base_name}_robot.h",
            robot_source=f"{unit.base_name}_robot.c",
            robot_guard=f"DELTAGEN_{unit.base_name.upper()}_ROBOT_H",
            suffix="f" if real_type == "float" else "",
        )
        for name, template in (
            (robot["robot_header"], "robot.h.j2"),
            (robot["robot_source"], "robot.c.j2"),
        ):
            files[name] = env.get_template(template).render(template=template, **robot)
    sources = tuple(n for n in files if n.endswith(".c"))
    return Package(
        files=files,
        cdef="".join(cdef_parts),
        unit=unit,
        functions=tuple(point["functions"]),
        real_type=real_type,
        batch=batch,
        header=point["scalar_header"],
        robot_header=f"{unit.base_name}_robot.h" if encoder else None,
        sources=sources,
    )


def render_extra(template: str, real_type: str, **context) -> str:
    """One of the package's other files (example.c, CMakeLists.txt, Makefile, README.md)
    from its template (templates/export/)."""
    env = environment(real_type)
    return env.get_template(f"export/{template}.j2").render(**{"real": real_type, **context})
