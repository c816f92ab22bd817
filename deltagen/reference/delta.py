"""Independent pure-numpy reference kinematics of the rotary delta robot.

This module deliberately shares nothing with the SymPy derivation or the generated C
core: it works from the vector geometry of the delta report (eq. (1)-(5), (43))
and numpy linear algebra, vectorised over a batch of N points.

Geometry. Chain i (drive angle ``theta_i``, crank angle ``q_i``) confines the platform
centre p to the sphere of radius ``l_b`` about::

    S_i(q_i) = ((r + l_a cos q_i) cos theta_i, (r + l_a cos q_i) sin theta_i, -l_a sin q_i)

with ``r = r_a - r_b``; z points up and the platform works at negative z.

* Direct kinematics: trilateration of the three spheres. With ``a = S_2 - S_1``,
  ``b = S_3 - S_1``, ``e = a x b`` and ``u = p - S_1`` the two plane equations
  ``u.a = |a|^2/2``, ``u.b = |b|^2/2`` give the foot point
  ``u_0 = (|a|^2 (b x e) + |b|^2 (e x a)) / (2 |e|^2)`` on the line of the two
  planes; ``p = S_1 + u_0 + t e/|e|`` with ``t^2 = l_b^2 - |u_0|^2`` and the sign of t
  chosen for the lower (min z) intersection.
* Velocity: d/dt |p - S_i|^2 = 0 gives ``D pd = diag(j) qd`` with rows
  ``D_i = p - S_i`` and ``j_i = (p - S_i) . dS_i/dq_i`` (the report's J_p / 2 and
  J_q / 2).
* Acceleration: d^2/dt^2 gives
  ``D pdd = [(p - S_i) . Sdd_i - |pd - Sd_i|^2]_i`` with ``Sd_i = S_i' qd_i`` and
  ``Sdd_i = S_i'' qd_i^2 + S_i' qdd_i``.
* Inverse kinematics (elbow-out branch, crank pointing away from the axis): in the
  chain frame ``x_i = cos th x + sin th y`` the constraint reads
  ``E cos q + F sin q + G = 0`` with ``E = 2 l_a (r - x_i)``, ``F = 2 l_a z``,
  ``G = r^2 + l_a^2 - 2 r x_i + |p|^2 - l_b^2`` and
  ``q = atan2(F, E) + atan2(sqrt(E^2 + F^2 - G^2), -G)``. On this branch
  ``E sin q - F cos q = 2 j_i >= 0``, i.e. ``j_i`` vanishes exactly where the two
  branches meet (rod and crank aligned).
* A fourth input column (report eq. (43)) passes through unchanged.

Status rules (per point, int8; see :mod:`deltagen.status`):

* INVALID if any input value of the row is NaN or infinite; all outputs of the row NaN.
* fk level (:func:`fk`, :func:`fk_vel`, :func:`fk_acc`, :func:`jacobian`):
  SINGULAR if the sphere centres are (near) collinear, ``|e| / l_b^2 < tol``
  (outputs NaN; the spheres' intersection cannot be trilaterated, so this is decided
  before reachability); else UNREACHABLE if the spheres do not meet,
  ``l_b^2 - |u_0|^2 < 0`` (outputs NaN); else SINGULAR if
  ``|det D| / l_b^3 < tol`` (p is returned, pd / pdd / J are NaN); else OK.
* ik: UNREACHABLE if for any chain ``E^2 + F^2 - G^2 < 0`` (row NaN); else SINGULAR if
  for any chain ``|j_i| / (l_a l_b) < tol`` (q is returned); else OK.
* Finite outputs (:mod:`deltagen.status`, the rule the generated C applies too): INVALID
  where an output the status gives is not finite (finite but huge inputs overflow, e.g. a
  target 1e155 m away); all outputs of the row NaN.

``tol`` is ``geom.singular_tol``. An exactly zero ``|e|``, ``det D`` or ``j_i`` counts
as singular even when ``tol == 0``. Whole rows are NaN'd, including a fourth column.
"""

from __future__ import annotations

import numpy as np

from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

__all__ = ["fk", "fk_vel", "fk_acc", "jacobian", "ik"]


# --------------------------------------------------------------------------- helpers


def _as_batch(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _invalid_rows(*arrays) -> np.ndarray:
    """Rows holding any non-finite value in any of the (N, k) input arrays."""
    bad = np.zeros(arrays[0].shape[0], dtype=bool)
    for a in arrays:
        bad |= ~np.all(np.isfinite(a), axis=1)
    return bad


def _sanitised(a: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """The first three columns of ``a`` with invalid rows replaced by zeros."""
    out = np.array(a[:, :3], dtype=np.float64, copy=True)
    out[bad] = 0.0
    return out


def _trig(geom):
    th = np.asarray(geom.theta, dtype=np.float64)
    return np.cos(th), np.sin(th)


def _centres(geom, q3: np.ndarray):
    """S_i, dS_i/dq_i and d^2S_i/dq_i^2 as (N, 3 chains, 3 coords) arrays."""
    c, s = _trig(geom)
    cq, sq = np.cos(q3), np.sin(q3)
    rho = geom.r + geom.l_a * cq
    S = np.stack((rho * c, rho * s, -geom.l_a * sq), axis=-1)
    dS = np.stack((-geom.l_a * sq * c, -geom.l_a * sq * s, -geom.l_a * cq), axis=-1)
    d2S = np.stack((-geom.l_a * cq * c, -geom.l_a * cq * s, geom.l_a * sq), axis=-1)
    return S, dS, d2S


def _det3(D: np.ndarray) -> np.ndarray:
    """Determinant of a stack of 3x3 matrices as the triple product of the rows."""
    return np.einsum("ni,ni->n", D[:, 0], np.cross(D[:, 1], D[:, 2]))


def _solve(D: np.ndarray, rhs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Solve D x = rhs for the rows in ``mask``; other rows are NaN.

    ``rhs`` is (N, 3) (vector right-hand sides) or (N, 3, k) (matrix right-hand sides).
    Masked-out matrices are replaced by the identity so that LAPACK never sees them.
    """
    vector = rhs.ndim == 2
    A = np.where(mask[:, None, None], D, np.eye(3))
    B = rhs[..., None] if vector else rhs
    B = np.where(mask.reshape((-1,) + (1,) * (B.ndim - 1)), B, 0.0)
    try:
        x = np.linalg.solve(A, B)
    except np.linalg.LinAlgError:  # an exactly singular LU pivot with det != 0: adjugate
        adj_t = np.stack(
            (np.cross(A[:, 1], A[:, 2]), np.cross(A[:, 2], A[:, 0]), np.cross(A[:, 0], A[:, 1])),
            axis=-1,
        )
        x = adj_t @ B / _det3(A)[:, None, None]
    if vector:
        x = x[..., 0]
    x[~mask] = np.nan
    return x


def _with_fourth(out3: np.ndarray, src: np.ndarray, nan_rows: np.ndarray) -> np.ndarray:
    """Append the pass-through fourth column of ``src`` (if any) and NaN whole rows."""
    if src.shape[1] == 4:
        out = np.empty((out3.shape[0], 4), dtype=np.float64)
        out[:, :3] = out3
        out[:, 3] = src[:, 3]
    else:
        out = np.array(out3, dtype=np.float64, copy=True)
    out[nan_rows] = np.nan
    return np.ascontiguousarray(out)


def _fk_core(geom, q: np.ndarray, *others: np.ndarray):
    """Position level shared by every fk-level function.

    Returns sanitised q3, p3 (NaN where not found), S, dS, d2S, D (rows p - S_i),
    ``status`` and ``solvable`` (rows where D may be inverted: status OK).
    """
    n = q.shape[0]
    bad = _invalid_rows(q, *others)
    q3 = _sanitised(q, bad)
    S, dS, d2S = _centres(geom, q3)
    l_b = geom.l_b
    tol = geom.singular_tol

    a = S[:, 1] - S[:, 0]
    b = S[:, 2] - S[:, 0]
    e = np.cross(a, b)
    e2 = np.einsum("ni,ni->n", e, e)
    e_norm = np.sqrt(e2)
    collinear = (e_norm / l_b**2 < tol) | (e2 == 0.0)

    safe_e2 = np.where(collinear, 1.0, e2)
    aa = np.einsum("ni,ni->n", a, a)
    bb = np.einsum("ni,ni->n", b, b)
    u0 = (aa[:, None] * np.cross(b, e) + bb[:, None] * np.cross(e, a)) / (2.0 * safe_e2[:, None])
    h = l_b**2 - np.einsum("ni,ni->n", u0, u0)
    unreachable = ~collinear & (h < 0.0)

    e_hat = e / np.where(collinear, 1.0, e_norm)[:, None]
    # lower intersection: move against the upward component of the unit normal
    sign = np.where(e_hat[:, 2] < 0.0, 1.0, -1.0)
    t = sign * np.sqrt(np.maximum(h, 0.0))
    p3 = S[:, 0] + u0 + t[:, None] * e_hat

    D = p3[:, None, :] - S
    det = _det3(D)
    det_singular = (np.abs(det) / l_b**3 < tol) | (det == 0.0)

    status = np.full(n, OK, dtype=np.int8)
    status[det_singular] = SINGULAR
    status[unreachable] = UNREACHABLE
    status[collinear] = SINGULAR
    status[bad] = INVALID

    no_position = bad | collinear | unreachable
    p3[no_position] = np.nan
    solvable = status == OK
    return q3, p3, S, dS, d2S, D, status, no_position, solvable


def _finite_outputs(status, pairs):
    """The finite-output rule: rows where an output holds a non-finite value its status does
    not explain become INVALID, every output NaN. ``pairs``: (output (N, ...), rows whose
    NaN in that output the status explains)."""
    over = np.zeros(status.shape[0], dtype=bool)
    for out, explained in pairs:
        width = int(np.prod(out.shape[1:]))
        over |= ~explained & ~np.all(np.isfinite(out.reshape(status.shape[0], width)), axis=1)
    if over.any():
        status[over] = INVALID
        for out, _ in pairs:
            out[over] = np.nan
    return status


# ------------------------------------------------------------------------------ API


def fk(geom, q):
    """Direct kinematics: drive angles q (N,3|4) -> platform pose p (N,3|4), status (N,)."""
    q = _as_batch(q)
    with np.errstate(all="ignore"):
        _, p3, _, _, _, _, status, no_position, _ = _fk_core(geom, q)
        p = _with_fourth(p3, q, no_position)
    return p, _finite_outputs(status, [(p, no_position)])


def fk_vel(geom, q, qd):
    """Direct velocity kinematics: (q, qd) -> (p, pd, status)."""
    q, qd = _as_batch(q), _as_batch(qd)
    with np.errstate(all="ignore"):
        q3, p3, S, dS, _, D, status, no_position, ok = _fk_core(geom, q, qd)
        bad = status == INVALID
        qd3 = _sanitised(qd, bad)
        j = np.einsum("nci,nci->nc", D, dS)
        pd3 = _solve(D, j * qd3, ok)
        p = _with_fourth(p3, q, no_position)
        pd = _with_fourth(pd3, qd, ~ok)
    return p, pd, _finite_outputs(status, [(p, no_position), (pd, ~ok)])


def fk_acc(geom, q, qd, qdd):
    """Direct acceleration kinematics: (q, qd, qdd) -> (p, pd, pdd, status)."""
    q, qd, qdd = _as_batch(q), _as_batch(qd), _as_batch(qdd)
    with np.errstate(all="ignore"):
        q3, p3, S, dS, d2S, D, status, no_position, ok = _fk_core(geom, q, qd, qdd)
        bad = status == INVALID
        qd3 = _sanitised(qd, bad)
        qdd3 = _sanitised(qdd, bad)
        j = np.einsum("nci,nci->nc", D, dS)
        pd3 = _solve(D, j * qd3, ok)
        Sd = dS * qd3[:, :, None]
        Sdd = d2S * (qd3**2)[:, :, None] + dS * qdd3[:, :, None]
        rel_vel = np.where(ok[:, None], pd3, 0.0)[:, None, :] - Sd
        rhs = np.einsum("nci,nci->nc", D, Sdd) - np.einsum("nci,nci->nc", rel_vel, rel_vel)
        pdd3 = _solve(D, rhs, ok)
        p = _with_fourth(p3, q, no_position)
        pd = _with_fourth(pd3, qd, ~ok)
        pdd = _with_fourth(pdd3, qdd, ~ok)
    return p, pd, pdd, _finite_outputs(status, [(p, no_position), (pd, ~ok), (pdd, ~ok)])


def jacobian(geom, q):
    """J (N,3,3) with pd = J @ qd (first three columns of q only), status (N,)."""
    q = _as_batch(q)
    with np.errstate(all="ignore"):
        _, _, _, dS, _, D, status, _, ok = _fk_core(geom, q)
        j = np.einsum("nci,nci->nc", D, dS)
        Jq = j[:, :, None] * np.eye(3)  # diagonal J_q
        J = np.ascontiguousarray(_solve(D, Jq, ok))
    return J, _finite_outputs(status, [(J, ~ok)])


def ik(geom, p):
    """Inverse kinematics, elbow-out branch: p (N,3|4) -> q (N,3|4) in (-pi, pi], status."""
    p = _as_batch(p)
    with np.errstate(all="ignore"):
        n = p.shape[0]
        bad = _invalid_rows(p)
        p3 = _sanitised(p, bad)
        c, s = _trig(geom)
        r, l_a, l_b = geom.r, geom.l_a, geom.l_b
        x_i = p3[:, 0:1] * c + p3[:, 1:2] * s  # (N, 3 chains)
        z = p3[:, 2:3]
        pp = np.einsum("ni,ni->n", p3, p3)[:, None]
        E = 2.0 * l_a * (r - x_i)
        F = np.broadcast_to(2.0 * l_a * z, E.shape)
        G = r * r + l_a * l_a - 2.0 * r * x_i + pp - l_b * l_b
        disc = E * E + F * F - G * G
        unreachable = np.any(disc < 0.0, axis=1) & ~bad
        q3 = np.arctan2(F, E) + np.arctan2(np.sqrt(np.maximum(disc, 0.0)), -G)
        q3 = np.pi - np.mod(np.pi - q3, 2.0 * np.pi)  # wrap to (-pi, pi]

        S, dS, _ = _centres(geom, q3)
        j = np.einsum("nci,nci->nc", p3[:, None, :] - S, dS)
        singular = np.any((np.abs(j) / (l_a * l_b) < geom.singular_tol) | (j == 0.0), axis=1)

        status = np.full(n, OK, dtype=np.int8)
        status[singular] = SINGULAR
        status[unreachable] = UNREACHABLE
        status[bad] = INVALID
        q = _with_fourth(q3, p, bad | unreachable)
    return q, _finite_outputs(status, [(q, bad | unreachable)])
