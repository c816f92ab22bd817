"""Real files load (model/urdf.py, "Inertials"): an inertia indefinite by the rounding of its
printed digits is clamped with a URDFWarning naming the link; a larger defect is an error
naming it; and a defect in a link that does not reach the chain never blocks the chain
(TIAGo's 1 mg antenna on the mobile base, smallest principal moment -3.5e-8 kg m^2)."""

from __future__ import annotations

import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinocchio_oracles import assert_gravity_as_pinocchio, pinocchio_chain

from deltagen import SerialRobot
from deltagen.errors import GeometryError
from deltagen.model.urdf import URDFWarning, description_from_urdf

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"

# the antenna's inertia as TIAGo's file prints it: eigenvalues -3.5e-8 .. 1.0e-7 kg m^2
ANTENNA = 'ixx="0.00000002371" ixy="0.00000006119" ixz="0.00000001179" iyy="0.00000002833" iyz="0.00000000774" izz="0.00000003849"'


def _inertia_attrs(tensor):
    v = {k: float(tensor[r, c]) for k, (r, c) in _ENTRIES.items()}
    return " ".join(f'{k}="{x!r}"' for k, x in v.items())


_ENTRIES = {
    "ixx": (0, 0),
    "iyy": (1, 1),
    "izz": (2, 2),
    "ixy": (0, 1),
    "ixz": (0, 2),
    "iyz": (1, 2),
}


def _indefinite(smallest, others=(0.02, 0.03)):
    """An inertia tensor with principal moments (smallest, *others) in turned axes."""
    c, s = np.cos(0.5), np.sin(0.5)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ np.array(
        [[1, 0, 0], [0, c, -s], [0, s, c]]
    )
    tensor = R @ np.diag([smallest, *others]) @ R.T
    return np.triu(tensor) + np.triu(tensor, 1).T  # symmetric as the file's six numbers


def _file(arm_inertia, base_extra="", antenna=ANTENNA, antenna_mass="0.000001"):
    """base -> (fixed) mobile base with an antenna -> j1 -> l1 -> j2 -> l2 (the arm; both
    axes along z, so that link 1's universal frame has the axes of the URDF's link frame
    and its inertia tensor is the file's)."""
    return f"""<?xml version="1.0"?>
<robot name="mobile">
  <link name="footprint"/>
  <link name="mobile_base"><inertial><mass value="20"/>
    <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="antenna"><inertial><mass value="{antenna_mass}"/><inertia {antenna}/></inertial></link>
  <link name="l1"><inertial><origin xyz="0 0 0.1"/><mass value="2"/>
    <inertia {arm_inertia}/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  {base_extra}
  <joint name="base_joint" type="fixed"><parent link="footprint"/><child link="mobile_base"/></joint>
  <joint name="antenna_joint" type="fixed"><parent link="mobile_base"/><child link="antenna"/>
    <origin xyz="-0.2 0.1 0.2"/></joint>
  <joint name="j1" type="revolute"><parent link="mobile_base"/><child link="l1"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
</robot>
"""


GOOD = _inertia_attrs(_indefinite(0.01))


def _load(tmp_path, text, base="mobile_base", tip="l2"):
    path = tmp_path / "arm.urdf"
    path.write_text(text)
    return description_from_urdf(path, base, tip)


def _inertia(desc, i):
    return desc.joints[i].inertial.inertia_matrix


def test_defects_off_the_chain_do_not_block_it(tmp_path):
    """TIAGo's antenna, a negative mass and a garbled number in links the chain does not
    reach: the chain loads, equal to the one of a file without them."""
    clean = _load(tmp_path, _file(GOOD, antenna=GOOD))
    bad_elsewhere = (
        '<link name="tray"><inertial><mass value="-1"/></inertial></link>'
        '<link name="lamp"><inertial><mass value="one"/></inertial></link>'
        '<joint name="tray_joint" type="fixed"><parent link="mobile_base"/><child link="tray"/></joint>'
        '<joint name="lamp_joint" type="fixed"><parent link="footprint"/><child link="lamp"/></joint>'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", URDFWarning)
        for base in ("mobile_base", "footprint"):
            desc = _load(tmp_path, _file(GOOD, base_extra=bad_elsewhere), base=base)
            assert desc.key().split("\n")[1:] == clean.key().split("\n")[1:]


def test_a_defect_on_the_chain_is_an_error_naming_the_link(tmp_path):
    with pytest.raises(GeometryError, match=r"link 'l1' <inertia>: not positive semidefinite"):
        _load(tmp_path, _file(_inertia_attrs(_indefinite(-1e-3))))
    with pytest.raises(GeometryError, match=r"link 'l1' <inertia>: not positive semidefinite"):
        _load(tmp_path, _file(ANTENNA))  # the antenna's tensor is more than rounding
    # on the chain when it is fixed to a moving link
    text = _file(GOOD).replace(
        '<parent link="mobile_base"/><child link="antenna"/>',
        '<parent link="l2"/><child link="antenna"/>',
    )
    with pytest.raises(GeometryError, match=r"link 'antenna' <inertia>: not positive"):
        _load(tmp_path, text)
    text = _file(GOOD).replace('<mass value="1"/>', '<mass value="-1"/>')
    with pytest.raises(GeometryError, match=r"link 'l2' <mass>: must be >= 0 kg"):
        _load(tmp_path, text)


@pytest.mark.parametrize(
    "smallest, others",
    [(-5e-9, (0.02, 0.03)), (-1e-10, (1e-6, 1e-6))],  # 1e-7 of the trace; 1e-10 kg m^2
)
def test_rounding_noise_is_clamped_with_a_warning(tmp_path, smallest, others):
    tensor = _indefinite(smallest, others)
    with pytest.warns(
        URDFWarning, match=r"link 'l1' <inertia>: smallest principal moment .*clamped"
    ):
        desc = _load(tmp_path, _file(_inertia_attrs(tensor)))
    got = _inertia(desc, 0)
    lam = np.linalg.eigvalsh(got)
    assert lam[0] >= -1e-15 * lam[-1]  # positive semidefinite up to the rounding of the turn
    np.testing.assert_allclose(np.sort(lam)[1:], sorted(others), rtol=1e-12)
    exact = _indefinite(0.0, others)  # the tensor the rounded digits stand for
    assert np.abs(got - exact).max() <= 2 * abs(smallest)
    with pytest.raises(GeometryError, match="not positive semidefinite"):  # beyond both bounds
        _load(tmp_path, _file(_inertia_attrs(_indefinite(smallest * 30, others))))


def test_tiny_rounding_is_kept_as_the_file_writes_it(tmp_path):
    """Below 1e-12 of the tensor's size nothing is changed (and nothing is said)."""
    tensor = _indefinite(-1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter("error", URDFWarning)
        desc = _load(tmp_path, _file(_inertia_attrs(tensor)))
    np.testing.assert_array_equal(_inertia(desc, 0), tensor)


@pytest.mark.skipif(not ROBOTS_DIR.is_dir(), reason="example-robot-data (test extra) is absent")
@pytest.mark.parametrize("file", ["tiago.urdf", "tiago_no_hand.urdf", "tiago_dual.urdf"])
def test_tiago_arms_load_and_agree_with_pinocchio(file):
    pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")

    path = ROBOTS_DIR / "tiago_description/robots" / file
    tip = "arm_left_7_link" if file == "tiago_dual.urdf" else "arm_7_link"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)  # locked fingers and head
        robot = SerialRobot.from_urdf(path, "base_footprint", tip, backend="reference")
    chain = [j.name for j in robot.description.joints]
    assert robot.n == 8 and chain[0] == "torso_lift_joint"
    model = pinocchio_chain(path, chain)
    data = model.createData()
    rng = np.random.default_rng(6)
    lim = robot.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (50, robot.n))
    T = robot.fk(q)
    fid = model.getFrameId(tip)
    for k in range(len(q)):
        pin.framesForwardKinematics(model, data, q[k])
        np.testing.assert_allclose(T[k], data.oMf[fid].homogeneous, rtol=0, atol=1e-12)
    assert_gravity_as_pinocchio(robot, model, rng)
    assert pin is not None
