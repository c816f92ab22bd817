"""deltagen: robot geometry -> fast, verified kinematics code (SymPy -> C99 -> cffi).

The public names below are imported on first use (PEP 562 ``__getattr__``): ``import
deltagen`` alone, as the command line does before it knows the command, loads none of the
robot families, and ``from deltagen import DeltaRobot`` loads that one's module only."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from deltagen.api.delta import DeltaInertia, DeltaRobot
    from deltagen.api.five_axis import FiveAxisMachine
    from deltagen.api.hexapod import Hexapod
    from deltagen.api.linear_delta import LinearDelta, Tripod
    from deltagen.api.serial import SerialRobot
    from deltagen.api.sweep import SweepResult, SweepSpec, sweep
    from deltagen.errors import (
        GeometryError,
        IncompleteSolutionsWarning,
        SingularityError,
        UnreachableError,
    )
    from deltagen.inputs import InputError

#: each public name and the module that defines it
_MODULES = {
    "DeltaInertia": "deltagen.api.delta",
    "DeltaRobot": "deltagen.api.delta",
    "FiveAxisMachine": "deltagen.api.five_axis",
    "GeometryError": "deltagen.errors",
    "Hexapod": "deltagen.api.hexapod",
    "IncompleteSolutionsWarning": "deltagen.errors",
    "InputError": "deltagen.inputs",
    "LinearDelta": "deltagen.api.linear_delta",
    "SerialRobot": "deltagen.api.serial",
    "SingularityError": "deltagen.errors",
    "SweepResult": "deltagen.api.sweep",
    "SweepSpec": "deltagen.api.sweep",
    "Tripod": "deltagen.api.linear_delta",
    "UnreachableError": "deltagen.errors",
    "sweep": "deltagen.api.sweep",
}

__all__ = [
    "DeltaInertia",
    "DeltaRobot",
    "FiveAxisMachine",
    "GeometryError",
    "Hexapod",
    "IncompleteSolutionsWarning",
    "InputError",
    "LinearDelta",
    "SerialRobot",
    "SingularityError",
    "SweepResult",
    "SweepSpec",
    "Tripod",
    "UnreachableError",
    "sweep",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    module = _MODULES.get(name)
    if module is None:
        raise AttributeError(f"module 'deltagen' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
