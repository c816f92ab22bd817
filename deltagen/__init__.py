"""deltagen: robot geometry -> fast, verified kinematics code (SymPy -> C99 -> cffi)."""

from deltagen.api.delta import DeltaInertia, DeltaRobot
from deltagen.api.hexapod import Hexapod  # noqa: E402  (the hexapod family)
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
__all__ += ["Hexapod"]
__version__ = "0.1.0"
