"""Reading robot files: TOML via tomllib, and the checks every description shares."""

from __future__ import annotations

import math
import numbers
import os
import tomllib
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any, Self, TypeAlias

from deltagen.errors import GeometryError
from deltagen.inputs import InputError, read_regular_file

PathLike: TypeAlias = str | os.PathLike[str]


def read_toml(path: PathLike, what: str = "robot file") -> dict[str, Any]:
    """The parsed table of a robot file (``what``: the kind of file, for messages); an
    unreadable file (read_regular_file: a regular file of bounded size) or malformed TOML
    raises GeometryError."""
    path = Path(path)
    try:
        text = read_regular_file(path, what).decode("utf-8")
    except InputError as exc:
        raise GeometryError(str(exc)) from None
    except UnicodeDecodeError:
        raise GeometryError(f"{path}: not UTF-8 text") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise GeometryError(f"{path}: malformed TOML: {exc}") from None


class RobotFile:
    """The ``from_toml`` of every description a TOML robot file holds (the delta, the
    hexapod, the 5-axis machine, the linear delta, the tripod, the serial arm): the file read
    by read_toml, then the class's own ``from_mapping`` with the file's path as the source
    its errors name."""

    @classmethod
    def from_toml(cls, path: PathLike) -> Self:
        return cls.from_mapping(read_toml(path), source=str(path))  # type: ignore[attr-defined]


def real(value: object, where: str) -> float:
    """A finite real number (bools and text are rejected), as float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise GeometryError(f"{where} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise GeometryError(f"{where} must be finite, got {value!r}")
    return value


def number_text(text: str, where: str, context: str = "") -> float:
    """The finite number a text of a robot file spells (URDF attributes, Klipper options);
    else GeometryError "<where>: '<text>' is not a number<context>" or "... is not finite"."""
    try:
        value = float(text)
    except ValueError:
        raise GeometryError(f"{where}: {text!r} is not a number{context}") from None
    if not math.isfinite(value):
        raise GeometryError(f"{where}: {text!r} is not finite")
    return value


def family_table(
    data: object,
    section: str,
    top_keys: Collection[str],
    keys: Collection[str],
    required: Sequence[str],
    source: str,
) -> dict[str, Any]:
    """The ``[section]`` table of a parsed robot file, checked: ``data`` is a table whose keys
    are among ``top_keys``, ``[section]`` is a table whose keys are among ``keys`` and that
    holds every key of ``required``; else GeometryError naming ``source`` and the key."""
    if not isinstance(data, dict):
        raise GeometryError(f"{source}: expected a table, got {type(data).__name__}")
    unknown = set(data) - set(top_keys)
    if unknown:
        raise GeometryError(f"{source}: unknown top-level keys {sorted(unknown)}")
    if section not in data:
        raise GeometryError(f"{source}: missing [{section}] table")
    table = data[section]
    if not isinstance(table, dict):
        raise GeometryError(f"{source}: [{section}] must be a table")
    unknown = set(table) - set(keys)
    if unknown:
        raise GeometryError(f"{source}: unknown keys in [{section}]: {sorted(unknown)}")
    missing = [k for k in required if k not in table]
    if missing:
        raise GeometryError(f"{source}: missing keys in [{section}]: {missing}")
    return table


def degrees(table: dict[str, Any], key: str, count: int, source: str) -> tuple[float, ...]:
    """``table[key]``, a list of ``count`` angles in degrees, in radians (GeometryError naming
    ``source`` and the key otherwise)."""
    raw = table[key]
    if not isinstance(raw, list) or len(raw) != count:
        raise GeometryError(f"{source}: {key} must be a list of {count} numbers")
    try:
        return tuple(math.radians(real(v, f"{key}[{i}]")) for i, v in enumerate(raw))
    except GeometryError as exc:
        raise GeometryError(f"{source}: {exc}") from None
