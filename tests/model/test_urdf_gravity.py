"""Gravity in the URDF's world (model/urdf.py, "Gravity"): the root link's frame is the
world, g = (0, 0, -9.81) there, and a chain whose base link is turned in that world (iCub's
``chest``: z horizontal) gets g turned into its base frame through the joints above it.
Checked against pinocchio building the whole file with the world's gravity and locking the
joints outside the chain (buildReducedModel)."""

from __future__ import annotations

import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinocchio_oracles import assert_gravity_as_pinocchio, pinocchio_chain

from deltagen import SerialRobot
from deltagen.errors import GeometryError
from deltagen.model.urdf import URDFWarning

pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"


def _link(name, mass, com, rpy, inertia):
    ixx, iyy, izz, ixy, ixz, iyz = inertia
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}" rpy="{rpy}"/>'
        f'<mass value="{mass}"/><inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="{ixy}" '
        f'ixz="{ixz}" iyz="{iyz}"/></inertial></link>'
    )


def _joint(name, kind, parent, child, xyz, rpy, axis="0 0 1"):
    limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>' if kind != "fixed" else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{limit}</joint>'
    )


# world -> (waist, movable, above the chain) -> torso -> (fixed, turned) -> chest = the
# chain's base -> three revolute joints -> hand, plus a branch (head) off the torso
TURNED = (
    '<?xml version="1.0"?><robot name="turned">'
    '<link name="world"/>'
    + _link("torso", 5.0, "0 0 0.2", "0 0 0", (0.1, 0.1, 0.05, 0, 0, 0))
    + _link("chest", 3.0, "0.05 0 0.1", "0 0 0", (0.04, 0.05, 0.03, 0, 0, 0))
    + _link("head", 2.0, "0 0 0.1", "0 0 0", (0.01, 0.01, 0.01, 0, 0, 0))
    + _link("upper", 2.0, "0.02 0.15 0.01", "0.3 -0.2 0.5", (0.03, 0.04, 0.02, 0.001, 0, 0.002))
    + _link("fore", 1.5, "0.1 0 -0.02", "0 0.4 0", (0.02, 0.02, 0.004, 0, 0, 0))
    + _link("hand", 0.7, "0 0.03 0.05", "1.0 0 0", (0.002, 0.003, 0.002, 0, 0.0001, 0))
    + _joint("waist", "revolute", "world", "torso", "0.1 0 0.8", "0 0 0", "0.6 0.8 0")
    + _joint("neck", "revolute", "torso", "head", "0 0 0.5", "0 0 0")
    + _joint("chest_mount", "fixed", "torso", "chest", "0 0.1 0.4", "1.5707963267948966 0.3 -0.6")
    + _joint("shoulder", "revolute", "chest", "upper", "0.1 0.2 0", "0.2 0 0", "1 0 0")
    + _joint("elbow", "revolute", "upper", "fore", "0 0.3 0", "0 0 0.3", "0 1 0")
    + _joint("wrist", "revolute", "fore", "hand", "0.25 0 0", "-0.4 0 0", "0 0 1")
    + "</robot>"
)
CHAIN = ["shoulder", "elbow", "wrist"]


@pytest.fixture(scope="module")
def turned_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("gravity") / "turned.urdf"
    path.write_text(TURNED)
    return path


@pytest.mark.parametrize("backend", ["reference", "compiled"])
def test_gravity_of_a_turned_base_is_the_worlds(turned_path, backend):
    with pytest.warns(URDFWarning, match=r"movable joints above the base at waist = 0"):
        robot = SerialRobot.from_urdf(turned_path, "chest", "hand", backend=backend)
    g = np.array(robot.description.gravity)
    assert np.linalg.norm(g) == pytest.approx(9.81, rel=1e-15)
    assert abs(g[2] + 9.81) > 1.0  # the base is turned: not its own -z
    assert_gravity_as_pinocchio(
        robot, pinocchio_chain(turned_path, CHAIN), np.random.default_rng(1)
    )


def test_locked_joints_above_the_base_and_gravity_given(turned_path):
    at = {"waist": 0.6}
    with warnings.catch_warnings():
        warnings.simplefilter("error", URDFWarning)  # waist is given: no warning about it
        robot = SerialRobot.from_urdf(
            turned_path, "chest", "hand", locked={**at, "neck": 0.0}, backend="reference"
        )
    model = pinocchio_chain(turned_path, CHAIN, at)
    assert_gravity_as_pinocchio(robot, model, np.random.default_rng(2))
    world_g = (1.5, -2.0, -9.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        robot = SerialRobot.from_urdf(
            turned_path, "chest", "hand", gravity=world_g, backend="reference"
        )
    model = pinocchio_chain(turned_path, CHAIN, gravity=world_g)
    assert_gravity_as_pinocchio(robot, model, np.random.default_rng(3))


def test_a_chain_from_the_root_keeps_the_files_gravity(turned_path):
    with pytest.warns(URDFWarning, match="off the chain"):
        robot = SerialRobot.from_urdf(turned_path, "world", "torso", backend="reference")
    assert robot.description.gravity == (0.0, 0.0, -9.81)


@pytest.mark.parametrize("bad", [(0, 0), (0, float("nan"), 1), "down"])
def test_gravity_must_be_three_finite_numbers(turned_path, bad):
    with pytest.raises(GeometryError, match="gravity must be 3 finite numbers"):
        SerialRobot.from_urdf(turned_path, "chest", "hand", gravity=bad, backend="reference")


def test_dh_arm_gravity_is_in_the_frame_of_its_poses():
    """Turning the world (base) and gravity together changes no torque; from_dh takes g."""
    rows = [
        dict(
            a=0.1, alpha_deg=90, d=0.3, mass=2.0, com=[0, 0.05, 0.01], inertia=[0.01] * 3 + [0] * 3
        ),
        dict(a=0.4, mass=1.5, com=[-0.2, 0, 0.02], inertia=[0.004, 0.02, 0.02, 0, 0, 0]),
        dict(
            a=0.3, alpha_deg=-90, mass=1.0, com=[-0.1, 0, 0], inertia=[0.002, 0.01, 0.01, 0, 0, 0]
        ),
    ]
    c, s = np.cos(0.7), np.sin(0.7)
    turn = np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])
    g = np.array([0.0, 0.0, -9.81])
    upright = SerialRobot.from_dh(rows, "standard", backend="reference")
    turned = SerialRobot.from_dh(
        rows, "standard", base=turn, gravity=turn[:3, :3] @ g, backend="reference"
    )
    q = np.random.default_rng(4).uniform(-2, 2, (20, 3))
    np.testing.assert_allclose(turned.gravity_torque(q), upright.gravity_torque(q), atol=1e-12)
    leaning = SerialRobot.from_dh(rows, "standard", gravity=(0, -9.81, 0), backend="reference")
    assert np.abs(leaning.gravity_torque(q) - upright.gravity_torque(q)).max() > 1.0


# published humanoids whose arms hang from a base that is not upright in the file's world
HUMANOID_ARMS = {
    # iCub: chest's z axis is horizontal; the torso joints above it locked at 0
    "icub_left_arm": ("icub_description/robots/icub.urdf", "chest", "l_hand"),
    "icub_right_arm": ("icub_description/robots/icub.urdf", "chest", "r_hand"),
    "talos_left_arm": ("talos_data/robots/talos_full_v2.urdf", "torso_2_link", "arm_left_7_link"),
}


@pytest.mark.skipif(not ROBOTS_DIR.is_dir(), reason="example-robot-data (test extra) is absent")
@pytest.mark.parametrize("name", sorted(HUMANOID_ARMS))
def test_published_humanoid_arms_gravity_as_pinocchio(name):
    file, base, tip = HUMANOID_ARMS[name]
    path = ROBOTS_DIR / file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        robot = SerialRobot.from_urdf(path, base, tip, backend="reference")
    chain = [j.name for j in robot.description.joints]
    assert_gravity_as_pinocchio(robot, pinocchio_chain(path, chain), np.random.default_rng(5))
