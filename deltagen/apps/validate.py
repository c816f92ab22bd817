"""`deltagen validate`: the validation trajectory of the delta report (section 4).

The platform follows the test trajectory of eqs. (40)-(42) (two crossed chirps in x and
y between 0.1 Hz and 5 Hz, a 5 Hz oscillation in z), and the fourth axis follows
``phi(t) = 0.5 rad * sin(2 pi * 0.5 Hz * t)`` to exercise eq. (43). At every sample:

1. inverse kinematics and rates: ``q, qd, qdd = robot.ik_acc(p, pd, pdd)``
   (``qd = J^-1 pd``, ``qdd = J^-1 (pdd - Jdot qd)``);
2. back through the direct kinematics: ``p', pd', pdd' = robot.fk_acc(q, qd, qdd)``;
3. the round-trip errors ``|p' - p|``, ``|pd' - pd|``, ``|pdd' - pdd|`` (Euclidean norm
   per sample of x, y, z) against the *analytic* trajectory and its analytic derivatives.

Normalisation of the relative errors (each error is divided by the size of the quantity
it is an error of, so all three are dimensionless and comparable):

* position error     / robot size (``geometry.size`` = l_a + l_b + r_a)   [m / m]
* velocity error     / peak platform speed on the trajectory              [m/s / m/s]
* acceleration error / peak platform acceleration on the trajectory      [m/s^2 / m/s^2]
* fourth axis: |phi' - phi|, |phid' - phid|, |phidd' - phidd| over the peaks of
  |phi|, |phid|, |phidd|.

The run passes (exit code 0) when every relative error is below :data:`TOLERANCE`
(1e-9) and every sample is reachable and regular; otherwise it fails (exit code 1)
and says which time samples failed.

Singularity margins reported per sample (both as in :mod:`deltagen.status`):

* ``det_margin = |det D| / l_b^3``, rows ``D_i = p - S_i`` with
  ``S_i = ((r + l_a cos q_i) cos th_i, (r + l_a cos q_i) sin th_i, -l_a sin q_i)``,
  ``r = r_a - r_b`` (the report's J_p = 2 D; direct-kinematics singularity);
* ``jq_margin = min_i |j_i| / (l_a l_b)``, ``j_i = (p - S_i) . dS_i/dq_i``
  (the report's J_q,ii / 2; inverse-kinematics singularity, crank and rod aligned);
* ``cond``: the 2-norm condition number of J = J_p^-1 J_q (``robot.jacobian(q)``).

When the robot has inertial parameters (an ``[inertia]`` table; the default robot has
chosen ones), the run also computes the feed-forward torques of both dynamic models along
the trajectory (:mod:`deltagen.apps.dynamics`): peak and RMS torque and peak mechanical
power per drive, the simplified model's difference from the exact one, and a plot of q,
qdot, qddot and tau per drive (``validation_torques.png``).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from deltagen.errors import KinematicsError

#: Every relative round-trip error must stay below this for the run to pass.
TOLERANCE = 1e-9
#: Samples per chunk of the kinematic evaluation (progress is reported per chunk).
CHUNK = 2000

# -- trajectory parameters, eqs. (40)-(42) ------------------------------------------------
AMP_XY = 0.25  # [m]
AMP_Z = 0.1  # [m]
Z_OFFSET = -0.7556  # [m]
F_LOW, F_HIGH = 0.1, 5.0  # [Hz] chirp end frequencies
T_SWEEP = 10.0  # [s] chirp duration of eqs. (40), (41)
F_Z = 5.0  # [Hz]
# -- fourth axis (eq. (43)), not part of the report's trajectory -----------------------
AMP_PHI = 0.5  # [rad]
F_PHI = 0.5  # [Hz]

#: What section 4 of the report claims for the trajectory.
REPORT_SPEED = 8.0  # [m/s]
REPORT_ACCEL = 24.0  # [m/s^2]


def _chirp(t, amp, f0, f1, t_sweep):
    """amp sin(a t^2 + b t) with a = (f1 - f0) pi / t_sweep, b = 2 pi f0, and its
    first two time derivatives (theta = a t^2 + b t, theta' = 2 a t + b, theta'' = 2 a):
    x' = amp cos(theta) theta', x'' = amp (2 a cos(theta) - sin(theta) theta'^2)."""
    a = 0.5 * (f1 - f0) * 2.0 * math.pi / t_sweep
    b = 2.0 * math.pi * f0
    th = (a * t + b) * t
    thd = 2.0 * a * t + b
    s, c = np.sin(th), np.cos(th)
    return amp * s, amp * c * thd, amp * (2.0 * a * c - s * thd * thd)


def _sine(t, amp, f, phase=0.0, offset=0.0):
    """offset + amp sin(w t + phase), w = 2 pi f, and its first two derivatives."""
    w = 2.0 * math.pi * f
    th = w * t + phase
    s, c = np.sin(th), np.cos(th)
    return offset + amp * s, amp * w * c, -amp * w * w * s


def trajectory(t):
    """The report's test trajectory plus the fourth axis at times ``t`` [s].

    Returns ``(p, pd, pdd)``, each of shape ``t.shape + (4,)``: columns x, y, z [m],
    phi [rad] and their analytic first and second time derivatives.
    """
    t = np.asarray(t, dtype=np.float64)
    x = _chirp(t, AMP_XY, F_LOW, F_HIGH, T_SWEEP)  # eq. (40)
    y = _chirp(t, AMP_XY, F_HIGH, F_LOW, T_SWEEP)  # eq. (41): (0.1 - 5) t^2 / 2 + 5 t
    z = _sine(t, AMP_Z, F_Z, phase=0.5 * math.pi, offset=Z_OFFSET)  # eq. (42)
    phi = _sine(t, AMP_PHI, F_PHI)
    return tuple(np.stack([x[k], y[k], z[k], phi[k]], axis=-1) for k in range(3))


def sample_times(rate: float, duration: float) -> np.ndarray:
    """0, 1/rate, ... up to and including ``duration`` (when it falls on the grid)."""
    rate, duration = float(rate), float(duration)
    if not (math.isfinite(rate) and rate > 0.0):
        raise ValueError(f"rate must be a positive number of Hz, got {rate!r}")
    if not (math.isfinite(duration) and duration >= 0.0):
        raise ValueError(f"duration must be a non-negative number of seconds, got {duration!r}")
    n = int(math.floor(duration * rate * (1.0 + 1e-12))) + 1
    if n > 50_000_000:
        raise ValueError(f"{n} samples is too many (rate * duration must stay below 5e7)")
    return np.arange(n, dtype=np.float64) / rate


# ------------------------------------------------------------------ margins


def singularity_margins(geometry, p, q):
    """(det_margin, jq_margin) per sample; see the module docstring. NaN where q is NaN."""
    th = np.asarray(geometry.theta)
    la, lb, r = geometry.l_a, geometry.l_b, geometry.r
    q3 = q[:, :3]
    cq, sq = np.cos(q3), np.sin(q3)
    rho = r + la * cq
    S = np.stack([rho * np.cos(th), rho * np.sin(th), -la * sq], axis=-1)  # (N, 3, 3)
    dS = np.stack([-la * sq * np.cos(th), -la * sq * np.sin(th), -la * cq], axis=-1)
    D = p[:, None, :3] - S
    det_margin = np.full(D.shape[0], np.nan)
    finite = np.isfinite(D).all(axis=(1, 2))
    det_margin[finite] = np.abs(np.linalg.det(D[finite])) / lb**3
    j = np.einsum("nik,nik->ni", D, dS)
    jq_margin = np.min(np.abs(j), axis=1) / (la * lb)
    return det_margin, jq_margin


def _condition(J, ok):
    cond = np.full(J.shape[0], np.nan)
    if ok.any():
        cond[ok] = np.linalg.cond(J[ok])
    return cond


# ------------------------------------------------------------------ the run


@dataclass
class ValidationResult:
    robot: object
    t: np.ndarray  # (N,)
    p: np.ndarray  # (N, 4) analytic trajectory x, y, z, phi
    pd: np.ndarray
    pdd: np.ndarray
    q: np.ndarray  # (N, 4) joint positions, velocities, accelerations
    qd: np.ndarray
    qdd: np.ndarray
    p_back: np.ndarray  # (N, 4) fk_acc(q, qd, qdd)
    pd_back: np.ndarray
    pdd_back: np.ndarray
    err_pos: np.ndarray  # (N,) |p' - p| over x, y, z [m]
    err_vel: np.ndarray  # [m/s]
    err_acc: np.ndarray  # [m/s^2]
    err_phi: np.ndarray  # (N, 3) |phi' - phi|, |phid' - phid|, |phidd' - phidd|
    det_margin: np.ndarray  # (N,) |det D| / l_b^3
    jq_margin: np.ndarray  # (N,) min_i |j_i| / (l_a l_b)
    cond: np.ndarray  # (N,) cond(J)
    unreachable: np.ndarray  # (N,) bool: inverse kinematics has no solution
    singular: np.ndarray  # (N,) bool: reachable, but J_q or J_p (near) singular
    elapsed: float = 0.0
    tolerance: float = TOLERANCE
    dynamics: object = None  # apps.dynamics.TorqueProfile, when the robot has inertia
    _summary: dict = field(default_factory=dict, repr=False)

    # -- summary numbers ----------------------------------------------------------------

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def failed(self) -> np.ndarray:
        return self.unreachable | self.singular

    @property
    def ok(self) -> np.ndarray:
        return ~self.failed

    @property
    def size(self) -> float:
        return self.robot.geometry.size

    @property
    def speed(self) -> np.ndarray:
        return np.linalg.norm(self.pd[:, :3], axis=1)

    @property
    def accel(self) -> np.ndarray:
        return np.linalg.norm(self.pdd[:, :3], axis=1)

    @property
    def peak_speed(self) -> float:
        return float(self.speed.max())

    @property
    def peak_accel(self) -> float:
        return float(self.accel.max())

    def _scale(self, value):
        return value if value > 0.0 else 1.0

    def _worst(self, values, smallest=False):
        """(value, time) of the max (or min) over the samples that did not fail; NaN if none."""
        v = np.where(self.ok & np.isfinite(values), values, np.nan)
        if np.isnan(v).all():
            return math.nan, math.nan
        i = int(np.nanargmin(v) if smallest else np.nanargmax(v))
        return float(v[i]), float(self.t[i])

    def max_errors(self) -> dict:
        """Largest absolute errors and their times: {name: (value, t)}."""
        return {
            "position": self._worst(self.err_pos),
            "velocity": self._worst(self.err_vel),
            "acceleration": self._worst(self.err_acc),
            "phi": self._worst(self.err_phi[:, 0]),
            "phid": self._worst(self.err_phi[:, 1]),
            "phidd": self._worst(self.err_phi[:, 2]),
        }

    def scales(self) -> dict:
        """The normalisation of each error (see the module docstring)."""
        return {
            "position": self.size,
            "velocity": self._scale(self.peak_speed),
            "acceleration": self._scale(self.peak_accel),
            "phi": self._scale(float(np.abs(self.p[:, 3]).max())),
            "phid": self._scale(float(np.abs(self.pd[:, 3]).max())),
            "phidd": self._scale(float(np.abs(self.pdd[:, 3]).max())),
        }

    def relative_errors(self) -> dict:
        scales = self.scales()
        return {k: v / scales[k] for k, (v, _) in self.max_errors().items()}

    @property
    def passed(self) -> bool:
        rel = self.relative_errors()
        return (not self.failed.any()) and all(
            math.isfinite(v) and v < self.tolerance for v in rel.values()
        )

    def relative_error_series(self) -> dict:
        """Per-sample relative errors of x, y, z (for the plot)."""
        s = self.scales()
        return {
            "position": self.err_pos / s["position"],
            "velocity": self.err_vel / s["velocity"],
            "acceleration": self.err_acc / s["acceleration"],
        }


def run_trajectory(
    robot, rate=1000.0, duration=10.0, progress=None, chunk=CHUNK, payload=0.0
) -> ValidationResult:
    """Run the validation trajectory through ``robot``; see the module docstring.

    ``progress(done, total)`` is called after each chunk of samples. Failing samples
    (unreachable or singular) do not raise: they are NaN in the joint and round-trip
    arrays and flagged in ``result.unreachable`` / ``result.singular``.
    """
    start = time.perf_counter()
    t = sample_times(rate, duration)
    n = t.size
    p, pd, pdd = trajectory(t)
    shape4 = (n, 4)
    q, qd, qdd = (np.full(shape4, np.nan) for _ in range(3))
    pb, pdb, pddb = (np.full(shape4, np.nan) for _ in range(3))
    J = np.full((n, 3, 3), np.nan)
    unreachable = np.zeros(n, dtype=bool)
    singular = np.zeros(n, dtype=bool)
    for lo in range(0, n, chunk):
        sl = slice(lo, min(lo + chunk, n))
        # ik alone accepts singular-but-reachable poses: its failures are unreachable ones
        _, ik_ok = robot.ik(p[sl], errors="nan")
        q[sl], qd[sl], qdd[sl], acc_ok = robot.ik_acc(p[sl], pd[sl], pdd[sl], errors="nan")
        pb[sl], pdb[sl], pddb[sl], fk_ok = robot.fk_acc(q[sl], qd[sl], qdd[sl], errors="nan")
        J[sl], j_ok = robot.jacobian(q[sl], errors="nan")
        unreachable[sl] = ~ik_ok
        singular[sl] = ik_ok & ~(acc_ok & fk_ok & j_ok)
        if progress is not None:
            progress(sl.stop, n)
    err_pos = np.linalg.norm(pb[:, :3] - p[:, :3], axis=1)
    err_vel = np.linalg.norm(pdb[:, :3] - pd[:, :3], axis=1)
    err_acc = np.linalg.norm(pddb[:, :3] - pdd[:, :3], axis=1)
    err_phi = np.abs(
        np.stack([pb[:, 3] - p[:, 3], pdb[:, 3] - pd[:, 3], pddb[:, 3] - pdd[:, 3]], axis=1)
    )
    # margins: where ik reached the pose, from q of ik (ik_acc NaNs singular rows)
    q_pos = q.copy()
    missing = ~unreachable & np.isnan(q_pos[:, 0])
    if missing.any():
        q_pos[missing] = robot.ik(p[missing], errors="nan")[0]
    det_margin, jq_margin = singularity_margins(robot.geometry, p, q_pos)
    cond = _condition(J, ~(unreachable | singular))
    dynamics = None
    if robot.inertia is not None:  # the torques the trajectory asks of the drives
        from deltagen.apps.dynamics import torque_profile

        dynamics = torque_profile(robot, t, q, qd, qdd, payload)
    return ValidationResult(
        robot=robot,
        t=t,
        p=p,
        pd=pd,
        pdd=pdd,
        q=q,
        qd=qd,
        qdd=qdd,
        p_back=pb,
        pd_back=pdb,
        pdd_back=pddb,
        err_pos=err_pos,
        err_vel=err_vel,
        err_acc=err_acc,
        err_phi=err_phi,
        det_margin=det_margin,
        jq_margin=jq_margin,
        cond=cond,
        unreachable=unreachable,
        singular=singular,
        elapsed=time.perf_counter() - start,
        dynamics=dynamics,
    )


# ------------------------------------------------------------------ output

CSV_COLUMNS = (
    ["t", "x", "y", "z", "phi"]
    + [f"q{i}" for i in range(1, 5)]
    + [f"qd{i}" for i in range(1, 5)]
    + [f"qdd{i}" for i in range(1, 5)]
    + [
        "err_pos",
        "err_vel",
        "err_acc",
        "err_phi",
        "err_phid",
        "err_phidd",
        "det_margin",
        "jq_margin",
        "cond",
        "valid",
    ]
    + [f"tau{i}" for i in range(1, 5)]  # exact model [N m]; NaN without inertia
)


def write_csv(result: ValidationResult, path) -> Path:
    """One row per sample, a single header line of column names (SI units, rad)."""
    path = Path(path)
    table = np.column_stack(
        [
            result.t,
            result.p,
            result.q,
            result.qd,
            result.qdd,
            result.err_pos,
            result.err_vel,
            result.err_acc,
            result.err_phi,
            result.det_margin,
            result.jq_margin,
            result.cond,
            result.ok.astype(np.float64),
            result.dynamics.tau if result.dynamics is not None else np.full((result.n, 4), np.nan),
        ]
    )
    assert table.shape[1] == len(CSV_COLUMNS)
    np.savetxt(path, table, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt="%.17g")
    return path


def _positive(values):
    """Zeros (exact round trips) and NaNs are left out of log-scale plots."""
    v = np.array(values, dtype=np.float64)
    v[~(v > 0.0)] = np.nan
    return v


def plot(result: ValidationResult, path) -> Path:
    """A PNG overview: 3D path, speed and acceleration, relative errors, margins, cond."""
    from deltagen.apps.plotting import pyplot

    plt = pyplot()
    path = Path(path)
    g = result.robot.geometry
    t = result.t
    fig = plt.figure(figsize=(15, 14), layout="constrained")
    gs = fig.add_gridspec(4, 2)
    fig.suptitle(
        f"deltagen validate: robot {g.name!r} (r_a={g.r_a:g}, r_b={g.r_b:g}, l_a={g.l_a:g}, "
        f"l_b={g.l_b:g} m), {result.n} samples, backend {result.robot.backend}: "
        f"{'PASSED' if result.passed else 'FAILED'}",
        fontsize=13,
    )
    failed = result.failed
    p = result.p

    ax = fig.add_subplot(gs[0:2, 0], projection="3d")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], lw=0.4, color="tab:blue", label="trajectory (40)-(42)")
    if failed.any():
        ax.scatter(
            p[failed, 0],
            p[failed, 1],
            p[failed, 2],
            s=4,
            color="tab:red",
            label=f"failed samples ({int(failed.sum())})",
        )
    ax.scatter(*p[0, :3], color="k", s=20, label="t = 0")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]", labelpad=12)
    ax.tick_params(axis="z", pad=6)
    ax.set_title("platform path")
    ax.legend(loc="upper left", fontsize=8)

    def shade_failed(ax):
        if failed.any():
            ax.fill_between(
                t,
                0,
                1,
                where=failed,
                color="tab:red",
                alpha=0.2,
                lw=0,
                transform=ax.get_xaxis_transform(),
                label="failed samples",
            )

    def rate_panel(row, quantity, series, color, name, report, unit, title, where):
        """|pd| or |pdd| over t against the report's figure, failed samples shaded."""
        ax = fig.add_subplot(gs[row, 0])
        ax.plot(t, series, lw=0.5, color=color, label=name)
        ax.axhline(report, color="k", ls="--", lw=0.8, label=f"report: {report:g} {unit}")
        shade_failed(ax)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"{quantity} [{unit}]")
        ax.set_title(title)
        ax.legend(loc=where, fontsize=8)

    rate_panel(
        2,
        "speed",
        result.speed,
        "tab:blue",
        "|pd|",
        REPORT_SPEED,
        "m/s",
        f"platform speed (peak {result.peak_speed:.3g} m/s)",
        "lower right",
    )
    rate_panel(
        3,
        "acceleration",
        result.accel,
        "tab:orange",
        "|pdd|",
        REPORT_ACCEL,
        "m/s²",
        f"platform acceleration (peak {result.peak_accel:.3g} m/s²"
        f" = {result.peak_accel / 9.80665:.3g} g)",
        "upper center",
    )

    ax = fig.add_subplot(gs[0:2, 1])
    rel = result.relative_error_series()
    labels = {
        "position": "|Δp| / robot size",
        "velocity": "|Δpd| / peak speed",
        "acceleration": "|Δpdd| / peak acceleration",
    }
    for (k, v), color in zip(rel.items(), ("tab:blue", "tab:green", "tab:red")):
        ax.plot(t, _positive(v), lw=0.4, color=color, alpha=0.8, label=labels[k])
    ax.axhline(
        result.tolerance, color="k", ls="--", lw=0.8, label=f"tolerance {result.tolerance:g}"
    )
    shade_failed(ax)
    ax.set_yscale("log")
    ax.set_ylim(1e-20, 1e-6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("relative round-trip error")
    ax.set_title("fk_acc(ik_acc(p, pd, pdd)) vs analytic trajectory (exact zeros not drawn)")
    ax.legend(loc="upper left", fontsize=8, ncol=2)

    ax = fig.add_subplot(gs[2, 1])
    ax.plot(t, result.det_margin, lw=0.6, color="tab:purple", label="|det D| / l_b³  (J_p = 2D)")
    ax.plot(t, result.jq_margin, lw=0.6, color="tab:brown", label="min_i |J_q,ii| / (2 l_a l_b)")
    shade_failed(ax)
    ax.set_ylim(0.0, 1.05)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("normalised margin (0 = singular)")
    dm, dm_t = result._worst(result.det_margin, smallest=True)
    jm, jm_t = result._worst(result.jq_margin, smallest=True)
    ax.set_title(
        f"singularity margins (smallest: det {dm:.3g} at t = {dm_t:.3f} s, "
        f"J_q {jm:.3g} at t = {jm_t:.3f} s)"
    )
    ax.legend(loc="lower right", fontsize=8)

    ax = fig.add_subplot(gs[3, 1])
    ax.plot(t, result.cond, lw=0.6, color="tab:gray")
    shade_failed(ax)
    finite = result.cond[np.isfinite(result.cond)]
    if finite.size and finite.max() > 20.0 * finite.min():
        ax.set_yscale("log")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("cond(J)")
    c, c_t = result._worst(result.cond)
    ax.set_title(f"condition number of J = J_p⁻¹ J_q (max {c:.3g} at t = {c_t:.3f} s)")

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _ranges(t, mask, limit=8) -> str:
    """'t = 0.1-0.25 s, 3.2 s, ...' for the runs of True in mask."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return ""
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.r_[idx[0], idx[breaks + 1]]
    ends = np.r_[idx[breaks], idx[-1]]
    parts = [
        f"{t[a]:.6g} s" if a == b else f"{t[a]:.6g}-{t[b]:.6g} s"
        for a, b in zip(starts[:limit], ends[:limit])
    ]
    more = f", ... ({starts.size - limit} more intervals)" if starts.size > limit else ""
    return "t = " + ", ".join(parts) + more


def report(result: ValidationResult, out=None) -> None:
    """Print the summary (robot, errors, peaks, margins, verdict) to ``out`` (stdout)."""
    out = sys.stdout if out is None else out

    def w(text=""):
        print(text, file=out)

    g = result.robot.geometry
    w(
        f"robot {g.name!r}: r_a={g.r_a:g} m, r_b={g.r_b:g} m, l_a={g.l_a:g} m, l_b={g.l_b:g} m, "
        f"theta=({', '.join(f'{math.degrees(a):g}' for a in g.theta)}) deg, "
        f"size={g.size:g} m, backend {result.robot.backend}"
    )
    dt = result.t[1] - result.t[0] if result.n > 1 else 0.0
    w(
        f"trajectory eqs. (40)-(42) + phi = {AMP_PHI:g} sin(2 pi {F_PHI:g} t): {result.n} samples, "
        f"t = 0..{result.t[-1]:g} s"
        + (f" at {1.0 / dt:g} Hz" if dt else "")
        + f" ({result.elapsed:.2f} s)"
    )
    nfail = int(result.failed.sum())
    if nfail:
        w(f"FAILED SAMPLES: {nfail} of {result.n}")
        if result.unreachable.any():
            w(
                f"  unreachable (a crank cannot reach the platform position): "
                f"{int(result.unreachable.sum())} samples, {_ranges(result.t, result.unreachable)}"
            )
        if result.singular.any():
            w(
                f"  singular (J_q or J_p near singular, rates undefined): "
                f"{int(result.singular.sum())} samples, {_ranges(result.t, result.singular)}"
            )
        w("  errors, peaks and margins below are over the remaining samples")

    errs = result.max_errors()
    rel = result.relative_errors()
    sc = result.scales()
    w(
        "round-trip errors fk_acc(ik_acc(p, pd, pdd)) vs the analytic trajectory "
        "(max over samples, Euclidean norm of x, y, z):"
    )
    units = {
        "position": "m",
        "velocity": "m/s",
        "acceleration": "m/s^2",
        "phi": "rad",
        "phid": "rad/s",
        "phidd": "rad/s^2",
    }
    norms = {
        "position": f"robot size {sc['position']:.6g} m",
        "velocity": f"peak speed {sc['velocity']:.6g} m/s",
        "acceleration": f"peak acceleration {sc['acceleration']:.6g} m/s^2",
        "phi": f"peak |phi| {sc['phi']:.6g} rad",
        "phid": f"peak |phid| {sc['phid']:.6g} rad/s",
        "phidd": f"peak |phidd| {sc['phidd']:.6g} rad/s^2",
    }
    for k, (v, tv) in errs.items():
        w(
            f"  {k:<12} {v:10.3e} {units[k]:<7} (t = {tv:.3f} s)  relative {rel[k]:9.3e}"
            f"  (/ {norms[k]})"
        )

    ok = result.ok
    sp = np.where(ok, result.speed, np.nan)
    ac = np.where(ok, result.accel, np.nan)
    if np.isfinite(sp).any():
        i, j = int(np.nanargmax(sp)), int(np.nanargmax(ac))
        w(
            f"peak speed        {sp[i]:8.3f} m/s    at t = {result.t[i]:.3f} s "
            f"(report claims up to {REPORT_SPEED:g} m/s)"
        )
        w(
            f"peak acceleration {ac[j]:8.3f} m/s^2  at t = {result.t[j]:.3f} s "
            f"(report claims up to {REPORT_ACCEL:g} m/s^2; = {ac[j] / 9.80665:.1f} g)"
        )
        qd = np.abs(result.qd[ok])
        qdd = np.abs(result.qdd[ok])
        w(
            "joint peaks  max |qd|  = ["
            + ", ".join(f"{v:.3f}" for v in qd[:, :3].max(axis=0))
            + f"] rad/s, q4: {qd[:, 3].max():.3f} rad/s"
        )
        w(
            "             max |qdd| = ["
            + ", ".join(f"{v:.1f}" for v in qdd[:, :3].max(axis=0))
            + f"] rad/s^2, q4: {qdd[:, 3].max():.3f} rad/s^2"
        )
        q = result.q[ok]
        w(
            "joint range  q = ["
            + ", ".join(
                f"{math.degrees(a):.1f}..{math.degrees(b):.1f}"
                for a, b in zip(q[:, :3].min(axis=0), q[:, :3].max(axis=0))
            )
            + "] deg"
        )
    dm, dmt = result._worst(result.det_margin, smallest=True)
    jm, jmt = result._worst(result.jq_margin, smallest=True)
    cn, cnt = result._worst(result.cond)
    w(f"singularity margins (singular below {g.singular_tol:g}):")
    w(f"  smallest |det D| / l_b^3          {dm:.4g} (t = {dmt:.3f} s)   [J_p = 2 D]")
    w(f"  smallest min_i |J_q,ii|/(2 l_a l_b) {jm:.4g} (t = {jmt:.3f} s)")
    w(f"  largest cond(J)                   {cn:.4g} (t = {cnt:.3f} s)")
    if result.dynamics is not None:
        from deltagen.apps import dynamics

        dynamics.report(result.dynamics, out, title="feed-forward torques along the trajectory")
    verdict = "PASSED" if result.passed else "FAILED"
    why = []
    if nfail:
        why.append(f"{nfail} samples unreachable or singular")
    bad = [k for k, v in rel.items() if not (math.isfinite(v) and v < result.tolerance)]
    if bad and not (nfail and all(math.isnan(rel[k]) for k in bad)):
        why.append("relative errors above tolerance: " + ", ".join(bad))
    w(
        f"{verdict}: every relative error must be < {result.tolerance:g} and every sample "
        f"reachable and regular" + (f" ({'; '.join(why)})" if why else "")
    )


def add_parser(subparsers) -> None:
    """`deltagen validate [--robot DELTA] ...`."""
    from deltagen.apps.robots import add_urdf_options

    v = subparsers.add_parser("validate", help="the report's validation trajectory, eqs. (40)-(42)")
    v.add_argument(
        "--robot", default="default", help="a delta robot: 'default', a TOML or a printer.cfg"
    )
    v.add_argument("--rate", type=float, default=1000.0, help="sample rate [Hz] (default 1000)")
    v.add_argument("--duration", type=float, default=10.0, help="duration [s] (default 10)")
    v.add_argument("--out", default="validation", help="folder for the CSV and PNG")
    v.add_argument("--no-plot", action="store_true", help="skip the PNG figure")
    v.add_argument("--backend", choices=("compiled", "reference"), default="compiled")
    v.add_argument("--quiet", action="store_true", help="no progress output")
    add_urdf_options(v)


def run(args) -> int:
    """The `deltagen validate` subcommand: 0 if the run passes, 1 if it fails."""
    from deltagen.apps.robots import DELTA, robot_of

    quiet = bool(args.quiet)
    if not args.no_plot:
        from deltagen.apps.plotting import pyplot

        pyplot()  # before the run: without matplotlib, say so now (or use --no-plot)
    robot = robot_of(args, kinds=(DELTA,))
    rate = args.rate
    duration = args.duration

    def progress(done, total):
        print(
            f"validate: {done}/{total} samples ({100 * done // total} %)",
            file=sys.stderr,
            flush=True,
        )

    try:
        result = run_trajectory(robot, rate, duration, progress=None if quiet else progress)
    except KinematicsError as exc:  # run_trajectory() works in errors="nan" mode: should not happen
        print(f"deltagen validate: FAILED: {exc}", file=sys.stderr)
        return 1
    report(result)

    out = Path(args.out or "validation")
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(result, out / "validation.csv")
    print(f"wrote {csv_path}")
    if not args.no_plot:
        png = plot(result, out / "validation.png")
        print(f"wrote {png}")
        if result.dynamics is not None:
            from deltagen.apps import dynamics

            g = robot.geometry
            png = dynamics.plot(
                result.dynamics,
                out / "validation_torques.png",
                title=f"deltagen validate: q, qdot, qddot and feed-forward torques along the "
                f"report's trajectory, robot {g.name!r}",
            )
            print(f"wrote {png}")
    if not result.passed:
        if result.failed.any():
            print(
                f"deltagen validate: FAILED: {int(result.failed.sum())} of {result.n} samples "
                f"unreachable or singular (first at t = {result.t[result.failed][0]:.6g} s); "
                f"see above",
                file=sys.stderr,
            )
        else:
            print("deltagen validate: FAILED: round-trip errors above tolerance", file=sys.stderr)
        return 1
    return 0
