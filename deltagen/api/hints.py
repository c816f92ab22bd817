"""Type aliases of the public API (``numpy.typing``), shared by ``delta`` and ``serial``."""

from __future__ import annotations

import os
from typing import Any, Literal, TypeAlias

import numpy as np
import numpy.typing as npt

FloatArray: TypeAlias = npt.NDArray[np.float64]
BoolArray: TypeAlias = npt.NDArray[np.bool_]
#: ``"raise"``: bad rows raise; ``"nan"``: NaN there, and the valid mask as the last result.
Errors: TypeAlias = Literal["raise", "nan"]
Backend: TypeAlias = Literal["compiled", "reference"]
PathLike: TypeAlias = str | os.PathLike[str]
#: What a batched call returns: with errors="raise" its array (or tuple of arrays, e.g.
#: fk_vel's (p, pd)); with errors="nan" that tuple plus the valid mask. The shape depends on
#: the mode, so the static type is left open (each method's docstring gives the shapes).
Result: TypeAlias = Any
