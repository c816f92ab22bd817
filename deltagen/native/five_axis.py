"""The compiled 5-axis machine core (generated/five_axis_kinematics.c) via cffi: one module
for every machine; the description's layout and rotary pair choose the functions."""

from __future__ import annotations

from deltagen.model.five_axis import FIVE_AXIS_PARAMETERS
from deltagen.model.parameters import struct_values
from deltagen.native.core import CompiledCore

MODULE = "five_axis_kinematics"  # generated/five_axis_kinematics.{c,h,cdef.h,kernels.json}
STRUCT = "deltagen_five_axis_geometry"


def geometry_struct(desc) -> dict:
    """Every field of deltagen_five_axis_geometry for a MachineDescription, read through its
    one declaration (model.five_axis.FIVE_AXIS_PARAMETERS): what the compiled core passes,
    and what `deltagen export` writes into its example."""
    return struct_values(FIVE_AXIS_PARAMETERS, desc)


class CompiledFiveAxis(CompiledCore):
    """Batched calls into the C core; arrays are (N, w) C-contiguous float64."""

    def __init__(self, desc, threads=None):
        super().__init__(MODULE, "deltagen_five_axis", STRUCT, FIVE_AXIS_PARAMETERS, desc, threads)
        # this machine's functions (deltagen_five_axis_<layout>_<rotary>_<quantity>) by
        # quantity, with their ports (generated/five_axis_kinematics.kernels.json)
        config = f"{desc.config}_"
        self._kernels = {
            name[len(config) :]: entry
            for name, entry in self._kernels.items()
            if name.startswith(config)
        }

    def single(self, quantity):
        """A lean function for one pose (native.lean): fk takes a joint row (5), ik the tool
        tip (3), the tool axis (3) and the previous joints (5); None from it when the general
        path must answer (other inputs, or a status other than OK)."""
        return self._single(quantity)

    def fk(self, j):
        return self._run("fk", [j])

    def ik(self, p, d, j_prev):
        return self._run("ik", [p, d, j_prev])

    def ik_all(self, p, d, j_prev):
        """Both branches (N, 2, 5), their within-travel flags (N, 2) and the status."""
        j, valid, status = self._run("ik_all", [p, d, j_prev])
        return j, valid.astype(bool), status
