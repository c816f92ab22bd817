"""Delta robot description: the geometry of the report's Figure 4, validated.

r_a  base radius, origin O to a drive axis            [m]
r_b  platform radius, centre P to a joint C_i          [m]
l_a  crank length, A_i to B_i                          [m]
l_b  parallelogram rod length, B_i to C_i              [m]
theta_i  angular position of drive i about base z      [rad]

Every length lies in [MIN_LENGTH, MAX_LENGTH] = [1e-6 m, 1e3 m] (r_b may also be 0): the range
float64 evaluates reliably, with a wide margin (see MAX_LENGTH); outside it the geometry is
refused with a GeometryError naming the field.

Robot files are TOML::

    name = "my_delta"          # optional, a C identifier
    [delta]
    r_a = 0.2
    r_b = 0.045
    l_a = 0.35
    l_b = 0.8
    theta_deg = [0, 120, 240]  # or theta = [...] in radians, not both
    [inertia]                  # optional; needed only for the dynamics
    I_a = 0.037                # crank inertia about its drive axis, rotor + gearbox reflected [kg m^2]
    m_a = 0.6                  # crank mass [kg]
    r_ca = 0.15                # crank centre of mass from A_i along the crank [m]
    m_b = 0.2                  # mass of one rod pair (both rods of a parallelogram) [kg]
    m_p = 0.5                  # platform mass, without payload [kg]
    gravity = [0, 0, -9.81]    # in the base frame O, z up [m/s^2]
    I_4 = 0.0                  # fourth-axis inertia about its own axis [kg m^2]

Asymmetric robots (a robot as built, e.g. after calibration): every chain i may have its
own r_a_i, r_b_i, l_a_i, l_b_i (``chain_r_a`` ... ``chain_l_b``, 3 values each; None: the
symmetric value) and an encoder offset q_offset_i [rad]: the geometric crank angle is
q_i + q_offset_i for the reading q_i every API call takes and returns (the measured
angle). The scalar r_a, r_b, l_a, l_b stay the nominal values: they scale the singularity
thresholds and give the dynamics, which are derived for the symmetric robot only. In a
robot file (optional keys of [delta])::

    chain_l_a = [0.35, 0.351, 0.3495]   # likewise chain_r_a, chain_r_b, chain_l_b [m]
    q_offset = [0.0, 0.001, -0.002]     # or q_offset_deg [deg]

Dynamics (``DeltaInertia``): each crank turns about its fixed drive axis (inertia I_a,
mass m_a at r_ca along the crank for gravity). Each parallelogram is two slender rods of
length l_b moving in parallel (the report, Figure 4, lumps them into one rod): their pair
has mass m_b, its centre of mass midway between B_i and C_i, and the inertia
m_b l_b^2 / 12 about every axis perpendicular to the rods (none about the rod axis). The
platform translates only (the parallelograms keep its orientation) with mass m_p plus the
payload given per call.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from deltagen.errors import GeometryError
from deltagen.model.naming import check_identifier
from deltagen.model.parameters import RobotParameter
from deltagen.model.robot_file import RobotFile, degrees, family_table, real
from deltagen.status import SINGULAR_TOL

_LENGTHS = ("r_a", "r_b", "l_a", "l_b")
_CHAIN_KEYS = tuple(f"chain_{k}" for k in _LENGTHS)
_DELTA_KEYS = (
    set(_LENGTHS)
    | {"theta", "theta_deg", "singular_tol", "q_offset", "q_offset_deg"}
    | set(_CHAIN_KEYS)
)
_TOP_KEYS = {"name", "delta", "inertia"}
_INERTIA_KEYS = ("I_a", "m_a", "r_ca", "m_b", "m_p", "I_4")
STANDARD_GRAVITY = (0.0, 0.0, -9.81)
#: Smallest angular separation of two drives still called distinct [rad].
MIN_DRIVE_SEPARATION = 1e-6
#: The range of every length of a delta geometry (r_a, l_a, l_b and their per-chain values;
#: r_b may also be 0) [m]. The kernels evaluate eq. (1) and its derivatives in float64 with
#: products of up to about six lengths (e.g. the fk's quadratic and det J_p): far outside
#: (1e-100 m) they underflow to wrong angles, or overflow (1e150 m). Measured: ik(fk(q)) = q
#: to 1e-15 rad for the default robot scaled from 1e-20 m to 1e20 m in both backends. The
#: range covers every physical delta, from a millimetre-sized micro-robot (1e-6 m leaves room
#: for micrometre parts) to a 1 km structure, with a margin of 1e14 and 1e17 to where the
#: arithmetic fails; outside it a geometry is refused (GeometryError naming the field).
MIN_LENGTH = 1e-6
MAX_LENGTH = 1e3


def _length_in_range(value: float, key: str, zero_allowed: bool = False) -> None:
    if zero_allowed and value == 0.0:
        return
    if not MIN_LENGTH <= value <= MAX_LENGTH:
        raise GeometryError(
            f"{key} = {value!r} m is outside the range of delta lengths, {MIN_LENGTH:g} m to "
            f"{MAX_LENGTH:g} m{' (or 0)' if zero_allowed else ''}, that deltagen evaluates "
            "reliably in float64 (check the units: metres)"
        )


def _triple(values: Any, key: str) -> tuple[float, float, float]:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or len(values) != 3:
        raise GeometryError(f"{key} must hold 3 numbers (one per chain), got {values!r}")
    a, b, c = (real(v, f"{key}[{i}]") for i, v in enumerate(values))
    return (a, b, c)


@dataclass(frozen=True)
class DeltaInertia:
    """Inertial parameters of a rotary delta robot (SI units; see the module docstring).

    I_a      crank inertia about its drive axis, incl. reflected motor rotor and gearbox [kg m^2]
    m_a      crank mass (its gravity only: its inertia is in I_a)                      [kg]
    r_ca     distance of the crank's centre of mass from A_i along the crank          [m]
    m_b      mass of one rod pair (both rods of a parallelogram)                       [kg]
    m_p      platform mass without payload (fourth-axis parts riding on it included)   [kg]
    gravity  gravity vector in the base frame O (z up)                                 [m/s^2]
    I_4      fourth-axis inertia about its own axis, reflected to its motor (eq. (43)) [kg m^2]
    """

    I_a: float
    m_a: float
    r_ca: float
    m_b: float
    m_p: float
    gravity: tuple[float, ...] = STANDARD_GRAVITY
    I_4: float = 0.0

    def __post_init__(self) -> None:
        for key in _INERTIA_KEYS:
            value = real(getattr(self, key), f"inertia {key}")
            if value < 0.0:
                raise GeometryError(f"inertia {key} must be non-negative, got {value!r}")
            object.__setattr__(self, key, value)
        g = self.gravity
        if isinstance(g, (str, bytes)) or not hasattr(g, "__len__") or len(g) != 3:
            raise GeometryError(f"inertia gravity must hold 3 numbers (m/s^2), got {g!r}")
        object.__setattr__(
            self, "gravity", tuple(real(v, f"inertia gravity[{i}]") for i, v in enumerate(g))
        )

    @classmethod
    def default(cls) -> DeltaInertia:
        """Chosen values for the report's robot (the report prints no masses): see
        robots/default_delta.toml for where each number comes from."""
        return cls(I_a=0.037, m_a=0.6, r_ca=0.15, m_b=0.2, m_p=0.5, I_4=2.0e-4)

    @classmethod
    def from_mapping(cls, data: Any, source: str = "[inertia]") -> DeltaInertia:
        if not isinstance(data, dict):
            raise GeometryError(f"{source}: [inertia] must be a table")
        allowed = set(_INERTIA_KEYS) | {"gravity"}
        unknown = set(data) - allowed
        if unknown:
            raise GeometryError(f"{source}: unknown keys in [inertia]: {sorted(unknown)}")
        missing = [k for k in ("I_a", "m_a", "r_ca", "m_b", "m_p") if k not in data]
        if missing:
            raise GeometryError(f"{source}: missing keys in [inertia]: {missing}")
        try:
            return cls(**data)
        except (GeometryError, TypeError) as exc:
            raise GeometryError(f"{source}: {exc}") from None


@dataclass(frozen=True)
class DeltaGeometry(RobotFile):
    r_a: float
    r_b: float
    l_a: float
    l_b: float
    theta: tuple[float, ...]  # exactly 3 drive angles [rad], checked in __post_init__
    name: str = "delta"
    singular_tol: float = SINGULAR_TOL
    inertia: DeltaInertia | None = None  # needed only for the dynamics
    # per-chain values of an asymmetric robot (None: the symmetric r_a, r_b, l_a, l_b)
    chain_r_a: tuple[float, ...] | None = None
    chain_r_b: tuple[float, ...] | None = None
    chain_l_a: tuple[float, ...] | None = None
    chain_l_b: tuple[float, ...] | None = None
    q_offset: tuple[float, ...] = (0.0, 0.0, 0.0)  # encoder offsets [rad]

    def __post_init__(self) -> None:
        if self.inertia is not None and not isinstance(self.inertia, DeltaInertia):
            raise GeometryError(
                f"inertia must be a DeltaInertia, got {type(self.inertia).__name__}"
            )
        for key in _LENGTHS:
            object.__setattr__(self, key, real(getattr(self, key), key))
        for key in ("r_a", "l_a", "l_b"):
            if getattr(self, key) <= 0.0:
                raise GeometryError(f"{key} must be positive, got {getattr(self, key)!r}")
        if self.r_b < 0.0:
            raise GeometryError(f"r_b must be non-negative, got {self.r_b!r}")
        for key in _LENGTHS:
            _length_in_range(getattr(self, key), key, zero_allowed=key == "r_b")
        theta = self.theta
        if isinstance(theta, (str, bytes)) or not hasattr(theta, "__len__") or len(theta) != 3:
            raise GeometryError(f"theta must hold exactly 3 drive angles, got {theta!r}")
        theta = tuple(real(t, f"theta[{i}]") for i, t in enumerate(theta))
        object.__setattr__(self, "theta", theta)
        for i in range(3):
            for j in range(i + 1, 3):
                d = math.remainder(theta[i] - theta[j], 2.0 * math.pi)
                if abs(d) < MIN_DRIVE_SEPARATION:
                    raise GeometryError(
                        f"drive angles theta[{i}] and theta[{j}] coincide "
                        f"({theta[i]!r} and {theta[j]!r} rad): the chains would be parallel"
                    )
        # On the base axis (x = y = 0) the distance from P to the circle of sphere
        # centres S_i is |sqrt(r^2 + z^2) - l_a|; some z closes it iff |r| <= l_a + l_b.
        if abs(self.r) > self.l_a + self.l_b:
            raise GeometryError(
                f"rods too short: |r_a - r_b| = {abs(self.r):g} m exceeds l_a + l_b = "
                f"{self.l_a + self.l_b:g} m, so the chains close nowhere"
            )
        for key in _CHAIN_KEYS:
            values = getattr(self, key)
            if values is None:
                continue
            values = _triple(values, key)
            low = 0.0 if key == "chain_r_b" else None
            for i, v in enumerate(values):
                if (v < 0.0) if low is not None else (v <= 0.0):
                    raise GeometryError(
                        f"{key}[{i}] must be {'non-negative' if low is not None else 'positive'}, got {v!r}"
                    )
            for i, v in enumerate(values):
                _length_in_range(v, f"{key}[{i}]", zero_allowed=key == "chain_r_b")
            object.__setattr__(self, key, values)
        object.__setattr__(self, "q_offset", _triple(self.q_offset, "q_offset"))
        for i in range(3):
            r_i = self.chain("r_a")[i] - self.chain("r_b")[i]
            if abs(r_i) > self.chain("l_a")[i] + self.chain("l_b")[i]:
                raise GeometryError(
                    f"chain {i + 1}: rods too short: |r_a - r_b| = {abs(r_i):g} m exceeds l_a + l_b"
                )
        check_identifier(self.name)
        tol = real(self.singular_tol, "singular_tol")
        if not 0.0 <= tol < 1.0:
            raise GeometryError(f"singular_tol must lie in [0, 1), got {tol!r}")
        object.__setattr__(self, "singular_tol", tol)

    @property
    def r(self) -> float:
        """r = r_a - r_b, the radius of the sphere-centre circles' axis (report, eq. (1))."""
        return self.r_a - self.r_b

    def chain(self, key: str) -> tuple[float, float, float]:
        """Per-chain values of r_a, r_b, l_a or l_b (the symmetric value thrice if the chains
        do not differ)."""
        values = getattr(self, f"chain_{key}")
        if values is None:
            v = getattr(self, key)
            return (v, v, v)
        return values

    @property
    def chain_r(self) -> tuple[float, float, float]:
        """r_i = r_a_i - r_b_i per chain (eq. (1))."""
        a, b = self.chain("r_a"), self.chain("r_b")
        return (a[0] - b[0], a[1] - b[1], a[2] - b[2])

    @property
    def symmetric(self) -> bool:
        """No per-chain lengths and no encoder offsets."""
        return all(getattr(self, k) is None for k in _CHAIN_KEYS) and not any(self.q_offset)

    def with_chains(self, **values: Any) -> DeltaGeometry:
        """A copy with per-chain values: chain keys r_a, r_b, l_a, l_b (3 numbers each),
        theta (3 angles) or q_offset (3 offsets) [m, rad]."""
        from dataclasses import replace

        kwargs: dict[str, Any] = {}
        for key, v in values.items():
            if key in _LENGTHS:
                kwargs[f"chain_{key}"] = tuple(v)
            elif key in ("theta", "q_offset"):
                kwargs[key] = tuple(v)
            else:
                raise GeometryError(f"unknown per-chain key {key!r}")
        return replace(self, **kwargs)

    @property
    def size(self) -> float:
        """Characteristic length used for relative tolerances: l_a + l_b + r_a."""
        return self.l_a + self.l_b + self.r_a

    @classmethod
    def default(cls) -> DeltaGeometry:
        """The embedded default robot: r_a 0.2, r_b 0.045, l_a 0.35, l_b 0.8, 0/120/240 deg."""
        return cls(
            r_a=0.2,
            r_b=0.045,
            l_a=0.35,
            l_b=0.8,
            theta=tuple(math.radians(t) for t in (0.0, 120.0, 240.0)),
            name="default",
            inertia=DeltaInertia.default(),
        )

    @classmethod
    def from_mapping(cls, data: dict[str, Any], source: str = "robot description") -> DeltaGeometry:
        delta = family_table(data, "delta", _TOP_KEYS, _DELTA_KEYS, _LENGTHS, source)
        if "theta" in delta and "theta_deg" in delta:
            raise GeometryError(f"{source}: give theta (rad) or theta_deg (deg), not both")
        key = "theta_deg" if "theta_deg" in delta else "theta"
        if key not in delta:
            raise GeometryError(f"{source}: missing key theta (rad) or theta_deg (deg) in [delta]")
        raw = delta[key]
        if not isinstance(raw, list) or len(raw) != 3:
            raise GeometryError(f"{source}: {key} must be a list of 3 numbers")
        try:
            values = [real(t, f"{key}[{i}]") for i, t in enumerate(raw)]
        except GeometryError as exc:
            raise GeometryError(f"{source}: {exc}") from None
        theta = tuple(math.radians(t) for t in values) if key == "theta_deg" else tuple(values)
        kwargs = {k: delta[k] for k in _LENGTHS}
        if "singular_tol" in delta:
            kwargs["singular_tol"] = delta["singular_tol"]
        for k in _CHAIN_KEYS:
            if k in delta:
                kwargs[k] = delta[k]
        if "q_offset" in delta and "q_offset_deg" in delta:
            raise GeometryError(f"{source}: give q_offset (rad) or q_offset_deg (deg), not both")
        if "q_offset" in delta:
            kwargs["q_offset"] = delta["q_offset"]
        if "q_offset_deg" in delta:
            kwargs["q_offset"] = degrees(delta, "q_offset_deg", 3, source)
        if "inertia" in data:
            kwargs["inertia"] = DeltaInertia.from_mapping(data["inertia"], source)
        try:
            return cls(theta=theta, name=data.get("name", "delta"), **kwargs)
        except GeometryError as exc:
            raise GeometryError(f"{source}: {exc}") from None


def _inertia(key: str) -> Callable[[DeltaGeometry], Any]:
    """Reader of an inertia field: None for a geometry without inertia (the dynamics raise
    first in the API, so the compiled core leaves these fields zero)."""

    def read(g: DeltaGeometry) -> Any:
        return None if g.inertia is None else getattr(g.inertia, key)

    return read


_NO_INERTIA = "a geometry without [inertia]: the API refuses the dynamics first"

#: The fields of the delta core's parameter struct (deltagen_delta_geometry), in order: the
#: one declaration of the delta's parameters (model/parameters.py). The kinematics read the
#: per-chain values (an asymmetric robot); r_a, r_b, l_a, l_b are the nominal values that
#: scale the singularity thresholds and enter the dynamics.
DELTA_PARAMETERS = (
    RobotParameter("r_a", "m", "base radius, O to a drive axis [m]", lambda g: g.r_a),
    RobotParameter("r_b", "m", "platform radius, P to a joint C_i [m]", lambda g: g.r_b),
    RobotParameter("l_a", "m", "crank length [m]", lambda g: g.l_a),
    RobotParameter("l_b", "m", "parallelogram rod length [m]", lambda g: g.l_b),
    RobotParameter(
        "chain_r",
        "m",
        "per chain r_a,i - r_b,i [m] (symmetric: r_a - r_b)",
        lambda g: g.chain_r,
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "chain_l_a",
        "m",
        "per-chain crank length [m] (symmetric: l_a)",
        lambda g: g.chain("l_a"),
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "chain_l_b",
        "m",
        "per-chain rod length [m] (symmetric: l_b)",
        lambda g: g.chain("l_b"),
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "cos_theta",
        "1",
        "cos of the drive positions theta_i",
        lambda g: [math.cos(t) for t in g.theta],
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "sin_theta",
        "1",
        "sin of the drive positions theta_i",
        lambda g: [math.sin(t) for t in g.theta],
        count=3,
        per_chain=True,
    ),
    RobotParameter(
        "singular_tol",
        "1",
        "relative singularity threshold, e.g. 1e-9",
        lambda g: g.singular_tol,
    ),
    RobotParameter(
        "I_a",
        "kg m^2",
        "crank inertia about the drive axis, rotor + gearbox [kg m^2]",
        _inertia("I_a"),
        optional=_NO_INERTIA,
    ),
    RobotParameter("m_a", "kg", "crank mass (gravity) [kg]", _inertia("m_a"), optional=_NO_INERTIA),
    RobotParameter(
        "r_ca",
        "m",
        "crank centre of mass from A_i along the crank [m]",
        _inertia("r_ca"),
        optional=_NO_INERTIA,
    ),
    RobotParameter(
        "m_b",
        "kg",
        "mass of one rod pair (parallelogram) [kg]",
        _inertia("m_b"),
        optional=_NO_INERTIA,
    ),
    RobotParameter(
        "m_p", "kg", "platform mass without payload [kg]", _inertia("m_p"), optional=_NO_INERTIA
    ),
    RobotParameter(
        "gravity",
        "m/s^2",
        "gravity vector in the base frame [m/s^2]",
        _inertia("gravity"),
        count=3,
        optional=_NO_INERTIA,
    ),
    RobotParameter(
        "I_4",
        "kg m^2",
        "fourth-axis inertia about its axis [kg m^2]",
        _inertia("I_4"),
        optional=_NO_INERTIA,
    ),
)
