"""Links off the base-tip chain (branches, links beyond the tip) folded into the chain link
they hang from (model/urdf.py, "Inertials"): fixed joints by their origin, movable ones
locked.

Evidence: (1) a two-link URDF whose first link carries a fixed child, against the same arm
with the merged inertial written in by hand, computed here a second way (each body's
inertia about the link origin, summed, then moved back to the common COM); (2) pinocchio's
buildReducedModel on the Panda with its hand and fingers locked at a configuration that is
not zero."""

from __future__ import annotations

import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinocchio_oracles import assert_dynamics_as_pinocchio, random_urdf_q

from deltagen import SerialRobot
from deltagen.errors import GeometryError
from deltagen.model.urdf import URDFWarning

# link1's own inertial and its fixed child's (origin of the fixed joint, then the child's
# inertial origin and inertia)
M1, C1, RPY1 = 2.0, (0.1, 0.02, -0.03), (0.2, -0.1, 0.3)
I1 = np.array([[0.03, 0.001, -0.002], [0.001, 0.04, 0.003], [-0.002, 0.003, 0.05]])
FIX_XYZ, FIX_RPY = (0.05, -0.12, 0.2), (0.4, 0.7, -1.1)
M3, C3, RPY3 = 0.7, (0.03, 0.01, 0.06), (-0.5, 0.2, 0.9)
I3 = np.array([[0.004, 0.0002, 0.0], [0.0002, 0.006, -0.0004], [0.0, -0.0004, 0.005]])


def _inertial(mass, xyz, rpy, inertia):
    mass, xyz, rpy = float(mass), [float(v) for v in xyz], [float(v) for v in rpy]
    I = inertia.tolist()  # noqa: E741 (the inertia tensor's usual name)
    return (
        f'<inertial><origin xyz="{xyz[0]!r} {xyz[1]!r} {xyz[2]!r}" '
        f'rpy="{rpy[0]!r} {rpy[1]!r} {rpy[2]!r}"/><mass value="{mass!r}"/>'
        f'<inertia ixx="{I[0][0]!r}" iyy="{I[1][1]!r}" izz="{I[2][2]!r}" ixy="{I[0][1]!r}" '
        f'ixz="{I[0][2]!r}" iyz="{I[1][2]!r}"/></inertial>'
    )


def _two_link(link1_inertial: str, fixed_child: bool) -> str:
    child = ""
    if fixed_child:
        child = (
            f'<link name="sensor">{_inertial(M3, C3, RPY3, I3)}</link>'
            '<joint name="mount" type="fixed"><parent link="link1"/><child link="sensor"/>'
            f'<origin xyz="{FIX_XYZ[0]!r} {FIX_XYZ[1]!r} {FIX_XYZ[2]!r}" '
            f'rpy="{FIX_RPY[0]!r} {FIX_RPY[1]!r} {FIX_RPY[2]!r}"/></joint>'
        )
    I2 = np.diag([0.01, 0.02, 0.015])
    return f"""<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="link1">{link1_inertial}</link>
  <link name="link2">{_inertial(1.1, (0.2, 0.0, 0.01), (0.0, 0.0, 0.0), I2)}</link>
  {child}
  <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.4 0.0 0.1" rpy="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def _rpy(r, p, y):
    """URDF's fixed-axis roll-pitch-yaw: Rot_z(y) Rot_y(p) Rot_x(r)."""
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _merged_by_hand():
    """link1 + sensor as one body in link1's frame: each body's rotational inertia about
    link1's origin, I_o = R Ic R^T + m (|c|^2 1 - c c^T), summed, then moved to the common
    COM (a second route to model/urdf.py's lumping about the COM)."""
    R1 = _rpy(*RPY1)
    F = np.eye(4)
    F[:3, :3] = _rpy(*FIX_RPY)
    F[:3, 3] = FIX_XYZ
    c3 = F[:3, :3] @ np.array(C3) + F[:3, 3]
    R3 = F[:3, :3] @ _rpy(*RPY3)

    def about_origin(m, c, R, Ic):
        c = np.asarray(c, dtype=float)
        return R @ Ic @ R.T + m * (float(c @ c) * np.eye(3) - np.outer(c, c))

    mass = M1 + M3
    com = (M1 * np.array(C1) + M3 * c3) / mass
    I_o = about_origin(M1, C1, R1, I1) + about_origin(M3, c3, R3, I3)
    Ic = I_o - mass * (float(com @ com) * np.eye(3) - np.outer(com, com))
    return mass, com, Ic


@pytest.fixture(scope="module")
def two_link_pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fold")
    with_child = folder / "with_child.urdf"
    with_child.write_text(_two_link(_inertial(M1, C1, RPY1, I1), fixed_child=True))
    mass, com, Ic = _merged_by_hand()
    merged = folder / "merged.urdf"
    merged.write_text(_two_link(_inertial(mass, com, (0.0, 0.0, 0.0), Ic), fixed_child=False))
    return with_child, merged


def test_a_fixed_branch_is_lumped_into_its_link(two_link_pair):
    with_child, merged = two_link_pair
    a = SerialRobot.from_urdf(with_child, "base", "link2", backend="reference")
    b = SerialRobot.from_urdf(merged, "base", "link2", backend="reference")
    rng = np.random.default_rng(11)
    q = rng.uniform(-3, 3, (50, 2))
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    tau_a = a.inverse_dynamics(q, qd, qdd)
    tau_b = b.inverse_dynamics(q, qd, qdd)
    assert np.abs(tau_a - tau_b).max() <= 1e-12 * np.abs(tau_b).max()
    M_a, M_b = a.mass_matrix(q), b.mass_matrix(q)
    assert np.abs(M_a - M_b).max() <= 1e-12 * np.abs(M_b).max()
    assert a.description.joints[0].inertial.mass == pytest.approx(M1 + M3, rel=1e-15)


pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")


def test_the_fixed_branch_matches_pinocchio(two_link_pair):
    """pinocchio merges the fixed child into link1 by its own code."""
    with_child, _ = two_link_pair
    robot = SerialRobot.from_urdf(with_child, "base", "link2", backend="reference")
    model = pin.buildModelFromUrdf(str(with_child))
    data = model.createData()
    rng = np.random.default_rng(12)
    q = rng.uniform(-3, 3, (50, 2))
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    tau = robot.inverse_dynamics(q, qd, qdd)
    for k in range(len(q)):
        taup = pin.rnea(model, data, q[k], qd[k], qdd[k])
        assert np.abs(tau[k] - taup).max() <= 1e-10 * np.abs(taup).max()


ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
PANDA = ROBOTS_DIR / "panda_description/urdf/panda.urdf"


@pytest.mark.skipif(not PANDA.is_file(), reason="example-robot-data (test extra) not installed")
@pytest.mark.parametrize("tip", ["panda_link8", "panda_link7"])
def test_panda_fingers_locked_open_match_pinocchio_reduced_model(tip):
    """The hand and both fingers beyond the tip, the fingers locked 3 cm open: joint 1 given,
    joint 2 following by its <mimic>; pinocchio locks both at the same configuration."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", URDFWarning)  # every locked joint is given or mimics
        robot = SerialRobot.from_urdf(
            PANDA, "panda_link0", tip, locked={"panda_finger_joint1": 0.03}, backend="reference"
        )
    full = pin.buildModelFromUrdf(str(PANDA))
    q_ref = pin.neutral(full)
    lock = []
    for name in ("panda_finger_joint1", "panda_finger_joint2"):
        k = full.getJointId(name)
        q_ref[full.joints[k].idx_q] = 0.03
        lock.append(k)
    model = pin.buildReducedModel(full, lock, q_ref)
    data = model.createData()
    rng = np.random.default_rng(5)
    q = random_urdf_q(robot, rng, 100)
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    tau = robot.inverse_dynamics(q, qd, qdd)
    M = robot.mass_matrix(q)
    assert_dynamics_as_pinocchio(model, data, q, qd, qdd, tau, M)
    # the fingers' 2 x 15 g matter: locked closed, the mass matrix differs
    with pytest.warns(URDFWarning, match=r"panda_finger_joint1 = 0, panda_finger_joint2 = 0"):
        closed = SerialRobot.from_urdf(PANDA, "panda_link0", tip, backend="reference")
    assert np.abs(closed.mass_matrix(q) - M).max() > 1e-6


@pytest.mark.skipif(not PANDA.is_file(), reason="example-robot-data (test extra) not installed")
def test_locking_a_joint_that_is_not_off_the_chain_is_refused():
    with pytest.raises(GeometryError, match=r"locked: 'panda_joint3' is not a movable joint off"):
        SerialRobot.from_urdf(
            PANDA, "panda_link0", "panda_link8", locked={"panda_joint3": 0.1}, backend="reference"
        )
    with pytest.raises(GeometryError, match=r"locked\['panda_finger_joint1'\]: nan is not finite"):
        SerialRobot.from_urdf(
            PANDA,
            "panda_link0",
            "panda_link8",
            locked={"panda_finger_joint1": float("nan")},
            backend="reference",
        )
    with pytest.raises(GeometryError, match=r"locked: 'nope'"):
        SerialRobot.from_urdf(
            PANDA, "panda_link0", "panda_link8", locked={"nope": 0.1}, backend="reference"
        )


def test_an_off_chain_joint_mimicking_a_chain_joint_is_refused(tmp_path, two_link_pair):
    text = two_link_pair[0].read_text()
    text = text.replace(
        "</robot>",
        '<link name="flap"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" '
        'izz="1e-4"/></inertial></link><joint name="flap_joint" type="revolute">'
        '<parent link="link1"/><child link="flap"/><axis xyz="1 0 0"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j2"/></joint>'
        "</robot>",
    )
    path = tmp_path / "flap.urdf"
    path.write_text(text)
    with pytest.raises(GeometryError, match=r"'flap_joint' off the chain mimics joint 'j2'"):
        SerialRobot.from_urdf(path, "base", "link2", backend="reference")
