"""5-axis NC machine description: three linear axes X, Y, Z and two rotary axes, a tilt
axis (A about x, or B about y) and the rotary axis C about z, in one of the three classical
layouts (EASY-ROB paper: "5-axis NC machines with C and A axes"; LinuxCNC's trunnion and
head kinematics modules, docs/sources.md):

``table-table``  (trunnion) the tilt axis is the machine's, it carries the C table, which
                 carries the workpiece; the spindle only translates (LinuxCNC xyzac-trt,
                 xyzbc-trt)
``head-head``    the table is fixed; the spindle carrier turns about C, the head on it
                 tilts about A or B (LinuxCNC 5axiskins, a bridge mill)
``table-head``   the C table carries the workpiece, the head tilts about A or B
                 (LinuxCNC maxkins)

Frames and directions. The machine frame M is fixed to the bed; the workpiece frame W is
fixed to the workpiece and equals M when every rotary axis is at zero. The joints are
j = (x, y, z, tilt, c) [m, m, m, rad, rad] in that column order whatever the layout. A
rotary axis turns by the right-hand rule about +x (A), +y (B) or +z (C) *as the motion of
the tool relative to the workpiece* (ISO 841; LinuxCNC's ``conventional_directions = 1``):
a table axis therefore turns the table the other way. The tool axis direction d points
from the tool tip into the spindle; in W it is d = R_z(c) R_tilt(tilt) e_z in every layout.

The geometry (every point in metres):

``c_pivot``         a point of the C axis, machine frame, all axes at zero (table-table,
                    table-head)
``tilt_pivot``      a point of the tilt axis, machine frame, all axes at zero (table-table)
``head_pivot``      the tilt axis's point relative to the point the X, Y, Z joints move,
                    in the C-turned frame of the carrier (head-head) or the machine frame
                    (table-head); for table-table a constant shift of the tool
``spindle_offset``  the spindle's gauge point relative to the tilt pivot, in the tilted
                    head frame (head layouts; a constant shift for table-table)
``tool_length``     gauge point to tool tip along -d [m]
``tilt_limits``     the tilt axis's travel [rad] (``tilt_limits_deg`` in degrees in a file),
                    within [-pi, pi]; a branch of the inverse beyond it is not valid.
                    C turns without limit.

Tool tip in M:  m = (x, y, z) + R_hc (head_pivot + R_ht spindle_offset) - tool_length d_M
Tool tip in W:  w = c_pivot + R_tc (tilt_pivot - c_pivot + R_tt (m - tilt_pivot))
where R_hc, R_ht, R_tc, R_tt are R_z(c), R_tilt(tilt) or the identity as the layout puts
the axis in the head (h) or under the table (t). A key that cannot act in the layout
(``tilt_pivot`` of a head layout, ``c_pivot`` of head-head) must be left at zero.

Robot files are TOML::

    name = "xyzac_trt"              # optional, a C identifier
    doc = "where the numbers come from"
    [machine]
    layout = "table-table"           # table-table | head-head | table-head
    rotary = "AC"                    # AC | BC: the tilt axis and C
    tool_length = 0.1                # [m]
    c_pivot = [0.0, 0.0, 0.0]        # [m], optional (zero)
    tilt_pivot = [0.0, 0.02, 0.05]   # [m], optional (zero)
    head_pivot = [0.0, 0.0, 0.0]     # [m], optional (zero)
    spindle_offset = [0.0, 0.0, 0.0] # [m], optional (zero)
    tilt_limits_deg = [-120, 30]     # optional (default [-180, 180]); or tilt_limits [rad]
    singular_tol = 1e-9              # optional: |sin tilt| at or below it is SINGULAR
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from deltagen.errors import GeometryError
from deltagen.model.naming import check_identifier
from deltagen.model.parameters import RobotParameter
from deltagen.model.robot_file import RobotFile, degrees, family_table, real
from deltagen.status import SINGULAR_TOL

LAYOUTS = ("table-table", "head-head", "table-head")
ROTARIES = ("AC", "BC")
#: the point keys of [machine] and the layouts in which each acts
POINTS = {
    "c_pivot": ("table-table", "table-head"),
    "tilt_pivot": ("table-table",),
    "head_pivot": LAYOUTS,
    "spindle_offset": LAYOUTS,
}
_MACHINE_KEYS = {
    "layout",
    "rotary",
    "tool_length",
    "singular_tol",
    "tilt_limits",
    "tilt_limits_deg",
    *POINTS,
}
_TOP_KEYS = {"name", "doc", "machine"}
_ZERO = (0.0, 0.0, 0.0)


def _point(values: Any, key: str) -> tuple[float, float, float]:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or len(values) != 3:
        raise GeometryError(f"{key} must hold 3 numbers (x, y, z in metres), got {values!r}")
    a, b, c = (real(v, f"{key}[{i}]") for i, v in enumerate(values))
    return (a, b, c)


def config_name(layout: str, rotary: str) -> str:
    """The kernels' name of a layout and rotary pair: ``table_table_ac`` ... (C names)."""
    return f"{layout.replace('-', '_')}_{rotary.lower()}"


@dataclass(frozen=True)
class MachineDescription(RobotFile):
    layout: str
    rotary: str
    tool_length: float = 0.0
    c_pivot: tuple[float, float, float] = _ZERO
    tilt_pivot: tuple[float, float, float] = _ZERO
    head_pivot: tuple[float, float, float] = _ZERO
    spindle_offset: tuple[float, float, float] = _ZERO
    name: str = "machine"
    singular_tol: float = SINGULAR_TOL
    tilt_limits: tuple[float, float] = (-math.pi, math.pi)
    doc: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        check_identifier(self.name, "machine name")
        if self.layout not in LAYOUTS:
            raise GeometryError(f"layout must be one of {', '.join(LAYOUTS)}, got {self.layout!r}")
        rotary = self.rotary.upper() if isinstance(self.rotary, str) else self.rotary
        if rotary not in ROTARIES:
            raise GeometryError(
                f"rotary must be AC (tilt about x, then C) or BC (tilt about y, then C), "
                f"got {self.rotary!r}"
            )
        object.__setattr__(self, "rotary", rotary)
        object.__setattr__(self, "tool_length", real(self.tool_length, "tool_length"))
        for key, layouts in POINTS.items():
            point = _point(getattr(self, key), key)
            object.__setattr__(self, key, point)
            if self.layout not in layouts and any(point):
                raise GeometryError(
                    f"{key} has no effect in a {self.layout} machine (it acts in "
                    f"{', '.join(layouts)}); leave it out or zero"
                )
        limits = self.tilt_limits
        if isinstance(limits, (str, bytes)) or not hasattr(limits, "__len__") or len(limits) != 2:
            raise GeometryError(f"tilt_limits must hold 2 numbers (lower, upper), got {limits!r}")
        lo, hi = (real(v, f"tilt_limits[{i}]") for i, v in enumerate(limits))
        if not -math.pi <= lo < hi <= math.pi:
            raise GeometryError(
                f"tilt_limits must satisfy -pi <= lower < upper <= pi [rad], got ({lo!r}, {hi!r})"
            )
        object.__setattr__(self, "tilt_limits", (lo, hi))
        tol = real(self.singular_tol, "singular_tol")
        if not 0.0 < tol < 1.0:
            raise GeometryError(f"singular_tol must lie in (0, 1), got {tol!r}")
        object.__setattr__(self, "singular_tol", tol)
        if not isinstance(self.doc, str):
            raise GeometryError(f"doc must be text, got {self.doc!r}")

    @property
    def config(self) -> str:
        """``<layout>_<rotary>`` as the generated C names it, e.g. ``table_table_ac``."""
        return config_name(self.layout, self.rotary)

    @property
    def tilt_axis(self) -> str:
        """ "A" or "B"."""
        return self.rotary[0]

    @property
    def size(self) -> float:
        """The machine's length scale [m]: the largest offset or tool length, at least 1 mm
        (the round-trip tolerances of the tests are relative to it)."""
        values = [abs(self.tool_length)] + [abs(v) for k in POINTS for v in getattr(self, k)]
        return max(max(values), 1e-3)

    @classmethod
    def from_mapping(
        cls, data: dict[str, Any], source: str = "machine description"
    ) -> MachineDescription:
        required = ("layout", "rotary")
        machine = family_table(data, "machine", _TOP_KEYS, _MACHINE_KEYS, required, source)
        kwargs = dict(machine)
        if "tilt_limits" in kwargs and "tilt_limits_deg" in kwargs:
            raise GeometryError(f"{source}: give tilt_limits (rad) or tilt_limits_deg, not both")
        if "tilt_limits_deg" in kwargs:
            kwargs["tilt_limits"] = degrees(kwargs, "tilt_limits_deg", 2, source)
            del kwargs["tilt_limits_deg"]
        for key in ("name", "doc"):
            if key in data:
                kwargs[key] = data[key]
        try:
            return cls(**kwargs)
        except GeometryError as exc:
            raise GeometryError(f"{source}: {exc}") from None


#: The fields of the 5-axis core's parameter struct (deltagen_five_axis_geometry), in order
#: (model/parameters.py); a layout reads only the fields that act in it (POINTS).
FIVE_AXIS_PARAMETERS = (
    RobotParameter(
        "c_pivot", "m", "a point of the C axis, machine frame [m]", lambda d: d.c_pivot, count=3
    ),
    RobotParameter(
        "tilt_pivot",
        "m",
        "a point of the tilt axis (table-table) [m]",
        lambda d: d.tilt_pivot,
        count=3,
    ),
    RobotParameter(
        "head_pivot",
        "m",
        "tilt pivot from the XYZ reference point (head) [m]",
        lambda d: d.head_pivot,
        count=3,
    ),
    RobotParameter(
        "spindle_offset",
        "m",
        "spindle gauge point from the tilt pivot [m]",
        lambda d: d.spindle_offset,
        count=3,
    ),
    RobotParameter("tool_length", "m", "gauge point to tool tip [m]", lambda d: d.tool_length),
    RobotParameter(
        "singular_tol",
        "rad",
        "tool axis within it of the C axis: SINGULAR",
        lambda d: d.singular_tol,
    ),
    RobotParameter(
        "tilt_min", "rad", "the tilt axis's travel, lower end [rad]", lambda d: d.tilt_limits[0]
    ),
    RobotParameter(
        "tilt_max", "rad", "the tilt axis's travel, upper end [rad]", lambda d: d.tilt_limits[1]
    ),
)
