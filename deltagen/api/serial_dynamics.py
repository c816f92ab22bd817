"""The dynamics of SerialRobot (README, "Serial arms"): inverse and forward dynamics, the
mass matrix, gravity torques, the Coriolis matrix and the nonlinear effects, with their
call plumbing (the one-state paths, made on the first call of each kernel, and the error
of a mass matrix that is not positive definite). ``SerialDynamics`` is a base of
SerialRobot, which gives ``_core``, ``description``, ``name`` and the argument checks."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.api.hints import Errors, Result
from deltagen.api.validity import invalid_message
from deltagen.errors import SingularityError, rows_text
from deltagen.inputs import InputError, check_errors_mode

PENDING = object()  # a one-state path not made yet
#: the dynamics quantities (the kernels' names, the methods' names)
DYNAMICS: tuple[str, ...] = ("inverse_dynamics", "forward_dynamics", "mass_matrix")
DYNAMICS += ("gravity_torque", "coriolis", "nonlinear_effects")


class SerialDynamics:
    """The dynamics methods of SerialRobot (module docstring)."""

    _core: Any
    description: Any
    # one-state inverse_dynamics / forward_dynamics / mass_matrix (compiled, with inertia):
    # PENDING until the first call of that kernel
    _id_single: Any
    _fd_single: Any
    _mass_single: Any
    # SerialRobot's argument checks and shaping
    _prepare: Any
    _broadcast: Any
    _finish: Any

    # -- dynamics -----------------------------------------------------------------------
    #
    # Arms whose robot file gives inertial parameters (deltagen.model.serial): recursive
    # Newton-Euler in generated C (derive/serial/dynamics.py), or the Jacobian-form numpy
    # reference. Torques in N m (N for prismatic joints); gravity from the description.

    def _dynamics_single(self, name: str) -> Any:
        """The one-state path of ``name`` (inverse_dynamics, forward_dynamics,
        mass_matrix), made on its first call; None when there is none."""
        attr = {"inverse_dynamics": "_id_single", "forward_dynamics": "_fd_single"}.get(
            name, "_mass_single"
        )
        single = getattr(self, attr)
        if single is PENDING:
            core = self._core
            single = (
                core.single_mass_matrix() if attr == "_mass_single" else core.single_dynamics(name)
            )
            setattr(self, attr, single)
        return single

    def _dynamics(self):
        """The core, after checking that the arm has inertial parameters."""
        if not self.description.has_inertia:
            raise InputError(
                f"{self.description.name} has no inertial parameters: its robot file gives no mass, com "
                "or inertia in its [[joint]] tables (see deltagen.model.serial), so it has "
                "no dynamics"
            )
        return self._core

    def inverse_dynamics(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """Joint torques tau (..., n) = M(q) qdd + C(q, qd) qd + g(q) + armature qdd +
        viscous qd + Coulomb friction; q, qd, qdd broadcast against each other."""
        id_single = self._dynamics_single("inverse_dynamics")
        if id_single is not None and errors == "raise":
            tau = id_single(q, qd, qdd)
            if tau is not None:
                return tau
        return self._dynamics_rows("inverse_dynamics", errors, q=q, qd=qd, qdd=qdd)

    def mass_matrix(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Joint-space inertia matrix M (..., n, n), armature on the diagonal."""
        mass_single = self._dynamics_single("mass_matrix")
        if mass_single is not None and errors == "raise":
            M = mass_single(q)
            if M is not None:
                return M
        return self._dynamics_rows("mass_matrix", errors, q=q)

    def gravity_torque(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """g(q) (..., n): the joint torques that hold the arm still against gravity."""
        return self._dynamics_rows("gravity_torque", errors, q=q)

    def coriolis(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """Coriolis matrix C (..., n, n) in the Christoffel form: C qd holds the Coriolis
        and centrifugal torques and Mdot - 2C is skew-symmetric."""
        return self._dynamics_rows("coriolis", errors, q=q, qd=qd)

    def nonlinear_effects(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """h (..., n) = C(q, qd) qd + g(q) + friction: the torques at qdd = 0."""
        return self._dynamics_rows("nonlinear_effects", errors, q=q, qd=qd)

    def forward_dynamics(
        self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """Joint accelerations qdd (..., n) = M^-1 (tau - h(q, qd)) (a Cholesky solve);
        SingularityError (or NaN) where M is not positive definite (e.g. a massless arm)."""
        fd_single = self._dynamics_single("forward_dynamics")
        if fd_single is not None and errors == "raise":
            qdd = fd_single(q, qd, tau)
            if qdd is not None:
                return qdd
        return self._dynamics_rows("forward_dynamics", errors, q=q, qd=qd, tau=tau)

    def _dynamics_rows(self, name: str, errors: Errors, **states: ArrayLike) -> Result:
        """The general path of every dynamics quantity: the core's ``name`` on the rows of
        the joint states (q alone, or q, qd, ... broadcast against each other), checked and
        shaped by _finish_dynamics."""
        core = self._dynamics()
        if len(states) == 1:
            lead, qf = self._prepare(errors, states["q"])
            flat = [qf]
        else:
            check_errors_mode(errors)
            lead, flat = self._broadcast(**states)
        out, status = getattr(core, name)(*flat)
        return self._finish_dynamics(errors, lead, status, [out], tuple(states), list(flat))

    def _finish_dynamics(self, errors, lead, status, outs, names, inputs):
        singular = status == st.SINGULAR
        if errors == "raise" and np.any(singular) and np.all((status == st.OK) | singular):
            bad = np.flatnonzero(singular)
            raise SingularityError(
                f"the mass matrix of {self.description.name} is not positive definite in rows "
                f"{rows_text(bad)} (forward dynamics has no unique solution)",
                bad,
            )
        if errors == "raise" and not np.all((status == st.OK) | singular):
            bad = np.flatnonzero((status != st.OK) & ~singular)
            raise InputError(invalid_message(names, inputs, bad), bad)
        return self._finish(errors, lead, status, outs, names, inputs)
