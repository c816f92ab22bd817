"""The numerical range of a delta geometry: lengths in [MIN_LENGTH, MAX_LENGTH] = [1e-6 m,
1e3 m] are evaluated as exactly as the 1 m robot (the kinematics are scale invariant: a robot
scaled by s maps q to p s, so ik of the scaled robot at p s must equal ik of the robot at p),
in both backends; lengths outside are refused by name, from Python, robot files and Klipper
configs, and the CLI exits 2 without a traceback. Before: arm lengths of 1e200 (Klipper)
ended in an OverflowError of the reference backend, and a delta scaled to 1e-100 m returned
wrong ik angles marked valid in both backends."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from deltagen import DeltaRobot
from deltagen.cli import main
from deltagen.errors import GeometryError
from deltagen.model.delta import MAX_LENGTH, MIN_LENGTH, DeltaGeometry
from deltagen.model.klipper import klipper_from_text

UNIT = DeltaGeometry.default()
SMALLEST = min(UNIT.r_a, UNIT.r_b, UNIT.l_a, UNIT.l_b)
LARGEST = max(UNIT.r_a, UNIT.r_b, UNIT.l_a, UNIT.l_b)


def scaled(s: float, geometry: DeltaGeometry = UNIT) -> DeltaGeometry:
    return DeltaGeometry(
        r_a=geometry.r_a * s,
        r_b=geometry.r_b * s,
        l_a=geometry.l_a * s,
        l_b=geometry.l_b * s,
        theta=geometry.theta,
        name="scaled",
    )


#: the scale factors that put the default robot's shortest length on MIN_LENGTH and its
#: longest on MAX_LENGTH: the two ends of the range
ENDS = {"smallest": MIN_LENGTH / SMALLEST, "largest": MAX_LENGTH / LARGEST}


@pytest.fixture(scope="module")
def poses():
    rng = np.random.default_rng(31)
    q = rng.uniform(-0.3, 1.0, (400, 3))
    unit = DeltaRobot.from_geometry(UNIT, "reference")
    p, valid = unit.fk(q, errors="nan")
    return q[valid], p[valid]


@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize("end", list(ENDS))
def test_both_ends_of_the_range_are_as_exact_as_the_metre_robot(end, backend, poses):
    s = ENDS[end]
    q, p = poses
    robot = DeltaRobot.from_geometry(scaled(s), backend)
    p_s, valid = robot.fk(q, errors="nan")
    assert valid.all()
    np.testing.assert_allclose(p_s / s, p, rtol=0, atol=1e-14)
    q_s, valid = robot.ik(p * s, errors="nan")
    assert valid.all()
    np.testing.assert_allclose(q_s, q, rtol=0, atol=1e-12)  # ik(fk(q)) = q
    # the rates scale too: J(q) of the scaled robot is s J(q)
    J1 = DeltaRobot.from_geometry(UNIT, backend).jacobian(q[:50])
    np.testing.assert_allclose(robot.jacobian(q[:50]) / s, J1, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize(
    "end, factor, key",
    [
        ("smallest", 0.5, "r_b"),
        ("smallest", 1e-94, "r_a"),
        ("largest", 2.0, "l_b"),
        ("largest", 1e197, "r_a"),
    ],
)
def test_lengths_outside_the_range_are_refused_by_name(end, factor, key):
    """Just outside (only the shortest or longest length leaves the range) and far outside
    (1e-100 m, 1e200 m: where the arithmetic fails)."""
    with pytest.raises(GeometryError, match=rf"^{key} = .* outside the range .*1e-06 m to 1000 m"):
        scaled(ENDS[end] * factor)


def test_per_chain_lengths_are_refused_by_name_and_r_b_may_be_zero():
    with pytest.raises(GeometryError, match=r"chain_l_b\[1\] = 2000.0 m is outside"):
        UNIT.with_chains(l_b=(0.8, 2000.0, 0.8))
    with pytest.raises(GeometryError, match=r"chain_l_a\[2\] = 1e-09 m is outside"):
        UNIT.with_chains(l_a=(0.35, 0.35, 1e-9))
    assert UNIT.with_chains(r_b=(0.0, 0.0, 0.0)).chain("r_b") == (0.0, 0.0, 0.0)
    assert DeltaGeometry(r_a=0.2, r_b=0.0, l_a=0.35, l_b=0.8, theta=UNIT.theta).r_b == 0.0


KLIPPER = """
[stepper_a]
position_endstop: 252
upper_arm_length: {upper}
lower_arm_length: 320.000
[stepper_b]
[stepper_c]
{stepper_c}
[printer]
kinematics: rotary_delta
shoulder_radius: 33.900
shoulder_height: 412.900
"""


def test_klipper_names_the_printer_cfg_key_in_mm():
    with pytest.raises(
        GeometryError, match=r"\[stepper_a\] upper_arm_length: 1e\+200 mm .*1e\+06 mm"
    ):
        klipper_from_text(KLIPPER.format(upper="1e200", stepper_c=""))
    with pytest.raises(GeometryError, match=r"\[stepper_c\] lower_arm_length: 2e\+06 mm"):
        klipper_from_text(KLIPPER.format(upper="170", stepper_c="lower_arm_length: 2e6"))
    with pytest.raises(GeometryError, match=r"\[stepper_a\] upper_arm_length: 0.0001 mm"):
        klipper_from_text(KLIPPER.format(upper="1e-4", stepper_c=""))
    # inside the range: the import of Klipper's example numbers works
    assert klipper_from_text(KLIPPER.format(upper="170", stepper_c="")).geometry.l_a == 0.17


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_cli_refuses_out_of_range_geometries_with_exit_2(tmp_path, capsys, backend):
    cfg = tmp_path / "printer.cfg"
    cfg.write_text(KLIPPER.format(upper="1e200", stepper_c=""))
    assert main(["fk", str(cfg), "0.3", "0.3", "0.3", "--backend", backend]) == 2
    err = capsys.readouterr().err
    assert "[stepper_a] upper_arm_length" in err and "Traceback" not in err
    tiny = tmp_path / "tiny.toml"
    tiny.write_text(
        "[delta]\nr_a = 0.2e-100\nr_b = 0.045e-100\nl_a = 0.35e-100\nl_b = 0.8e-100\n"
        "theta_deg = [0, 120, 240]\n"
    )
    assert main(["ik", str(tiny), "0", "0", "-1e-100", "--backend", backend]) == 2
    err = capsys.readouterr().err
    assert "r_a = 2e-101 m is outside the range" in err and "Traceback" not in err


def test_a_serial_arm_with_huge_dh_lengths_gives_no_traceback(tmp_path, capsys):
    """Serial arms are not range-checked; a planar arm with 1e200 m links still answers fk
    exactly (the products stay finite) and ik with a clear message, never a traceback."""
    arm = tmp_path / "huge.toml"
    arm.write_text(
        'name = "huge_arm"\nconvention = "standard"\n'
        '[[joint]]\ntype = "revolute"\na = 4e200\nalpha = 0.0\nd = 0.0\n'
        '[[joint]]\ntype = "revolute"\na = 3e200\nalpha = 0.0\nd = 0.0\n'
    )
    assert main(["fk", str(arm), "0.3", "0.3", "--backend", "reference"]) == 0
    out = capsys.readouterr().out
    printed = re.search(r"x, y, z = \[([^,]+), ([^,]+), ([^\]]+)\]", out)
    assert printed, out
    x = 4e200 * math.cos(0.3) + 3e200 * math.cos(0.6)  # planar two-link arm
    y = 4e200 * math.sin(0.3) + 3e200 * math.sin(0.6)
    assert float(printed.group(1)) == pytest.approx(x, rel=1e-7)
    assert float(printed.group(2)) == pytest.approx(y, rel=1e-7)
    code = main(["ik", str(arm), "1e200", "1e200", "0", "0", "0", "0", "--backend", "reference"])
    assert code in (0, 1, 2)
    assert "Traceback" not in capsys.readouterr().err
