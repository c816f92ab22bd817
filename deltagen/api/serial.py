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

import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.api.hints import Backend, BoolArray, Errors, FloatArray, PathLike, Result
from deltagen.api.threads import ThreadsProperty
from deltagen.api.validity import invalid_message, mark_nonfinite
from deltagen.errors import (
    GeometryError,
    IncompleteSolutionsWarning,
    SingularityError,
    rows_text,
)
from deltagen.geometry.limits import wrap_to_pi
from deltagen.geometry.rotations import euler_zyx, skew  # euler_zyx: public here too
from deltagen.inputs import (
    InputError,
    as_float_array,
    broadcast_rows,
    check_errors_mode,
)
from deltagen.model.serial import DEFAULT_GRAVITY, SerialDescription
from deltagen.native.parallel import check_threads
from deltagen.paths import robots_dir
from deltagen.status import SINGULAR_TOL

_BACKENDS = ("compiled", "reference")
_IK_METHODS = ("auto", "analytic", "numeric")
_EYE3 = np.eye(3)
_F64 = np.dtype(np.float64)  # native byte order

if TYPE_CHECKING:
    from deltagen.solve.analytic import ReversedSolver


class IKSolutions(tuple):
    """What ik_all returns: unpacks as ``q, valid`` (also ``.q``, ``.valid``), and
    ``.complete``: True when the method used finds every solution of the arm, so that a pose
    without a valid one is unreachable within the joint limits (SerialRobot.ik_all).
    ``IKSolutions.of(q, valid, complete)`` makes one; ``complete`` is a class attribute of
    the two subclasses, so that no Python ``__new__`` runs on the one-pose path (a third of
    its Python time)."""

    complete: bool = False

    @staticmethod
    def of(q: FloatArray, valid: BoolArray, complete: bool) -> IKSolutions:
        return (_CompleteIKSolutions if complete else _IncompleteIKSolutions)((q, valid))

    @property
    def q(self) -> FloatArray:
        return self[0]

    @property
    def valid(self) -> BoolArray:
        return self[1]


class _CompleteIKSolutions(IKSolutions):
    complete = True


class _IncompleteIKSolutions(IKSolutions):
    complete = False


_BOTTOM = np.array([0.0, 0.0, 0.0, 1.0])
_RIGID_TOL, _BOTTOM_TOL = 1e-6, 1e-12  # SerialRobot._poses: what counts as a rigid transform


try:  # np.linalg.det's LAPACK gufunc without its errstate context (a third of the cost
    # of one-pose ik's singularity check; J is finite there, its status was OK)
    from numpy.linalg import _umath_linalg

    def _det(J):
        return _umath_linalg.det(J, signature="d->d")

    if _det(np.eye(2)) != 1.0:  # pragma: no cover - a private module that changed
        raise ImportError("numpy.linalg._umath_linalg.det is not the determinant")
except Exception:  # pragma: no cover - a numpy without the module, or with another one
    _det = np.linalg.det


def _check_one_pose(v):
    """(finite, rigid) of one pose given as its 16 entries (row by row, a Python list):
    SerialRobot._poses's rule for a batch, in Python floats (a few us instead of ~20)."""
    if not all(map(math.isfinite, v)):
        return False, False
    a, b, c, _, d, e, f, _, g, h, i, _, w, x, y, z = v
    tol, bottom = _RIGID_TOL, _BOTTOM_TOL
    rigid = (
        abs(a * a + b * b + c * c - 1.0) < tol
        and abs(d * d + e * e + f * f - 1.0) < tol
        and abs(g * g + h * h + i * i - 1.0) < tol
        and abs(a * d + b * e + c * f) < tol
        and abs(a * g + b * h + c * i) < tol
        and abs(d * g + e * h + f * i) < tol
        and abs(w) < bottom
        and abs(x) < bottom
        and abs(y) < bottom
        and abs(z - 1.0) < bottom
    )
    return True, rigid


Frame = Literal["base", "tool"]  # the frame a Jacobian is expressed in


def _is_arm_file(path: Path) -> bool:
    """A robot file of a serial arm (serial files state a convention; delta files do not)."""
    return path.is_file() and "convention" in path.read_text()


def bundled_robots() -> list[str]:
    """Names of the bundled serial arms (robots/*.toml with a convention)."""
    return [path.stem for path in sorted(robots_dir().glob("*.toml")) if _is_arm_file(path)]


def bundled_urdfs() -> list[str]:
    """Names of the bundled URDF arms (robots/*.urdf: SerialRobot.load(name) reads the chain
    from the root link to the single leaf, under the file's name)."""
    return [path.stem for path in sorted(robots_dir().glob("*.urdf"))]


_PENDING = object()  # a one-state path not made yet


class SerialRobot(ThreadsProperty):
    """A serial arm (standard DH, modified DH or universal coordinates)."""

    _core: Any  # CompiledArm or _ReferenceArm: the same call signatures
    _ik_all_single: Any  # the C closed form's one-pose path, once ik_all has made it
    _general_single: Any  # the complete solver's one-pose path (None: not made yet)
    # one-state inverse_dynamics / forward_dynamics / mass_matrix (compiled, with inertia):
    # _PENDING until the first call of that kernel
    _id_single: Any
    _fd_single: Any
    _mass_single: Any

    def __init__(
        self,
        description: SerialDescription,
        backend: Backend = "compiled",
        *,
        threads: int | None = None,
    ) -> None:
        if not isinstance(description, SerialDescription):
            raise InputError("SerialRobot needs a SerialDescription (see from_dh, from_toml, load)")
        if backend not in _BACKENDS:
            raise InputError(f"backend must be one of {_BACKENDS}, got {backend!r}")
        threads = check_threads(threads)
        self.description = description
        self.backend = backend
        self.n = description.n
        # ik_all: whether each method used so far is complete (warned once where it is not)
        self._ik_all_completeness: dict[str, bool] = {}
        if backend == "compiled":
            from deltagen.native.serial import CompiledArm

            self._core = CompiledArm(description, threads)
            self._fk_single = self._core.single("fk")
            self._jacobian_single = self._core.single("jacobian")
            self._ik_all_single = None  # made by ik_all when the arm has a C closed form
            self._general_single = None  # the complete solver's one-pose path (ik_all)
            # each one-state dynamics path is made on the first call of its kernel: the core
            # may defer building that kernel until then (native.serial.CompiledArm)
            pending = _PENDING if description.has_inertia else None
            self._id_single = self._fd_single = self._mass_single = pending
        else:
            from deltagen.reference import serial as reference

            self._core = _ReferenceArm(reference, description)
            self._fk_single = self._jacobian_single = self._ik_all_single = None
            self._general_single = False  # numpy engine: the general path
            self._id_single = self._fd_single = self._mass_single = None
        self._threads = threads

    # -- construction ---------------------------------------------------------------

    @classmethod
    def load(
        cls, name: str, backend: Backend = "compiled", *, threads: int | None = None
    ) -> SerialRobot:
        """A bundled robot by name, e.g. "puma560" (see bundled_robots()), or a bundled URDF
        (robots/<name>.urdf, e.g. "ur5")."""
        if (
            isinstance(name, str)
            and name.isidentifier()
            and not (robots_dir() / f"{name}.toml").exists()
            and (robots_dir() / f"{name}.urdf").is_file()
        ):
            from deltagen.model.urdf import description_from_urdf

            desc = description_from_urdf(robots_dir() / f"{name}.urdf", name=name)
            return cls(desc, backend, threads=threads)
        if (
            not isinstance(name, str)
            or not name.isidentifier()
            or not _is_arm_file(robots_dir() / f"{name}.toml")
        ):
            raise InputError(
                f"no bundled serial robot {name!r}; bundled: "
                f"{', '.join(bundled_robots() + bundled_urdfs())}"
            )
        return cls(
            SerialDescription.from_toml(robots_dir() / f"{name}.toml"), backend, threads=threads
        )

    @classmethod
    def from_toml(
        cls, path: PathLike, backend: Backend = "compiled", *, threads: int | None = None
    ) -> SerialRobot:
        return cls(SerialDescription.from_toml(Path(path)), backend, threads=threads)

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
    ) -> SerialRobot:
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
        from deltagen.model.urdf import chain_from_urdf

        desc, coupling = chain_from_urdf(
            path, base=base, tip=tip, name=name, locked=locked, gravity=gravity
        )
        if coupling is not None:
            from deltagen.api.coupled import CoupledArm

            return CoupledArm(cls(desc, backend, threads=threads), coupling)  # type: ignore[return-value]
        return cls(desc, backend, threads=threads)

    def with_backend(self, backend: Backend) -> SerialRobot:
        return type(self)(self.description, backend, threads=self.threads)

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
        check_errors_mode(errors)
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
            out = np.prod(self._singular_values(J, valid), axis=-1)
        return self._plain(errors, q, out, valid, "manipulability")

    def condition_number(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """sigma_max / sigma_min of the geometric Jacobian. At an exact singularity
        (sigma_min = 0) it is infinite: a non-finite value is never valid, so such rows
        raise SingularityError (errors="raise") or give NaN and False (errors="nan")."""
        check_errors_mode(errors)
        J, valid = self.jacobian(q, errors="nan")
        sv = self._singular_values(J, valid)
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
        deltagen.plan.trajectory.PathBuilder) from the joints q0 (None: ``ik`` at the start
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
        if single is _PENDING:
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
        id_single = self._dynamics_single("inverse_dynamics")
        if id_single is not None and errors == "raise":
            tau = id_single(q, qd, qdd)
            if tau is not None:
                return tau
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf, qddf) = self._broadcast(q=q, qd=qd, qdd=qdd)
        tau, status = core.inverse_dynamics(qf, qdf, qddf)
        return self._finish_dynamics(
            errors, lead, status, [tau], ("q", "qd", "qdd"), [qf, qdf, qddf]
        )

    def mass_matrix(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Joint-space inertia matrix M (..., n, n), armature on the diagonal."""
        mass_single = self._dynamics_single("mass_matrix")
        if mass_single is not None and errors == "raise":
            M = mass_single(q)
            if M is not None:
                return M
        core = self._dynamics()
        lead, qf = self._prepare(errors, q)
        M, status = core.mass_matrix(qf)
        return self._finish_dynamics(errors, lead, status, [M], ("q",), [qf])

    def gravity_torque(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """g(q) (..., n): the joint torques that hold the arm still against gravity."""
        core = self._dynamics()
        lead, qf = self._prepare(errors, q)
        g, status = core.gravity_torque(qf)
        return self._finish_dynamics(errors, lead, status, [g], ("q",), [qf])

    def coriolis(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """Coriolis matrix C (..., n, n) in the Christoffel form: C qd holds the Coriolis
        and centrifugal torques and Mdot - 2C is skew-symmetric."""
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf) = self._broadcast(q=q, qd=qd)
        C, status = core.coriolis(qf, qdf)
        return self._finish_dynamics(errors, lead, status, [C], ("q", "qd"), [qf, qdf])

    def nonlinear_effects(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """h (..., n) = C(q, qd) qd + g(q) + friction: the torques at qdd = 0."""
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf) = self._broadcast(q=q, qd=qd)
        h, status = core.nonlinear_effects(qf, qdf)
        return self._finish_dynamics(errors, lead, status, [h], ("q", "qd"), [qf, qdf])

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
        core = self._dynamics()
        check_errors_mode(errors)
        lead, (qf, qdf, tf) = self._broadcast(q=q, qd=qd, tau=tau)
        qdd, status = core.forward_dynamics(qf, qdf, tf)
        return self._finish_dynamics(errors, lead, status, [qdd], ("q", "qd", "tau"), [qf, qdf, tf])

    def _finish_dynamics(self, errors, lead, status, outs, names, inputs):
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
            raise InputError(invalid_message(names, inputs, bad), bad)
        return self._finish(errors, lead, status, outs, names, inputs)

    # -- inverse kinematics -------------------------------------------------------------

    def _poses(self, T, name="T"):
        """The one check of target poses (every ik / ik_all call, single pose or batch):
        (lead, flat (N, 4, 4), finite (N,), rigid (N,)). rigid: finite, the rotation block
        orthonormal (|R R^T - I| < 1e-6 entrywise) and the bottom row 0 0 0 1 to 1e-12.
        One pose is checked with Python floats (the same rule, a tenth of the time)."""
        if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype.char == "d":
            arr = np.ascontiguousarray(T)
        else:
            arr = as_float_array(T, name, "(..., 4, 4)")
            if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
                raise InputError(f"{name} must have shape (..., 4, 4), got {arr.shape}")
        lead = arr.shape[:-2]
        flat = arr.reshape(-1, 4, 4)  # C-contiguous
        if flat.shape[0] == 1:
            finite, rigid = _check_one_pose(flat.ravel().tolist())
            return lead, flat, np.array([finite]), np.array([rigid])
        m = np.ascontiguousarray(flat.reshape(-1, 16).T)  # (16, N): contiguous columns
        finite = np.isfinite(m).all(axis=0)
        # R R^T entry by entry on columns of the batch (its 6 distinct entries: the (i, j)
        # and (j, i) sums are the same products in the same order): a batched 3 x 3 matmul
        # was ~0.7 us per pose, a third of the UR5's whole ik_all
        rows = [[m[4 * i + k] for k in range(3)] for i in range(3)]
        with np.errstate(all="ignore"):
            rigid = (np.abs(m[12:] - _BOTTOM[:, None]) < _BOTTOM_TOL).all(axis=0)
            for i in range(3):
                for j in range(i, 3):
                    a, b = rows[i], rows[j]
                    g = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
                    rigid &= np.abs(g - _EYE3[i, j]) < _RIGID_TOL
        return lead, flat, finite, rigid & finite

    @staticmethod
    def _raise_bad_poses(finite, rigid, name="T"):
        """InputError naming the rows of T that are not finite, or not rigid transforms."""
        nonfinite = np.flatnonzero(~finite)
        if nonfinite.size:
            raise InputError(
                f"{name} contains NaN or infinite values in rows {rows_text(nonfinite)}",
                nonfinite,
            )
        bad = np.flatnonzero(~rigid)
        if bad.size:
            raise InputError(
                f"{name} is not a rigid transform (rotation block not orthonormal, or bottom "
                f"row not [0, 0, 0, 1]) in rows {rows_text(bad)}",
                bad,
            )

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

    def _general(self):
        """(eliminations, complete) of deltagen.solve.general6r for a 6R arm, else None."""
        if not hasattr(self, "_general_6r"):
            self._general_6r = None
            if self.n == 6 and all(j.revolute for j in self.description.joints):
                from deltagen.solve import general6r

                self._general_6r = general6r.eliminations(self.description)
        return self._general_6r

    def _analytic(self):
        if not hasattr(self, "_analytic_solver"):
            from deltagen.solve.analytic import analytic_solver

            self._analytic_solver = analytic_solver(self.description)
        return self._analytic_solver

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
        q, valid = self._ik_all(T, method)
        complete = self._ik_all_completeness.get(method)
        if complete is None:
            complete = self._ik_all_completeness[method] = self._ik_all_complete(method)
            if not complete:
                self._warn_incomplete(method)
        return IKSolutions.of(q, valid, complete)

    def _warn_incomplete(self, method: str) -> None:
        """The IncompleteSolutionsWarning of ik_all (stacklevel: the caller of ik_all)."""
        why = (
            "the combined method (the nearest central-wrist arm's branches, refined by "
            "Newton) may miss solutions"
            if method == "combined" or (method == "auto" and self._combined() is not None)
            else "the general 6R solver's eliminations are singular for this arm (no "
            "closed form either): its answer is a best effort"
        )
        warnings.warn(
            f"ik_all of {self.name} (method={method!r}) is not complete: {why}; a pose "
            "without a valid solution may still be reachable (result.complete is False)",
            IncompleteSolutionsWarning,
            stacklevel=3,
        )

    def _ik_all_complete(self, method: str) -> bool:
        """Whether ik_all's ``method`` finds every solution of this arm (ik_all's docstring):
        the same choice of path as _ik_all's."""
        if method == "combined":
            return False
        solver = self._analytic()
        if solver is not None and method in ("auto", "closed_form"):
            return True
        # "complete", or "auto" without a closed form: the general solver, complete when its
        # elimination is regular (else its best effort, or the combined method)
        general = self._general()
        return general is not None and bool(general[1])

    def _ik_all(self, T: ArrayLike, method: str) -> tuple[FloatArray, BoolArray]:
        one = self._general_single
        if (
            one
            and type(T) is np.ndarray
            and T.shape == (4, 4)
            and T.dtype is _F64
            and (method == "complete" or (method == "auto" and one.auto))
            and _check_one_pose(T.ravel().tolist())[1]
        ):  # one pose, complete solver: one C call (general6r.single), after _poses' check
            return one(T if T.flags.c_contiguous else np.ascontiguousarray(T))
        if method not in ("auto", "closed_form", "complete", "combined"):
            raise InputError(
                f'method must be "auto", "closed_form", "complete" or "combined", got {method!r}'
            )
        solver = self._analytic()
        if method == "auto" and solver is None and self._general() is not None:
            eliminations, complete = self._general()
            if complete or self._combined() is None:
                method = "complete"
        if method == "complete":
            general = self._general()
            if general is None:
                raise InputError(f"{self.name}: the complete solver needs a 6R arm")
            from deltagen.solve import general6r

            if one is None and general[1]:  # made once: the fast path above from now on
                made = general6r.single(self, general[0])
                self._general_single = made if made is not None else False
                if made is not None:
                    made.auto = solver is None  # "auto" is "complete" here (checked above)
                    if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype is _F64:
                        return self._ik_all(T, method)
            lead, flat, finite, rigid = self._poses(T)
            safe = flat.copy()
            safe[~rigid] = np.eye(4)
            extra = None
            if not general[1] and self._combined() is not None:
                # an incomplete (singular-pencil) elimination: the combined method's
                # branches join the candidates
                extra = self._combined().solve_all(self, safe)[0]
            q, valid = general6r.solve(self, safe, general[0], extra=extra)
            q[~rigid], valid[~rigid] = np.nan, False
            k = q.shape[1]
            return q.reshape(lead + (k, self.n)), valid.reshape(lead + (k,))
        if method == "combined":
            if self._combined() is None:
                raise InputError(f"{self.name}: the combined method does not apply")
            lead, flat, finite, rigid = self._poses(T)
            return self._ik_all_rows(lead, flat, rigid, None, self._combined())
        if method == "closed_form" and solver is None:
            raise InputError(f"{self.name} has no closed-form inverse")
        combined = self._combined() if solver is None else None
        if solver is None and combined is None:
            raise InputError(f"{self.name} has no closed-form inverse; use ik(T, method='numeric')")
        single = self._ik_all_single
        if single is not None and type(T) is np.ndarray and T.shape == (4, 4) and T.dtype is _F64:
            # one pose: the lean path, after the same check as _poses'
            if _check_one_pose(T.ravel().tolist())[1]:
                result = single(T)
                if result is not None:
                    return result
        lead, flat, finite, rigid = self._poses(T)  # every call, whichever path follows
        if single is not None and flat.shape[0] == 1 and rigid[0]:
            result = single(flat[0])
            if result is not None:
                q1, valid1 = result
                return q1.reshape(lead + q1.shape), valid1.reshape(lead + valid1.shape)
        return self._ik_all_rows(lead, flat, rigid, solver, combined)

    def _reversed_arm(self, solver: ReversedSolver) -> SerialRobot:
        """The reversed chain (model/structure.py reversed_description) as an arm of this
        backend, made once: its compiled closed form serves ik_all (built on first use)."""
        if getattr(self, "_reversed", None) is None:
            self._reversed = type(self)(
                solver.reversed_description, self.backend, threads=self.threads
            )
        return self._reversed

    def _ik_all_rows(self, lead, flat, good, solver, combined):
        """ik_all's general path for checked poses (good: finite rigid rows)."""
        bad = ~good
        safe = flat.copy()
        safe[bad] = np.eye(4)
        k = len(self.analytic_configs())
        from deltagen.solve.analytic import ReversedSolver, invert

        if isinstance(solver, ReversedSolver) and self.backend == "compiled":
            # solved backwards: the reversed chain's own compiled closed form for T^-1
            back = self._reversed_arm(solver)
            q, valid = back._ik_all(invert(safe), "closed_form")
            q = np.ascontiguousarray(q[..., ::-1])
        elif solver is not None and self.backend == "compiled" and self._core.has_ik_all:
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

    def _ik_request(self, config, q0, method, errors, singular, options):
        """The one check of ik's options, made on every call before any path is chosen
        (so a call is accepted or refused the same way for one pose or a batch, first call
        or later). Returns (analytic: bool, q0 as a float64 array or None, numeric options
        checked by deltagen.solve.numeric.check_options or None)."""
        check_errors_mode(errors)
        if not isinstance(singular, str) or singular not in ("raise", "allow"):
            raise InputError(f'singular must be "raise" or "allow", got {singular!r}')
        if not isinstance(method, str) or method not in _IK_METHODS:
            raise InputError(f'method must be "auto", "analytic" or "numeric", got {method!r}')
        configs = self.analytic_configs()
        if method == "analytic" and not configs:
            raise InputError(f"{self.name} has no closed-form inverse; use method='numeric'")
        analytic = method == "analytic" or (method == "auto" and bool(configs))
        if config is not None:
            if not analytic:
                raise InputError(
                    f"config picks a closed-form branch; it does not apply to the numeric "
                    f"method ({self.name}, method={method!r}; give q0 to choose the start)"
                )
            if not isinstance(config, str) or config not in configs:
                raise InputError(f"unknown configuration {config!r}; {self.name} has {configs}")
        from deltagen.solve import numeric as ik_numeric

        unknown = sorted(set(options) - set(ik_numeric.OPTIONS)) if options else ()
        if unknown:
            raise InputError(
                f"ik got unknown option(s) {', '.join(unknown)}; it takes config, q0, method, "
                f"errors, singular and, for method='numeric', {', '.join(ik_numeric.OPTIONS)}"
            )
        checked = None
        if analytic:
            if options:
                raise InputError(
                    f"option(s) {', '.join(sorted(options))} apply to method='numeric' only; "
                    f"this call uses {self.name}'s closed form (method={method!r})"
                )
        else:
            # max_iter >= 1 here; no options: the defaults, which pass
            checked = ik_numeric.check_options(self, **options) if options else None
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
        analytic, q0a, checked = self._ik_request(config, q0, method, errors, singular, options)
        if type(T) is np.ndarray and T.dtype is _F64 and T.shape == (4, 4) and T.flags.c_contiguous:
            # one pose as a plain array: _poses' rule in Python floats, and the lean paths
            # (None: the general path below answers, after its own check of T)
            if _check_one_pose(T.ravel().tolist())[1]:
                q = self._ik_one(T, config, q0a, analytic, errors, singular, options)
                if q is not None:
                    return q
        lead, flat, finite, rigid = self._poses(T)
        if flat.shape[0] == 1 and not lead and rigid[0]:
            q = self._ik_one(flat[0], config, q0a, analytic, errors, singular, options)
            if q is not None:
                return q
        good = rigid
        if errors == "raise" and not np.all(good):
            self._raise_bad_poses(finite, rigid)
        start = None
        if q0a is not None:
            start = self._start(q0a, lead)
            q0_ok = np.isfinite(start).all(axis=1)
            if errors == "raise" and not np.all(q0_ok):
                bad = np.flatnonzero(~q0_ok)
                raise InputError(
                    f"q0 contains NaN or infinite values in rows {rows_text(bad)}", bad
                )
            good = good & q0_ok
        if analytic:
            q_all, valid_all = self._ik_all_rows(
                (flat.shape[0],), flat, good, self._analytic(), self._combined()
            )
            q, ok = self._pick_branch(q_all, valid_all, config, start)
        else:
            from deltagen.solve import numeric as ik_numeric

            if start is None:
                start = self._start(None, (flat.shape[0],))
            with np.errstate(all="ignore"):  # huge targets: the distances overflow to inf
                dist, reach = self._reach_of(flat)
            good = good & ~(dist > reach)  # beyond the reach: no attempt (and no restarts)
            q = np.full((flat.shape[0], self.n), np.nan)
            ok = np.zeros(flat.shape[0], dtype=bool)
            if np.any(good):  # only these rows: a placeholder target would cost its restarts
                result = ik_numeric.solve(self, flat[good], start[good], **options)
                q[good], ok[good] = result.q, result.converged
            unfit = np.zeros_like(ok)
            if "mask" not in options and self._fits_tool() and np.any(ok):
                # the default mask of an arm with fewer than 6 joints matches what it can
                # move; a target it cannot take in the other components (a tilted SCARA
                # tool) is not reached: no solution here (mask= asks for the fit)
                unfit[ok] = ~self._reaches_fully(q[ok], flat[ok])
                ok = ok & ~unfit
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
                bad = np.flatnonzero(~ok)
                unfit_rows = None if analytic else np.flatnonzero(unfit)
                raise self._unsolved(flat, bad, analytic, config, options, unfit_rows)
            return q.reshape(lead + (self.n,))
        return q.reshape(lead + (self.n,)), ok.reshape(lead)

    # -- why a target has no solution (errors="raise" only: the error path) -------------

    def _fits_tool(self):
        """True when the numeric solver's default mask leaves pose components out (arms
        with fewer than 6 joints): its solutions are then checked against the whole pose."""
        if not hasattr(self, "_partial_mask"):
            from deltagen.solve.numeric import default_mask

            self._partial_mask = not bool(default_mask(self).all())
        return self._partial_mask

    def _reaches_fully(self, q, T, tol=1e-8):
        """Rows where fk(q) is the whole target pose T: position within tol [m], rotation
        within tol [rad] (the closed form's tolerance, analytic.AnalyticSolver.solve)."""
        from deltagen.solve.numeric import pose_error

        Tq, _ = self._core.fk(np.ascontiguousarray(q))
        err = pose_error(Tq, T)
        return (np.linalg.norm(err[:, :3], axis=1) <= tol) & (
            np.linalg.norm(err[:, 3:], axis=1) <= tol
        )

    def _unsolved(self, flat, bad, analytic, config, options, unfit=None):
        """UnreachableError for the unsolved rows ``bad`` of finite rigid targets, naming
        each row's cause: out of reach, an orientation this structure cannot reach, a
        solution only outside the joint limits, or (numeric) no convergence."""

        with np.errstate(all="ignore"):  # huge targets: the distances overflow to inf
            return self._unsolved_rows(flat[bad], bad, analytic, config, options, unfit)

    def _unsolved_rows(self, T, bad, analytic, config, options, unfit):
        from deltagen.errors import UnreachableError

        cause = np.full(bad.size, "", dtype=object)
        dist, reach = self._reach_of(T)
        far = dist > reach
        tilt = self._tilt_of(T)
        solver = self._analytic() if analytic else None
        if solver is not None:
            with np.errstate(all="ignore"):
                _, free = solver.solve(T, limits=False)
                _, within = solver.solve(T)
            k = None if config is None else self.analytic_configs().index(config)
            sel = slice(None) if k is None else k
            exists = np.asarray(free[:, sel]).reshape(bad.size, -1).any(axis=1)
            other = within.any(axis=1) & (k is not None)
            cause[exists] = "its solution lies outside the joint limits"
            cause[~exists & other] = f"no solution in configuration {config!r} (others exist)"
            oriented = np.zeros(bad.size, dtype=bool)
            if solver.detected.position_only_ok:
                _, pos = solver.solve(T, limits=False, position_only=True)
                oriented = pos.any(axis=1)
            cause[(cause == "") & tilt & ~far] = "orientation not reachable: tilted"
            cause[(cause == "") & oriented & ~far] = "orientation not reachable"
        elif not analytic:
            max_iter = options.get("max_iter", 100)
            from deltagen.solve.numeric import RESTARTS

            restarts = options.get("restarts", RESTARTS)
            fitted = np.isin(bad, unfit) if unfit is not None else np.zeros(bad.size, bool)
            cause[fitted & tilt] = "orientation not reachable: tilted"
            cause[fitted & ~tilt] = "pose not reachable: fitted"
            cause[~fitted] = (
                f"no convergence in max_iter={max_iter} steps and restarts={restarts} "
                "(a target outside the joint limits or a poor start; try restarts= or "
                "another q0)"
            )
        cause[far] = "out of reach"
        cause[cause == ""] = (
            "out of reach"
            if solver is not None
            else "no solution found (out of reach or outside the joint limits)"
        )
        parts = []
        for text in dict.fromkeys(cause):
            rows = bad[cause == text]
            if text == "out of reach":
                sub = far[cause == text]
                detail = (
                    f" (the tool point is up to {float(np.max(dist[cause == text])):.4g} m "
                    f"from the base; {self.name} reaches at most {reach:.4g} m)"
                    if np.any(sub)
                    else " (no closed-form solution)"
                )
                text = text + detail
            elif text == "orientation not reachable: tilted":
                text = (
                    f"orientation not reachable by this structure ({self.name} turns the "
                    "tool about the base z axis only; the target's tool axis is tilted)"
                )
            elif text == "pose not reachable: fitted":
                text = (
                    f"pose not reachable by this structure ({self.name} matches the "
                    "components it can move, but not the whole target; mask= asks for "
                    "that fit)"
                )
            elif text == "orientation not reachable":
                text = (
                    f"orientation not reachable by this structure ({self.name} cannot reach "
                    "the target's rotation at that position; the position alone is reachable)"
                )
            parts.append(f"{text} in rows {rows_text(rows)}")
        return UnreachableError(f"ik of {self.name} has no solution: " + "; ".join(parts), bad)

    def _reach_of(self, T):
        """(distance of each target's tool point from the base origin, the arm's reach):
        for arms of revolute joints only the distance between consecutive joint frames is
        constant, so their sum bounds the reach; otherwise the reach is inf."""
        if not hasattr(self, "_reach"):
            reach = np.inf
            if all(j.revolute for j in self.description.joints):
                F, _ = self._core.frames(np.zeros((1, self.n)))
                o = F[0, :, :3, 3]
                reach = float(np.sum(np.linalg.norm(np.diff(o, axis=0), axis=1)))
                reach = reach * (1 + 1e-9) + 1e-12
            self._reach = reach
        base_origin = self.description.base[:3, 3]
        return np.linalg.norm(T[:, :3, 3] - base_origin, axis=1), self._reach

    def _turns_about_z(self):
        """R0 (tool rotation at q = 0) if every reachable tool rotation is Rz(a) R0 (the
        SCARAs, the planar arms: checked at fixed sample configurations), else None."""
        if not hasattr(self, "_z_only"):
            rng = np.random.default_rng(7)
            qs = np.vstack([np.zeros(self.n), rng.uniform(-2.0, 2.0, (8, self.n))])
            R, _ = self._core.fk(np.ascontiguousarray(qs))
            R = R[:, :3, :3]
            Rrel = R @ R[0].T
            z_only = np.all(np.abs(Rrel[:, 2, 2] - 1.0) < 1e-9)
            self._z_only = R[0].copy() if z_only else None
        return self._z_only

    def _tilt_of(self, T):
        """Rows of T whose rotation this arm cannot reach by turning about z (only for the
        arms of _turns_about_z; False elsewhere)."""
        R0 = self._turns_about_z()
        if R0 is None:
            return np.zeros(T.shape[0], dtype=bool)
        Rrel = T[:, :3, :3] @ R0.T
        return np.linalg.norm(Rrel[:, :, 2] - [0.0, 0.0, 1.0], axis=1) > 1e-8

    def _ik_one(self, T, config, q0a, analytic, errors, singular, options):
        """ik's lean paths for one checked rigid pose T (4, 4) C-contiguous: the C closed
        form's branch, or the C numeric solver (every attempt in C) -- ik's result, or None
        when the general path must answer (it then raises or reports the errors)."""
        if analytic:
            if errors == "raise" and q0a is None and self._ik_all_single is not None:
                q = self._ik_single(T, config)
                if q is not None and (singular == "allow" or not self._singular_one(q)):
                    return q
            return None
        if not (
            self.backend == "compiled"
            and (not options or options.keys() <= {"restarts", "seed"})
            and (q0a is None or (q0a.shape == (self.n,) and all(map(math.isfinite, q0a.tolist()))))
        ):
            return None
        q = self._numeric_single(T, q0a, options.get("restarts"), options.get("seed", 0))
        if q is None:
            return None
        if self._fits_tool() and not self._reaches_fully(q[None], T[None])[0]:
            return None  # the general path names the pose the arm cannot take
        if singular == "allow" or not self._singular_one(q):
            return q if errors == "raise" else (q, np.array(True))
        return None

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
        """Fast path of the numerical ik for one checked target T (4, 4) and q0 None or a
        finite (n,) array (ik_numeric.single_solver): q, or None when the general path must
        answer (the first attempt did not converge: restarts and errors are its)."""
        solver = self.__dict__.get("_numeric_solver")
        if solver is None:
            from deltagen.solve.numeric import single_solver

            solver = self._numeric_solver = single_solver(self)
            self._mid_range = np.ascontiguousarray(self._start(None, (1,))[0])
        start = self._mid_range if q0 is None else np.ascontiguousarray(q0)
        if restarts is None:
            return solver(T, start, seed=seed)
        return solver(T, start, int(restarts), seed)

    def _singular_one(self, q):
        """_singular_rows for one configuration, lean (the single-pose fast path)."""
        J = self._jacobian_single(q)
        if J is None or J.shape[0] != J.shape[1]:
            return bool(self._singular_rows(q[None])[0])
        flat = J.reshape(-1)
        bound = SINGULAR_TOL * math.sqrt(float(flat @ flat)) ** J.shape[0]
        if abs(float(_det(J))) >= bound:
            return False
        return bool(self._singular_rows(q[None])[0])

    def _ik_single(self, T, config):
        """Fast path of ik for one checked pose with a C closed form (config checked by
        _ik_request): q, or None when the general path must answer (it raises the errors)."""
        result = self._ik_all_single(T)
        if result is None:
            return None
        q_all, valid = result
        k = int(valid.argmax()) if config is None else self._analytic().configs.index(config)
        return q_all[k] if valid[k] else None

    def _start(self, q0, lead):
        """(N, n) start rows for targets of leading shape ``lead``: q0 (checked by
        _ik_request) broadcast against it, or the middle of the joint ranges (0 where a
        range is unbounded)."""
        count = int(np.prod(lead))
        if q0 is None:
            lim = self.qlim
            bounded = np.isfinite(lim).all(axis=1)
            mid = np.where(bounded, np.where(bounded[:, None], lim, 0.0).mean(axis=1), 0.0)
            return np.tile(mid, (count, 1))
        try:
            start = np.broadcast_to(q0, tuple(lead) + (self.n,))
        except ValueError:
            raise InputError(
                f"q0 of shape {q0.shape} does not broadcast to the targets' leading shape "
                f"{tuple(lead)}"
            ) from None
        return np.ascontiguousarray(start.reshape(count, self.n))

    def _pick_branch(self, q_all, valid_all, config, start):
        """The branch of each row: ``config`` (checked by _ik_request), else the valid
        branch nearest the start rows (N, n), else the first valid one."""
        configs = self.analytic_configs()
        rows = np.arange(q_all.shape[0])
        if config is not None:
            k = configs.index(config)
            return q_all[:, k], valid_all[:, k]
        if start is not None:
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

    @staticmethod
    def _singular_values(J, valid):
        """Singular values (..., min(6, n)) of the valid rows' J, NaN elsewhere (and where
        LAPACK does not converge, which huge finite entries can cause)."""
        sv = np.full(J.shape[:-2] + (min(J.shape[-2:]),), np.nan)
        try:
            sv[valid] = np.linalg.svd(J[valid], compute_uv=False)
        except np.linalg.LinAlgError:
            rows = np.argwhere(valid)
            for index in map(tuple, rows):
                try:
                    sv[index] = np.linalg.svd(J[index], compute_uv=False)
                except np.linalg.LinAlgError:
                    pass
        return sv

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

    def _finish(self, errors, lead, status, outs, names, inputs):
        """Shape the outputs. The status already applies the finite-output rule (the kernels
        and the reference give OK only where every output is finite; outputs transformed in
        Python after a kernel get it from validity.mark_nonfinite where they are made), so
        the outputs are not read again: that pass cost about as much as the kernel."""
        ok = status == st.OK
        if not ok.all():
            if errors == "raise":
                bad = np.flatnonzero(~ok)
                raise InputError(invalid_message(names, inputs, bad), bad)
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
