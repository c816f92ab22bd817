"""The compiled backends of the linear delta and the tripod: generated/
linear_delta_kinematics.c and tripod_kinematics.c via cffi (rows of 3, no axes argument)."""

from __future__ import annotations

from deltagen.model.linear_delta import LINEAR_DELTA_PARAMETERS, TRIPOD_PARAMETERS
from deltagen.model.parameters import struct_values
from deltagen.native.core import CompiledCore


def linear_delta_struct(g) -> dict:
    """The fields of deltagen_linear_delta_geometry for a LinearDeltaGeometry (its one
    declaration: model.linear_delta.LINEAR_DELTA_PARAMETERS)."""
    return struct_values(LINEAR_DELTA_PARAMETERS, g)


def tripod_struct(g) -> dict:
    """The fields of deltagen_tripod_geometry for a TripodGeometry (its one declaration:
    model.linear_delta.TRIPOD_PARAMETERS)."""
    return struct_values(TRIPOD_PARAMETERS, g)


class CompiledTrilateration(CompiledCore):
    """Batched calls into one of the two cores; arrays are (N, 3) C-contiguous float64."""

    #: per machine: module file stem, C prefix, parameter table
    MODULES = {
        "linear_delta": (
            "linear_delta_kinematics",
            "deltagen_linear_delta",
            LINEAR_DELTA_PARAMETERS,
        ),
        "tripod": ("tripod_kinematics", "deltagen_tripod", TRIPOD_PARAMETERS),
    }

    def __init__(self, kind: str, geometry, threads=None):
        base, prefix, table = self.MODULES[kind]
        super().__init__(base, prefix, f"{prefix}_geometry", table, geometry, threads)

    def single(self, name):
        """A lean function for one pose (native.lean), or None where the general path must
        answer (as CompiledDelta.single); every kernel of the module has one (rows of 3)."""
        return self._single(name)

    def fk(self, q):
        return self._run("fk", [q])

    def fk_vel(self, q, qd):
        return self._run("fk_vel", [q, qd])

    def fk_acc(self, q, qd, qdd):
        return self._run("fk_acc", [q, qd, qdd])

    def jacobian(self, q):
        return self._run("jacobian", [q])

    def ik(self, p):
        return self._run("ik", [p])

    def ik_vel(self, p, pd):
        return self._run("ik_vel", [p, pd])

    def ik_acc(self, p, pd, pdd):
        return self._run("ik_acc", [p, pd, pdd])
