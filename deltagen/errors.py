"""Exceptions raised by deltagen. Both kinematic errors are ``ValueError`` subclasses."""

from __future__ import annotations

import numpy as np


def rows_text(rows) -> str:
    """The failing rows of a batch for an error message: the first ten and the count."""
    rows = list(rows)
    shown = ", ".join(str(r) for r in rows[:10])
    return f"[{shown}{', ...' if len(rows) > 10 else ''}] ({len(rows)} of the batch)"


class DeltagenError(Exception):
    """Base class of deltagen's own errors. ``rows`` lists the failing batch indices (flat,
    C order over the leading dimensions); empty when the error is not about rows (a bad
    option, a malformed file) or concerns the whole call."""

    def __init__(self, message: str = "", rows=()):
        self.rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        super().__init__(message)


class GeometryError(DeltagenError, ValueError):
    """A robot description that cannot describe a real robot (or a malformed file)."""


class KinematicsError(DeltagenError, ValueError):
    """A pose the kinematics cannot evaluate; ``rows`` lists the failing batch indices."""


class UnreachableError(KinematicsError):
    """The spheres do not meet (direct kinematics) or a crank cannot reach (inverse)."""


class SingularityError(KinematicsError):
    """The pose is singular: det J_p ~ 0, a J_q diagonal entry ~ 0, or collinear centres."""


class IncompleteSolutionsWarning(UserWarning):
    """ik_all answered with a method that may miss solutions (its result's ``complete`` is
    False): a pose without a valid solution may still be reachable."""


class ManifestError(DeltagenError, RuntimeError):
    """A compiled module and the Python declaration disagree: a field of the parameter
    struct, or a kernel's ports (the generated C is stale, or a parameter table was edited
    without `deltagen generate`)."""
