"""The hexapod (Stewart-Gough platform): ``Hexapod(base_joints, platform_joints, ...)``.

Poses are 4x4 homogeneous transforms of the platform frame in the base frame, single
(4, 4) or batched (..., 4, 4); :meth:`Hexapod.pose` builds them from a position and
roll-pitch-yaw angles or a rotation vector. Leg lengths are (..., 6) [m]; twists and leg
rates (..., 6): (vx, vy, vz, wx, wy, wz) of the platform origin in the base frame, and
dl/dt; wrenches (..., 6): (fx, fy, fz, mx, my, mz) on the platform about its origin, in the
base frame.

* ``ik``: the leg lengths l_i = |p + R b_i - a_i|, closed form (generated C).
* ``fk``: damped Newton in C (codegen/runtime/deltagen_hexapod_fk.c) from a start pose
  (default: the home pose; ``guess=``: one pose or one per point; ``trajectory=True``: each
  point from the previous solution). Converged means max_i |l_i(pose) - l_i| <= ``tol``
  (default 1e-11 m), after which the Newton step of that iterate is still taken, so the
  returned pose reproduces the lengths to rounding (about 1e-15 m) at well-conditioned
  poses, and to about ``tol`` near a singularity; at most ``max_iter``
  (default 50) steps. A point that does not converge is UNREACHABLE (or SINGULAR when the
  Jacobian is singular there) and never returned as valid. Newton finds the solution
  nearest the start (in its basin): a general 6-6 platform has up to 40 assembly modes,
  and fk does not enumerate them.
* ``jacobian`` (dl/d(v, w)), ``condition``, ``leg_rates``, ``twist``, ``leg_forces``
  (the leg forces F with J^T F = w, i.e. F = J^-T w; positive F pushes the platform away
  from the base), ``joint_angles`` and ``within_limits`` (leg lengths in ``leg_limits``,
  joint angles within the cones, a non-singular pose).
* ``position_workspace`` / ``orientation_workspace``: reachable poses over a grid of
  positions at one orientation, or of roll-pitch-yaw angles at one position.

``errors="raise"`` (default) raises InputError, UnreachableError or SingularityError naming
the rows; ``errors="nan"`` gives NaN rows and returns a boolean ``valid`` mask last.
``backend="reference"`` runs the numpy reference (reference/hexapod.py) instead of C; the
class sits on api/base.RobotFamily (``default``/``genhexkins``, ``from_toml``,
``from_geometry``, ``with_backend``, ``threads``, the errors-mode shaping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from deltagen import status as st
from deltagen.api.base import ReferenceCore, RobotFamilyWithDefault
from deltagen.api.hints import Backend
from deltagen.errors import SingularityError, UnreachableError, rows_text
from deltagen.geometry.rotations import matrix_from_rpy, rot_exp
from deltagen.inputs import InputError, as_float_array, check_errors_mode
from deltagen.model.hexapod import HexapodGeometry
from deltagen.status import SINGULAR_TOL

#: fk defaults: tolerance on the leg lengths [m], Newton steps, damping, rotation per step
FK_TOL = 1e-11
FK_MAX_ITER = 50
FK_DAMPING = 1.0
FK_MAX_STEP = 0.5
#: the reference functions a Hexapod calls (reference/hexapod.py)
_CALLS = ("ik", "jacobian", "joint_angles", "fk")


@dataclass(frozen=True)
class FkResult:
    """The full answer of :meth:`Hexapod.fk_result`, per point: the pose (NaN unless OK),
    the status code (deltagen.status), max_i |l_i(pose) - l_i| of the last iterate [m] and
    the Newton steps taken."""

    pose: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray


class Hexapod(RobotFamilyWithDefault):
    """A hexapod: six legs from base joints a_i (base frame) to platform joints b_i
    (platform frame); keyword arguments as HexapodGeometry (model/hexapod.py). The default
    robot (``default()``, also ``genhexkins()``) is LinuxCNC genhexkins' geometry."""

    _core: Any  # CompiledHexapod or a ReferenceCore: the same call signatures
    _model_class = HexapodGeometry
    geometry: HexapodGeometry

    def __init__(
        self,
        base_joints: Any,
        platform_joints: Any,
        *,
        backend: Backend = "compiled",
        threads: int | None = None,
        **geometry: Any,
    ) -> None:
        self.geometry = HexapodGeometry(
            base_joints=base_joints, platform_joints=platform_joints, **geometry
        )
        self._init_backend(backend, threads)

    def _init_backend(self, backend: Any, threads: int | None = None) -> None:
        self._check_backend(backend, threads)
        if backend == "compiled":
            from deltagen.native.hexapod import CompiledHexapod

            self._core = CompiledHexapod(self.geometry, threads=self._threads)
        else:
            from deltagen.reference import hexapod as reference

            self._core = ReferenceCore(reference, (self.geometry,), _CALLS)

    @classmethod
    def from_geometry(
        cls, geometry: HexapodGeometry, backend: Backend = "compiled", threads: int | None = None
    ) -> Hexapod:
        return cls._from_model(geometry, backend, threads)

    @classmethod
    def genhexkins(cls, backend: Backend = "compiled", *, threads: int | None = None) -> Hexapod:
        """LinuxCNC genhexkins' default geometry (model/hexapod.py), in metres: default()."""
        return cls.default(backend, threads=threads)

    def __repr__(self) -> str:
        return f"Hexapod(name={self.geometry.name!r}, backend={self.backend!r})"

    # ----------------------------------------------------------------- poses

    @property
    def home(self) -> np.ndarray:
        """The home pose (4, 4): fk's default start."""
        return self.pose(self.geometry.home_position, rpy=self.geometry.home_rpy)

    @staticmethod
    def pose(position: Any, rpy: Any = None, rotvec: Any = None) -> np.ndarray:
        """Poses (..., 4, 4) from positions (..., 3) [m] and either roll-pitch-yaw angles
        (..., 3) [rad], R = Rz(yaw) Ry(pitch) Rx(roll), or rotation vectors (..., 3) [rad]
        (neither: R = I)."""
        p = as_float_array(position, "position", "(..., 3)")
        if p.shape[-1:] != (3,):
            raise InputError(f"position must have shape (..., 3), got {p.shape}")
        if rpy is not None and rotvec is not None:
            raise InputError("give rpy or rotvec, not both")
        if rpy is not None:
            R = matrix_from_rpy(as_float_array(rpy, "rpy", "(..., 3)"))
        elif rotvec is not None:
            v = as_float_array(rotvec, "rotvec", "(..., 3)")
            if v.shape[-1:] != (3,):
                raise InputError(f"rotvec must have shape (..., 3), got {v.shape}")
            R = rot_exp(v.reshape(-1, 3)).reshape(v.shape[:-1] + (3, 3))
        else:
            R = np.eye(3)
        shape = np.broadcast_shapes(p.shape[:-1], R.shape[:-2])
        T = np.zeros(shape + (4, 4))
        T[..., :3, :3] = R
        T[..., :3, 3] = p
        T[..., 3, 3] = 1.0
        return T

    def _poses(self, pose: Any, name: str = "pose") -> tuple[tuple, np.ndarray, np.ndarray]:
        """(leading shape, flat (N, 16) C-contiguous, ok rows): poses checked for shape; rows
        with a non-finite value or a rotation block that is not a rotation are not ok."""
        T = as_float_array(pose, name, "(..., 4, 4)")
        if T.ndim < 2 or T.shape[-2:] != (4, 4):
            raise InputError(f"{name} must have shape (..., 4, 4), got {T.shape}")
        lead = T.shape[:-2]
        flat = np.ascontiguousarray(T.reshape(-1, 16))
        R = flat.reshape(-1, 4, 4)[:, :3, :3]
        finite = np.all(np.isfinite(flat[:, :12]), axis=1)
        with np.errstate(invalid="ignore", over="ignore"):
            orthonormal = np.all(
                np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)) <= 1e-8, axis=(1, 2)
            ) & (np.linalg.det(np.where(finite[:, None, None], R, 0.0)) > 0)
        return lead, flat, finite & orthonormal

    @staticmethod
    def _bad_input(name: str, rows: np.ndarray) -> InputError:
        what = (
            "a non-finite value, or outputs that overflow"
            if name == "lengths"
            else "a non-finite value or a rotation block that is not a rotation "
            "(R R^T = I to 1e-8, det R > 0)"
        )
        return InputError(f"{name}: {what} in rows {rows_text(rows)}", rows)

    def _raise(self, status, ok, names, inputs):
        """INVALID rows: InputError naming the input (``names``: its name in messages);
        UNREACHABLE (fk only): UnreachableError; else SingularityError."""
        bad = np.flatnonzero(~ok)
        invalid = bad[status[bad] == st.INVALID]
        if invalid.size:
            raise self._bad_input(names, invalid)
        unreachable = bad[status[bad] == st.UNREACHABLE]
        if unreachable.size:
            raise UnreachableError(
                f"fk did not converge (lengths the platform cannot take, or a start "
                f"pose outside the solution's basin) in rows {rows_text(unreachable)}",
                unreachable,
            )
        raise SingularityError(f"singular pose in rows {rows_text(bad)}", bad)

    def _done(self, errors, lead, outs, ok, name):
        """``_finish`` of outputs whose failing rows (not ``ok``: a bad input, or a kernel
        status other than OK) are all the input's fault: INVALID, an InputError naming
        ``name``."""
        status = np.where(ok, st.OK, st.INVALID).astype(np.int8)
        return self._finish(errors, lead, status, outs, name, None)

    # ----------------------------------------------------------------- kinematics

    def ik(self, pose: Any, errors: str = "raise") -> Any:
        """Leg lengths (..., 6) [m] of poses (..., 4, 4)."""
        check_errors_mode(errors)
        lead, flat, ok = self._poses(pose)
        lengths, status = self._core.ik(flat)
        return self._done(errors, lead, [lengths], ok & (status == st.OK), "pose")

    def fk_result(
        self,
        lengths: Any,
        guess: Any = None,
        *,
        trajectory: bool = False,
        tol: float = FK_TOL,
        max_iter: int = FK_MAX_ITER,
        damping: float = FK_DAMPING,
        max_step: float = FK_MAX_STEP,
    ) -> FkResult:
        """The forward kinematics with its status, residuals and iteration counts, shaped
        like ``lengths`` (..., 6); never raises for a point that fails (its status says)."""
        L = as_float_array(lengths, "lengths", "(..., 6)")
        if L.ndim < 1 or L.shape[-1] != 6:
            raise InputError(f"lengths must have shape (..., 6), got {L.shape}")
        for name, value, low in (
            ("tol", tol, 0.0),
            ("damping", damping, -1.0),
            ("max_step", max_step, 0.0),
        ):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > low):
                raise InputError(f"{name} must be a finite number > {max(low, 0)}, got {value!r}")
        if (
            isinstance(max_iter, bool)
            or not isinstance(max_iter, int)
            or not 1 <= max_iter <= 10_000
        ):
            raise InputError(f"max_iter must be an int in [1, 10000], got {max_iter!r}")
        lead = L.shape[:-1]
        flat = np.ascontiguousarray(L.reshape(-1, 6))
        n = len(flat)
        start = self.home if guess is None else guess
        _, G, good = self._poses(start, "guess")
        if len(G) == 1:
            G = np.ascontiguousarray(np.broadcast_to(G, (n, 16)))
            good = np.broadcast_to(good, (n,))
        elif len(G) != n:
            raise InputError(f"guess must be one pose or one per point ({n}), got {len(G)}")
        if not good.all():
            raise self._bad_input("guess", np.flatnonzero(~good))
        P, residual, iterations, status = self._core.fk(
            flat, G, tol, damping, max_step, max_iter, warm_start=trajectory
        )
        return FkResult(
            P.reshape(lead + (4, 4)),
            status.reshape(lead),
            residual.reshape(lead),
            iterations.reshape(lead),
        )

    def fk(self, lengths: Any, guess: Any = None, errors: str = "raise", **options: Any) -> Any:
        """Poses (..., 4, 4) of leg lengths (..., 6) [m] by damped Newton in C from
        ``guess`` (default the home pose); ``trajectory=True``: each point starts from the
        previous point's pose. Options (``tol``, ``max_iter``, ``damping``, ``max_step``)
        as :meth:`fk_result`."""
        check_errors_mode(errors)
        result = self.fk_result(lengths, guess, **options)
        lead = result.status.shape
        status = result.status.reshape(-1)
        return self._finish(errors, lead, status, [result.pose.reshape(-1, 4, 4)], "lengths", None)

    # ----------------------------------------------------------------- rates and forces

    def _jacobian(self, pose):
        lead, flat, ok = self._poses(pose)
        _, J, status = self._core.jacobian(flat)
        return lead, J, ok & (status == st.OK)

    def jacobian(self, pose: Any, errors: str = "raise") -> Any:
        """The leg-length Jacobian J (..., 6, 6) = dl/d(v, w): row i is
        (u_i, (R b_i) x u_i), u_i the unit vector of leg i."""
        check_errors_mode(errors)
        lead, J, ok = self._jacobian(pose)
        return self._done(errors, lead, [J], ok, "pose")

    def condition(self, pose: Any, errors: str = "raise") -> Any:
        """The 2-norm condition number of J (...,), rotation columns scaled by the robot's
        size (so it does not depend on the length unit); inf at a singular pose."""
        check_errors_mode(errors)
        lead, J, ok = self._jacobian(pose)
        scaled = J.copy()
        scaled[:, :, 3:] /= self.geometry.size
        with np.errstate(all="ignore"):
            s = np.linalg.svd(np.where(ok[:, None, None], scaled, 0.0), compute_uv=False)
            cond = np.where(s[:, -1] > 0, s[:, 0] / s[:, -1], np.inf)
        return self._done(errors, lead, [cond], ok, "pose")

    def _solve(self, pose, rhs, name, transpose):
        lead, J, ok = self._jacobian(pose)
        b = as_float_array(rhs, name, "(..., 6)")
        if b.shape[-1:] != (6,):
            raise InputError(f"{name} must have shape (..., 6), got {b.shape}")
        b = np.broadcast_to(b, lead + (6,)).reshape(-1, 6)
        ok &= np.all(np.isfinite(b), axis=1)
        A = np.swapaxes(J, 1, 2) if transpose else J
        with np.errstate(all="ignore"):
            s = np.linalg.svd(np.where(ok[:, None, None], J, 0.0), compute_uv=False)
        singular = ok & ~(s[:, -1] > self.geometry.singular_tol * s[:, 0])
        ok &= ~singular
        x = np.full_like(b, np.nan)
        if ok.any():
            x[ok] = np.linalg.solve(A[ok], b[ok, :, None])[..., 0]
        status = np.where(ok, st.OK, np.where(singular, st.SINGULAR, st.INVALID))
        return lead, x, status

    def leg_rates(self, pose: Any, twist: Any, errors: str = "raise") -> Any:
        """Leg rates dl/dt (..., 6) [m/s] of a platform twist (v, w) (..., 6)."""
        check_errors_mode(errors)
        lead, J, ok = self._jacobian(pose)
        v = as_float_array(twist, "twist", "(..., 6)")
        if v.shape[-1:] != (6,):
            raise InputError(f"twist must have shape (..., 6), got {v.shape}")
        v = np.broadcast_to(v, lead + (6,)).reshape(-1, 6)
        ok &= np.all(np.isfinite(v), axis=1)
        with np.errstate(all="ignore"):
            ld = np.einsum("nij,nj->ni", J, v)
        return self._done(errors, lead, [ld], ok, "pose or twist")

    def twist(self, pose: Any, leg_rates: Any, errors: str = "raise") -> Any:
        """The platform twist (v, w) (..., 6) of leg rates (..., 6): J^-1 ldot."""
        check_errors_mode(errors)
        lead, x, status = self._solve(pose, leg_rates, "leg_rates", transpose=False)
        return self._finish(errors, lead, status, [x], "pose or leg_rates", None)

    def leg_forces(self, pose: Any, wrench: Any, errors: str = "raise") -> Any:
        """Leg forces F (..., 6) [N] whose resultant wrench on the platform is ``wrench``
        (fx, fy, fz, mx, my, mz about the platform origin, base frame): J^T F = w, so
        F = J^-T w; F_i > 0 pushes the platform away from the base. To hold an external
        load w_ext, pass -w_ext (a payload of mass m: wrench (0, 0, m g, ...))."""
        check_errors_mode(errors)
        lead, x, status = self._solve(pose, wrench, "wrench", transpose=True)
        return self._finish(errors, lead, status, [x], "pose or wrench", None)

    # ----------------------------------------------------------------- limits

    def joint_angles(self, pose: Any, errors: str = "raise") -> Any:
        """(..., 12) [rad]: the angle of each leg against its base joint's axis n_a,i, then
        against its platform joint's axis R n_b,i (the leg pointing to the base)."""
        check_errors_mode(errors)
        lead, flat, ok = self._poses(pose)
        angles, status = self._core.joint_angles(flat)
        return self._done(errors, lead, [angles], ok & (status == st.OK), "pose")

    def limits(self, pose: Any) -> dict[str, np.ndarray]:
        """Per pose (...,) booleans: ``legs`` (every length within leg_limits), ``base_joints``
        and ``platform_joints`` (every angle within its cone), ``nonsingular`` (cond(J)
        below 1 / singular_tol) and ``reachable`` (all four); invalid poses are False."""
        lead, flat, ok = self._poses(pose)
        g = self.geometry
        T = np.where(ok[:, None], flat, np.eye(4).reshape(16)).reshape(-1, 4, 4)  # bad: harmless
        lengths = self.ik(T)
        angles = self.joint_angles(T)
        cond = self.condition(T, errors="nan")[0]
        lo, hi = g.leg_limits
        legs = ok & np.all((lengths >= lo) & (lengths <= hi), axis=1)
        base = ok & np.all(angles[:, :6] <= g.base_cone, axis=1)
        platform = ok & np.all(angles[:, 6:] <= g.platform_cone, axis=1)
        nonsingular = ok & (cond < 1.0 / g.singular_tol)
        out = {
            "legs": legs,
            "base_joints": base,
            "platform_joints": platform,
            "nonsingular": nonsingular,
            "reachable": legs & base & platform & nonsingular,
        }
        return {k: v.reshape(lead) for k, v in out.items()}

    def within_limits(self, pose: Any) -> np.ndarray:
        """(...,) True where the pose is reachable: :meth:`limits` ``reachable``."""
        return self.limits(pose)["reachable"]

    # ----------------------------------------------------------------- workspace

    def position_workspace(
        self, x: Any, y: Any, z: Any, rpy: Any = (0.0, 0.0, 0.0)
    ) -> HexapodWorkspace:
        """Reachability over the grid of positions x by y by z (1-D arrays [m]) at one
        orientation (roll, pitch, yaw [rad])."""
        axes = [np.asarray(v, dtype=float).reshape(-1) for v in (x, y, z)]
        X, Y, Z = np.meshgrid(*axes, indexing="ij")
        P = np.stack([X, Y, Z], axis=-1)
        T = self.pose(P, rpy=np.broadcast_to(np.asarray(rpy, dtype=float), P.shape))
        return self._workspace(T, axes, ("x [m]", "y [m]", "z [m]"))

    def orientation_workspace(
        self, roll: Any, pitch: Any, yaw: Any, position: Any = None
    ) -> HexapodWorkspace:
        """Reachability over the grid of roll by pitch by yaw angles (1-D arrays [rad]) at one
        position (default the home position)."""
        axes = [np.asarray(v, dtype=float).reshape(-1) for v in (roll, pitch, yaw)]
        A = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        p = self.geometry.home_position if position is None else position
        T = self.pose(np.broadcast_to(np.asarray(p, dtype=float), A.shape), rpy=A)
        return self._workspace(T, axes, ("roll [rad]", "pitch [rad]", "yaw [rad]"))

    def _workspace(self, T: np.ndarray, axes: list, labels: tuple) -> HexapodWorkspace:
        limits = self.limits(T)
        cond = self.condition(T, errors="nan")[0]
        return HexapodWorkspace(
            axes=tuple(axes),
            labels=labels,
            reachable=limits["reachable"],
            condition=np.where(limits["reachable"], cond, np.nan),
            limits=limits,
        )


@dataclass(frozen=True)
class HexapodWorkspace:
    """A grid of poses: ``axes`` (three 1-D arrays), their ``labels``, ``reachable`` and
    ``condition`` (NaN where not reachable) on the grid, and every limit's mask."""

    axes: tuple
    labels: tuple
    reachable: np.ndarray
    condition: np.ndarray
    limits: dict

    @property
    def fraction(self) -> float:
        """The reachable fraction of the grid."""
        return float(self.reachable.mean())

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(M, 3) grid coordinates of the reachable poses (positions [m] for a position
        workspace) and their (M,) condition numbers, as DeltaWorkspace.points gives them."""
        grid = np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1)
        return grid[self.reachable], self.condition[self.reachable]


__all__ = ["FkResult", "Hexapod", "HexapodWorkspace", "SINGULAR_TOL"]
