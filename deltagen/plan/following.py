"""Path following: inverse kinematics along a Cartesian trajectory
(:mod:`deltagen.plan.cartesian`) into a joint trajectory with its rates, and the
lecture's step-by-step path following.

* **Prescribed joints**: an arm with fewer than six joints cannot follow an arbitrary pose.
  A :class:`Task` picks what is prescribed: some base-frame position axes (``"xy"`` for
  the planar lecture SCARA, ``"xyz"``), optionally the full orientation (six-axis arms),
  and optionally joint coordinates directly (e.g. the wrist roll q4 of the Miskolc RRRR
  arm, which turns the gripper about the forearm and does not move the gripper origin).
  Prescribed joint values are interpolated with the same time scaling.

* **Inverse kinematics along the path** (:func:`to_joint_trajectory`): sample the path on a
  uniform time grid and, at each sample, run a small damped Newton (Levenberg-Marquardt)
  iteration starting from the previous sample's solution (extrapolated quadratically from
  the last three samples as a predictor). Starting in a chosen configuration (``q0``) and moving by small
  steps keeps the solution on that branch: no elbow or wrist flips. Every step is checked:
  ``max |q_k - q_(k-1)| <= max_step`` and an optional ``branch`` predicate (e.g. elbow up,
  ``q3 <= 0``); a violation raises :class:`TrajectoryError` naming the samples.

* **Joint rates**, two ways, compared by :meth:`JointTrajectory.rate_errors`:

  - exact, from the task Jacobian (rows of the geometric Jacobian, unit rows for prescribed
    joints): ``qd = J^+ xd`` and ``qdd = J^+ (xdd - Jdot qd)``;
  - numerically, as the Miskolc paper does (section 5: "the joint velocities and
    accelerations can be obtained by numerical differentiation of the angle functions with
    respect to time"): second-order central differences ``(q_(k+1) - q_(k-1)) / 2h`` and
    ``(q_(k+1) - 2 q_k + q_(k-1)) / h^2`` with second-order one-sided formulas at the ends,
    :func:`numerical_rates`. Both are O(h^2). Differentiated across a segment joint where
    the jerk jumps (quintic stops), the second difference is only O(h) there, so the joint
    samples can be used as breaks: each segment is differentiated on its own.

  For a square task (as many task rows as joints) the exact rates are the derivatives of
  the sampled IK solution, so the two agree to O(h^2) (plus IK noise / h^2). For a redundant
  task the exact rates are the minimum-norm rates, and the IK solution may drift in the null
  space: the comparison then also shows that drift.

* The lecture's path following (slides 106-111; table on the slide footed
  "Folie 111"): :func:`jacobian_path_following` splits the straight line into equal
  sub-steps and takes ONE step ``dQ = J^-1(q) (P_soll,k+1 - P_ist,k)`` per sub-point with
  the inverse Jacobian at the current q, then a direct transformation ``P_ist = f(q)``
  ("damit sich die einzelnen Fehler nicht addieren, wird nach jedem Schritt eine direkte
  Transformation durchgefuehrt"). :func:`newton_step` is that step.

Units: as the robot (metres, radians); time in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from deltagen.errors import KinematicsError
from deltagen.geometry.rotations import rot_log
from deltagen.inputs import InputError, as_float_array
from deltagen.plan.cartesian import CartesianSamples, CartesianTrajectory, _rotation, _vec3
from deltagen.solve import least_squares

_AXES = "xyz"


class TrajectoryError(KinematicsError):
    """The IK along a path failed: no convergence, a jump (branch flip), a branch predicate
    or a joint limit violated. ``rows`` lists the failing sample indices."""


# =========================================================================== tasks and IK


@dataclass(frozen=True)
class Task:
    """What the IK prescribes: base-frame position axes (a subset of "xyz"), optionally the
    full orientation (three angular rows), and optionally joints by index (0-based), in
    that row order. The number of rows must not exceed the number of joints."""

    position: str = "xyz"
    orientation: bool = False
    joints: tuple = ()

    def __post_init__(self):
        if (
            not isinstance(self.position, str)
            or any(c not in _AXES for c in self.position)
            or len(set(self.position)) != len(self.position)
        ):
            raise InputError(
                f"Task position must be distinct letters of 'xyz', got {self.position!r}"
            )
        object.__setattr__(self, "joints", tuple(int(j) for j in self.joints))

    @property
    def rows(self) -> int:
        return len(self.position) + 3 * bool(self.orientation) + len(self.joints)

    @property
    def axes(self) -> list:
        return [_AXES.index(c) for c in self.position]

    def check(self, robot):
        if self.rows == 0:
            raise InputError("the task prescribes nothing")
        if self.rows > robot.n:
            raise InputError(
                f"the task has {self.rows} rows but {robot.name} only {robot.n} joints"
            )
        if any(not (0 <= j < robot.n) for j in self.joints):
            raise InputError(f"task joints must be indices 0..{robot.n - 1}, got {self.joints}")

    def jacobian(self, J):
        """Task Jacobian (..., m, n) from geometric Jacobians (..., 6, n)."""
        parts = [J[..., self.axes, :]]
        if self.orientation:
            parts.append(J[..., 3:, :])
        if self.joints:
            E = np.zeros(J.shape[:-2] + (len(self.joints), J.shape[-1]))
            for r, j in enumerate(self.joints):
                E[..., r, j] = 1.0
            parts.append(E)
        return np.concatenate(parts, axis=-2)

    def jacobian_dot(self, Jd):
        parts = [Jd[..., self.axes, :]]
        if self.orientation:
            parts.append(Jd[..., 3:, :])
        if self.joints:
            parts.append(np.zeros(Jd.shape[:-2] + (len(self.joints), Jd.shape[-1])))
        return np.concatenate(parts, axis=-2)

    def error(self, T, q, p, R=None, qj=None):
        """Task error (m,) at pose T (4, 4), joints q: position p - p(q), orientation
        log(R R(q)^T) (base frame), prescribed joints qj - q[joints]."""
        parts = [np.asarray(p, dtype=float)[self.axes] - T[self.axes, 3]]
        if self.orientation:
            parts.append(rot_log(R @ T[:3, :3].T))
        if self.joints:
            parts.append(np.asarray(qj, dtype=float) - q[list(self.joints)])
        return np.concatenate(parts)

    def _rates(self, linear, angular, joint):
        """The task's rows of sampled rates: the translation axes, the rotation if the task
        has one, the joints it holds."""
        parts = [linear[:, self.axes]]
        if self.orientation:
            parts.append(angular)
        if self.joints:
            parts.append(joint)
        return np.concatenate(parts, axis=-1)

    def velocity(self, cs: CartesianSamples):
        return self._rates(cs.v, cs.w, cs.qjd)

    def acceleration(self, cs: CartesianSamples):
        return self._rates(cs.a, cs.wd, cs.qjdd)


def _solve(Jt, e, damping):
    """The damped least-squares step dq of the task Jacobian Jt and error e
    (solve/least_squares.py): lambda^2 = damping^2 times the mean eigenvalue of Jt Jt^T;
    damping 0: Jt^-1 e (square and regular) or the minimum-norm solution."""
    return least_squares.solve(Jt, e, damping**2, scale="mean")


def newton_step(robot, q, task: Task, p, R=None, qj=None, damping=0.0):
    """One Newton step towards the target: ``q + J^-1(q) e(q)`` (the lecture's
    ``Q = Q0 + J^-1 (P - P0)`` with P0 = f(Q0), slide 109). Returns the new q."""
    q = np.asarray(q, dtype=float)
    T = robot.fk(q)
    e = task.error(T, q, p, R, qj)
    Jt = task.jacobian(robot.jacobian(q))
    return q + _solve(Jt, e, damping)


def solve_ik(
    robot, task: Task, p, R=None, qj=None, q_init=None, tol=1e-13, max_iter=50, damping=1e-9
):
    """Damped Newton (Levenberg-Marquardt) from q_init: returns (q, |e|, iterations).

    The damping lam^2 = (damping)^2 * mean(eig(J J^T)) is tiny by default, so the steps are
    Newton steps away from singularities and stay bounded near them; a step that increases
    the error is retried with ten times the damping. Converged when |e| <= tol, or when the
    iteration stalls (|e| no longer halves) below ``floor = max(tol, 1e-3 sqrt(tol))`` (the
    rounding floor of a large arm); else TrajectoryError."""
    task.check(robot)
    if q_init is None:
        raise InputError("solve_ik needs a start guess q_init (it selects the configuration)")
    q = as_float_array(q_init, "q_init", f"({robot.n},)")
    if q.shape != (robot.n,):
        raise InputError(f"q_init must have {robot.n} values, got shape {q.shape}")
    # the inputs' own faults are named here, not reported as "did not converge"
    if not np.all(np.isfinite(q)):
        raise InputError("q_init contains NaN or infinite values")
    _vec3(p, "p")
    if task.orientation:
        R = _rotation(R)
    if task.joints:
        qj_arr = as_float_array(qj, "qj", f"({len(task.joints)},)")
        if qj_arr.shape != (len(task.joints),) or not np.all(np.isfinite(qj_arr)):
            raise InputError(f"qj must be {len(task.joints)} finite values, got {qj_arr.tolist()}")
    if not (isinstance(max_iter, (int, np.integer)) and not isinstance(max_iter, bool)) or (
        max_iter < 1
    ):
        raise InputError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    floor = max(tol, 1e-3 * math.sqrt(tol))
    lam = damping
    T = robot.fk(q)
    e = task.error(T, q, p, R, qj)
    err = float(np.linalg.norm(e))
    it = 0
    while err > tol and it < max_iter:
        it += 1
        Jt = task.jacobian(robot.jacobian(q))
        for _ in range(12):
            dq = _solve(Jt, e, lam)
            q_new = q + dq
            T_new = robot.fk(q_new)
            e_new = task.error(T_new, q_new, p, R, qj)
            err_new = float(np.linalg.norm(e_new))
            if err_new < err or err_new <= tol:
                break
            lam = max(lam * 10.0, 1e-6)
        else:
            break  # no decrease even with strong damping: stagnation
        stalled = err_new >= 0.5 * err
        q, e, err = q_new, e_new, err_new
        lam = max(lam * 0.1, damping)
        if stalled and err <= floor:  # rounding floor reached
            break
    if not err <= floor:
        raise TrajectoryError(f"IK did not converge: |e| = {err:.3g} after {it} iterations")
    return q, err, it


# =========================================================================== joint trajectory


def numerical_rates(t, q, breaks=()):
    """qd, qdd of samples q (N, n) on the uniform grid t (N,) by second-order finite
    differences: central (q[k+1] - q[k-1]) / 2h and (q[k+1] - 2 q[k] + q[k-1]) / h^2 inside,
    second-order one-sided formulas at the ends ((-3 q0 + 4 q1 - q2) / 2h and
    (2 q0 - 5 q1 + 4 q2 - q3) / h^2). ``breaks`` (times): differentiate each piece between
    breaks on its own (a break sample gets the mean of both one-sided values)."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[:, None]
    N = t.size
    if N < 4:
        raise InputError("numerical differentiation needs at least 4 samples")
    h = (t[-1] - t[0]) / (N - 1)
    if np.max(np.abs(np.diff(t) - h)) > 1e-9 * h:
        raise InputError("numerical_rates needs a uniform time grid")
    cuts = [0]
    for b in np.sort(np.atleast_1d(np.asarray(breaks, dtype=float))):
        i = int(round((b - t[0]) / h))
        if 0 < i < N - 1 and abs(t[i] - b) <= 1e-9 * max(1.0, abs(b)) + 1e-6 * h:
            if i - cuts[-1] >= 3 and N - 1 - i >= 3:
                cuts.append(i)
    cuts.append(N - 1)
    qd = np.zeros_like(q)
    qdd = np.zeros_like(q)
    count = np.zeros(N)
    for a, b in zip(cuts[:-1], cuts[1:]):
        x = q[a : b + 1]
        d1 = np.empty_like(x)
        d2 = np.empty_like(x)
        d1[1:-1] = (x[2:] - x[:-2]) / (2 * h)
        d1[0] = (-3 * x[0] + 4 * x[1] - x[2]) / (2 * h)
        d1[-1] = (3 * x[-1] - 4 * x[-2] + x[-3]) / (2 * h)
        d2[1:-1] = (x[2:] - 2 * x[1:-1] + x[:-2]) / h**2
        d2[0] = (2 * x[0] - 5 * x[1] + 4 * x[2] - x[3]) / h**2
        d2[-1] = (2 * x[-1] - 5 * x[-2] + 4 * x[-3] - x[-4]) / h**2
        qd[a : b + 1] += d1
        qdd[a : b + 1] += d2
        count[a : b + 1] += 1
    return qd / count[:, None], qdd / count[:, None]


@dataclass
class JointTrajectory:
    """The IK solution along a Cartesian trajectory and its rates.

    t (N,), q, qd, qdd (N, n) exact rates from the task Jacobian; qd_num, qdd_num numerical
    (piecewise between segment joints); task_error (N,) |e| after the IK; iterations (N,)
    Newton iterations per sample; cartesian: the sampled target."""

    robot: object
    task: Task
    trajectory: CartesianTrajectory
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qd_num: np.ndarray
    qdd_num: np.ndarray
    task_error: np.ndarray
    iterations: np.ndarray
    cartesian: CartesianSamples

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def joint_steps(self) -> np.ndarray:
        """|q_k - q_(k-1)| per joint (N - 1, n)."""
        return np.abs(np.diff(self.q, axis=0))

    @property
    def max_joint_step(self) -> float:
        return float(self.joint_steps.max())

    def rate_errors(self) -> dict:
        """Max |exact - numerical| per joint and overall, for qd and qdd."""
        dqd = np.abs(self.qd - self.qd_num)
        dqdd = np.abs(self.qdd - self.qdd_num)
        return {
            "qd": float(dqd.max()),
            "qdd": float(dqdd.max()),
            "qd_per_joint": dqd.max(axis=0),
            "qdd_per_joint": dqdd.max(axis=0),
            "qd_peak": float(np.abs(self.qd).max()),
            "qdd_peak": float(np.abs(self.qdd).max()),
        }

    def numerical_rates_unsplit(self):
        """The paper's way without breaks: the whole signal differentiated at once."""
        return numerical_rates(self.t, self.q)


def exact_rates(robot, task: Task, q, cs: CartesianSamples):
    """qd = J^+ xd and qdd = J^+ (xdd - Jdot qd) with the task Jacobian at q (N, n)."""
    Jt = task.jacobian(robot.jacobian(q))
    pinv = np.linalg.pinv(Jt)
    qd = np.einsum("nij,nj->ni", pinv, task.velocity(cs))
    Jdt = task.jacobian_dot(robot.jacobian_dot(q, qd))
    rhs = task.acceleration(cs) - np.einsum("nij,nj->ni", Jdt, qd)
    qdd = np.einsum("nij,nj->ni", pinv, rhs)
    return qd, qdd


def to_joint_trajectory(
    robot,
    trajectory: CartesianTrajectory,
    task: Task,
    q0,
    dt=0.01,
    *,
    tol=1e-13,
    max_iter=30,
    max_step=0.2,
    branch=None,
    limits="raise",
    damping=1e-9,
) -> JointTrajectory:
    """Inverse kinematics along ``trajectory`` sampled every ``dt`` (or less, see
    :meth:`CartesianTrajectory.sample_times`), in the configuration of ``q0``.

    ``q0`` is the starting guess for the first sample (a joint vector or the name of one of
    the robot's configurations); every later sample starts from the previous solutions
    extrapolated by a quadratic (``3 q_(k-1) - 3 q_(k-2) + q_(k-3)``). Checks (TrajectoryError naming the
    samples): convergence, ``max |q_k - q_(k-1)| <= max_step`` [rad or m] (no jumps, i.e.
    no branch flips), ``branch(q) -> bool`` (optional, e.g. elbow up), and the joint limits
    (``limits="raise"``; ``"ignore"`` skips them)."""
    task.check(robot)
    if limits not in ("raise", "ignore"):
        raise InputError('limits must be "raise" or "ignore"')
    if task.orientation and not trajectory.has_orientation:
        raise InputError("the task prescribes the orientation but the trajectory has none")
    if len(task.joints) != trajectory.n_joints_prescribed:
        raise InputError(
            f"the task prescribes {len(task.joints)} joints, the trajectory "
            f"{trajectory.n_joints_prescribed}"
        )
    if isinstance(q0, str):
        q0 = robot.configuration(q0)
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (robot.n,):
        raise InputError(f"q0 must have {robot.n} values")
    t = trajectory.sample_times(dt)
    cs = trajectory.evaluate(t)
    N = t.size
    Q = np.empty((N, robot.n))
    err = np.empty(N)
    its = np.zeros(N, dtype=int)
    guess = q0
    for k in range(N):
        R = None if cs.R is None else cs.R[k]
        try:
            q, err[k], its[k] = solve_ik(
                robot,
                task,
                cs.p[k],
                R,
                cs.qj[k],
                guess,
                tol=tol,
                max_iter=max_iter,
                damping=damping,
            )
        except TrajectoryError as exc:
            raise TrajectoryError(f"sample {k} (t = {t[k]:.6g} s): {exc}", [k]) from None
        if k > 0:
            step = float(np.max(np.abs(q - Q[k - 1])))
            if step > max_step:
                raise TrajectoryError(
                    f"joint jump of {step:.3g} > max_step = {max_step:g} between samples {k - 1} "
                    f"and {k} (t = {t[k]:.6g} s): a branch flip or a singularity on the path",
                    [k],
                )
        Q[k] = q
        # predictor for the next sample: the quadratic through the last three solutions
        # (error O(h^3)), so one or two Newton iterations suffice
        if k >= 2:
            guess = 3.0 * (q - Q[k - 1]) + Q[k - 2]
        elif k == 1:
            guess = 2.0 * q - Q[0]
        else:
            guess = q
    if branch is not None:
        ok = np.asarray(branch(Q), dtype=bool)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            raise TrajectoryError(
                f"the branch condition fails at {bad.size} samples (first t = {t[bad[0]]:.6g} s)",
                bad,
            )
    if limits == "raise":
        inside = robot.within_limits(Q)
        if not inside.all():
            bad = np.flatnonzero(~inside)
            lim = robot.qlim
            worst = np.max(np.maximum(lim[:, 0] - Q[bad], Q[bad] - lim[:, 1]), axis=0)
            raise TrajectoryError(
                f"joint limits exceeded at {bad.size} samples (first t = "
                f"{t[bad[0]]:.6g} s; overshoot per joint {np.round(worst, 6)})",
                bad,
            )
    qd, qdd = exact_rates(robot, task, Q, cs)
    qd_num, qdd_num = numerical_rates(t, Q, trajectory.breaks)
    return JointTrajectory(robot, task, trajectory, t, Q, qd, qdd, qd_num, qdd_num, err, its, cs)


# =========================================================================== the lecture


@dataclass
class PathFollowingTable:
    """The lecture's table (slide "Folie 111"): per sub-point k = 0..steps the commanded
    ("Soll") and reached ("Ist") task coordinates, and the joints; then the further Newton
    iterations at the target (``converge_*``)."""

    soll: np.ndarray
    ist: np.ndarray
    q: np.ndarray
    converge_ist: np.ndarray
    converge_q: np.ndarray

    @property
    def final_error(self) -> float:
        last = self.converge_ist[-1] if len(self.converge_ist) else self.ist[-1]
        return float(np.linalg.norm(last - self.soll[-1]))


def jacobian_path_following(
    robot, q0, target, steps=10, task=Task("xy"), converge_tol=1e-12, max_converge=20
) -> PathFollowingTable:
    """Slides 106-111: the straight line from P0 = f(q0) to ``target`` split into ``steps``
    equal parts along each axis; per sub-point ONE step ``q += J^-1(q) (P_soll,k+1 - f(q))``
    with J the task Jacobian at the current q (for the planar SCARA the 2x2 matrix of slide
    108), then the direct transformation. Afterwards Newton steps at the target itself until
    ``|P_ist - target| <= converge_tol``."""
    task.check(robot)
    if task.orientation or task.joints:
        raise InputError("jacobian_path_following follows positions only")
    q = np.array(q0, dtype=float)
    target = np.asarray(target, dtype=float)
    axes = task.axes

    def pos(qq):
        return robot.fk(qq)[axes, 3]

    def full(x):
        out = np.zeros(3)
        out[axes] = x
        return out

    P0 = pos(q)
    soll = P0 + (target - P0) * (np.arange(steps + 1) / steps)[:, None]
    soll[-1] = target
    ist, qs = [P0], [q.copy()]
    for k in range(1, steps + 1):
        q = newton_step(robot, q, task, full(soll[k]), damping=0.0)
        qs.append(q.copy())
        ist.append(pos(q))
    c_ist, c_q = [], []
    for _ in range(max_converge):
        if np.linalg.norm((c_ist[-1] if c_ist else ist[-1]) - target) <= converge_tol:
            break
        q = newton_step(robot, q, task, full(target), damping=0.0)
        c_q.append(q.copy())
        c_ist.append(pos(q))
    return PathFollowingTable(
        soll,
        np.array(ist),
        np.array(qs),
        np.array(c_ist).reshape(-1, len(axes)),
        np.array(c_q).reshape(-1, robot.n),
    )
