"""URDF import (model/urdf.py, SerialRobot.from_urdf), checked against pinocchio's own URDF
parser and dynamics on the same files, and against the UR5 written as a DH table."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pinocchio_oracles import (
    compare_with_pinocchio,
    pin_q,
    random_urdf_q,
)

from deltagen import SerialRobot
from deltagen.errors import GeometryError
from deltagen.geometry.rotations import rot_axis
from deltagen.model.serial import SerialDescription
from deltagen.model.urdf import URDFWarning, description_from_urdf
from deltagen.paths import robots_dir

pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")

UR5 = robots_dir() / "ur5.urdf"

# An arm that uses every feature: reversed axes (-z, -x), a non-unit axis (continuous joint),
# a tilted prismatic axis, fixed joints in the middle (with a massive link, lumped into its
# parent body) and at the end, inertia frames turned by rpy, a side branch (massless sensor
# link) so that the tip must be named.
ODD = """<?xml version="1.0"?>
<robot name="odd-arm">
  <link name="world_base"/>
  <link name="l1">
    <inertial><origin xyz="0.01 0.02 0.1" rpy="0.3 -0.2 0.5"/><mass value="2.5"/>
      <inertia ixx="0.03" ixy="0.001" ixz="-0.002" iyy="0.04" iyz="0.003" izz="0.02"/></inertial>
  </link>
  <link name="l2">
    <inertial><origin xyz="0.2 -0.01 0.03" rpy="-0.4 0.1 1.2"/><mass value="3.0"/>
      <inertia ixx="0.05" ixy="0" ixz="0.004" iyy="0.06" iyz="0" izz="0.03"/></inertial>
  </link>
  <link name="l2_plate">
    <inertial><origin xyz="0.05 0.05 0.0" rpy="0 0.7 0"/><mass value="0.8"/>
      <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.006"/></inertial>
  </link>
  <link name="l3">
    <inertial><origin xyz="0 0 0.15" rpy="0 0 0"/><mass value="1.5"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.004"/></inertial>
  </link>
  <link name="l4">
    <inertial><origin xyz="0.03 0 0.02" rpy="1.0 0.2 -0.3"/><mass value="1.1"/>
      <inertia ixx="0.006" ixy="0.0005" ixz="0" iyy="0.007" iyz="0" izz="0.003"/></inertial>
  </link>
  <link name="l5">
    <inertial><origin xyz="0 0.04 0.01" rpy="0 0 0"/><mass value="0.6"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.002"/></inertial>
  </link>
  <link name="sensor"/>
  <link name="tip"/>
  <joint name="j1" type="revolute">
    <parent link="world_base"/><child link="l1"/>
    <origin xyz="0.1 0.05 0.3" rpy="0.1 0.2 0.3"/><axis xyz="0 0 -1"/>
    <limit lower="-2.5" upper="2.5" effort="10" velocity="2"/>
  </joint>
  <joint name="j2" type="continuous">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0 0.1 0.2" rpy="1.5707963267948966 0 0"/><axis xyz="1 2 2"/>
  </joint>
  <joint name="plate_mount" type="fixed">
    <parent link="l2"/><child link="l2_plate"/>
    <origin xyz="0.3 0 0.05" rpy="0 0 0.4"/>
  </joint>
  <joint name="j3" type="prismatic">
    <parent link="l2_plate"/><child link="l3"/>
    <origin xyz="0.05 0 0" rpy="0 0 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-0.1" upper="0.2" effort="100" velocity="0.5"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="l3"/><child link="l4"/>
    <origin xyz="0 0.02 0.3" rpy="0 -0.6 0"/><axis xyz="-1 0 0"/>
    <limit lower="-2" upper="2" effort="5" velocity="3"/>
  </joint>
  <joint name="j5" type="revolute">
    <parent link="l4"/><child link="l5"/>
    <origin xyz="0.1 0 0" rpy="0 0 0"/><axis xyz="0 -1 0"/>
    <limit lower="-3" upper="3" effort="5" velocity="3"/>
  </joint>
  <joint name="sensor_mount" type="fixed">
    <parent link="l3"/><child link="sensor"/><origin xyz="0 0.1 0"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="l5"/><child link="tip"/><origin xyz="0 0.05 0.12" rpy="0.2 0.3 -0.1"/>
  </joint>
</robot>
"""


@pytest.fixture(scope="session")
def odd_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "odd.urdf"
    path.write_text(ODD)
    return path


def test_ur5_matches_pinocchio():
    robot = SerialRobot.from_urdf(UR5, backend="reference")
    assert robot.name == "ur5" and robot.n == 6
    assert robot.description.has_inertia
    compare_with_pinocchio(robot, UR5, "ee_link")


def test_odd_arm_matches_pinocchio(odd_path):
    with pytest.warns(URDFWarning, match="j2.*normalised"):
        robot = SerialRobot.from_urdf(odd_path, tip="tip", backend="reference")
    assert robot.name == "odd_arm"
    assert [j.type for j in robot.description.joints] == ["revolute"] * 2 + ["prismatic"] + [
        "revolute"
    ] * 2
    lim = robot.qlim
    assert np.isinf(lim[1]).all()  # continuous
    np.testing.assert_array_equal(lim[2], [-0.1, 0.2])
    compare_with_pinocchio(robot, odd_path, "tip")


def test_ur5_urdf_equals_the_published_dh_table():
    """UR5 URDF (ur_description joint origins) vs Universal Robots' DH table: the same
    joint variables (same zero and sign) and T_urdf(q) = B T_dh(q) E with the constant
    B = Rot_z(pi) (ur_description's base_link faces the other way) and E the pure rotation
    with columns (e_z, -e_x, -e_y) read as E = [[0,-1,0],[0,0,-1],[1,0,0]] (ee_link has x
    along the tool axis, DH frame 6 has z there)."""
    pi = math.pi
    a = [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0]
    alpha = [pi / 2, 0.0, 0.0, pi / 2, -pi / 2, 0.0]
    d = [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823]
    rows = [dict(a=x, alpha=y, d=z) for x, y, z in zip(a, alpha, d)]
    dh = SerialRobot(SerialDescription.from_rows(rows, "standard", name="ur5_dh"), "reference")
    urdf = SerialRobot.from_urdf(UR5, backend="reference")
    B = np.eye(4)
    B[:3, :3] = rot_axis(2, pi)
    E = np.eye(4)
    E[:3, :3] = [[0, -1, 0], [0, 0, -1], [1, 0, 0]]
    q = random_urdf_q(urdf, np.random.default_rng(3))
    np.testing.assert_allclose(urdf.fk(q), B @ dh.fk(q) @ E, rtol=0, atol=1e-12)


def test_links_fixed_to_a_moving_link_are_lumped_into_it(odd_path):
    """The body of j2 is l2 plus the plate fixed to it (3.0 + 0.8 kg); the sensor link on
    the side branch and the massless tip add nothing. (Its COM and inertia are checked
    through pinocchio's rnea/crba in test_odd_arm_matches_pinocchio.)"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        desc = description_from_urdf(odd_path, tip="tip")
    assert desc.joints[1].inertial.mass == pytest.approx(3.8, abs=1e-15)
    assert [j.inertial.mass for j in desc.joints] == pytest.approx([2.5, 3.8, 1.5, 1.1, 0.6])


# ------------------------------------------------------------------ chain selection


def test_several_leaves_are_listed(odd_path):
    with pytest.raises(GeometryError, match=r"2 leaves \(sensor, tip\).*tip="):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", URDFWarning)
            description_from_urdf(odd_path)


def test_sub_chain_and_unknown_links(odd_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        desc = description_from_urdf(odd_path, base="l1", tip="sensor")
        assert [j.name for j in desc.joints] == ["j2", "j3"]
        with pytest.raises(GeometryError, match=r"tip link 'nowhere' is not defined; links: .*l2"):
            description_from_urdf(odd_path, tip="nowhere")
        with pytest.raises(GeometryError, match=r"base link 'nob' is not defined"):
            description_from_urdf(odd_path, base="nob", tip="tip")
        with pytest.raises(GeometryError, match="does not lie below base link 'l4'"):
            description_from_urdf(odd_path, base="l4", tip="sensor")
        with pytest.raises(GeometryError, match="no movable joint"):
            description_from_urdf(odd_path, base="l5", tip="tip")


# ------------------------------------------------------------------ malformed files


def _robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="bad">\n{body}\n</robot>\n'


_TWO = '<link name="a"/><link name="b"/>'


def _joint(kind="revolute", inner="", name="j"):
    return f'<joint name="{name}" type="{kind}"><parent link="a"/><child link="b"/>{inner}</joint>'


_LIMIT = '<limit lower="-1" upper="1"/>'

MALFORMED = {
    "floating": (_TWO + _joint("floating"), r"joint 'j': floating joints are not supported"),
    "planar": (_TWO + _joint("planar"), r"joint 'j': planar joints are not supported"),
    "unknown type": (_TWO + _joint("hinge"), r"joint 'j': unknown joint type 'hinge'"),
    "mimic": (
        _TWO + _joint(inner=_LIMIT + '<mimic joint="k"/>'),
        r"joint 'j': <mimic joint='k'> names a joint that is not a movable joint of the chain",
    ),
    "missing parent": (
        _TWO + '<joint name="j" type="fixed"><child link="b"/></joint>',
        r"joint 'j': missing <parent link=...>",
    ),
    "undefined child": (
        '<link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint>',
        r"joint 'j': <child> names link 'zz', which is not defined",
    ),
    "non-numeric origin": (
        _TWO + _joint(inner=_LIMIT + '<origin xyz="0 one 0"/>'),
        r"joint 'j' <origin xyz>: 'one' is not a number",
    ),
    "short rpy": (
        _TWO + _joint(inner=_LIMIT + '<origin rpy="0 0"/>'),
        r"joint 'j' <origin rpy>: expected 3 numbers",
    ),
    "non-numeric limit": (
        _TWO + _joint(inner='<limit lower="-1" upper="abc"/>'),
        r"joint 'j' <limit> attribute 'upper': 'abc' is not a number",
    ),
    "missing limit": (_TWO + _joint(), r"joint 'j': a revolute joint needs <limit"),
    "zero axis": (
        _TWO + _joint(inner=_LIMIT + '<axis xyz="0 0 0"/>'),
        r"joint 'j' <axis>: zero vector",
    ),
    "nan mass": (
        '<link name="a"/><link name="b"><inertial><mass value="nan"/></inertial></link>'
        + _joint(inner=_LIMIT),
        r"link 'b' <mass> attribute 'value': 'nan' is not finite",
    ),
    "indefinite inertia": (
        '<link name="a"/><link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" iyy="1" izz="-1"/></inertial></link>' + _joint(inner=_LIMIT),
        r"link 'b' <inertia>: not positive semidefinite",
    ),
    "negative mass": (
        '<link name="a"/><link name="b"><inertial><mass value="-2"/></inertial></link>'
        + _joint(inner=_LIMIT),
        r"link 'b' <mass>: must be >= 0 kg",
    ),
    "limit upside down": (
        _TWO + _joint(inner='<limit lower="1" upper="-1"/>'),
        r"joint 'j' <limit>: lower 1.0 must be below upper -1.0",
    ),
    "two parents": (
        '<link name="a"/><link name="b"/><link name="c"/>'
        + _joint("fixed")
        + '<joint name="k" type="fixed"><parent link="c"/><child link="b"/></joint>',
        r"joint 'k': link 'b' is already the child of joint 'j'",
    ),
    "cycle": (
        '<link name="r"/><link name="a"/><link name="b"/>'
        + _joint("fixed")
        + '<joint name="k" type="fixed"><parent link="b"/><child link="a"/></joint>',
        r"cycle through link",
    ),
    "not a robot": (None, r"root element is <model>"),
    "broken xml": ("<link name='a'>", r"not well-formed XML"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_urdf_names_the_element(tmp_path, case):
    body, message = MALFORMED[case]
    path = tmp_path / "bad.urdf"
    path.write_text("<model/>" if body is None else _robot(body))
    with pytest.raises(GeometryError, match=message):
        description_from_urdf(path)


def test_entity_expansion_is_refused_before_parsing(tmp_path):
    lol = (
        '<?xml version="1.0"?>\n<!DOCTYPE robot [\n <!ENTITY lol "lol">\n'
        ' <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n]>\n'
        '<robot name="&lol2;"><link name="a"/></robot>\n'
    )
    path = tmp_path / "lol.urdf"
    path.write_text(lol)
    with pytest.raises(GeometryError, match="DOCTYPE/ENTITY declarations are refused"):
        description_from_urdf(path)


def test_unit_axes_do_not_warn(odd_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", URDFWarning)
        SerialRobot.from_urdf(UR5, backend="reference")


@pytest.mark.slow
def test_compiled_core_of_a_urdf_arm_matches_the_reference():
    """The compiled core comes from the same pipeline (generation + cffi build)."""
    compiled = SerialRobot.from_urdf(UR5)
    reference = compiled.with_backend("reference")
    rng = np.random.default_rng(11)
    q = random_urdf_q(compiled, rng, 200)
    qd, qdd = rng.uniform(-2, 2, q.shape), rng.uniform(-2, 2, q.shape)
    np.testing.assert_allclose(compiled.fk(q), reference.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.jacobian(q), reference.jacobian(q), rtol=0, atol=1e-12)
    tau_c, tau_r = compiled.inverse_dynamics(q, qd, qdd), reference.inverse_dynamics(q, qd, qdd)
    assert np.abs(tau_c - tau_r).max() <= 1e-10 * np.abs(tau_r).max()


# two revolute joints, no inertials: `deltagen generate` renders and compiles its whole module
# in a few seconds (the UR5's is checked in: generating it compiled generated/serial_ur5.c,
# 13 units at -O3, and rendered nothing)
TWO_JOINTS = """<?xml version="1.0"?>
<robot name="urdf_pair">
  <link name="base"/><link name="upper"/><link name="tip"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="tip"/>
    <origin xyz="0.3 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def test_generate_renders_compiles_and_caches_a_urdf_arm(tmp_path, private_cache):
    """`deltagen generate arm.urdf` (apps/generate.py generate_robot_file): the chain's C
    rendered into the (empty) cache and its complete module compiled there, whose fk is the
    reference's."""
    from deltagen.apps.generate import generate_robot_file
    from deltagen.native.serial import module_ready

    path = tmp_path / "pair.urdf"
    path.write_text(TWO_JOINTS)
    desc = description_from_urdf(path)
    assert not module_ready(desc)
    folder = generate_robot_file(path)
    assert (folder / "serial_urdf_pair.c").is_file() and module_ready(desc)
    arm = SerialRobot.from_urdf(path)
    q = np.random.default_rng(3).uniform(-3, 3, (50, 2))
    np.testing.assert_allclose(arm.fk(q), arm.with_backend("reference").fk(q), rtol=0, atol=1e-14)


def test_cli_reads_a_urdf(capsys):
    """`deltagen fk arm.urdf ...` loads the chain (the position printed is from_urdf's)."""
    from deltagen.cli import main

    q = [0.1, -1.2, 1.4, -0.3, 1.5708, 0.2]
    assert main(["fk", str(UR5), "--backend", "reference", *map(str, q)]) == 0
    out = capsys.readouterr().out
    p = SerialRobot.from_urdf(UR5, backend="reference").fk(np.array(q))[:3, 3]
    assert f"x, y, z = [{p[0]:.9f}, {p[1]:.9f}, {p[2]:.9f}] m" in out


def test_declarations_the_byte_check_cannot_read_are_refused_by_the_parser(tmp_path):
    """A UTF-16 file hides '<!DOCTYPE' from a look at the bytes; expat's handlers refuse it."""
    lol = (
        '<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE robot [<!ENTITY lol "lol">]>\n'
        '<robot name="&lol;"><link name="a"/></robot>\n'
    )
    path = tmp_path / "lol16.urdf"
    path.write_bytes(lol.encode("utf-16"))
    assert b"<!DOCTYPE" not in path.read_bytes()
    with pytest.raises(GeometryError, match="DOCTYPE/ENTITY declarations are refused"):
        description_from_urdf(path)


def test_joint_dynamics_become_viscous_and_coulomb_friction(tmp_path):
    """<dynamics damping friction> adds damping qd + friction sign(qd) to that joint's
    torque (model/urdf.py), and nothing elsewhere."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        path = tmp_path / "damped.urdf"
        path.write_text(
            ODD.replace(
                '<axis xyz="0 -1 0"/>',
                '<axis xyz="0 -1 0"/><dynamics damping="0.7" friction="0.2"/>',
            )
        )
        damped = SerialRobot.from_urdf(path, tip="tip", backend="reference")
        odd = tmp_path / "odd.urdf"
        odd.write_text(ODD)
        free = SerialRobot.from_urdf(odd, tip="tip", backend="reference")
    rng = np.random.default_rng(5)
    q = random_urdf_q(free, rng, 50)
    qd, qdd = rng.uniform(-2, 2, q.shape), rng.uniform(-2, 2, q.shape)
    extra = damped.inverse_dynamics(q, qd, qdd) - free.inverse_dynamics(q, qd, qdd)
    expected = np.zeros_like(q)
    expected[:, 4] = 0.7 * qd[:, 4] + 0.2 * np.sign(qd[:, 4])
    np.testing.assert_allclose(extra, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("path_name", ["ur5", "odd"])
def test_every_link_pose_matches_pinocchio(path_name, odd_path):
    """fk of every link: the chain from the root to each link in turn (tip=link), against
    pinocchio's frame of that link, on 200 random configurations of the whole arm."""
    path = UR5 if path_name == "ur5" else odd_path
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        whole = SerialRobot.from_urdf(
            path, tip="ee_link" if path_name == "ur5" else "tip", backend="reference"
        )
        names = [j.name for j in whole.description.joints]
        q = random_urdf_q(whole, np.random.default_rng(9), 200)
        checked = 0
        for frame in model.frames:
            if frame.type != pin.FrameType.BODY:
                continue
            try:
                part = SerialRobot.from_urdf(path, tip=frame.name, backend="reference")
            except GeometryError as exc:  # the root and links fixed to it: no joint
                assert "no movable joint" in str(exc)
                continue
            cols = [names.index(j.name) for j in part.description.joints]
            T = part.fk(q[:, cols])
            fid = model.getFrameId(frame.name)
            for k in range(len(q)):
                pin.framesForwardKinematics(model, data, pin_q(model, q[k]))
                np.testing.assert_allclose(T[k], data.oMf[fid].homogeneous, rtol=0, atol=1e-12)
            checked += 1
    assert checked == (6 if path_name == "ur5" else 7) + 1  # every moving link and the tip


def test_quirks_of_published_files_are_read_with_a_warning(tmp_path):
    """<limit lower="0" upper="0"> (the specification's defaults, in files that give only
    effort and velocity) is no position limit, and <mimic> on a fixed joint is ignored
    (urdfdom and pinocchio ignore it); both say so."""
    path = tmp_path / "quirks.urdf"
    path.write_text(
        _robot(
            '<link name="a"/><link name="b"/><link name="c"/>'
            + _joint(inner='<limit lower="0" upper="0" effort="1" velocity="1"/>')
            + '<joint name="k" type="fixed"><parent link="b"/><child link="c"/>'
            '<mimic joint="j"/></joint>'
        )
    )
    with pytest.warns(URDFWarning) as record:
        desc = description_from_urdf(path)
    messages = " | ".join(str(w.message) for w in record)
    assert "lower = upper = 0.0, read as no position limits" in messages
    assert "<mimic> on a fixed joint is ignored" in messages
    assert desc.n == 1 and np.all(np.isinf(desc.qlim))
