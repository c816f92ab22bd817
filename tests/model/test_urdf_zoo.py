"""Real arms' URDF files, as their makers and the robotics community publish them
(example-robot-data, the URDF collection pinocchio's developers maintain: Franka Panda,
Kinova Jaco 2, UR3 and UR10, UFactory xArm7, Unitree Z1, SO-100, TALOS' left arm, a double
pendulum), read by deltagen and by
pinocchio's own URDF parser: the tool pose and the Jacobian on random configurations, and
where the chain carries all of the arm's mass, the inverse dynamics (with the files' joint
damping and friction) and the mass matrix.

The reference backend (numpy) is used: the compiled core equals it (tests/native/test_delta.py,
tests/derive/test_serial_dynamics.py), and compiling seven arms' dynamics would cost minutes."""

from __future__ import annotations

import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinocchio_oracles import assert_dynamics_as_pinocchio, pin_q, random_urdf_q

from deltagen import SerialRobot
from deltagen.model.urdf import URDFWarning

pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
if not ROBOTS_DIR.is_dir():
    pytest.skip(
        "example-robot-data (test extra: pip install example-robot-data) is not installed",
        allow_module_level=True,
    )

# name: (file under robots/, base link, tip link, whether the chain carries all the mass)
ARMS = {
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "base_link", "tool0", True),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "base_link", "tool0", True),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", None, None, True),
    "z1": ("z1_description/urdf/z1.urdf", None, None, True),
    "so100": ("so_arm_description/urdf/so100.urdf", None, None, True),
    # the hand and its fingers (a mimic pair) lie beyond the tip: folded into link 7 with the
    # fingers locked at 0 (model/urdf.py), as pinocchio's buildReducedModel locks them
    "panda": ("panda_description/urdf/panda.urdf", "panda_link0", "panda_link8", True),
    "panda_hand": ("panda_description/urdf/panda.urdf", "panda_link0", "panda_hand", True),
    "kinova": ("kinova_description/robots/kinova.urdf", None, "j2s6s200_end_effector", True),
    # a gripper with <mimic> on fixed joints (ignored with a warning) hangs off the chain
    "talos_left_arm": ("talos_data/robots/talos_left_arm.urdf", None, "arm_left_7_link", True),
    # <limit lower="0" upper="0"> (the specification's defaults): no position limits
    "double_pendulum": (
        "double_pendulum_description/urdf/double_pendulum.urdf",
        None,
        None,
        True,
    ),
}
N = 200


def _pin_chain(path, base, tip, robot):
    """Pinocchio's model of the whole file, with every joint off the base-tip chain locked
    at zero (buildReducedModel), and its joint order checked against deltagen's."""
    full = pin.buildModelFromUrdf(str(path))
    chain = [j.name for j in robot.description.joints]
    lock = [k for k in range(1, full.njoints) if full.names[k] not in chain]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    assert [model.names[k] for k in range(1, model.njoints)] == chain
    return model


@pytest.mark.parametrize("name", list(ARMS))
def test_published_arm_matches_pinocchio(name):
    file, base, tip, all_mass = ARMS[name]
    path = ROBOTS_DIR / file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)  # the files' quirks, tested in test_urdf
        robot = SerialRobot.from_urdf(path, base, tip, backend="reference")
    model = _pin_chain(path, base, tip, robot)
    data = model.createData()
    root = model.getFrameId(base) if base else 0
    fid = model.getFrameId(tip or model.frames[-1].name)
    rng = np.random.default_rng(3)
    q = random_urdf_q(robot, rng, N)
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    T = robot.fk(q)
    J = robot.jacobian(q)
    size = max(1.0, float(np.abs(T[:, :3, 3]).max()))
    dynamics = all_mass and robot.description.has_inertia
    if dynamics:
        tau = robot.inverse_dynamics(q, qd, qdd)
        M = robot.mass_matrix(q)
    for k in range(N):
        qp = pin_q(model, q[k])
        pin.framesForwardKinematics(model, data, qp)
        Tb = data.oMf[root].homogeneous
        Tp = np.linalg.solve(Tb, data.oMf[fid].homogeneous)
        np.testing.assert_allclose(T[k], Tp, rtol=0, atol=1e-12 * size)
        Jp = pin.computeFrameJacobian(model, data, qp, fid, pin.LOCAL_WORLD_ALIGNED)
        Rb = Tb[:3, :3]  # pinocchio's world axes -> deltagen's base axes
        Jp = np.vstack((Rb.T @ Jp[:3], Rb.T @ Jp[3:]))
        np.testing.assert_allclose(J[k], Jp, rtol=0, atol=1e-12 * size)
    if dynamics:
        # joint friction from the file's <dynamics damping friction>, as pinocchio read it
        assert_dynamics_as_pinocchio(model, data, q, qd, qdd, tau, M)
