"""CoupledArm: a serial arm whose joints are coupled (URDF ``<mimic>``), in its independent
variables r (..., k).

Every quantity is the full chain's (a :class:`SerialRobot` of all n physical joints) at
q = E r + c, mapped back by the chain rule and virtual work (model/coupling.py):
J_r = J E, Jdot_r = Jdot(q, E rd) E, tau_r = E^T tau(q, E rd, E rdd), M_r = E^T M E,
g_r = E^T g. ``errors="nan"`` works as in SerialRobot (the full chain's mask, per row of r).
Inverse kinematics: numeric, on r (the solver of solve/numeric.py with J_r and fk(E r + c),
in the box of r that keeps every coupled joint within its limits); the closed forms
(``ik_all``, ``method="analytic"``) assume free joints and are offered only for an identity
coupling.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike

from deltagen.api.hints import Backend, BoolArray, Errors, FloatArray, PathLike, Result
from deltagen.api.validity import mark_nonfinite
from deltagen.errors import rows_text
from deltagen.inputs import InputError, as_float_array, check_errors_mode
from deltagen.model.coupling import Coupling

if TYPE_CHECKING:  # serial.py imports this module, never the other way round
    from deltagen.api.serial import SerialRobot


def load_urdf_arm(
    arm_class: Any,
    path: PathLike,
    base: str | None = None,
    tip: str | None = None,
    *,
    name: str | None = None,
    locked: Mapping[str, float] | None = None,
    gravity: Any = None,
    backend: Backend = "compiled",
    threads: int | None = None,
    coupled: Any = None,
) -> Any:
    """The one loader of a URDF chain (SerialRobot.from_urdf, CoupledArm.from_urdf), which
    decides plain or coupled arm: the full chain as ``arm_class`` (SerialRobot), returned
    as it is when the chain has no ``<mimic>`` joints, else wrapped in a CoupledArm in the
    independent variables. ``coupled`` (a CoupledArm class): always wrap, the identity
    coupling for a chain without mimic joints."""
    from deltagen.model.urdf import chain_from_urdf

    desc, coupling = chain_from_urdf(
        path, base=base, tip=tip, name=name, locked=locked, gravity=gravity
    )
    if coupling is None and coupled is not None:
        coupling = Coupling.from_mimics([j.name for j in desc.joints], {})
    full = arm_class(desc, backend, threads=threads)
    if coupling is None:
        return full
    return (coupled or CoupledArm)(full, coupling)


class CoupledArm:
    """A chain with couplings, in its k independent variables (module docstring)."""

    #: the class of the full chain: deltagen.api.serial sets SerialRobot here when it defines
    #: it (serial.py imports this module; this module does not import serial.py)
    arm_class: ClassVar[type[Any]]

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
        return load_urdf_arm(
            cls.arm_class,
            path,
            base,
            tip,
            name=name,
            locked=locked,
            backend=backend,
            threads=threads,
            coupled=cls,
        )

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

    # -- inverse kinematics ---------------------------------------------------------

    @property
    def is_free(self) -> bool:
        """True when the coupling is the identity (no joint mimics another): every
        closed form of the full chain applies."""
        E, c = self.coupling.matrix, self.coupling.offset
        return E.shape[0] == E.shape[1] and bool(np.all(E == np.eye(self.n)) and not c.any())

    def independent_limits(self) -> FloatArray:
        """(k, 2) box of r in which every physical joint is within its limits: for joint j
        coupled to r_c, lo_j <= m_j r_c + c_j <= hi_j bounds r_c (each row of E has one
        entry, model/coupling.py), intersected over the joints of r_c."""
        E, c = self.coupling.matrix, self.coupling.offset
        qlim = np.asarray(self.full.qlim, dtype=float)
        box = np.tile([-np.inf, np.inf], (self.n, 1))
        for j in range(self.coupling.n):
            (cols,) = np.nonzero(E[j])
            if cols.size == 0:
                continue
            col, m = int(cols[0]), float(E[j, cols[0]])
            with np.errstate(invalid="ignore"):
                ends = (qlim[j] - c[j]) / m
            lo, hi = min(ends), max(ends)
            box[col] = (max(box[col, 0], lo), min(box[col, 1], hi))
        empty = np.flatnonzero(box[:, 0] > box[:, 1])
        if empty.size:
            names = ", ".join(self.joint_names[i] for i in empty)
            raise InputError(
                f"{self.name}: the limits of the joints coupled to {names} leave no common range"
            )
        return box

    def ik(
        self,
        T: ArrayLike,
        config: str | None = None,
        q0: ArrayLike | None = None,
        method: Literal["auto", "analytic", "numeric"] = "auto",
        errors: Errors = "raise",
        **options: Any,
    ) -> Result:
        """Independent variables r (..., k) reaching the tool pose(s) T (..., 4, 4).

        A coupled chain (k < n, or offsets): the numeric solver (solve/numeric.py, its numpy
        engine; ``options`` go there) on the independent variables, with the Jacobian
        J_r = J E and fk(E r + c), in the box of :meth:`independent_limits` (so every
        physical joint, independent or coupled, stays within its limits). Starts at q0
        (k,) or (..., k), default the middle of that box. The closed forms assume free
        joints: ``method="analytic"`` and ``config`` are refused for a coupled chain.
        An identity coupling (no mimic) hands the call to the full chain's ik.
        errors="raise" raises UnreachableError naming the unsolved rows; "nan" returns
        (r, valid)."""
        check_errors_mode(errors)
        if self.is_free:
            return self.full.ik(T, config=config, q0=q0, method=method, errors=errors, **options)
        if method not in ("auto", "analytic", "numeric"):
            raise InputError(f'method must be "auto", "analytic" or "numeric", got {method!r}')
        if method == "analytic" or config is not None:
            raise InputError(
                f"{self.name} has coupled (mimic) joints: closed-form inverse kinematics "
                "(method='analytic', config=) assumes free joints; use method='numeric'"
            )
        for key, allowed in (("engine", ("auto", "numpy")), ("jacobian", ("symbolic", "fd"))):
            if key in options and options[key] not in allowed:
                raise InputError(
                    f"{key}={options[key]!r} is not available for a coupled chain "
                    f"(allowed: {', '.join(map(repr, allowed))})"
                )
        from deltagen.errors import UnreachableError
        from deltagen.solve import numeric as ik_numeric
        from deltagen.solve.ik import check_poses, raise_bad_poses

        lead, flat, finite, rigid = check_poses(T)
        if errors == "raise" and not np.all(rigid):
            raise_bad_poses(finite, rigid)
        reduced = _ReducedChain(self)
        if q0 is None:
            start = np.broadcast_to(reduced.middle, (flat.shape[0], self.n))
        else:
            start = self._r(q0, "q0")
            try:
                start = np.broadcast_to(start, lead + (self.n,)).reshape(-1, self.n)
            except ValueError:
                raise InputError(
                    f"q0 of shape {start.shape} does not broadcast to the targets' {lead}"
                ) from None
        good = rigid & np.all(np.isfinite(start), axis=1)
        if errors == "raise" and not np.all(good):
            bad = np.flatnonzero(~good)
            raise InputError(f"q0 contains NaN or infinite values in rows {rows_text(bad)}", bad)
        r = np.full((flat.shape[0], self.n), np.nan)
        ok = np.zeros(flat.shape[0], dtype=bool)
        if np.any(good):  # only these rows: a placeholder target would cost its restarts
            options = {**options, "engine": "numpy"}
            result = ik_numeric.solve(reduced, flat[good], start[good], **options)
            r[good], ok[good] = result.q, result.converged
        if np.any(ok):
            # the whole pose (a chain of fewer than 6 variables fits the components it can
            # move: a target it cannot take is not reached) and every physical joint's limits
            q = self.coupling.expand(r[ok])
            fits = self.full.ik_planner.reaches_fully(q, flat[ok])
            ok[ok] = fits & np.asarray(self.full.within_limits(q))
        r[~ok] = np.nan
        if errors == "raise":
            if not np.all(ok):
                bad = np.flatnonzero(~ok)
                raise UnreachableError(
                    f"{self.name}: no solution found in rows {rows_text(bad)} (out of reach, "
                    "outside the limits of a joint or of the joints coupled to it, or no "
                    "convergence: try restarts= or another q0)",
                    bad,
                )
            return r.reshape(lead + (self.n,))
        return r.reshape(lead + (self.n,)), ok.reshape(lead)

    def ik_all(self, T: ArrayLike, method: str = "auto") -> tuple[FloatArray, BoolArray]:
        """Every closed-form branch, where the chain is free (identity coupling: the full
        chain's ik_all). A coupled chain has no closed form here: InputError."""
        if self.is_free:
            return self.full.ik_all(T, method=method)
        coupled = [
            self.full.description.joints[i].name
            for i in range(self.coupling.n)
            if i not in self.coupling.independent
        ]
        raise InputError(
            f"{self.name}: ik_all (every closed-form branch) is not available for a chain with "
            f"coupled joints ({', '.join(coupled)} mimic others); the closed forms assume "
            "free joints. Use ik(T) (numeric, in the independent variables)"
        )


class _ReducedJoint:
    """What the numeric solver reads of a joint: whether a 2 pi shift of it is the same
    pose (every physical joint coupled to it revolute, with an integer multiplier)."""

    def __init__(self, name: str, revolute: bool):
        self.name = name
        self.revolute = revolute
        self.sign = 1.0
        self.axis = "z"


class _ReducedDescription:
    def __init__(self, joints: list[_ReducedJoint]):
        self.joints = tuple(joints)
        self.convention = "reduced"


class _ReducedCore:
    """fk and the Jacobian J E of the full chain's core at q = E r + c."""

    def __init__(self, arm: CoupledArm):
        self._full = arm.full._core
        self._coupling = arm.coupling

    def fk(self, r: FloatArray) -> Any:
        return self._full.fk(np.ascontiguousarray(self._coupling.expand(r)))

    def jacobian(self, r: FloatArray) -> Any:
        J, status = self._full.jacobian(np.ascontiguousarray(self._coupling.expand(r)))
        JE = np.ascontiguousarray(J @ self._coupling.matrix)
        return JE, mark_nonfinite(status, JE)


class _ReducedChain:
    """The coupled chain as the numeric solver sees an arm (solve/numeric.py reads name, n,
    qlim, description.joints, configurations, backend and _core)."""

    backend = "reference"  # the compiled Newton routine is the full chain's: numpy engine

    def __init__(self, arm: CoupledArm):
        self.name = arm.name
        self.n = arm.n
        self.qlim = arm.independent_limits()
        E = arm.coupling.matrix
        joints = arm.full.description.joints
        wraps = []
        for col in range(arm.n):
            rows = np.flatnonzero(E[:, col])
            wraps.append(all(joints[j].revolute and float(E[j, col]).is_integer() for j in rows))
        self.description = _ReducedDescription(
            [_ReducedJoint(name, w) for name, w in zip(arm.joint_names, wraps, strict=True)]
        )
        finite = np.isfinite(self.qlim)
        self.middle = np.where(finite.all(axis=1), self.qlim.mean(axis=1), 0.0)
        self.configurations = {"qz": self.middle}
        self._core = _ReducedCore(arm)
