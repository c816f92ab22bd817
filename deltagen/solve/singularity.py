"""Singularity report of serial arms (lecture slides 112-114: which joint axes line up).

``report(arm, q, tol=1e-6)`` takes a :class:`SerialRobot` or a :class:`SerialDescription` and
joint vectors q (..., n) and returns a dict of arrays of shape (...,):

``sigma_min``, ``manipulability``, ``condition``
    From the singular values of the *task Jacobian* J_t (pure-numpy reference kinematics,
    :mod:`deltagen.reference.serial`, base frame): ``condition = sigma_max / sigma_min``
    (inf where sigma_min is exactly 0), ``manipulability`` = product of the singular values
    (Yoshikawa). For n >= 6 joints J_t is the full 6 x n geometric Jacobian. For n < 6 it is
    the 3 x n tool-point (position) block when that block alone has generic rank n (e.g. the
    planar 2R SCARA: its 6 x 2 Jacobian never loses rank, since the two joints always turn
    the tool differently, but its position does at the stretched arm), and the full 6 x n
    Jacobian otherwise (3R planar arms, 4-axis SCARAs, the 4R elbow arm). Only the first r
    singular values are used, r = the generic rank of J_t (taken at a few fixed pseudo-random
    configurations), so an arm whose J_t can never have full rank is not reported as
    singular everywhere.
``singular``
    ``sigma_r / sigma_max < tol``.
``aligned_axes`` (object array of lists)
    Pairs (i, j), 1-based joint numbers i < j, of revolute joints whose axes are collinear
    (the same line): ``|w_i x w_j| < tol`` and the distance of axis j's point from axis i
    below ``tol * size``. Computed per configuration, for every arm.
``structure`` (str, same for all rows)
    ``"spherical_wrist_6r"`` or ``"general"``.

For ``spherical_wrist_6r`` arms -- 6 revolute joints, axes 4, 5, 6 through one point W
(the wrist centre), axis 1 not parallel to axis 2, axes 2 and 3 parallel: the Puma 560,
the Motoman UP6, the Manutec r15 -- the structure is read from the joint axes by
:func:`deltagen.model.structure.detect`, the detection the closed-form solver uses (no robot
names), and the Jacobian's determinant factors into the wrist part and the 3 x 3 position
Jacobian of W, whose columns are ``w_i x (W - o_i)``, i = 1..3 (W per configuration:
:func:`deltagen.geometry.axes.common_points`). Three named flags (each 1 where the factor vanishes) follow:

``wrist``
    axes 4 and 6 collinear: ``|w4 x w6| < tol`` (both pass through W, so parallel means the
    same line; the Puma at q5 = 0).
``shoulder``
    W in the plane through axis 1 spanned by the directions of axes 1 and 2: then the first
    column ``w1 x (W - o1)`` is normal to w2 like the other two. Without a shoulder offset
    that plane condition is "W on axis 1" (slide 112); with an offset (the Puma's d3) W can
    never reach axis 1, and this is where the singularity really is (W at the offset distance
    from axis 1, straight "above" it). Test: distance of W from the plane < ``tol * size``.
    ``shoulder_distance`` gives that distance.
``elbow``
    W in the plane of the parallel axes 2 and 3 (stretched or folded forearm): the columns 2
    and 3 of the W position Jacobian are then parallel. Test: distance of W from that plane
    < ``tol * size``; ``elbow_distance`` gives it.

For other arms these flags are False and the distances NaN; ``singular`` and
``aligned_axes`` still apply. ``size`` is the arm's length scale: the summed lengths of the
links (joint frame to joint frame, and to the tool) at q = 0.

Rows with non-finite q, or whose Jacobian is not finite (finite q so large that the
arithmetic overflows: the reference kinematics call them INVALID), give NaN numbers, False
flags and empty ``aligned_axes`` (``SerialRobot.singularities`` raises for them).

``describe(row)`` turns the report of one configuration (``report(arm, q)`` with q of shape
(n,), or ``row_of(rep, index)``) into one line of text for messages.
"""

from __future__ import annotations

import numpy as np

from deltagen.geometry.axes import common_points, unit
from deltagen.inputs import InputError, as_float_array, check_real
from deltagen.model.serial import SerialDescription
from deltagen.model.structure import SphericalWrist6R, detect
from deltagen.reference import serial as reference
from deltagen.status import OK

__all__ = ["report", "describe", "row_of", "structure_of"]


def _description(arm) -> SerialDescription:
    if isinstance(arm, SerialDescription):
        return arm
    desc = getattr(arm, "description", None)
    if isinstance(desc, SerialDescription):
        return desc
    raise InputError(f"arm must be a SerialRobot or a SerialDescription, got {type(arm).__name__}")


def _size(desc) -> float:
    F, _ = reference.frames(desc, np.zeros((1, desc.n)))
    p = F[0, :, :3, 3]
    return float(max(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)), 1e-12))


def _sample_q(desc, count=6):
    rng = np.random.default_rng(12345)
    return rng.uniform(-2.0, 2.0, size=(count, desc.n))


class _Structure:
    def __init__(self, desc):
        self.desc = desc
        self.n = desc.n
        self.size = _size(desc)
        self.revolute = np.array([j.revolute for j in desc.joints], dtype=bool)
        qs = _sample_q(desc)
        J, _ = reference.jacobian(desc, qs)
        # task Jacobian rows (see the module docstring)
        if self.n < 6 and all(
            np.linalg.matrix_rank(Ji[:3], tol=1e-9 * max(self.size, 1.0)) == self.n for Ji in J
        ):
            self.rows = slice(0, 3)
            self.task = "position"
        else:
            self.rows = slice(0, 6)
            self.task = "full"
        Jt = J[:, self.rows]
        self.rank = int(max(np.linalg.matrix_rank(Ji, tol=1e-9 * max(self.size, 1.0)) for Ji in Jt))
        # the closed-form solver's detection (model.structure): one reading of the axes
        wrist_6r = isinstance(detect(desc), SphericalWrist6R)
        self.kind = "spherical_wrist_6r" if wrist_6r else "general"


_CACHE: dict = {}


def structure_of(arm) -> _Structure:
    desc = _description(arm)
    key = id(desc)
    hit = _CACHE.get(key)
    if hit is None or hit.desc is not desc:
        hit = _Structure(desc)
        _CACHE[key] = hit
    return hit


def report(arm, q, tol: float = 1e-6) -> dict:
    """Singularity report of ``arm`` at q (..., n); see the module docstring."""
    desc = _description(arm)
    s = structure_of(desc)
    q = as_float_array(q, "q", f"(..., {desc.n})")
    if q.ndim == 0 or q.shape[-1] != desc.n:
        raise InputError(f"q must have shape (..., {desc.n}) for {desc.name}, got {q.shape}")
    tol = check_real(tol, "tol", low=0.0, low_open=True)
    lead = q.shape[:-1]
    qf = np.ascontiguousarray(q.reshape(-1, desc.n))
    N = qf.shape[0]
    good = np.all(np.isfinite(qf), axis=1)
    qc = np.where(good[:, None], qf, 0.0)

    J, status = reference.jacobian(desc, qc)
    good &= status == OK  # the finite-output rule: an overflowing row has no report
    qc[~good] = 0.0
    Jt = np.where(good[:, None, None], J[:, s.rows], 0.0)
    sv = np.linalg.svd(Jt, compute_uv=False)[:, : s.rank]
    smax, smin = sv[:, 0], sv[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = smax / smin
        ratio = smin / smax
    manip = np.prod(sv, axis=1)
    singular = ~(ratio >= tol)  # also a zero Jacobian (0 / 0)

    o, w = reference.joint_axes(desc, qc)
    size = s.size
    # collinear revolute axis pairs
    aligned = np.empty(N, dtype=object)
    pairs = [
        (i, j)
        for i in range(desc.n)
        for j in range(i + 1, desc.n)
        if s.revolute[i] and s.revolute[j]
    ]
    col = {}
    for i, j in pairs:
        par = np.linalg.norm(np.cross(w[:, i], w[:, j]), axis=1) < tol
        d = o[:, j] - o[:, i]
        off = d - np.sum(d * w[:, i], axis=1)[:, None] * w[:, i]
        col[(i, j)] = par & (np.linalg.norm(off, axis=1) < tol * size)
    for r in range(N):
        aligned[r] = [(i + 1, j + 1) for (i, j) in pairs if good[r] and col[(i, j)][r]]

    wrist = np.zeros(N, dtype=bool)
    shoulder = np.zeros(N, dtype=bool)
    elbow = np.zeros(N, dtype=bool)
    d_sh = np.full(N, np.nan)
    d_el = np.full(N, np.nan)
    if s.kind == "spherical_wrist_6r":
        W = common_points(o[:, 3:6], w[:, 3:6])
        wrist = np.linalg.norm(np.cross(w[:, 3], w[:, 5]), axis=1) < tol
        with np.errstate(invalid="ignore", divide="ignore"):  # NaN for aligned axes
            n_sh = unit(np.cross(w[:, 0], w[:, 1]))
        d_sh = np.abs(np.sum((W - o[:, 0]) * n_sh, axis=1))
        d23 = o[:, 2] - o[:, 1]
        d23 = d23 - np.sum(d23 * w[:, 1], axis=1)[:, None] * w[:, 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            n_el = unit(np.cross(w[:, 1], d23))
        d_el = np.abs(np.sum((W - o[:, 1]) * n_el, axis=1))
        shoulder = d_sh < tol * size
        elbow = d_el < tol * size

    out = {
        "condition": condition,
        "manipulability": manip,
        "sigma_min": smin,
        "sigma_max": smax,
        "singular": singular,
        "wrist": wrist,
        "shoulder": shoulder,
        "elbow": elbow,
        "shoulder_distance": d_sh,
        "elbow_distance": d_el,
    }
    for k, v in out.items():
        v = np.array(v, dtype=float if v.dtype != bool else bool)
        if v.dtype == bool:
            v[~good] = False
        else:
            v[~good] = np.nan
        out[k] = v.reshape(lead)
    out["aligned_axes"] = aligned.reshape(lead) if lead else aligned[0]
    if not lead:
        out = {k: (v[()] if isinstance(v, np.ndarray) else v) for k, v in out.items()}
    out["structure"] = s.kind
    out["task"] = s.task
    out["tol"] = float(tol)
    return out


def singular_values(J, valid):
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


def row_of(rep: dict, index) -> dict:
    """The report of one configuration out of a batched report."""
    return {k: (v[index] if isinstance(v, np.ndarray) else v) for k, v in rep.items()}


def describe(row: dict) -> str:
    """One line of text for the report of a single configuration."""
    vals = {}
    for k, v in row.items():
        if isinstance(v, np.ndarray) and v.dtype != object:
            if v.size != 1:
                raise InputError(
                    "describe() needs the report of one configuration (use row_of(report, index))"
                )
            v = v.reshape(())[()]
        vals[k] = v
    cond = vals.get("condition", np.nan)
    cond_txt = (
        f"condition number {float(cond):.3g}"
        if np.isfinite(cond)
        else ("condition number inf" if cond == np.inf else "condition number nan")
    )
    if not np.isfinite(vals.get("sigma_min", np.nan)):
        return "no singularity report: non-finite joint values"
    parts = []
    aligned = list(vals.get("aligned_axes", []) or [])
    if vals.get("wrist"):
        parts.append("wrist singularity: axes 4 and 6 aligned")
    if vals.get("shoulder"):
        parts.append(
            "shoulder singularity: wrist centre over axis 1 "
            f"(distance from the axis-1 plane {float(vals['shoulder_distance']):.2g})"
        )
    if vals.get("elbow"):
        parts.append(
            "elbow singularity: forearm stretched or folded "
            "(wrist centre in the plane of axes 2 and 3)"
        )
    others = [p for p in aligned if not (vals.get("wrist") and tuple(p) == (4, 6))]
    if others:
        parts.append("collinear axes " + ", ".join(f"{i} and {j}" for i, j in others))
    if vals.get("singular") and not parts:
        parts.append("singular configuration (Jacobian loses rank)")
    if not parts:
        return f"not singular; {cond_txt}"
    return "; ".join(parts) + f"; {cond_txt}"
