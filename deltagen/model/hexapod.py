"""The hexapod (Stewart-Gough platform): six legs of variable length, each between a base
joint a_i (base frame) and a platform joint b_i (platform frame), universal or spherical
joints at both ends.

A pose is the platform frame in the base frame, (R, p): a platform joint sits at
p + R b_i, and leg i has the length l_i = |p + R b_i - a_i| (the inverse kinematics of
LinuxCNC's genhexkins, which names the points the other way round). The joint-angle
limits are cones: the angle between the leg and the base joint's axis n_a,i (base frame;
the leg pointing away from the base) and between the leg and the platform joint's axis
n_b,i (platform frame; the leg pointing away from the platform, towards the base) must stay
at most ``base_cone`` and ``platform_cone`` [rad].

``HexapodGeometry.genhexkins()`` is LinuxCNC's default geometry
(src/emc/kinematics/genhexkins.h, DEFAULT_BASE_i_* and DEFAULT_PLATFORM_i_*, printed in
inches) converted to metres; the home pose, leg limits and cones are deltagen's choice
(genhexkins has none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from deltagen.errors import GeometryError
from deltagen.model.naming import check_identifier
from deltagen.model.parameters import RobotParameter
from deltagen.model.robot_file import RobotFile, family_table, real
from deltagen.status import SINGULAR_TOL

LEGS = 6

#: LinuxCNC genhexkins.h defaults [inch]: base joints (world frame) and platform joints
#: (platform frame), strut i = 0 .. 5
GENHEXKINS_BASE_INCH = (
    (-22.950, 13.250, 0.0),
    (22.950, 13.250, 0.0),
    (22.950, 13.250, 0.0),
    (0.000, -26.500, 0.0),
    (0.000, -26.500, 0.0),
    (-22.950, 13.250, 0.0),
)
GENHEXKINS_PLATFORM_INCH = (
    (-1.000, 11.500, 0.0),
    (1.000, 11.500, 0.0),
    (10.459, -4.884, 0.0),
    (9.459, -6.616, 0.0),
    (-9.459, -6.616, 0.0),
    (-10.459, -4.884, 0.0),
)
INCH = 0.0254

_HEXAPOD_KEYS = {
    "base_joints",
    "platform_joints",
    "leg_limits",
    "base_axes",
    "platform_axes",
    "base_cone_deg",
    "platform_cone_deg",
    "home_position",
    "home_rpy_deg",
    "singular_tol",
}
_TOP_KEYS = {"name", "kind", "hexapod"}


def _points(value: Any, where: str) -> tuple[tuple[float, ...], ...]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, list | tuple) or len(value) != LEGS:
        raise GeometryError(f"{where} must be {LEGS} points of 3 coordinates")
    rows = []
    for i, row in enumerate(value):
        if isinstance(row, np.ndarray):
            row = row.tolist()
        if not isinstance(row, list | tuple) or len(row) != 3:
            raise GeometryError(f"{where}[{i}] must be 3 coordinates [m], got {row!r}")
        rows.append(tuple(real(x, f"{where}[{i}]") for x in row))
    return tuple(rows)


def _vector(value: Any, n: int, where: str) -> tuple[float, ...]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, list | tuple) or len(value) != n:
        raise GeometryError(f"{where} must be {n} numbers, got {value!r}")
    return tuple(real(x, where) for x in value)


@dataclass(frozen=True)
class HexapodGeometry(RobotFile):
    """A hexapod as built; lengths in m, angles in rad.

    base_joints      6 points a_i in the base frame [m]
    platform_joints  6 points b_i in the platform frame [m]
    leg_limits       (l_min, l_max) [m]: the legs' length range (0, inf: none)
    base_axes        6 unit vectors n_a,i (base frame), the axes of the base joints' cones
                     (default +z: the legs leave the base upwards)
    platform_axes    6 unit vectors n_b,i (platform frame), the axes of the platform joints'
                     cones (default -z: the legs leave the platform downwards)
    base_cone        max angle between leg and n_a,i [rad] (pi: no limit)
    platform_cone    max angle between leg and n_b,i [rad] (pi: no limit)
    home_position    the platform origin at home [m] (fk's default start)
    home_rpy         roll, pitch, yaw at home [rad] (R = Rz(yaw) Ry(pitch) Rx(roll))
    singular_tol     relative threshold of the leg Jacobian's conditioning
    """

    base_joints: tuple
    platform_joints: tuple
    leg_limits: tuple = (0.0, math.inf)
    base_axes: tuple | None = None
    platform_axes: tuple | None = None
    base_cone: float = math.pi
    platform_cone: float = math.pi
    home_position: tuple = (0.0, 0.0, 0.0)
    home_rpy: tuple = (0.0, 0.0, 0.0)
    singular_tol: float = SINGULAR_TOL
    name: str = "hexapod"

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "name", check_identifier(self.name))
        set_(self, "base_joints", _points(self.base_joints, "base_joints"))
        set_(self, "platform_joints", _points(self.platform_joints, "platform_joints"))
        for field, default in (("base_axes", (0, 0, 1)), ("platform_axes", (0, 0, -1))):
            value = getattr(self, field)
            axes = _points([default] * LEGS if value is None else value, field)
            unit = []
            for i, n in enumerate(axes):
                norm = math.sqrt(sum(x * x for x in n))
                if not norm > 0:
                    raise GeometryError(f"{field}[{i}] must not be the zero vector")
                unit.append(tuple(x / norm for x in n))
            set_(self, field, tuple(unit))
        lo, hi = _leg_limits(self.leg_limits)
        set_(self, "leg_limits", (lo, hi))
        for field in ("base_cone", "platform_cone"):
            cone = real(getattr(self, field), field)
            if not 0 < cone <= math.pi:
                raise GeometryError(f"{field} must lie in (0, pi] rad, got {cone}")
            set_(self, field, cone)
        set_(self, "home_position", _vector(self.home_position, 3, "home_position"))
        set_(self, "home_rpy", _vector(self.home_rpy, 3, "home_rpy"))
        tol = real(self.singular_tol, "singular_tol")
        if not 0 < tol < 1:
            raise GeometryError(f"singular_tol must lie in (0, 1), got {tol}")
        set_(self, "singular_tol", tol)
        a, b = np.array(self.base_joints), np.array(self.platform_joints)
        for name, pts in (("base_joints", a), ("platform_joints", b)):
            centred = pts - pts.mean(axis=0)
            if np.linalg.matrix_rank(centred, tol=1e-9 * max(1.0, np.abs(pts).max())) < 2:
                raise GeometryError(f"{name} are collinear: the platform cannot be held")

    @property
    def size(self) -> float:
        """A length scale of the robot [m]: the largest joint radius, base or platform."""
        a, b = np.array(self.base_joints), np.array(self.platform_joints)
        return float(max(np.linalg.norm(a, axis=1).max(), np.linalg.norm(b, axis=1).max()))

    @classmethod
    def genhexkins(cls) -> HexapodGeometry:
        """LinuxCNC genhexkins.h's default joints [inch -> m], home 20 in above the base."""
        return cls(
            base_joints=tuple(tuple(x * INCH for x in p) for p in GENHEXKINS_BASE_INCH),
            platform_joints=tuple(tuple(x * INCH for x in p) for p in GENHEXKINS_PLATFORM_INCH),
            leg_limits=(0.60, 0.95),
            base_cone=math.radians(75.0),
            platform_cone=math.radians(75.0),
            home_position=(0.0, 0.0, 20 * INCH),
            name="genhex",
        )

    @classmethod
    def default(cls) -> HexapodGeometry:
        """The family's default robot (api.base.RobotFamilyWithDefault): genhexkins'."""
        return cls.genhexkins()

    @classmethod
    def from_mapping(cls, data: Any, source: str = "robot description") -> HexapodGeometry:
        required = ("base_joints", "platform_joints")
        table = family_table(data, "hexapod", _TOP_KEYS, _HEXAPOD_KEYS, required, source)
        kwargs: dict[str, Any] = {
            k: v for k, v in table.items() if not k.endswith("_deg") and k != "leg_limits"
        }
        try:
            if "leg_limits" in table:
                kwargs["leg_limits"] = tuple(_vector(table["leg_limits"], 2, "leg_limits"))
            for key in ("base_cone_deg", "platform_cone_deg"):
                if key in table:
                    kwargs[key[: -len("_deg")]] = math.radians(real(table[key], key))
            if "home_rpy_deg" in table:
                deg = _vector(table["home_rpy_deg"], 3, "home_rpy_deg")
                kwargs["home_rpy"] = tuple(math.radians(x) for x in deg)
            if "name" in data:
                kwargs["name"] = data["name"]
            return cls(**kwargs)
        except GeometryError as exc:
            raise GeometryError(f"{source}: {exc}") from None


def _leg_limits(value: Any) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise GeometryError(f"leg_limits must be (l_min, l_max) [m], got {value!r}")
    lo = real(value[0], "leg_limits[0]")
    hi = float(value[1]) if value[1] == math.inf else real(value[1], "leg_limits[1]")
    if not 0 <= lo < hi:
        raise GeometryError(f"leg_limits must satisfy 0 <= l_min < l_max, got {value!r}")
    return lo, hi


def _flat(points: Any) -> list:
    """6 points of 3 as the struct's 18 values, point after point."""
    return [x for point in points for x in point]


#: The fields of the hexapod core's parameter struct (deltagen_hexapod_geometry), in order
#: (model/parameters.py); the per-leg arrays hold the six legs' points one after another.
HEXAPOD_PARAMETERS = (
    RobotParameter(
        "base_joints",
        "m",
        "base joints a_i, 6 x 3, base frame [m]",
        lambda g: _flat(g.base_joints),
        count=3 * LEGS,
        per_chain=True,
    ),
    RobotParameter(
        "platform_joints",
        "m",
        "platform joints b_i, 6 x 3, platform frame [m]",
        lambda g: _flat(g.platform_joints),
        count=3 * LEGS,
        per_chain=True,
    ),
    RobotParameter(
        "base_axes",
        "1",
        "base joint axes n_a,i, 6 x 3 unit vectors",
        lambda g: _flat(g.base_axes),
        count=3 * LEGS,
        per_chain=True,
    ),
    RobotParameter(
        "platform_axes",
        "1",
        "platform joint axes n_b,i, 6 x 3 unit vectors, platform frame",
        lambda g: _flat(g.platform_axes),
        count=3 * LEGS,
        per_chain=True,
    ),
    RobotParameter("scale", "m", "size of the robot [m] (largest joint radius)", lambda g: g.size),
    RobotParameter(
        "singular_tol", "1", "relative singularity threshold, e.g. 1e-9", lambda g: g.singular_tol
    ),
)
