"""The compiled backend: the generated C core (generated/delta_kinematics.c) via cffi."""

from __future__ import annotations

import math

import numpy as np

from deltagen.native.build import load
from deltagen.native.lean import single_call
from deltagen.native.parallel import run_batch


def geometry_struct(g) -> dict:
    """The fields of the C parameter struct (deltagen_delta_geometry) for a DeltaGeometry:
    what the compiled core passes, and what `deltagen export` writes into its example.
    Without inertia the dynamics fields are left out (zero): the API raises first."""
    inertia = g.inertia
    dynamics = (
        {
            "I_a": inertia.I_a,
            "m_a": inertia.m_a,
            "r_ca": inertia.r_ca,
            "m_b": inertia.m_b,
            "m_p": inertia.m_p,
            "gravity": list(inertia.gravity),
            "I_4": inertia.I_4,
        }
        if inertia is not None
        else {}
    )
    return {
        "r_a": g.r_a,
        "r_b": g.r_b,
        "l_a": g.l_a,
        "l_b": g.l_b,
        "chain_r": list(g.chain_r),
        "chain_l_a": list(g.chain("l_a")),
        "chain_l_b": list(g.chain("l_b")),
        "cos_theta": [math.cos(t) for t in g.theta],
        "sin_theta": [math.sin(t) for t in g.theta],
        "singular_tol": g.singular_tol,
        **dynamics,
    }


class CompiledDelta:
    """Batched calls into the C core; arrays are (N, 3|4) C-contiguous float64."""

    def __init__(self, geometry, threads=None):
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        module = load("delta_kinematics", "deltagen_delta")
        self._ffi, self._lib = module.ffi, module.lib
        self._geometry = self._ffi.new("deltagen_delta_geometry *", geometry_struct(geometry))
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

    #: the single-pose functions: C function, inputs, outputs, output shape
    _SINGLE = {
        "fk": ("deltagen_delta_fk", 1, 1, (3,)),
        "ik": ("deltagen_delta_ik", 1, 1, (3,)),
        "fk_vel": ("deltagen_delta_fk_vel", 2, 2, (3,)),
        "fk_acc": ("deltagen_delta_fk_acc", 3, 3, (3,)),
        "jacobian": ("deltagen_delta_jacobian", 1, 1, (3, 3)),
        "inverse_dynamics": ("deltagen_delta_inverse_dynamics", 4, 1, (3,)),
        "inverse_dynamics_simplified": ("deltagen_delta_inverse_dynamics_simplified", 4, 1, (3,)),
    }

    def single(self, name):
        """A lean function for one pose of ``name`` (a key of _SINGLE), native.lean: its
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
        c_name, n_in, n_out, shape = self._SINGLE[name]
        rows = [3, 3, 3, "scalar"][:n_in]
        outputs = [(shape, "double")] * n_out
        return single_call(
            self._ffi, getattr(self._lib, c_name), (self._geometry, 1, 3), rows, outputs
        )

    def _run(self, fn, inputs, n_out, out_width=None, widths=None):
        """fn(geometry, rows, axes, *inputs, *outputs, status) over the batch, split into row
        chunks across threads (native.parallel); inputs are (N, ...) C-contiguous."""
        axes = inputs[0].shape[1]
        widths = [w or axes for w in (widths or (out_width,) * n_out)]
        return run_batch(
            self._ffi, fn, self._geometry, inputs, widths, self.threads, leading=(axes,)
        )

    def fk(self, q):
        return self._run(self._lib.deltagen_delta_fk, [self._to_crank(q)], 1)

    def fk_vel(self, q, qd):
        return self._run(self._lib.deltagen_delta_fk_vel, [self._to_crank(q), qd], 2)

    def fk_acc(self, q, qd, qdd):
        return self._run(self._lib.deltagen_delta_fk_acc, [self._to_crank(q), qd, qdd], 3)

    def jacobian(self, q):
        J, status = self._run(
            self._lib.deltagen_delta_jacobian, [self._to_crank(q)], 1, out_width=9
        )
        return J.reshape(-1, 3, 3), status

    def ik(self, p):
        q, status = self._run(self._lib.deltagen_delta_ik, [p], 1)
        return self._from_crank(q), status

    def ik_vel(self, p, pd):
        q, qd, status = self._run(self._lib.deltagen_delta_ik_vel, [p, pd], 2)
        return self._from_crank(q), qd, status

    def ik_acc(self, p, pd, pdd):
        q, qd, qdd, status = self._run(self._lib.deltagen_delta_ik_acc, [p, pd, pdd], 3)
        return self._from_crank(q), qd, qdd, status

    def fk_param_jacobian(self, q):
        """p (N, 3) and dp/d(chain parameters) (N, 3, 15): columns r_i, l_a,i, l_b,i,
        theta_i, q_i for i = 1..3 (generated/delta_kinematics.h)."""
        p, G, status = self._run(
            self._lib.deltagen_delta_fk_param_jacobian,
            [self._to_crank(q)],
            2,
            out_width=None,
            widths=(None, 45),
        )
        return p, G.reshape(-1, 15, 3).transpose(0, 2, 1), status

    def inverse_dynamics(self, q, qd, qdd, payload, model="exact"):
        """tau (N, axes) and status; ``payload`` is (N,) [kg], C-contiguous float64."""
        fn = (
            self._lib.deltagen_delta_inverse_dynamics
            if model == "exact"
            else self._lib.deltagen_delta_inverse_dynamics_simplified
        )
        return self._run(fn, [self._to_crank(q), qd, qdd, payload], 1)
