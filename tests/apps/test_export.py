"""`deltagen export`: the standalone C package.

One session fixture exports the default delta robot (double, float32, and double
--no-batch --prefix) and the lecture's SCARA (double and float32); the tests build the
packages in clean folders with only a C compiler (make and CMake), hold the single-point
functions to the batched ones and both to the Python API bit for bit in double, bound the
float32 error over the workspace, and compile every package warning-free with gcc, clang and
arm-none-eabi-gcc (each skipped with a reason when absent).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers import GCC, REPO, core_build_flags, shared_object

from deltagen import DeltaRobot, SerialRobot
from deltagen import status as st
from deltagen.apps import export as ex
from deltagen.codegen.export import arm_unit_kernels, delta_unit_kernels, package_sources
from deltagen.native.build import compile_flags
from deltagen.native.delta import geometry_struct

CC = ex.compiler()
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")

# (robot, export options) of the session's packages
# (measure=False: no stack, example run or accuracy, to keep the fixture short)
EXPORTS = {
    "delta": ("delta", {"cortex_m": False}),
    "delta_f32": ("delta", {"float32": True}),
    "delta_lean": ("delta", {"batch": False, "prefix": "my_delta", "measure": False}),
    "scara": ("lecture_scara", {"cortex_m": False}),
    "scara_f32": ("lecture_scara", {"float32": True, "measure": False}),
}


def _robot(name):
    if name == "delta":
        return DeltaRobot.default()
    return SerialRobot.load(name)


@pytest.fixture(scope="session")
def exports(tmp_path_factory):
    """{key: (robot, ExportResult)} for EXPORTS, written under one temporary folder."""
    root = tmp_path_factory.mktemp("export")
    out = {}
    for key, (name, options) in EXPORTS.items():
        robot = _robot(name)
        out[key] = (robot, ex.export(robot, root / key, robot_arg=name, **options))
    return out


def _clean_copy(src: Path, dst: Path) -> Path:
    """The package alone in a fresh folder: nothing of the repository or the build."""
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("build", "*.o", "*.a", "example"))
    return dst


def _run(cmd, cwd):
    result = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{result.stderr}"
    return result.stdout


def _numbers(line: str) -> list:
    return [float(x) for x in re.findall(r"-?\d+\.\d+", line)]


# ------------------------------------------------------------------ contents


def test_package_contents(exports):
    _, result = exports["delta"]
    names = set(result.files)
    assert {"CMakeLists.txt", "Makefile", "example.c", "README.md"} <= names
    assert {"delta_kinematics.c", "delta_kinematics.h"} <= names
    assert {"delta_kinematics_point.c", "delta_kinematics_point.h"} <= names
    # the batched module is the checked-in one, byte for byte (same templates, same math)
    assert (result.out / "delta_kinematics.c").read_text() == (
        REPO / "generated" / "delta_kinematics.c"
    ).read_text()
    # the SCARA's batched ik_newton needs the runtime: copied beside it
    _, scara = exports["scara"]
    assert {"deltagen_ik_newton.c", "deltagen_linalg.c", "deltagen_linalg.h"} <= set(scara.files)
    readme = (result.out / "README.md").read_text()
    for needed in ("DELTAGEN_UNREACHABLE", "deltagen_delta_ik_point", "stack", "SI units"):
        assert needed in readme


def test_readme_states_stack_per_function(exports):
    """Every function of the float package has a measured stack in its README: the host's
    (cc -fstack-usage) and, where arm-none-eabi-gcc is installed, the Cortex-M4F's."""
    _, result = exports["delta_f32"]
    if result.stack is None:
        pytest.skip("no C compiler: stack not measured")
    readme = (result.out / "README.md").read_text()
    rows = [line for line in readme.splitlines() if line.startswith("| `deltagen_delta_")]
    from deltagen.derive.delta.kernels import all_kernels

    assert len(rows) == 2 * len(all_kernels())  # every kernel, batched and single-point
    m4 = shutil.which("arm-none-eabi-gcc") is not None
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[2].isdigit() and int(cells[2]) > 0, row
        if m4:
            assert cells[3].isdigit() and int(cells[3]) > 0, row
        # single-point functions keep no blocks: far below the batched ones
        if cells[0].endswith("_point`"):
            assert int(cells[2]) < 1024, row


def test_no_batch_is_math_h_only(exports):
    """--no-batch: single-point functions only; no libmvec, no OpenMP, no C library beyond
    <math.h> (stddef.h/stdint.h are the compiler's own freestanding headers)."""
    _, result = exports["delta_lean"]
    c_files = [n for n in result.files if n.endswith((".c", ".h")) and n != "example.c"]
    assert sorted(c_files) == ["my_delta_point.c", "my_delta_point.h"]
    for name in c_files:
        text = (result.out / name).read_text()
        includes = set(re.findall(r'#include [<"]([^>"]+)[>"]', text))
        assert includes <= {"math.h", "stddef.h", "stdint.h", "my_delta_point.h"}, name
        code = re.sub(r'/\*.*?\*/|"[^"\n]*"', "", text, flags=re.DOTALL)  # no comments, strings
        assert not re.search(r"pragma|\bomp\b|mvec", code), name
        assert "for (" not in text  # no loops: one point per call
        assert "deltagen_delta_" not in text  # the prefix reached every symbol
    assert "my_delta_geometry" in (result.out / "my_delta_point.h").read_text()


def test_float32_package_has_no_double(exports):
    _, result = exports["delta_f32"]
    for name in ("delta_kinematics_point.c", "delta_kinematics.c"):
        text = (result.out / name).read_text()
        code = re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL)
        assert "double" not in code, name
        assert "cosf(" in code and "sqrtf(" in code
        assert not re.search(r"\b(cos|sin|sqrt|atan2)\(", code), name


# ------------------------------------------------------------------ builds


@needs_cc
@pytest.mark.parametrize("key", ["delta_f32", "scara"])
def test_builds_and_runs_with_make(exports, key, tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    robot, result = exports[key]
    folder = _clean_copy(result.out, tmp_path / "pkg")
    _run(["make", f"CC={CC}"], folder)
    output = _run(["./example"], folder)
    assert output == result.example_output
    if key.startswith("delta"):  # the example's pose against the Python API
        fk, ik = output.splitlines()[:2]
        numbers = _numbers(fk)
        q, p = np.array(numbers[:3]), np.array(numbers[3:6])
        tol = 1e-5 if key == "delta_f32" else 1e-6  # printed with 6 decimals
        np.testing.assert_allclose(p, robot.fk(q), atol=tol)
        np.testing.assert_allclose(_numbers(ik)[:3], q, atol=tol)
        assert fk.endswith("status 0") and ik.endswith("status 0")


@needs_cc
@pytest.mark.parametrize("key", ["delta"])
def test_builds_and_runs_with_cmake(exports, key, tmp_path):
    if shutil.which("cmake") is None:
        pytest.skip("cmake is not installed")
    _, result = exports[key]
    folder = _clean_copy(result.out, tmp_path / "pkg")
    build = folder / "build"
    _run(["cmake", "-S", str(folder), "-B", str(build), f"-DCMAKE_C_COMPILER={CC}"], folder)
    _run(["cmake", "--build", str(build)], folder)
    assert _run([str(build / "deltagen_delta_example")], folder) == result.example_output


# ------------------------------------------------------------------ warnings


def _compilers():
    found = []
    for name in ("gcc", "clang", "arm-none-eabi-gcc"):
        mark = pytest.mark.skipif(shutil.which(name) is None, reason=f"{name} is not installed")
        found.append(pytest.param(name, marks=mark, id=name))
    return found


@pytest.mark.parametrize("compiler", _compilers())
@pytest.mark.parametrize("key", ["delta_f32", "delta_lean", "scara", "scara_f32"])
def test_compiles_warning_free(exports, key, compiler, tmp_path):
    """The float delta package holds the batched and single-point C of the double one in
    float (the double delta module is generated/'s, compiled -Werror by test_c_standalone);
    the SCARA's double package adds the runtime C and the flag outputs of ik_all. -O1:
    the optimiser's warnings (e.g. maybe-uninitialized) without -O2's compile time."""
    _, result = exports[key]
    flags = ["-std=c99", "-O1", "-Wall", "-Wextra", "-Werror"]
    if key.endswith("f32"):
        flags.append("-Wdouble-promotion")
    if compiler == "arm-none-eabi-gcc":
        flags += ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
    sources = [n for n in result.files if n.endswith(".c")]
    if compiler == "arm-none-eabi-gcc":
        sources.remove("example.c")  # printf needs a target's syscalls: the library only
    for source in sources:
        _run([compiler, *flags, "-I", str(result.out), "-c", str(result.out / source)], tmp_path)


# ------------------------------------------------------------------ bit for bit


@pytest.fixture(scope="session")
def delta_library(exports, tmp_path_factory):
    """The double delta package (batched + single-point) compiled by cffi, plain
    (-std=c99 -O2, libm), as a user builds it."""
    _, result = exports["delta"]
    unit, kernels = delta_unit_kernels()
    package = package_sources(unit, kernels)
    build = tmp_path_factory.mktemp("delta_cffi")
    return ex.load_package(package, result.out, build, "_test_export_delta")


@pytest.fixture(scope="session")
def delta_library_as_core(exports, tmp_path_factory):
    """The same package compiled with the Python core's flags (native.build.compile_flags:
    -O3 -march=native and, on x86-64 Linux, libmvec's vector cos/sin for the batched trig
    loops; the extension flags): the build the Python API runs. Its batched module (the
    checked-in one, byte for byte: test_package_contents) is the object of
    helpers.core_build_flags (these flags plus -pedantic -Werror, which shape no code) that
    tests/c/test_standalone.py compiles warning-free, built once per test run
    (helpers.shared_object); the single-point C and the cffi wrapper are compiled here."""
    from importlib.machinery import EXTENSION_SUFFIXES

    import cffi

    from deltagen.native import toolchain

    _, result = exports["delta"]
    unit, kernels = delta_unit_kernels()
    package = package_sources(unit, kernels)
    flags, libraries = compile_flags(unit.prefix)
    build = tmp_path_factory.mktemp("delta_cffi_core")
    name = "_test_export_delta_core"
    batched = f"{unit.base_name}.c"
    if GCC is None or shutil.which(toolchain.host_compiler()) != GCC:  # not the tests' gcc
        return ex.load_package(package, result.out, build, name, flags, libraries)
    assert batched in package.sources
    obj = shared_object(result.out, batched, core_build_flags(unit.prefix))
    ffi = cffi.FFI()
    ffi.cdef(package.cdef)
    headers = "".join(f'#include "{h}"\n' for h in package.files if h.endswith(".h"))
    wrapper = toolchain.write_cffi_wrapper(ffi, name, headers, build / f"{name}.c")
    library = build / f"{name}{EXTENSION_SUFFIXES[0]}"
    include = [f"-I{result.out}", f"-I{toolchain.python_include()}"]
    toolchain.compile_and_link(
        [wrapper, *(result.out / s for s in package.sources if s != batched)],
        library,
        build,
        [*toolchain.extension_flags(), *flags, *include],
        libraries,
        name,
        prebuilt=[lambda: obj],
    )
    return toolchain.import_extension(name, library)


def _bits(a):
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


@needs_cc
def test_single_point_equals_batched_equals_python_bit_for_bit(
    delta_library, delta_library_as_core, default_robot
):
    """Every kernel of the delta core: the single-point function and the batched function
    of the package give the same bits (same build), and the batched function built with the
    Python core's flags gives the Python API's bits. (The Python core's vector cos/sin of
    libmvec may differ from libm's scalar ones in the last bit, so the plain build matches
    Python to a few ulps only, up to 1e-13 relative after cancellation.)"""
    ffi, lib = delta_library.ffi, delta_library.lib
    core = delta_library_as_core
    robot = default_robot
    rng = np.random.default_rng(14)
    n = 200
    p_goal = np.column_stack(
        [rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-0.95, -0.6, n)]
    )
    q, valid = robot.ik(p_goal, errors="nan")
    q = q[valid]
    n = len(q)
    assert n > 100
    qd = rng.normal(size=(n, 3))
    qdd = rng.normal(size=(n, 3))
    payload = rng.uniform(0, 2, n)
    geometry = ffi.new("deltagen_delta_geometry *", geometry_struct(robot.geometry))
    p, pd, pdd = robot.fk_acc(q, qd, qdd)
    python = {  # kernel: (its inputs, the Python API's outputs)
        "fk": (["q"], [robot.fk(q)]),
        "fk_vel": (["q", "qd"], list(robot.fk_vel(q, qd))),
        "fk_acc": (["q", "qd", "qdd"], list(robot.fk_acc(q, qd, qdd))),
        "jacobian": (["q"], [robot.jacobian(q).reshape(n, 9)]),
        "ik": (["p"], [robot.ik(p)]),
        "inverse_dynamics": (
            ["q", "qd", "qdd", "payload"],
            [robot.inverse_dynamics(q, qd, qdd, payload=payload)],
        ),
        "inverse_dynamics_simplified": (
            ["q", "qd", "qdd", "payload"],
            [robot.inverse_dynamics(q, qd, qdd, payload=payload, model="simplified")],
        ),
    }
    inputs = {"q": q, "qd": qd, "qdd": qdd, "payload": payload, "p": p, "pd": pd, "pdd": pdd}
    _, kernels = delta_unit_kernels()
    assert set(python) <= {k.name for k in kernels}
    for kernel in kernels:  # every kernel the module has (a new one: point = batch at least)
        name = kernel.name
        args = [np.ascontiguousarray(inputs[port.name]) for port in kernel.inputs]
        widths = [3 if port.width == "axes" else int(port.width) for port in kernel.outputs]
        outs = _batched(delta_library, name, robot.geometry, args, widths)
        point = [np.empty((n, w)) for w in widths]
        point_fn = getattr(lib, f"deltagen_delta_{name}_point")
        for i in range(n):
            row_in = [float(a[i]) if a.ndim == 1 else ffi.new("double[]", list(a[i])) for a in args]
            bufs = [ffi.new(f"double[{w}]") for w in widths]
            assert point_fn(geometry, *row_in, *bufs) == st.OK
            for o, b, w in zip(point, bufs, widths):
                o[i] = ffi.unpack(b, w)
        for b, pt in zip(outs, point):
            np.testing.assert_array_equal(_bits(pt), _bits(b), err_msg=f"{name}: point/batch")
        if name not in python:
            continue
        expected = python[name][1]
        as_core = _batched(core, name, robot.geometry, args, widths)
        for e, b, c in zip(expected, outs, as_core):
            np.testing.assert_array_equal(_bits(c), _bits(e), err_msg=f"{name}: core/Python")
            np.testing.assert_allclose(b, e, rtol=1e-13, atol=1e-13 * np.abs(e).max(), err_msg=name)


def _batched(module, name, delta_geometry, args, widths):
    """The package's batched function on all rows (axes 3); asserts every row is OK."""
    ffi, lib = module.ffi, module.lib
    geometry = ffi.new("deltagen_delta_geometry *", geometry_struct(delta_geometry))
    n = len(args[0])
    outs = [np.empty((n, w)) for w in widths]
    status = np.empty(n, dtype=np.int8)
    fb = ffi.from_buffer
    rc = getattr(lib, f"deltagen_delta_{name}")(
        geometry,
        n,
        3,
        *(fb("double[]", a) for a in args),
        *(fb("double[]", o, require_writable=True) for o in outs),
        fb("int8_t[]", status, require_writable=True),
    )
    assert rc == 0
    assert (status == st.OK).all(), name
    return outs


@needs_cc
def test_single_point_status_and_null(delta_library, default_robot):
    """An unreachable point gets its status and NaN; a NULL pointer gets -1."""
    ffi, lib = delta_library.ffi, delta_library.lib
    geometry = ffi.new("deltagen_delta_geometry *", geometry_struct(default_robot.geometry))
    q = ffi.new("double[3]")
    assert lib.deltagen_delta_ik_point(geometry, [0.0, 0.0, -5.0], q) == st.UNREACHABLE
    assert all(math.isnan(v) for v in q)
    assert lib.deltagen_delta_ik_point(geometry, [math.nan, 0.0, -0.8], q) == st.INVALID
    assert lib.deltagen_delta_ik_point(ffi.NULL, [0.0, 0.0, -0.8], q) == -1
    assert lib.deltagen_delta_fk_point(geometry, ffi.NULL, q) == -1


# ------------------------------------------------------------------ float32


def _float_library(result, unit, kernels, tmp, name, struct):
    """The float package's single-point functions alone (--no-batch: the same single-point
    C as the exported package's, asserted; the batched C is not compiled again)."""
    package = package_sources(unit, kernels, real_type="float", batch=False)
    exported = (result.out / package.sources[0]).read_text()
    assert package.files[package.sources[0]] == exported
    for file, text in package.files.items():
        (tmp / file).write_text(text)
    module = ex.load_package(package, tmp, tmp / "build", name)
    return ex.PointLibrary(module, unit.prefix, "float", struct, package)


U = 2.0**-24  # unit roundoff of binary32


@needs_cc
def test_float32_delta_error_bound(exports, default_robot, tmp_path):
    """float32 fk and ik along the report's trajectory against the double Python API.

    The bound, derived before looking at the errors: a kernel of N operations (its cost,
    SymPy's count_ops) commits at most N roundings of relative size u = 2^-24 on quantities no
    larger than the robot's size L = l_a + l_b + r_a; they perturb the closure equations by at
    most N u L, which moves the solution by at most cond(J) times that (J the Jacobian of the
    report's eq. (30), its condition number the worst on the trajectory); rounding the input
    angles to float adds |J| u max|q|. ik errors are measured where they matter, the position
    the float angles reach (double fk of the float ik), by the same argument with ik's N."""
    robot, result = exports["delta_f32"]
    unit, kernels = delta_unit_kernels()
    lib = _float_library(
        result, unit, kernels, tmp_path, "_test_export_f32", geometry_struct(robot.geometry)
    )
    p = ex.accuracy_points(default_robot, "delta")
    q = default_robot.ik(p)
    J = default_robot.jacobian(q)
    cond = float(np.linalg.cond(J).max())
    norm_J = float(np.linalg.norm(J, 2, axis=(1, 2)).max())
    g = robot.geometry
    L = g.l_a + g.l_b + g.r_a
    ops = {fn["name"]: fn["operation_count"] for fn in package_sources(unit, kernels).functions}
    p_f, s_fk = lib("fk", [q])
    q_f, s_ik = lib("ik", [p])
    assert (s_fk == st.OK).all() and (s_ik == st.OK).all()
    fk_error = np.linalg.norm(p_f - default_robot.fk(q), axis=1).max()
    ik_error = np.linalg.norm(default_robot.fk(q_f) - p, axis=1).max()
    fk_bound = ops["fk"] * U * L * cond + norm_J * U * np.abs(q).max()
    ik_bound = ops["ik"] * U * L * cond + U * np.abs(p).max()
    assert fk_error < fk_bound, (fk_error, fk_bound)
    assert ik_error < ik_bound, (ik_error, ik_bound)
    # not vacuous: float is not double (the errors are of the order of u L, not 0)
    assert fk_error > 0.01 * U * L and ik_error > 0.01 * U * L
    # the export measured against its own double build and wrote it down below the bound
    measured = result.accuracy
    assert measured["fk position error [um]"][0] * 1e-6 < fk_bound
    assert measured["ik position error, fk(ik(p)) - p [um]"][0] * 1e-6 < ik_bound
    assert "float32 accuracy" in (result.out / "README.md").read_text()


@needs_cc
def test_float32_serial_error_bound(exports, tmp_path):
    """float32 fk of the SCARA on random configurations against the double Python API.
    Bound: a serial fk is a product of rotations and translations, no equations solved, so
    N operations of the fk kernel, each rounding by at most u a quantity no larger than the
    arm's reach L = sum |a_i| + |d_i|, give |dp| <= N u L, plus L u max|q| from rounding the
    input angles; rotation entries (of size <= 1): N u."""
    robot, result = exports["scara_f32"]
    unit, kernels = arm_unit_kernels(robot.description)
    lib = _float_library(result, unit, kernels, tmp_path, "_test_export_scara_f32", None)
    q = ex.accuracy_points(robot, "serial")
    T_f, status = lib("fk", [q])
    assert (status == st.OK).all()
    T = robot.fk(q)
    L = sum(abs(j.a) + abs(j.d) for j in robot.description.joints)
    ops = {fn["name"]: fn["operation_count"] for fn in package_sources(unit, kernels).functions}
    T_f = T_f.reshape(-1, 4, 4)
    p_error = np.linalg.norm(T_f[:, :3, 3] - T[:, :3, 3], axis=1).max()
    r_error = np.abs(T_f[:, :3, :3] - T[:, :3, :3]).max()
    assert p_error < ops["fk"] * U * L + L * U * np.abs(q).max()
    assert r_error < ops["fk"] * U + U * np.abs(q).max()
    assert p_error > 0.01 * U * L


# ------------------------------------------------------------------ CLI and README


def test_cli_export_and_bad_prefix(tmp_path, capsys):
    from deltagen.cli import main

    out = tmp_path / "prp"
    assert main(["export", "lecture_prp", "--out", str(out), "--no-batch"]) == 0
    assert (out / "serial_lecture_prp_point.h").is_file()
    assert "wrote" in capsys.readouterr().out
    assert main(["export", "delta", "--out", str(tmp_path / "x"), "--prefix", "9bad"]) == 2
    assert "invalid prefix '9bad'" in capsys.readouterr().err


def test_readme_shows_the_real_example_output(exports):
    """README "Running it on a controller": the output it shows is what the exported
    example prints (same command, the default delta robot in double)."""
    _, result = exports["delta"]
    if result.example_output is None:
        pytest.skip("no C compiler: the example was not run")
    text = (REPO / "README.md").read_text()
    section = text.split("## Running it on a controller", 1)[1].split("\n## ", 1)[0]
    for line in result.example_output.splitlines():
        assert line in section, line


# ------------------------------------------------------------------ names and folders


@pytest.mark.parametrize(
    "prefix, says",
    [
        ("example", "example.c"),  # would overwrite the demo (or be overwritten by it)
        ("Example", "example.c"),  # the same file on a case-insensitive file system
        ("deltagen", "runtime C"),  # the runtime's own names
        ("deltagen_ik", "deltagen_ik_newton"),
        ("DELTAGEN_FIT", "deltagen_fit_angle"),
        ("limits", "DELTAGEN_LIMITS_H"),  # the header guard of deltagen_limits.h
        ("all", "CMake"),
    ],
)
def test_cli_refuses_a_prefix_that_collides(tmp_path, capsys, prefix, says):
    """A prefix naming the package's other files or deltagen's runtime symbols: exit 2, a
    message naming the prefix and what it collides with, no folder written."""
    from deltagen.cli import main

    out = tmp_path / "pkg"
    assert main(["export", "lecture_prp", "--out", str(out), "--prefix", prefix]) == 2
    err = capsys.readouterr().err
    assert f"--prefix {prefix!r}" in err and says.lower() in err.lower(), err
    assert "Traceback" not in err
    assert not out.exists()


@needs_cc
def test_a_prefix_that_is_fine_builds(tmp_path, capsys):
    """Not over-eager: a prefix of the user's own namespace (even one containing
    'deltagen') exports and its example builds and runs."""
    from deltagen.cli import main

    out = tmp_path / "pkg"
    assert main(["export", "lecture_prp", "--out", str(out), "--prefix", "my_deltagen"]) == 0
    assert "example output:" in capsys.readouterr().out
    assert (out / "my_deltagen.c").is_file() and (out / "example.c").is_file()


def test_out_with_the_users_files_needs_force(tmp_path, capsys):
    """--out on a folder holding the user's own Makefile: refused (exit 2, the file named,
    nothing touched) without --force; with --force overwritten, the user's other files
    kept. A folder an earlier export wrote is exported into again without --force."""
    from deltagen.cli import main

    out = tmp_path / "mine"
    out.mkdir()
    (out / "Makefile").write_text("my makefile\n")
    (out / "notes.txt").write_text("my notes\n")
    args = ["export", "lecture_prp", "--out", str(out), "--no-batch"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Makefile" in err and "--force" in err and "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == ["Makefile", "notes.txt"]
    assert (out / "Makefile").read_text() == "my makefile\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".mine")]  # no leftovers
    assert main([*args, "--force"]) == 0
    assert "deltagen export" in (out / "Makefile").read_text()
    assert (out / "notes.txt").read_text() == "my notes\n"
    assert main(args) == 0  # its own earlier export: no --force needed
    capsys.readouterr()


def test_a_failed_cortex_m4_compile_fails_the_export_as_the_host_one_does(
    tmp_path, monkeypatch, capsys
):
    """The Cortex-M4F stack compiles run beside the host's (apps/export.py
    _write_and_measure): one that fails there is the same clear exit 2, naming the
    compiler, with no traceback and no folder left, while the host's build succeeds."""
    from deltagen.cli import main

    if ex.compiler() is None:
        pytest.skip("no host C compiler: the export measures nothing")
    fake = tmp_path / "bin" / "arm-none-eabi-gcc"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\necho 'arm-none-eabi-gcc: no such target' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    out = tmp_path / "work" / "pkg"
    assert main(["export", "lecture_prp", "--out", str(out), "--no-batch"]) == 2
    err = capsys.readouterr().err
    assert "arm-none-eabi-gcc could not compile" in err and "no such target" in err, err
    assert "Traceback" not in err
    assert not out.exists()
    assert list(out.parent.iterdir()) == []


def test_a_failed_export_leaves_no_folder(tmp_path, monkeypatch, capsys):
    """A compiler that fails while the export measures its package: exit 2 naming the
    failure, and neither the folder nor a temporary one beside it is left."""
    from deltagen.cli import main

    fail = tmp_path / "bin" / "failcc"
    fail.parent.mkdir()
    fail.write_text("#!/bin/sh\necho 'failcc: no' >&2\nexit 1\n")
    fail.chmod(0o755)
    monkeypatch.setenv("CC", str(fail))
    out = tmp_path / "work" / "pkg"
    assert main(["export", "lecture_prp", "--out", str(out), "--no-batch"]) == 2
    err = capsys.readouterr().err
    assert "could not compile" in err and "Traceback" not in err
    assert not out.exists()
    assert list(out.parent.iterdir()) == []
