"""Cartesian path following of six-axis arms through singular regions (lecture slides
112-114).

The lecture (slide 112, "Singularitaet bei Bewegung"): a path that runs through a singular
configuration would need infinite joint speeds to keep the programmed path speed; "Abhilfe:
kurzzeitig beide Achsen zu einer zusammenfassen oder eine Achse 'einfrieren'". Slide 114:
"Manche Roboter bleiben beim Auftreten einer Singularitaet einfach stehen", or the robot
language offers "SingArea/Wrist", which switches the wrist axes from path to PTP (joint)
interpolation across the critical region. :func:`follow_path` plans the whole path before
any motion (it sees each region ahead) and offers the three behaviours as ``remedy``:

``"stop"`` (default)
    :class:`SingularPathError` naming the segment, the entry and exit times, the kind of the
    singularity and the axes involved; nothing is returned.
``"wrist"`` ("SingArea/Wrist")
    Across the region the wrist joints 4, 5, 6 move by joint interpolation: a quintic in
    time that matches position, velocity and acceleration of the path solution at the
    region's entry and exit (so q, qd, qdd stay continuous). Joints 1-3 keep the TCP
    position on the path (position task with the wrist joints prescribed; checked to 1e-9 m);
    the orientation leaves the path and its deviation is reported.
``"freeze"``
    One of the two (nearly) aligned wrist axes, ``freeze_axis`` 4 or 6, is held at its value
    at the region's entry for the whole region, and the other joints keep the TCP position on
    the path exactly while turning the tool as close to the path's orientation as they can
    (least squares on the orientation error: the partner axis takes the frozen axis's
    motion). Ramps of ``ramp`` seconds (default half the region's duration; shortened where
    the path's start or end or a neighbouring region is nearer) before and after the region
    bring the frozen axis to rest and back onto the path solution (quintics matching q, qd,
    qdd), so the joints stay continuous; the orientation deviation (ramps included) is
    reported.

Detection: at every sample the 6 x 6 geometric Jacobian's ``sigma_min / sigma_max`` (metres
and radians mixed as the Jacobian has them) is compared with ``threshold``; a region is a run
of samples below it. Its kind is read from the arm's axes at the region's most singular sample:
``wrist`` (axes 4 and 6 parallel, ``|w4 x w6|``, which for a central wrist means in line: the
Puma at q5 = 0; for the UR family axis 6 parallel to axes 2, 3, 4), and for central-wrist 6R
arms ``shoulder`` (wrist centre over axis 1) and ``elbow`` (arm stretched or folded), with
the distances of :mod:`deltagen.solve.singularity` divided by the arm's size; the smallest of
these measures names the kind when it is below 0.1, else the kind is ``singular``. The axes
involved are the joints with a large share (>= 0.3 of the largest) in the Jacobian's null
direction (the right singular vector of sigma_min). The wrist remedies handle wrist regions
only (at a shoulder or elbow singularity no wrist motion keeps the TCP on the path); other
kinds raise whatever the remedy.

Branch at the exit: near a wrist singularity the wrist has two solutions (q4, q5, q6) and
(q4 + pi, -q5, q6 + pi); the exit solution is the one whose wrist joints are nearest those
at the entry, so the remedy never turns the wrist half a revolution.

Speed limits: ``qd_max`` and ``qdd_max`` (per joint or one number; the robot files carry no
speed limits, so they are arguments). When the planned motion exceeds them, the whole
trajectory is slowed uniformly by ``time_scale = max(1, max |qd| / qd_max,
sqrt(max |qdd| / qdd_max))`` (durations times ``time_scale``, joint speeds divided by it,
accelerations by its square: the same joint path, later), so every sample is within the
limits. The joint rates are exact (inverse task Jacobian, and ``Jdot``) on path samples and in
"wrist" regions, and second-order finite differences in "freeze" intervals (whose joints come
from a least-squares solve).

Units: metres, radians, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from deltagen.errors import SingularityError
from deltagen.geometry.rotations import rot_log
from deltagen.inputs import InputError
from deltagen.plan.cartesian import CartesianSamples, CartesianTrajectory
from deltagen.plan.following import (
    Task,
    TrajectoryError,
    exact_rates,
    numerical_rates,
    solve_ik,
)
from deltagen.reference import serial as reference
from deltagen.solve import least_squares, singularity

__all__ = [
    "REMEDIES",
    "SingularPathError",
    "SingularRegion",
    "SingularPathReport",
    "SingularPathResult",
    "follow_path",
    "quintic_hermite",
]

REMEDIES = ("stop", "wrist", "freeze")
WRIST = (3, 4, 5)  # joints 4, 5, 6 (0-based)
POSE_TASK = Task("xyz", orientation=True)
ARM_TASK = Task("xyz", joints=WRIST)  # TCP position, wrist joints prescribed
_KIND_BOUND = 0.1  # a structural measure below this names the region's kind
_AXIS_SHARE = 0.3  # share in the null direction that counts a joint as involved
PATH, WRIST_PTP, FROZEN = 0, 1, 2  # per-sample modes


class SingularPathError(TrajectoryError, SingularityError):
    """The path runs through a singular region and ``remedy`` does not pass it (``"stop"``,
    or a wrist remedy at a shoulder or elbow singularity). ``region`` is the
    :class:`SingularRegion`; ``rows`` the samples in it."""

    def __init__(self, message, rows=(), region=None):
        super().__init__(message, rows)
        self.region = region


@dataclass(frozen=True)
class SingularRegion:
    """One singular region on the path.

    ``t_entry`` / ``t_exit``: the last regular sample before and the first after the run of
    samples with sigma_min / sigma_max < threshold [s, of the returned (time-scaled) motion];
    ``segment`` / ``segment_label``: the segment at the entry; ``kind``: "wrist", "shoulder",
    "elbow" or "singular"; ``axes``: 1-based joints in the Jacobian's null direction;
    ``sigma_ratio_min`` at ``t_closest``; ``remedy`` applied; ``frozen_axis`` (1-based, "freeze");
    ``t_start`` / ``t_end``: where the joints leave and rejoin the path solution (the region
    itself, plus the ramps for "freeze"); ``max_orientation_deviation`` [rad] and
    ``max_position_deviation`` [m] over that interval, from fk of the returned joints."""

    kind: str
    axes: tuple
    t_entry: float
    t_exit: float
    segment: int
    segment_label: str
    sigma_ratio_min: float
    t_closest: float
    remedy: str
    frozen_axis: int | None = None
    t_start: float = math.nan
    t_end: float = math.nan
    max_orientation_deviation: float = 0.0
    max_position_deviation: float = 0.0

    def describe(self) -> str:
        axes = ", ".join(str(a) for a in self.axes)
        what = {
            "wrist": "wrist singularity (axes 4 and 6 parallel: in line for a central wrist)",
            "shoulder": "shoulder singularity (wrist centre over axis 1)",
            "elbow": "elbow singularity (arm stretched or folded)",
        }.get(self.kind, "singular configuration")
        label = f" ({self.segment_label!r})" if self.segment_label else ""
        return (
            f"segment {self.segment}{label}, t = {self.t_entry:.6g} s .. {self.t_exit:.6g} s: "
            f"{what}, axes {axes}; sigma_min/sigma_max down to {self.sigma_ratio_min:.3g} "
            f"at t = {self.t_closest:.6g} s"
        )


@dataclass
class SingularPathReport:
    """What :func:`follow_path` did: the regions, the uniform ``time_scale`` (>= 1) applied
    for the speed limits, the limits, the peak |qd| and |qdd| per joint of the returned
    motion, the largest TCP position error [m] and orientation deviation [rad] over all
    samples."""

    regions: list
    threshold: float
    remedy: str
    time_scale: float
    qd_max: np.ndarray
    qdd_max: np.ndarray
    peak_qd: np.ndarray
    peak_qdd: np.ndarray
    max_position_error: float
    max_orientation_deviation: float

    def lines(self) -> list[str]:
        out = [
            f"{len(self.regions)} singular region(s) (sigma_min/sigma_max < {self.threshold:g}), "
            f"remedy {self.remedy!r}, time scale {self.time_scale:.4g}"
        ]
        for r in self.regions:
            extra = f", frozen axis {r.frozen_axis}" if r.frozen_axis else ""
            out.append(
                f"  {r.describe()}; joints off the path solution t = {r.t_start:.6g} .. "
                f"{r.t_end:.6g} s{extra}; orientation deviation <= "
                f"{math.degrees(r.max_orientation_deviation):.4g} deg, position <= "
                f"{r.max_position_deviation:.2g} m"
            )
        return out


@dataclass
class SingularPathResult:
    """The joint motion: t (N,), q, qd, qdd (N, 6); ``mode`` (N,) 0 on the path, 1 wrist
    joint interpolation, 2 frozen axis (ramps included); ``position_error`` (N,) |p - p(q)|
    [m] and ``orientation_deviation`` (N,) angle of R^T R(q) [rad] from the robot's fk;
    ``trajectory`` the (time-scaled) Cartesian trajectory, ``cartesian`` its samples;
    ``report``."""

    robot: object
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    mode: np.ndarray
    position_error: np.ndarray
    orientation_deviation: np.ndarray
    trajectory: CartesianTrajectory
    cartesian: CartesianSamples
    report: SingularPathReport

    @property
    def regions(self) -> list:
        return self.report.regions


# ----------------------------------------------------------------------- helpers


def quintic_hermite(T, x0, v0, a0, x1, v1, a1, t):
    """The quintic x(t) on [0, T] with x, dx/dt, d2x/dt2 = (x0, v0, a0) at 0 and (x1, v1, a1)
    at T; vectors (m,) each, times t (K,). Returns x, xd, xdd (K, m)."""
    x0, v0, a0, x1, v1, a1 = (np.asarray(v, dtype=float) for v in (x0, v0, a0, x1, v1, a1))
    u = np.asarray(t, dtype=float)[:, None] / T
    # in u: x(u) = c0 + c1 u + ... + c5 u^5 with derivatives scaled by T
    V0, A0, V1, A1 = v0 * T, a0 * T * T, v1 * T, a1 * T * T
    d = x1 - x0 - V0 - A0 / 2.0
    e = V1 - V0 - A0
    f = A1 - A0
    # c3, c4, c5 from the three end conditions at u = 1
    c3 = 10.0 * d - 4.0 * e + f / 2.0
    c4 = -15.0 * d + 7.0 * e - f
    c5 = 6.0 * d - 3.0 * e + f / 2.0
    x = x0 + u * (V0 + u * (A0 / 2.0 + u * (c3 + u * (c4 + u * c5))))
    xd = V0 + u * (A0 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)))
    xdd = A0 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5))
    return x, xd / T, xdd / (T * T)


def _limits(value, n, name):
    if value is None:
        return np.full(n, np.inf)
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,) or not np.all(a > 0) or np.any(np.isnan(a)):
        raise InputError(
            f"{name} must be one positive number or {n} positive numbers, got {value!r}"
        )
    return a


def _ratio(robot, q):
    s = np.linalg.svd(robot.jacobian(q), compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def _classify(robot, q):
    """(kind, axes) of the singular configuration q (module docstring)."""
    desc = robot.description
    _, w = reference.joint_axes(desc, q[None])
    measures = {"wrist": float(np.linalg.norm(np.cross(w[0, 3], w[0, 5])))}
    rep = singularity.report(desc, q)
    if rep["structure"] == "spherical_wrist_6r":
        size = singularity.structure_of(desc).size
        measures["shoulder"] = float(rep["shoulder_distance"]) / size
        measures["elbow"] = float(rep["elbow_distance"]) / size
    finite = {k: v for k, v in measures.items() if math.isfinite(v)}
    kind = min(finite, key=finite.__getitem__) if finite else "singular"
    if not finite or finite[kind] >= _KIND_BOUND:
        kind = "singular"
    v = np.linalg.svd(robot.jacobian(q))[2][-1]
    share = np.abs(v)
    axes = tuple(int(i) + 1 for i in np.flatnonzero(share >= _AXIS_SHARE * share.max()))
    return kind, axes


def _wrap_near(q, ref, qlim, revolute):
    """q with each revolute joint shifted by whole turns towards ref, where the shifted value
    stays within the joint limits (prismatic joints unchanged)."""
    out = q.copy()
    turns = np.round((ref - q) / (2.0 * math.pi))
    cand = q + 2.0 * math.pi * turns
    ok = revolute & (cand >= qlim[:, 0]) & (cand <= qlim[:, 1])
    out[ok] = cand[ok]
    return out


def _predict(Q, k, lo):
    """Quadratic predictor for sample k from the samples lo..k-1."""
    m = k - lo
    if m >= 3:
        return 3.0 * (Q[k - 1] - Q[k - 2]) + Q[k - 3]
    if m == 2:
        return 2.0 * Q[k - 1] - Q[k - 2]
    return Q[k - 1].copy()


def _solve_pose(robot, cs, k, guess, tol, max_iter, task=POSE_TASK, qj=None):
    """solve_ik at sample k; a singular linear system (an exact singularity) is a
    TrajectoryError like a failed convergence."""
    R = cs.R[k] if task.orientation else None
    try:
        return solve_ik(
            robot,
            task,
            cs.p[k],
            R,
            cs.qj[k] if qj is None else qj,
            guess,
            tol=tol,
            max_iter=max_iter,
        )[0]
    except np.linalg.LinAlgError as exc:
        raise TrajectoryError(f"singular linear system in the IK step ({exc})") from None


def _solve_frozen(robot, p, R, f, value, guess, tol, max_iter):
    """TCP position p exact, joint f at ``value``, orientation R by least squares (Gauss-Newton
    in the null space of the equality rows)."""
    q = np.array(guess, dtype=float)
    q[f] = value
    n = q.size
    E = np.zeros((1, n))
    E[0, f] = 1.0
    for _ in range(max_iter):
        T = robot.fk(q)
        J = robot.jacobian(q)
        e_eq = np.concatenate([p - T[:3, 3], [value - q[f]]])
        e_o = rot_log(R @ T[:3, :3].T)
        A = np.vstack([J[:3], E])
        dq_eq = least_squares.solve(A, e_eq)  # the minimum-norm solution
        Nsp = np.linalg.svd(A)[2][A.shape[0] :].T
        B = J[3:] @ Nsp
        z = least_squares.solve(B, e_o - J[3:] @ dq_eq)
        dq = dq_eq + Nsp @ z
        q = q + dq
        if float(np.max(np.abs(dq))) <= 1e-13 and float(np.linalg.norm(e_eq)) <= 10 * tol:
            break
    T = robot.fk(q)
    err = float(np.linalg.norm(p - T[:3, 3]))
    if not err <= max(tol, 1e-12):
        raise TrajectoryError(f"frozen-axis solve did not converge: |p - p(q)| = {err:.3g} m")
    return q


def _scaled(trajectory, k):
    if k == 1.0:
        return trajectory
    return CartesianTrajectory([replace(s, duration=s.duration * k) for s in trajectory.segments])


# ----------------------------------------------------------------------- the planner


def follow_path(
    robot: Any,
    trajectory: CartesianTrajectory,
    q0: Any = None,
    *,
    remedy: str = "stop",
    threshold: float = 0.02,
    qd_max: Any = None,
    qdd_max: Any = None,
    dt: float = 0.005,
    freeze_axis: int = 4,
    ramp: float | None = None,
    limits: str = "raise",
    max_step: float = 0.2,
    tol: float = 1e-13,
    max_iter: int = 30,
) -> SingularPathResult:
    """Follow ``trajectory`` (position and orientation) with a six-axis arm from the joints
    ``q0`` (a vector or a configuration name: it picks the branch; None: the arm's ``ik`` at
    the start pose), through singular regions as ``remedy`` says (module docstring; "joint"
    is another name of "wrist"). Returns a :class:`SingularPathResult`; its
    ``report`` lists every region."""
    if remedy == "joint":  # the wrist switches to joint interpolation
        remedy = "wrist"
    if remedy not in REMEDIES:
        raise InputError(f"remedy must be one of {REMEDIES} ('joint' = 'wrist'), got {remedy!r}")
    if robot.n != 6:
        raise InputError(f"follow_path handles six-axis arms; {robot.name} has {robot.n} joints")
    if not isinstance(trajectory, CartesianTrajectory):
        raise InputError("trajectory must be a CartesianTrajectory (PathBuilder(...).build())")
    if not trajectory.has_orientation:
        raise InputError("the trajectory needs an orientation (PathBuilder(start, R=...))")
    if trajectory.n_joints_prescribed:
        raise InputError("follow_path takes trajectories without prescribed joints")
    if not (isinstance(threshold, (int, float)) and 0.0 < threshold < 1.0):
        raise InputError(f"threshold must be a number in (0, 1), got {threshold!r}")
    if freeze_axis not in (4, 6):
        raise InputError(
            f"freeze_axis must be 4 or 6 (the wrist axes that line up), got {freeze_axis!r}"
        )
    if limits not in ("raise", "ignore"):
        raise InputError('limits must be "raise" or "ignore"')
    if ramp is not None and not (
        isinstance(ramp, (int, float)) and not isinstance(ramp, bool) and 0.0 < ramp < math.inf
    ):
        raise InputError(f"ramp must be a positive time [s] or None, got {ramp!r}")
    if not (isinstance(max_step, (int, float)) and 0.0 < max_step < math.inf):
        raise InputError(f"max_step must be a positive number [rad], got {max_step!r}")
    n = robot.n
    revolute = np.array([j.revolute for j in robot.description.joints], dtype=bool)
    if not revolute[3:].all():
        raise InputError(f"follow_path needs revolute wrist joints 4-6; {robot.name} has others")
    vmax = _limits(qd_max, n, "qd_max")
    amax = _limits(qdd_max, n, "qdd_max")
    if q0 is None:  # the arm's own IK at the start pose (its first valid branch)
        start = np.eye(4)
        start[:3, :3] = trajectory.segments[0].R0
        start[:3, 3] = trajectory.segments[0].path.start
        q0 = robot.ik(start)
    elif isinstance(q0, str):
        q0 = robot.configuration(q0)
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (n,) or not np.all(np.isfinite(q0)):
        raise InputError(f"q0 must be {n} finite joint values")
    qlim = robot.qlim

    t = trajectory.sample_times(dt)
    cs = trajectory.evaluate(t)
    R_path = cs.R
    assert R_path is not None  # checked above: the trajectory has an orientation
    N = t.size
    h = float(t[1] - t[0])
    Q = np.empty((N, n))
    ratio = np.empty(N)
    runs: list[tuple[int, int, int, float]] = []  # (i_in, i_out, k_min, ratio) per region

    # ---- march along the path; scan each singular run ahead and pick the exit branch
    k: int = 0
    lo: int = 0
    while k < N:
        guess = q0 if k == 0 else _predict(Q, k, lo)
        try:
            q = _solve_pose(robot, cs, k, guess, tol, max_iter)
        except TrajectoryError as exc:
            raise TrajectoryError(f"sample {k} (t = {t[k]:.6g} s): {exc}", [k]) from None
        r = _ratio(robot, q)
        if r >= threshold:
            if k > lo and float(np.max(np.abs(q - Q[k - 1]))) > max_step:
                raise TrajectoryError(
                    f"joint jump of {np.max(np.abs(q - Q[k - 1])):.3g} rad between samples "
                    f"{k - 1} and {k} (t = {t[k]:.6g} s) outside any singular region (max_step "
                    f"{max_step:g}): a branch flip; use a finer dt",
                    [k],
                )
            Q[k], ratio[k] = q, r
            k += 1
            continue
        if k == 0:
            raise SingularPathError(
                f"the path starts in a singular region (sigma_min/sigma_max = {r:.3g} < "
                f"{threshold:g} at t = 0): start elsewhere",
                [0],
            )
        i_in = k - 1
        j, qs, k_min, r_min = k, q, k, r
        Q[k], ratio[k] = q, r
        while True:
            j += 1
            if j >= N:
                kind, axes = _classify(robot, Q[k_min])
                raise SingularPathError(
                    f"the path ends in a singular region (from t = {t[i_in]:.6g} s, "
                    f"{kind}, axes {axes}): end elsewhere",
                    np.arange(k, N),
                )
            try:
                qs = _solve_pose(robot, cs, j, qs, tol, max_iter)
                rj = _ratio(robot, qs)
            except TrajectoryError:  # ill-conditioned inside the region: keep scanning
                rj = 0.0
            Q[j], ratio[j] = qs, rj
            if rj < r_min:
                k_min, r_min = j, rj
            if rj >= threshold:
                break
        i_out = j
        # exit branch: of the candidates, the one whose wrist is nearest the entry's
        ref = Q[i_in]
        flipped = ref.copy()
        flipped[3] += math.pi
        flipped[4] = -flipped[4]
        flipped[5] += math.pi
        cands = [qs]
        for g in (ref, flipped, _wrap_near(flipped, ref, qlim, revolute)):
            try:
                cands.append(_solve_pose(robot, cs, i_out, g, tol, max_iter))
            except TrajectoryError:
                pass
        cands = [_wrap_near(c, ref, qlim, revolute) for c in cands]
        best = min(cands, key=lambda c: float(np.max(np.abs(c[3:] - ref[3:]))))
        Q[i_out], ratio[i_out] = best, _ratio(robot, best)
        runs.append((i_in, i_out, k_min, float(ratio[k_min])))
        k, lo = i_out + 1, i_out

    # ---- regions: kind, and the stop / non-wrist check before any remedy
    regions = []
    for i_in, i_out, k_min, r_min in runs:
        kind, axes = _classify(robot, Q[k_min])
        seg = int(cs.segment[i_in + 1])
        region = SingularRegion(
            kind=kind,
            axes=axes,
            t_entry=float(t[i_in]),
            t_exit=float(t[i_out]),
            segment=seg,
            segment_label=trajectory.segments[seg].label,
            sigma_ratio_min=r_min,
            t_closest=float(t[k_min]),
            remedy=remedy,
        )
        if remedy == "stop":
            raise SingularPathError(
                f"{region.describe()} (threshold {threshold:g}); the remedies 'wrist' "
                "(SingArea/Wrist) and 'freeze' pass a wrist singularity",
                np.arange(i_in + 1, i_out),
                region,
            )
        if kind != "wrist":
            raise SingularPathError(
                f"{region.describe()}: remedy {remedy!r} handles wrist singularities only (no "
                "wrist motion keeps the TCP on the path here); change the path",
                np.arange(i_in + 1, i_out),
                region,
            )
        regions.append(region)

    # ---- exact rates of the path solution (overwritten inside the regions)
    mode = np.zeros(N, dtype=int)
    qd, qdd = exact_rates(robot, POSE_TASK, Q, cs)

    # ---- the remedies
    bounds = []
    f = freeze_axis - 1
    for idx, (i_in, i_out, _, _) in enumerate(runs):
        if remedy == "wrist":
            ks = np.arange(i_in + 1, i_out)
            x, xd, xdd = quintic_hermite(
                t[i_out] - t[i_in],
                Q[i_in, 3:],
                qd[i_in, 3:],
                qdd[i_in, 3:],
                Q[i_out, 3:],
                qd[i_out, 3:],
                qdd[i_out, 3:],
                t[ks] - t[i_in],
            )
            for m, kk in enumerate(ks):
                guess = _predict(Q, kk, i_in - min(i_in, 2))
                guess[3:] = x[m]
                try:
                    Q[kk] = _solve_pose(robot, cs, kk, guess, tol, max_iter, ARM_TASK, x[m])
                except TrajectoryError as exc:
                    raise TrajectoryError(
                        f"sample {kk} (t = {t[kk]:.6g} s), wrist joint interpolation: {exc}", [kk]
                    ) from None
            sub = CartesianSamples(
                t[ks], cs.p[ks], cs.v[ks], cs.a[ks], None, None, None, x, xd, xdd, cs.segment[ks]
            )
            qd[ks], qdd[ks] = exact_rates(robot, ARM_TASK, Q[ks], sub)
            mode[ks] = WRIST_PTP
            bounds.append((i_in, i_out))
        else:  # freeze
            span = t[i_out] - t[i_in]
            nr = max(2, int(round((0.5 * span if ramp is None else float(ramp)) / h)))
            prev_end = bounds[-1][1] if bounds else 0
            i_a = max(prev_end, i_in - nr)
            nxt = runs[idx + 1][0] if idx + 1 < len(runs) else N - 1
            i_b = min(nxt, i_out + nr)
            c = Q[i_in, f]
            target = np.empty(i_b - i_a + 1)
            target[i_in - i_a : i_out - i_a + 1] = c
            if i_in > i_a:
                ks = np.arange(i_a + 1, i_in)
                target[1 : i_in - i_a] = quintic_hermite(
                    t[i_in] - t[i_a],
                    Q[i_a, f : f + 1],
                    qd[i_a, f : f + 1],
                    qdd[i_a, f : f + 1],
                    [c],
                    [0.0],
                    [0.0],
                    t[ks] - t[i_a],
                )[0][:, 0]
            target[0] = Q[i_a, f]
            if i_b > i_out:
                ks = np.arange(i_out + 1, i_b)
                target[i_out - i_a + 1 : i_b - i_a] = quintic_hermite(
                    t[i_b] - t[i_out],
                    [c],
                    [0.0],
                    [0.0],
                    Q[i_b, f : f + 1],
                    qd[i_b, f : f + 1],
                    qdd[i_b, f : f + 1],
                    t[ks] - t[i_out],
                )[0][:, 0]
            target[-1] = Q[i_b, f]
            for kf in range(i_a + 1, i_b):
                guess = _predict(Q, kf, max(i_a - 2, 0))
                Q[kf] = _solve_frozen(
                    robot, cs.p[kf], R_path[kf], f, target[kf - i_a], guess, tol, 50
                )
            mode[i_a + 1 : i_b] = FROZEN
            bounds.append((i_a, i_b))
    if remedy == "freeze" and bounds:
        qd_n, qdd_n = numerical_rates(t, Q)
        sel = mode == FROZEN
        qd[sel], qdd[sel] = qd_n[sel], qdd_n[sel]

    # ---- checks: steps, joint limits
    steps = np.max(np.abs(np.diff(Q, axis=0)), axis=1)
    if np.any(steps > max_step):
        first = int(np.argmax(steps > max_step))
        raise TrajectoryError(
            f"joint jump of {steps[first]:.3g} rad between samples {first} and {first + 1} "
            f"(t = {t[first + 1]:.6g} s; max_step {max_step:g}): use a finer dt",
            [first + 1],
        )
    if limits == "raise":
        inside = robot.within_limits(Q)
        if not inside.all():
            bad = np.flatnonzero(~inside)
            raise TrajectoryError(
                f"joint limits exceeded at {bad.size} samples (first t = {t[bad[0]]:.6g} s)", bad
            )

    # ---- deviation from the path, from the robot's fk of the joints
    T = robot.fk(Q)
    pos_err = np.linalg.norm(cs.p - T[:, :3, 3], axis=1)
    ori_dev = np.linalg.norm(rot_log(np.einsum("nji,njk->nik", R_path, T[:, :3, :3])), axis=1)

    # the promise of every mode: the TCP on the path (the solves converge to 1e-13 m, or
    # stall at their rounding floor, 3e-10 m)
    if not pos_err.max() <= 1e-9:
        bad = np.flatnonzero(~(pos_err <= 1e-9))
        raise TrajectoryError(
            f"the TCP is off the path by {np.nanmax(pos_err):.3g} m at {bad.size} samples "
            f"(first t = {t[bad[0]]:.6g} s)",
            bad,
        )

    # ---- uniform time scaling for the speed limits
    with np.errstate(divide="ignore", invalid="ignore"):
        kv = float(np.max(np.abs(qd) / vmax))
        ka = math.sqrt(float(np.max(np.abs(qdd) / amax)))
    scale = max(1.0, kv, ka)
    traj = _scaled(trajectory, scale)
    if scale != 1.0:
        t = t * scale
        qd = qd / scale
        qdd = qdd / (scale * scale)
        cs = traj.evaluate(t)

    out_regions = []
    for region, (a, b) in zip(regions, bounds):
        out_regions.append(
            replace(
                region,
                t_entry=region.t_entry * scale,
                t_exit=region.t_exit * scale,
                t_closest=region.t_closest * scale,
                t_start=float(t[a]),
                t_end=float(t[b]),
                frozen_axis=freeze_axis if remedy == "freeze" else None,
                max_orientation_deviation=float(ori_dev[a : b + 1].max()),
                max_position_deviation=float(pos_err[a : b + 1].max()),
            )
        )
    report = SingularPathReport(
        regions=out_regions,
        threshold=float(threshold),
        remedy=remedy,
        time_scale=scale,
        qd_max=vmax,
        qdd_max=amax,
        peak_qd=np.max(np.abs(qd), axis=0),
        peak_qdd=np.max(np.abs(qdd), axis=0),
        max_position_error=float(pos_err.max()),
        max_orientation_deviation=float(ori_dev.max()),
    )
    return SingularPathResult(robot, t, Q, qd, qdd, mode, pos_err, ori_dev, traj, cs, report)
