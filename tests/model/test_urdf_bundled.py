"""The bundled URDF arms (robots/*.urdf): loadable by name, their C
checked in under generated/, and each against independent evidence -- the Panda against
pinocchio's reading of example-robot-data's Panda (franka_description's file, written by
others) and against Franka's modified-DH table through deltagen's DH path; the SCARA against
the same arm's DH table (robots/bosch_sr800.toml)."""

from __future__ import annotations

import math
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from helpers import ROBOTS
from pinocchio_oracles import compare_with_pinocchio, random_urdf_q

from deltagen import SerialRobot
from deltagen.api.serial import bundled_urdfs
from deltagen.model.serial import SerialDescription
from deltagen.native.serial import source_dir
from deltagen.paths import generated_dir

N = 300


@pytest.mark.parametrize("name", ["panda", "scara_sr800", "ur5"])
def test_bundled_urdfs_load_by_name_from_the_checked_in_c(name):
    assert name in bundled_urdfs()
    robot = SerialRobot.load(name, backend="reference")
    assert robot.name == name
    # the module comes from generated/ (no derivation on a user's machine)
    assert source_dir(robot.description, render=False) == generated_dir()


def test_panda_equals_frankas_modified_dh_table():
    """T_urdf(q) = T_mdh(q) Trans_z(0.107) Rot_z(-pi/4) Trans_z(0.1034) (flange, hand, TCP)."""
    pi = math.pi
    a = [0, 0, 0, 0.0825, -0.0825, 0, 0.088]
    d = [0.333, 0, 0.316, 0, 0.384, 0, 0]
    alpha = [0, -pi / 2, pi / 2, pi / 2, -pi / 2, pi / 2, pi / 2]
    rows = [dict(a=x, alpha=y, d=z) for x, y, z in zip(a, alpha, d, strict=True)]
    mdh = SerialRobot(SerialDescription.from_rows(rows, "modified", name="panda_mdh"), "reference")
    urdf = SerialRobot.load("panda", backend="reference")
    c, s = math.cos(-pi / 4), math.sin(-pi / 4)
    tool = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0.107 + 0.1034], [0, 0, 0, 1]])
    q = random_urdf_q(urdf, np.random.default_rng(1), N)
    np.testing.assert_allclose(urdf.fk(q), mdh.fk(q) @ tool, rtol=0, atol=1e-12)


def test_panda_inertials_are_physically_feasible():
    """Gaz et al. 2019 retrieve a *feasible* set (their paper's point): positive masses, each
    inertia about its centre of mass positive definite
    with the triangle inequalities I_xx + I_yy >= I_zz (cyclic) of its principal moments. A
    mistyped value (a sign, a decimal place) breaks some of these."""
    robot = SerialRobot.load("panda", backend="reference")
    joints = robot.description.joints
    assert robot.description.has_inertia and len(joints) == 7
    for j in joints:
        inertial = j.inertial
        assert 0.5 < inertial.mass < 5.0, j.name
        ixx, iyy, izz, ixy, ixz, iyz = inertial.inertia
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        moments = np.linalg.eigvalsh(tensor)
        assert moments.min() > 0, j.name
        assert 2 * moments.max() <= moments.sum(), j.name  # largest <= sum of the other two


def test_scara_equals_its_dh_table():
    urdf = SerialRobot.load("scara_sr800", backend="reference")
    dh = SerialRobot.load("bosch_sr800", backend="reference")
    np.testing.assert_allclose(urdf.qlim, dh.qlim, rtol=0, atol=1e-15)
    q = random_urdf_q(urdf, np.random.default_rng(2), N)
    np.testing.assert_allclose(urdf.fk(q), dh.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(urdf.jacobian(q), dh.jacobian(q), rtol=0, atol=1e-12)


def test_bundled_urdf_ik_round_trips():
    rng = np.random.default_rng(3)
    for name in ("panda", "scara_sr800"):
        robot = SerialRobot.load(name, backend="reference")
        q = random_urdf_q(robot, rng, 30)
        T = robot.fk(q)
        q_ik = robot.ik(T, method="numeric")
        np.testing.assert_allclose(robot.fk(q_ik), T, rtol=0, atol=1e-10, err_msg=name)
        assert robot.within_limits(q_ik).all()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["panda", "scara_sr800"])
def test_the_checked_in_c_of_the_bundled_urdfs_equals_the_reference(name):
    compiled = SerialRobot.load(name)
    reference = compiled.with_backend("reference")
    q = random_urdf_q(compiled, np.random.default_rng(6), N)
    np.testing.assert_allclose(compiled.fk(q), reference.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.jacobian(q), reference.jacobian(q), rtol=0, atol=1e-12)
    if name == "panda":  # the only one with inertials; its C holds the dynamics kernels
        rng = np.random.default_rng(7)
        qd, qdd = rng.normal(size=(2, N, compiled.n))
        tau = compiled.inverse_dynamics(q, qd, qdd)
        np.testing.assert_allclose(
            tau, reference.inverse_dynamics(q, qd, qdd), rtol=1e-12, atol=1e-12
        )
        np.testing.assert_allclose(
            compiled.mass_matrix(q), reference.mass_matrix(q), rtol=1e-12, atol=1e-14
        )


pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")
PANDA = (
    Path(sysconfig.get_paths()["purelib"])
    / "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
)


@pytest.mark.skipif(not PANDA.is_file(), reason="example-robot-data (test extra) not installed")
def test_panda_matches_example_robot_data_through_pinocchio():
    """Every link frame the two files share (panda_link1..8, panda_hand, panda_hand_tcp)
    and the TCP Jacobian, pinocchio reading the published file, deltagen the bundled one;
    the joint limits agree too."""
    robot = SerialRobot.load("panda", backend="reference")
    full = pin.buildModelFromUrdf(str(PANDA))
    lock = [full.getJointId(f"panda_finger_joint{i}") for i in (1, 2)]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    data = model.createData()
    assert [model.names[k] for k in range(1, model.njoints)] == [
        j.name for j in robot.description.joints
    ]
    np.testing.assert_allclose(robot.qlim[:, 0], model.lowerPositionLimit, rtol=0, atol=1e-12)
    np.testing.assert_allclose(robot.qlim[:, 1], model.upperPositionLimit, rtol=0, atol=1e-12)
    q = random_urdf_q(robot, np.random.default_rng(4), N)
    F = robot.frames(q)  # universal frames 0..7 (frame i-1: joint i's axis is its z), tool
    T = robot.fk(q)
    J = robot.jacobian(q)
    tcp = model.getFrameId("panda_hand_tcp")
    for k in range(N):
        pin.framesForwardKinematics(model, data, q[k])
        np.testing.assert_allclose(T[k], data.oMf[tcp].homogeneous, rtol=0, atol=1e-12)
        for i in range(1, 8):  # link i = universal frame i-1 turned by q_i about its z
            link = data.oMf[model.getFrameId(f"panda_link{i}")].homogeneous
            c, s = math.cos(q[k, i - 1]), math.sin(q[k, i - 1])
            turn = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
            np.testing.assert_allclose(F[k, i - 1] @ turn, link, rtol=0, atol=1e-12)
        Jp = pin.computeFrameJacobian(model, data, q[k], tcp, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(J[k], Jp, rtol=0, atol=1e-12)


def test_panda_dynamics_match_pinocchio_on_the_same_file():
    """The bundled Panda's inertials (Gaz et al. 2019) through deltagen's derivation and through
    pinocchio's rnea/crba reading the same file, to 1e-10 relative."""

    path = ROBOTS / "panda.urdf"
    robot = SerialRobot.load("panda", backend="reference")
    compare_with_pinocchio(robot, path, "panda_hand_tcp")
