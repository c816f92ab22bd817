"""SerialRobot: the Python API of serial-arm kinematics (README, "Serial arms").

Joint vectors are (..., n) arrays (any leading shape); poses are (..., 4, 4). Angles in
radians, lengths in metres. ``errors="raise"`` raises on bad rows; ``errors="nan"`` returns
NaN there plus a boolean ``valid`` mask as the last result.

Orientation conventions (spelled out because they are the usual source of confusion):

* ``euler(q)`` -> (psi, theta, phi), the angles after Vukobratovic (lecture slide 89):
  R = Rot_z(psi) Rot_y(theta) Rot_x(phi), i.e. turn about the base z axis by psi, then about
  the new y axis by theta, then about the newest x axis by phi.
  psi = atan2(r21, r11), theta = atan2(-r31, r11 cos psi + r21 sin psi), phi = atan2(r32, r33).
* ``rpy(q)`` -> (roll, pitch, yaw) of the same rotation read as fixed-axis angles: roll about
  the base x axis, then pitch about the base y axis, then yaw about the base z axis:
  R = Rot_z(yaw) Rot_y(pitch) Rot_x(roll); so roll = phi, pitch = theta, yaw = psi.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from deltagen.api.base import ReferenceCore, RobotFamily
from deltagen.api.bundled import bundled_arm, bundled_robots, bundled_urdfs
from deltagen.api.coupled import CoupledArm, load_urdf_arm
from deltagen.api.hints import Backend, BoolArray, Errors, FloatArray, PathLike, Result
from deltagen.api.serial_dynamics import DYNAMICS, PENDING, SerialDynamics
from deltagen.api.validity import invalid_message, mark_nonfinite
from deltagen.errors import SingularityError, rows_text
from deltagen.geometry.rotations import euler_zyx, skew  # euler_zyx: public here too
from deltagen.inputs import (
    InputError,
    as_float_array,
    broadcast_rows,
    check_errors_mode,
)
from deltagen.model.serial import DEFAULT_GRAVITY, SerialDescription
from deltagen.solve.ik import (
    IK_METHODS,
    IKPlanner,
    IKSolutions,
    check_poses,
    raise_bad_poses,
)
from deltagen.solve.singularity import singular_values

__all__ = ["IKSolutions", "SerialRobot", "bundled_robots", "bundled_urdfs", "euler_zyx"]

#: the reference functions a SerialRobot calls (reference/serial.py)
_CALLS = ("fk", "frames", "jacobian", "jacobian_dot", *DYNAMICS)

Frame = Literal["base", "tool"]  # the frame a Jacobian is expressed in


class SerialRobot(SerialDynamics, RobotFamily):
    """A serial arm (standard DH, modified DH or universal coordinates)."""

    _core: Any  # CompiledArm or a ReferenceCore: the same call signatures
    _model_attr = "description"
    _model_class = SerialDescription

    def __init__(
        self,
        description: SerialDescription,
        backend: Backend = "compiled",
        *,
        threads: int | None = None,
    ) -> None:
        if not isinstance(description, SerialDescription):
            raise InputError("SerialRobot needs a SerialDescription (see from_dh, from_toml, load)")
        self.description = description
        self._init_backend(backend, threads)

    def _init_backend(self, backend: Any, threads: int | None = None) -> None:
        threads = self._check_backend(backend, threads)
        description = self.description
        self.n = description.n
        if backend == "compiled":
            from deltagen.native.serial import CompiledArm

            self._core = CompiledArm(description, threads)
            self._fk_single = self._core.single("fk")
            self._jacobian_single = self._core.single("jacobian")
            # each one-state dynamics path is made on the first call of its kernel: the core
            # may defer building that kernel until then (native.serial.CompiledArm)
            pending = PENDING if description.has_inertia else None
            self._id_single = self._fd_single = self._mass_single = pending
        else:
            from deltagen.reference import serial as reference

            self._core = ReferenceCore(reference, (description,), _CALLS)
            self._fk_single = self._jacobian_single = None
            self._id_single = self._fd_single = self._mass_single = None
        self.ik_planner = IKPlanner(self)  # the choice of ik / ik_all method (solve/ik.py)

    @classmethod
    def load(
        cls, name: str, backend: Backend = "compiled", *, threads: int | None = None
    ) -> SerialRobot:
        """A bundled robot by name, e.g. "puma560" (see bundled_robots()), or a bundled URDF
        (robots/<name>.urdf, e.g. "ur5")."""
        return cls(bundled_arm(name), backend, threads=threads)

    @classmethod
    def from_dh(
        cls,
        rows: Iterable[Mapping[str, Any]],
        convention: Literal["standard", "modified"] | None = None,
        *,
        name: str = "arm",
        base: ArrayLike | None = None,
        tool: ArrayLike | None = None,
        configurations: Mapping[str, Sequence[float]] | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> SerialRobot:
        """rows: dicts with a, alpha, d, offset, joint|type, qlim (and *_deg keys);
        convention "standard" or "modified" must be given (no silent default). ``gravity``
        [m/s^2] is in the frame the poses are given in (the one ``base`` is given in)."""
        if convention not in ("standard", "modified"):
            raise InputError('from_dh needs convention="standard" or convention="modified"')
        desc = SerialDescription.from_rows(
            rows,
            convention,
            name=name,
            base=base,
            tool=tool,
            configurations=configurations,
            gravity=gravity,
        )
        return cls(desc, backend, threads=threads)

    @classmethod
    def from_urdf(
        cls,
        path: PathLike,
        base: str | None = None,
        tip: str | None = None,
        *,
        name: str | None = None,
        locked: Mapping[str, float] | None = None,
        gravity: Sequence[float] | None = None,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> SerialRobot | CoupledArm:
        """The chain of a URDF file from link ``base`` (default: the root link) to link
        ``tip`` (default: the single leaf) as universal coordinates (model/urdf.py states the
        mapping): revolute, continuous, prismatic and fixed joints, axes of any direction,
        limits and inertials (the links off the chain folded in, movable joints there locked
        at 0 or at ``locked[name]``). The joint variables are the URDF's (same zero, same sign).
        ``gravity`` [m/s^2] is in the URDF's root (world) frame (default (0, 0, -9.81)) and
        is turned into the base link's frame through the joints above it (those movable
        locked like the ones off the chain).
        A chain with ``<mimic>`` joints gives a :class:`deltagen.api.coupled.CoupledArm`
        in the independent variables instead."""
        return load_urdf_arm(
            cls,
            path,
            base,
            tip,
            name=name,
            locked=locked,
            gravity=gravity,
            backend=backend,
            threads=threads,
        )

    def __repr__(self) -> str:
        d = self.description
        return f"SerialRobot({d.name!r}, {d.n} joints, {d.convention}, backend={self.backend!r})"

    @property
    def qlim(self) -> FloatArray:
        return self.description.qlim

    @property
    def configurations(self) -> dict[str, FloatArray]:
        return {k: np.array(v) for k, v in self.description.configurations.items()}

    def configuration(self, name: str) -> FloatArray:
        try:
            return np.array(self.description.configurations[name])
        except KeyError:
            known = ", ".join(self.description.configurations) or "none"
            raise InputError(
                f"{self.name} has no configuration {name!r} (known: {known})"
            ) from None

    def within_limits(self, q: ArrayLike) -> BoolArray:
        qa = self._joints(q, "q")[1]
        lim = self.qlim
        return np.all((qa >= lim[:, 0]) & (qa <= lim[:, 1]), axis=-1)

    # -- quantities -------------------------------------------------------------------

    def fk(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Tool pose T (..., 4, 4) = base A_1(q_1) ... A_n(q_n) tool."""
        if type(errors) is str and errors == "raise" and self._fk_single is not None:
            T = self._fk_single(q)  # one configuration: the lean path (None: general path)
            if T is not None:
                return T
        lead, qf = self._prepare(errors, q)
        T, status = self._core.fk(qf)
        return self._finish(errors, lead, status, [T], ("q",), [qf])

    def frames(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """All frames (..., n + 2, 4, 4): base, after each joint, tool (for drawing)."""
        lead, qf = self._prepare(errors, q)
        F, status = self._core.frames(qf)
        return self._finish(errors, lead, status, [F], ("q",), [qf])

    def jacobian(self, q: ArrayLike, frame: Frame = "base", errors: Errors = "raise") -> Result:
        """Geometric Jacobian (..., 6, n) of the tool point; rows vx vy vz wx wy wz, in the
        base frame (default) or the tool frame (frame="tool")."""
        if (
            type(errors) is str
            and errors == "raise"
            and type(frame) is str
            and frame == "base"
            and self._jacobian_single is not None
        ):
            J = self._jacobian_single(q)  # one configuration: the lean path
            if J is not None:
                return J
        frame = self._check_frame(frame)
        lead, qf = self._prepare(errors, q)
        J, status = self._core.jacobian(qf)
        if frame == "tool":
            J = self._to_tool(qf, J)
            mark_nonfinite(status, J)
        return self._finish(errors, lead, status, [J], ("q",), [qf])

    def jacobian_dot(
        self, q: ArrayLike, qd: ArrayLike, frame: Frame = "base", errors: Errors = "raise"
    ) -> Result:
        """dJ/dt along qd (..., 6, n): tool acceleration = J qdd + Jdot qd (base frame).
        frame="tool" gives d/dt of the tool-frame Jacobian."""
        frame = self._check_frame(frame)
        check_errors_mode(errors)
        lead, (qf, qdf) = self._broadcast(q=q, qd=qd)
        Jd, status = self._core.jacobian_dot(qf, qdf)
        if frame == "tool":
            # J_t = Rbar^T J with Rbar = diag(R, R): dJ_t/dt = Rbar^T (Jd - [w]x J) (w = tool
            # angular velocity in the base frame)
            J, _ = self._core.jacobian(qf)
            with np.errstate(all="ignore"):  # overflow: the finite-output rule below
                w = np.einsum("nij,nj->ni", J[:, 3:], qdf)
                W = skew(w)
                corr = np.concatenate([W @ J[:, :3], W @ J[:, 3:]], axis=1)
                Jd = self._to_tool(qf, Jd - corr)
            mark_nonfinite(status, Jd)
        return self._finish(errors, lead, status, [Jd], ("q", "qd"), [qf, qdf])

    def euler(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """(..., 3): (psi, theta, phi) after Vukobratovic; see the module docstring."""
        check_errors_mode(errors)
        if errors == "raise":
            return euler_zyx(self.fk(q)[..., :3, :3])
        T, valid = self.fk(q, errors=errors)
        return euler_zyx(T[..., :3, :3]), valid

    def rpy(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """(..., 3): (roll, pitch, yaw) = (phi, theta, psi); see the module docstring."""
        res = self.euler(q, errors=errors)
        if errors == "raise":
            return res[..., ::-1].copy()
        return res[0][..., ::-1].copy(), res[1]

    def pose(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """(..., 6): x, y, z [m], psi, theta, phi [rad] (Vukobratovic angles)."""
        check_errors_mode(errors)
        T = self.fk(q, errors="nan")
        T, valid = T
        out = np.concatenate([T[..., :3, 3], euler_zyx(T[..., :3, :3])], axis=-1)
        if errors == "raise":
            if not np.all(valid):
                self.fk(q)  # raises with the rows named
            return out
        return out, valid

    def analytic_jacobian(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """(..., 6, n): d(x, y, z, psi, theta, phi)/dq = diag(I, E^-1) J, where the angular
        velocity is w = E (psi_dot, theta_dot, phi_dot) for R = Rz(psi) Ry(theta) Rx(phi).
        Singular where cos(theta) = 0 (the Euler angles' own singularity)."""
        check_errors_mode(errors)
        J, valid = self.jacobian(q, errors="nan")
        eta, _ = self.euler(q, errors="nan")
        psi, theta = eta[..., 0], eta[..., 1]
        c_th = np.cos(theta)
        singular = np.abs(c_th) < 1e-12
        valid = valid & ~singular
        with np.errstate(divide="ignore", invalid="ignore"):
            # E^-1 for E = [[0, -s psi, c psi c th], [0, c psi, s psi c th], [1, 0, -s th]]
            cp, sp_, st_ = np.cos(psi), np.sin(psi), np.sin(theta)
            Einv = np.zeros(eta.shape[:-1] + (3, 3))
            Einv[..., 0, 0] = cp * st_ / c_th
            Einv[..., 0, 1] = sp_ * st_ / c_th
            Einv[..., 0, 2] = 1.0
            Einv[..., 1, 0] = -sp_
            Einv[..., 1, 1] = cp
            Einv[..., 2, 0] = cp / c_th
            Einv[..., 2, 1] = sp_ / c_th
            Ja = J.copy()
            Ja[..., 3:, :] = Einv @ J[..., 3:, :]
            # the finite-output rule: E^-1 near cos theta = 0 times a huge J may overflow
            overflow = valid & ~np.all(np.isfinite(Ja), axis=(-2, -1))
        valid = valid & ~overflow
        Ja[~valid] = np.nan
        if errors == "raise":
            if not np.all(valid):
                self.jacobian(q)  # non-finite input rows raise there
                bad = np.flatnonzero(~valid.reshape(-1))
                cause = "Euler-angle singularity (cos theta = 0)"
                if np.any(overflow):
                    cause += " or a result that is not finite (q too large: overflow)"
                raise SingularityError(f"{cause} in rows {rows_text(bad)}", bad)
            return Ja
        return Ja, valid

    def manipulability(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Yoshikawa's measure: the product of J's singular values (= sqrt(det(J J^T)) for
        n >= 6, sqrt(det(J^T J)) for n < 6)."""
        check_errors_mode(errors)
        J, valid = self.jacobian(q, errors="nan")
        with np.errstate(over="ignore"):  # a product that overflows: not valid (_plain)
            out = np.prod(singular_values(J, valid), axis=-1)
        return self._plain(errors, q, out, valid, "manipulability")

    def condition_number(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """sigma_max / sigma_min of the geometric Jacobian. At an exact singularity
        (sigma_min = 0) it is infinite: a non-finite value is never valid, so such rows
        raise SingularityError (errors="raise") or give NaN and False (errors="nan")."""
        check_errors_mode(errors)
        J, valid = self.jacobian(q, errors="nan")
        sv = singular_values(J, valid)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = sv[..., 0] / sv[..., -1]
        return self._plain(errors, q, out, valid, "condition number")

    def singularities(
        self, q: ArrayLike, tol: float = 1e-6, errors: Errors = "raise"
    ) -> dict[str, Any]:
        """Singularity report (lecture slides 112-114): condition number, manipulability,
        sigma_min, ``singular``, and for 6R arms with a central wrist the classic ``wrist``,
        ``shoulder`` and ``elbow`` flags; ``aligned_axes`` lists collinear joint axes.
        deltagen.solve.singularity.describe(row) words one configuration's report.

        Rows of q with NaN or infinite values, or q so large that the Jacobian is not
        finite, have no report: errors="raise" raises InputError naming them;
        errors="nan" gives NaN numbers and False flags there and adds ``valid`` (...) to
        the report."""
        from deltagen.solve.singularity import report

        check_errors_mode(errors)
        lead, arr = self._joints(q, "q")
        rep = report(self, arr, tol=tol)
        no_report = np.isnan(np.asarray(rep["sigma_max"], dtype=float)).reshape(-1)
        if errors == "raise" and np.any(no_report):
            bad = np.flatnonzero(no_report)
            flat = np.ascontiguousarray(arr.reshape(-1, self.n))
            raise InputError(
                f"{invalid_message(('q',), [flat], bad)} (no singularity report for them; "
                "errors='nan' reports the others)",
                bad,
            )
        if errors == "nan":
            valid = ~no_report
            rep["valid"] = valid.reshape(lead) if lead else bool(valid[0])
        return rep

    def workspace(self, step: float | None = None, **options: Any) -> Any:
        """Reachability, manipulability and condition number over a voxel grid of tool
        positions, singular surfaces located: deltagen.api.workspace.serial_workspace."""
        from deltagen.api.workspace import serial_workspace

        return serial_workspace(self, step, **options)

    def follow(
        self, trajectory: Any, q0: Any = None, *, singularity: str = "stop", **options: Any
    ) -> Any:
        """Follow a Cartesian trajectory (position and orientation; built with
        deltagen.plan.cartesian.PathBuilder) from the joints q0 (None: ``ik`` at the start
        pose), seeing singular regions ahead (lecture slides 112-114):
        ``singularity="stop"`` (default) raises SingularPathError naming the segment, times
        and kind; ``"joint"`` (or ``"wrist"``: SingArea/Wrist) interpolates the wrist joints
        across a wrist region with the TCP kept on the path; ``"freeze"`` holds axis
        ``freeze_axis`` (4 or 6) there. ``qd_max``, ``qdd_max`` time-scale the motion into
        the joint limits. See deltagen.plan.singular_path.follow_path (``singularity`` is its
        ``remedy``); returns its SingularPathResult."""
        from deltagen.plan.singular_path import follow_path

        return follow_path(self, trajectory, q0, remedy=singularity, **options)

    def follow_path(self, trajectory: Any, q0: Any = None, **options: Any) -> Any:
        """:meth:`follow` with the planner's own keyword: ``remedy="stop" | "wrist" |
        "freeze"`` (deltagen.plan.singular_path.follow_path)."""
        from deltagen.plan.singular_path import follow_path

        return follow_path(self, trajectory, q0, **options)

    # -- inverse kinematics (the choice of method: deltagen.solve.ik.IKPlanner) ---------

    def analytic_configs(self) -> tuple[str, ...]:
        """Branch names of ik_all ((), if the arm has none): the closed form's, or for a
        6R arm whose wrist axes nearly meet, those of its nearest central-wrist arm."""
        return self.ik_planner.configs()

    def ik_all(self, T: ArrayLike, method: str = "auto") -> IKSolutions:
        """Every analytic branch: q (..., k, n) and valid (..., k) (reachable, finite,
        within the joint limits). Branch names: analytic_configs(). Rows of T that are not
        finite rigid transforms come back NaN and invalid.

        The result unpacks as ``q, valid`` and says in ``.complete`` whether the method
        used finds every solution: True for the closed forms (those of model/structure.py,
        including a 6R chain whose first three axes meet, solved backwards) and for the
        general 6R solver where its elimination is regular; then a pose without a valid
        solution is unreachable within the joint limits. False (with an
        IncompleteSolutionsWarning, once per arm and method) for the combined method and the
        general solver's best effort: a pose without a valid solution may be reachable.

        method: "auto" (the closed form where the structure has one; else, for a 6R arm, the
        complete general solver when one of its eliminations is regular -- then the slots
        are unnamed and analytic_configs() names the combined method's branches that
        ik(config=...) uses --, else the combined method where it applies, else the general
        solver's best effort), "closed_form",
        "complete" (solve/general6r.py: every solution, up to 16 slots, unnamed, valid ones
        first; for an arm whose elimination is singular the combined method's branches
        join its candidates) or "combined" (solve/combined.py: the named branches of analytic_configs())."""
        return self.ik_planner.ik_all(T, method)

    def _ik_request(self, config, q0, method, errors, singular, options):
        """The one check of ik's options, made on every call before any path is chosen
        (so a call is accepted or refused the same way for one pose or a batch, first call
        or later). Returns (analytic: bool, q0 as a float64 array or None, numeric options
        checked by deltagen.solve.numeric.check_options or None)."""
        check_errors_mode(errors)
        if not isinstance(singular, str) or singular not in ("raise", "allow"):
            raise InputError(f'singular must be "raise" or "allow", got {singular!r}')
        if not isinstance(method, str) or method not in IK_METHODS:
            raise InputError(f'method must be "auto", "analytic" or "numeric", got {method!r}')
        analytic, checked = self.ik_planner.choose(method, config, options)
        if q0 is not None:
            if not (type(q0) is np.ndarray and q0.dtype.char == "d"):
                q0 = as_float_array(q0, "q0", f"(..., {self.n})")
            if q0.ndim == 0 or q0.shape[-1] != self.n:
                raise InputError(
                    f"q0 must have shape (..., {self.n}) for {self.name}, got {q0.shape}"
                )
        return analytic, q0, checked

    def ik(
        self,
        T: ArrayLike,
        config: str | None = None,
        q0: ArrayLike | None = None,
        method: Literal["auto", "analytic", "numeric"] = "auto",
        errors: Errors = "raise",
        singular: Literal["raise", "allow"] = "raise",
        **options: Any,
    ) -> Result:
        """Joint coordinates reaching the tool pose(s) T (..., 4, 4).

        method "analytic" (closed form, where the structure allows), "numeric" (Newton /
        damped least squares, deltagen.solve.numeric.solve; ``options`` go there), or
        "auto" (analytic if available). Analytic: ``config`` picks a branch by name
        (analytic_configs()); ``q0`` picks the valid branch nearest q0; neither: the first
        valid branch in the order of analytic_configs(). Numeric: starts at q0 (default the
        middle of the joint ranges, or zeros). q0 (n,) or (..., n) broadcasts against T's
        leading shape.

        A solution at an exact singularity of the arm (sigma_min / sigma_max of the geometric
        Jacobian below status.SINGULAR_TOL = 1e-9: the Puma's wrist at q5 = 0, a stretched
        elbow) is not unique: ``singular="raise"`` (default) raises SingularityError for such
        rows (errors="raise") or gives NaN and False (errors="nan"); ``singular="allow"``
        returns the solution found (e.g. q4 = 0 at a wrist singularity).

        Every call checks all of its arguments the same way, whichever internal path (one
        pose or a batch) answers it. errors="raise" raises InputError for targets that are
        not finite rigid transforms, non-finite q0 rows and bad options, and
        UnreachableError naming the cause per row (out of reach, orientation not reachable
        by this structure, outside the joint limits, no convergence)."""
        planner = self.ik_planner
        q, tried = planner.remembered(T, config, q0, method, errors, singular, options)
        if q is not None:
            return q
        analytic, q0a, checked = self._ik_request(config, q0, method, errors, singular, options)
        planner.remember(config, q0, method, errors, singular, options, analytic)
        if not tried:
            q, tried = planner.one_plain(T, config, q0a, analytic, errors, singular, options)
            if q is not None:
                return q
        lead, flat, finite, rigid = check_poses(T)
        if not tried and flat.shape[0] == 1 and not lead and rigid[0]:
            q = planner.one(flat[0], config, q0a, analytic, errors, singular, options)
            if q is not None:
                return q
        good = rigid
        if errors == "raise" and not np.all(good):
            raise_bad_poses(finite, rigid)
        start = None
        if q0a is not None:
            start = planner.start(q0a, lead)
            q0_ok = np.isfinite(start).all(axis=1)
            if errors == "raise" and not np.all(q0_ok):
                bad = np.flatnonzero(~q0_ok)
                raise InputError(
                    f"q0 contains NaN or infinite values in rows {rows_text(bad)}", bad
                )
            good = good & q0_ok
        explain = errors == "raise"
        q, ok, cause, _ = planner.solve(
            flat, good, start, analytic, config, singular, options, explain
        )
        if explain:
            if cause is not None:
                raise cause
            return q.reshape(lead + (self.n,))
        return q.reshape(lead + (self.n,)), ok.reshape(lead)

    # the planner's parts that tests and the combined method read on the arm
    _poses = staticmethod(check_poses)

    def _analytic(self):
        return self.ik_planner.analytic

    def _general(self):
        return self.ik_planner.general

    def _start(self, q0, lead):
        return self.ik_planner.start(q0, lead)

    _general_6r = property(_general, lambda self, v: setattr(self.ik_planner, "general", v))

    # -- helpers ----------------------------------------------------------------------

    def _plain(self, errors, q, out, valid, what):
        """A per-row number derived from J: valid only where it is finite (the finite-output
        rule); NaN where not valid."""
        out = np.asarray(out, dtype=float)
        nonfinite = valid & ~np.isfinite(out)
        valid = valid & ~nonfinite
        out = np.where(valid, out, np.nan)
        if errors == "raise":
            if not np.all(valid):
                self.jacobian(q)  # non-finite q: raises there, naming the rows
                bad = np.flatnonzero(nonfinite.reshape(-1))
                message = (
                    f"the {what} is not finite in rows {rows_text(bad)} (an exact singularity "
                    "of the Jacobian, or q so large that the arithmetic overflows)"
                )
                raise SingularityError(message, bad)
            return out[()] if out.ndim == 0 else out
        return out[()] if out.ndim == 0 else out, valid

    @staticmethod
    def _check_frame(frame):
        if not isinstance(frame, str) or frame not in ("base", "tool"):
            raise InputError(f'frame must be "base" or "tool", got {frame!r}')
        return frame

    def _to_tool(self, qf, J):
        T, _ = self._core.fk(qf)
        Rt = np.swapaxes(T[:, :3, :3], -1, -2)
        return np.concatenate([Rt @ J[:, :3], Rt @ J[:, 3:]], axis=1)

    def _joints(self, q, name):
        arr = as_float_array(q, name, f"(..., {self.n})")
        if arr.ndim == 0 or arr.shape[-1] != self.n:
            raise InputError(
                f"{name} must have shape (..., {self.n}) for {self.name}, got {arr.shape}"
            )
        return arr.shape[:-1], arr

    def _prepare(self, errors, q):
        check_errors_mode(errors)
        lead, arr = self._joints(q, "q")
        return lead, np.ascontiguousarray(arr.reshape(-1, self.n))

    def _broadcast(self, **arrays):
        checked = {k: self._joints(v, k)[1] for k, v in arrays.items()}  # names the arm on errors
        lead, _, flat = broadcast_rows(checked, widths=(self.n,))
        return lead, flat

    def _raise(self, status, ok, names, inputs):  # a non-finite input, or an overflow
        bad = np.flatnonzero(~ok)
        raise InputError(invalid_message(names, inputs, bad), bad)


CoupledArm.arm_class = SerialRobot  # the full chain of CoupledArm.from_urdf (api/coupled.py)
