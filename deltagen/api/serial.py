"""SerialRobot: the Python API of serial-arm kinematics (DESIGN.md, "Serial-arm details").

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
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.api.hints import Backend, BoolArray, Errors, FloatArray, PathLike, Result
from deltagen.errors import GeometryError, SingularityError, rows_text
from deltagen.geometry.limits import wrap_to_pi
from deltagen.geometry.rotations import euler_zyx, skew  # euler_zyx: public here too
from deltagen.inputs import (
    InputError,
    as_float_array,
    broadcast_rows,
    check_errors_mode,
    plain_pose,
)
from deltagen.model.serial import SerialDescription
from deltagen.paths import robots_dir
from deltagen.status import SINGULAR_TOL

_BACKENDS = ("compiled", "reference")
Frame = Literal["base", "tool"]  # the frame a Jacobian is expressed in


def _is_arm_file(path: Path) -> bool:
    """A robot file of a serial arm (serial files state a convention; delta files do not)."""
    return path.is_file() and "convention" in path.read_text()


def bundled_robots() -> list[str]:
    """Names of the bundled serial arms (robots/*.toml with a convention)."""
    return [path.stem for path in sorted(robots_dir().glob("*.toml")) if _is_arm_file(path)]


class SerialRobot:
    """A serial arm (standard DH, modified DH or universal coordinates)."""

    _core: Any  # CompiledArm or _ReferenceArm: the same call signatures
    _ik_all_single: Any  # the C closed form's one-pose path, once ik_all has made it
    _id_single: Any  # one-state inverse_dynamics / forward_dynamics (compiled, with inertia)
    _fd_single: Any
    _mass_single: Any

    def __init__(self, description: SerialDescription, backend: Backend = "compiled") -> None:
        if not isinstance(description, SerialDescription):
            raise InputError("SerialRobot needs a SerialDescription (see from_dh, from_toml, load)")
        if backend not in _BACKENDS:
            raise InputError(f"backend must be one of {_BACKENDS}, got {backend!r}")
        self.description = description
        self.backend = backend
        self.n = description.n
        if backend == "compiled":
            from deltagen.native.serial import CompiledArm

            self._core = CompiledArm(description)
            self._fk_single = self._core.single("fk")
            self._jacobian_single = self._core.single("jacobian")
            self._ik_all_single = None  # made by ik_all when the arm has a C closed form
            dynamics = description.has_inertia
            self._id_single = self._core.single_dynamics("inverse_dynamics") if dynamics else None
            self._fd_single = self._core.single_dynamics("forward_dynamics") if dynamics else None
            self._mass_single = self._core.single_mass_matrix() if dynamics else None
        else:
            from deltagen.reference import serial as reference

            self._core = _ReferenceArm(reference, description)
            self._fk_single = self._jacobian_single = self._ik_all_single = None
            self._id_single = self._fd_single = self._mass_single = None

    # -- construction ---------------------------------------------------------------

    @classmethod
    def load(cls, name: str, backend: Backend = "compiled") -> SerialRobot:
        """A bundled robot by name, e.g. "puma560" (see bundled_robots())."""
        if (
            not isinstance(name, str)
            or not name.isidentifier()
            or not _is_arm_file(robots_dir() / f"{name}.toml")
        ):
            raise InputError(
                f"no bundled serial robot {name!r}; bundled: {', '.join(bundled_robots())}"
            )
        return cls(SerialDescription.from_toml(robots_dir() / f"{name}.toml"), backend)

    @classmethod
    def from_toml(cls, path: PathLike, backend: Backend = "compiled") -> SerialRobot:
        return cls(SerialDescription.from_toml(Path(path)), backend)

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
        backend: Backend = "compiled",
    ) -> SerialRobot:
        """rows: dicts with a, alpha, d, offset, joint|type, qlim (and *_deg keys);
        convention "standard" or "modified" must be given (no silent default)."""
        if convention not in ("standard", "modified"):
            raise InputError('from_dh needs convention="standard" or convention="modified"')
        desc = SerialDescription.from_rows(
            rows, convention, name=name, base=base, tool=tool, configurations=configurations
        )
        return cls(desc, backend)

    def with_backend(self, backend: Backend) -> SerialRobot:
        return type(self)(self.description, backend)

    def __repr__(self) -> str:
        d = self.description
        return f"SerialRobot({d.name!r}, {d.n} joints, {d.convention}, backend={self.backend!r})"

    @property
    def name(self) -> str:
        return self.description.name

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
        if self._fk_single is not None and errors == "raise":
            T = self._fk_single(q)
            if T is not None:
                return T
        lead, qf = self._prepare(errors, q)
        T, status = self._core.fk(qf)
        return self._finish(errors, lead, status, [T], ("q",))

    def frames(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """All frames (..., n + 2, 4, 4): base, after each joint, tool (for drawing)."""
        lead, qf = self._prepare(errors, q)
        F, status = self._core.frames(qf)
        return self._finish(errors, lead, status, [F], ("q",))

    def jacobian(self, q: ArrayLike, frame: Frame = "base", errors: Errors = "raise") -> Result:
        """Geometric Jacobian (..., 6, n) of the tool point; rows vx vy vz wx wy wz, in the
        base frame (default) or the tool frame (frame="tool")."""
        if self._jacobian_single is not None and frame == "base" and errors == "raise":
            J = self._jacobian_single(q)
            if J is not None:
                return J
        frame = self._check_frame(frame)
        lead, qf = self._prepare(errors, q)
        J, status = self._core.jacobian(qf)
        if frame == "tool":
            J = self._to_tool(qf, J)
        return self._finish(errors, lead, status, [J], ("q",))

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
            w = np.einsum("nij,nj->ni", J[:, 3:], qdf)
            W = skew(w)
            corr = np.concatenate([W @ J[:, :3], W @ J[:, 3:]], axis=1)
            Jd = self._to_tool(qf, Jd - corr)
        return self._finish(errors, lead, status, [Jd], ("q", "qd"))

    def euler(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """(..., 3): (psi, theta, phi) after Vukobratovic; see the module docstring."""
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
        Ja[~valid] = np.nan
        if errors == "raise":
            if not np.all(valid):
                self.jacobian(q)  # non-finite input rows raise there
                bad = np.flatnonzero(~valid.reshape(-1))
                raise SingularityError(
                    f"Euler-angle singularity (cos theta = 0) in rows {rows_text(bad)}", bad
                )
            return Ja
        return Ja, valid

    def manipulability(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Yoshikawa's measure: the product of J's singular values (= sqrt(det(J J^T)) for
        n >= 6, sqrt(det(J^T J)) for n < 6)."""
        J, valid = self.jacobian(q, errors="nan")
        sv = np.full(J.shape[:-2] + (min(J.shape[-2:]),), np.nan)
        sv[valid] = np.linalg.svd(J[valid], compute_uv=False)
        out = np.prod(sv, axis=-1)
        return self._plain(errors, q, out, valid)

    def condition_number(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """sigma_max / sigma_min of the geometric Jacobian (inf at a singularity)."""
        J, valid = self.jacobian(q, errors="nan")
        sv = np.full(J.shape[:-2] + (min(J.shape[-2:]),), np.nan)
        sv[valid] = np.linalg.svd(J[valid], compute_uv=False)
        with np.errstate(divide="ignore"):
            out = sv[..., 0] / sv[..., -1]
        return self._plain(errors, q, out, valid)

    def singularities(self, q: ArrayLike, tol: float = 1e-6) -> dict[str, Any]:
        """Singularity report (lecture slides 112-114): condition number, manipulability,
        sigma_min, ``singular``, and for 6R arms with a central wrist the classic ``wrist``,
        ``shoulder`` and ``elbow`` flags; ``aligned_axes`` lists collinear joint axes.
        deltagen.solve.singularity.describe(row) words one configuration's report."""
        from deltagen.solve.singularity import report

        return report(self, q, tol=tol)

    # -- dynamics -----------------------------------------------------------------------
    #
    # Arms whose robot file gives inertial parameters (deltagen.model.serial): recursive
    # Newton-Euler in generated C (derive/serial/dynamics.py), or the Jacobian-form numpy
    # reference. Torques in N m (N for prismatic joints); gravity from the description.

    def _dynamics(self):
        """The core, after checking that the arm has inertial parameters."""
        if not self.description.has_inertia:
            raise InputError(
                f"{self.name} has no inertial parameters: its robot file gives no mass, com "
                "or inertia in its [[joint]] tables (see deltagen.model.serial), so it has "
                "no dynamics"
            )
        return self._core

    def inverse_dynamics(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """Joint torques tau (..., n) = M(q) qdd + C(q, qd) qd + g(q) + armature qdd +
        viscous qd + Coulomb friction; q, qd, qdd broadcast against each other."""
        if self._id_single is not None and errors == "raise":
            tau = self._id_single(q, qd, qdd)
            if tau is not None:
                return tau
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf, qddf) = self._broadcast(q=q, qd=qd, qdd=qdd)
        tau, status = core.inverse_dynamics(qf, qdf, qddf)
        return self._finish_dynamics(errors, lead, status, [tau], ("q", "qd", "qdd"))

    def mass_matrix(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Joint-space inertia matrix M (..., n, n), armature on the diagonal."""
        if self._mass_single is not None and errors == "raise":
            M = self._mass_single(q)
            if M is not None:
                return M
        core = self._dynamics()
        lead, qf = self._prepare(errors, q)
        M, status = core.mass_matrix(qf)
        return self._finish_dynamics(errors, lead, status, [M], ("q",))

    def gravity_torque(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """g(q) (..., n): the joint torques that hold the arm still against gravity."""
        core = self._dynamics()
        lead, qf = self._prepare(errors, q)
        g, status = core.gravity_torque(qf)
        return self._finish_dynamics(errors, lead, status, [g], ("q",))

    def coriolis(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """Coriolis matrix C (..., n, n) in the Christoffel form: C qd holds the Coriolis
        and centrifugal torques and Mdot - 2C is skew-symmetric."""
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf) = self._broadcast(q=q, qd=qd)
        C, status = core.coriolis(qf, qdf)
        return self._finish_dynamics(errors, lead, status, [C], ("q", "qd"))

    def nonlinear_effects(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """h (..., n) = C(q, qd) qd + g(q) + friction: the torques at qdd = 0."""
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf) = self._broadcast(q=q, qd=qd)
        h, status = core.nonlinear_effects(qf, qdf)
        return self._finish_dynamics(errors, lead, status, [h], ("q", "qd"))

    def forward_dynamics(
        self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """Joint accelerations qdd (..., n) = M^-1 (tau - h(q, qd)) (a Cholesky solve);
        SingularityError (or NaN) where M is not positive definite (e.g. a massless arm)."""
        if self._fd_single is not None and errors == "raise":
            qdd = self._fd_single(q, qd, tau)
            if qdd is not None:
                return qdd
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf, tf) = self._broadcast(q=q, qd=qd, tau=tau)
        qdd, status = core.forward_dynamics(qf, qdf, tf)
        return self._finish_dynamics(errors, lead, status, [qdd], ("q", "qd", "tau"))

    def _finish_dynamics(self, errors, lead, status, outs, names):
        singular = status == st.SINGULAR
        if errors == "raise" and np.any(singular) and np.all((status == st.OK) | singular):
            bad = np.flatnonzero(singular)
            raise SingularityError(
                f"the mass matrix of {self.name} is not positive definite in rows "
                f"{rows_text(bad)} (forward dynamics has no unique solution)",
                bad,
            )
        if errors == "raise" and not np.all((status == st.OK) | singular):
            bad = np.flatnonzero((status != st.OK) & ~singular)
            raise InputError(
                f"{' or '.join(names)} contain NaN or infinite values (or the result "
                f"overflows) in rows {rows_text(bad)}"
            )
        return self._finish(errors, lead, status, outs, names)

    # -- inverse kinematics -------------------------------------------------------------

    def _poses(self, T, name="T"):
        arr = as_float_array(T, name)
        if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
            raise InputError(f"{name} must have shape (..., 4, 4), got {arr.shape}")
        lead = arr.shape[:-2]
        flat = np.ascontiguousarray(arr.reshape(-1, 4, 4))
        finite = np.all(np.isfinite(flat), axis=(1, 2))
        R = flat[:, :3, :3]
        with np.errstate(invalid="ignore"):
            rigid = np.all(np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)) < 1e-6, axis=(1, 2))
            rigid &= np.all(np.abs(flat[:, 3] - [0, 0, 0, 1]) < 1e-12, axis=1)
        return lead, flat, finite, rigid

    def analytic_configs(self) -> tuple[str, ...]:
        """Branch names of ik_all ((), if the arm has none): the closed form's, or for a
        6R arm whose wrist axes nearly meet, those of its nearest central-wrist arm."""
        solver = self._analytic()
        if solver is not None:
            return tuple(solver.configs)
        combined = self._combined()
        return () if combined is None else combined.branch_names(self)

    def _combined(self):
        """deltagen.solve.combined when it applies to this arm, else None."""
        if not hasattr(self, "_combined_module"):
            from deltagen.solve import combined as ik_combined

            try:
                ik_combined.nearest_central_wrist(self.description)
                self._combined_module = ik_combined
            except (InputError, GeometryError):
                self._combined_module = None
        return self._combined_module

    def _analytic(self):
        if not hasattr(self, "_analytic_solver"):
            from deltagen.solve.analytic import analytic_solver

            self._analytic_solver = analytic_solver(self.description)
        return self._analytic_solver

    def ik_all(self, T: ArrayLike) -> tuple[FloatArray, BoolArray]:
        """Every analytic branch: q (..., k, n) and valid (..., k) (reachable, finite,
        within the joint limits). Branch names: analytic_configs()."""
        if self._ik_all_single is not None:
            result = self._ik_all_single(T)
            if result is not None:
                return result
        solver = self._analytic()
        combined = self._combined() if solver is None else None
        if solver is None and combined is None:
            raise InputError(f"{self.name} has no closed-form inverse; use ik(T, method='numeric')")
        lead, flat, finite, rigid = self._poses(T)
        bad = ~(finite & rigid)
        safe = flat.copy()
        safe[bad] = np.eye(4)
        k = len(self.analytic_configs())
        if solver is not None and self.backend == "compiled" and self._core.has_ik_all:
            q, valid, _ = self._core.ik_all(safe, k)  # the generated C (ik_kernel.py)
            if self._ik_all_single is None:
                self._ik_all_single = self._core.single_ik_all(k)
        elif solver is not None:
            q, valid = solver.solve(safe)
        else:  # explicit start from the nearest central-wrist arm, refined by Newton
            assert combined is not None  # solver is None here, so combined is not
            q, valid = combined.solve_all(self, safe)
        q[bad], valid[bad] = np.nan, False
        return q.reshape(lead + (k, self.n)), valid.reshape(lead + (k,))

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
        middle of the joint ranges, or zeros).

        A solution at an exact singularity of the arm (sigma_min / sigma_max of the geometric
        Jacobian below status.SINGULAR_TOL = 1e-9: the Puma's wrist at q5 = 0, a stretched
        elbow) is not unique: ``singular="raise"`` (default) raises SingularityError for such
        rows (errors="raise") or gives NaN and False (errors="nan"); ``singular="allow"``
        returns the solution found (e.g. q4 = 0 at a wrist singularity)."""
        if singular not in ("raise", "allow"):
            raise InputError(f'singular must be "raise" or "allow", got {singular!r}')
        if (
            self._ik_all_single is not None
            and errors == "raise"
            and q0 is None
            and method != "numeric"
            and not options
        ):
            q = self._ik_single(T, config)
            if q is not None and (singular == "allow" or not self._singular_one(q)):
                return q
        if (
            method == "numeric"
            and self.backend == "compiled"
            and errors in ("raise", "nan")
            and options.keys() <= {"restarts", "seed"}
        ):
            q = self._numeric_single(T, q0, options.get("restarts", 0), options.get("seed", 0))
            if q is not None and (singular == "allow" or not self._singular_one(q)):
                return q if errors == "raise" else (q, np.array(True))
        check_errors_mode(errors)
        if method not in ("auto", "analytic", "numeric"):
            raise InputError(f'method must be "auto", "analytic" or "numeric", got {method!r}')
        lead, flat, finite, rigid = self._poses(T)
        if errors == "raise" and not np.all(finite & rigid):
            bad = np.flatnonzero(~(finite & rigid))
            raise InputError(f"T is not a finite rigid transform in rows {rows_text(bad)}")
        has_branches = bool(self.analytic_configs())
        use_analytic = method == "analytic" or (method == "auto" and has_branches)
        if use_analytic:
            if not has_branches:
                raise InputError(f"{self.name} has no closed-form inverse; use method='numeric'")
            q_all, valid_all = self.ik_all(flat)
            q, ok = self._pick_branch(q_all, valid_all, config, q0)
        else:
            from deltagen.solve import numeric as ik_numeric

            start = self._start(q0, flat.shape[0])
            safe = flat.copy()
            safe[~(finite & rigid)] = np.eye(4)
            result = ik_numeric.solve(self, safe, start, **options)
            q, ok = result.q, result.converged & finite & rigid
        q = q.copy()
        q[~ok] = np.nan
        if singular == "raise" and np.any(ok):
            at_singularity = np.zeros_like(ok)
            at_singularity[ok] = self._singular_rows(q[ok])
            if np.any(at_singularity):
                if errors == "raise":
                    bad = np.flatnonzero(at_singularity)
                    raise SingularityError(
                        f"the target is at a singularity of {self.name} (sigma_min/sigma_max "
                        f"< {SINGULAR_TOL:g}; the solution is not unique) in rows "
                        f"{rows_text(bad)}; singular='allow' returns one of its solutions",
                        bad,
                    )
                ok = ok & ~at_singularity
                q[at_singularity] = np.nan
        if errors == "raise":
            if not np.all(ok):
                from deltagen.errors import UnreachableError

                bad = np.flatnonzero(~ok)
                raise UnreachableError(
                    f"no solution within the joint limits for rows {rows_text(bad)}"
                    + (f" in configuration {config!r}" if config else ""),
                    bad,
                )
            return q.reshape(lead + (self.n,))
        return q.reshape(lead + (self.n,)), ok.reshape(lead)

    def _singular_rows(self, q):
        """Rows of finite q (M, n) whose Jacobian is singular: sigma_min / sigma_max <
        SINGULAR_TOL. For square J, |det J| / |J|_F^n bounds the ratio from below (|J|_F >=
        sigma_max), so only rows failing that cheap test need the SVD."""
        J, _ = self._core.jacobian(np.ascontiguousarray(q, dtype=float))
        check = np.ones(J.shape[0], dtype=bool)
        if J.shape[-1] == J.shape[-2]:
            norm = np.linalg.norm(J, axis=(-2, -1))
            with np.errstate(all="ignore"):
                check = ~(np.abs(np.linalg.det(J)) >= SINGULAR_TOL * norm ** J.shape[-1])
        singular = np.zeros(J.shape[0], dtype=bool)
        if np.any(check):
            sv = np.linalg.svd(J[check], compute_uv=False)
            singular[check] = ~(sv[:, -1] >= SINGULAR_TOL * sv[:, 0])
        return singular

    def _numeric_single(self, T, q0, restarts, seed):
        """Fast path of the numerical ik for one target (ik_numeric.single_solver): q, or
        None when the general path must answer (other inputs, or the first attempt did not
        converge: restarts and errors are the general path's)."""
        n, ndarray = self.n, np.ndarray
        if not plain_pose(T):
            return None
        if q0 is not None and (
            type(q0) is not ndarray
            or q0.shape != (n,)
            or q0.dtype.char != "d"
            or not q0.flags.c_contiguous
        ):
            return None
        if not isinstance(restarts, int) or isinstance(restarts, bool) or restarts < 0:
            return None
        solver = self.__dict__.get("_numeric_solver")
        if solver is None:
            from deltagen.solve.numeric import single_solver

            solver = self._numeric_solver = single_solver(self)
            self._mid_range = np.ascontiguousarray(self._start(None, 1)[0])
        return solver(T, self._mid_range if q0 is None else q0, restarts, seed)

    def _singular_one(self, q):
        """_singular_rows for one configuration, lean (the single-pose fast path)."""
        J = self._jacobian_single(q)
        if J is None or J.shape[0] != J.shape[1]:
            return bool(self._singular_rows(q[None])[0])
        bound = SINGULAR_TOL * float(np.sqrt(np.vdot(J, J))) ** J.shape[0]
        if abs(float(np.linalg.det(J))) >= bound:
            return False
        return bool(self._singular_rows(q[None])[0])

    def _ik_single(self, T, config):
        """Fast path of ik for one pose with a C closed form: q, or None when the general
        path must answer (it also raises the errors)."""
        result = self._ik_all_single(T)
        if result is None:
            return None
        q_all, valid = result
        if config is None:
            k = int(valid.argmax())
        else:
            configs = self._analytic().configs
            if config not in configs:
                return None
            k = configs.index(config)
        return q_all[k] if valid[k] else None

    def _start(self, q0, count):
        if q0 is None:
            lim = self.qlim
            bounded = np.isfinite(lim).all(axis=1)
            mid = np.where(bounded, np.where(bounded[:, None], lim, 0.0).mean(axis=1), 0.0)
            return np.tile(mid, (count, 1))
        _, arr = self._joints(q0, "q0")
        return np.ascontiguousarray(np.broadcast_to(arr.reshape(-1, self.n), (count, self.n)))

    def _pick_branch(self, q_all, valid_all, config, q0):
        configs = self.analytic_configs()
        rows = np.arange(q_all.shape[0])
        if config is not None:
            if config not in configs:
                raise InputError(f"unknown configuration {config!r}; {self.name} has {configs}")
            k = configs.index(config)
            return q_all[:, k], valid_all[:, k]
        if q0 is not None:
            start = self._start(q0, q_all.shape[0])
            d = wrap_to_pi(q_all - start[:, None, :])
            revolute = np.array([j.revolute for j in self.description.joints])
            d = np.where(revolute, d, q_all - start[:, None, :])
            dist = np.where(
                valid_all, np.linalg.norm(np.nan_to_num(d, nan=np.inf), axis=-1), np.inf
            )
            k = np.argmin(dist, axis=1)
        else:
            k = np.argmax(valid_all, axis=1)
        return q_all[rows, k], valid_all[rows, k]

    # -- helpers ----------------------------------------------------------------------

    def _plain(self, errors, q, out, valid):
        if errors == "raise":
            if not np.all(valid):
                self.jacobian(q)
            return out
        return out, valid

    @staticmethod
    def _check_frame(frame):
        if frame not in ("base", "tool"):
            raise InputError(f'frame must be "base" or "tool", got {frame!r}')
        return frame

    def _to_tool(self, qf, J):
        T, _ = self._core.fk(qf)
        Rt = np.swapaxes(T[:, :3, :3], -1, -2)
        return np.concatenate([Rt @ J[:, :3], Rt @ J[:, 3:]], axis=1)

    def _joints(self, q, name):
        arr = as_float_array(q, name)
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

    def _finish(self, errors, lead, status, outs, names):
        ok = status == st.OK
        if not ok.all():
            if errors == "raise":
                bad = np.flatnonzero(~ok)
                raise InputError(
                    f"{' or '.join(names)} {'contains' if len(names) == 1 else 'contain'} NaN "
                    f"or infinite values in rows {rows_text(bad)}"
                )
            for o in outs:
                o[~ok] = np.nan
        shaped = [o.reshape(lead + o.shape[1:]) for o in outs]
        if errors == "nan":
            return (*shaped, ok.reshape(lead))
        return shaped[0] if len(shaped) == 1 else tuple(shaped)


class _ReferenceArm:
    """The numpy reference with the compiled backend's call signatures."""

    def __init__(self, module, desc):
        self._m, self._d = module, desc

    def fk(self, q):
        return self._m.fk(self._d, q)

    def frames(self, q):
        return self._m.frames(self._d, q)

    def jacobian(self, q):
        return self._m.jacobian(self._d, q)

    def jacobian_dot(self, q, qd):
        return self._m.jacobian_dot(self._d, q, qd)

    def inverse_dynamics(self, q, qd, qdd):
        return self._m.inverse_dynamics(self._d, q, qd, qdd)

    def mass_matrix(self, q):
        return self._m.mass_matrix(self._d, q)

    def gravity_torque(self, q):
        return self._m.gravity_torque(self._d, q)

    def coriolis(self, q, qd):
        return self._m.coriolis(self._d, q, qd)

    def nonlinear_effects(self, q, qd):
        return self._m.nonlinear_effects(self._d, q, qd)

    def forward_dynamics(self, q, qd, tau):
        return self._m.forward_dynamics(self._d, q, qd, tau)
