"""The file's numbers are kept (derive/serial/chain.py): a constant becomes an exact value
(0, +-1, +-1/2, a multiple of pi/12) only when it is that value up to float rounding, never
because it is close to one. Files that print pi as 3.14159265359 (2e-13 from pi; HyQ,
ANYmal-Kinova) then give the compiled core what the numpy reference and pinocchio compute
from the same digits, and the structure detection, which reads the geometry with its own
tolerances, still finds the closed forms of arms whose angles are printed rounded."""

from __future__ import annotations

import math
import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from deltagen import SerialRobot
from deltagen.derive.serial.chain import exact_angle, exact_number
from deltagen.model.structure import detect
from deltagen.model.urdf import URDFWarning

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
PI_12 = "3.14159265359"  # pi to 12 decimals, as HyQ's and ANYmal's files print it
HALF_PI_11 = "1.57079632679"


def test_only_float_rounding_is_snapped():
    assert exact_angle(math.pi / 2) == sp.pi / 2
    assert exact_angle(math.radians(-135)) == -3 * sp.pi / 4
    assert exact_angle(float("1.570796326794897")) == sp.pi / 2  # 2 ulp: the float of pi/2
    assert exact_angle(float(PI_12)) == sp.Float(PI_12, 17)
    assert exact_angle(1e-13).is_Float and exact_angle(1e-13) != 0
    assert exact_number(math.cos(math.pi / 2)) == 0  # 6e-17: a turn by pi/2 in floats
    assert exact_number(math.sin(float(PI_12))) != 0  # -2.07e-13: the file's pi
    assert exact_number(-1.0 + 2e-16) == -1
    assert exact_number(0.5 - 1e-13) != sp.Rational(1, 2)


def _arm_urdf():
    """Four joints whose origins print pi and pi/2 rounded, with inertials."""
    inertial = (
        '<inertial><origin xyz="0.02 0.01 0.1" rpy="{r} 0 0"/><mass value="1.3"/>'
        '<inertia ixx="0.02" iyy="0.03" izz="0.01" ixy="0.001" ixz="0" iyz="0.002"/></inertial>'
    )
    links = "".join(
        f'<link name="l{i}">{inertial.format(r=PI_12 if i % 2 else 0)}</link>' for i in range(1, 5)
    )
    rpys = [f"{PI_12} 0 0", f"0 {HALF_PI_11} 0", f"{HALF_PI_11} 0 -{HALF_PI_11}", f"0 -{PI_12} 0"]
    joints = "".join(
        f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
        f'<origin xyz="0.1 0.05 0.3" rpy="{rpys[i - 1]}"/><axis xyz="0 0 1"/>'
        '<limit lower="-3" upper="3"/></joint>'
        for i in range(1, 5)
    )
    foot = (
        f'<joint name="foot_joint" type="fixed"><parent link="l4"/><child link="foot"/>'
        f'<origin xyz="0 0 0.2" rpy="0 {PI_12} {HALF_PI_11}"/></joint>'
    )
    return (
        '<?xml version="1.0"?><robot name="digits"><link name="l0"/><link name="foot"/>'
        + links
        + joints
        + foot
        + "</robot>"
    )


def _assert_compiled_is_reference(compiled, tol=1e-14, count=500):
    reference = compiled.with_backend("reference")
    rng = np.random.default_rng(11)
    lim = np.clip(compiled.qlim, -np.pi, np.pi)
    q = rng.uniform(lim[:, 0], lim[:, 1], (count, compiled.n))
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)

    def rel(a, b):
        return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))

    assert rel(compiled.fk(q), reference.fk(q)) <= tol
    assert rel(compiled.jacobian(q), reference.jacobian(q)) <= tol
    if compiled.description.has_inertia:
        tau = compiled.inverse_dynamics(q, qd, qdd)
        assert rel(tau, reference.inverse_dynamics(q, qd, qdd)) <= tol
        assert rel(compiled.mass_matrix(q), reference.mass_matrix(q)) <= tol


def test_rounded_pi_in_a_file_is_compiled_as_written(tmp_path):
    path = tmp_path / "digits.urdf"
    path.write_text(_arm_urdf())
    _assert_compiled_is_reference(SerialRobot.from_urdf(path))


def test_closed_form_of_an_arm_with_rounded_angles():
    """The Puma 560 with its twists printed to 13 digits (3e-14 from pi/2, snapped before):
    still a central-wrist arm, and its compiled closed form finds the original q."""
    rows = [
        dict(a=0.0, alpha=1.5707963267949, d=0.6718),
        dict(a=0.4318, alpha=0.0, d=0.0),
        dict(a=0.0203, alpha=-1.5707963267949, d=0.15005),
        dict(a=0.0, alpha=1.5707963267949, d=0.4318),
        dict(a=0.0, alpha=-1.5707963267949, d=0.0),
        dict(a=0.0, alpha=0.0, d=0.0),
    ]
    arm = SerialRobot.from_dh(rows, "standard", name="puma_13_digits")
    assert detect(arm.description).kind == "spherical_wrist_6r"
    rng = np.random.default_rng(12)
    q = rng.uniform(-2.5, 2.5, (300, 6))
    T = arm.fk(q)
    q_all, valid = arm.ik_all(T)
    err = np.abs(arm.fk(np.where(valid[..., None], q_all, 0.0)) - T[:, None]).max(axis=(-1, -2))
    assert np.all(err[valid] <= 1e-10)
    near = np.abs(np.angle(np.exp(1j * (q_all - q[:, None]))))
    found = (valid & np.all(near < 1e-8, axis=-1)).any(axis=1)
    assert found.all()
    _assert_compiled_is_reference(arm)


LEGS = {
    "hyq_lf": ("hyq_description/robots/hyq_no_sensors.urdf", "trunk", "lf_foot"),
    "anymal_kinova_arm": (
        "anymal_b_simple_description/robots/anymal-kinova.urdf",
        "base",
        "j2s6s200_end_effector",
    ),
}


@pytest.mark.skipif(not ROBOTS_DIR.is_dir(), reason="example-robot-data (test extra) is absent")
@pytest.mark.parametrize("name", sorted(LEGS))
def test_published_chains_with_rounded_pi(name):
    file, base, tip = LEGS[name]
    path = ROBOTS_DIR / file
    assert PI_12 in path.read_text()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        arm = SerialRobot.from_urdf(path, base, tip, name=f"digits_{name}")
    _assert_compiled_is_reference(arm, count=300)
