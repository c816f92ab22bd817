"""The compiled backends of the linear delta and the tripod: generated/
linear_delta_kinematics.c and tripod_kinematics.c via cffi (rows of 3, no axes argument)."""

from __future__ import annotations

from deltagen.model.linear_delta import LINEAR_DELTA_PARAMETERS, TRIPOD_PARAMETERS
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


def linear_delta_struct(g) -> dict:
    """The fields of deltagen_linear_delta_geometry for a LinearDeltaGeometry (its one
    declaration: model.linear_delta.LINEAR_DELTA_PARAMETERS)."""
    return struct_values(LINEAR_DELTA_PARAMETERS, g)


def tripod_struct(g) -> dict:
    """The fields of deltagen_tripod_geometry for a TripodGeometry (its one declaration:
    model.linear_delta.TRIPOD_PARAMETERS)."""
    return struct_values(TRIPOD_PARAMETERS, g)


class CompiledTrilateration:
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
        self.threads = threads
        base, prefix, table = self.MODULES[kind]
        module = load(base, prefix)
        self._ffi, self._lib, self._prefix = module.ffi, module.lib, prefix
        self._kernels = kernels(base)  # ports and widths (generated/*.kernels.json)
        self._geometry = fill_struct(self._ffi, f"{prefix}_geometry", table, geometry)

    def _fn(self, name):
        return getattr(self._lib, self._kernels[name]["function"])

    def single(self, name):
        """A lean function for one pose (native.lean), or None where the general path must
        answer (as CompiledDelta.single); every kernel of the module has one (rows of 3)."""
        entry = self._kernels[name]
        rows = [port["width"] for port in entry["inputs"]]
        outputs = [(point_shape(port), port["ctype"]) for port in entry["outputs"]]
        return single_call(self._ffi, self._fn(name), (self._geometry, 1), rows, outputs)

    def run(self, name, inputs):
        """fn(geometry, rows, *inputs, *outputs, status) split across threads; the outputs'
        widths are the manifest's, a matrix output reshaped to (N, rows, columns)."""
        entry = self._kernels[name]
        *outs, status = run_batch(
            self._ffi, self._fn(name), self._geometry, inputs, output_widths(entry), self.threads
        )
        return (*reshape_outputs(entry, outs), status)

    def fk(self, q):
        return self.run("fk", [q])

    def fk_vel(self, q, qd):
        return self.run("fk_vel", [q, qd])

    def fk_acc(self, q, qd, qdd):
        return self.run("fk_acc", [q, qd, qdd])

    def jacobian(self, q):
        return self.run("jacobian", [q])

    def ik(self, p):
        return self.run("ik", [p])

    def ik_vel(self, p, pd):
        return self.run("ik_vel", [p, pd])

    def ik_acc(self, p, pd, pdd):
        return self.run("ik_acc", [p, pd, pdd])
