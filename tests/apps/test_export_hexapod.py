"""`deltagen export` of the hexapod (robots/hexapod_genhex.toml) through apps/export.py's
shared path, like every other family: a double package under --prefix and a float32
package build with their Makefiles, and the numbers their examples print are the Python
API's on the numpy reference backend (deltagen/reference/hexapod.py: independent of the C);
the double package's single-point functions, compiled with cffi, give the reference's leg
lengths and Jacobian on random poses; --no-batch leaves the batched module (and fk, its
extra) out."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from deltagen import Hexapod, paths
from deltagen import status as st
from deltagen.apps import export as ex
from deltagen.apps.hexapod import EXAMPLE_POSITION, EXAMPLE_RPY
from deltagen.cli import main
from deltagen.codegen.export import package_sources

CC = ex.compiler()
MAKE = shutil.which("make")
pytestmark = pytest.mark.skipif(
    CC is None or MAKE is None, reason="needs a C compiler and make on PATH"
)

ROBOT_FILE = str(paths.robots_dir() / "hexapod_genhex.toml")


@pytest.fixture(scope="module")
def reference():
    return Hexapod.from_toml(ROBOT_FILE, backend="reference")


def _example_pose(robot):
    return robot.pose(np.add(robot.geometry.home_position, EXAMPLE_POSITION), rpy=EXAMPLE_RPY)


def _build_and_run(folder) -> list[str]:
    built = subprocess.run([MAKE, "-s"], cwd=folder, capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stderr
    run = subprocess.run(["./example"], cwd=folder, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    return run.stdout.splitlines()


def _numbers(line: str) -> np.ndarray:
    tokens = line.split("=")[1].split()  # "ik: l = l1 .. l6 m", "fk: p = x y z m after ..."
    return np.array([float(v) for v in tokens[: tokens.index("m")]])


def test_double_package_under_a_prefix_agrees_with_the_reference(reference, tmp_path, capsys):
    out = tmp_path / "hx"
    assert main(["export", ROBOT_FILE, "--out", str(out), "--prefix", "hx"]) == 0
    capsys.readouterr()
    names = {p.name for p in out.iterdir()}
    assert {"hx.c", "hx.h", "hx_point.c", "hx_point.h", "deltagen_hexapod_fk.c"} <= names
    assert not any(n.startswith("hexapod_kinematics") for n in names)
    assert "int hx_fk(" in (out / "hx.h").read_text()
    ik_line, fk_line = _build_and_run(out)
    pose = _example_pose(reference)
    np.testing.assert_allclose(_numbers(ik_line), reference.ik(pose), atol=1e-9)
    np.testing.assert_allclose(_numbers(fk_line)[:3], pose[:3, 3], atol=1e-9)
    readme = (out / "README.md").read_text()
    assert "`hx_fk`" in readme and "DELTAGEN_UNREACHABLE" in readme


def test_float32_package_is_float_and_close_to_the_reference(reference, tmp_path, capsys):
    out = tmp_path / "hx32"
    assert main(["export", ROBOT_FILE, "--out", str(out), "--float32"]) == 0
    printed = capsys.readouterr().out
    assert "float32 ik leg length error [um]" in printed
    header = (out / "hexapod_kinematics_point.h").read_text()
    assert "const float pose[16]" in header and "double" not in header.split("#include")[-1]
    assert "_fk(" not in (out / "hexapod_kinematics.h").read_text()  # the runtime Newton: double
    (ik_line,) = _build_and_run(out)
    expected = reference.ik(_example_pose(reference))
    got = _numbers(ik_line)
    # float: a few units of 2^-24 of lengths below 1 m, far above the double's 1e-15
    np.testing.assert_allclose(got, expected, atol=2e-6)
    assert np.abs(got - expected).max() > 1e-12
    assert "## float32 accuracy" in (out / "README.md").read_text()


def test_point_functions_give_the_reference_numbers(reference, tmp_path, capsys):
    out = tmp_path / "points"
    assert main(["export", ROBOT_FILE, "--out", str(out), "--no-batch"]) == 0
    capsys.readouterr()
    assert not (out / "hexapod_kinematics.c").exists()  # no batched module, no fk
    package = package_sources(*ex._robot_parts(reference)[1:], batch=False)
    module = ex.load_package(package, out, tmp_path / "build", "_test_export_hexapod_points")
    points = ex.PointLibrary(
        module, package.unit.prefix, "double", ex._geometry_struct(reference, "hexapod"), package
    )
    rng = np.random.default_rng(3)
    home = np.asarray(reference.geometry.home_position)
    T = reference.pose(
        home + rng.uniform(-0.05, 0.05, (40, 3)), rpy=rng.uniform(-0.2, 0.2, (40, 3))
    )
    lengths, status = points("ik", [T.reshape(-1, 16)])
    assert np.all(status == st.OK)
    np.testing.assert_allclose(lengths, reference.ik(T), rtol=0, atol=1e-12)
    _, J, status = points("jacobian", [T.reshape(-1, 16)])
    assert np.all(status == st.OK)
    np.testing.assert_allclose(J.reshape(-1, 6, 6), reference.jacobian(T), rtol=0, atol=1e-9)
