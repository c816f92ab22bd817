"""The linear delta and the tripod, validated: the geometry of the two machines whose
direct kinematics is a three-sphere intersection like the rotary delta's.

Linear delta (a delta 3D printer; Klipper's ``delta`` kinematics): three vertical towers
stand at (radius_i cos angle_i, radius_i sin angle_i); tower i's carriage rides at height
h_i and an arm (rod pair) of length arm_i joins it to the effector point p (the effector's
own offset folded into the radius, as Klipper does). Robot files are TOML::

    name = "kossel"                 # optional, a C identifier
    [linear_delta]
    radius = 0.1                    # tower radius [m]; or a list of 3 (per tower)
    angle_deg = [210, 330, 90]      # tower angles [deg] (Klipper's default), or angle [rad]
    arm_length = 0.25               # [m]; or a list of 3 (per tower)
    carriage_range = [0.0, 0.5]     # travel of the carriages h [m] (workspace, optional)
    singular_tol = 1e-9             # optional

Tripod (LinuxCNC's ``tripodkins``): base points A = (0, 0, 0), B = (b_x, 0, 0),
C = (c_x, c_y, 0); struts of variable length from A, B, C to the controlled point D. The
direct kinematics has two mirror solutions about the base plane; ``side`` picks one
("above": z > 0, tripodkins' forward flag 0; "below": z < 0, flag 1). TOML::

    name = "tripod"
    [tripod]
    b_x = 1.0                       # [m]
    c_x = 0.5
    c_y = 0.8
    side = "above"                  # or "below"
    strut_range = [0.2, 2.0]        # strut travel [m] (workspace, optional)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from deltagen.errors import GeometryError
from deltagen.model.naming import check_identifier
from deltagen.model.parameters import RobotParameter
from deltagen.model.robot_file import RobotFile, family_table, real
from deltagen.status import SINGULAR_TOL

#: Klipper's default tower angles of stepper_a, _b, _c [deg] (klippy/kinematics/delta.py).
KLIPPER_TOWER_ANGLES = (210.0, 330.0, 90.0)


def _triple(value: Any, key: str) -> tuple[float, float, float]:
    """Three numbers, or one number repeated thrice."""
    if isinstance(value, (list, tuple)):
        if len(value) != 3:
            raise GeometryError(
                f"{key} must be a number or 3 numbers (one per tower), got {value!r}"
            )
        a, b, c = (real(v, f"{key}[{i}]") for i, v in enumerate(value))
        return (a, b, c)
    v = real(value, key)
    return (v, v, v)


def _range(value: Any, key: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise GeometryError(f"{key} must be [low, high], got {value!r}")
    lo, hi = (real(v, f"{key}[{i}]") for i, v in enumerate(value))
    if not lo < hi:
        raise GeometryError(f"{key} must be [low, high] with low < high, got {value!r}")
    return (lo, hi)


def _check_tol(tol: float) -> None:
    if not (math.isfinite(tol) and 0.0 <= tol < 1.0):
        raise GeometryError(f"singular_tol must be in [0, 1), got {tol!r}")


@dataclass(frozen=True)
class LinearDeltaGeometry(RobotFile):
    """A linear delta (module docstring): per-tower radius [m], angle [rad] and arm length
    [m], the carriage travel [m] and the relative singularity threshold."""

    radius: tuple[float, float, float]
    angle: tuple[float, float, float]
    arm_length: tuple[float, float, float]
    carriage_range: tuple[float, float] = (0.0, 1.0)
    singular_tol: float = SINGULAR_TOL
    name: str = "linear_delta"

    def __post_init__(self) -> None:
        for key in ("radius", "angle", "arm_length"):
            object.__setattr__(self, key, _triple(getattr(self, key), key))
        object.__setattr__(self, "carriage_range", _range(self.carriage_range, "carriage_range"))
        object.__setattr__(self, "singular_tol", real(self.singular_tol, "singular_tol"))
        check_identifier(self.name, "name")
        if any(r < 0 for r in self.radius):
            raise GeometryError(f"tower radii must be >= 0 [m], got {self.radius!r}")
        if any(a <= 0 for a in self.arm_length):
            raise GeometryError(f"arm lengths must be positive [m], got {self.arm_length!r}")
        _check_tol(self.singular_tol)
        (x1, x2, x3), (y1, y2, y3) = self.tower_x, self.tower_y
        area2 = (x2 - x1) * (y3 - y1) - (y2 - y1) * (x3 - x1)
        size = max(max(self.radius), 1e-300)
        if abs(area2) <= 1e-9 * size**2:
            raise GeometryError(
                "the three towers stand in one line (or two coincide): the carriages' spheres "
                "would meet in a circle, not a point"
            )

    @property
    def tower_x(self) -> tuple[float, float, float]:
        return tuple(r * math.cos(a) for r, a in zip(self.radius, self.angle))  # type: ignore[return-value]

    @property
    def tower_y(self) -> tuple[float, float, float]:
        return tuple(r * math.sin(a) for r, a in zip(self.radius, self.angle))  # type: ignore[return-value]

    @classmethod
    def default(cls) -> LinearDeltaGeometry:
        """A Kossel-sized printer: towers at radius 0.1 m at Klipper's 210/330/90 deg, arms
        0.25 m, carriages travelling 0 .. 0.5 m."""
        return cls(
            radius=(0.1,) * 3,
            angle=tuple(math.radians(a) for a in KLIPPER_TOWER_ANGLES),  # type: ignore[arg-type]
            arm_length=(0.25,) * 3,
            carriage_range=(0.0, 0.5),
        )

    @classmethod
    def from_mapping(cls, data: dict, source: str = "robot file") -> LinearDeltaGeometry:
        keys = {"radius", "angle", "angle_deg", "arm_length", "carriage_range", "singular_tol"}
        required = ("radius", "arm_length")
        table = family_table(data, "linear_delta", {"name", "linear_delta"}, keys, required, source)
        if "angle" in table and "angle_deg" in table:
            raise GeometryError(f"{source} [linear_delta]: give angle or angle_deg, not both")
        if "angle" in table:
            angle = _triple(table["angle"], "angle")
        else:
            deg = _triple(table.get("angle_deg", list(KLIPPER_TOWER_ANGLES)), "angle_deg")
            angle = tuple(math.radians(a) for a in deg)  # type: ignore[assignment]
        return cls(
            radius=table["radius"],
            angle=angle,
            arm_length=table["arm_length"],
            carriage_range=tuple(table.get("carriage_range", (0.0, 1.0))),
            singular_tol=table.get("singular_tol", SINGULAR_TOL),
            name=data.get("name", "linear_delta"),
        )


_SIDES = {"above": 1.0, "below": -1.0}


@dataclass(frozen=True)
class TripodGeometry(RobotFile):
    """LinuxCNC tripodkins' tripod (module docstring): B = (b_x, 0, 0), C = (c_x, c_y, 0)
    [m], the side of the base plane ("above" or "below"), the strut travel [m] and the
    relative singularity threshold."""

    b_x: float
    c_x: float
    c_y: float
    side: str = "above"
    strut_range: tuple[float, float] = (0.0, 2.0)
    singular_tol: float = SINGULAR_TOL
    name: str = "tripod"

    def __post_init__(self) -> None:
        for key in ("b_x", "c_x", "c_y", "singular_tol"):
            object.__setattr__(self, key, real(getattr(self, key), key))
        object.__setattr__(self, "strut_range", _range(self.strut_range, "strut_range"))
        check_identifier(self.name, "name")
        if self.side not in _SIDES:
            raise GeometryError(f"side must be 'above' or 'below', got {self.side!r}")
        _check_tol(self.singular_tol)
        if self.b_x == 0.0:
            raise GeometryError("b_x must not be 0: base points A and B would coincide")
        if self.c_y == 0.0:
            raise GeometryError("c_y must not be 0: base points A, B, C would be collinear")

    @property
    def side_sign(self) -> float:
        """+1 above the base plane, -1 below."""
        return _SIDES[self.side]

    @property
    def base_points(self) -> tuple[tuple[float, float, float], ...]:
        return ((0.0, 0.0, 0.0), (self.b_x, 0.0, 0.0), (self.c_x, self.c_y, 0.0))

    @classmethod
    def default(cls) -> TripodGeometry:
        """B = (1, 0, 0), C = (0.5, 0.8, 0) m, the point above the base plane."""
        return cls(b_x=1.0, c_x=0.5, c_y=0.8, side="above", strut_range=(0.2, 2.0))

    @classmethod
    def from_mapping(cls, data: dict, source: str = "robot file") -> TripodGeometry:
        keys = {"b_x", "c_x", "c_y", "side", "strut_range", "singular_tol"}
        required = ("b_x", "c_x", "c_y")
        table = family_table(data, "tripod", {"name", "tripod"}, keys, required, source)
        return cls(
            b_x=table["b_x"],
            c_x=table["c_x"],
            c_y=table["c_y"],
            side=table.get("side", "above"),
            strut_range=tuple(table.get("strut_range", (0.0, 2.0))),
            singular_tol=table.get("singular_tol", SINGULAR_TOL),
            name=data.get("name", "tripod"),
        )


_TOL_DOC = "relative singularity threshold, e.g. 1e-9"

#: The fields of the linear delta core's parameter struct (deltagen_linear_delta_geometry),
#: in order (model/parameters.py).
LINEAR_DELTA_PARAMETERS = (
    RobotParameter(
        "tower_x",
        "m",
        "x of each tower (radius cos angle) [m]",
        lambda g: g.tower_x,
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "tower_y",
        "m",
        "y of each tower (radius sin angle) [m]",
        lambda g: g.tower_y,
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "arm_length",
        "m",
        "arm (rod) length of each tower [m]",
        lambda g: g.arm_length,
        count=3,
        per_chain=True,
    ),
    RobotParameter("singular_tol", "1", _TOL_DOC, lambda g: g.singular_tol),
)

#: The fields of the tripod core's parameter struct (deltagen_tripod_geometry), in order
#: (model/parameters.py): LinuxCNC tripodkins' Bx, Cx, Cy and the side of the base plane.
TRIPOD_PARAMETERS = (
    RobotParameter("b_x", "m", "x of base point B [m]", lambda g: g.b_x),
    RobotParameter("c_x", "m", "x of base point C [m]", lambda g: g.c_x),
    RobotParameter("c_y", "m", "y of base point C [m]", lambda g: g.c_y),
    RobotParameter(
        "side",
        "1",
        "+1: the solution above the base plane (z > 0), -1: below",
        lambda g: g.side_sign,
    ),
    RobotParameter("singular_tol", "1", _TOL_DOC, lambda g: g.singular_tol),
)
