"""The compiled 5-axis machine core (generated/five_axis_kinematics.c) via cffi: one module
for every machine; the description's layout and rotary pair choose the functions."""

from __future__ import annotations

import numpy as np

from deltagen.native.build import load
from deltagen.native.lean import single_call
from deltagen.native.parallel import check_rc, run_batch, run_rows


def geometry_struct(desc) -> dict:
    """Every field of deltagen_five_axis_geometry for a MachineDescription: what the
    compiled core passes, and what `deltagen export` writes into its example."""
    return {
        "c_pivot": list(desc.c_pivot),
        "tilt_pivot": list(desc.tilt_pivot),
        "head_pivot": list(desc.head_pivot),
        "spindle_offset": list(desc.spindle_offset),
        "tool_length": desc.tool_length,
        "singular_tol": desc.singular_tol,
        "tilt_min": desc.tilt_limits[0],
        "tilt_max": desc.tilt_limits[1],
    }


class CompiledFiveAxis:
    """Batched calls into the C core; arrays are (N, w) C-contiguous float64."""

    def __init__(self, desc, threads=None):
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        module = load("five_axis_kinematics", "deltagen_five_axis")
        self._ffi, self._lib = module.ffi, module.lib
        self._geometry = self._ffi.new("deltagen_five_axis_geometry *", geometry_struct(desc))
        self._name = f"deltagen_five_axis_{desc.config}"

    def _fn(self, quantity):
        return getattr(self._lib, f"{self._name}_{quantity}")

    def single(self, quantity):
        """A lean function for one pose (native.lean): fk takes a joint row (5), ik the tool
        tip (3), the tool axis (3) and the previous joints (5); None from it when the general
        path must answer (other inputs, or a status other than OK)."""
        if quantity == "fk":
            rows, outputs = [5], [((3,), "double"), ((3,), "double")]
        else:
            rows, outputs = [3, 3, 5], [((5,), "double")]
        return single_call(self._ffi, self._fn(quantity), (self._geometry, 1), rows, outputs)

    def _run(self, quantity, inputs, widths):
        """fn(geometry, rows, *inputs, *outputs, status) over the batch, split into row chunks
        across threads (native.parallel)."""
        return run_batch(
            self._ffi, self._fn(quantity), self._geometry, inputs, widths, self.threads
        )

    def fk(self, j):
        return self._run("fk", [j], (3, 3))

    def ik(self, p, d, j_prev):
        return self._run("ik", [p, d, j_prev], (5,))

    def ik_all(self, p, d, j_prev):
        """Both branches (N, 2, 5), their within-travel flags (N, 2) and the status."""
        fn = self._fn("ik_all")
        n = p.shape[0]
        fb, geometry = self._ffi.from_buffer, self._geometry
        j = np.empty((n, 10))
        valid = np.empty((n, 2), dtype=np.uint8)
        status = np.empty(n, dtype=np.int8)

        def call(lo, hi):
            return fn(
                geometry,
                hi - lo,
                *(fb("double[]", a[lo:hi]) for a in (p, d, j_prev)),
                fb("double[]", j[lo:hi], require_writable=True),
                fb("uint8_t[]", valid[lo:hi], require_writable=True),
                fb("int8_t[]", status[lo:hi], require_writable=True),
            )

        check_rc(run_rows(n, self.threads, call))
        return j.reshape(-1, 2, 5), valid.astype(bool), status
