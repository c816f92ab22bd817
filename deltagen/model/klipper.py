"""Klipper rotary-delta configurations (printer.cfg) as deltagen delta geometries, and
Klipper linear deltas (``kinematics: delta``) as LinearDeltaGeometry (KlipperLinearDelta
at the end of this module gives that mapping).

Klipper (the 3D-printer firmware) describes a rotary delta in ``[printer]`` with
``kinematics: rotary_delta`` and in the sections ``[stepper_a]``, ``[stepper_b]``,
``[stepper_c]``. Keys read here, in Klipper's units (mm, degrees):

    [printer]    shoulder_radius   horizontal radius of the shoulder joints minus that of the
                                   effector joints                       -> r_a (r_b = 0)
                 shoulder_height   height of the shoulder joints above the bed
    [stepper_X]  upper_arm_length  shoulder to elbow                     -> l_a
                 lower_arm_length  elbow to effector                     -> l_b
                 angle             the arm's position about z, degrees
                                   (default 30, 150, 270 for a, b, c)    -> theta_i
                 position_endstop  the z (above the bed) of the effector at x = y = 0 when
                                   the arm's endstop triggers: the homed pose
    (lengths of stepper_b and stepper_c default to stepper_a's, as in Klipper)

The mapping (Klipper's formulas: an elbow sits at
((shoulder_radius + upper_arm cos a) cos angle, (...) sin angle, shoulder_height +
upper_arm sin a); the effector is where the three lower-arm spheres meet):

* lengths: mm -> m;  r_a = shoulder_radius, r_b = 0 (Klipper folds the effector radius
  into shoulder_radius), l_a = upper_arm_length, l_b = lower_arm_length,
  theta_i = angle_i.
* arm angle: Klipper's a is positive up (elbow above the shoulder for a > 0); deltagen's q
  is positive down (B_z = -l_a sin q): q = -a.
* z origin: Klipper's z = 0 is the bed; deltagen's base frame O lies in the plane of the
  shoulder (drive) axes: z_deltagen = z_klipper - shoulder_height; x, y are the same.

The homed pose is p = (0, 0, position_endstop - shoulder_height) in deltagen's frame;
:meth:`KlipperRotaryDelta.home_q` gives its crank angles. Arm lengths that differ
between the steppers give per-chain lengths (an asymmetric robot). ``[include ...]``
sections are rejected (a clear error: pass the file that holds the printer). Klipper's
SAVE_CONFIG block at the end of printer.cfg (lines ``#*# ...``) overrides the sections
above it, as in Klipper. Lengths outside deltagen's range of delta lengths (1e-6 m to 1e3 m,
deltagen.model.delta.MIN_LENGTH/MAX_LENGTH; heights and endstops at most 1e3 m) are refused
by their printer.cfg key, in mm.
"""

from __future__ import annotations

import configparser
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from deltagen.errors import GeometryError
from deltagen.inputs import InputError, read_regular_file
from deltagen.model.delta import MAX_LENGTH, MIN_LENGTH, DeltaGeometry
from deltagen.model.linear_delta import KLIPPER_TOWER_ANGLES, LinearDeltaGeometry
from deltagen.model.robot_file import PathLike, number_text

#: Klipper's default arm positions of stepper_a, _b, _c [deg].
KLIPPER_DEFAULT_ANGLES = (30.0, 150.0, 270.0)
_MM = 1e-3
_AUTOSAVE = "#*#"


@dataclass(frozen=True)
class KlipperRotaryDelta:
    """A parsed Klipper rotary delta: the deltagen geometry and Klipper's frame offsets.

    geometry          the equivalent DeltaGeometry (SI units, deltagen conventions)
    shoulder_height   z of deltagen's base frame above Klipper's bed [m]
    position_endstop  Klipper's endstop heights of steppers a, b, c [m above the bed]
    """

    geometry: DeltaGeometry
    shoulder_height: float
    position_endstop: tuple[float, float, float]

    def to_klipper_xyz(self, p):
        """deltagen platform positions (..., 3) [m] -> Klipper toolhead x, y, z [mm]."""
        import numpy as np

        out = np.array(p, dtype=float, copy=True)
        out[..., 2] += self.shoulder_height
        return out / _MM

    def from_klipper_xyz(self, xyz_mm):
        """Klipper toolhead x, y, z [mm] (z above the bed) -> deltagen positions [m]."""
        import numpy as np

        out = np.array(xyz_mm, dtype=float, copy=True) * _MM
        out[..., 2] -= self.shoulder_height
        return out

    @staticmethod
    def arm_angle_to_q(a):
        """Klipper's arm angle (rad, positive up) -> deltagen's crank angle (positive down)."""
        return -a

    def home_p(self, i: int) -> tuple[float, float, float]:
        """deltagen position of the homed effector for stepper i's endstop [m]."""
        return (0.0, 0.0, self.position_endstop[i] - self.shoulder_height)


def _parse(text: str, source: str) -> configparser.ConfigParser:
    """Klipper's ini dialect: ``key: value`` or ``key = value``, ``#`` and ``;`` comments
    (also after a value), later definitions override earlier ones, and the SAVE_CONFIG
    block (``#*# ...`` lines) overrides everything above it."""
    main, autosave = [], []
    for line in text.splitlines():
        if line.startswith(_AUTOSAVE):
            autosave.append(line[len(_AUTOSAVE) :].lstrip(" ") if len(line) > 3 else "")
        else:
            main.append(line)

    def parser():
        return configparser.ConfigParser(
            comment_prefixes=("#", ";"),
            inline_comment_prefixes=("#", ";"),
            strict=False,
            interpolation=None,
            delimiters=(":", "="),
        )

    config = parser()
    try:
        config.read_string("\n".join(main), source=source)
        if autosave:
            saved = parser()
            # the block's header lines (the marker, "DO NOT EDIT ...") precede its sections
            first = next((k for k, line in enumerate(autosave) if line.startswith("[")), None)
            saved.read_string(
                "\n".join(autosave[first:] if first is not None else []), source=source
            )
            for section in saved.sections():
                if not config.has_section(section):
                    config.add_section(section)
                for key, value in saved.items(section):
                    config.set(section, key, value)
    except configparser.Error as exc:
        raise GeometryError(f"{source}: not a readable Klipper config: {exc}") from None
    includes = [s for s in config.sections() if s.split()[0].lower() == "include"]
    if includes:
        raise GeometryError(
            f"{source}: [{includes[0]}] - included files are not read; pass the config file "
            "that holds [printer] and [stepper_a..c] (or merge the includes into it)"
        )
    return config


def _number(config, section, key, source, default=None):
    if not config.has_option(section, key):
        if default is None:
            raise GeometryError(f"{source}: [{section}] needs {key}")
        return default
    return number_text(config.get(section, key), f"{source}: [{section}] {key}")


def _delta_config(
    text: str, source: str, kinematics: str, describes: str
) -> tuple[configparser.ConfigParser, list[str]]:
    """(config, stepper section names) of a Klipper config whose ``[printer] kinematics`` is
    ``kinematics``, with its [stepper_a/b/c] sections; GeometryError otherwise (``describes``:
    the message's "only ..." clause)."""
    config = _parse(text, source)
    if not config.has_section("printer"):
        raise GeometryError(f"{source}: no [printer] section")
    found = config.get("printer", "kinematics", fallback="").strip()
    if found != kinematics:
        raise GeometryError(
            f"{source}: [printer] kinematics is {found or 'missing'!r}; only {describes}"
        )
    steppers = [f"stepper_{a}" for a in "abc"]
    for section in steppers:
        if not config.has_section(section):
            raise GeometryError(f"{source}: no [{section}] section")
    return config, steppers


def klipper_from_text(
    text: str, source: str = "printer.cfg", name: str = "klipper"
) -> KlipperRotaryDelta:
    """Parse a Klipper config's text: a :class:`KlipperRotaryDelta`."""
    config, steppers = _delta_config(
        text,
        source,
        "rotary_delta",
        "'rotary_delta' describes a rotary delta robot (a linear delta, kinematics: delta: "
        "deltagen.LinearDelta.from_klipper)",
    )
    radius = _number(config, "printer", "shoulder_radius", source)
    height = _number(config, "printer", "shoulder_height", source)
    if radius <= 0.0 or height <= 0.0:
        raise GeometryError(f"{source}: [printer] shoulder_radius and shoulder_height must be > 0")
    upper_a = _number(config, "stepper_a", "upper_arm_length", source)
    lower_a = _number(config, "stepper_a", "lower_arm_length", source)
    upper = [_number(config, s, "upper_arm_length", source, upper_a) for s in steppers]
    lower = [_number(config, s, "lower_arm_length", source, lower_a) for s in steppers]
    angles = [
        _number(config, s, "angle", source, d) for s, d in zip(steppers, KLIPPER_DEFAULT_ANGLES)
    ]
    endstop_a = _number(config, "stepper_a", "position_endstop", source)
    endstops = [_number(config, s, "position_endstop", source, endstop_a) for s in steppers]
    for key, values in (("upper_arm_length", upper), ("lower_arm_length", lower)):
        if min(values) <= 0.0:
            raise GeometryError(f"{source}: {key} must be > 0, got {values}")
    # deltagen's range of delta lengths (model.delta.MIN_LENGTH..MAX_LENGTH), named by the
    # printer.cfg key and in its unit (mm); heights are frame offsets: at most MAX_LENGTH
    lengths = [("printer", "shoulder_radius", radius, True)]
    lengths += [(s, "upper_arm_length", v, True) for s, v in zip(steppers, upper)]
    lengths += [(s, "lower_arm_length", v, True) for s, v in zip(steppers, lower)]
    lengths += [("printer", "shoulder_height", height, False)]
    lengths += [(s, "position_endstop", v, False) for s, v in zip(steppers, endstops)]
    for section, key, value, is_length in lengths:
        low = MIN_LENGTH / _MM if is_length else 0.0
        if not (low <= abs(value) <= MAX_LENGTH / _MM):
            raise GeometryError(
                f"{source}: [{section}] {key}: {value:g} mm is outside the range deltagen "
                f"evaluates reliably, {low:g} to {MAX_LENGTH / _MM:g} mm"
                f"{'' if is_length else ' in magnitude'} (float64 kinematics; see "
                "deltagen.model.delta.MAX_LENGTH)"
            )
    kwargs: dict[str, Any] = {}
    if len(set(upper)) == 1 and len(set(lower)) == 1:
        kwargs.update(l_a=upper[0] * _MM, l_b=lower[0] * _MM)
    else:
        kwargs.update(
            l_a=upper[0] * _MM,
            l_b=lower[0] * _MM,
            chains=dict(l_a=tuple(u * _MM for u in upper), l_b=tuple(v * _MM for v in lower)),
        )
    try:
        geometry = _geometry(
            r_a=radius * _MM,
            r_b=0.0,
            theta=tuple(math.radians(a) for a in angles),
            name=name,
            **kwargs,
        )
    except GeometryError as exc:
        raise GeometryError(f"{source}: {exc}") from None
    return KlipperRotaryDelta(
        geometry=geometry,
        shoulder_height=height * _MM,
        position_endstop=(endstops[0] * _MM, endstops[1] * _MM, endstops[2] * _MM),
    )


def _geometry(chains: dict[str, Any] | None = None, **kwargs: Any) -> DeltaGeometry:
    """The symmetric geometry, or with per-chain arm lengths where the steppers differ."""
    geometry = DeltaGeometry(**kwargs)
    return geometry if chains is None else geometry.with_chains(**chains)


def _read_config(path: Path) -> str:
    """The text of a Klipper config, read as a bounded regular file (GeometryError else)."""
    try:
        return read_regular_file(path, "Klipper config").decode("utf-8")
    except InputError as exc:
        raise GeometryError(str(exc)) from None
    except UnicodeDecodeError as exc:
        raise GeometryError(f"cannot read Klipper config {path}: {exc}") from None


def read_klipper(path: PathLike, name: str = "klipper") -> KlipperRotaryDelta:
    """Read a Klipper printer.cfg (see the module docstring for the mapping)."""
    path = Path(path)
    text = _read_config(path)
    return klipper_from_text(text, source=str(path), name=name)


# -- the linear delta ([printer] kinematics: delta) ---------------------------------------


@dataclass(frozen=True)
class KlipperLinearDelta:
    """A parsed Klipper linear delta (``kinematics: delta``), in metres, in Klipper's frame
    (x, y as Klipper's; z above the bed; carriage heights = Klipper's stepper positions).

    geometry          the LinearDeltaGeometry: delta_radius for every tower at the
                      stepper's ``angle`` (default 210, 330, 90 deg), the per-stepper
                      arm_length (stepper_b, _c default to stepper_a's), carriage travel
                      from minimum_z_position to the highest endstop carriage height
    position_endstop  the effector heights at x = y = 0 when each carriage sits at its
                      endstop [m]
    endstop_carriage  the carriage heights at the endstops: position_endstop_i +
                      sqrt(arm_i^2 - delta_radius^2) (Klipper's abs_endstops) [m]
    print_radius      the printable radius [m] (delta_radius when not given)
    minimum_z         minimum_z_position [m]
    """

    geometry: LinearDeltaGeometry
    position_endstop: tuple[float, float, float]
    endstop_carriage: tuple[float, float, float]
    print_radius: float
    minimum_z: float

    @property
    def max_z(self) -> float:
        """The highest effector z, the lowest endstop (Klipper's max_z) [m]."""
        return min(self.position_endstop)


def klipper_kinematics(path: PathLike) -> str:
    """The ``[printer] kinematics`` of a Klipper config ('' when there is none)."""
    path = Path(path)
    text = _read_config(path)
    config = _parse(text, str(path))
    return config.get("printer", "kinematics", fallback="").strip()


def klipper_delta_from_text(
    text: str, source: str = "printer.cfg", name: str = "klipper"
) -> KlipperLinearDelta:
    """Parse a Klipper ``kinematics: delta`` config's text (KlipperLinearDelta's mapping)."""
    config, steppers = _delta_config(
        text,
        source,
        "delta",
        "'delta' describes a linear delta (a rotary delta: deltagen.DeltaRobot.from_klipper)",
    )
    radius = _number(config, "printer", "delta_radius", source)
    if radius <= 0.0:
        raise GeometryError(f"{source}: [printer] delta_radius must be > 0")
    print_radius = _number(config, "printer", "print_radius", source, radius)
    arm_a = _number(config, "stepper_a", "arm_length", source)
    arms = [_number(config, s, "arm_length", source, arm_a) for s in steppers]
    if min(arms) <= radius:  # Klipper: arm_length above=radius
        raise GeometryError(
            f"{source}: every arm_length must exceed delta_radius ({radius}), got {arms}"
        )
    angles = [
        _number(config, s, "angle", source, d) for s, d in zip(steppers, KLIPPER_TOWER_ANGLES)
    ]
    endstop_a = _number(config, "stepper_a", "position_endstop", source)
    endstops = [_number(config, s, "position_endstop", source, endstop_a) for s in steppers]
    minimum_z = _number(config, "printer", "minimum_z_position", source, 0.0)
    carriage = [e + math.sqrt(a**2 - radius**2) for e, a in zip(endstops, arms)]
    try:
        geometry = LinearDeltaGeometry(
            radius=(radius * _MM,) * 3,
            angle=tuple(math.radians(a) for a in angles),  # type: ignore[arg-type]
            arm_length=tuple(a * _MM for a in arms),
            carriage_range=(minimum_z * _MM, max(carriage) * _MM),
            name=name,
        )
    except GeometryError as exc:
        raise GeometryError(f"{source}: {exc}") from None
    return KlipperLinearDelta(
        geometry=geometry,
        position_endstop=tuple(e * _MM for e in endstops),
        endstop_carriage=tuple(c * _MM for c in carriage),
        print_radius=print_radius * _MM,
        minimum_z=minimum_z * _MM,
    )


def read_klipper_delta(path: PathLike, name: str = "klipper") -> KlipperLinearDelta:
    """Read a Klipper ``kinematics: delta`` printer.cfg (KlipperLinearDelta's mapping)."""
    path = Path(path)
    text = _read_config(path)
    return klipper_delta_from_text(text, source=str(path), name=name)
