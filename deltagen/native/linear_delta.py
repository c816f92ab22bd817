"""The compiled backends of the linear delta and the tripod: generated/
linear_delta_kinematics.c and tripod_kinematics.c via cffi (rows of 3, no axes argument)."""

from __future__ import annotations

from deltagen.native.build import load
from deltagen.native.lean import single_call
from deltagen.native.parallel import run_batch


def linear_delta_struct(g) -> dict:
    """The fields of deltagen_linear_delta_geometry for a LinearDeltaGeometry."""
    return {
        "tower_x": list(g.tower_x),
        "tower_y": list(g.tower_y),
        "arm_length": list(g.arm_length),
        "singular_tol": g.singular_tol,
    }


def tripod_struct(g) -> dict:
    """The fields of deltagen_tripod_geometry for a TripodGeometry."""
    return {
        "b_x": g.b_x,
        "c_x": g.c_x,
        "c_y": g.c_y,
        "side": g.side_sign,
        "singular_tol": g.singular_tol,
    }


class CompiledTrilateration:
    """Batched calls into one of the two cores; arrays are (N, 3) C-contiguous float64."""

    #: per machine: module file stem, C prefix, struct fill
    MODULES = {
        "linear_delta": ("linear_delta_kinematics", "deltagen_linear_delta", linear_delta_struct),
        "tripod": ("tripod_kinematics", "deltagen_tripod", tripod_struct),
    }
    #: the single-pose functions: inputs, outputs, output shape
    _SINGLE = {
        "fk": (1, 1, (3,)),
        "ik": (1, 1, (3,)),
        "fk_vel": (2, 2, (3,)),
        "fk_acc": (3, 3, (3,)),
        "jacobian": (1, 1, (3, 3)),
        "ik_vel": (2, 2, (3,)),
        "ik_acc": (3, 3, (3,)),
    }

    def __init__(self, kind: str, geometry, threads=None):
        self.threads = threads
        base, prefix, fill = self.MODULES[kind]
        module = load(base, prefix)
        self._ffi, self._lib, self._prefix = module.ffi, module.lib, prefix
        self._geometry = self._ffi.new(f"{prefix}_geometry *", fill(geometry))

    def _fn(self, name):
        return getattr(self._lib, f"{self._prefix}_{name}")

    def single(self, name):
        """A lean function for one pose (native.lean), or None where the general path must
        answer (as CompiledDelta.single)."""
        n_in, n_out, shape = self._SINGLE[name]
        return single_call(
            self._ffi, self._fn(name), (self._geometry, 1), [3] * n_in, [(shape, "double")] * n_out
        )

    def run(self, name, inputs, widths):
        """fn(geometry, rows, *inputs, *outputs, status) split across threads."""
        return run_batch(self._ffi, self._fn(name), self._geometry, inputs, widths, self.threads)

    def fk(self, q):
        return self.run("fk", [q], (3,))

    def fk_vel(self, q, qd):
        return self.run("fk_vel", [q, qd], (3, 3))

    def fk_acc(self, q, qd, qdd):
        return self.run("fk_acc", [q, qd, qdd], (3, 3, 3))

    def jacobian(self, q):
        J, status = self.run("jacobian", [q], (9,))
        return J.reshape(-1, 3, 3), status

    def ik(self, p):
        return self.run("ik", [p], (3,))

    def ik_vel(self, p, pd):
        return self.run("ik_vel", [p, pd], (3, 3))

    def ik_acc(self, p, pd, pdd):
        return self.run("ik_acc", [p, pd, pdd], (3, 3, 3))
