"""`deltagen export` of every robot deltagen ships, and a calibrated robot end to end.

Every bundled arm (robots/*.toml with a convention, robots/*.urdf), every bundled 5-axis
machine (robots/*.toml with a [machine] table), the delta robot and a
URDF arm written here (the path of a robot file that is not bundled), each in double and in
float32: the package alone in a clean folder builds with its Makefile and with its
CMakeLists.txt, its example runs, and the numbers it prints are the Python API's (the
numpy reference backend: independent of the C). Each robot is derived and lowered once
per run (codegen.export.DiskMemo keeps both in the suite's build cache, which every process
of the run shares); each package compiles once, at -O0 to keep the compile
time down (the runtime C, the same files in every arm's package, once per session for each
content: LAUNCHER's runtime mode): the numbers are compared at the example's print
precision, and the bit-level agreement of the optimised builds is
tests/apps/test_export.py's. The CMake build of a package reuses the objects its make build
compiled from the same files with the same code-shaping flags (LAUNCHER's reuse mode, in
the manner of ccache: CMake still configures, compiles every other file, archives, links
and runs the example); on its own (the make cell not run) it compiles everything. Its
build folder starts with CMake's record of the compiler (cmake_platform: the compiler
identification and ABI probes, made once per session), as a folder configured before has
it; the configure of a clean folder from nothing is tests/apps/test_export.py's
test_builds_and_runs_with_cmake.

Then the calibration workflow: `deltagen calibrate` on synthetic measurements of a robot
with encoder offsets writes a robot file; `deltagen export` of that file, built with make,
gives the numbers of `deltagen fk` and DeltaRobot.ik on the written file to 1e-12 (built
at -O0 as well).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot
from deltagen import status as st
from deltagen.api.five_axis import FiveAxisMachine, bundled_machines
from deltagen.api.serial import bundled_robots, bundled_urdfs
from deltagen.apps import export as ex

CC = ex.compiler()
MAKE = shutil.which("make")
CMAKE = shutil.which("cmake")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")

# A URDF arm that is not bundled: tilted origins, a reversed axis, a prismatic joint and
# inertials, so its package has the closed-form-free kinematics, ik_newton and dynamics.
URDF_ARM = """<?xml version="1.0"?>
<robot name="export_arm">
  <link name="base"/>
  <link name="l1">
    <inertial><origin xyz="0 0 0.1"/><mass value="2.0"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.01"/></inertial>
  </link>
  <link name="l2">
    <inertial><origin xyz="0.15 0 0"/><mass value="1.5"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
  </link>
  <link name="l3">
    <inertial><origin xyz="0.05 0 0"/><mass value="0.8"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.004"/></inertial>
  </link>
  <link name="tool"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/><origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0.05 0.2" rpy="0.3 0 0.2"/>
    <axis xyz="0 -1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="j3" type="prismatic">
    <parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.2" effort="1" velocity="1"/>
  </joint>
  <joint name="tool_mount" type="fixed">
    <parent link="l3"/><child link="tool"/><origin xyz="0.1 0 0" rpy="0 0.5 0"/>
  </joint>
</robot>
"""

# delta_built: a delta robot as built (per-chain lengths, encoder offsets): its package
# has the wrappers on encoder readings, which its example calls
ROBOTS = [
    "delta",
    "delta_built",
    *bundled_robots(),
    *bundled_urdfs(),
    "urdf_arm",
    *bundled_machines(),
]
CASES = [(name, real) for name in ROBOTS for real in ("double", "float")]


def _ids(case):
    return f"{case[0]}-{case[1]}"


@pytest.fixture(scope="session")
def urdf_arm_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("urdf_arm") / "export_arm.urdf"
    path.write_text(URDF_ARM)
    return path


def _load(name, urdf_arm_file):
    """The robot on the reference backend (the oracle), and its CLI argument."""
    if name == "delta":
        return DeltaRobot.default(backend="reference")
    if name == "delta_built":
        nominal = DeltaRobot.default(backend="reference").geometry
        built = nominal.with_chains(l_b=(0.801, 0.7995, 0.8), q_offset=(0.04, -0.03, 0.02))
        return DeltaRobot.from_geometry(built, backend="reference")
    if name == "urdf_arm":
        return SerialRobot.from_urdf(urdf_arm_file, backend="reference")
    if name in bundled_machines():
        return FiveAxisMachine.load(name, backend="reference")
    return SerialRobot.load(name, backend="reference")


@pytest.fixture(scope="session")
def packages(tmp_path_factory, urdf_arm_file):
    """{(robot, real): (robot, ExportResult)}, exported on first use (measure=False: no
    compiler run inside the export; the tests build)."""
    root = tmp_path_factory.mktemp("export_robots")
    made: dict = {}

    def get(name, real):
        if (name, real) not in made:
            robot = _load(name, urdf_arm_file)
            out = root / f"{name}_{real}"
            result = ex.export(robot, out, float32=real == "float", measure=False, cortex_m=False)
            made[name, real] = (robot, result)
        return made[name, real]

    return get


# A compiler launcher in the manner of ccache, `LAUNCHER MODE CC ARGS...`, in two modes:
# - reuse (CMAKE_C_COMPILER_LAUNCHER of the CMake cells): the object of a source is copied
#   from the folder the make cell of the same package built (DELTAGEN_MADE_PACKAGE) when
#   every .c and .h there is byte-identical to the CMake build's and the flags that shape
#   code (all but -I, -W, -M and -o/-c) are the ones recorded there (.flags);
# - runtime ($(CC) of the make cells): the runtime C (deltagen_*.c, copied into every
#   package that needs it) is compiled once per session for each content and flags, its
#   object kept in DELTAGEN_RUNTIME_OBJECTS under a digest of the compiler, those flags and
#   the names and texts of the source and the local headers it includes (transitively).
# Everything else runs the compiler.
LAUNCHER = r"""#!/bin/sh
LC_ALL=C
export LC_ALL
mode=$1
cc=$2
shift 2
out=
src=
flags=
skip=
for a in "$@"; do
    if [ -n "$skip" ]; then
        [ "$skip" = o ] && out=$a
        skip=
        continue
    fi
    case "$a" in
        -o) skip=o ;;
        -MT | -MF | -MQ) skip=m ;;
        -c | -MD | -MMD | -I* | -W*) ;;
        *.c) src=$a ;;
        *) flags="$flags $a" ;;
    esac
done
if [ -z "$src" ] || [ -z "$out" ]; then
    exec "$cc" "$@"
fi
if [ "$mode" = reuse ]; then
    store="$DELTAGEN_MADE_PACKAGE"
    name=$(basename "$src" .c)
    shaped=$(printf '%s\n' $flags | sort | tr '\n' ' ')
    same=yes
    [ -n "$store" ] && [ -f "$store/$name.o" ] && [ "$shaped" = "$(cat "$store/.flags")" ] || same=
    for f in "$(dirname "$src")"/*.[ch]; do
        [ -n "$same" ] && cmp -s "$f" "$store/$(basename "$f")" || same=
    done
    if [ -n "$same" ]; then
        cp "$store/$name.o" "$out" && exit 0
    fi
    exec "$cc" "$@"
fi
store="$DELTAGEN_RUNTIME_OBJECTS"
case "$src" in
    deltagen_*.c | */deltagen_*.c) ;;
    *) exec "$cc" "$@" ;;
esac
if [ -z "$store" ] || ! command -v md5sum >/dev/null; then
    exec "$cc" "$@"
fi
dir=$(dirname "$src")
deps=$src
todo=$src
while [ -n "$todo" ]; do
    next=
    for f in $todo; do
        for h in $(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f"); do
            case " $deps " in
                *" $dir/$h "*) ;;
                *) if [ -f "$dir/$h" ]; then deps="$deps $dir/$h"; next="$next $dir/$h"; fi ;;
            esac
        done
    done
    todo=$next
done
key=$({
    printf '%s\n' "$cc" $flags
    for f in $deps; do
        basename "$f"
        cat "$f"
    done
} | md5sum | cut -c1-32)
if [ -f "$store/$key.o" ]; then
    cp "$store/$key.o" "$out" && exit 0
fi
"$cc" "$@" || exit $?
cp "$out" "$store/.$key.$$" && mv "$store/.$key.$$" "$store/$key.o"
"""


@pytest.fixture(scope="session")
def launcher(tmp_path_factory) -> tuple[Path, Path]:
    """(LAUNCHER written out, the empty store of its runtime mode)."""
    folder = tmp_path_factory.mktemp("launcher")
    path = folder / "launcher.sh"
    path.write_text(LAUNCHER)
    path.chmod(0o755)
    (folder / "store").mkdir()
    return path, folder / "store"


def _shaping(flags: str) -> str:
    """The flags of a compile that shape the object (LAUNCHER's .flags)."""
    return "".join(f"{f} " for f in sorted(flags.split()) if not f.startswith(("-W", "-I")))


#: (robot, real) -> the folder its make cell built (objects for the CMake cell)
MADE: dict = {}


def _clean_copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _run(cmd, cwd, env=None):
    result = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600, env=env)
    assert result.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{result.stderr[-3000:]}"
    return result.stdout


def _numbers(line: str) -> np.ndarray:
    return np.array([float(x) for x in re.findall(r"-?\d+\.\d+", line)])


def _check_example(robot, output: str, real: str) -> None:
    """The example's printed numbers against the reference API (print precision: 6
    decimals for poses, 4 for torques; float adds its own rounding)."""
    lines = output.splitlines()
    atol = 1e-6 if real == "double" else 2e-5
    if isinstance(robot, FiveAxisMachine):  # fk of the example's joints, then ik back
        j = np.array(ex.MACHINE_EXAMPLE_J)
        fk, ik = _numbers(lines[0]), _numbers(lines[1])
        p, d = robot.fk(j)
        np.testing.assert_allclose(fk[:3], p, atol=atol)
        np.testing.assert_allclose(fk[3:6], d, atol=atol)
        np.testing.assert_allclose(ik[:5], j, atol=atol)
        assert lines[0].endswith("status 0") and lines[1].endswith("status 0"), output
        return
    if isinstance(robot, DeltaRobot):
        fk, ik = _numbers(lines[0]), _numbers(lines[1])
        q, p = fk[:3], fk[3:6]
        np.testing.assert_allclose(p, robot.fk(q), atol=atol)
        np.testing.assert_allclose(ik[:3], q, atol=atol)
        assert lines[0].endswith("status 0") and lines[1].endswith("status 0"), output
        torque = [line for line in lines if line.startswith("holding torque")]
        if robot.inertia is None or not robot.geometry.symmetric:
            assert not torque, output  # no dynamics the API would refuse
        else:
            tau = robot.inverse_dynamics(q, np.zeros(3), np.zeros(3))
            assert torque, output
            np.testing.assert_allclose(
                _numbers(torque[0])[:3],
                tau,
                atol=1e-4 + (0 if real == "double" else 1e-5) * abs(tau).max(),
            )
        return
    q, _ = ex._example_pose(robot, "serial")
    T = robot.fk(np.array(q))
    position, rotation = _numbers(lines[0]), _numbers(lines[1])
    np.testing.assert_allclose(position[:3], T[:3, 3], atol=atol)
    np.testing.assert_allclose(rotation.reshape(3, 3), T[:3, :3], atol=atol)
    assert lines[0].endswith("status 0"), output
    torque = [line for line in lines if line.startswith("holding torque")]
    if robot.description.has_inertia:
        assert torque, output
        tau = robot.inverse_dynamics(np.array(q), np.zeros(robot.n), np.zeros(robot.n))
        tol = 1e-4 + (0 if real == "double" else 1e-5) * float(np.abs(tau).max())
        np.testing.assert_allclose(_numbers(torque[0])[: robot.n], tau, atol=tol)
        assert torque[0].endswith("status 0"), output


@pytest.mark.slow  # every robot: about two minutes of derivation and compiling
@pytest.mark.skipif(MAKE is None, reason="make is not installed")
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_every_robot_builds_with_make_and_prints_the_api_numbers(
    packages, case, tmp_path, launcher
):
    robot, result = packages(*case)
    folder = _clean_copy(result.out, tmp_path / "pkg")
    flags = "-std=c99 -O0 -Wall -Wextra" + (" -Wdouble-promotion" if case[1] == "float" else "")
    script, store = launcher
    env = dict(os.environ, DELTAGEN_RUNTIME_OBJECTS=str(store))
    _run([MAKE, "-j2", f"CC={script} runtime {CC}", f"CFLAGS={flags}"], folder, env)
    _check_example(robot, _run(["./example"], folder), case[1])
    (folder / ".flags").write_text(_shaping(flags))
    MADE[case] = folder


@pytest.fixture(scope="session")
def cmake_platform(tmp_path_factory) -> Path:
    """CMake's record of the compiler (build/CMakeFiles/<version>/: what `project(... C)`
    determines by compiling and running CMakeCCompilerId.c and the ABI probe), made once per
    session by configuring an empty C project with the cells' compiler."""
    root = tmp_path_factory.mktemp("cmake_platform")
    (root / "CMakeLists.txt").write_text("cmake_minimum_required(VERSION 3.10)\nproject(probe C)\n")
    _run([CMAKE, "-S", str(root), "-B", str(root / "build"), f"-DCMAKE_C_COMPILER={CC}"], root)
    found = [p.parent for p in (root / "build" / "CMakeFiles").glob("*/CMakeCCompiler.cmake")]
    assert len(found) == 1, found
    return found[0]


@pytest.mark.slow
@pytest.mark.skipif(CMAKE is None, reason="cmake is not installed")
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_every_robot_builds_with_cmake_and_prints_the_api_numbers(
    packages, case, tmp_path, launcher, cmake_platform
):
    robot, result = packages(*case)
    folder = _clean_copy(result.out, tmp_path / "pkg")
    build = folder / "build"
    # the compiler's record copied in, as CMake keeps it in a build folder configured before
    # (CMAKE_PLATFORM_INFO_INITIALIZED: read it instead of probing the compiler again)
    shutil.copytree(cmake_platform, build / "CMakeFiles" / cmake_platform.name)
    env = dict(os.environ, DELTAGEN_MADE_PACKAGE=str(MADE.get(case, "")))
    _run(
        [CMAKE, "-S", str(folder), "-B", str(build), f"-DCMAKE_C_COMPILER={CC}",
         "-DCMAKE_BUILD_TYPE=", "-DCMAKE_C_FLAGS=-O0", "-DCMAKE_PLATFORM_INFO_INITIALIZED=1",
         f"-DCMAKE_C_COMPILER_LAUNCHER={launcher[0]};reuse"],
        folder, env,
    )  # fmt: skip
    _run([CMAKE, "--build", str(build), "-j2"], folder, env)
    example = build / f"{_library(result)}_example"
    _check_example(robot, _run([str(example)], folder), case[1])


def _library(result) -> str:
    """The package's library (CMake target) name, from its Makefile."""
    text = (result.out / "Makefile").read_text()
    return re.search(r"^lib(\w+)\.a:", text, re.MULTILINE).group(1)


# ------------------------------------------------------------------ includes

_CALL = re.compile(r"\b(deltagen_\w+)\s*\(")


def _declared(header_text: str) -> set:
    return set(re.findall(r"^[A-Za-z_][\w \t]*?[ \t*](deltagen_\w+)\s*\(", header_text, re.M))


def test_every_runtime_call_has_its_include(repo_root):
    """Every runtime function a generated C file calls is declared by a runtime header the
    file includes (itself or through its own headers): generated/*.c and the single-point C
    of a package whose ik_all fits angles into joint limits (the Manutec h5's), in double
    and float."""
    from deltagen.codegen.export import arm_unit_kernels, package_sources
    from deltagen.paths import runtime_dir

    headers = {p.name: p.read_text() for p in runtime_dir().glob("deltagen_*.h")}
    offered = set().union(*(_declared(t) for t in headers.values()))
    generated = repo_root / "generated"
    headers.update({p.name: p.read_text() for p in generated.glob("*.h")})
    texts = {p.name: p.read_text() for p in generated.glob("*.c")}
    arm = SerialRobot.load("manutec_h5", backend="reference")
    unit, kernels = arm_unit_kernels(arm.description)
    for real in ("double", "float"):
        package = package_sources(unit, kernels, real_type=real, batch=False)
        headers.update({n: t for n, t in package.files.items() if n.endswith(".h")})
        texts.update({f"{real}/{n}": t for n, t in package.files.items() if n.endswith(".c")})

    def reachable(text, seen):
        found = _declared(text)
        for name in re.findall(r'#include "([\w.]+)"', text):
            if name in headers and name not in seen:
                seen.add(name)
                found |= reachable(headers[name], seen)
        return found

    checked = 0
    for name, text in texts.items():
        calls = set(_CALL.findall(text)) & offered
        missing = calls - reachable(text, set())
        assert not missing, f"{name} calls {sorted(missing)} without including their header"
        checked += bool(calls)
    assert checked >= 3  # not vacuous: the arms' modules and both single-point files
    assert "deltagen_fit_angle(" in texts["double/serial_manutec_h5_point.c"]


# ------------------------------------------------------------------ calibrate -> export

DRIVER = r"""
#include <stdio.h>

#include "delta_kinematics_robot.h"
#include "deltagen_encoder.h"

static const double Q[][3] = {%(q)s};
static const double P[][3] = {%(p)s};
static const double WRAP[] = {%(wrap)s};

int main(void)
{
%(robot)s
    for (size_t i = 0; i < sizeof Q / sizeof Q[0]; ++i) {
        double p[3];
        int status = deltagen_delta_robot_fk(&robot, Q[i], p);
        printf("fk %%d %%.17g %%.17g %%.17g\n", status, p[0], p[1], p[2]);
    }
    for (size_t i = 0; i < sizeof P / sizeof P[0]; ++i) {
        double q[3];
        int status = deltagen_delta_robot_ik(&robot, P[i], q);
        printf("ik %%d %%.17g %%.17g %%.17g\n", status, q[0], q[1], q[2]);
    }
    for (size_t i = 0; i < sizeof WRAP / sizeof WRAP[0]; ++i) {
        double q[3] = {WRAP[i], WRAP[i], WRAP[i]};
        deltagen_encoder_from_crank(robot.q_offset, q);
        printf("wrap %%.17g %%.17g %%.17g\n", q[0], q[1], q[2]);
    }
    return 0;
}
"""


def _c_rows(rows) -> str:
    return ", ".join("{" + ", ".join(float(v).hex() for v in row) + "}" for row in rows)


@pytest.mark.skipif(MAKE is None, reason="make is not installed")
def test_calibrate_export_make_run_equals_deltagen_fk(tmp_path, capsys):
    """deltagen calibrate (synthetic measurements of a robot with encoder offsets) writes
    a robot file; deltagen export of that file, built with its Makefile and driven by a
    small C program, gives `deltagen fk`'s positions and DeltaRobot.ik's readings on the
    written file to 1e-12 -- and the offsets matter (tens of mm)."""
    from deltagen.cli import main

    nominal = DeltaRobot.default(backend="reference")
    built = DeltaRobot.from_geometry(
        nominal.geometry.with_chains(l_a=(0.3505, 0.3490, 0.3502), q_offset=(0.04, -0.03, 0.02)),
        backend="reference",
    )
    rng = np.random.default_rng(22)
    q = rng.uniform(-0.3, 1.0, (60, 3))
    p = built.fk(q) + rng.normal(0.0, 20e-6, (60, 3))
    data = tmp_path / "measured.csv"
    np.savetxt(data, np.column_stack([q, p]), delimiter=",", header="q1,q2,q3,x,y,z")
    robot_file = tmp_path / "built.toml"
    rc = main(
        ["calibrate", str(data), "--params", "l_a,q_offset", "--sigma", "2e-5",
         "--out", str(robot_file), "--backend", "reference"]
    )  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    calibrated = DeltaRobot.from_toml(robot_file, backend="reference")
    offsets = np.array(calibrated.geometry.q_offset)
    np.testing.assert_allclose(offsets, [0.04, -0.03, 0.02], atol=2e-3)

    package = tmp_path / "pkg"
    assert main(["export", str(robot_file), "--out", str(package)]) == 0
    capsys.readouterr()
    assert (package / "delta_kinematics_robot.h").is_file()

    # the inputs: readings on the workspace and targets, plus angles to wrap at the edges
    q_test = rng.uniform(-0.3, 1.0, (40, 3))
    p_test = calibrated.fk(rng.uniform(-0.3, 1.0, (40, 3)))
    wrap = [0.0, 1e-300, np.pi, -np.pi, np.nextafter(np.pi, 0), 3.2, -3.2, 7.0, -7.0, 40.0]
    example = (package / "example.c").read_text()
    robot_init = re.search(
        r"(    const deltagen_delta_robot robot = \{.*?\n    \};)", example, re.S
    )
    assert robot_init, "the example does not set up a deltagen_delta_robot"
    (package / "driver.c").write_text(
        DRIVER % dict(q=_c_rows(q_test), p=_c_rows(p_test), robot=robot_init.group(1),
                      wrap=", ".join(float(w).hex() for w in wrap))
    )  # fmt: skip
    # -O0, as the packages above: this checks the workflow and its numbers (to 1e-12, the
    # wrap to numpy's bits, which -std=c99 keeps at any level), not optimised code
    _run([MAKE, f"CC={CC}", "CFLAGS=-std=c99 -O0", "libdeltagen_delta.a"], package)
    _run([CC, "-std=c99", "-O0", "-o", "driver", "driver.c", "libdeltagen_delta.a", "-lm"], package)
    lines = _run(["./driver"], package).splitlines()
    rows = {kind: [] for kind in ("fk", "ik", "wrap")}
    for line in lines:
        kind, *values = line.split()
        rows[kind].append([float(v) for v in values])
    fk_c, ik_c, wrap_c = (np.array(rows[k]) for k in ("fk", "ik", "wrap"))

    # `deltagen fk` on the written robot file (compiled backend, full precision via .npy)
    q_csv, p_npy = tmp_path / "q.csv", tmp_path / "p.npy"
    np.savetxt(q_csv, q_test, delimiter=",", header="q1,q2,q3", comments="", fmt="%.17g")
    assert main(["fk", str(robot_file), "--input", str(q_csv), "--output", str(p_npy)]) == 0
    out = np.load(p_npy)
    p_cli = np.column_stack([out["x"], out["y"], out["z"]])
    assert (fk_c[:, 0] == st.OK).all()
    np.testing.assert_allclose(fk_c[:, 1:], p_cli, rtol=0, atol=1e-12)
    q_api = DeltaRobot.from_toml(robot_file).ik(p_test)
    assert (ik_c[:, 0] == st.OK).all()
    np.testing.assert_allclose(ik_c[:, 1:], q_api, rtol=0, atol=1e-12)
    # the wrap of the readings is numpy's (the API's), at the edges of (-pi, pi] too
    expect = np.pi - np.mod(np.pi - (np.array(wrap)[:, None] - offsets), 2.0 * np.pi)
    np.testing.assert_array_equal(wrap_c, expect)
    # not vacuous: without the offsets the exported C would be far off
    p_no_offset = DeltaRobot.from_geometry(
        calibrated.geometry.with_chains(q_offset=(0.0, 0.0, 0.0)), backend="reference"
    ).fk(q_test)
    assert np.linalg.norm(p_no_offset - p_cli, axis=1).max() > 5e-3
