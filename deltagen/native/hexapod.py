"""The compiled hexapod core: generated/hexapod_kinematics.c (ik, jacobian, joint_angles and
the fk wrapper) with the runtime's damped Newton (codegen/runtime/deltagen_hexapod_fk.c),
via cffi. Arrays are C-contiguous float64: poses (N, 16), leg lengths (N, 6)."""

from __future__ import annotations

import numpy as np

from deltagen.model.hexapod import HEXAPOD_PARAMETERS
from deltagen.model.parameters import struct_values
from deltagen.native.core import CompiledCore
from deltagen.native.parallel import check_rc, run_rows

MODULE = "hexapod_kinematics"  # generated/hexapod_kinematics.{c,h,cdef.h,kernels.json}
STRUCT = "deltagen_hexapod_geometry"


def geometry_struct(g) -> dict:
    """The fields of deltagen_hexapod_geometry for a HexapodGeometry (every field), read
    through its one declaration (model.hexapod.HEXAPOD_PARAMETERS): what the compiled core
    passes, and what `deltagen export` writes into its example."""
    return struct_values(HEXAPOD_PARAMETERS, g)


class CompiledHexapod(CompiledCore):
    """Batched calls into the hexapod's C core."""

    def __init__(self, geometry, threads=None):
        super().__init__(MODULE, "deltagen_hexapod", STRUCT, HEXAPOD_PARAMETERS, geometry, threads)

    def ik(self, pose):
        """Leg lengths (N, 6) and status of poses (N, 16)."""
        return self._run("ik", [pose])

    def jacobian(self, pose):
        """Leg lengths (N, 6), J (N, 6, 6) and status."""
        return self._run("jacobian", [pose])

    def joint_angles(self, pose):
        """Base and platform joint angles (N, 12) [rad] and status."""
        return self._run("joint_angles", [pose])

    def fk(self, lengths, guess, tol, damping, max_step, max_iter, warm_start=False):
        """Poses (N, 16), residuals (N,), iterations (N,) and status of leg lengths (N, 6)
        from start poses (N, 16), by the runtime's damped Newton; ``warm_start``: each point
        from the previous converged one (one call, no thread split: the points depend on
        each other)."""
        n = lengths.shape[0]
        fb = self._ffi.from_buffer
        options = self._ffi.new(
            "deltagen_hexapod_fk_options *",
            {
                "tol": tol,
                "damping": damping,
                "max_step": max_step,
                "max_iter": max_iter,
                "warm_start": int(warm_start),
            },
        )
        pose = np.empty((n, 16))
        residual = np.empty(n)
        iterations = np.empty(n, dtype=np.int32)
        status = np.empty(n, dtype=np.int8)

        def call(lo, hi):
            return self._lib.deltagen_hexapod_fk(
                self._geometry,
                hi - lo,
                options,
                fb("double[]", lengths[lo:hi]),
                fb("double[]", guess[lo:hi]),
                fb("double[]", pose[lo:hi], require_writable=True),
                fb("double[]", residual[lo:hi], require_writable=True),
                fb("int32_t[]", iterations[lo:hi], require_writable=True),
                fb("int8_t[]", status[lo:hi], require_writable=True),
            )

        check_rc(run_rows(n, 1 if warm_start else self.threads, call))
        return pose, residual, iterations, status
