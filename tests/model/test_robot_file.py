"""The checks every robot file shares (deltagen/model/robot_file.py): family_table, the one
check of a family's table that the rotary delta, the hexapod, the 5-axis machine, the linear
delta and the tripod all read their files through, and degrees, the one reading of an angle
list given in degrees. Evidence: each bundled file reads, and the same broken file gives each
family the same GeometryError naming the file, the table and the key."""

from __future__ import annotations

import copy
import math

import pytest

from deltagen.errors import GeometryError
from deltagen.model.delta import DeltaGeometry
from deltagen.model.five_axis import MachineDescription
from deltagen.model.hexapod import HexapodGeometry
from deltagen.model.linear_delta import LinearDeltaGeometry, TripodGeometry
from deltagen.model.robot_file import RobotFile, degrees, family_table, number_text, read_toml
from deltagen.model.serial import SerialDescription
from deltagen.paths import robots_dir

# family -> (its bundled file, its table, a key the table must hold)
FAMILIES = {
    DeltaGeometry: ("default_delta.toml", "delta", "l_b"),
    HexapodGeometry: ("hexapod_genhex.toml", "hexapod", "base_joints"),
    MachineDescription: ("xyzac_trt.toml", "machine", "rotary"),
    LinearDeltaGeometry: ("linear_delta.toml", "linear_delta", "arm_length"),
    TripodGeometry: ("tripod.toml", "tripod", "c_y"),
}


def _data(family):
    return read_toml(robots_dir() / FAMILIES[family][0])


@pytest.mark.parametrize("family", list(FAMILIES), ids=lambda f: f.__name__)
def test_each_family_reads_its_bundled_file(family):
    assert isinstance(family.from_mapping(_data(family), "f.toml"), family)


@pytest.mark.parametrize("family", list(FAMILIES), ids=lambda f: f.__name__)
def test_each_family_names_the_same_faults_the_same_way(family):
    _, section, key = FAMILIES[family]
    good = _data(family)
    broken = []
    d = copy.deepcopy(good)
    d["robot"] = 1
    broken.append((d, "f.toml: unknown top-level keys ['robot']"))
    d = copy.deepcopy(good)
    del d[section]
    broken.append((d, f"f.toml: missing [{section}] table"))
    d = copy.deepcopy(good)
    d[section] = [1, 2]
    broken.append((d, f"f.toml: [{section}] must be a table"))
    d = copy.deepcopy(good)
    d[section]["colour"] = "red"
    broken.append((d, f"f.toml: unknown keys in [{section}]: ['colour']"))
    d = copy.deepcopy(good)
    del d[section][key]
    broken.append((d, f"f.toml: missing keys in [{section}]: ['{key}']"))
    broken.append(([1], "f.toml: expected a table, got list"))
    for data, message in broken:
        with pytest.raises(GeometryError) as info:
            family.from_mapping(data, "f.toml")
        assert str(info.value) == message


def test_family_table_returns_the_section():
    data = {"name": "x", "t": {"a": 1.0}}
    assert family_table(data, "t", {"name", "t"}, {"a", "b"}, ("a",), "s") is data["t"]


def test_degrees_in_radians_and_its_faults():
    assert degrees({"k": [90, -180.0]}, "k", 2, "s") == (math.pi / 2, -math.pi)
    for raw, text in (
        ([1, 2, 3], "s: k must be a list of 2 numbers"),
        ("90", "s: k must be a list of 2 numbers"),
        ([1, True], "s: k[1] must be a real number, got True"),
        ([1, float("nan")], "s: k[1] must be finite, got nan"),
    ):
        with pytest.raises(GeometryError) as info:
            degrees({"k": raw}, "k", 2, "s")
        assert str(info.value) == text


def test_the_angle_lists_in_degrees_of_two_families():
    """The delta's q_offset_deg and the 5-axis machine's tilt_limits_deg, both read by
    degrees: the same numbers as the radian keys they stand for."""
    delta = _data(DeltaGeometry)
    delta["delta"]["q_offset_deg"] = [1.0, -2.0, 30.0]
    got = DeltaGeometry.from_mapping(delta).q_offset
    assert got == pytest.approx([math.radians(v) for v in (1.0, -2.0, 30.0)], abs=0, rel=1e-15)
    machine = _data(MachineDescription)
    tilt = MachineDescription.from_mapping(machine).tilt_limits
    assert tilt == pytest.approx((math.radians(-120), math.radians(120)), abs=0, rel=1e-15)
    machine["machine"]["tilt_limits_deg"] = [-120, 120, 5]
    with pytest.raises(GeometryError, match="tilt_limits_deg must be a list of 2 numbers"):
        MachineDescription.from_mapping(machine)


@pytest.mark.parametrize("family", [*FAMILIES, SerialDescription], ids=lambda f: f.__name__)
def test_each_family_reads_a_file_through_robot_file(family, tmp_path):
    """from_toml is RobotFile's for every family: the file's mapping through the family's
    own from_mapping, its errors naming the file's path."""
    assert family.from_toml.__func__ is RobotFile.from_toml.__func__
    name = FAMILIES[family][0] if family in FAMILIES else "puma560.toml"
    path = robots_dir() / name
    assert repr(family.from_toml(path)) == repr(family.from_mapping(read_toml(path), str(path)))
    broken = tmp_path / "broken.toml"
    broken.write_text('colour = "red"\n')
    with pytest.raises(GeometryError, match=f"^{broken}: unknown top-level keys"):
        family.from_toml(broken)


def test_number_text_of_the_urdf_and_klipper_readers(tmp_path):
    """number_text is the one reading of a number spelled in a file: a URDF attribute (with
    the attribute's whole text named) and a Klipper option give the same words."""
    import configparser

    from deltagen.model.klipper import _number
    from deltagen.model.urdf import _numbers

    assert number_text(" -1.5e-3", "w") == -1.5e-3
    with pytest.raises(GeometryError, match=r"^w: 'abc' is not a number \(in 'x'\)$"):
        number_text("abc", "w", " (in 'x')")
    with pytest.raises(GeometryError, match=r"^w: 'inf' is not finite$"):
        number_text("inf", "w")
    assert _numbers("1 2.5 -3", 3, "origin") == [1.0, 2.5, -3.0]
    with pytest.raises(GeometryError, match=r"^origin: 'two' is not a number \(in '1 two 3'\)$"):
        _numbers("1 two 3", 3, "origin")
    with pytest.raises(GeometryError, match=r"^origin: 'nan' is not finite$"):
        _numbers("1 nan 3", 3, "origin")
    config = configparser.ConfigParser()
    config.read_string("[printer]\ndelta_radius: wide\narm_length: 0.25\n")
    assert _number(config, "printer", "arm_length", "p.cfg") == 0.25
    with pytest.raises(GeometryError, match=r"^p.cfg: \[printer\] delta_radius: 'wide' is not a"):
        _number(config, "printer", "delta_radius", "p.cfg")
