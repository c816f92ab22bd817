"""LinearDelta and Tripod: the Python API of the two three-sphere machines (the linear
delta of Klipper's ``delta`` kinematics, the tripod of LinuxCNC's ``tripodkins``).

Every method takes one row of 3 or a batch with any leading dimensions (..., 3) and returns
arrays of the same leading shape. ``errors="raise"`` (default) raises on any failing row,
naming the rows; ``errors="nan"`` returns NaN there plus a boolean ``valid`` mask last.
fk and ik also return singular but well defined poses (the workspace boundary); fk_vel,
fk_acc and jacobian, which need D^-1, treat them as errors.

Joints q: the linear delta's carriage heights h (m, along the towers, z up; the effector
hangs below the carriages), the tripod's strut lengths l (m).
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
from deltagen.errors import SingularityError, UnreachableError, rows_text
from deltagen.inputs import InputError, broadcast_rows, check_errors_mode
from deltagen.model.linear_delta import LinearDeltaGeometry, TripodGeometry

__all__ = ["LinearDelta", "Tripod"]
#: Klipper's default tower angles, 210, 330, 90 deg [rad]
_KLIPPER_ANGLES = (math.radians(210.0), math.radians(330.0), math.radians(90.0))
#: the reference functions of the three-sphere machines (reference/linear_delta.py)
_CALLS = ("fk", "fk_vel", "fk_acc", "jacobian", "ik", "ik_vel", "ik_acc")


def _no_lean(name: str) -> None:
    """The reference backend's one-pose path of kernel ``name``: none (the general path)."""
    return None


class _ThreeSpheres(RobotFamilyWithDefault):
    """What the linear delta and the tripod share: the calls, the modes and the backends."""

    kind = ""
    joint = "q"  # the name of the joint values in messages
    _core: Any
    geometry: Any  # LinearDeltaGeometry or TripodGeometry
    backend: Backend
    _unreachable_ik = ""
    _unreachable_fk = ""

    def _init_backend(self, backend: Any, threads: int | None = None) -> None:
        self._check_backend(backend, threads)
        if backend == "compiled":
            from deltagen.native.linear_delta import CompiledTrilateration

            self._core = CompiledTrilateration(self.kind, self.geometry, self._threads)
            # lean paths for one pose (same C function, same results; native.lean)
            single = self._core.single
        else:
            from deltagen.reference import linear_delta as reference

            self._core = ReferenceCore(reference, (self.kind, self.geometry), _CALLS)
            single = _no_lean
        self._fk_single, self._ik_single = single("fk"), single("ik")
        self._jacobian_single = single("jacobian")
        self._fk_vel_single, self._fk_acc_single = single("fk_vel"), single("fk_acc")
        self._ik_vel_single, self._ik_acc_single = single("ik_vel"), single("ik_acc")

    @classmethod
    def from_geometry(
        cls, geometry: Any, backend: Backend = "compiled", *, threads: int | None = None
    ) -> Any:
        return cls._from_model(geometry, backend, threads)

    def fk(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """Point p (..., 3) [m] of joint values q (..., 3): the three-sphere intersection."""
        if type(errors) is str and errors == "raise" and self._fk_single is not None:
            out = self._fk_single(q)  # one pose: the lean path (None: the general path)
            if out is not None:
                return out
        lead, (qf,) = self._prepare(errors, {self.joint: q})
        p, status = self._core.fk(qf)
        return self._finish(errors, lead, status, [p], (self.joint,), [qf], allow_singular=True)

    def ik(self, p: ArrayLike, errors: Errors = "raise") -> Result:
        """Joint values q (..., 3) of points p (..., 3) [m], in closed form."""
        if type(errors) is str and errors == "raise" and self._ik_single is not None:
            out = self._ik_single(p)
            if out is not None:
                return out
        lead, (pf,) = self._prepare(errors, {"p": p})
        q, status = self._core.ik(pf)
        return self._finish(errors, lead, status, [q], ("p",), [pf], allow_singular=True)

    def jacobian(self, q: ArrayLike, errors: Errors = "raise") -> Result:
        """J (..., 3, 3) with pdot = J qdot: D^-1 diag(g), D's rows p - S_i."""
        if type(errors) is str and errors == "raise" and self._jacobian_single is not None:
            out = self._jacobian_single(q)
            if out is not None:
                return out
        lead, (qf,) = self._prepare(errors, {self.joint: q})
        J, status = self._core.jacobian(qf)
        return self._finish(errors, lead, status, [J], (self.joint,), [qf], trailing=[(3, 3)])

    def fk_vel(self, q: ArrayLike, qd: ArrayLike, errors: Errors = "raise") -> Result:
        """(p, pdot) from (q, qdot)."""
        if type(errors) is str and errors == "raise" and self._fk_vel_single is not None:
            out = self._fk_vel_single(q, qd)
            if out is not None:
                return out
        names = (self.joint, self.joint + "d")
        lead, flat = self._prepare(errors, dict(zip(names, (q, qd))))
        p, pd, status = self._core.fk_vel(*flat)
        return self._finish(errors, lead, status, [p, pd], names, flat)

    def fk_acc(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """(p, pdot, pddot) from (q, qdot, qddot)."""
        if type(errors) is str and errors == "raise" and self._fk_acc_single is not None:
            out = self._fk_acc_single(q, qd, qdd)
            if out is not None:
                return out
        names = (self.joint, self.joint + "d", self.joint + "dd")
        lead, flat = self._prepare(errors, dict(zip(names, (q, qd, qdd))))
        p, pd, pdd, status = self._core.fk_acc(*flat)
        return self._finish(errors, lead, status, [p, pd, pdd], names, flat)

    def ik_vel(self, p: ArrayLike, pd: ArrayLike, errors: Errors = "raise") -> Result:
        """(q, qdot) from (p, pdot): qdot_i = D_i . pdot / g_i (D rows p - S_i; g_i the
        arm's vertical component, or the strut length). A linear delta's arm lying
        horizontal has no finite carriage rate (SingularityError, or NaN)."""
        if type(errors) is str and errors == "raise" and self._ik_vel_single is not None:
            out = self._ik_vel_single(p, pd)
            if out is not None:
                return out
        lead, flat = self._prepare(errors, {"p": p, "pd": pd})
        q, qd, status = self._core.ik_vel(*flat)
        return self._finish(errors, lead, status, [q, qd], ("p", "pd"), flat, allow_singular=True)

    def ik_acc(
        self, p: ArrayLike, pd: ArrayLike, pdd: ArrayLike, errors: Errors = "raise"
    ) -> Result:
        """(q, qdot, qddot) from (p, pdot, pddot): the second time derivative of the sphere
        constraints solved for qddot (diag(g) is diagonal)."""
        if type(errors) is str and errors == "raise" and self._ik_acc_single is not None:
            out = self._ik_acc_single(p, pd, pdd)
            if out is not None:
                return out
        names = ("p", "pd", "pdd")
        lead, flat = self._prepare(errors, dict(zip(names, (p, pd, pdd))))
        q, qd, qdd, status = self._core.ik_acc(*flat)
        return self._finish(errors, lead, status, [q, qd, qdd], names, flat, allow_singular=True)

    def workspace(self, step: float | None = None, **options: Any) -> Any:
        """The usable workspace on a voxel grid with its dexterity maps (as the rotary
        delta's: deltagen.api.workspace.delta_workspace; the joint limits are the carriage
        travel or the strut range)."""
        from deltagen.api.workspace import delta_workspace

        return delta_workspace(self, step, **options)

    def workspace_extent(self) -> tuple[float, float, tuple, tuple[float, float]]:
        """(length scale, reach, default box ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)),
        joint travel) [m] for the workspace tooling (api/workspace.py)."""
        raise NotImplementedError

    # -- helpers ------------------------------------------------------------------------

    @staticmethod
    def _prepare(errors, arrays):
        check_errors_mode(errors)
        lead, _, flat = broadcast_rows(arrays, widths=(3,))
        return lead, flat

    def _raise(self, status, ok, names, inputs):
        bad = np.flatnonzero(~ok)
        invalid = bad[status[bad] == st.INVALID]
        if invalid.size:
            raise InputError(invalid_message(names, inputs, invalid), invalid)
        unreachable = bad[status[bad] == st.UNREACHABLE]
        if unreachable.size:
            what = self._unreachable_ik if names[0] == "p" else self._unreachable_fk
            raise UnreachableError(
                f"unreachable pose ({what}) in rows {rows_text(unreachable)}", unreachable
            )
        raise SingularityError(f"singular pose in rows {rows_text(bad)}", bad)


class LinearDelta(_ThreeSpheres):
    """Linear delta (a delta 3D printer): three vertical towers at (radius_i, angle_i), a
    carriage on each at height h_i, an arm of length arm_i from each carriage to the
    effector point (Klipper's ``delta`` kinematics). Lengths in metres, angles in radians.
    ``radius`` and ``arm_length`` take one number or three (per tower)."""

    kind = "linear_delta"
    joint = "h"
    _model_class = LinearDeltaGeometry
    _unreachable_ik = (
        "an arm cannot reach the point, or only with the effector above the carriages' plane"
    )
    _unreachable_fk = "the arms' spheres do not meet"

    def __init__(
        self,
        radius: float | tuple[float, float, float],
        arm_length: float | tuple[float, float, float],
        angle: tuple[float, float, float] = _KLIPPER_ANGLES,
        *,
        carriage_range: tuple[float, float] = (0.0, 1.0),
        name: str = "linear_delta",
        singular_tol: float = st.SINGULAR_TOL,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> None:
        self.geometry = LinearDeltaGeometry(
            radius=radius,  # type: ignore[arg-type]
            angle=angle,
            arm_length=arm_length,  # type: ignore[arg-type]
            carriage_range=carriage_range,
            singular_tol=singular_tol,
            name=name,
        )
        self._init_backend(backend, threads)

    @classmethod
    def from_klipper(
        cls, path: PathLike, backend: Backend = "compiled", *, threads: int | None = None
    ) -> LinearDelta:
        """The linear delta of a Klipper printer.cfg ([printer] kinematics: delta), in metres
        with Klipper's frame (z above the bed): carriage heights are Klipper's stepper
        positions (deltagen.model.klipper.read_klipper_delta gives the endstops too)."""
        from deltagen.model.klipper import read_klipper_delta

        return cls.from_geometry(read_klipper_delta(path).geometry, backend, threads=threads)

    def workspace_extent(self) -> tuple[float, float, tuple, tuple[float, float]]:
        """The arm length, the reach from the axis (tower radius + arm), a box around the
        towers from the lowest effector (lowest carriage - arm) to the highest carriage,
        and the carriage travel."""
        g = self.geometry
        arm = max(g.arm_length)
        lo, hi = g.carriage_range
        reach = max(g.radius) + arm
        return arm, reach, ((-reach, reach), (-reach, reach), (lo - arm, hi)), (lo, hi)

    def __repr__(self) -> str:
        g = self.geometry
        deg = ", ".join(f"{math.degrees(a):g}" for a in g.angle)
        return (
            f"LinearDelta(radius={g.radius!r}, arm_length={g.arm_length!r}, "
            f"angle_deg=({deg}), backend={self.backend!r})"
        )


class Tripod(_ThreeSpheres):
    """The tripod of LinuxCNC's ``tripodkins``: struts from A = (0, 0, 0), B = (b_x, 0, 0)
    and C = (c_x, c_y, 0) to one point D; the joints are the strut lengths |AD|, |BD|,
    |CD| [m]. fk returns the solution on ``side`` ("above": z > 0, "below": z < 0) of the
    base plane; :meth:`mirror` the same tripod with the other side chosen."""

    kind = "tripod"
    joint = "l"
    _model_class = TripodGeometry
    _unreachable_ik = "the point lies on the other side of the base plane than the tripod's side"
    _unreachable_fk = "the struts' spheres do not meet, or a strut length is negative"

    def __init__(
        self,
        b_x: float,
        c_x: float,
        c_y: float,
        side: str = "above",
        *,
        strut_range: tuple[float, float] = (0.0, 2.0),
        name: str = "tripod",
        singular_tol: float = st.SINGULAR_TOL,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> None:
        self.geometry = TripodGeometry(
            b_x=b_x,
            c_x=c_x,
            c_y=c_y,
            side=side,
            strut_range=strut_range,
            singular_tol=singular_tol,
            name=name,
        )
        self._init_backend(backend, threads)

    def workspace_extent(self) -> tuple[float, float, tuple, tuple[float, float]]:
        """The longest strut, the reach, the box of the base points grown by the longest
        strut on the chosen side of the base plane, and the strut travel."""
        g = self.geometry
        lo, hi = g.strut_range
        xs, ys = (0.0, g.b_x, g.c_x), (0.0, g.c_y)
        box = (
            (min(xs) - hi, max(xs) + hi),
            (min(ys) - hi, max(ys) + hi),
            (0.0, hi) if g.side == "above" else (-hi, 0.0),
        )
        return hi, hi + max(abs(g.b_x), math.hypot(g.c_x, g.c_y)), box, (lo, hi)

    def mirror(self) -> Tripod:
        """The same tripod with the other side of the base plane chosen (fk's other
        solution, the mirror image of each point in the base plane)."""
        from dataclasses import replace

        other = "below" if self.geometry.side == "above" else "above"
        return type(self).from_geometry(
            replace(self.geometry, side=other), self.backend, threads=self._threads
        )

    def __repr__(self) -> str:
        g = self.geometry
        return (
            f"Tripod(b_x={g.b_x!r}, c_x={g.c_x!r}, c_y={g.c_y!r}, side={g.side!r}, "
            f"backend={self.backend!r})"
        )
