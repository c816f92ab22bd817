"""Numerical inverse kinematics of serial arms: batched, damped Newton-Raphson.

The method is the iteration of the EASY-ROB paper ("Numerisches Loesungsverfahren
zur inversen Transformation", steps 1-6) and of the lecture's Jacobian method (lecture
slides 106-110), vectorised over N targets (no Python loop over targets):

1. given the target pose T* (position p*, rotation R*), find q with fk(q) = T*;
2. evaluate T = fk(q) and the Jacobian J(q);
3. error dx = [p* - p; w] in the base frame, where w = theta * axis is the rotation vector
   (axis-angle) of R* R^T, the rotation that still has to be applied to the tool (its
   norm theta is the rotation error, exact also near theta = pi);
4. solve J dq = dx on the selected rows ("mask"), limit dq;
5. q <- q + dq (wrapped by 2 pi / clamped into the joint limits), T = fk(q);
6. stop when |p* - p| <= tol_position [m] and |w| <= tol_rotation [rad], else go to 2.

Jacobian sources (``jacobian=``), the EASY-ROB paper's three methods:

* ``"symbolic"``  -- the generated C geometric Jacobian (the SymPy derivation, i.e. the
  "analytic derivative" route), ``arm._core.jacobian``;
* ``"geometric"`` -- the cross-product method, computed HERE from the frames of the arm
  (``arm._core.frames``): column i is [w_i x (p - o_i); w_i] for a revolute joint and
  [w_i; 0] for a prismatic one, w_i / o_i the joint axis direction / a point on it
  (standard DH: z and origin of frame i-1; modified DH: of frame i; universal: the joint's
  ``axis`` column of base D_1 ... D_{i-1}). It does not use the C Jacobian;
* ``"fd"``        -- central finite differences of fk alone (the paper's "general method",
  for chains with couplings): v_i = (p(q + h e_i) - p(q - h e_i)) / 2h and
  [w_i]x = skew((R(q + h e_i) - R(q - h e_i)) R^T) / 2h, h = 2^-17.

Solving J dq = dx (per row, batched), with k = number of matched components:

* n == k (e.g. a 6-axis arm, all six components), well-conditioned (sigma_min >=
  ``SIGMA_WELL`` = 1e-2) and the damping negligible (lambda <= 1e-3 sigma_min, i.e. it
  would change the step by less than 1e-6 relative; true in the final, quadratically
  convergent steps): Gauss elimination, ``np.linalg.solve`` (the paper's choice for
  m = n = 6);
* otherwise the singular value decomposition J = U S V^T and the damped pseudo-inverse
  dq = V diag(s / (s^2 + lambda^2)) U^T dx. With lambda = 0 this is the Moore-Penrose
  pseudo-inverse: the minimum-norm step for redundant arms (n > k, the paper's "SVD for
  m > 6") and the least-squares step for n < k. For n > k an optional null-space term
  ``null_space * min(1, |dx|) * (I - J^+ J) (q_mid - q)`` pulls towards the middle of the
  joint ranges while the error is large (it fades out with |dx|, so the final steps stay
  quadratic; its effect on where the solution lands is therefore modest).

Damping (``damping="auto"``: Levenberg-Marquardt with a singularity-robust term):
lambda^2 = (mu + c0 + K (1 - (sigma_min / SIGMA_WELL)^2)_+) * |dx|^2, c0 = 0.1, K = 1.
The K term is the Nakamura-Hanafusa rule (damping grows as sigma_min falls below a
threshold); mu is the row's Levenberg-Marquardt parameter (0 at the start, raised x10 /
at least to 1e-2 when a step is rejected, lowered /10 when one is accepted). All terms
are scaled by the squared error (Yamashita-Fukushima): the damping vanishes at the
solution, so the iteration stays fast even at singular solutions (the Puma wrist at
q5 = 0), where a constant damping would stall the weak direction at ~lambda^2-relative
accuracy. ``damping=<float c>``: the same with K = c. ``damping=None``: plain
Newton-Raphson as in the seed (no damping, every step taken, singular values below
1e-12 sigma_max dropped).

Step acceptance (with damping): non-monotone (Zhang-Hager): a step is taken if the new
|dx| = sqrt(|dp|^2 + |w|^2) (matched components, m and rad) is below C, the running
average C <- (eta Q C + |dx|) / (eta Q + 1), Q <- eta Q + 1 of the accepted errors
(eta = ``ETA`` = 0.95; eta = 0 is the monotone rule |dx_new| < |dx|). Allowing a
temporary rise lets the iteration leave the curved valleys near singular configurations
(an elbow stretched at the workspace boundary) where a monotone rule creeps for hundreds
of steps. The q returned for an unconverged row is the best one seen.

Step limiting: dq is scaled so that max_i |dq_i| <= ``step_limit`` (rad or m).

Joint limits (``respect_limits=True``; the result is always within arm.qlim):

* a revolute joint outside its range is shifted by a multiple of 2 pi wherever that
  brings it inside (the same pose; :func:`deltagen.geometry.limits.shift_into_limits`);
* each attempt (the first one from q0) first iterates with the limits unenforced (2 pi
  shifts only) -- Newton's basins are larger without clamping -- and checks the limits
  once |dx| <= max(tol, 1e-9) per component. If that solution is outside the limits,
  the attempt goes back to its start point (clamped into the limits) and iterates again
  with the limits enforced: after every step clamp, and joints that a step would push
  through a limit are set onto it while the remaining joints solve for the rest of dx
  (one active-set pass, a second SVD for those rows). Restarting the limited phase from
  the start rather than from the clamped out-of-range solution converged more often
  (Puma 560 from qz, no restarts: 72 vs 68 %);
* a row that is stuck ends its attempt: mu above 1e12 (no step is accepted any more),
  or, when a restart is left, |dx| not halved over 8 steps (24 in the attempt from the
  caller's q0, usually the informed one: a slow but converging start near a singularity
  is not given up early) -- at a limit or in a local minimum. With ``restarts`` > 0
  (default ``RESTARTS`` = 100) it starts again from another q in the box of the limits
  (unlimited revolute joints in [-pi, pi], unlimited prismatic ones in [-1, 1] m): the
  compiled engine takes the points of a deterministic additive-recurrence sequence spread
  evenly over the box (codegen/runtime/deltagen_ik_newton.c, the whole loop in C), the
  numpy engine draws them uniformly from ``np.random.default_rng(seed)``. Each attempt has at most ``max_iter`` steps; rows still
  unconverged after the last attempt return the best in-limit q found, converged False.

A 6-axis arm has up to 8 (16) isolated solutions and often only one or two lie inside the
limits; a random start reaches one of them with probability ~0.1-0.9 depending on the
target, so global success from an arbitrary start needs restarts (tens for 100 % on
1000 random targets); from a start near the solution one attempt suffices.

Mask ("tool fitting", EASY-ROB paper, for arms with fewer than 6 axes): 6 booleans for the
components (vx vy vz wx wy wz) to match; the others are ignored. Default: all six if
n >= 6; for n < 6 the components the arm can move at all, i.e. the rows of the Jacobian
(of the chosen source) that are not identically zero (max |J_row| <= 1e-9 max |J|; 1e-6
for "fd") over 32 random in-limit configurations. A SCARA (manutec_h5, bosch_sr800) gets
vx vy vz wz (position + rotation about z); the planar 2R lecture_scara gets vx vy wz
(three components for two joints: a least-squares fit that converges for targets of the
form fk(q); give mask=(1,1,0,0,0,0) for position only). With wz the only rotation
component, the z component of the rotation vector of R* R^T is driven to zero: the
tool's rotation about the base z axis is fitted, a tilt of the target's tool axis (which
such an arm cannot follow) is ignored. position_error / rotation_error measure the
matched components only.

Invalid input rows (any non-finite value in T or q0) are not iterated: converged False,
q, position_error and rotation_error NaN, iterations 0. Nothing warns: floating-point
errors are suppressed inside and every array is finite on the rows that are iterated.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from deltagen import status as st
from deltagen.geometry.limits import shift_into_limits
from deltagen.geometry.rotations import rot_log as rotation_vector  # rotation_vector: public
from deltagen.geometry.rotations import vee
from deltagen.inputs import InputError, as_float_array, is_real
from deltagen.solve.least_squares import damped_step, kept

__all__ = ["IKResult", "solve", "jacobian", "pose_error", "rotation_vector", "default_mask"]

JACOBIANS = ("symbolic", "geometric", "fd")
ENGINES = ("auto", "c", "numpy")
SIGMA_WELL = 1e-2  # sigma_min below this: damping grows (Nakamura-Hanafusa threshold)
BASE_DAMPING = 0.1  # c0: lambda^2 >= c0 |dx|^2 always
GAUSS_REL = 1e-3  # Gauss elimination when lambda <= GAUSS_REL * sigma_min (and n == k)
MU_START = 1e-2  # LM parameter after the first rejected step
MU_MAX = 1e12  # LM parameter above which the attempt counts as stuck
STALL_WINDOW = 8  # steps over which |dx| must at least halve (else stuck)
FIRST_WINDOW_FACTOR = 3  # ... times this for the attempt from the caller's q0
FD_STEP = 2.0**-17  # central-difference step (~ eps^(1/3))
ACTIVE_SET = True  # re-solve without the joints a step pushes through a limit
ETA = 0.95  # non-monotone acceptance weight (Zhang-Hager); 0: monotone
PHASE2_FROM_START = True  # the limited phase restarts from the attempt's start point
FREE_CHECK = 1e-9  # free phase: limits checked once |dx| <= max(tol, this)
FREE_FIRST = True  # each attempt starts with the limits unenforced (module docstring)
#: default number of restarts: enough for every reachable in-limit target of the Puma 560
#: and of a 7-axis arm in the tests and in `deltagen bench` (apps/bench/ik.py); a target
#: the first attempt solves costs nothing more, an unreachable one at most this many short
#: (stalled) attempts
RESTARTS = 100
_RCOND = 1e-12
_AXIS = {"x": 0, "y": 1, "z": 2}


@dataclass
class IKResult:
    """Result of :func:`solve`, shaped like the targets' leading dimensions.

    q: (..., n) joint values (the solution, or the best q found for unconverged rows);
    converged: (...) bool; iterations: (...) Newton steps used over all attempts;
    position_error [m] and rotation_error [rad]: (...) norms of the matched (masked)
    components of p* - p and of the rotation vector of R* R^T at q; mask: the (6,) bool
    mask used (vx vy vz wx wy wz).
    """

    q: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    mask: np.ndarray

    def __repr__(self):
        conv = np.asarray(self.converged)
        return (
            f"IKResult({int(conv.sum())} of {conv.size} converged, "
            f"max iterations {int(np.max(self.iterations, initial=0))})"
        )


# ------------------------------------------------------------------------------ geometry


def pose_error(T_current: np.ndarray, T_target: np.ndarray, mask=None) -> np.ndarray:
    """(N, 6): [p* - p; rotation vector of R* R^T] in the base frame; components outside
    ``mask`` set to 0."""
    e = np.empty(T_current.shape[:1] + (6,))
    e[:, :3] = T_target[:, :3, 3] - T_current[:, :3, 3]
    e[:, 3:] = rotation_vector(T_target[:, :3, :3] @ np.swapaxes(T_current[:, :3, :3], 1, 2))
    if mask is not None:
        e[:, ~np.asarray(mask, dtype=bool)] = 0.0
    return e


def _geometric_jacobian(arm, q: np.ndarray) -> np.ndarray:
    """Cross-product Jacobian from the frames (see the module docstring)."""
    desc = arm.description
    F, _ = arm._core.frames(q)
    N, n = q.shape
    idx = np.arange(n)
    if desc.convention == "modified":
        M = F[:, idx + 1]
        cols = np.full(n, 2)
    elif desc.convention == "standard":
        M = F[:, idx]
        cols = np.full(n, 2)
    else:
        M = F[:, idx]
        cols = np.array([_AXIS[j.axis] for j in desc.joints])
    o = M[:, :, :3, 3]  # (N, n, 3) points on the axes
    w = np.einsum("nkij,kj->nki", M[:, :, :3, :], np.eye(4)[cols])  # (N, n, 3) directions
    w = w * np.array([j.sign for j in desc.joints])[None, :, None]  # reversed joints
    p = F[:, -1, :3, 3]
    rev = np.array([j.revolute for j in desc.joints])
    J = np.empty((N, 6, n))
    J[:, :3] = np.where(rev[None, :, None], np.cross(w, p[:, None, :] - o), w).transpose(0, 2, 1)
    J[:, 3:] = np.where(rev[None, :, None], w, 0.0).transpose(0, 2, 1)
    return J


def _fd_jacobian(arm, q: np.ndarray) -> np.ndarray:
    N, n = q.shape
    h = FD_STEP
    Q = np.repeat(q[:, None, None, :], 2, axis=1).repeat(n, axis=2)  # (N, 2, n, n)
    eye = np.eye(n) * h
    Q[:, 0] += eye
    Q[:, 1] -= eye
    Tpm, _ = arm._core.fk(np.ascontiguousarray(Q.reshape(-1, n)))
    Tpm = Tpm.reshape(N, 2, n, 4, 4)
    T0, _ = arm._core.fk(q)
    Tp, Tm = Tpm[:, 0], Tpm[:, 1]
    J = np.empty((N, 6, n))
    J[:, :3] = ((Tp[..., :3, 3] - Tm[..., :3, 3]) / (2 * h)).transpose(0, 2, 1)
    D = (Tp[..., :3, :3] - Tm[..., :3, :3]) @ np.swapaxes(T0[:, None, :3, :3], -1, -2)
    D = D / (2 * h)
    wv = vee(D)  # (N, n, 3)
    J[:, 3:] = wv.transpose(0, 2, 1)
    return J


def jacobian(arm, q, source: str = "symbolic") -> np.ndarray:
    """Base-frame geometric Jacobian (N, 6, n) of finite q (N, n) from one of the sources
    "symbolic" (generated C), "geometric" (cross products of the frames) or "fd"
    (central differences of fk)."""
    if source not in JACOBIANS:
        raise InputError(f"jacobian must be one of {JACOBIANS}, got {source!r}")
    q = as_float_array(q, "q")
    if q.shape[-1] != arm.n:
        raise InputError(f"q must have shape (..., {arm.n}) for {arm.name}, got {q.shape}")
    q = np.ascontiguousarray(q.reshape(-1, arm.n))
    if source == "symbolic":
        return arm._core.jacobian(q)[0]
    if source == "geometric":
        return _geometric_jacobian(arm, q)
    return _fd_jacobian(arm, q)


# ----------------------------------------------------------------------------- helpers


def _sample_box(arm):
    """Finite (lo, hi) boxes for random starts."""
    lim = arm.qlim
    rev = np.array([j.revolute for j in arm.description.joints])
    width = np.where(rev, 2 * np.pi, 2.0)
    lo, hi = lim[:, 0].copy(), lim[:, 1].copy()
    lo_f, hi_f = np.isfinite(lo), np.isfinite(hi)
    lo = np.where(lo_f, lo, np.where(hi_f, hi - width, -width / 2))
    hi = np.where(hi_f, hi, lo + width)
    return lo, hi


def default_mask(arm, source: str = "symbolic") -> np.ndarray:
    """The default components to match (see the module docstring)."""
    if arm.n >= 6:
        return np.ones(6, dtype=bool)
    lo, hi = _sample_box(arm)
    rng = np.random.default_rng(20240601)
    q = lo + (hi - lo) * rng.random((32, arm.n))
    J = jacobian(arm, q, source)
    size = np.max(np.abs(J), axis=(0, 2))
    rel = 1e-6 if source == "fd" else 1e-9  # fd rows carry ~1e-11 relative noise
    return size > rel * max(float(np.max(size)), 1e-300)


def _check_mask(mask) -> np.ndarray:
    m = np.asarray(mask)
    if m.shape != (6,) or not (m.dtype.kind in "biu" and np.all((m == 0) | (m == 1))):
        raise InputError("mask must be 6 booleans (vx vy vz wx wy wz)")
    m = m.astype(bool)
    if not m.any():
        raise InputError("mask selects no pose component")
    return m


def _check_tol(tol):
    if type(tol) is float or type(tol) is int:  # the common case, without numpy
        if math.isfinite(tol) and tol >= 0:
            return float(tol), float(tol)
    try:
        t = np.asarray(tol, dtype=float)
        t = np.broadcast_to(t, (2,)) if t.ndim <= 1 else None
    except (TypeError, ValueError):
        t = None
    if t is None or not np.all(np.isfinite(t)) or np.any(t < 0):
        raise InputError("tol must be a finite value >= 0 or a pair (position [m], rotation [rad])")
    return float(t[0]), float(t[1])


class _Limits:
    def __init__(self, arm, respect):
        lim = arm.qlim
        self.lo, self.hi = lim[:, 0], lim[:, 1]
        self.respect = respect
        rev = np.array([j.revolute for j in arm.description.joints])
        self.wrap = rev & np.isfinite(self.lo) & np.isfinite(self.hi)
        self.mid = np.where(
            np.isfinite(self.lo) & np.isfinite(self.hi), 0.5 * (self.lo + self.hi), np.nan
        )

    def wrap_only(self, q):
        """q with out-of-range revolute joints shifted by 2 pi where that brings them in."""
        if not self.respect:
            return q
        return shift_into_limits(q, self.lo, self.hi, self.wrap)

    def apply(self, q):
        if not self.respect:
            return q
        return np.clip(self.wrap_only(q), self.lo, self.hi)


# ------------------------------------------------------------------------------- solve

#: the keyword options of solve() (and of SerialRobot.ik(method="numeric")) and their
#: defaults, written once: check_options() fills what a call leaves out from here
DEFAULTS = {
    "tol": 1e-10,
    "max_iter": 100,
    "mask": None,
    "jacobian": "symbolic",
    "damping": "auto",
    "step_limit": 0.5,
    "respect_limits": True,
    "restarts": RESTARTS,
    "seed": 0,
    "null_space": 0.0,
    "engine": "auto",
}
OPTIONS = tuple(DEFAULTS)


def _is_count(x) -> bool:
    if type(x) is int:
        return True
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _finite_real(x) -> bool:
    return is_real(x) and math.isfinite(x)


def check_options(arm, *, min_iter=1, **options) -> dict:
    """The one check of solve()'s options (solve() and SerialRobot.ik call it on every
    call): raises InputError naming the first bad option, else returns them checked:
    tol as (position, rotation), damping as (K, c0, Levenberg-Marquardt on), mask as a
    (6,) bool array or None, and c_ok (the compiled engine applies). ``min_iter``: the
    smallest max_iter accepted (solve(): 0, which only checks the start; ik: 1). The
    returned dict also holds every option, the defaults (DEFAULTS) filled in."""
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)}; the options are {OPTIONS}")
    given = {**DEFAULTS, **options}
    tol, max_iter, mask, jacobian, damping, step_limit = (
        given[k] for k in ("tol", "max_iter", "mask", "jacobian", "damping", "step_limit")
    )
    respect_limits, restarts, seed, null_space, engine = (
        given[k] for k in ("respect_limits", "restarts", "seed", "null_space", "engine")
    )
    if jacobian not in JACOBIANS:
        raise InputError(f"jacobian must be one of {JACOBIANS}, got {jacobian!r}")
    tol_pr = _check_tol(tol)
    if not _is_count(max_iter) or max_iter < min_iter:
        raise InputError(f"max_iter must be an integer >= {min_iter}, got {max_iter!r}")
    if not _is_count(restarts) or restarts < 0:
        raise InputError(f"restarts must be an integer >= 0, got {restarts!r}")
    if not (
        (_is_count(seed) and seed >= 0)
        or seed is None
        or isinstance(seed, (np.random.Generator, np.random.SeedSequence))
    ):
        raise InputError(
            f"seed must be an integer >= 0, None or a numpy Generator/SeedSequence, got {seed!r}"
        )
    if isinstance(damping, str) and damping == "auto":
        damp = (1.0, BASE_DAMPING, True)
    elif damping is None:
        damp = (0.0, 0.0, False)
    elif _finite_real(damping) and damping >= 0:
        damp = (float(damping), BASE_DAMPING, True)
    else:
        raise InputError(f'damping must be "auto", a number >= 0 or None, got {damping!r}')
    if step_limit is not None and not (
        is_real(step_limit) and not math.isnan(step_limit) and step_limit > 0
    ):
        raise InputError(f"step_limit must be a number > 0 or None, got {step_limit!r}")
    if respect_limits is not True and not isinstance(respect_limits, (bool, np.bool_)):
        raise InputError(f"respect_limits must be True or False, got {respect_limits!r}")
    if not (_finite_real(null_space) and null_space >= 0):
        raise InputError(f"null_space must be a finite number >= 0, got {null_space!r}")
    if not isinstance(engine, str) or engine not in ENGINES:
        raise InputError(f"engine must be one of {ENGINES}, got {engine!r}")
    c_ok = (
        getattr(arm, "backend", None) == "compiled"
        and jacobian == "symbolic"
        and damp[2]
        and null_space == 0
    )
    if engine == "c" and not c_ok:
        raise InputError(
            'engine="c" needs the compiled backend, jacobian="symbolic", '
            'damping "auto" or a number, and null_space=0'
        )
    return {
        **given,
        "tol": tol_pr,
        "damping": damp,
        "mask": None if mask is None else _check_mask(mask),
        "c_ok": c_ok,
    }


def solve(arm, T, q0=None, **options) -> IKResult:
    """Joint values q with fk(q) = T for a batch of target poses (module docstring).

    arm: a SerialRobot (its raw batched backend ``arm._core`` is used).
    T: (..., 4, 4) targets (only the rotation block and the position column are used).
    q0: (n,) or (..., n) start, broadcast against T's leading shape; None: the arm's "qz"
    configuration if it has one, else zeros.
    options (keywords; defaults in DEFAULTS, written once):
    tol: one value for both, or (position [m], rotation [rad]).
    max_iter: Newton steps per attempt.
    mask: 6 booleans vx vy vz wx wy wz (default: see the module docstring).
    jacobian: "symbolic" | "geometric" | "fd".
    damping: "auto" | float >= 0 (the Nakamura-Hanafusa weight K) | None (plain Newton).
    step_limit: max |dq_i| per step [rad or m] (None: unlimited).
    respect_limits: keep q in arm.qlim (always True for the returned q then).
    restarts: extra attempts for unconverged rows (default RESTARTS); the C engine starts
    them from a deterministic sequence spread over the limits, the numpy engine from random
    in-limit draws; seed: the sequence's offset, or the numpy generator's seed (results are
    reproducible for an integer seed).
    null_space: gain of the pull towards mid-range (redundant case n > k only).
    engine: "c" (the compiled Newton routine deltagen_<arm>_ik_newton, restarts included), "numpy"
    (the batched numpy iteration), or "auto": "c" when it applies -- the compiled
    backend, jacobian="symbolic", damping not None, null_space == 0 -- else "numpy".

    Returns an :class:`IKResult` shaped like T's leading dimensions; invalid rows (any
    non-finite value in T or q0) come back NaN and unconverged, nothing raises or warns
    for them.
    """
    opts = check_options(arm, min_iter=0, **options)
    max_iter, jacobian, step_limit, respect_limits = (
        opts[k] for k in ("max_iter", "jacobian", "step_limit", "respect_limits")
    )
    restarts, seed, null_space, engine = (
        opts[k] for k in ("restarts", "seed", "null_space", "engine")
    )
    tol_p, tol_r = opts["tol"]
    k_nh, c0, lm = opts["damping"]
    c_ok = opts["c_ok"]
    use_c = engine == "c" or (engine == "auto" and c_ok)
    n = arm.n
    T = as_float_array(T, "T")
    if T.ndim < 2 or T.shape[-2:] != (4, 4):
        raise InputError(f"T must have shape (..., 4, 4), got {T.shape}")
    lead = T.shape[:-2]
    if q0 is None:
        q0 = arm.configurations.get("qz", np.zeros(n))
    q0 = as_float_array(q0, "q0")
    if q0.shape[-1] != n:
        raise InputError(f"q0 must have shape (..., {n}) for {arm.name}, got {q0.shape}")
    try:
        q0 = np.broadcast_to(q0, lead + (n,))
    except ValueError:
        raise InputError(
            f"q0 of shape {q0.shape} does not broadcast to the targets' {lead}"
        ) from None
    mask = default_mask(arm, jacobian) if opts["mask"] is None else opts["mask"]

    Tt = np.ascontiguousarray(T.reshape(-1, 4, 4))
    Q0 = np.array(q0.reshape(-1, n), dtype=float)
    N = Tt.shape[0]
    valid = np.all(np.isfinite(Tt), axis=(1, 2)) & np.all(np.isfinite(Q0), axis=1)
    q_out = np.full((N, n), np.nan)
    conv = np.zeros(N, dtype=bool)
    iters = np.zeros(N, dtype=np.int64)
    pos_err = np.full(N, np.nan)
    rot_err = np.full(N, np.nan)
    rows = np.flatnonzero(valid)
    if rows.size:
        if use_c:
            q, c, it, pe, re = _iterate_c(
                arm,
                Tt[rows],
                Q0[rows],
                mask,
                tol_p,
                tol_r,
                int(max_iter),
                k_nh,
                c0,
                step_limit,
                bool(respect_limits),
                int(restarts),
                seed,
            )
        else:
            with np.errstate(all="ignore"):
                q, c, it, pe, re = _iterate(
                    arm,
                    Tt[rows],
                    Q0[rows],
                    mask,
                    tol_p,
                    tol_r,
                    int(max_iter),
                    jacobian,
                    k_nh,
                    c0,
                    lm,
                    step_limit,
                    bool(respect_limits),
                    int(restarts),
                    seed,
                    float(null_space),
                )
        q_out[rows], conv[rows], iters[rows], pos_err[rows], rot_err[rows] = q, c, it, pe, re
    # the finite-output rule (deltagen.status): converged means every value is finite
    conv &= np.all(np.isfinite(q_out), axis=1) & np.isfinite(pos_err) & np.isfinite(rot_err)
    return IKResult(
        q=q_out.reshape(lead + (n,)),
        converged=conv.reshape(lead),
        iterations=iters.reshape(lead),
        position_error=pos_err.reshape(lead),
        rotation_error=rot_err.reshape(lead),
        mask=mask,
    )


def _newton_step(A, r, err, mu, damped, c0, k_nh, q, mid, null_gain, step_limit, smin_prev):
    """The step dq for (k, m, n) A and (k, m) r (module docstring), and sigma_min.

    lambda^2 = mu |dx|^2, plus (c0 + K (1 - (sigma_min / SIGMA_WELL)^2)_+) |dx|^2 if
    ``damped``. Square rows whose damping is negligible are solved by Gauss elimination;
    the decision uses the row's sigma_min of the previous step (``smin_prev``, 0: unknown)
    with a safety factor 2, so that those rows skip the SVD (the costly part); the others
    get the damped SVD step, the null-space pull (n > k) and a fresh sigma_min."""
    k, m, n = A.shape
    dq = np.empty((k, n))
    smin = smin_prev.copy()

    def lam2_of(sm, rows):
        lam2 = mu[rows] * err[rows] ** 2
        if damped:
            nh = k_nh * np.clip(1.0 - (sm / SIGMA_WELL) ** 2, 0.0, None)
            lam2 = lam2 + (c0 + nh) * err[rows] ** 2
        return lam2

    fast = np.zeros(k, dtype=bool)
    if m == n:
        negligible = lam2_of(smin_prev, np.arange(k)) <= (GAUSS_REL * smin_prev) ** 2
        fast = (smin_prev >= 2 * SIGMA_WELL) & negligible
        if np.any(fast):
            try:
                dq[fast] = np.linalg.solve(A[fast], r[fast][:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:  # an exactly singular matrix: use the SVD
                fast[:] = False
    slow = np.flatnonzero(~fast)
    if slow.size:
        As, rs = A[slow], r[slow]
        U, s, Vt = np.linalg.svd(As, full_matrices=False)
        sm = s[:, -1]
        smin[slow] = sm
        keep = kept(s, _RCOND)
        lam2 = lam2_of(sm, slow)
        d = damped_step(U, s, Vt, rs, lam2, keep)
        if m == n:
            gauss = (lam2 <= (GAUSS_REL * sm) ** 2) & (sm >= SIGMA_WELL)
            if np.any(gauss):
                try:
                    d[gauss] = np.linalg.solve(As[gauss], rs[gauss][:, :, None])[:, :, 0]
                except np.linalg.LinAlgError:  # pragma: no cover - excluded by sm check
                    pass
        if mid is not None and m < n:
            ok = np.isfinite(mid)
            # scaled by min(1, |dx|): the pull fades out as the error vanishes, so its
            # second-order effect on the pose (~ |dx|^2) keeps the convergence quadratic
            gain = null_gain * np.minimum(1.0, err[slow])[:, None]
            z = np.where(ok, gain * (np.where(ok, mid, 0.0) - q[slow]), 0.0)
            Vk = Vt * keep[:, :, None]
            d = d + z - np.einsum("kri,kr->ki", Vk, np.einsum("kri,ki->kr", Vk, z))
        dq[slow] = d
    if step_limit is not None:
        big = np.max(np.abs(dq), axis=1)
        dq = dq * np.where(big > step_limit, step_limit / np.where(big > 0, big, 1.0), 1.0)[:, None]
    return dq, smin


class _SingleBuffers(threading.local):
    """Per-thread cffi buffers of single_solver (cffi releases the GIL during calls)."""

    def __init__(self, ffi, n):
        self.T = ffi.new("double[16]")
        self.q0 = ffi.new(f"double[{n}]")
        self.q = ffi.new(f"double[{n}]")
        self.ep, self.er = ffi.new("double[1]"), ffi.new("double[1]")
        self.it = ffi.new("int32_t[1]")
        self.status = ffi.new("int8_t[1]")
        self.q_np = np.frombuffer(ffi.buffer(self.q), dtype=np.float64)
        # everything in one tuple: a call reads the thread-local once (~600 instructions
        # per attribute read)
        self.b = (self.T, self.q0, self.q, self.ep, self.er, self.it, self.status, self.q_np)


def single_solver(arm):
    """Fast path of :func:`solve` for one target with default options but ``restarts`` and
    ``seed`` on the compiled backend: ``call(T, q0, restarts, seed)`` with T a (4, 4) and q0
    an (n,) C-contiguous float64 array returns q if the C routine converged (the same call
    as solve()'s: every attempt in C), else None (the caller then runs the general path).
    ``call.lean``: the extension's callable (native/lean_ext.c newton_kernel) of the
    default options, ``lean(T, q0)``, or None where the extension does not build (the
    planner's one-call numeric path, solve/ik.py IKPlanner.lean_numeric, is made from it)."""
    core = arm._core
    ffi, n, memmove = core._ffi, arm.n, core._ffi.memmove
    # solve()'s defaults, read from DEFAULTS and checked as solve() checks them
    d = check_options(arm)
    (tol_p, tol_r), (k_nh, c0, _) = d["tol"], d["damping"]
    max_iter, step_limit, respect = int(d["max_iter"]), d["step_limit"], bool(d["respect_limits"])
    mask = default_mask(arm, d["jacobian"])
    options = _c_options(core, tol_p, tol_r, max_iter, k_nh, c0, step_limit, respect, mask)
    default_restarts, default_seed = d["restarts"], d["seed"]
    made: dict = {}  # (restarts, seed) -> (options struct, the extension's call or None)
    qlim = ffi.new("double[]", [float(x) for x in np.asarray(arm.qlim).reshape(-1)])
    scratch = _SingleBuffers(ffi, n)
    fn, OK, nbytes = core._ik_newton, st.OK, 8 * n

    from deltagen.native.lean import extension

    ext = extension()

    def made_for(restarts, seed):
        """(options struct, the extension's call on it or None) of (restarts, seed)."""
        opts = options(STALL_WINDOW, restarts, _seed_offset(seed))
        fast = None
        if ext is not None:  # T and q0 read in place, one C call (native/lean_ext.c)
            fast = ext.newton_kernel(
                int(ffi.cast("uintptr_t", fn)),
                n,
                int(ffi.cast("uintptr_t", opts)),
                int(ffi.cast("uintptr_t", qlim)),
                OK,
                (ffi, fn, opts, qlim),
            )
        return opts, fast

    default = made_for(default_restarts, default_seed)[1]  # without the lookups below

    def call(T, q0, restarts=default_restarts, seed=default_seed):
        if (
            default is not None
            and restarts is default_restarts
            and type(seed) is int
            and seed == default_seed
        ):
            return default(T, q0)
        if not _is_count(seed):  # a Generator is consumed by its draw: the general path
            return None
        key = (restarts, seed)
        entry = made.get(key)
        if entry is None:
            if len(made) > 64:
                made.clear()
            entry = made[key] = made_for(restarts, seed)
        opts, fast = entry
        if fast is not None:
            return fast(T, q0)
        Tb, q0b, qb, ep, er, it, status, q_np = scratch.b
        memmove(Tb, T, 128)
        memmove(q0b, q0, nbytes)
        fn(1, opts, Tb, q0b, qlim, qb, ep, er, it, status)
        return q_np.copy() if status[0] == OK else None

    call.lean = default  # the extension's call with the default options, or None
    return call


def _c_options(core, tol_p, tol_r, max_iter, k_nh, c0, step_limit, respect, mask):
    """options(stall_window, restarts=0, seed=0): the deltagen_ik_options struct of these
    settings."""

    def options(window, restarts=0, seed=0):
        return core.ik_options(
            tol_p=tol_p,
            tol_r=tol_r,
            step_limit=np.inf if step_limit is None else step_limit,
            damping=k_nh,
            base_damping=c0,
            max_iter=max_iter,
            stall_window=window,
            respect_limits=respect,
            free_first=respect and FREE_FIRST,
            mask=mask,
            restarts=restarts,
            seed=seed,
        )

    return options


def _iterate_c(
    arm, Tt, q0, mask, tol_p, tol_r, max_iter, k_nh, c0, step_limit, respect, restarts, seed
):
    """The compiled engine: one C call (deltagen_<arm>_ik_newton) runs every attempt of
    every row -- the attempt from q0 and the restarts from its deterministic sequence spread
    over the joint box (codegen/runtime/deltagen_ik_newton.c), with the numpy engine's
    stall windows."""
    core = arm._core
    qlim = np.ascontiguousarray(arm.qlim, dtype=float)
    options = _c_options(core, tol_p, tol_r, max_iter, k_nh, c0, step_limit, respect, mask)
    opts = options(STALL_WINDOW, restarts, _seed_offset(seed))
    q, ep, er, it, status = core.ik_newton(opts, Tt, np.ascontiguousarray(q0), qlim)
    return q, status == st.OK, it.astype(np.int64), ep, er


def _seed_offset(seed) -> int:
    """The C engine's restart-sequence offset (uint32) for solve()'s ``seed``: an integer
    as it is (mod 2^32); a Generator or SeedSequence gives one draw, None a fresh one."""
    if _is_count(seed):
        return int(seed) % 2**32
    return int(np.random.default_rng(seed).integers(2**32))


class _Rows:
    """The per-row state of the numpy engine's iteration (:func:`_iterate`): every row
    carries its own q, error, Levenberg-Marquardt parameter, non-monotone reference,
    attempt counters, phase and best in-limit q so far (module docstring)."""

    def __init__(self, arm, Tt, q, mask, limits, respect):
        N = q.shape[0]
        self.arm, self.Tt, self.mask = arm, Tt, mask
        self.limits, self.respect = limits, respect
        self.free = np.full(N, respect and FREE_FIRST)  # phase 1: limits only checked at the end
        self.q = q = np.where(self.free[:, None], limits.wrap_only(q), limits.apply(q))
        self.e, self.ep, self.er = self.errors(q, np.arange(N))
        self.err = np.hypot(self.ep, self.er)
        self.mu = np.zeros(N)
        self.it = np.zeros(N, dtype=np.int64)  # steps over all attempts
        self.it_att = np.zeros(N, dtype=np.int64)  # steps in the current attempt
        self.attempts = np.zeros(N, dtype=np.int64)
        self.chk = self.err.copy()  # |dx| at the last stall checkpoint
        self.cref = self.err.copy()  # non-monotone reference (Zhang-Hager)
        self.qz = np.ones(N)
        self.sig = np.zeros(N)  # sigma_min at the last SVD (0: unknown)
        self.stuck = np.zeros(N, dtype=bool)
        self.conv = np.zeros(N, dtype=bool)
        self.active = np.ones(N, dtype=bool)
        # the best in-limit q seen (start: q0 clamped into the limits)
        self.best_q = limits.apply(q)
        _, self.best_ep, self.best_er = self.errors(self.best_q, np.arange(N))
        self.best_err = np.hypot(self.best_ep, self.best_er)
        self.q_start = q.copy()  # start of the current attempt

    def errors(self, qa, rows):
        """Pose error (k, 6) at the joints qa of ``rows`` and its position and rotation
        norms (k,)."""
        Tc, _ = self.arm._core.fk(np.ascontiguousarray(qa))
        e = pose_error(Tc, self.Tt[rows], self.mask)
        return e, np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1)

    def inside(self, qa):
        limits = self.limits
        return (
            np.all((qa >= limits.lo) & (qa <= limits.hi), axis=1)
            if self.respect
            else np.ones(qa.shape[0], dtype=bool)
        )

    def set_state(self, rows, qr):
        """``rows`` start afresh at qr: error recomputed, LM parameter, stall checkpoint,
        non-monotone reference and sigma_min reset."""
        self.q[rows] = qr
        self.e[rows], self.ep[rows], self.er[rows] = self.errors(qr, rows)
        self.err[rows] = np.hypot(self.ep[rows], self.er[rows])
        self.mu[rows] = 0.0
        self.chk[rows] = self.err[rows]
        self.cref[rows] = self.err[rows]
        self.qz[rows] = 1.0
        self.sig[rows] = 0.0
        self.stuck[rows] = False

    def record_best(self, rows):
        """Keep the q of ``rows`` as their best where it is within the limits and better."""
        err, q = self.err, self.q
        rows = rows[(err[rows] < self.best_err[rows]) & self.inside(q[rows])]
        self.best_q[rows], self.best_err[rows] = q[rows], err[rows]
        self.best_ep[rows], self.best_er[rows] = self.ep[rows], self.er[rows]


def _converge(s: _Rows, a, tol_p, tol_r):
    """Rows of ``a`` within tol and the limits are done (converged); a free-phase row near
    a solution outside the limits continues from its attempt's start, clamped, with the
    limits enforced. Returns the rows of ``a`` that go on."""
    ep, er, free, limits = s.ep, s.er, s.free, s.limits
    met = (ep[a] <= tol_p) & (er[a] <= tol_r)
    within = s.inside(s.q[a])
    ok = met & within
    s.conv[a[ok]] = True
    s.active[a[ok]] = False
    # a free-phase row near a solution outside the limits (checked at max(tol, 1e-9),
    # so that a tol at or below rounding level cannot keep it there)
    near = (ep[a] <= max(tol_p, FREE_CHECK)) & (er[a] <= max(tol_r, FREE_CHECK))
    out = a[near & ~within & free[a]]
    if out.size:
        free[out] = False
        s.set_state(out, limits.apply(s.q_start[out] if PHASE2_FROM_START else s.q[out]))
    a = a[~ok]
    return a[~np.isin(a, out)] if out.size else a


def _end_attempts(s: _Rows, a, max_iter, restarts, box_lo, box_hi, rng):
    """Rows of ``a`` whose attempt is over (step cap or stuck) restart from a random
    in-limit q while restarts are left, else stop. Returns the rows of ``a`` that step."""
    over = (s.it_att[a] >= max_iter) | s.stuck[a]
    if np.any(over):
        attempts = s.attempts
        ended = a[over]
        again = ended[attempts[ended] < restarts]
        s.active[ended[attempts[ended] >= restarts]] = False
        if again.size:
            attempts[again] += 1
            s.it_att[again] = 0
            s.free[again] = s.respect and FREE_FIRST
            n = s.q.shape[1]
            s.set_state(again, box_lo + (box_hi - box_lo) * rng.random((again.size, n)))
            s.q_start[again] = s.q[again]
            s.record_best(again)
        a = a[~over]
    return a


def _damped_step(s: _Rows, a, source, mrows, lm, c0, k_nh, mid, null_gain, step_limit):
    """One damped Newton step on the rows ``a``, with the active-set pass for joints the
    step pushes through a limit; returns the new q of those rows (wrapped, or clamped
    outside the free phase)."""
    limits, err, mu = s.limits, s.err, s.mu
    qa = np.ascontiguousarray(s.q[a])
    A = jacobian(s.arm, qa, source)[:, mrows, :]  # (k, m, n)
    r = s.e[a][:, mrows]  # (k, m)
    fa = s.free[a]
    step = (err[a], mu[a], lm, c0, k_nh)
    dq, s.sig[a] = _newton_step(A, r, *step, qa, mid, null_gain, step_limit, s.sig[a])
    target = qa + dq
    if s.respect and ACTIVE_SET:
        # joints the step would push beyond a limit (no 2 pi shift helps) are set onto
        # the limit and the others solve for the rest of dx (one active-set pass)
        viol = (limits.apply(target) != limits.wrap_only(target)) & ~fa[:, None]
        fix = np.flatnonzero(np.any(viol, axis=1))
        if fix.size:
            Af, vf = A[fix], viol[fix]
            moved = np.where(vf, limits.apply(target[fix]) - qa[fix], 0.0)
            rf = r[fix] - np.einsum("kmi,ki->km", Af, moved)
            Af = np.where(vf[:, None, :], 0.0, Af)
            dq2, _ = _newton_step(
                Af,
                rf,
                err[a][fix],
                mu[a][fix],
                *step[2:],
                qa[fix],
                mid,
                null_gain,
                step_limit,
                np.zeros(fix.size),
            )
            target[fix] = qa[fix] + np.where(vf, moved, dq2)
    return np.where(fa[:, None], limits.wrap_only(target), limits.apply(target))


def _accept(s: _Rows, a, q_new, lm):
    """Count the step of the rows ``a`` and take it where the non-monotone rule (Zhang-Hager,
    with damping) accepts it; lower the LM parameter of the accepted rows, raise that of
    the rejected ones."""
    q, e, ep, er, err, mu, qz, cref = s.q, s.e, s.ep, s.er, s.err, s.mu, s.qz, s.cref
    e_new, ep_new, er_new = s.errors(q_new, a)
    err_new = np.hypot(ep_new, er_new)
    s.it[a] += 1
    s.it_att[a] += 1
    good = np.isfinite(err_new)
    accept = good & (err_new < cref[a]) if lm else good
    acc, rej = a[accept], a[~accept]
    qz_new = ETA * qz[acc] + 1.0
    cref[acc] = (ETA * qz[acc] * cref[acc] + err_new[accept]) / qz_new
    qz[acc] = qz_new
    q[acc], e[acc], ep[acc] = q_new[accept], e_new[accept], ep_new[accept]
    er[acc], err[acc] = er_new[accept], err_new[accept]
    mu[acc] = np.where(mu[acc] / 10.0 < MU_START, 0.0, mu[acc] / 10.0)
    mu[rej] = np.maximum(mu[rej] * 10.0, MU_START)
    s.record_best(acc)


def _check_stall(s: _Rows, a, restarts):
    """Mark rows of ``a`` stuck: the LM parameter ran away (no step is accepted any more),
    or, with a restart left, |dx| did not halve over the last STALL_WINDOW steps (three
    times that in the attempt from the caller's q0)."""
    err, chk, attempts, it_att, stuck = s.err, s.chk, s.attempts, s.it_att, s.stuck
    stuck[a] = s.mu[a] > MU_MAX
    span = np.where(attempts[a] == 0, FIRST_WINDOW_FACTOR * STALL_WINDOW, STALL_WINDOW)
    window = a[it_att[a] % span == 0]
    slow = err[window] > 0.5 * chk[window]
    stuck[window[slow & (attempts[window] < restarts)]] = True
    chk[window] = err[window]


def _iterate(
    arm,
    Tt,
    q,
    mask,
    tol_p,
    tol_r,
    max_iter,
    source,
    k_nh,
    c0,
    lm,
    step_limit,
    respect,
    restarts,
    seed,
    null_gain,
):
    """The batched iteration; every row carries its own state (see the module docstring):
    per pass, the rows still active are checked for convergence (:func:`_converge`), for
    the end of their attempt (:func:`_end_attempts`: restart or stop), take one damped
    step (:func:`_damped_step`), accept it or not (:func:`_accept`) and are checked for a
    stall (:func:`_check_stall`)."""
    N, n = q.shape
    limits = _Limits(arm, respect)
    rng = np.random.default_rng(seed)
    box_lo, box_hi = _sample_box(arm)
    if respect:
        box_lo, box_hi = np.maximum(box_lo, limits.lo), np.minimum(box_hi, limits.hi)
    mid = limits.mid if null_gain > 0 else None
    mrows = np.flatnonzero(mask)
    s = _Rows(arm, Tt, q, mask, limits, respect)

    for _ in range((restarts + 1) * (2 * max_iter + 3) + 2):
        a = np.flatnonzero(s.active)
        if a.size == 0:
            break
        a = _converge(s, a, tol_p, tol_r)
        a = _end_attempts(s, a, max_iter, restarts, box_lo, box_hi, rng)
        if a.size == 0:
            continue
        q_new = _damped_step(s, a, source, mrows, lm, c0, k_nh, mid, null_gain, step_limit)
        _accept(s, a, q_new, lm)
        _check_stall(s, a, restarts)

    conv = s.conv
    q_res = np.where(conv[:, None], s.q, s.best_q)
    return q_res, conv, s.it, np.where(conv, s.ep, s.best_ep), np.where(conv, s.er, s.best_er)


def polisher(arm, tol=1e-10, max_iter=30):
    """A lean form of ``solve(arm, T, q0, tol=tol, max_iter=max_iter, restarts=0,
    respect_limits=False)`` on the compiled engine, its options checked and packed once:
    ``call(T (k, 4, 4), q0 (k, n))`` -> (q (k, n), converged (k,)) for finite rows, the
    same C call with the same options as solve()'s (the same bits), without its per-call
    checks (the general 6R solver's Newton polish of its candidates calls it once per
    batch). None where the compiled engine does not apply."""
    opts = check_options(
        arm, min_iter=0, tol=tol, max_iter=max_iter, respect_limits=False, restarts=0
    )
    if not opts["c_ok"]:
        return None
    tol_p, tol_r = opts["tol"]
    k_nh, c0, _ = opts["damping"]
    core = arm._core
    mask = default_mask(arm, "symbolic")
    packed = _c_options(
        core, tol_p, tol_r, int(max_iter), k_nh, c0, opts["step_limit"], False, mask
    )(STALL_WINDOW, 0, _seed_offset(0))
    qlim = np.ascontiguousarray(arm.qlim, dtype=float)

    def call(T, q0):
        q, ep, er, _, status = core.ik_newton(
            packed, np.ascontiguousarray(T), np.ascontiguousarray(q0, dtype=float), qlim
        )
        ok = (status == st.OK) & np.all(np.isfinite(q), axis=1)
        return q, ok & np.isfinite(ep) & np.isfinite(er)

    # the same kernel and options for a C caller (the general 6R solver's one-call path,
    # native/general6r.py): (function address, options address, qlim, keep-alive)
    ffi = core._ffi
    call.kernel = (
        int(ffi.cast("uintptr_t", core._ik_newton)),
        int(ffi.cast("uintptr_t", packed)),
        qlim,
        packed,
    )
    return call
