"""deltagen: robot geometry -> fast, verified kinematics code (SymPy -> C99 -> cffi)."""

from deltagen.api.delta import DeltaInertia, DeltaRobot
from deltagen.api.five_axis import FiveAxisMachine
from deltagen.api.serial import SerialRobot
from deltagen.api.sweep import SweepResult, SweepSpec, sweep
from deltagen.errors import (
    GeometryError,
    IncompleteSolutionsWarning,
    SingularityError,
    UnreachableError,
)
from deltagen.inputs import InputError

__all__ = [
    "DeltaInertia",
    "DeltaRobot",
    "FiveAxisMachine",
    "GeometryError",
    "IncompleteSolutionsWarning",
    "InputError",
    "SerialRobot",
    "SingularityError",
    "SweepResult",
    "SweepSpec",
    "UnreachableError",
    "sweep",
]
__version__ = "0.1.0"
