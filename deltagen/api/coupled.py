"""CoupledArm: a serial arm whose joints are coupled (URDF ``<mimic>``), in its independent
variables r (..., k).

Every quantity is the full chain's (a :class:`SerialRobot` of all n physical joints) at
q = E r + c, mapped back by the chain rule and virtual work (model/coupling.py):
J_r = J E, Jdot_r = Jdot(q, E rd) E, tau_r = E^T tau(q, E rd, E rdd), M_r = E^T M E,
g_r = E^T g. ``errors="nan"`` works as in SerialRobot (the full chain's mask, per row of r).
Inverse kinematics of a coupled chain is not offered yet (the closed forms and the numeric
solver work on free joints); ``ik`` raises saying so.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from deltagen.api.hints import Backend, BoolArray, Errors, FloatArray, PathLike, Result
from deltagen.api.serial import SerialRobot
from deltagen.inputs import InputError, as_float_array, check_errors_mode
from deltagen.model.coupling import Coupling


class CoupledArm:
    """A chain with couplings, in its k independent variables (module docstring)."""

    def __init__(self, full: SerialRobot, coupling: Coupling):
        if coupling.n != full.n:
            raise InputError(f"the coupling maps to {coupling.n} joints, the arm has {full.n}")
        self.full = full
        self.coupling = coupling

    @classmethod
    def from_urdf(
        cls,
        path: PathLike,
        base: str | None = None,
        tip: str | None = None,
        *,
        name: str | None = None,
        locked: Mapping[str, float] | None = None,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> CoupledArm:
        """The chain of a URDF with ``<mimic>`` joints (a coupling-free chain gives the
        identity coupling)."""
        from deltagen.model.urdf import chain_from_urdf

        desc, coupling = chain_from_urdf(path, base=base, tip=tip, name=name, locked=locked)
        if coupling is None:
            coupling = Coupling.from_mimics([j.name for j in desc.joints], {})
        return cls(SerialRobot(desc, backend, threads=threads), coupling)

    def __repr__(self) -> str:
        return f"CoupledArm({self.name!r}, {self.n} of {self.full.n} joints independent)"

    @property
    def name(self) -> str:
        return self.full.name

    @property
    def n(self) -> int:
        """Number of independent variables k."""
        return self.coupling.k

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the independent joints, in the order of r."""
        return tuple(self.full.description.joints[i].name for i in self.coupling.independent)

    @property
    def qlim(self) -> FloatArray:
        """(k, 2) limits of the independent joints (the coupled joints' own limits are
        checked by within_limits on the expanded q)."""
        return np.asarray(self.full.qlim[list(self.coupling.independent)])

    def expand(self, q: ArrayLike) -> FloatArray:
        """The full joint vector (..., n) of r (..., k)."""
        return self.coupling.expand(self._r(q, "q"))

    def within_limits(self, q: ArrayLike) -> BoolArray:
        """Every physical joint (independent and coupled) within its limits."""
        return np.asarray(self.full.within_limits(self.expand(q)))

    def _r(self, q: ArrayLike, name: str) -> FloatArray:
        r = as_float_array(q, name)
        if r.ndim < 1 or r.shape[-1] != self.n:
            raise InputError(
                f"{name} must have shape (..., {self.n}) for {self.name} ({self.n} independent "
                f"joints: {', '.join(self.joint_names)}), got {r.shape}"
            )
        return r

    def _rate(self, qd: ArrayLike, name: str) -> FloatArray:
        return self.coupling.expand_rate(self._r(qd, name))

    @staticmethod
    def _map(errors: Errors, result: Any, f: Any) -> Result:
        if errors == "nan":
            *outs, valid = result
            return (*[f(x) for x in outs], valid)
        return f(result)

    # -- kinematics -------------------------------------------------------------------

    def fk(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Tool pose T (..., 4, 4) at r = q."""
        check_errors_mode(errors)
        return self.full.fk(self.expand(q), errors=errors)

    def frames(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Frames (..., n + 2, 4, 4) of the full chain (every physical joint)."""
        check_errors_mode(errors)
        return self.full.frames(self.expand(q), errors=errors)

    def jacobian(
        self, q: ArrayLike, frame: Literal["base", "tool"] = "base", errors: Errors = "raise"
    ) -> Result:
        """J_r = J E (..., 6, k): tool twist per independent joint rate."""
        check_errors_mode(errors)
        E = self.coupling.matrix
        return self._map(errors, self.full.jacobian(self.expand(q), frame, errors), lambda J: J @ E)

    def jacobian_dot(
        self,
        q: ArrayLike,
        qd: ArrayLike,
        frame: Literal["base", "tool"] = "base",
        errors: Errors = "raise",
    ) -> Result:
        """Jdot_r = Jdot(E r + c, E rd) E (..., 6, k)."""
        check_errors_mode(errors)
        E = self.coupling.matrix
        Jd = self.full.jacobian_dot(self.expand(q), self._rate(qd, "qd"), frame, errors)
        return self._map(errors, Jd, lambda X: X @ E)

    # -- dynamics ---------------------------------------------------------------------

    def inverse_dynamics(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """tau_r = E^T tau(q, E rd, E rdd) (..., k): the generalised forces of the
        independent joints (the drive of a coupled group)."""
        check_errors_mode(errors)
        E = self.coupling.matrix
        tau = self.full.inverse_dynamics(
            self.expand(q), self._rate(qd, "qd"), self._rate(qdd, "qdd"), errors
        )
        return self._map(errors, tau, lambda t: t @ E)

    def mass_matrix(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """M_r = E^T M E (..., k, k)."""
        check_errors_mode(errors)
        E = self.coupling.matrix
        M = self.full.mass_matrix(self.expand(q), errors)
        return self._map(errors, M, lambda X: E.T @ X @ E)

    def gravity_torque(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """g_r = E^T g (..., k)."""
        check_errors_mode(errors)
        E = self.coupling.matrix
        return self._map(errors, self.full.gravity_torque(self.expand(q), errors), lambda g: g @ E)

    def ik(self, *_args: Any, **_kwargs: Any) -> Result:
        raise InputError(
            f"{self.name} has coupled (mimic) joints: inverse kinematics of coupled chains is "
            "not supported yet (use the full chain, CoupledArm.full, and check the coupling)"
        )

    ik_all = ik
