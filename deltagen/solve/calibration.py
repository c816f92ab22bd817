"""Calibration of a built delta robot: identify per-chain geometry deviations from measured
pairs (crank angles q as the encoders read them, platform positions p as a probe or a
tracker measures them, in the base frame O).

Model: p_i = fk(q_i; pi) with pi the chosen parameters of the asymmetric geometry
(deltagen.model.delta): per chain r_a,i, r_b,i, l_a,i, l_b,i, theta_i and the encoder
offset q_offset,i. Least squares min_pi sum |fk(q_i; pi) - p_i|^2 by Levenberg-Marquardt
(Marquardt's damping on the column-scaled Jacobian, steps through its SVD). The Jacobian
dp/dpi is the generated C kernel deltagen_delta_fk_param_jacobian (SymPy's implicit
derivative of eq. (1), deltagen/derive/delta/calibration.py).

Identifiability: the singular values of the column-scaled Jacobian at the solution. A
singular value below ``rcond`` times the largest is a direction in parameter space the
measurements do not see: the parameters with weight in it are reported together as an
unidentifiable set (e.g. r_a,i and r_b,i, which enter only as r_a,i - r_b,i), the step
leaves that direction alone (minimum-norm), and their uncertainty is infinite.
Uncertainty: the covariance sigma^2 (J^T J)^+ with sigma^2 = RSS / (3N - rank) from the
residual (or the measurement noise given as ``sigma``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from deltagen import status as st
from deltagen.errors import KinematicsError, rows_text
from deltagen.inputs import InputError
from deltagen.model.delta import DeltaGeometry
from deltagen.native.delta import CompiledDelta

#: Per-chain parameter families and their column block in the fk_param_jacobian kernel
#: (r_a and r_b share the block of r = r_a - r_b, with opposite signs).
FAMILIES = {
    "r_a": (0, 1.0),
    "r_b": (0, -1.0),
    "l_a": (1, 1.0),
    "l_b": (2, 1.0),
    "theta": (3, 1.0),
    "q_offset": (4, 1.0),
}
DEFAULT_PARAMS = ("r_a", "l_a", "l_b", "theta", "q_offset")
_NAME = re.compile(r"^([a-z_]+?)(?:\[([0-2])\])?$")


@dataclass
class CalibrationResult:
    """What calibrate() found. Values in SI units (m, rad); per-parameter arrays follow
    ``names`` (e.g. "l_a[0]" is chain 1's crank length)."""

    geometry: DeltaGeometry  # the calibrated (asymmetric) geometry
    names: tuple[str, ...]
    nominal: np.ndarray  # starting values
    values: np.ndarray  # identified values
    uncertainty: np.ndarray  # one standard deviation (inf where unidentifiable)
    covariance: np.ndarray
    singular_values: np.ndarray  # of the column-scaled Jacobian, largest first, normalised
    unidentifiable: tuple[tuple[str, ...], ...]  # parameter sets the data cannot separate
    rms_before: float  # residual |fk(q) - p| RMS over the points [m]
    rms_after: float
    residuals: np.ndarray  # (N, 3) fk(q) - p after calibration [m]
    iterations: int
    converged: bool
    robot: Any = field(default=None, repr=False)  # set by DeltaRobot.calibrate

    @property
    def identifiable(self) -> bool:
        return not self.unidentifiable

    def report(self) -> str:
        """A plain-text table: parameter, nominal, identified, deviation, 1 sigma."""
        lines = [
            f"{'parameter':<12}{'nominal':>14}{'identified':>14}{'deviation':>14}{'1 sigma':>12}"
        ]
        for name, a, b, s in zip(self.names, self.nominal, self.values, self.uncertainty):
            unit = "rad" if name.startswith(("theta", "q_offset")) else "m"
            lines.append(f"{name:<12}{a:>14.6g}{b:>14.6g}{b - a:>14.3e}{s:>12.2e} {unit}")
        lines.append(
            f"residual RMS: {self.rms_before * 1e6:.3f} um before, {self.rms_after * 1e6:.3f} um "
            f"after ({self.iterations} iterations{'' if self.converged else ', not converged'})"
        )
        sv = ", ".join(f"{v:.3g}" for v in self.singular_values)
        lines.append(f"singular values (scaled, relative): {sv}")
        if self.unidentifiable:
            for group in self.unidentifiable:
                lines.append(f"NOT identifiable from these measurements: {', '.join(group)}")
        else:
            lines.append("every parameter is identifiable from these measurements")
        return "\n".join(lines)


def parameter_names(params) -> tuple[tuple[str, int, int, float], ...]:
    """("l_a", ...) or ("l_a[1]", ...) -> (name, chain, kernel column, sign) per parameter."""
    if isinstance(params, str):
        params = (params,)
    out = []
    for raw in params:
        m = _NAME.match(str(raw).strip())
        if not m or m.group(1) not in FAMILIES:
            raise InputError(
                f"unknown calibration parameter {raw!r}: use {', '.join(FAMILIES)} "
                "(all three chains) or one chain as e.g. l_a[0]"
            )
        family, index = m.group(1), m.group(2)
        block, sign = FAMILIES[family]
        for i in range(3) if index is None else (int(index),):
            name = f"{family}[{i}]"
            if any(o[0] == name for o in out):
                raise InputError(f"calibration parameter {name} given twice")
            out.append((name, i, 3 * block + i, sign))
    if not out:
        raise InputError("no calibration parameters given")
    return tuple(out)


def _values(geometry: DeltaGeometry, spec) -> np.ndarray:
    vals = []
    for name, i, _, _ in spec:
        family = name.split("[")[0]
        if family in ("theta", "q_offset"):
            vals.append(getattr(geometry, family)[i])
        else:
            vals.append(geometry.chain(family)[i])
    return np.array(vals, dtype=np.float64)


def _apply(geometry: DeltaGeometry, spec, x: np.ndarray) -> DeltaGeometry:
    table: dict[str, list[float]] = {
        "r_a": list(geometry.chain("r_a")),
        "r_b": list(geometry.chain("r_b")),
        "l_a": list(geometry.chain("l_a")),
        "l_b": list(geometry.chain("l_b")),
        "theta": list(geometry.theta),
        "q_offset": list(geometry.q_offset),
    }
    for (name, i, _, _), v in zip(spec, x):
        table[name.split("[")[0]][i] = float(v)
    return geometry.with_chains(**table)


def _measurements(q, p):
    q = np.asarray(q, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 3 or p.shape != q.shape:
        raise InputError(
            f"q_measured and p_measured must both be (N, 3) arrays, got {q.shape} and {p.shape}"
        )
    bad = np.flatnonzero(~(np.isfinite(q).all(axis=1) & np.isfinite(p).all(axis=1)))
    if bad.size:
        raise InputError(f"measurements contain NaN or infinite values in rows {rows_text(bad)}")
    return np.ascontiguousarray(q), np.ascontiguousarray(p)


def _evaluate(geometry, spec, q, p):
    """Residual (3N,) and Jacobian (3N, k) of fk(q) - p at ``geometry``."""
    core = CompiledDelta(geometry, threads=1)
    p_fk, G, status = core.fk_param_jacobian(q)
    bad = np.flatnonzero(status != st.OK)
    if bad.size:
        raise KinematicsError(
            f"the model's fk fails (unreachable or singular) at measurements {rows_text(bad)}: "
            "check the data and the starting geometry",
            bad,
        )
    cols = [sign * G[:, :, col] for _, _, col, sign in spec]
    J = np.stack(cols, axis=-1).reshape(-1, len(spec))
    return (p_fk[:, :3] - p).reshape(-1), J


def calibrate(
    geometry: DeltaGeometry,
    q_measured,
    p_measured,
    params=DEFAULT_PARAMS,
    *,
    sigma: float | None = None,
    rcond: float = 1e-9,
    max_iterations: int = 100,
    tol: float = 1e-12,
) -> CalibrationResult:
    """Identify ``params`` (see :func:`parameter_names`) from measured (q, p) pairs
    ((N, 3) each, rad and m) starting from ``geometry``. ``sigma``: the measurement noise
    per coordinate [m] if known (else estimated from the residual)."""
    spec = parameter_names(params)
    q, p = _measurements(q_measured, p_measured)
    k = len(spec)
    x0 = _values(geometry, spec)
    x = x0.copy()
    r, J = _evaluate(geometry, spec, q, p)
    cost0 = cost = float(r @ r)
    lam, iterations, converged = 1e-3, 0, False
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (iterations is reported)
        scale = np.linalg.norm(J, axis=0)
        scale[scale == 0.0] = 1.0
        U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
        keep = s > rcond * s[0] if s.size and s[0] > 0 else np.zeros_like(s, dtype=bool)
        g = U.T @ r
        improved = False
        for _ in range(30):
            damp = np.where(keep, s / (s * s + lam * s[0] ** 2), 0.0)
            step = -(Vt.T @ (damp * g)) / scale
            trial = x + step
            try:
                geom_t = _apply(geometry, spec, trial)
                r_t, J_t = _evaluate(geom_t, spec, q, p)
            except (KinematicsError, ValueError):  # a step out of the feasible geometry
                lam *= 10.0
                continue
            cost_t = float(r_t @ r_t)
            if cost_t <= cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            converged = True  # no step lowers the cost: a minimum (to rounding)
            break
        small_step = np.all(np.abs(step) * scale <= tol * (1.0 + np.abs(x) * scale))
        small_gain = cost - cost_t <= tol * max(cost, 1e-300)
        x, r, J, cost = trial, r_t, J_t, cost_t
        lam = max(lam / 10.0, 1e-12)
        if small_step or small_gain:
            converged = True
            break

    # identifiability and covariance at the solution
    scale = np.linalg.norm(J, axis=0)
    zero = scale == 0.0
    scale[zero] = 1.0
    U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
    s_max = s[0] if s.size and s[0] > 0 else 1.0
    keep = s > rcond * s_max
    rank = int(keep.sum())
    null = Vt[~keep] if rank < k else np.zeros((0, k))
    if k > len(s):  # fewer equations than parameters: the missing directions are null too
        _, _, Vt_full = np.linalg.svd(J / scale, full_matrices=True)
        null = Vt_full[rank:]
    names = [n for n, *_ in spec]
    # the projector onto the unseen directions: parameters it couples form one set
    P = null.T @ null if null.size else np.zeros((k, k))
    weak = (np.diag(P) > 1e-2) | zero
    groups: list[tuple[str, ...]] = []
    seen: set[int] = set()
    for j in np.flatnonzero(weak):
        if j in seen:
            continue
        members, todo = {int(j)}, [int(j)]
        while todo:
            a = todo.pop()
            for b in np.flatnonzero((np.abs(P[a]) > 1e-2) & weak):
                if int(b) not in members:
                    members.add(int(b))
                    todo.append(int(b))
        seen |= members
        groups.append(tuple(names[m] for m in sorted(members)))
    dof = r.size - rank
    noise2 = sigma**2 if sigma is not None else (cost / dof if dof > 0 else math.inf)
    inv_s2 = np.where(keep, 1.0 / np.where(keep, s, 1.0) ** 2, 0.0)
    cov_scaled = (Vt.T * inv_s2) @ Vt
    cov = noise2 * cov_scaled / np.outer(scale, scale)
    unc = np.sqrt(np.maximum(np.diag(cov), 0.0))
    unc[weak] = np.inf
    n = q.shape[0]
    return CalibrationResult(
        geometry=_apply(geometry, spec, x),
        names=tuple(names),
        nominal=x0,
        values=x,
        uncertainty=unc,
        covariance=cov,
        singular_values=np.concatenate([s / s_max, np.zeros(max(0, k - len(s)))]),
        unidentifiable=tuple(groups),
        rms_before=math.sqrt(cost0 / n),
        rms_after=math.sqrt(cost / n),
        residuals=r.reshape(n, 3),
        iterations=iterations,
        converged=converged,
    )
