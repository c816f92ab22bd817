"""deltagen: robot geometry -> fast, verified kinematics code (SymPy -> C99 -> cffi)."""

from .delta.robot import DeltaRobot
from .serial.robot import SerialRobot
from .errors import GeometryError, SingularityError, UnreachableError
from .inputs import InputError

__all__ = [
    "DeltaRobot",
    "GeometryError",
    "InputError",
    "SerialRobot",
    "SingularityError",
    "UnreachableError",
]
__version__ = "0.1.0"
