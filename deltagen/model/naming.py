"""Validation of names that end up in C identifiers or file paths."""

from __future__ import annotations

import re

from deltagen.errors import GeometryError

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}\Z")


def check_identifier(name: object, what: str = "robot name") -> str:
    """Return ``name`` if it is a valid C identifier (letters, digits, underscore)."""
    if not isinstance(name, str) or not _IDENTIFIER.match(name):
        raise GeometryError(
            f"invalid {what} {name!r}: use 1-64 letters, digits or underscores, "
            "not starting with a digit"
        )
    return name
