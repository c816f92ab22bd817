"""The command line's one robot loader: what a robot argument names (a delta robot, a serial
arm or a serial arm with coupled joints), read from the file itself, and the refusal of a
command that cannot serve that kind.

A robot argument is 'default' (the delta robot of robots/default_delta.toml), a bundled arm's
name (robots/<name>.toml or robots/<name>.urdf), or a file: a URDF (its content is XML,
whatever its extension), a Klipper printer.cfg (kinematics: rotary_delta, or delta: a linear
delta), a delta robot TOML (a [delta] table), a linear delta's or a tripod's TOML (a
[linear_delta] or [tripod] table), a hexapod TOML (a [hexapod] table), a 5-axis machine
TOML (a [machine] table; a bundled machine by its name) or a serial-arm TOML (a
`convention` key and [[joint]] tables). A URDF gives
a SerialRobot, or a CoupledArm when its chain has ``<mimic>`` joints; ``base``, ``tip`` and
``locked`` (the CLI's --base, --tip, --locked) choose its chain (SerialRobot.from_urdf)."""

from __future__ import annotations

import sys
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from deltagen.inputs import InputError, read_regular_file

DELTA, SERIAL, COUPLED = "delta", "serial", "coupled"
LINEAR_DELTA, TRIPOD = "linear_delta", "tripod"
HEXAPOD = "hexapod"
MACHINE = "machine"

#: How messages name each kind (with an article).
KIND_NAMES = {
    DELTA: "a delta robot",
    SERIAL: "a serial arm",
    COUPLED: "a serial arm with coupled (URDF <mimic>) joints",
    LINEAR_DELTA: "a linear delta",
    TRIPOD: "a tripod",
    HEXAPOD: "a hexapod",
    MACHINE: "a 5-axis NC machine",
}


#: What a command's robot argument may be (its help text).
ROBOT_HELP = (
    "'default' (the delta robot), a bundled serial arm's or 5-axis machine's name, a robot "
    "TOML file, a URDF, or a Klipper printer.cfg (kinematics: rotary_delta)"
)


def add_urdf_options(parser: Any) -> None:
    """--base, --tip, --locked: the chain of a URDF robot (SerialRobot.from_urdf)."""
    parser.add_argument(
        "--base", metavar="LINK", help="URDF: the chain's first link (default: the root)"
    )
    parser.add_argument(
        "--tip",
        metavar="LINK",
        help="URDF: the chain's last link (default: the single leaf; needed when the tree "
        "branches, e.g. an arm with a two-finger gripper)",
    )
    parser.add_argument(
        "--locked",
        metavar="NAME=VALUE",
        action="append",
        help="URDF: the value [rad or m] of a movable joint off the chain (or above --base), "
        "where its link's mass is folded in (default 0); repeatable",
    )


def robot_of(
    args: Any,
    kinds: Sequence[str] | None = None,
    *,
    spec: str | None = None,
    backend: str | None = None,
) -> Any:
    """The robot of a command's parsed arguments, the one place a command loads it
    (:func:`load_robot`): ``spec`` or ``args.robot``, ``backend`` or ``args.backend``
    (default compiled), the URDF options --base, --tip, --locked; refused (InputError, exit
    status 2) unless of ``kinds``, naming ``args.command``."""
    return load_robot(
        args.robot if spec is None else spec,
        backend or getattr(args, "backend", None) or "compiled",
        base=getattr(args, "base", None),
        tip=getattr(args, "tip", None),
        locked=parse_locked(getattr(args, "locked", None)),
        command=args.command,
        kinds=kinds,
    )


def run_job(args: Any, jobs: Mapping[str, Any], *before: Any) -> int:
    """A command's job table at work: the robot of ``args`` (robot_of, refusing the kinds
    ``jobs`` does not serve), then ``jobs[its kind](robot, *before, args)``, the exit
    status."""
    robot = robot_of(args, kinds=tuple(jobs))
    return jobs[kind_of(robot)](robot, *before, args)


#: (kind, module, class) of every robot class but SerialRobot's, tested in this order
_CLASSES = (
    (MACHINE, "deltagen.api.five_axis", "FiveAxisMachine"),
    (LINEAR_DELTA, "deltagen.api.linear_delta", "LinearDelta"),
    (TRIPOD, "deltagen.api.linear_delta", "Tripod"),
    (HEXAPOD, "deltagen.api.hexapod", "Hexapod"),
    (DELTA, "deltagen.api.delta", "DeltaRobot"),
    (COUPLED, "deltagen.api.coupled", "CoupledArm"),
)


def kind_of(robot: Any) -> str:
    """The kind (DELTA, SERIAL, COUPLED, LINEAR_DELTA, TRIPOD, HEXAPOD, MACHINE) of a loaded
    robot."""
    for kind, module, name in _CLASSES:
        loaded = sys.modules.get(module)  # a robot's class is loaded: no import needed
        if loaded is not None and isinstance(robot, getattr(loaded, name)):
            return kind
    return SERIAL


def _require(command: str, kind: str, name: str, kinds: Sequence[str] | None) -> None:
    if kinds is None or kind in kinds:
        return
    served = " or ".join(KIND_NAMES[k] for k in kinds)
    shown = f" ({name})" if name else ""
    raise InputError(
        f"`deltagen {command}` takes {served}; the robot given is {KIND_NAMES[kind]}{shown}"
    )


def parse_locked(items: Sequence[str] | None) -> dict[str, float] | None:
    """--locked NAME=VALUE (repeated) -> {NAME: VALUE}."""
    if not items:
        return None
    locked: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        try:
            number = float(value) if sep and name else None
        except ValueError:
            number = None
        if number is None:
            raise InputError(f"--locked {item!r}: give NAME=VALUE, e.g. --locked finger_joint=0.02")
        locked[name] = number
    return locked


def file_kind(path: Path) -> str:
    """ "urdf", "klipper", "serial", "linear_delta", "tripod", "hexapod", "machine" or "delta"
    for a robot file, from its content (the extension decides only for .urdf and .cfg, and
    for a file that cannot be read)."""
    suffix = path.suffix.lower()
    if suffix == ".urdf":
        return "urdf"
    if suffix == ".cfg":
        return "klipper"
    try:
        text = read_regular_file(path, "robot file").decode("utf-8")
    except (InputError, UnicodeDecodeError):
        return "delta"  # its loader reports the unreadable file
    if text.lstrip().startswith("<"):
        return "urdf"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError:  # malformed: the loader named by a plain look reports it
        if "kinematics:" in text and "[printer]" in text:
            return "klipper"
        if "[machine]" in text and "[delta]" not in text:
            return "machine"
        return "serial" if "convention" in text and "[delta]" not in text else "delta"
    if "hexapod" in data and "delta" not in data:
        return "hexapod"
    if "machine" in data and "delta" not in data:
        return "machine"
    if "delta" not in data and ("convention" in data or "joint" in data):
        return "serial"
    for table in (LINEAR_DELTA, TRIPOD):
        if "delta" not in data and table in data:
            return table
    return "delta"


def load_robot(
    spec: str | None,
    backend: Any = "compiled",
    *,
    base: str | None = None,
    tip: str | None = None,
    locked: Mapping[str, float] | None = None,
    command: str = "",
    kinds: Sequence[str] | None = None,
) -> Any:
    """The robot a robot argument names (module docstring). With ``kinds``: refused
    (InputError naming ``command`` and the robot's kind) unless it is of one of them, before
    any compiled core is built."""
    from deltagen.api.bundled import bundled_robots, bundled_urdfs
    from deltagen.api.five_axis import bundled_machines
    from deltagen.paths import robots_dir

    urdf_options = [
        flag
        for flag, value in (("--base", base), ("--tip", tip), ("--locked", locked))
        if value is not None
    ]
    name = spec if spec is not None else "default"
    path = Path(name)
    if name == "default":
        kind, path = "delta", robots_dir() / "default_delta.toml"
    elif name in bundled_urdfs() and name not in bundled_robots():
        kind, path = "bundled-urdf", robots_dir() / f"{name}.urdf"
    elif name in bundled_robots():
        kind = "bundled"
    elif name in bundled_machines():
        kind, path = "machine", robots_dir() / f"{name}.toml"
    elif not path.exists() and path.suffix.lower() not in (".toml", ".urdf", ".cfg"):
        raise InputError(
            f"unknown robot {name!r}: use 'default', a bundled arm "
            f"({', '.join(bundled_robots() + bundled_urdfs())}), a bundled 5-axis machine "
            f"({', '.join(bundled_machines())}), a robot .toml file, a .urdf or a Klipper "
            "printer.cfg"
        )
    else:
        kind = file_kind(path)
    if urdf_options and kind not in ("urdf", "bundled-urdf"):
        raise InputError(
            f"{' and '.join(urdf_options)} {'chooses' if len(urdf_options) == 1 else 'choose'} "
            f"the chain of a URDF; {name} is not a URDF"
        )
    if kind in ("urdf", "bundled-urdf"):  # read without a core: serial or coupled
        from deltagen.api.serial import SerialRobot

        if kind == "bundled-urdf" and not urdf_options:
            robot = SerialRobot.load(name, backend="reference")  # under the bundled name
        else:
            robot = _from_urdf(path, base, tip, locked, "reference")
        _require(command, kind_of(robot), robot.name, kinds)
        if backend == "reference":
            return robot
        if hasattr(robot, "coupling"):
            return type(robot)(robot.full.with_backend(backend), robot.coupling)
        return robot.with_backend(backend)
    if kind == "klipper":
        from deltagen.model.klipper import klipper_kinematics

        if klipper_kinematics(path) == "delta":
            kind = "klipper_linear_delta"
    if kind in (LINEAR_DELTA, TRIPOD, "klipper_linear_delta"):
        from deltagen.api.linear_delta import LinearDelta, Tripod

        _require(command, TRIPOD if kind == TRIPOD else LINEAR_DELTA, path.stem, kinds)
        if kind == "klipper_linear_delta":
            return LinearDelta.from_klipper(path, backend=backend)
        return (Tripod if kind == TRIPOD else LinearDelta).from_toml(path, backend=backend)
    if kind == "hexapod":  # a [hexapod] table (model/hexapod.py)
        from deltagen.api.hexapod import Hexapod

        _require(command, HEXAPOD, name, kinds)
        return Hexapod.from_toml(path, backend=backend)
    if kind == "machine":
        from deltagen.api.five_axis import FiveAxisMachine

        _require(command, MACHINE, name, kinds)
        return FiveAxisMachine.from_toml(path, backend=backend)
    serial = kind in ("bundled", "serial")
    _require(command, SERIAL if serial else DELTA, name if serial else "", kinds)
    if serial:
        from deltagen.api.serial import SerialRobot

        if kind == "bundled":
            return SerialRobot.load(name, backend=backend)
        return SerialRobot.from_toml(path, backend=backend)
    from deltagen.api.delta import DeltaRobot

    if kind == "klipper":
        return DeltaRobot.from_klipper(path, backend=backend)
    if name == "default":
        return DeltaRobot.default(backend=backend)
    return DeltaRobot.from_toml(path, backend=backend)


def _from_urdf(path, base, tip, locked, backend):
    from deltagen.api.serial import SerialRobot
    from deltagen.model.urdf import TipChoiceError

    try:
        return SerialRobot.from_urdf(path, base, tip, locked=locked, backend=backend)
    except TipChoiceError as exc:
        if not exc.leaves:  # the base link is itself a leaf
            raise InputError(
                f"URDF {path}: no link lies below link {exc.base!r}; choose the chain with "
                "--base NAME and --tip NAME"
            ) from None
        raise InputError(
            f"URDF {path}: the tree below link {exc.base!r} has {len(exc.leaves)} leaves "
            f"({', '.join(exc.leaves)}); choose the chain's end with --tip NAME "
            f"(e.g. --tip {exc.leaves[0]})"
        ) from None
