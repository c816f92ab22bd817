"""The compiled 5-axis machine core (generated/five_axis_kinematics.c) via cffi: one module
for every machine; the description's layout and rotary pair choose the functions."""

from __future__ import annotations

from deltagen.model.five_axis import FIVE_AXIS_PARAMETERS
from deltagen.model.parameters import struct_values
from deltagen.native.build import load
from deltagen.native.lean import single_call
from deltagen.native.manifest import (
    fill_struct,
    kernels,
    output_widths,
    point_shape,
    reshape_outputs,
)
from deltagen.native.parallel import run_batch

MODULE = "five_axis_kinematics"  # generated/five_axis_kinematics.{c,h,cdef.h,kernels.json}
STRUCT = "deltagen_five_axis_geometry"


def geometry_struct(desc) -> dict:
    """Every field of deltagen_five_axis_geometry for a MachineDescription, read through its
    one declaration (model.five_axis.FIVE_AXIS_PARAMETERS): what the compiled core passes,
    and what `deltagen export` writes into its example."""
    return struct_values(FIVE_AXIS_PARAMETERS, desc)


class CompiledFiveAxis:
    """Batched calls into the C core; arrays are (N, w) C-contiguous float64."""

    def __init__(self, desc, threads=None):
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        module = load(MODULE, "deltagen_five_axis")
        self._ffi, self._lib = module.ffi, module.lib
        self._geometry = fill_struct(self._ffi, STRUCT, FIVE_AXIS_PARAMETERS, desc)
        # this machine's functions (deltagen_five_axis_<layout>_<rotary>_<quantity>) by
        # quantity, with their ports (generated/five_axis_kinematics.kernels.json)
        config = f"{desc.config}_"
        self._kernels = {
            name[len(config) :]: entry
            for name, entry in kernels(MODULE).items()
            if name.startswith(config)
        }

    def _fn(self, quantity):
        return getattr(self._lib, self._kernels[quantity]["function"])

    def single(self, quantity):
        """A lean function for one pose (native.lean): fk takes a joint row (5), ik the tool
        tip (3), the tool axis (3) and the previous joints (5); None from it when the general
        path must answer (other inputs, or a status other than OK)."""
        entry = self._kernels[quantity]
        rows = [port["width"] for port in entry["inputs"]]
        outputs = [(point_shape(port), port["ctype"]) for port in entry["outputs"]]
        return single_call(self._ffi, self._fn(quantity), (self._geometry, 1), rows, outputs)

    def _run(self, quantity, inputs):
        """fn(geometry, rows, *inputs, *outputs, status) over the batch, split into row chunks
        across threads (native.parallel); the outputs' widths are the manifest's, a matrix
        output reshaped to (N, rows, columns)."""
        entry = self._kernels[quantity]
        *outs, status = run_batch(
            self._ffi,
            self._fn(quantity),
            self._geometry,
            inputs,
            output_widths(entry),
            self.threads,
        )
        return (*reshape_outputs(entry, outs), status)

    def fk(self, j):
        return self._run("fk", [j])

    def ik(self, p, d, j_prev):
        return self._run("ik", [p, d, j_prev])

    def ik_all(self, p, d, j_prev):
        """Both branches (N, 2, 5), their within-travel flags (N, 2) and the status."""
        j, valid, status = self._run("ik_all", [p, d, j_prev])
        return j, valid.astype(bool), status
