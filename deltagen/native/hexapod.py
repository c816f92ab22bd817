"""The compiled hexapod core: generated/hexapod_kinematics.c (ik, jacobian, joint_angles and
the fk wrapper) with the runtime's damped Newton (codegen/runtime/deltagen_hexapod_fk.c),
via cffi. Arrays are C-contiguous float64: poses (N, 16), leg lengths (N, 6)."""

from __future__ import annotations

import numpy as np

from deltagen.native.build import load
from deltagen.native.parallel import check_rc, run_batch, run_rows


def geometry_struct(g) -> dict:
    """The fields of deltagen_hexapod_geometry for a HexapodGeometry (every field): what the
    compiled core passes, and what `deltagen export` writes into its example."""
    return {
        "base_joints": [x for point in g.base_joints for x in point],
        "platform_joints": [x for point in g.platform_joints for x in point],
        "base_axes": [x for point in g.base_axes for x in point],
        "platform_axes": [x for point in g.platform_axes for x in point],
        "scale": g.size,
        "singular_tol": g.singular_tol,
    }


class CompiledHexapod:
    """Batched calls into the hexapod's C core."""

    def __init__(self, geometry, threads=None):
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        module = load("hexapod_kinematics", "deltagen_hexapod")
        self._ffi, self._lib = module.ffi, module.lib
        self._geometry = self._ffi.new("deltagen_hexapod_geometry *", geometry_struct(geometry))

    def _run(self, fn, pose, widths):
        return run_batch(self._ffi, fn, self._geometry, [pose], widths, self.threads)

    def ik(self, pose):
        """Leg lengths (N, 6) and status of poses (N, 16)."""
        return self._run(self._lib.deltagen_hexapod_ik, pose, (6,))

    def jacobian(self, pose):
        """Leg lengths (N, 6), J (N, 6, 6) and status."""
        lengths, J, status = self._run(self._lib.deltagen_hexapod_jacobian, pose, (6, 36))
        return lengths, J.reshape(-1, 6, 6), status

    def joint_angles(self, pose):
        """Base and platform joint angles (N, 12) [rad] and status."""
        return self._run(self._lib.deltagen_hexapod_joint_angles, pose, (12,))

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
