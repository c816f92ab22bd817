"""Klipper rotary-delta configurations (deltagen.model.klipper, DeltaRobot.from_klipper, the
CLI): the mapped robot against Klipper's published kinematics formulas, written here
independently from their description in Klipper's sources (klippy/kinematics/rotary_delta.py:
the elbow position; klippy/chelper/kin_rotary_delta.c: the arm angle of a toolhead
position in the shoulder's plane), on a set of poses."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from helpers import KLIPPER_ROTARY_CFG

from deltagen import DeltaRobot
from deltagen.errors import GeometryError
from deltagen.model.klipper import klipper_from_text, read_klipper

SHOULDER_RADIUS, SHOULDER_HEIGHT, UPPER, LOWER = 33.9, 412.9, 170.0, 320.0
ANGLES_DEG = (30.0, 150.0, 270.0)  # Klipper's defaults for stepper_a, _b, _c


def klipper_elbow(i, arm_angle, radius=SHOULDER_RADIUS, angles=ANGLES_DEG, upper=UPPER):
    """Klipper's elbow position [mm], z above the bed; arm angle positive up."""
    reach = radius + upper * math.cos(arm_angle)
    ang = math.radians(angles[i])
    return np.array(
        [
            reach * math.cos(ang),
            reach * math.sin(ang),
            SHOULDER_HEIGHT + upper * math.sin(arm_angle),
        ]
    )


def klipper_arm_angle(i, xyz, radius=SHOULDER_RADIUS, angles=ANGLES_DEG, upper=UPPER, lower=LOWER):
    """Klipper's arm angle for toolhead position xyz [mm]: in the shoulder's frame (u along
    the arm's radial direction, v up, w across) the elbow lies on the circle of radius
    upper about the shoulder and at distance sqrt(lower^2 - w^2) from the effector's
    projection; of the two circle intersections Klipper takes the one further out in u."""
    ang = math.radians(angles[i])
    x, y, z = xyz
    u = x * math.cos(ang) + y * math.sin(ang) - radius
    v = z - SHOULDER_HEIGHT
    w = y * math.cos(ang) - x * math.sin(ang)
    reach2 = lower**2 - w**2
    # elbow (eu, ev): eu^2 + ev^2 = upper^2 and (u - eu)^2 + (v - ev)^2 = reach2, so
    # ev = k - m eu with k = (u^2 + v^2 + upper^2 - reach2) / (2 v), m = u / v
    k = (u * u + v * v + upper**2 - reach2) / (2.0 * v)
    m = u / v
    # (1 + m^2) eu^2 - 2 k m eu + k^2 - upper^2 = 0, larger root
    a2, b2, c2 = 1.0 + m * m, -2.0 * k * m, k * k - upper**2
    eu = (-b2 + math.sqrt(b2 * b2 - 4.0 * a2 * c2)) / (2.0 * a2)
    ev = k - m * eu
    return math.atan2(ev, eu)


def klipper_effector(arm_angles, lower=LOWER):
    """The effector where the three lower-arm spheres meet (the lower point), by the
    textbook trilateration in the frame of the three elbows."""
    p1, p2, p3 = (klipper_elbow(i, a) for i, a in enumerate(arm_angles))
    ex = (p2 - p1) / np.linalg.norm(p2 - p1)
    i_ = ex @ (p3 - p1)
    ey = p3 - p1 - i_ * ex
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    d = np.linalg.norm(p2 - p1)
    j = ey @ (p3 - p1)
    x = d / 2.0
    y = (i_ * i_ + j * j) / (2.0 * j) - i_ * x / j
    zz = math.sqrt(lower**2 - x * x - y * y)
    candidates = [p1 + x * ex + y * ey + s * zz * ez for s in (1.0, -1.0)]
    return min(candidates, key=lambda c: c[2])


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    path = tmp_path_factory.mktemp("klipper") / "printer.cfg"
    path.write_text(KLIPPER_ROTARY_CFG)
    return path


def test_the_example_maps_to_the_documented_geometry(example):
    k = read_klipper(example)
    g = k.geometry
    assert (g.r_a, g.r_b, g.l_a, g.l_b) == pytest.approx((0.0339, 0.0, 0.17, 0.32), abs=1e-15)
    assert np.degrees(g.theta) == pytest.approx(ANGLES_DEG)
    assert k.shoulder_height == pytest.approx(0.4129)
    assert k.position_endstop == pytest.approx((0.252, 0.252, 0.252))


def _poses():
    rng = np.random.default_rng(11)
    # toolhead positions [mm] over the printable volume around the bed centre
    xy = rng.uniform(-80.0, 80.0, size=(40, 2))
    z = rng.uniform(20.0, 200.0, size=40)
    return np.column_stack([xy, z])


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_ik_agrees_with_klippers_arm_angles(example, backend):
    k = read_klipper(example)
    robot = DeltaRobot.from_klipper(example, backend=backend)
    xyz = _poses()
    q = robot.ik(k.from_klipper_xyz(xyz))
    a = np.array([[klipper_arm_angle(i, row) for i in range(3)] for row in xyz])
    np.testing.assert_allclose(q, -a, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_fk_agrees_with_klippers_trilateration(example, backend):
    k = read_klipper(example)
    robot = DeltaRobot.from_klipper(example, backend=backend)
    rng = np.random.default_rng(5)
    a = rng.uniform(-0.9, 0.1, size=(30, 3))  # arm angles, positive up [rad]
    xyz = np.array([klipper_effector(row) for row in a])
    p = robot.fk(-a)
    np.testing.assert_allclose(k.to_klipper_xyz(p), xyz, rtol=0, atol=1e-9)  # mm


def test_home_pose_is_the_endstop_height(example):
    k = read_klipper(example)
    robot = DeltaRobot.from_klipper(example)
    q_home = robot.ik(k.home_p(0))
    a = [klipper_arm_angle(i, (0.0, 0.0, 252.0)) for i in range(3)]
    np.testing.assert_allclose(q_home, -np.array(a), rtol=0, atol=1e-12)
    assert k.to_klipper_xyz(robot.fk(q_home)) == pytest.approx([0.0, 0.0, 252.0], abs=1e-9)


def test_per_stepper_angles_and_save_config_override():
    text = KLIPPER_ROTARY_CFG.replace("[stepper_c]\n", "[stepper_c]\nangle: 275.5\n") + (
        "\n#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n"
        "#*#\n#*# [printer]\n#*# shoulder_height = 410.000\n"
    )
    k = klipper_from_text(text)
    assert math.degrees(k.geometry.theta[2]) == pytest.approx(275.5)
    assert k.shoulder_height == pytest.approx(0.41)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("rotary_delta", "delta"), "only 'rotary_delta'"),
        (lambda t: "[include macros.cfg]\n" + t, "included files"),
        (lambda t: t.replace("shoulder_radius: 33.900\n", ""), "shoulder_radius"),
        (lambda t: t.replace("320.000", "long"), "not a number"),
        (lambda t: t.replace("[stepper_c]", "[stepper_x]"), "stepper_c"),
        (lambda t: t.replace("upper_arm_length: 170.000", "upper_arm_length: -170"), "> 0"),
    ],
)
def test_bad_configs_are_clear_errors(edit, message):
    with pytest.raises(GeometryError, match=message):
        klipper_from_text(edit(KLIPPER_ROTARY_CFG))


def test_cli_accepts_a_printer_cfg(example, repo_root):
    out = subprocess.run(
        [sys.executable, "-m", "deltagen", "fk", str(example), "0.3", "0.3", "0.3"],
        capture_output=True,
        text=True,
        cwd=repo_root,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    p = DeltaRobot.from_klipper(example).fk([0.3, 0.3, 0.3])
    assert f"{p[2]:.6f}"[:7] in out.stdout


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_per_stepper_arm_lengths_give_an_asymmetric_robot(backend):
    upper, lower = (170.0, 171.5, 169.0), (320.0, 318.0, 321.0)
    text = KLIPPER_ROTARY_CFG.replace(
        "[stepper_b]\n", "[stepper_b]\nupper_arm_length: 171.5\nlower_arm_length: 318\n"
    ).replace("[stepper_c]\n", "[stepper_c]\nupper_arm_length: 169\nlower_arm_length: 321\n")
    k = klipper_from_text(text)
    assert k.geometry.chain("l_a") == pytest.approx(np.array(upper) * 1e-3)
    robot = DeltaRobot.from_geometry(k.geometry, backend)
    xyz = _poses()
    q = robot.ik(k.from_klipper_xyz(xyz))
    a = np.array(
        [
            [klipper_arm_angle(i, row, upper=upper[i], lower=lower[i]) for i in range(3)]
            for row in xyz
        ]
    )
    np.testing.assert_allclose(q, -a, rtol=0, atol=1e-12)
