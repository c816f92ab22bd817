"""Calibration of a built delta robot: identify per-chain geometry deviations from measured
pairs (crank angles q as the encoders read them, platform positions p as a probe or a
tracker measures them, in the base frame O).

Model: p_i = fk(q_i; pi) with pi the chosen parameters of the asymmetric geometry
(deltagen.model.delta): per chain r_a,i, r_b,i, l_a,i, l_b,i, theta_i and the encoder
offset q_offset,i. Least squares min_pi sum |fk(q_i; pi) - p_i|^2 by Levenberg-Marquardt
(Marquardt's damping on the column-scaled Jacobian, steps through its SVD), bounded: every
parameter stays within a physical bound of its nominal value (lengths within
``max_length_deviation``, default 10 % of the robot's size; angles within
``max_angle_deviation``, default 0.3 rad), each trial point projected onto that box. A
calibration corrects a drawing by small deviations; a fit that wants to leave the box is not
a calibration of this robot (wrong units, wrong columns, wrong nominal robot). The Jacobian
dp/dpi is the generated C kernel deltagen_delta_fk_param_jacobian (SymPy's implicit
derivative of eq. (1), deltagen/derive/delta/calibration.py).

What the data can know is judged against the noise sigma (given, or estimated as
sqrt(RSS / (3N - rank))). The Jacobian is weighted by 1/sigma and each column scaled by the
parameter's bound b_j: a singular value s of J diag(b) / sigma says that moving the
parameters by a full bound along that direction changes the residual by s standard
deviations. Below ``NOISE_DETECTION`` = 3 the measurements cannot place the parameters
inside their bounds along that direction. Per parameter, the 1-sigma uncertainty (the
covariance sigma^2 (J^T J)^+) is compared with the bound: a parameter whose 1 sigma exceeds
b_j / 3 is not identifiable (its 3-sigma interval spans its whole allowed range), one with
weight in an exactly unseen direction (singular value below ``rcond`` of the largest, e.g.
r_a,i and r_b,i, which enter only as r_a,i - r_b,i) has an infinite uncertainty; the step
leaves such directions alone (minimum-norm). Unidentifiable parameters that share unseen
directions are reported as one set.

Validity of the fit (``CalibrationResult.valid`` and ``problems``; the CLI exits 1 and writes
no robot file for an invalid fit): the iteration converged; every parameter is identifiable
and none ended on its bound; the residual agrees with the noise. With ``sigma`` given that is
the chi-square test: RSS / sigma^2 follows chi^2 with 3N - rank degrees of freedom for a
model that fits, and a probability below ``CHI2_P_MIN`` (1e-3) of a residual at least this
large refuses the fit. Without sigma the residual can be judged only against the robot: an
estimated noise above ``PLAUSIBLE_NOISE`` (1 %) of the robot's size is no measurement noise
but a model that does not fit. At least one degree of freedom (3N > number of parameters)
is required. When the residual is far above the noise, the nominal robot is evaluated on
re-read data (positions in mm, q and p columns swapped, q in degrees) and an alternative that
fits much better is named as a hint.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import chdtrc

from deltagen import status as st
from deltagen.errors import KinematicsError, rows_text
from deltagen.inputs import InputError
from deltagen.model.delta import DeltaGeometry
from deltagen.native.delta import CompiledDelta
from deltagen.solve.least_squares import damped_step, kept, lambda2

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
ANGLES = ("theta", "q_offset")
DEFAULT_PARAMS = ("r_a", "l_a", "l_b", "theta", "q_offset")
_NAME = re.compile(r"^([a-z_]+?)(?:\[([0-2])\])?$")

#: Default bound of a length parameter's deviation from nominal, as a fraction of the
#: robot's size (l_a + l_b + r_a): 10 %, 0.135 m for the default robot.
LENGTH_BOUND = 0.1
#: Default bound of an angle parameter's deviation (theta_i, q_offset,i) [rad], about 17 deg.
ANGLE_BOUND = 0.3
#: A direction (or parameter) is seen when a full bound along it moves the residual by at
#: least this many noise standard deviations (equivalently: 1 sigma <= bound / 3).
NOISE_DETECTION = 3.0
#: Chi-square test: a residual this improbable (or less) under the given noise refuses the fit.
CHI2_P_MIN = 1e-3
#: Without a given sigma: an estimated noise above this fraction of the robot's size is a
#: model that does not fit, not measurement noise.
PLAUSIBLE_NOISE = 0.01


@dataclass
class CalibrationResult:
    """What calibrate() found. Values in SI units (m, rad); per-parameter arrays follow
    ``names`` (e.g. "l_a[0]" is chain 1's crank length). ``valid`` is False (and
    ``problems`` says why) when the result must not be used as the robot's geometry."""

    geometry: DeltaGeometry  # the calibrated (asymmetric) geometry
    names: tuple[str, ...]
    nominal: np.ndarray  # starting values
    values: np.ndarray  # identified values
    uncertainty: np.ndarray  # one standard deviation (inf where exactly unseen)
    covariance: np.ndarray
    bounds: np.ndarray  # (k, 2) lower and upper bound of each parameter
    singular_values: np.ndarray  # of J diag(bound) / sigma, largest first (noise units)
    unidentifiable: tuple[tuple[str, ...], ...]  # parameter sets the data cannot place
    at_bound: tuple[str, ...]  # parameters that ended on their bound
    rms_before: float  # residual |fk(q) - p| RMS over the points [m]
    rms_after: float
    residuals: np.ndarray  # (N, 3) fk(q) - p after calibration [m]
    iterations: int
    converged: bool
    sigma: float  # noise per coordinate the judgement used [m] (given or estimated)
    sigma_given: bool
    dof: int  # 3N - rank
    chi2: float  # RSS / sigma^2
    p_value: float  # P(chi^2_dof >= chi2); nan when sigma was estimated
    problems: tuple[str, ...] = ()  # why the fit is not valid (empty: valid)
    hints: tuple[str, ...] = ()  # likely causes of a residual far above the noise
    robot: Any = field(default=None, repr=False)  # set by DeltaRobot.calibrate

    @property
    def identifiable(self) -> bool:
        return not self.unidentifiable

    @property
    def valid(self) -> bool:
        return not self.problems

    @property
    def reduced_chi2(self) -> float:
        return self.chi2 / self.dof

    def report(self) -> str:
        """A plain-text table: parameter, nominal, identified, deviation, 1 sigma; then the
        residual, the noise test, what the data cannot place and the verdict."""
        lines = [
            f"{'parameter':<12}{'nominal':>14}{'identified':>14}{'deviation':>14}{'1 sigma':>12}"
        ]
        for name, a, b, s in zip(self.names, self.nominal, self.values, self.uncertainty):
            unit = "rad" if name.startswith(ANGLES) else "m"
            lines.append(f"{name:<12}{a:>14.6g}{b:>14.6g}{b - a:>14.3e}{s:>12.2e} {unit}")
        lines.append(
            f"residual RMS: {self.rms_before * 1e6:.3f} um before, {self.rms_after * 1e6:.3f} um "
            f"after ({self.iterations} iterations{'' if self.converged else ', not converged'})"
        )
        if self.sigma_given:
            lines.append(
                f"noise: sigma {self.sigma * 1e6:.3g} um given; chi-square {self.chi2:.4g} with "
                f"{self.dof} degrees of freedom (reduced {self.reduced_chi2:.3g}, "
                f"p = {self.p_value:.3g})"
            )
        else:
            lines.append(
                f"noise: sigma {self.sigma * 1e6:.3g} um estimated from the residual "
                f"({self.dof} degrees of freedom; give sigma for a chi-square test)"
            )
        sv = ", ".join(f"{v:.3g}" for v in self.singular_values)
        lines.append(
            f"singular values (noise sigmas per bound; below {NOISE_DETECTION:g} unseen): {sv}"
        )
        if self.unidentifiable:
            for group in self.unidentifiable:
                lines.append(f"NOT identifiable from these measurements: {', '.join(group)}")
        else:
            lines.append("every parameter is identifiable from these measurements")
        if self.problems:
            lines.append("FIT NOT VALID:")
            lines.extend(f"  - {p}" for p in self.problems)
            lines.extend(f"  hint: {h}" for h in self.hints)
        else:
            lines.append("fit valid")
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
        if family in ANGLES:
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


def _positive_finite(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0.0):
        raise InputError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _bounds(geometry: DeltaGeometry, spec, x0, length_bound: float, angle_bound: float):
    """(k, 2) box of each parameter: nominal +- its bound; lengths stay positive (r_b >= 0)."""
    half = np.array(
        [angle_bound if n.startswith(ANGLES) else length_bound for n, *_ in spec], dtype=float
    )
    lo, hi = x0 - half, x0 + half
    for j, (name, *_) in enumerate(spec):
        if name.startswith("r_b"):
            lo[j] = max(lo[j], 0.0)
        elif not name.startswith(ANGLES):
            lo[j] = max(lo[j], 1e-3 * x0[j])
    return np.column_stack([lo, hi]), half


def _measurements(q, p, k: int):
    q = np.asarray(q, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 3 or p.shape != q.shape:
        raise InputError(
            f"q_measured and p_measured must both be (N, 3) arrays, got {q.shape} and {p.shape}"
        )
    n = q.shape[0]
    if n == 0:
        raise InputError("no measurements: q_measured and p_measured are empty")
    if 3 * n <= k:
        raise InputError(
            f"too few measurements: {n} points give {3 * n} equations for {k} parameters; "
            f"at least {k // 3 + 1} points are needed to judge the fit (many more to "
            "identify it: e.g. 10 per parameter)"
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


def _nominal_rms(geometry, q, p) -> float:
    """RMS of |fk(q) - p| of the nominal robot over the points its fk reaches (nan if fewer
    than half of them)."""
    if not (np.isfinite(q).all() and np.isfinite(p).all()):
        return math.nan
    p_fk, status = CompiledDelta(geometry, threads=1).fk(q)
    ok = status == st.OK
    if ok.sum() < 0.5 * len(q):
        return math.nan
    return float(np.sqrt(np.mean(np.sum((p_fk[ok] - p[ok]) ** 2, axis=1))))


def unit_hints(geometry: DeltaGeometry, q, p) -> tuple[str, ...]:
    """The re-reading of the data (positions in mm, q and p columns swapped, q in degrees)
    the nominal robot fits best, if it fits 10x better (RMS) than the data as given."""
    q = np.asarray(q, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    as_given = _nominal_rms(geometry, q, p)
    alternatives = (
        ("positions look like millimetres: give x, y, z in metres", q, p / 1000.0),
        ("q and p look swapped: the columns are q1, q2, q3 then x, y, z", p, q),
        ("q look like degrees: give radians (the CLI: --degrees)", np.radians(q), p),
        ("q and p look swapped, q in degrees and p in mm", np.radians(p), q / 1000.0),
    )
    best, best_rms = "", math.inf
    for text, q_alt, p_alt in alternatives:
        rms = _nominal_rms(geometry, q_alt, p_alt)
        if rms < best_rms:
            best, best_rms = text, rms
    if math.isfinite(best_rms) and not (as_given <= 10.0 * best_rms):  # nan: any fit helps
        return (f"{best} (the nominal robot then fits to {best_rms:.3g} m RMS)",)
    return ()


def calibrate(
    geometry: DeltaGeometry,
    q_measured,
    p_measured,
    params=DEFAULT_PARAMS,
    *,
    sigma: float | None = None,
    max_length_deviation: float | None = None,
    max_angle_deviation: float = ANGLE_BOUND,
    rcond: float = 1e-9,
    max_iterations: int = 100,
    tol: float = 1e-12,
) -> CalibrationResult:
    """Identify ``params`` (see :func:`parameter_names`) from measured (q, p) pairs
    ((N, 3) each, rad and m) starting from ``geometry``. ``sigma``: the measurement noise
    per coordinate [m] if known (else estimated from the residual; only a given sigma allows
    the chi-square test). ``max_length_deviation`` [m] (default 10 % of the robot's size)
    and ``max_angle_deviation`` [rad] bound every parameter around its nominal value.
    The result's ``valid`` and ``problems`` say whether it may be used (module docstring)."""
    spec = parameter_names(params)
    k = len(spec)
    q, p = _measurements(q_measured, p_measured, k)
    if sigma is not None:
        sigma = _positive_finite(sigma, "sigma (the measurement noise per coordinate, m)")
    length_bound = _positive_finite(
        LENGTH_BOUND * geometry.size if max_length_deviation is None else max_length_deviation,
        "max_length_deviation",
    )
    angle_bound = _positive_finite(max_angle_deviation, "max_angle_deviation")
    n = q.shape[0]
    x0 = _values(geometry, spec)
    box, half = _bounds(geometry, spec, x0, length_bound, angle_bound)
    x = x0.copy()
    try:
        r, J = _evaluate(geometry, spec, q, p)
    except KinematicsError as exc:
        hints = unit_hints(geometry, q, p)
        raise KinematicsError(str(exc) + "".join(f"; hint: {h}" for h in hints), exc.rows) from None
    cost0 = cost = float(r @ r)
    lam, iterations, converged = 1e-3, 0, False
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (iterations is reported)
        scale = np.linalg.norm(J, axis=0)
        scale[scale == 0.0] = 1.0
        U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
        keep = kept(s, rcond)
        improved = False
        for _ in range(30):
            step = -damped_step(U, s, Vt, r, lambda2(s, lam, "largest", len(r)), keep) / scale
            trial = np.clip(x + step, box[:, 0], box[:, 1])  # projected onto the bounds
            step = trial - x
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

    names = [nm for nm, *_ in spec]
    # exactly unseen directions: relative singular values of the column-normalised Jacobian
    norms = np.linalg.norm(J, axis=0)
    zero = norms == 0.0
    norms[zero] = 1.0
    _, s_rel, Vt_rel = np.linalg.svd(J / norms, full_matrices=True)
    s_rel_max = s_rel[0] if s_rel.size and s_rel[0] > 0 else 1.0
    exact = np.concatenate([s_rel <= rcond * s_rel_max, np.ones(k - s_rel.size, dtype=bool)])
    rank = int((~exact).sum())
    null = Vt_rel[exact]
    unseen = (np.sum(null**2, axis=0) > 1e-2) | zero if null.size else zero.copy()
    dof = r.size - rank
    # the noise: given, or estimated (floored at rounding of the robot's size)
    sigma_used = sigma if sigma is not None else max(math.sqrt(cost / dof), 1e-13 * geometry.size)
    chi2 = cost / sigma_used**2
    p_value = float(chdtrc(dof, chi2)) if sigma is not None else math.nan
    # noise-relative: J diag(bound) / sigma; a full bound along v_i moves the residual s_i sigmas
    Jb = J * half / sigma_used
    U, s, Vt = np.linalg.svd(Jb, full_matrices=True)
    s_full = np.concatenate([s, np.zeros(max(0, k - s.size))])
    keep = s_full > rcond * (s_full[0] if s_full[0] > 0 else 1.0)
    inv_s2 = np.where(keep, 1.0 / np.where(keep, s_full, 1.0) ** 2, 0.0)
    cov = half[:, None] * ((Vt.T * inv_s2) @ Vt) * half[None, :]
    unc = np.sqrt(np.maximum(np.diag(cov), 0.0))
    unc[unseen] = np.inf
    weak_param = ~(unc <= half / NOISE_DETECTION)
    # sets: parameters sharing an exactly unseen direction (its projector couples them), or
    # correlated through the noise-weak directions (their part of the covariance)
    coupled = np.abs(null.T @ null) > 1e-2 if null.size else np.zeros((k, k), dtype=bool)
    weak_dir = (s_full < NOISE_DETECTION) & keep
    if weak_dir.any():
        V = Vt[weak_dir]
        C = (V.T / s_full[weak_dir] ** 2) @ V
        d = np.sqrt(np.maximum(np.diag(C), 1e-300))
        coupled |= np.abs(C / np.outer(d, d)) > 0.3
    groups: list[tuple[str, ...]] = []
    seen: set[int] = set()
    for j in np.flatnonzero(weak_param):
        if j in seen:
            continue
        members, todo = {int(j)}, [int(j)]
        while todo:
            a = todo.pop()
            for b in np.flatnonzero(coupled[a] & weak_param):
                if int(b) not in members:
                    members.add(int(b))
                    todo.append(int(b))
        seen |= members
        groups.append(tuple(names[m] for m in sorted(members)))

    # validity of the fit
    span = box[:, 1] - box[:, 0]
    on_bound = (x - box[:, 0] <= 1e-9 * span) | (box[:, 1] - x <= 1e-9 * span)
    at_bound = tuple(nm for nm, b in zip(names, on_bound) if b)
    problems: list[str] = []  # root causes first: residual, identifiability, bounds
    rms_coordinate = math.sqrt(cost / r.size)
    residual_bad = False
    if sigma is not None:
        if p_value < CHI2_P_MIN:
            residual_bad = True
            problems.append(
                f"the residual does not agree with the noise: {rms_coordinate * 1e6:.4g} um RMS "
                f"per coordinate is {rms_coordinate / sigma:.3g} x sigma = {sigma * 1e6:.4g} um "
                f"(chi-square {chi2:.4g} with {dof} degrees of freedom, p = {p_value:.3g} < "
                f"{CHI2_P_MIN:g})"
            )
    elif sigma_used > PLAUSIBLE_NOISE * geometry.size:
        residual_bad = True
        problems.append(
            f"the model does not fit: the residual ({sigma_used:.4g} m per coordinate) is more "
            f"than {PLAUSIBLE_NOISE:.0%} of the robot's size ({geometry.size:.4g} m), no "
            "measurement noise"
        )
    if groups:
        problems.append(
            "not identifiable (1 sigma above a third of the bound, or unseen): "
            + "; ".join(", ".join(g) for g in groups)
            + " - measure poses that move these parameters, or calibrate fewer"
        )
    if at_bound:
        problems.append(
            f"ended on the bound (nominal +- {length_bound:.3g} m or +- {angle_bound:.3g} rad): "
            f"{', '.join(at_bound)} - the nominal robot or the data are not this robot's"
        )
    if not converged:  # often a consequence of the above
        problems.append(f"the iteration did not converge in {max_iterations} iterations")
    hints: tuple[str, ...] = ()
    if residual_bad:
        hints = unit_hints(geometry, q, p)
        if not hints:
            hints = (
                "check the units (m, rad), the column order (q1 q2 q3 x y z), the base frame "
                "of the positions and the nominal robot",
            )
    return CalibrationResult(
        geometry=_apply(geometry, spec, x),
        names=tuple(names),
        nominal=x0,
        values=x,
        uncertainty=unc,
        covariance=cov,
        bounds=box,
        singular_values=s_full,
        unidentifiable=tuple(groups),
        at_bound=at_bound,
        rms_before=math.sqrt(cost0 / n),
        rms_after=math.sqrt(cost / n),
        residuals=r.reshape(n, 3),
        iterations=iterations,
        converged=converged,
        sigma=float(sigma_used),
        sigma_given=sigma is not None,
        dof=int(dof),
        chi2=float(chi2),
        p_value=p_value,
        problems=tuple(problems),
        hints=hints,
    )
