"""`deltagen export ROBOT --out DIR [--float32] [--prefix NAME] [--no-batch]`: a
self-contained C package for a controller.

The folder holds the robot's generated C (codegen/export.py: the batched module as in
generated/ and the single-point functions, both from the same lowered statements), the
runtime C it includes (codegen/runtime/), a CMakeLists.txt, a plain Makefile, an example.c
that evaluates one pose and prints it, and a README with the units, conventions, status codes,
cost and stack use of every function, the example's output and, for --float32, the accuracy
against the double build. A delta robot with encoder offsets (q_offset) also gets wrappers
taking and returning encoder readings (<base>_robot.{c,h}), which the example uses.

The package is written and measured in a folder beside --out and moved into place when
complete. --out may be a new folder or one whose files of the package's names an earlier
export wrote (recorded in its .deltagen-export); other files of those names are refused
without --force. --prefix may not name deltagen's runtime C or the package's other files.

Measurements need a C compiler (``$CC``, else ``cc``); without one the README says what was
not measured. Stack: ``-O2 -fstack-usage`` of the host compiler (the frame of each function;
the batched ones at the default block of 64 points). float32 accuracy: the single-point
functions of the float and of the double build, compiled side by side (cffi), on the delta
report's trajectory (eqs. (40)-(42), 1 kHz for 10 s) or, for a serial arm, on random
configurations within its joint limits.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from deltagen import status as st
from deltagen.errors import DeltagenError
from deltagen.native.toolchain import CORTEX_M4  # the README's Cortex-M4F stack column

#: Unit roundoff of IEEE binary32 (round to nearest): 2^-24.
FLOAT32_ROUNDOFF = 2.0**-24

STATUS_MEANINGS = {
    st.OK: "success: every output finite",
    st.UNREACHABLE: "the pose cannot be reached (fk: the rod spheres do not meet; ik: a target "
    "out of a crank's reach, or no closed-form branch)",
    st.SINGULAR: "a singular pose: outputs the singularity leaves undefined are NaN",
    st.INVALID: "a non-finite input, or finite inputs so large that the arithmetic overflows: "
    "all outputs NaN",
}
#: where a 5-axis machine's kernels say otherwise (derive/five_axis/kernels.py)
MACHINE_STATUS_MEANINGS = {
    st.UNREACHABLE: "not returned: every tool pose has its two rotary branches",
    st.SINGULAR: "the tool axis is parallel to the C axis: C is undetermined and keeps the "
    "previous value (ik, ik_all); every output is given, finite",
    st.INVALID: "a non-finite input, a zero tool axis (ik), or finite inputs so large that the "
    "arithmetic overflows: all outputs NaN",
}
#: where a hexapod's kernels (derive/hexapod/kernels.py) and its fk (the runtime's damped
#: Newton, runtime/deltagen_hexapod_fk.c) say otherwise
HEXAPOD_STATUS_MEANINGS = {
    st.UNREACHABLE: "fk: no convergence within the options' iteration cap (lengths the "
    "platform cannot take, or a start pose outside the solution's basin); not returned by "
    "ik, jacobian, joint_angles",
    st.SINGULAR: "jacobian: a leg shorter than singular_tol * scale (J NaN, the lengths still "
    "given); fk: no convergence with J singular at the last iterate",
    st.INVALID: "a non-finite input, or finite inputs so large that the arithmetic overflows: "
    "all outputs NaN",
}
#: The status meanings per robot kind where they differ from STATUS_MEANINGS.
KIND_STATUS_MEANINGS = {"machine": MACHINE_STATUS_MEANINGS, "hexapod": HEXAPOD_STATUS_MEANINGS}


#: The robot kinds (apps/robots.py) an export serves, in the order messages name them.
KINDS = ("delta", "serial", "linear_delta", "tripod", "hexapod", "machine")


class ExportError(DeltagenError, ValueError):
    """The export cannot be written (a bad option or output folder)."""


@dataclass
class ExportResult:
    out: Path
    files: list
    stack: dict | None  # {function symbol: bytes} measured with -fstack-usage
    example_output: str | None
    accuracy: dict | None  # float32 only: {quantity: (max, rms)} in the units of its label
    notes: list = field(default_factory=list)


# ---------------------------------------------------------------- the robot


def _robot_parts(robot):
    """(kind, unit, kernels) of a DeltaRobot, SerialRobot, LinearDelta, Tripod, Hexapod or
    FiveAxisMachine."""
    from deltagen.api.five_axis import FiveAxisMachine
    from deltagen.api.hexapod import Hexapod
    from deltagen.codegen.export import (
        arm_unit_kernels,
        delta_unit_kernels,
        hexapod_unit_kernels,
        machine_unit_kernels,
        trilateration_unit_kernels,
    )

    if isinstance(robot, Hexapod):  # the batched module's extra: fk (the runtime's Newton)
        unit, kernels = hexapod_unit_kernels()
        return "hexapod", unit, kernels
    if isinstance(robot, FiveAxisMachine):
        unit, kernels = machine_unit_kernels(robot.description)
        return "machine", unit, kernels
    if hasattr(robot, "workspace_extent"):  # LinearDelta, Tripod: kind "linear_delta", "tripod"
        unit, kernels = trilateration_unit_kernels(robot.kind)
        return robot.kind, unit, kernels
    if hasattr(robot, "geometry"):
        unit, kernels = delta_unit_kernels()
        return "delta", unit, kernels
    unit, kernels = arm_unit_kernels(robot.description)
    return "serial", unit, kernels


def _literal(value: float, real: str) -> str:
    text = repr(float(value))
    if real == "float":
        text += "F" if ("." in text or "e" in text) else ".0F"
    return text


def _geometry_struct(robot, kind) -> dict | None:
    """The C parameter struct's fields of a DeltaRobot, LinearDelta, Tripod, Hexapod or 5-axis
    machine (None for an arm: its numbers are compiled in)."""
    if kind == "hexapod":
        from deltagen.native.hexapod import geometry_struct as hexapod_struct

        return hexapod_struct(robot.geometry)
    if kind == "delta":
        from deltagen.native.delta import geometry_struct

        return geometry_struct(robot.geometry)
    if kind == "machine":
        from deltagen.native.five_axis import geometry_struct as machine_struct

        return machine_struct(robot.description)
    if kind in ("linear_delta", "tripod"):
        from deltagen.native.linear_delta import linear_delta_struct, tripod_struct

        fill = linear_delta_struct if kind == "linear_delta" else tripod_struct
        return fill(robot.geometry)
    return None


def _struct_values(robot, real: str, kind: str = "delta") -> list:
    values = []
    for name, value in (_geometry_struct(robot, kind) or {}).items():
        if isinstance(value, (list, tuple)):
            values.append((name, "{" + ", ".join(_literal(v, real) for v in value) + "}"))
        else:
            values.append((name, _literal(value, real)))
    return values


#: The delta example's pose: crank angles [rad] (inside the workspace of the default robot).
DELTA_EXAMPLE_Q = (0.3, 0.5, 0.7)
#: The 5-axis machine example's joints: x, y, z [m], tilt, C [rad].
MACHINE_EXAMPLE_J = (0.05, -0.02, 0.1, 0.4, 0.7)


def _three_sphere_points(robot, n: int, seed: int = 0) -> np.ndarray:
    """Points (n, 3) [m] about the middle of a LinearDelta's or a Tripod's working volume:
    below the carriages' lowest travel within half the tower radius of the axis, or above
    (below) the tripod's base triangle."""
    rng = np.random.default_rng(seed)
    g = robot.geometry
    if robot.kind == "linear_delta":
        lo, arm, r = g.carriage_range[0], min(g.arm_length), 0.5 * min(g.radius)
        z = rng.uniform(lo - 0.6 * arm, lo - 0.2 * arm, n)
        return np.c_[rng.uniform(-r, r, (n, 2)) / math.sqrt(2.0), z]
    centre = np.mean(np.array(g.base_points), axis=0)
    size = 0.25 * min(abs(g.b_x), abs(g.c_y))
    z = g.side_sign * rng.uniform(0.5, 1.0, n) * g.strut_range[1] / 2
    return np.c_[centre[:2] + rng.uniform(-size, size, (n, 2)), z]


def _hexapod_poses(robot, n: int, seed: int = 0) -> np.ndarray:
    """Poses (n, 4, 4) about a Hexapod's home: positions within 0.05 x its size, roll, pitch
    and yaw within 0.1 rad (uniform, ``seed``)."""
    rng = np.random.default_rng(seed)
    home = np.asarray(robot.geometry.home_position, dtype=float)
    p = home + 0.05 * robot.geometry.size * rng.uniform(-1.0, 1.0, (n, 3))
    return robot.pose(p, rpy=rng.uniform(-0.1, 0.1, (n, 3)))


def _example_context(robot, kind, real: str, package) -> tuple[str, dict]:
    """The example's template (templates/export/) and what a family's own template needs
    besides the shared context: the hexapod's example (ik of a shifted, tilted pose and,
    where the package has it, fk of those lengths from home: the batched double module's
    extra) has its own."""
    if kind != "hexapod":
        return "example.c", {}
    from deltagen.apps.hexapod import EXAMPLE_POSITION, EXAMPLE_RPY

    g = robot.geometry
    pose = robot.pose(np.add(g.home_position, EXAMPLE_POSITION), rpy=EXAMPLE_RPY)
    return "hexapod_example.c", dict(
        pose=[_literal(v, real) for v in pose.reshape(-1)],
        home=[repr(float(v)) for v in robot.home.reshape(-1)],
        fk=package.batch and "hexapod_fk" in package.unit.extras,
    )


def _example_pose(robot, kind):
    if kind == "hexapod":
        return [], None
    if kind == "delta":
        return list(DELTA_EXAMPLE_Q), None
    if kind == "machine":
        return list(MACHINE_EXAMPLE_J), None
    if kind in ("linear_delta", "tripod"):
        q = robot.with_backend("reference").ik(_three_sphere_points(robot, 1)[0])
        return [float(v) for v in q], None
    configurations = robot.configurations
    for name in ("qn", "qr", *configurations):
        if name in configurations:
            return [float(v) for v in configurations[name]], name
    return [0.0] * robot.n, None


# ---------------------------------------------------------------- compiling


def compiler() -> str | None:
    """The host C compiler: $CC, else cc, gcc or clang on PATH (None if there is none)."""
    from deltagen.native.toolchain import find_compiler

    return find_compiler()


def _compile(command: list[str], cwd, what: str, name: str) -> None:
    """Run one compile of the package; ExportError with the compiler's own text when it
    fails."""
    from deltagen.native import toolchain

    result = toolchain.run(command, cwd, what)
    if result.returncode != 0:
        text = toolchain.message(result)[-toolchain.MESSAGE_CHARS :]
        raise ExportError(f"{name} could not compile {what}:\n{text}")


def _compile_objects(
    command: list[str], directory: Path, sources, tmp: str, name: str
) -> list[str]:
    """Compile each of ``sources`` (in ``directory``) with ``command`` into an object in
    ``tmp`` (and its .su file: the command carries -fstack-usage); the compilers run at once,
    as many as native/build.py runs (DELTAGEN_BUILD_JOBS, else one per core), the largest
    source first: the package's module takes most of the time. (While the Cortex-M4F set
    runs beside the host's, _write_and_measure, that is up to twice as many: on the 2-core
    VM still 15 s for the Puma against 21-22 s one after another.) Returns the objects in the
    order of ``sources``; ExportError with the compiler's text when one fails."""
    from concurrent.futures import ThreadPoolExecutor

    from deltagen.native import build

    def one(source) -> str:
        obj = str(Path(tmp) / Path(source).with_suffix(".o"))
        _compile([*command, "-c", str(directory / source), "-o", obj], tmp, source, name)
        return obj

    order = sorted(sources, key=lambda source: -(directory / source).stat().st_size)
    with ThreadPoolExecutor(max_workers=build._build_jobs()) as pool:
        objects = dict(zip(order, pool.map(one, order)))
    return [objects[source] for source in sources]


def build_and_measure(directory: Path, sources, cc: str) -> tuple[dict, str]:
    """Compile the package's sources once with ``cc -std=c99 -O2 -fstack-usage``: the stack
    use of every function ({function: (bytes, static|dynamic|bounded)}); then link the
    example with those objects, run it and return its output."""
    from deltagen.native import toolchain

    flags = ["-std=c99", "-O2", "-I", str(directory)]
    with tempfile.TemporaryDirectory(prefix="deltagen-export-") as tmp:
        objects = _compile_objects(
            [*cc.split(), *flags, "-fstack-usage"], directory, sources, tmp, cc
        )
        usage = toolchain.stack_usage(Path(tmp))
        exe = str(Path(tmp) / "example")
        example = str(directory / "example.c")
        link = [*cc.split(), *flags, "-o", exe, example, *objects, "-lm"]
        built = toolchain.run(link, tmp, "the example")
        if built.returncode != 0:
            raise ExportError(f"{cc} could not build the example:\n{built.stderr[-2000:]}")
        return usage, toolchain.run([exe], tmp, "the example").stdout


def stack_cortex_m4(directory: Path, sources) -> dict | None:
    """{function: bytes} of ``arm-none-eabi-gcc -std=c99 -O2 -fstack-usage`` for a
    Cortex-M4F, or None when that compiler is not installed."""
    from deltagen.native import toolchain

    command = toolchain.cortex_m4_command()
    if command is None:
        return None
    with tempfile.TemporaryDirectory(prefix="deltagen-m4-") as tmp:
        cmd = [*command, "-std=c99", "-O2", "-fstack-usage", "-I", str(directory)]
        _compile_objects(cmd, directory, sources, tmp, command[0])
        return {name: nbytes for name, (nbytes, _) in toolchain.stack_usage(Path(tmp)).items()}


def load_package(
    package, directory: Path, build_dir: Path, module_name: str, flags=None, libraries=None
):
    """Compile the package's C (``package.files`` written in ``directory``) into a cffi
    module and import it: for the float32 measurement and the tests (``flags`` and
    ``libraries``: -std=c99 -O2 and libm unless given). Built by the toolchain, which never
    changes the working directory (native/toolchain.py)."""
    import cffi

    from deltagen.native import toolchain

    ffi = cffi.FFI()
    ffi.cdef(package.cdef)
    headers = [n for n in package.files if n.endswith(".h")]
    library = toolchain.build_cffi(
        ffi,
        module_name,
        "".join(f'#include "{h}"\n' for h in headers),
        [directory / s for s in package.sources],
        build_dir,
        include_dirs=[directory],
        flags=list(flags or ["-std=c99", "-O2"]),
        libraries=list(libraries or ["m"]),
    )
    return toolchain.import_extension(module_name, library)


class PointLibrary:
    """Calls the single-point functions of a compiled package, point by point, in its real
    type (inputs rounded to it by cffi, results returned as float64). The output widths of
    each function are its kernel's ports as the package declares them (``package.functions``:
    one point of each output)."""

    def __init__(self, module, prefix: str, real: str, struct: dict | None, package):
        self.ffi, self.lib, self.prefix, self.real = module.ffi, module.lib, prefix, real
        self.out_widths = {
            fn["name"]: [port["point_width"] for port in fn["outputs"]] for fn in package.functions
        }
        self.geometry = None
        if struct is not None:
            self.geometry = self.ffi.new(f"{prefix}_geometry *", struct)

    def __call__(self, name: str, inputs):
        """Evaluate ``name`` on the rows of ``inputs`` (arrays (N, width)); returns the
        outputs (N, width) float64 and the statuses (N,)."""
        out_widths = self.out_widths[name]
        fn = getattr(self.lib, f"{self.prefix}_{name}_point")
        n = len(inputs[0])
        outs = [np.empty((n, w)) for w in out_widths]
        status = np.empty(n, dtype=np.int64)
        args_out = [self.ffi.new(f"{self.real}[{w}]") for w in out_widths]
        for i in range(n):
            args = [
                float(a[i]) if np.ndim(a) == 1 else self.ffi.new(f"{self.real}[]", list(a[i]))
                for a in inputs
            ]
            head = [self.geometry] if self.geometry is not None else []
            status[i] = fn(*head, *args, *args_out)
            for o, buf, w in zip(outs, args_out, out_widths):
                o[i] = self.ffi.unpack(buf, w)
        return (*outs, status)


# ---------------------------------------------------------------- float32 accuracy


def accuracy_points(robot, kind, n_random: int = 2000, seed: int = 0):
    """The points the float32 build is measured on: the delta report's trajectory, eqs.
    (40)-(42), 1 kHz for 10 s (positions p, (N, 3)); for a serial arm ``n_random`` joint
    vectors uniform within its limits (+-pi where a revolute joint has none, +-1 m prismatic)."""
    if kind in ("linear_delta", "tripod"):
        return _three_sphere_points(robot, n_random, seed)
    if kind == "hexapod":  # poses, 16 values each
        return _hexapod_poses(robot, n_random, seed).reshape(-1, 16)
    if kind == "delta":
        from deltagen.apps.validate import sample_times, trajectory

        p, _, _ = trajectory(sample_times(1000.0, 10.0))
        return p[:, :3]
    rng = np.random.default_rng(seed)
    if kind == "machine":  # x, y, z within +-0.5 m, tilt and C within +-pi
        return rng.uniform(-1.0, 1.0, size=(n_random, 5)) * [0.5, 0.5, 0.5, math.pi, math.pi]
    qlim = np.array(robot.qlim, dtype=float)
    lo, hi = qlim[:, 0].copy(), qlim[:, 1].copy()
    revolute = np.array([j.revolute for j in robot.description.joints])
    bad = ~np.isfinite(lo) | ~np.isfinite(hi)
    lo[bad] = np.where(revolute[bad], -math.pi, -1.0)
    hi[bad] = np.where(revolute[bad], math.pi, 1.0)
    return rng.uniform(lo, hi, size=(n_random, robot.n))


def _stats(values) -> tuple[float, float]:
    values = np.asarray(values, dtype=float)
    return float(values.max()), float(math.sqrt(float(np.mean(values**2))))


def float32_accuracy(robot, kind, double_lib: PointLibrary, float_lib: PointLibrary) -> dict:
    """{quantity label: (max, rms)} of the float32 single-point functions against the double
    ones on :func:`accuracy_points` (rows OK in both builds)."""
    points = accuracy_points(robot, kind)
    if kind == "hexapod":
        l_d, s_d = double_lib("ik", [points])
        l_f, s_f = float_lib("ik", [points])
        _, J_d, s_jd = double_lib("jacobian", [points])
        _, J_f, s_jf = float_lib("jacobian", [points])
        ok = (s_d == st.OK) & (s_f == st.OK)
        ok_j = (s_jd == st.OK) & (s_jf == st.OK)
        return {
            "n": int(len(points)),
            "ok": int(np.count_nonzero(ok & ok_j)),
            "ik leg length error [um]": _stats(1e6 * np.abs(l_f - l_d).max(axis=1)[ok]),
            "jacobian error, max |J_f - J_d| entry [1e-6]": _stats(
                1e6 * np.abs(J_f - J_d).max(axis=1)[ok_j]
            ),
        }
    if kind not in ("serial", "machine"):
        q_d, s_qd = double_lib("ik", [points])
        q_f, s_qf = float_lib("ik", [points])
        p_d, s_pd = double_lib("fk", [q_d])
        p_f, s_pf = float_lib("fk", [q_d])  # q_d rounded to float by the call
        p_back, s_back = double_lib("fk", [q_f])  # where the float ik's angles put P
        ok_ik = (s_qd == st.OK) & (s_qf == st.OK) & (s_back == st.OK)
        ok_fk = (s_pd == st.OK) & (s_pf == st.OK)
        return {
            "n": int(len(points)),
            "ok": int(np.count_nonzero(ok_ik & ok_fk)),
            "fk position error [um]": _stats(1e6 * np.linalg.norm(p_f - p_d, axis=1)[ok_fk]),
            ("ik angle error [urad]" if kind == "delta" else "ik joint error [um]"): _stats(
                1e6 * np.abs(q_f - q_d).max(axis=1)[ok_ik]
            ),
            "ik position error, fk(ik(p)) - p [um]": _stats(
                1e6 * np.linalg.norm(p_back - points, axis=1)[ok_ik]
            ),
        }
    if kind == "machine":
        name = robot.description.config
        p_d, d_d, s_d = double_lib(f"{name}_fk", [points])
        p_f, d_f, s_f = float_lib(f"{name}_fk", [points])
        ok = (s_d == st.OK) & (s_f == st.OK)
        return {
            "n": int(len(points)),
            "ok": int(np.count_nonzero(ok)),
            "fk tool tip error [um]": _stats(1e6 * np.linalg.norm(p_f - p_d, axis=1)[ok]),
            "fk tool axis error [urad]": _stats(1e6 * np.linalg.norm(d_f - d_d, axis=1)[ok]),
        }
    T_d, s_d = double_lib("fk", [points])
    T_f, s_f = float_lib("fk", [points])
    ok = (s_d == st.OK) & (s_f == st.OK)
    R_d, R_f = T_d.reshape(-1, 4, 4)[:, :3, :3], T_f.reshape(-1, 4, 4)[:, :3, :3]
    return {
        "n": int(len(points)),
        "ok": int(np.count_nonzero(ok)),
        "fk position error [um]": _stats(
            1e6 * np.linalg.norm(T_f[:, [3, 7, 11]] - T_d[:, [3, 7, 11]], axis=1)[ok]
        ),
        "fk rotation error, max |R_f - R_d| entry [urad]": _stats(
            1e6 * np.abs(R_f - R_d).reshape(len(points), -1).max(axis=1)[ok]
        ),
    }


def _accuracy_text(kind, result) -> str:
    if kind in ("linear_delta", "tripod"):
        where = f"{result['n']} random points of the working volume (seed 0)"
        how = (
            "ik of each point in float and in double; fk in float and in double of the "
            "double ik's joints; and the double fk of the float ik's joints against the point"
        )
    elif kind == "delta":
        where = (
            f"the delta report's trajectory (eqs. (40)-(42), 1 kHz for 10 s: {result['n']} "
            "positions)"
        )
        how = (
            "ik of each position in float and in double; fk in float and in double of the "
            "double ik's angles; and the double fk of the float ik's angles against the "
            "position asked for"
        )
    elif kind == "hexapod":
        where = (
            f"{result['n']} random poses about home (within 0.05 x the size and 0.1 rad, seed 0)"
        )
        how = "ik and the jacobian in float and in double of the same pose"
    elif kind == "machine":
        where = f"{result['n']} random joint vectors (x, y, z within 0.5 m, angles within pi)"
        how = "fk in float and in double of the same joint vector"
    else:
        where = f"{result['n']} random joint vectors within the joint limits (seed 0)"
        how = "fk in float and in double of the same joint vector"
    return (
        f"Measured when exported: the float build's single-point functions against the double "
        f"build's, on {where}: {how} ({result['ok']} points OK in both). For scale: the "
        f"unit roundoff of float is 2^-24 = {FLOAT32_ROUNDOFF:.2e}, i.e. "
        f"{FLOAT32_ROUNDOFF * 1e6:.3f} um per m."
    )


# ---------------------------------------------------------------- the export


def _command(robot_arg, out, float32, prefix, batch) -> str:
    parts = ["deltagen export", str(robot_arg), "--out", str(out)]
    if float32:
        parts.append("--float32")
    if prefix:
        parts += ["--prefix", prefix]
    if not batch:
        parts.append("--no-batch")
    return " ".join(parts)


#: Target names CMake reserves (policy CMP0037 and the targets of its generators and of
#: CTest/CPack): a library target of that name does not configure.
CMAKE_RESERVED = frozenset(
    ("all", "all_build", "clean", "help", "install", "preinstall", "edit_cache",
     "rebuild_cache", "zero_check", "test", "run_tests", "package", "package_source")
)  # fmt: skip

#: Files of every package besides the generated C and the runtime (lower case: a
#: case-insensitive file system holds one of Example.c and example.c)
FIXED_FILES = ("example.c", "CMakeLists.txt", "Makefile", "README.md")

#: The record of what an export wrote into its folder: a later export may replace those
#: files, never others (without --force).
MANIFEST = ".deltagen-export"

_RUNTIME_NAME = re.compile(r"\b(?:deltagen|DELTAGEN)_\w+")


def runtime_identifiers() -> set:
    """Every global name of deltagen's runtime C, lower case (a prefix differing only in
    case still clashes with the macros): its functions, types, macros and include guards
    (codegen/runtime/), and the status codes every module defines."""
    from deltagen.paths import runtime_dir

    names = {f"deltagen_{name.lower()}" for name in st.STATUS_NAMES.values()}
    for path in runtime_dir().glob("deltagen_*.[ch]"):
        names.update(n.lower() for n in _RUNTIME_NAME.findall(path.read_text()))
        names.add(path.stem.lower())
    return names


def check_prefix(prefix: str) -> str:
    """``prefix`` as --prefix: a C identifier whose names (<prefix>_*, the headers' guards
    DELTAGEN_<PREFIX>_H, the files <prefix>*.c|h, the CMake target) cannot be those of
    deltagen's runtime C or of the package's other files; ExportError naming it otherwise."""
    from deltagen.errors import GeometryError
    from deltagen.model.naming import check_identifier

    try:
        check_identifier(prefix, "prefix")
    except GeometryError as exc:
        raise ExportError(str(exc)) from None
    low = prefix.lower()
    runtime = runtime_identifiers()
    guards = [f"deltagen_{low}{part}_h" for part in ("", "_point", "_robot")]
    clashes = sorted(n for n in runtime if n == low or n.startswith(low + "_") or n in guards)
    if clashes:
        shown = ", ".join(clashes[:4]) + (" ..." if len(clashes) > 4 else "")
        raise ExportError(
            f"--prefix {prefix!r} collides with deltagen's runtime C, which the package "
            f"includes ({shown}): choose a prefix that is not deltagen's"
        )
    if low == "example":
        raise ExportError(
            f"--prefix {prefix!r} would name the library's source {prefix}.c, which is the "
            "package's example.c: choose another prefix"
        )
    if low in CMAKE_RESERVED:
        raise ExportError(
            f"--prefix {prefix!r} would name the CMake library target {prefix!r}, which CMake "
            "reserves: choose another prefix"
        )
    return prefix


def _previous_export(out: Path) -> set:
    """The files a previous export recorded in ``out`` (its MANIFEST), lower case."""
    import json

    try:
        record = json.loads((out / MANIFEST).read_text())
        return {str(name).lower() for name in record["files"]}
    except (OSError, ValueError, KeyError, TypeError):
        return set()


def check_out(out: Path, names, force: bool) -> None:
    """``out`` may take the files ``names``: it does not exist, or is a folder where each of
    them is missing or was written by an earlier export (or ``force``)."""
    if out.exists() and not out.is_dir():
        raise ExportError(f"--out {out} exists and is not a folder")
    if not out.is_dir() or force:
        return
    ours = _previous_export(out)
    present = {p.name.lower(): p.name for p in out.iterdir()}
    theirs = sorted(
        present[n.lower()] for n in names if n.lower() in present and n.lower() not in ours
    )
    if theirs:
        raise ExportError(
            f"--out {out} holds files the export would overwrite that no earlier export wrote "
            f"({', '.join(theirs)}): choose another folder, or add --force to overwrite them"
        )


def _publish(tmp: Path, out: Path, names) -> None:
    """Move the finished package from ``tmp`` (beside ``out``) into place: one rename when
    ``out`` does not exist, else file by file (each an atomic replace), its other files left."""
    import json

    (tmp / MANIFEST).write_text(json.dumps({"files": sorted(names)}, indent=1) + "\n")
    if not out.exists():
        os.rename(tmp, out)
        return
    for name in [*names, MANIFEST]:
        os.replace(tmp / name, out / name)
    shutil.rmtree(tmp, ignore_errors=True)


def _encoder_kernels(robot, kind, kernels) -> tuple:
    """The kernels wrapped for encoder readings (a delta robot with encoder offsets): those
    with crank angles among their ports, but not the dynamics, which the API refuses on a
    robot with offsets (api/delta.py: derived for the symmetric robot)."""
    if kind != "delta" or not any(robot.geometry.q_offset):
        return ()
    return tuple(
        k.name
        for k in kernels
        if not k.name.startswith("inverse_dynamics")
        and any(port.name == "q" for port in (*k.inputs, *k.outputs))
    )


def export(
    robot,
    out,
    *,
    float32: bool = False,
    prefix: str | None = None,
    batch: bool = True,
    robot_arg: str | None = None,
    measure: bool = True,
    cortex_m: bool = True,
    force: bool = False,
) -> ExportResult:
    """Write the package of ``robot`` (a DeltaRobot or SerialRobot) into the folder ``out``:
    a new folder, or one whose files of the same names an earlier export wrote (``force``:
    any). The package is written and measured in a folder beside ``out`` and moved into
    place when complete: a failed export leaves ``out`` as it was."""
    from deltagen.codegen.export import package_sources, render_extra
    from deltagen.native.build import runtime_files

    if prefix is not None:
        check_prefix(prefix)
    real = "float" if float32 else "double"
    kind, unit, kernels = _robot_parts(robot)
    encoder = _encoder_kernels(robot, kind, kernels)
    out = Path(out)
    if out.exists() and not out.is_dir():  # before seconds of derivation
        raise ExportError(f"--out {out} exists and is not a folder")
    package = package_sources(
        unit, kernels, real_type=real, prefix=prefix, batch=batch, encoder=encoder
    )
    unit = package.unit

    files: dict = {}
    what: dict = {}
    owner: dict = {}  # lower-case file name -> what produced it (one producer per name)

    def add(name: str, text: str, description: str, source: str) -> None:
        if name.lower() in owner:
            cause = f"--prefix {prefix!r}: " if prefix else ""
            raise ExportError(
                f"{cause}the package's {source} and {owner[name.lower()]} would both be "
                f"written to {name}; choose another prefix"
            )
        owner[name.lower()] = source
        files[name] = text
        what[name] = description

    for name, text in package.files.items():
        point = name.startswith(f"{unit.base_name}_point")
        if name == package.robot_header or name == f"{unit.base_name}_robot.c":
            description = "the functions on encoder readings (this robot's q_offset)"
        else:
            description = "single-point functions" if point else "batched functions"
        if name.endswith(".h"):
            description += ": declarations and documentation"
        add(name, text, description, "generated C")
    runtime = runtime_files(package.files.values())
    if not (batch and real == "double"):  # only the header-only runtime (the joint-limit fit)
        runtime = [p for p in runtime if p.suffix == ".h" and not p.with_suffix(".c").is_file()]
    for path in runtime:
        add(
            path.name,
            path.read_text(),
            "deltagen runtime C (hand-written), used by the generated C",
            "runtime C",
        )
    sources = [n for n in files if n.endswith(".c")]
    library = unit.prefix
    q, q_name = _example_pose(robot, kind)
    symmetric = kind != "delta" or robot.geometry.symmetric
    has_dynamics = any(k.name == "inverse_dynamics" for k in kernels) and (
        kind == "serial" or (kind == "delta" and robot.inertia is not None and symmetric)
    )
    common = dict(
        robot_name=(
            f"the delta robot '{robot.geometry.name}'"
            if kind == "delta"
            else f"the 5-axis machine '{robot.name}'"
            if kind == "machine"
            else f"the hexapod '{robot.geometry.name}'"
            if kind == "hexapod"
            else f"the {kind.replace('_', ' ')} '{robot.name}'"
            if kind != "serial"
            else robot.name
        ),
        library=library,
        sources=sources,
        prefix=unit.prefix,
        header=package.robot_header or package.header,
        real=real,
    )
    example_template, example_context = _example_context(robot, kind, real, package)
    add(
        "example.c",
        render_extra(
            example_template,
            real,
            **common,
            **example_context,
            kind=kind,
            struct_name=unit.struct_name,
            struct_values=_struct_values(robot, real, kind),
            config=robot.description.config if kind == "machine" else "",
            tilt=robot.description.tilt_axis if kind == "machine" else "",
            has_inertia=kind == "delta" and robot.inertia is not None,
            joint_doc={
                "delta": "crank angles [rad], positive down",
                "linear_delta": "carriage heights along the towers [m]",
                "tripod": "strut lengths |AD|, |BD|, |CD| [m]",
            }.get(kind, ""),
            joint_unit="rad" if kind == "delta" else "m",
            has_dynamics=has_dynamics,
            encoder=bool(encoder),
            q_offset=[_literal(v, real) for v in robot.geometry.q_offset] if encoder else [],
            q=[_literal(v, real) for v in q],
            q_name=q_name,
            n=len(q),
            cast="(double)" if real == "float" else "",
            zero="0.0F" if real == "float" else "0.0",
            zeros3=", ".join(["0.0F" if real == "float" else "0.0"] * 3),
        ),
        "evaluates one pose and prints it (`make && ./example`)",
        "example",
    )
    add(
        "CMakeLists.txt",
        render_extra("CMakeLists.txt", real, **common),
        f"CMake: library target `{library}`, example `{library}_example`",
        "CMakeLists.txt",
    )
    add(
        "Makefile",
        render_extra("Makefile", real, **common),
        f"plain make: lib{library}.a and the example",
        "Makefile",
    )
    names = [*files, "README.md"]
    check_out(out, names, force)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        result = _write_and_measure(
            robot, kind, unit, kernels, package, files, what, tmp, out, common,
            real=real, float32=float32, prefix=prefix, batch=batch, robot_arg=robot_arg,
            measure=measure, cortex_m=cortex_m, sources=sources, encoder=encoder,
        )  # fmt: skip
        _publish(tmp, out, names)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return result


def _write_and_measure(
    robot, kind, unit, kernels, package, files, what, tmp, out, common, *, real, float32,
    prefix, batch, robot_arg, measure, cortex_m, sources, encoder,
) -> ExportResult:  # fmt: skip
    """Write ``files`` into ``tmp``, build and measure them there, and add the README."""
    for name, text in files.items():
        (tmp / name).write_text(text)

    from concurrent.futures import ThreadPoolExecutor

    library_sources = [s for s in sources if s != "example.c"]
    cc = compiler() if measure else None
    notes = []
    stack = example_output = accuracy = stack_m4 = None
    # the Cortex-M4 compiles (the longest: ~7 s of a Puma's 15 s) run beside the host's
    with ThreadPoolExecutor(max_workers=1) as background:
        m4 = None
        if measure and cortex_m:
            m4 = background.submit(stack_cortex_m4, tmp.resolve(), library_sources)
        if cc is None:
            if measure:
                notes.append("no C compiler: stack use, example output and accuracy not measured")
        else:
            stack, example_output = build_and_measure(tmp.resolve(), library_sources, cc)
            if float32:
                accuracy = _measure_float32(robot, kind, unit, kernels, prefix, tmp)
        if m4 is not None:
            stack_m4 = m4.result()

    function_rows = []
    symbols = []
    for fn in package.functions:
        if batch:
            symbols.append((f"{unit.prefix}_{fn['name']}", fn["operation_count"]))
        symbols.append((f"{unit.prefix}_{fn['name']}_point", fn["operation_count"]))
    if batch and unit.newton:
        symbols.append((f"{unit.prefix}_ik_newton", "see header"))
    if batch and unit.dynamics:
        symbols.append((f"{unit.prefix}_forward_dynamics", "see header"))
    if batch and "hexapod_fk" in unit.extras:
        symbols.append((f"{unit.prefix}_fk", "see header"))
    for symbol, ops in symbols:
        measured = stack.get(symbol) if stack else None
        text = (
            "-"
            if measured is None
            else f"{measured[0]}" + ("" if measured[1] == "static" else f" ({measured[1]})")
        )
        m4 = stack_m4.get(symbol, "-") if stack_m4 else "-"
        function_rows.append(dict(symbol=symbol, ops=ops, stack=text, stack_m4=m4))
    accuracy_context = None
    if accuracy is not None:
        accuracy_context = dict(
            text=_accuracy_text(kind, accuracy),
            rows=[
                dict(what=k, max=f"{v[0]:.3g}", rms=f"{v[1]:.3g}")
                for k, v in accuracy.items()
                if isinstance(v, tuple)
            ],
        )
    from deltagen import __version__
    from deltagen.codegen.export import render_extra

    what["README.md"] = "this file"
    files["README.md"] = render_extra(
        "README.md",
        real,
        **common,
        title=unit.title,
        command=_command(
            robot_arg or (robot.geometry.name if kind in ("delta", "hexapod") else robot.name),
            out.name,
            float32,
            prefix,
            batch,
        ),
        version=__version__,
        point_header=package.header,
        robot_header=package.robot_header,
        q_offset=list(robot.geometry.q_offset) if encoder else None,
        files=[(n, what[n]) for n in [*files, "README.md"] if n in what],
        folder=out.name,
        compiler=cc,
        example_output=example_output,
        conventions=unit.conventions,
        axes_choices=unit.axes_choices,
        batch=batch,
        status_codes=[
            (
                code,
                name,
                KIND_STATUS_MEANINGS.get(kind, {}).get(code, STATUS_MEANINGS[code]),
            )
            for code, name in sorted(st.STATUS_NAMES.items())
        ],
        stack_note=(
            f"bytes of each function's frame, `{cc} -std=c99 -O2 -fstack-usage` on the host "
            "(batched functions at the default block of 64 points; define "
            f"{unit.prefix.upper()}_BLOCK smaller for small stacks; other compilers and targets "
            "differ)"
            if stack
            else None
        ),
        function_rows=function_rows,
        stack_m4=stack_m4 is not None,
        cortex_m4=" ".join(CORTEX_M4),
        accuracy=accuracy_context,
    )
    (tmp / "README.md").write_text(files["README.md"])
    return ExportResult(
        out=out,
        files=sorted(files),
        stack={k: v[0] for k, v in stack.items()} if stack else None,
        example_output=example_output,
        accuracy=accuracy,
        notes=notes,
    )


def _measure_float32(robot, kind, unit, kernels, prefix, out: Path) -> dict:
    """Compile the float package just written and a double twin side by side and compare."""
    from deltagen.codegen.export import package_sources

    struct = _geometry_struct(robot, kind)
    libraries = {}
    with tempfile.TemporaryDirectory(prefix="deltagen-float32-") as tmp:
        for real in ("double", "float"):
            name = f"_deltagen_export_{real}_{os.getpid()}"
            package = package_sources(
                unit, kernels, real_type=real, prefix=f"m_{real}", batch=False
            )
            directory = Path(tmp) / real
            directory.mkdir()
            for file, text in package.files.items():
                (directory / file).write_text(text)
            module = load_package(package, directory, Path(tmp) / f"build_{real}", name)
            libraries[real] = PointLibrary(module, f"m_{real}", real, struct, package)
        return float32_accuracy(robot, kind, libraries["double"], libraries["float"])


def add_parser(subparsers) -> None:
    """`deltagen export ROBOT --out DIR [--float32] [--prefix NAME] [--no-batch] [--force]`."""
    from deltagen.apps.robots import ROBOT_HELP, add_urdf_options

    x = subparsers.add_parser(
        "export",
        help="standalone C package of a robot for a controller (CMake, Makefile, example)",
        description="Write a self-contained C99 package of the robot: its generated C "
        "(batched and single-point functions), the runtime C it needs, CMakeLists.txt, a "
        "Makefile, example.c and a README with units, status codes, cost, stack use and "
        "(--float32) the accuracy against double.",
    )
    x.add_argument("robot", help="'delta' or " + ROBOT_HELP)
    x.add_argument("--out", required=True, help="folder to write the package into")
    x.add_argument(
        "--float32",
        action="store_true",
        help="float arithmetic (sinf/cosf/sqrtf); the README states the accuracy against double",
    )
    x.add_argument("--prefix", help="C prefix of functions and files (default deltagen_<robot>)")
    x.add_argument(
        "--no-batch", action="store_true", help="single-point functions only (no batched ones)"
    )
    x.add_argument(
        "--force",
        action="store_true",
        help="overwrite files in --out that an earlier export did not write (e.g. your own "
        "Makefile); without it such a folder is refused",
    )
    add_urdf_options(x)


def run(args) -> int:
    """`deltagen export`: the package written (and measured, with a C compiler)."""
    from deltagen.apps.robots import robot_of

    spec = "default" if args.robot == "delta" else args.robot
    # only the description is needed: no compiled core
    robot = robot_of(args, kinds=KINDS, spec=spec, backend="reference")
    result = export(
        robot,
        args.out,
        float32=args.float32,
        prefix=args.prefix,
        batch=not args.no_batch,
        robot_arg=args.robot,
        force=args.force,
    )
    print(f"wrote {len(result.files)} files to {result.out}/: {', '.join(result.files)}")
    for note in result.notes:
        print(f"note: {note}", file=sys.stderr)
    if result.example_output:
        print("example output:")
        print(result.example_output, end="")
    if result.accuracy:
        for key, value in result.accuracy.items():
            if isinstance(value, tuple):
                print(f"float32 {key}: max {value[0]:.3g}, rms {value[1]:.3g}")
    return 0
