"""Where the templates and the checked-in generated C live (checkout or installed wheel)."""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _find(name: str, marker: str) -> Path:
    for candidate in (_PACKAGE.parent / name, _PACKAGE / name):
        if (candidate / marker).is_file():
            return candidate
    return _PACKAGE.parent / name


def generated_dir() -> Path:
    """generated/ of the checkout, or the copy installed inside the package."""
    return _find("generated", "delta_kinematics.h")


def template_dir() -> Path:
    """codegen/templates/: the Jinja layout of the generated C."""
    return _PACKAGE / "codegen" / "templates"


def runtime_dir() -> Path:
    """codegen/runtime/: hand-written C compiled beside each generated module."""
    return _PACKAGE / "codegen" / "runtime"


_RESOLVED: dict[str, Path] = {}


def cache_dir() -> Path:
    """Build cache of compiled cores: $DELTAGEN_CACHE, else $XDG_CACHE_HOME/deltagen, else
    ~/.cache/deltagen. Always absolute: a relative value is resolved once, against the
    working directory at its first use, so a later chdir cannot move the cache."""
    raw = os.environ.get("DELTAGEN_CACHE")
    if not raw:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        raw = os.path.join(base, "deltagen")
    if raw not in _RESOLVED:
        _RESOLVED[raw] = Path(os.path.abspath(os.path.expanduser(raw)))
    return _RESOLVED[raw]


def robots_dir() -> Path:
    """robots/ (bundled robot files) of the checkout, or the copy inside the package."""
    return _find("robots", "default_delta.toml")
