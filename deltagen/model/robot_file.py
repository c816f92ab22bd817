"""Reading robot files: TOML via tomllib, and the checks every description shares."""

from __future__ import annotations

import math
import numbers
import os
import tomllib
from pathlib import Path
from typing import Any, TypeAlias

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


def real(value: object, where: str) -> float:
    """A finite real number (bools and text are rejected), as float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise GeometryError(f"{where} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise GeometryError(f"{where} must be finite, got {value!r}")
    return value
