"""URDF loading at the edges: a side branch thousands of links long (walked with loops, its
masses folded in and checked against a sum written here), messages that name the file once
and the element at fault (no joints, a huge origin, mass, inertia or prismatic limit), and
an axis of any finite length read as its direction (a length below 1e-9 stays a zero
vector, refused)."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from helpers import REPO

from deltagen import SerialRobot, cli
from deltagen.errors import GeometryError
from deltagen.model.urdf import URDFWarning, description_from_urdf

BRANCH = 3000  # links of the side branch: far beyond Python's recursion limit (1000)
BRANCH_MASS = 0.002  # [kg] each
BRANCH_STEP = 0.001  # [m] between branch links, along the y axis of l1


def _arm(axis="0 0 1", xyz="0 0 0.1", mass="1.5", extra="", limit=None):
    """Two-joint arm base -> l1 -> l2; l1 (1.5 kg, COM at its origin) carries ``extra``."""
    j1 = (
        f'<joint name="j1" type="prismatic"><parent link="base"/><child link="l1"/>'
        f'<axis xyz="{axis}"/><origin xyz="{xyz}"/><limit lower="{limit[0]}" upper="{limit[1]}"/>'
        "</joint>"
        if limit
        else f'<joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>'
        f'<axis xyz="{axis}"/><origin xyz="{xyz}"/></joint>'
    )
    return f"""<robot name="edge">
<link name="base"/>
<link name="l1"><inertial><mass value="{mass}"/>
  <inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial></link>
<link name="l2"/>
{j1}
<joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
  <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
{extra}</robot>"""


def _branch() -> str:
    """A chain of BRANCH links fixed below l1, each BRANCH_STEP further along y."""
    parts = []
    for i in range(BRANCH):
        parts.append(
            f'<link name="b{i}"><inertial><mass value="{BRANCH_MASS}"/>'
            '<inertia ixx="0" iyy="0" izz="0"/></inertial></link>'
        )
        parent = "l1" if i == 0 else f"b{i - 1}"
        parts.append(
            f'<joint name="bj{i}" type="fixed"><parent link="{parent}"/><child link="b{i}"/>'
            f'<origin xyz="0 {BRANCH_STEP} 0"/></joint>'
        )
    return "\n".join(parts)


def _write(tmp_path, text, name="arm.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_side_branch_of_3000_links_is_folded_without_recursion(tmp_path):
    path = _write(tmp_path, _arm(extra=_branch()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        desc = description_from_urdf(path, tip="l2")
    # independent sum: l1 (1.5 kg at its origin) and BRANCH point masses on the y axis
    # at y_i = (i + 1) BRANCH_STEP, all rigid with l1
    m = 1.5 + BRANCH * BRANCH_MASS
    y = np.arange(1, BRANCH + 1) * BRANCH_STEP
    com_y = BRANCH_MASS * y.sum() / m
    inertial = desc.joints[0].inertial
    assert inertial.mass == pytest.approx(m, rel=1e-12)
    # the universal frame of joint 1 is l1's frame moved to joint 2, 0.3 m along its x
    # (module docstring of model/urdf.py: U_1 = W_1 G_1, G_1 = O_2 for z axes)
    assert inertial.com == pytest.approx((-0.3, com_y, 0.0), abs=1e-12)
    # parallel-axis theorem about the COM: I_xx gains sum m_i (y_i - com_y)^2 + 1.5 com_y^2
    ixx = 0.01 + BRANCH_MASS * float(((y - com_y) ** 2).sum()) + 1.5 * com_y**2
    assert inertial.inertia[0] == pytest.approx(ixx, rel=1e-9)


def test_a_long_mimic_chain_off_the_arm_is_followed_without_recursion(tmp_path):
    """Joints off the chain that mimic each other 1500 deep: locked at multiplier q +
    offset of their leader, followed in a loop."""
    n = 1500
    parts = ['<link name="m0"/>']
    parts.append(
        '<joint name="mj0" type="continuous"><parent link="l1"/><child link="m0"/>'
        '<axis xyz="0 0 1"/></joint>'
    )
    for i in range(1, n):
        parts.append(f'<link name="m{i}"/>')
        parts.append(
            f'<joint name="mj{i}" type="continuous"><parent link="m{i - 1}"/>'
            f'<child link="m{i}"/><axis xyz="0 0 1"/>'
            f'<mimic joint="mj{i - 1}" multiplier="1" offset="0.001"/></joint>'
        )
    path = _write(tmp_path, _arm(extra="\n".join(parts)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        desc = description_from_urdf(path, tip="l2", locked={"mj0": 0.25})
    assert desc.n == 2


def test_cli_reads_the_long_branch(tmp_path, capsys):
    path = _write(tmp_path, _arm(extra=_branch()))
    code = cli.main(["fk", str(path), "--tip", "l2", "--backend", "reference", "0", "0"])
    out, err = capsys.readouterr()
    assert code == 0 and "Traceback" not in err and "0.3" in out


@pytest.mark.parametrize(
    "text, message",
    [
        ("<robot name='x'><link name='a'/>", "not well-formed XML"),
        ("<!DOCTYPE x><robot/>", "DOCTYPE/ENTITY declarations are refused"),
        ("<rob/>", "the root element is <rob>"),
        ('<robot name="x"><link name="base"/></robot>', "no joints"),
        ('<robot name="x"/>', "no <link>"),
    ],
)
def test_the_file_is_named_once_and_the_fault_said(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(GeometryError) as info:
        description_from_urdf(path)
    assert message in str(info.value)
    assert str(info.value).count(str(path)) == 1, str(info.value)


def test_one_link_file_from_the_cli_says_no_joints(tmp_path, capsys):
    path = _write(tmp_path, '<robot name="x"><link name="base"/></robot>')
    assert cli.main(["fk", str(path), "--backend", "reference", "0"]) == 2
    err = capsys.readouterr().err
    assert "no joints" in err and err.count(str(path)) == 1


@pytest.mark.parametrize("axis", ["1e300 0 0", "1e300 1e300 0", "0 0 -3e200"])
def test_an_axis_of_any_finite_length_is_its_direction(tmp_path, axis):
    raw = np.array([float(v) for v in axis.split()])
    unit = raw / np.max(np.abs(raw))
    unit /= np.linalg.norm(unit)
    huge = _write(tmp_path, _arm(axis=axis), "huge.urdf")
    plain = _write(tmp_path, _arm(axis=" ".join(repr(float(v)) for v in unit)), "plain.urdf")
    with pytest.warns(URDFWarning, match=r"joint 'j1': axis .* has length"):
        a = SerialRobot.from_urdf(huge, backend="reference")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        b = SerialRobot.from_urdf(plain, backend="reference")
    q = np.array([[0.3, -0.7], [1.1, 0.2]])
    assert np.allclose(a.fk(q), b.fk(q), atol=1e-14)


@pytest.mark.parametrize(
    "kwargs, named",
    [
        ({"xyz": "1e300 0 0"}, "joint 'j1' <origin xyz>: 1e+300 m is beyond"),
        ({"xyz": "0 0 -2e6"}, "joint 'j1' <origin xyz>: -2000000.0 m is beyond"),
        ({"mass": "1e300"}, "link 'l1' <mass>: 1e+300 kg is beyond"),
        ({"limit": ("-1e300", "1")}, "joint 'j1' <limit>: -1e+300 m is beyond"),
        (
            {
                "extra": '<link name="s"><inertial><origin xyz="1e301 0 0"/><mass value="1"/>'
                '</inertial></link><joint name="js" type="fixed"><parent link="l1"/>'
                '<child link="s"/></joint>'
            },
            "link 's' <inertial> <origin xyz>: 1e+301 m is beyond",
        ),
    ],
)
def test_huge_lengths_and_masses_are_named(tmp_path, kwargs, named):
    path = _write(tmp_path, _arm(**kwargs))
    with pytest.raises(GeometryError) as info:
        description_from_urdf(path, tip="l2")
    assert named in str(info.value)
    assert "finite" not in str(info.value)


def test_huge_inertia_is_named(tmp_path):
    text = _arm().replace('ixx="0.01"', 'ixx="1e300"')
    with pytest.raises(GeometryError, match=r"link 'l1' <inertia>: 1e\+300 kg m\^2 is beyond"):
        description_from_urdf(_write(tmp_path, text), tip="l2")


def test_cli_huge_origin_exits_2_without_traceback(tmp_path):
    path = _write(tmp_path, _arm(xyz="1e300 0 0"))
    r = subprocess.run(
        [sys.executable, "-m", "deltagen", "fk", str(path), "0", "0", "--backend", "reference"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert "<origin xyz>" in r.stderr and "Traceback" not in r.stderr
    assert r.stderr.count(str(path)) == 1
