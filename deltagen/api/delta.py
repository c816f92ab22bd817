"""DeltaRobot: the Python API of the delta kinematics (docs/architecture.md traces fk through it).

Every method takes one pose (shape (3,) or (4,) with the fourth axis) or a batch with any
leading dimensions (..., 3|4), and returns arrays of the same leading shape.
``errors="raise"`` (default) raises on any failing row, naming the rows;
``errors="nan"`` returns NaN there plus a boolean ``valid`` mask as the last result.

Position-level calls (fk, ik) also return poses that are singular but well defined
(det J_p ~ 0 in fk, a J_q entry ~ 0 in ik: the workspace boundary); calls that need a
Jacobian inverse (fk_vel, fk_acc, jacobian, ik_vel, ik_acc) treat them as errors.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.api.base import ReferenceCore, RobotFamilyWithDefault
from deltagen.api.hints import Backend, Errors, PathLike, Result
from deltagen.api.validity import invalid_message
from deltagen.errors import (
    GeometryError,
    SingularityError,
    UnreachableError,
    rows_text,
)
from deltagen.inputs import InputError, as_float_array, broadcast_rows, check_errors_mode
from deltagen.model.delta import DeltaGeometry, DeltaInertia

_MODELS = ("exact", "simplified")
__all__ = ["DeltaInertia", "DeltaRobot"]
#: the reference functions a DeltaRobot calls (reference/delta.py)
_CALLS = ("fk", "fk_vel", "fk_acc", "jacobian", "ik", "ik_vel", "ik_acc")


class DeltaRobot(RobotFamilyWithDefault):
    """Rotary delta robot of the 2008 report with an optional independent fourth axis.

    Parameters are in metres and radians: r_a (base radius to the drive axes), r_b
    (platform radius), l_a (crank), l_b (parallelogram rod), theta (the three drives'
    angular positions about the base z axis). The base frame O lies in the plane of the
    drive axes with z up, so the platform works at negative z; q_i > 0 turns a crank down.
    """

    _core: Any  # CompiledDelta or a ReferenceCore: the same call signatures
    _model_class = DeltaGeometry

    def __init__(
        self,
        r_a: float,
        r_b: float,
        l_a: float,
        l_b: float,
        theta: tuple[float, ...] = (0.0, 2 * math.pi / 3, 4 * math.pi / 3),
        *,
        name: str = "delta",
        singular_tol: float = st.SINGULAR_TOL,
        inertia: DeltaInertia | None = None,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> None:
        self.geometry = DeltaGeometry(
            r_a=r_a,
            r_b=r_b,
            l_a=l_a,
            l_b=l_b,
            theta=theta,
            name=name,
            singular_tol=singular_tol,
            inertia=inertia,
        )
        self._init_backend(backend, threads)

    def _init_backend(self, backend, threads=None):
        threads = self._check_backend(backend, threads)
        if backend == "compiled":
            from deltagen.native.delta import CompiledDelta

            self._core = CompiledDelta(self.geometry, threads)
            # lean paths for one pose (same C function, same results; native.delta.single)
            single = self._core.single
            self._fk_single, self._ik_single = single("fk"), single("ik")
            self._fk_vel_single, self._fk_acc_single = single("fk_vel"), single("fk_acc")
            self._jacobian_single = single("jacobian")
            self._id_single = {
                "exact": single("inverse_dynamics"),
                "simplified": single("inverse_dynamics_simplified"),
            }
        else:
            from deltagen.reference import delta as reference

            g = self.geometry
            self._core = ReferenceCore(reference, (g,), _CALLS)
            self._core.inverse_dynamics = lambda q, qd, qdd, payload, model="exact": (
                reference.inverse_dynamics(g, g.inertia, q, qd, qdd, payload, model=model)
            )
            self._fk_single = self._ik_single = None
            self._fk_vel_single = self._fk_acc_single = self._jacobian_single = None
            self._id_single = None

    @classmethod
    def from_geometry(
        cls, geometry: DeltaGeometry, backend: Backend = "compiled", *, threads: int | None = None
    ) -> DeltaRobot:
        return cls._from_model(geometry, backend, threads)

    @classmethod
    def from_klipper(
        cls, path: PathLike, backend: Backend = "compiled", *, threads: int | None = None
    ) -> DeltaRobot:
        """The rotary delta of a Klipper printer.cfg ([printer] kinematics: rotary_delta),
        in deltagen's conventions: metres, q positive down (Klipper's arm angle is positive
        up: q = -a), base frame in the shoulder plane (Klipper's z is above the bed:
        z = z_klipper - shoulder_height). deltagen.model.klipper.read_klipper gives the
        frame offset and the endstop heights too."""
        from deltagen.model.klipper import read_klipper

        return cls.from_geometry(read_klipper(path).geometry, backend, threads=threads)

    def with_inertia(self, inertia: DeltaInertia | None) -> DeltaRobot:
        """The same robot with other inertial parameters (same backend)."""
        from dataclasses import replace

        return type(self).from_geometry(
            replace(self.geometry, inertia=inertia), self.backend, threads=self.threads
        )

    def __repr__(self) -> str:
        g = self.geometry
        deg = ", ".join(f"{math.degrees(t):g}" for t in g.theta)
        return (
            f"DeltaRobot(r_a={g.r_a!r}, r_b={g.r_b!r}, l_a={g.l_a!r}, l_b={g.l_b!r}, "
            f"theta_deg=({deg}), backend={self.backend!r})"
        )

    # -- the batched quantities -------------------------------------------------------

    def fk(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Platform position p (..., 3|4) of crank angles q (..., 3|4), eqs. (2)-(27), (43)."""
        if type(errors) is str and errors == "raise" and self._fk_single is not None:
            p = self._fk_single(q)  # one pose: the lean path (None: the general path)
            if p is not None:
                return p
        lead, _, (qf,) = self._prepare(errors, q=q)
        p, status = self._core.fk(qf)
        return self._finish(errors, lead, status, [p], ("q",), [qf], allow_singular=True)

    def fk_vel(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """(p, pdot) from (q, qdot), eq. (30)."""
        if type(errors) is str and errors == "raise" and self._fk_vel_single is not None:
            out = self._fk_vel_single(q, qd)
            if out is not None:
                return out
        lead, _, (qf, qdf) = self._prepare(errors, q=q, qd=qd)
        p, pd, status = self._core.fk_vel(qf, qdf)
        return self._finish(errors, lead, status, [p, pd], ("q", "qd"), [qf, qdf])

    def fk_acc(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """(p, pdot, pddot) from (q, qdot, qddot), eqs. (30), (38)."""
        if type(errors) is str and errors == "raise" and self._fk_acc_single is not None:
            out = self._fk_acc_single(q, qd, qdd)
            if out is not None:
                return out
        lead, _, (qf, qdf, qddf) = self._prepare(errors, q=q, qd=qd, qdd=qdd)
        p, pd, pdd, status = self._core.fk_acc(qf, qdf, qddf)
        return self._finish(errors, lead, status, [p, pd, pdd], ("q", "qd", "qdd"), [qf, qdf, qddf])

    def jacobian(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """J = J_p^-1 J_q (..., 3, 3) with pdot = J @ qdot (first three axes)."""
        if type(errors) is str and errors == "raise" and self._jacobian_single is not None:
            J = self._jacobian_single(q)
            if J is not None:
                return J
        lead, _, (qf,) = self._prepare(errors, q=q)
        J, status = self._core.jacobian(qf)
        return self._finish(errors, lead, status, [J], ("q",), [qf], trailing=[(3, 3)])

    def ik(self, p: ArrayLike, errors: Errors = "raise") -> Result:
        """Crank angles q (..., 3|4) in (-pi, pi] of platform positions p, elbow-out branch."""
        if type(errors) is str and errors == "raise" and self._ik_single is not None:
            q = self._ik_single(p)
            if q is not None:
                return q
        lead, _, (pf,) = self._prepare(errors, p=p)
        q, status = self._core.ik(pf)
        return self._finish(errors, lead, status, [q], ("p",), [pf], allow_singular=True)

    def ik_vel(self, p: ArrayLike, pd: ArrayLike, errors: Errors = "raise") -> Result:
        """(q, qdot) from (p, pdot): inverse kinematics, then qdot = J_q^-1 J_p pdot
        (eq. (30); J_q is diagonal). Only a singular J_q (crank and rod in line) is an
        error here: at a J_p singularity qdot is still defined."""
        return self._inverse_rates(errors, dict(p=p, pd=pd))

    def ik_acc(
        self, p: ArrayLike, pd: ArrayLike, pdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """(q, qdot, qddot) from (p, pdot, pddot): qddot from the second time derivative
        of constraint (1), eqs. (36)-(39), solved for qddot (J_q diagonal)."""
        return self._inverse_rates(errors, dict(p=p, pd=pd, pdd=pdd))

    def workspace(self, step: float | None = None, **options: Any) -> Any:
        """The usable workspace on a voxel grid, its dexterity maps and the largest
        inscribed cylinder and box: deltagen.api.workspace.delta_workspace (options there)."""
        from deltagen.api.workspace import delta_workspace

        return delta_workspace(self, step, **options)

    def calibrate(
        self,
        q_measured: ArrayLike,
        p_measured: ArrayLike,
        params: tuple[str, ...] | str = ("r_a", "l_a", "l_b", "theta", "q_offset"),
        **options: Any,
    ) -> Any:
        """Identify geometry deviations of the robot as built from measured pairs: q (N, 3)
        as the encoders read them [rad], p (N, 3) measured in the base frame [m]. ``params``:
        families r_a, r_b, l_a, l_b, theta, q_offset (per chain, all three) or single
        entries like "l_a[0]". Levenberg-Marquardt with the generated C Jacobian of fk with
        respect to the parameters, every parameter bounded around its nominal value; see
        deltagen.solve.calibration (options: sigma, max_length_deviation,
        max_angle_deviation, rcond, max_iterations, tol). Returns a CalibrationResult: the
        calibrated geometry and ``robot`` (same backend), values, uncertainty, residual RMS
        before/after, the noise test, singular values, the parameters the data cannot place,
        and ``valid`` / ``problems`` / ``hints``: use the geometry only when ``valid``."""
        from dataclasses import replace

        from deltagen.solve.calibration import calibrate

        result = calibrate(self.geometry, q_measured, p_measured, params, **options)
        robot = type(self).from_geometry(result.geometry, self.backend, threads=self.threads)
        return replace(result, robot=robot)

    # -- dynamics -----------------------------------------------------------------------

    @property
    def inertia(self) -> DeltaInertia | None:
        return self.geometry.inertia

    def inverse_dynamics(
        self,
        q: ArrayLike,
        qd: ArrayLike,
        qdd: ArrayLike,
        payload: ArrayLike = 0.0,
        model: str = "exact",
        errors: Errors = "raise",
    ) -> Result:
        """Motor torques tau (..., 3|4) [N m] for crank motion (q, qdot, qddot): the
        feed-forward torques of the report's Figure 2. ``payload`` [kg] rides on the
        platform: a number or an array broadcasting with the leading dimensions (it may
        change along a trajectory). ``model``: "exact" (rigid bodies, rods with their own
        rotation) or "simplified" (each rod pair's mass split between crank tip and
        platform). Column 4: the fourth axis, I_4 qddot_4. Singular poses (det J_p ~ 0)
        have no torques (SingularityError, or NaN with errors="nan")."""
        self._check_dynamics(model)
        lean = self._id_single[model] if self._id_single is not None else None
        if type(errors) is str and errors == "raise" and lean is not None:
            tau = lean(q, qd, qdd, payload)
            if tau is not None:
                return tau
        check_errors_mode(errors)
        lead, _, (qf, qdf, qddf) = broadcast_rows(dict(q=q, qd=qd, qdd=qdd))
        load = self._payload_column(payload, lead)
        tau, status = self._core.inverse_dynamics(qf, qdf, qddf, load, model)
        return self._finish(
            errors, lead, status, [tau], ("q", "qd", "qdd", "payload"), [qf, qdf, qddf, load]
        )

    def inverse_dynamics_from_platform(
        self,
        p: ArrayLike,
        pd: ArrayLike,
        pdd: ArrayLike,
        payload: ArrayLike = 0.0,
        model: str = "exact",
        errors: Errors = "raise",
    ) -> Result:
        """Motor torques tau (..., 3|4) for platform motion (p, pdot, pddot): ik_acc, then
        inverse_dynamics (the report's Figure 1: the inverse kinematic model feeds the
        dynamic model). In NaN mode rows failing either step are NaN and not valid."""
        self._check_dynamics(model)
        check_errors_mode(errors)
        if errors == "raise":
            q, qd, qdd = self.ik_acc(p, pd, pdd)
            return self.inverse_dynamics(q, qd, qdd, payload, model)
        q, qd, qdd, ok = self.ik_acc(p, pd, pdd, errors="nan")
        tau, valid = self.inverse_dynamics(q, qd, qdd, payload, model, errors="nan")
        return tau, valid & ok

    def _check_dynamics(self, model):
        if model not in _MODELS:
            raise InputError(f"model must be one of {_MODELS}, got {model!r}")
        if not self.geometry.symmetric:
            raise GeometryError(
                "the dynamics are derived for the symmetric robot: this one has per-chain "
                "lengths or encoder offsets (an asymmetric robot: kinematics only)"
            )
        if self.geometry.inertia is None:
            raise GeometryError(
                "this robot has no inertial parameters: give DeltaRobot(..., "
                "inertia=DeltaInertia(...)) or an [inertia] table in its robot file"
            )

    @staticmethod
    def _payload_column(payload, lead):
        scalar = np.ndim(payload) == 0
        load = as_float_array(np.reshape(payload, (1,)) if scalar else payload, "payload")
        if scalar:
            load = load.reshape(())
        try:
            load = np.broadcast_to(load, lead)
        except ValueError:
            raise InputError(
                f"payload of shape {np.shape(payload)} does not broadcast to the leading "
                f"shape {lead} of q"
            ) from None
        negative = np.flatnonzero(load.reshape(-1) < 0.0)
        if negative.size:
            raise InputError(
                f"payload must be non-negative [kg], negative in rows {rows_text(negative)}"
            )
        return np.ascontiguousarray(load.reshape(-1), dtype=np.float64)

    # -- helpers ------------------------------------------------------------------------

    def _prepare(self, errors, **arrays):
        check_errors_mode(errors)
        return broadcast_rows(arrays)

    @staticmethod
    def _raise(status, ok, names, inputs):
        bad = np.flatnonzero(~ok)
        invalid = bad[status[bad] == st.INVALID]
        if invalid.size:
            raise InputError(invalid_message(names, inputs, invalid), invalid)
        unreachable = bad[status[bad] == st.UNREACHABLE]
        if unreachable.size:
            what = (
                "a crank cannot reach the target, or only in the other assembly mode with the "
                "platform above the rods' sphere centres"
                if names[0] == "p"
                else "spheres do not meet"
            )
            raise UnreachableError(
                f"unreachable pose ({what}) in rows {rows_text(unreachable)}", unreachable
            )
        raise SingularityError(f"singular pose in rows {rows_text(bad)}", bad)

    def _inverse_rates(self, errors, arrays):
        """ik_vel / ik_acc: the kernels give q (kept where only J_q is singular) and the
        rates (NaN unless OK); here J_q singular rows are errors, as qdot is infinite."""
        lead, _, flat = self._prepare(errors, **arrays)
        if len(flat) == 2:
            *outs, status = self._core.ik_vel(*flat)
        else:
            *outs, status = self._core.ik_acc(*flat)
        return self._finish(errors, lead, status, outs, tuple(arrays), flat)
