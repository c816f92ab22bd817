"""FiveAxisMachine: the Python API of the 5-axis NC machines (model/five_axis.py gives the
layouts, the frames and the chain).

Joints are (..., 5): x, y, z [m], the tilt axis A or B [rad], C [rad]. The tool tip p and
the tool axis d (from the tip into the spindle) are (..., 3) in the workpiece frame.
``errors="raise"`` (default) raises on a failing row, naming the rows; ``errors="nan"``
returns NaN there and a boolean ``valid`` mask as the last result. A pose with the tool
axis parallel to the C axis is SINGULAR (C is undetermined and keeps the previous value):
it is a valid, finite answer; ``return_status=True`` returns the per-row status codes
(deltagen.status: OK, SINGULAR, INVALID) last, so a caller sees where C was held.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.api.base import ReferenceCore, RobotFamily
from deltagen.api.hints import Backend, Errors, Result
from deltagen.api.validity import invalid_message
from deltagen.errors import GeometryError, UnreachableError, rows_text
from deltagen.inputs import InputError, as_rows, check_errors_mode
from deltagen.model.five_axis import MachineDescription

__all__ = ["FiveAxisMachine", "bundled_machines"]

#: the reference functions a FiveAxisMachine calls (reference/five_axis.py)
_CALLS = ("fk", "ik", "ik_all")


def _is_machine_file(path: Path) -> bool:
    import tomllib

    try:
        return "machine" in tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False


def bundled_machines() -> list[str]:
    """Names of the bundled machines (robots/*.toml with a [machine] table)."""
    from deltagen.paths import robots_dir

    return [p.stem for p in sorted(robots_dir().glob("*.toml")) if _is_machine_file(p)]


class FiveAxisMachine(RobotFamily):
    """A 5-axis NC machine: layout "table-table" (trunnion), "head-head" or "table-head",
    rotary "AC" or "BC" (the tilt axis, then C), the pivot points and the tool length in
    metres (model/five_axis.py)."""

    _core: Any  # CompiledFiveAxis or a ReferenceCore: the same call signatures
    _model_attr = "description"
    _model_class = MachineDescription

    def __init__(
        self,
        layout: str,
        rotary: str,
        *,
        tool_length: float = 0.0,
        tilt_limits: tuple[float, float] = (-np.pi, np.pi),
        c_pivot: ArrayLike = (0.0, 0.0, 0.0),
        tilt_pivot: ArrayLike = (0.0, 0.0, 0.0),
        head_pivot: ArrayLike = (0.0, 0.0, 0.0),
        spindle_offset: ArrayLike = (0.0, 0.0, 0.0),
        name: str = "machine",
        singular_tol: float = st.SINGULAR_TOL,
        backend: Backend = "compiled",
        threads: int | None = None,
    ) -> None:
        self.description = MachineDescription(
            layout=layout,
            rotary=rotary,
            tool_length=tool_length,
            tilt_limits=tilt_limits,
            c_pivot=c_pivot,  # type: ignore[arg-type]
            tilt_pivot=tilt_pivot,  # type: ignore[arg-type]
            head_pivot=head_pivot,  # type: ignore[arg-type]
            spindle_offset=spindle_offset,  # type: ignore[arg-type]
            name=name,
            singular_tol=singular_tol,
        )
        self._init_backend(backend, threads)

    def _init_backend(self, backend, threads=None):
        self._check_backend(backend, threads)
        if backend == "compiled":
            from deltagen.native.five_axis import CompiledFiveAxis

            self._core = CompiledFiveAxis(self.description, self._threads)
            self._fk_single = self._core.single("fk")
            self._ik_single = self._core.single("ik")
        else:
            from deltagen.reference import five_axis as reference

            self._core = ReferenceCore(reference, (self.description,), _CALLS)
            self._fk_single = self._ik_single = None

    @classmethod
    def from_description(
        cls,
        description: MachineDescription,
        backend: Backend = "compiled",
        *,
        threads: int | None = None,
    ) -> FiveAxisMachine:
        return cls._from_model(description, backend, threads)

    @classmethod
    def load(
        cls, name: str, backend: Backend = "compiled", *, threads: int | None = None
    ) -> FiveAxisMachine:
        """A bundled machine by name (robots/<name>.toml with a [machine] table)."""
        from deltagen.paths import robots_dir

        if name not in bundled_machines():
            raise GeometryError(
                f"no bundled machine {name!r}; bundled: {', '.join(bundled_machines())}"
            )
        return cls.from_toml(robots_dir() / f"{name}.toml", backend, threads=threads)

    def __repr__(self) -> str:
        g = self.description
        return (
            f"FiveAxisMachine(layout={g.layout!r}, rotary={g.rotary!r}, "
            f"tool_length={g.tool_length!r}, name={g.name!r}, backend={self.backend!r})"
        )

    # -- kinematics ---------------------------------------------------------------------

    def fk(
        self, joints: ArrayLike, errors: Errors = "raise", return_status: bool = False
    ) -> Result:
        """Tool tip p (..., 3) [m] and tool axis d (..., 3) (unit, from the tip into the
        spindle) in the workpiece frame, of joints (..., 5): x, y, z [m], tilt, C [rad]."""
        if not return_status and type(errors) is str and errors == "raise":
            if self._fk_single is not None:
                out = self._fk_single(joints)
                if out is not None:
                    return out
        check_errors_mode(errors)
        j = as_rows(joints, "joints", (5,))
        lead = j.shape[:-1]
        jf = np.ascontiguousarray(j.reshape(-1, 5))
        p, d, status = self._core.fk(jf)
        return self._finish(errors, lead, status, [p, d], ["joints"], [jf], return_status)

    def ik(
        self,
        p: ArrayLike,
        d: ArrayLike,
        previous: ArrayLike | None = None,
        errors: Errors = "raise",
        return_status: bool = False,
    ) -> Result:
        """Joints (..., 5) that put the tool tip at p (..., 3) with the tool axis along d
        (..., 3, any length > 0): of the two rotary branches within the tilt's travel the
        one nearest ``previous`` (..., 5; default zeros) in tilt and C, C at its turn nearest
        the previous C. Where the tool axis is parallel to the C axis (SINGULAR) C keeps the
        previous value; where neither branch is within the travel the row is UNREACHABLE."""
        prev = np.zeros(5) if previous is None else previous
        if not return_status and type(errors) is str and errors == "raise":
            if self._ik_single is not None:
                out = self._ik_single(p, d, prev)
                if out is not None:
                    return out
        check_errors_mode(errors)
        lead, flat = self._inverse_inputs(p, d, prev)
        j, status = self._core.ik(*flat)
        return self._finish(errors, lead, status, [j], ["p", "d", "previous"], flat, return_status)

    def ik_all(
        self,
        p: ArrayLike,
        d: ArrayLike,
        previous: ArrayLike | None = None,
        errors: Errors = "raise",
        return_status: bool = False,
    ) -> Result:
        """Both rotary branches: joints (..., 2, 5), branch 1 with sin(tilt) >= 0, branch 2
        with sin(tilt) <= 0 (C at the turn nearest ``previous``'s C), and valid (..., 2):
        False (and NaN joints) where the branch's tilt lies beyond its travel
        (``tilt_limits``). errors="raise" raises on invalid input rows; "nan" leaves them
        NaN, not valid."""
        check_errors_mode(errors)
        prev = np.zeros(5) if previous is None else previous
        lead, flat = self._inverse_inputs(p, d, prev)
        j, valid, status = self._core.ik_all(*flat)
        if errors == "raise" and np.any(status == st.INVALID):
            self._raise(status, ["p", "d", "previous"], flat)
        j[~valid] = np.nan
        out = (j.reshape(lead + (2, 5)), valid.reshape(lead + (2,)))
        return (*out, status.reshape(lead)) if return_status else out

    def ik_path(
        self,
        p: ArrayLike,
        d: ArrayLike,
        previous: ArrayLike | None = None,
        errors: Errors = "raise",
    ) -> Result:
        """Joints (N, 5) along a path of N tool tips (N, 3) and tool axes (N, 3): each
        point's ik takes the joints of the point before (the first takes ``previous``,
        default zeros), so C runs on without 2 pi jumps and the branch does not flip;
        through a SINGULAR point C holds. errors="nan": an invalid row is NaN (the next
        row continues from the last valid one) and valid (N,) is returned last."""
        check_errors_mode(errors)
        pf, df = as_rows(p, "p", (3,)), as_rows(d, "d", (3,))
        if pf.ndim != 2 or df.shape != pf.shape:
            raise InputError(f"p and d must be (N, 3) of one shape, got {pf.shape}, {df.shape}")
        last = np.zeros(5) if previous is None else as_rows(previous, "previous", (5,))
        if last.shape != (5,):
            raise InputError(f"previous must be one joint row (5,), got {last.shape}")
        out = np.empty((pf.shape[0], 5))
        valid = np.ones(pf.shape[0], dtype=bool)
        for i in range(pf.shape[0]):
            if errors == "raise":
                try:
                    last = out[i] = self.ik(pf[i], df[i], last)
                except InputError as exc:
                    raise InputError(f"path point {i}: {exc}", [i]) from None
                continue
            row, ok = self.ik(pf[i], df[i], last, errors="nan")
            out[i], valid[i] = row, ok
            if ok:
                last = row
        return out if errors == "raise" else (out, valid)

    # -- helpers ------------------------------------------------------------------------

    @staticmethod
    def _inverse_inputs(p, d, prev):
        arrays = [as_rows(p, "p", (3,)), as_rows(d, "d", (3,)), as_rows(prev, "previous", (5,))]
        try:
            lead = np.broadcast_shapes(*(a.shape[:-1] for a in arrays))
        except ValueError:
            shapes = {k: a.shape for k, a in zip(("p", "d", "previous"), arrays)}
            raise InputError(f"argument shapes do not broadcast: {shapes}") from None
        flat = [
            np.ascontiguousarray(np.broadcast_to(a, lead + a.shape[-1:]).reshape(-1, a.shape[-1]))
            for a in arrays
        ]
        return lead, flat

    def _finish(self, errors, lead, status, outs, names, inputs, return_status):
        # SINGULAR rows are given, finite (the kernel's status)
        ok = (status != st.INVALID) & (status != st.UNREACHABLE)
        if errors == "raise" and not ok.all():
            self._raise(status, names, inputs)
        shaped = [o.reshape(lead + o.shape[1:]) for o in outs]
        extra = [status.reshape(lead)] if return_status else []
        if errors == "nan":
            for o in outs:
                o[~ok] = np.nan
            return (*shaped, ok.reshape(lead), *extra)
        if len(shaped) == 1 and not extra:
            return shaped[0]
        return (*shaped, *extra)

    def _raise(self, status, names, inputs):
        bad = np.flatnonzero(status == st.INVALID)
        if bad.size == 0:
            rows = np.flatnonzero(status == st.UNREACHABLE)
            lo, hi = self.description.tilt_limits
            raise UnreachableError(
                f"both rotary branches put the tilt axis {self.description.tilt_axis} beyond "
                f"its travel [{lo:.6g}, {hi:.6g}] rad in rows {rows_text(rows)}",
                rows,
            )
        if len(inputs) > 1:  # the inverse: a zero tool axis is invalid too
            zero = bad[np.all(inputs[1][bad] == 0.0, axis=1)]
            if zero.size:
                raise InputError(
                    f"d (the tool axis) has zero length in rows {rows_text(zero)}", zero
                )
        raise InputError(invalid_message(names, inputs, bad), bad)
