"""Robot descriptions: DeltaGeometry validation and TOML robot files. Every impossible
or malformed description is a GeometryError (a ValueError) that names the problem."""

from __future__ import annotations

import math

import pytest

import deltagen
from deltagen import DeltaRobot, GeometryError
from deltagen.model.delta import DeltaGeometry

GOOD = dict(r_a=0.2, r_b=0.045, l_a=0.35, l_b=0.8, theta=(0.0, 2 * math.pi / 3, 4 * math.pi / 3))

GOOD_TOML = """\
name = "my_delta"

[delta]
r_a = 0.2
r_b = 0.045
l_a = 0.35
l_b = 0.8
theta_deg = [0, 120, 240]
"""


def _with(**changes):
    return {**GOOD, **changes}


# ------------------------------------------------------------------------ geometry


def test_good_geometry_and_derived_lengths():
    g = DeltaGeometry(**GOOD)
    assert g.r == pytest.approx(0.155, abs=1e-15)
    assert g.size == pytest.approx(0.35 + 0.8 + 0.2, abs=1e-15)
    assert g.name == "delta" and g.singular_tol == 1e-9
    assert DeltaGeometry(**_with(r_b=0.0)).r_b == 0.0  # a point platform is allowed
    ints = DeltaGeometry(r_a=1, r_b=0, l_a=2, l_b=3, theta=[0, 2, 4])
    assert isinstance(ints.r_a, float) and ints.theta == (0.0, 2.0, 4.0)


@pytest.mark.parametrize(
    "key,value,words",
    [
        ("r_a", 0.0, ["r_a", "positive"]),
        ("r_a", -0.2, ["r_a", "positive"]),
        ("l_a", 0.0, ["l_a", "positive"]),
        ("l_a", -0.35, ["l_a", "positive"]),
        ("l_b", 0.0, ["l_b", "positive"]),
        ("l_b", -1e-3, ["l_b", "positive"]),
        ("r_b", -0.01, ["r_b", "non-negative"]),
        ("l_b", math.nan, ["l_b", "finite"]),
        ("r_a", math.inf, ["r_a", "finite"]),
        ("l_a", "0.35", ["l_a", "real number"]),
        ("l_a", True, ["l_a", "real number"]),
        ("r_b", None, ["r_b", "real number"]),
        ("l_b", 1j, ["l_b", "real number"]),
    ],
)
def test_impossible_lengths(key, value, words):
    with pytest.raises(GeometryError) as info:
        DeltaGeometry(**_with(**{key: value}))
    assert isinstance(info.value, ValueError)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize(
    "theta",
    [
        (0.0, 0.0, 2.0),
        (0.0, 2.0, 2.0),
        (1.0, 2.0, 1.0),
        (0.0, 2 * math.pi, 2.0),  # the same direction, one turn apart
        (0.0, 1.0, -2 * math.pi + 1e-9),  # equal to theta[0] up to 1e-9 rad
    ],
)
def test_coinciding_drive_angles(theta):
    with pytest.raises(GeometryError, match="coincide"):
        DeltaGeometry(**_with(theta=theta))


@pytest.mark.parametrize(
    "theta",
    [(0.0, 1.0), (0.0, 1.0, 2.0, 3.0), 1.0, "abc", None, (0.0, "x", 2.0), (0.0, math.nan, 2.0)],
)
def test_bad_theta(theta):
    with pytest.raises(GeometryError, match="theta"):
        DeltaGeometry(**_with(theta=theta))


def test_rods_too_short():
    """|r_a - r_b| > l_a + l_b: no chain closes anywhere."""
    with pytest.raises(GeometryError, match="rods too short"):
        DeltaGeometry(**_with(r_a=2.0, r_b=0.0, l_a=0.3, l_b=0.5))
    with pytest.raises(GeometryError, match="rods too short"):
        DeltaGeometry(**_with(r_a=0.1, r_b=1.0, l_a=0.3, l_b=0.5))
    DeltaGeometry(**_with(r_a=0.8, r_b=0.0, l_a=0.3, l_b=0.5))  # just closes: allowed


@pytest.mark.parametrize(
    "name", ["my robot", "1delta", "delta-2", "", "a/b", "x" * 65, "delta.toml", "naïve", 3, None]
)
def test_invalid_names(name):
    with pytest.raises(GeometryError, match="invalid robot name"):
        DeltaGeometry(**GOOD, name=name)


@pytest.mark.parametrize("name", ["d", "_x", "Delta_2", "x" * 64])
def test_valid_names(name):
    assert DeltaGeometry(**GOOD, name=name).name == name


@pytest.mark.parametrize("tol", [-1e-9, 1.0, 2.0, math.nan, "small"])
def test_bad_singular_tol(tol):
    with pytest.raises(GeometryError, match="singular_tol"):
        DeltaGeometry(**GOOD, singular_tol=tol)


def test_geometry_errors_are_exported():
    assert deltagen.GeometryError is GeometryError
    assert issubclass(GeometryError, ValueError)


# ------------------------------------------------------------------------ TOML files


def _write(tmp_path, text, name="robot.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_toml_theta_deg_and_theta_rad(tmp_path):
    g = DeltaGeometry.from_toml(_write(tmp_path, GOOD_TOML))
    assert (g.r_a, g.r_b, g.l_a, g.l_b, g.name) == (0.2, 0.045, 0.35, 0.8, "my_delta")
    for got, deg in zip(g.theta, (0, 120, 240)):
        assert got == pytest.approx(math.radians(deg), abs=1e-15)
    rad = GOOD_TOML.replace(
        "theta_deg = [0, 120, 240]", "theta = [0.5, 2.5, 4.5]\nsingular_tol = 1e-6"
    )
    g = DeltaGeometry.from_toml(_write(tmp_path, rad))
    assert g.theta == (0.5, 2.5, 4.5) and g.singular_tol == 1e-6
    no_name = GOOD_TOML.replace('name = "my_delta"\n', "")
    assert DeltaGeometry.from_toml(_write(tmp_path, no_name)).name == "delta"
    robot = DeltaRobot.from_toml(_write(tmp_path, GOOD_TOML), backend="reference")
    assert robot.geometry == DeltaGeometry.from_toml(_write(tmp_path, GOOD_TOML))


def test_bundled_robot_file_is_the_default(repo_root):
    g = DeltaGeometry.from_toml(repo_root / "robots" / "default_delta.toml")
    d = DeltaGeometry.default()
    assert (g.r_a, g.r_b, g.l_a, g.l_b, g.name) == (d.r_a, d.r_b, d.l_a, d.l_b, d.name)
    assert g.theta == pytest.approx(d.theta, abs=1e-15)


BROKEN = {
    "missing r_a": (lambda t: t.replace("r_a = 0.2\n", ""), ["r_a", "missing"]),
    "missing l_b": (lambda t: t.replace("l_b = 0.8\n", ""), ["l_b", "missing"]),
    "missing theta": (lambda t: t.replace("theta_deg = [0, 120, 240]\n", ""), ["theta", "missing"]),
    "missing [delta]": (lambda t: t.split("[delta]")[0], ["[delta]", "missing"]),
    "unknown key": (lambda t: t + "l_c = 0.3\n", ["l_c", "unknown"]),
    "misspelt key": (lambda t: t.replace("r_b =", "rb ="), ["rb", "unknown"]),
    "unknown top-level key": (lambda t: 'robot = "x"\n' + t, ["robot", "unknown"]),
    "unknown table": (lambda t: t + "[serial]\na = 1\n", ["serial", "unknown"]),
    "string length": (lambda t: t.replace("l_a = 0.35", 'l_a = "0.35"'), ["l_a", "real number"]),
    "bool length": (lambda t: t.replace("l_a = 0.35", "l_a = true"), ["l_a", "real number"]),
    "table length": (lambda t: t.replace("l_a = 0.35", "l_a = {value = 0.35}"), ["l_a"]),
    "nan length": (lambda t: t.replace("l_b = 0.8", "l_b = nan"), ["l_b", "finite"]),
    "negative length": (lambda t: t.replace("l_b = 0.8", "l_b = -0.8"), ["l_b", "positive"]),
    "theta_deg string": (lambda t: t.replace("[0, 120, 240]", '"0, 120, 240"'), ["theta_deg"]),
    "theta_deg two": (lambda t: t.replace("[0, 120, 240]", "[0, 120]"), ["theta_deg", "3"]),
    "theta_deg words": (lambda t: t.replace("[0, 120, 240]", '[0, "a", 240]'), ["theta_deg[1]"]),
    "theta_deg same": (lambda t: t.replace("[0, 120, 240]", "[0, 120, 360]"), ["coincide"]),
    "theta and theta_deg": (
        lambda t: t + "theta = [0.0, 2.0, 4.0]\n",
        ["theta", "theta_deg", "not both"],
    ),
    "theta rad bad": (
        lambda t: t.replace("theta_deg = [0, 120, 240]", "theta = [0, 1]"),
        ["theta"],
    ),
    "invalid name": (lambda t: t.replace('"my_delta"', '"my robot"'), ["my robot", "invalid"]),
    "name not string": (lambda t: t.replace('"my_delta"', "42"), ["42", "invalid"]),
    "delta not table": (lambda t: t.split("[delta]")[0] + "delta = 3\n", ["[delta]", "table"]),
    "syntax error": (lambda t: t.replace("r_a = 0.2", "r_a = "), ["malformed TOML"]),
    "unclosed array": (lambda t: t.replace("[0, 120, 240]", "[0, 120, 240"), ["malformed TOML"]),
    "duplicate key": (lambda t: t + "r_a = 0.3\n", ["malformed TOML"]),
    "rods too short": (lambda t: t.replace("r_a = 0.2", "r_a = 5.0"), ["rods too short"]),
    "bad singular_tol": (lambda t: t + "singular_tol = 2.0\n", ["singular_tol"]),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_broken_robot_files(tmp_path, case):
    edit, words = BROKEN[case]
    path = _write(tmp_path, edit(GOOD_TOML))
    with pytest.raises(GeometryError) as info:
        DeltaGeometry.from_toml(path)
    message = str(info.value)
    assert isinstance(info.value, ValueError)
    assert str(path) in message, message  # the message says which file
    for word in words:
        assert word in message, message
    with pytest.raises(GeometryError):
        DeltaRobot.from_toml(path)


def test_unreadable_robot_files(tmp_path):
    with pytest.raises(GeometryError, match="cannot read robot file"):
        DeltaGeometry.from_toml(tmp_path / "missing.toml")
    with pytest.raises(GeometryError, match="robot file .*: is a directory, not a file"):
        DeltaGeometry.from_toml(tmp_path)  # a directory
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe[delta]\n")
    with pytest.raises(GeometryError, match="UTF-8"):
        DeltaGeometry.from_toml(binary)
    empty = _write(tmp_path, "", "empty.toml")
    with pytest.raises(GeometryError, match=r"missing \[delta\]"):
        DeltaGeometry.from_toml(empty)


def test_from_mapping_rejects_non_tables():
    with pytest.raises(GeometryError, match="expected a table"):
        DeltaGeometry.from_mapping([1, 2, 3])
