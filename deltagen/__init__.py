"""deltagen: robot geometry -> fast, verified kinematics code (SymPy -> C99 -> cffi)."""

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
