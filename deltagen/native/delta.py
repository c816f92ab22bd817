"""The compiled backend: the generated C core (generated/delta_kinematics.c) via cffi."""

from __future__ import annotations

import numpy as np

from deltagen.model.delta import DELTA_PARAMETERS
from deltagen.model.parameters import struct_values
from deltagen.native.core import CompiledCore

MODULE = "delta_kinematics"  # generated/delta_kinematics.{c,h,cdef.h,kernels.json}
STRUCT = "deltagen_delta_geometry"


def geometry_struct(g) -> dict:
    """The fields of the C parameter struct (deltagen_delta_geometry) for a DeltaGeometry,
    read through its one declaration (model.delta.DELTA_PARAMETERS): what the compiled core
    passes, and what `deltagen export` writes into its example. Without inertia the
    dynamics fields are left out (zero): the API raises first."""
    return struct_values(DELTA_PARAMETERS, g)


class CompiledDelta(CompiledCore):
    """Batched calls into the C core; arrays are (N, 3|4) C-contiguous float64."""

    def __init__(self, geometry, threads=None):
        super().__init__(MODULE, "deltagen_delta", STRUCT, DELTA_PARAMETERS, geometry, threads)
        # encoder offsets (an asymmetric robot as built): the kernels take geometric crank
        # angles q + q_offset; None when there are none (no copies)
        self._offset = np.array(geometry.q_offset) if any(geometry.q_offset) else None

    def _to_crank(self, q):
        """Measured angles (N, 3|4) -> the kernels' geometric crank angles."""
        if self._offset is None:
            return q
        out = q.copy()
        out[:, :3] += self._offset
        return out

    def _from_crank(self, q):
        """The kernels' crank angles -> measured angles, wrapped to (-pi, pi] (in place)."""
        if self._offset is not None:
            q[:, :3] = np.pi - np.mod(np.pi - (q[:, :3] - self._offset), 2.0 * np.pi)
        return q

    #: the kernels with a single-pose path (their ports: the manifest)
    _SINGLE = (
        "fk",
        "ik",
        "fk_vel",
        "fk_acc",
        "jacobian",
        "inverse_dynamics",
        "inverse_dynamics_simplified",
    )

    def single(self, name):
        """A lean function for one pose of ``name`` (one of _SINGLE), native.lean: its
        inputs as what inputs.plain_row(x, 3) accepts (a (3,) float64 array, or a
        list/tuple of 3 Python floats/ints; the dynamics' payload a Python float or int
        >= 0) in, the result (a fresh array, or a tuple of them) out -- or None when the
        general path must handle the call: other inputs, whose checks it makes, or a status
        other than OK (INVALID input, a singular or unreachable pose: the general path
        reports it, or returns fk's and ik's singular but finite poses). The kernel's
        status is OK only when every output is finite (deltagen/status.py), so no check is
        repeated here. Same C function on the same numbers as the batch path: the same bits."""
        if self._offset is not None:  # the general path applies the encoder offsets
            return None
        if name not in self._SINGLE:
            raise KeyError(name)
        inputs = self._kernels[name]["inputs"]
        rows = [3 if port["width"] == "axes" else "scalar" for port in inputs]
        return self._single(name, rows, leading=(3,))

    def _run(self, name, inputs, axes=None):
        """<prefix>_<name>(geometry, rows, axes, *inputs, *outputs, status) over the batch
        (CompiledCore._run), axes the inputs' row length (3 or 4)."""
        return super()._run(name, inputs, inputs[0].shape[1])

    def fk(self, q):
        return self._run("fk", [self._to_crank(q)])

    def fk_vel(self, q, qd):
        return self._run("fk_vel", [self._to_crank(q), qd])

    def fk_acc(self, q, qd, qdd):
        return self._run("fk_acc", [self._to_crank(q), qd, qdd])

    def jacobian(self, q):
        return self._run("jacobian", [self._to_crank(q)])

    def ik(self, p):
        q, status = self._run("ik", [p])
        return self._from_crank(q), status

    def ik_vel(self, p, pd):
        q, qd, status = self._run("ik_vel", [p, pd])
        return self._from_crank(q), qd, status

    def ik_acc(self, p, pd, pdd):
        q, qd, qdd, status = self._run("ik_acc", [p, pd, pdd])
        return self._from_crank(q), qd, qdd, status

    def fk_param_jacobian(self, q):
        """p (N, 3) and dp/d(chain parameters) (N, 3, 15): columns r_i, l_a,i, l_b,i,
        theta_i, q_i for i = 1..3 (generated/delta_kinematics.h; the C stores the 15
        parameters' rows of 3, hence the transpose)."""
        p, G, status = self._run("fk_param_jacobian", [self._to_crank(q)])
        return p, G.reshape(-1, 15, 3).transpose(0, 2, 1), status

    def inverse_dynamics(self, q, qd, qdd, payload, model="exact"):
        """tau (N, axes) and status; ``payload`` is (N,) [kg], C-contiguous float64."""
        name = "inverse_dynamics" if model == "exact" else "inverse_dynamics_simplified"
        return self._run(name, [self._to_crank(q), qd, qdd, payload])
