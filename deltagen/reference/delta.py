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
* Inverse rates: ``J_q`` is diagonal, so row i of the velocity relation gives
  ``qd_i = D_i . pd / j_i`` and of the acceleration relation
  ``qdd_i = (D_i . pdd - qd_i^2 D_i . S_i'' + |pd - Sd_i|^2) / j_i``.
* A fourth input column (report eq. (43)) passes through unchanged.

Status rules (per point, int8; see :mod:`deltagen.status`):

* INVALID if any input value of the row is NaN or infinite; all outputs of the row NaN.
* fk level (:func:`fk`, :func:`fk_vel`, :func:`fk_acc`, :func:`jacobian`):
  SINGULAR if the sphere centres are (near) collinear, ``|e| / l_b^2 < tol``
  (outputs NaN; the spheres' intersection cannot be trilaterated, so this is decided
  before reachability); else UNREACHABLE if the spheres do not meet,
  ``l_b^2 - |u_0|^2 < 0`` (outputs NaN); else SINGULAR if
  ``|det D| / l_b^3 < tol`` (p is returned, pd / pdd / J are NaN); else OK.
* ik_vel, ik_acc: the status of ik, with the rates NaN unless OK (a SINGULAR row has
  an infinite qd); the finite-output rule covers q and the rates.
* ik: UNREACHABLE if for any chain ``E^2 + F^2 - G^2 < 0`` (row NaN), or if the target
  lies in the other assembly mode; else SINGULAR if for any chain ``|j_i| / (l_a l_b) < tol``
  or at the parallel singularity ``|det D| / l_b^3 <= tol`` (where fk(q) is SINGULAR too)
  (q is returned); else OK.
* Finite outputs (:mod:`deltagen.status`, the rule the generated C applies too): INVALID
  where an output the status gives is not finite (finite but huge inputs overflow, e.g. a
  target 1e155 m away); all outputs of the row NaN.

``tol`` is ``geom.singular_tol``. An exactly zero ``|e|``, ``det D`` or ``j_i`` counts
as singular even when ``tol == 0``. Whole rows are NaN'd, including a fourth column.
"""

from __future__ import annotations

import numpy as np

from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

__all__ = [
    "fk",
    "fk_vel",
    "fk_acc",
    "jacobian",
    "ik",
    "ik_vel",
    "ik_acc",
    "inverse_dynamics",
    "mass_matrix",
    "forward_dynamics",
    "simulate",
]


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


def _chains(geom):
    """Per-chain r_i = r_a,i - r_b,i, l_a,i, l_b,i as (3,) arrays (an asymmetric robot)."""
    return (
        np.asarray(geom.chain_r, dtype=np.float64),
        np.asarray(geom.chain("l_a"), dtype=np.float64),
        np.asarray(geom.chain("l_b"), dtype=np.float64),
    )


def _crank_angles(geom, q: np.ndarray) -> np.ndarray:
    """Measured angles (N, 3|4) -> geometric crank angles: + the encoder offsets."""
    if not any(geom.q_offset):
        return q
    out = np.array(q, dtype=np.float64, copy=True)
    out[:, :3] += np.asarray(geom.q_offset)
    return out


def _measured_angles(geom, q: np.ndarray) -> np.ndarray:
    """Geometric crank angles -> measured angles in (-pi, pi] (in place)."""
    if any(geom.q_offset):
        q[:, :3] = np.pi - np.mod(np.pi - (q[:, :3] - np.asarray(geom.q_offset)), 2.0 * np.pi)
    return q


def _centres(geom, q3: np.ndarray):
    """S_i, dS_i/dq_i and d^2S_i/dq_i^2 as (N, 3 chains, 3 coords) arrays."""
    c, s = _trig(geom)
    r, l_a, _ = _chains(geom)
    cq, sq = np.cos(q3), np.sin(q3)
    rho = r + l_a * cq
    S = np.stack((rho * c, rho * s, -l_a * sq), axis=-1)
    dS = np.stack((-l_a * sq * c, -l_a * sq * s, -l_a * cq), axis=-1)
    d2S = np.stack((-l_a * cq * c, -l_a * cq * s, l_a * sq), axis=-1)
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
    q3 = _sanitised(_crank_angles(geom, q), bad)
    S, dS, d2S = _centres(geom, q3)
    l_b = geom.l_b  # nominal: the scale of the thresholds
    rod = _chains(geom)[2]
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
    # planes u.a = (|a|^2 + l_b1^2 - l_b2^2) / 2, u.b = (|b|^2 + l_b1^2 - l_b3^2) / 2
    aa = aa + rod[0] ** 2 - rod[1] ** 2
    bb = bb + rod[0] ** 2 - rod[2] ** 2
    u0 = (aa[:, None] * np.cross(b, e) + bb[:, None] * np.cross(e, a)) / (2.0 * safe_e2[:, None])
    h = rod[0] ** 2 - np.einsum("ni,ni->n", u0, u0)
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
        r, l_a, l_b = _chains(geom)  # per chain, (3,)
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
        scale = geom.l_a * geom.l_b  # nominal
        singular = np.any((np.abs(j) / scale < geom.singular_tol) | (j == 0.0), axis=1)
        # the assembly mode: fk returns the intersection below the centre plane (against its
        # normal's z); a target above it is reached only in the other mode, through a
        # parallel singularity, and fk(q) would be its mirror image: unreachable here
        det = _det3(p3[:, None, :] - S)
        normal_z = np.cross(S[:, 1] - S[:, 0], S[:, 2] - S[:, 0])[:, 2]
        parallel = np.abs(det) / geom.l_b**3 <= geom.singular_tol
        above = (det * normal_z > 0.0) & ~parallel
        unreachable |= above & ~bad
        # at the parallel singularity fk(q) is SINGULAR (with collinear centres it has no p)
        singular |= parallel

        status = np.full(n, OK, dtype=np.int8)
        status[singular] = SINGULAR
        status[unreachable] = UNREACHABLE
        status[bad] = INVALID
        q = _measured_angles(geom, _with_fourth(q3, p, bad | unreachable))
    return q, _finite_outputs(status, [(q, bad | unreachable)])


def _inverse_rates(geom, p, pd, pdd=None):
    p, pd = _as_batch(p), _as_batch(pd)
    extra = () if pdd is None else (_as_batch(pdd),)
    with np.errstate(all="ignore"):
        bad_rates = _invalid_rows(pd, *extra)
        q, status = ik(geom, np.where(bad_rates[:, None], np.nan, p))
        no_q = (status == INVALID) | (status == UNREACHABLE)
        q[status == INVALID] = np.nan  # a row with a non-finite rate has no q either
        ok = status == OK
        q3 = _sanitised(_crank_angles(geom, q), ~ok)
        p3 = _sanitised(p, ~ok)
        S, dS, d2S = _centres(geom, q3)
        D = p3[:, None, :] - S
        j = np.einsum("nci,nci->nc", D, dS)
        j = np.where(ok[:, None], j, 1.0)
        pd3 = _sanitised(pd, ~ok)
        qd3 = np.einsum("nci,ni->nc", D, pd3) / j
        outs = [q, _with_fourth(qd3, pd, ~ok)]
        pairs = [(q, no_q), (outs[1], ~ok)]
        if pdd is not None:
            pdd3 = _sanitised(extra[0], ~ok)
            rel_vel = pd3[:, None, :] - dS * qd3[:, :, None]
            qdd3 = (
                np.einsum("nci,ni->nc", D, pdd3)
                - qd3**2 * np.einsum("nci,nci->nc", D, d2S)
                + np.einsum("nci,nci->nc", rel_vel, rel_vel)
            ) / j
            outs.append(_with_fourth(qdd3, extra[0], ~ok))
            pairs.append((outs[2], ~ok))
    return (*outs, _finite_outputs(status, pairs))


def ik_vel(geom, p, pd):
    """Inverse rates: (p, pd) (N,3|4) -> (q, qd, status); qd NaN unless OK."""
    return _inverse_rates(geom, p, pd)


def ik_acc(geom, p, pd, pdd):
    """Inverse rates: (p, pd, pdd) (N,3|4) -> (q, qd, qdd, status); rates NaN unless OK."""
    return _inverse_rates(geom, p, pd, pdd)


# ------------------------------------------------------------------------ dynamics
#
# A second formulation of the delta robot's dynamics, written from the bodies and not from
# the derivation (deltagen/derive/delta/dynamics.py works by virtual work with J of
# eq. (30)). Here every body gets its own Newton-Euler equations and the joint reaction
# forces are unknowns, solved for numerically per state:
#
#   rod pair i (slender rigid body, mass m_b, centre x_i midway between B_i and C_i,
#   inertia tensor I_r (E - u u^T) about x_i, I_r = m_b l_b^2 / 12, u = (C_i - B_i) / l_b):
#       F_Bi + F_Ci + m_b g = m_b a_xi
#       (B_i - x_i) x F_Bi + (C_i - x_i) x F_Ci = I alpha_i + w_i x I w_i   (two components
#       perpendicular to u; the axial one is 0 = 0 for slender rods)
#   with w_i = u x udot, alpha_i = u x uddot (the spin about u carries no inertia);
#   platform (translating point mass m_p + payload at P, rods act at C_i):
#       -sum_i F_Ci + (m_p + payload) g = (m_p + payload) pddot
#   crank i (turning about its drive axis e_t,i through A_i):
#       I_a qddot_i = tau_i + e_t . ((c_i - A_i) x m_a g) - e_t . ((B_i - A_i) x F_Bi)
#
# F_Bi is the force of crank i on rod i, F_Ci that of the platform on rod i. 21 equations,
# 21 unknowns (F_B, F_C, tau) per state, solved by LU (numpy.linalg.solve) for a batch.


def _crank_frames(geom, q3):
    """Per chain (N, 3, 3 coords): A_i, the crank's unit direction, its derivative per
    unit angle and the drive axis e_t (so that d(B - A)/dq = e_t x (B - A))."""
    c, s = _trig(geom)
    e_r = np.stack((c, s, np.zeros(3)), axis=-1)  # (3 chains, 3)
    e_z = np.array([0.0, 0.0, 1.0])
    e_t = np.cross(e_z, e_r)
    cq, sq = np.cos(q3)[..., None], np.sin(q3)[..., None]
    direction = cq * e_r - sq * e_z  # crank points down for q > 0
    d_direction = -sq * e_r - cq * e_z
    A = geom.r_a * e_r
    return A, direction, d_direction, e_t


def _rod_basis(u):
    """Two unit vectors perpendicular to u (N, 3, 3) and to each other."""
    helper = np.where(
        (np.abs(u[..., 2]) < 0.9)[..., None], np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    )
    n1 = np.cross(u, helper)
    n1 /= np.linalg.norm(n1, axis=-1, keepdims=True)
    return n1, np.cross(u, n1)


def _reaction_system(geom, inertia, q3, qd3, qdd3, p3, pd3, pdd3, payload, gravity):
    """Assemble and solve the 21 x 21 Newton-Euler system per state.
    Returns tau (N, 3), F_B (N, 3, 3), F_C (N, 3, 3)."""
    n = q3.shape[0]
    m_b, l_b = inertia.m_b, geom.l_b
    I_r = m_b * l_b**2 / 12.0
    m_P = inertia.m_p + payload  # (N,)
    g = np.asarray(gravity, dtype=np.float64)
    A, direction, d_direction, e_t = _crank_frames(geom, q3)
    B = A + geom.l_a * direction
    vB = geom.l_a * d_direction * qd3[..., None]
    # d^2 direction / dq^2 = -direction
    aB = geom.l_a * (d_direction * qdd3[..., None] - direction * (qd3**2)[..., None])
    c, s = _trig(geom)
    e_r = np.stack((c, s, np.zeros(3)), axis=-1)
    C = p3[:, None, :] + geom.r_b * e_r
    vC = np.broadcast_to(pd3[:, None, :], C.shape)
    aC = np.broadcast_to(pdd3[:, None, :], C.shape)
    x = 0.5 * (B + C)
    a_x = 0.5 * (aB + aC)
    d = C - B
    length = np.linalg.norm(d, axis=-1, keepdims=True)
    u = d / length
    udot = (vC - vB) / length
    uddot = (aC - aB) / length
    w = np.cross(u, udot)
    alpha = np.cross(u, uddot)
    # inertia tensor about x: I_r (E - u u^T), applied to vectors
    Iw = I_r * (w - u * np.einsum("nck,nck->nc", u, w)[..., None])
    Ialpha = I_r * (alpha - u * np.einsum("nck,nck->nc", u, alpha)[..., None])
    moment = Ialpha + np.cross(w, Iw)
    n1, n2 = _rod_basis(u)

    def skew(v):  # (..., 3) -> (..., 3, 3), skew(v) @ f = v x f
        z = np.zeros(v.shape[:-1])
        return np.stack(
            (
                np.stack((z, -v[..., 2], v[..., 1]), -1),
                np.stack((v[..., 2], z, -v[..., 0]), -1),
                np.stack((-v[..., 1], v[..., 0], z), -1),
            ),
            -2,
        )

    # unknown layout: F_B1..3 (0:9), F_C1..3 (9:18), tau (18:21)
    M = np.zeros((n, 21, 21))
    rhs = np.zeros((n, 21))
    row = 0
    eye = np.eye(3)
    for i in range(3):
        fb, fc = slice(3 * i, 3 * i + 3), slice(9 + 3 * i, 9 + 3 * i + 3)
        # rod i, force balance
        M[:, row : row + 3, fb] = eye
        M[:, row : row + 3, fc] = eye
        rhs[:, row : row + 3] = m_b * (a_x[:, i] - g)
        row += 3
        # rod i, moment balance about x_i, two components perpendicular to the rod
        lever_B = skew(B[:, i] - x[:, i])
        lever_C = skew(C[:, i] - x[:, i])
        for nvec in (n1[:, i], n2[:, i]):
            M[:, row, fb] = np.einsum("nk,nkj->nj", nvec, lever_B)
            M[:, row, fc] = np.einsum("nk,nkj->nj", nvec, lever_C)
            rhs[:, row] = np.einsum("nk,nk->n", nvec, moment[:, i])
            row += 1
    # platform: -sum F_C = m_P (pddot - g)
    for i in range(3):
        M[:, row : row + 3, 9 + 3 * i : 12 + 3 * i] = -eye
    rhs[:, row : row + 3] = m_P[:, None] * (pdd3 - g)
    row += 3
    # cranks: tau_i - e_t . ((B - A) x F_B) = I_a qdd - e_t . ((c - A) x m_a g)
    for i in range(3):
        lever = geom.l_a * direction[:, i]
        M[:, row, 18 + i] = 1.0
        # e_t . (l x F_B) = (e_t x l) . F_B, moved to the left-hand side
        M[:, row, 3 * i : 3 * i + 3] = -np.cross(e_t[i], lever)
        gravity_moment = np.einsum(
            "k,nk->n", e_t[i], np.cross(inertia.r_ca * direction[:, i], inertia.m_a * g)
        )
        rhs[:, row] = inertia.I_a * qdd3[:, i] - gravity_moment
        row += 1
    sol = np.linalg.solve(M, rhs[..., None])[..., 0]
    return sol[:, 18:21], sol[:, 0:9].reshape(n, 3, 3), sol[:, 9:18].reshape(n, 3, 3)


def simplified_inertia(geom, inertia):
    """The common simplified model as a robot of its own: each rod pair's mass split, m_b/2
    a point mass at the crank tip (adding (m_b/2) l_a^2 to the crank's inertia about its
    axis and moving its centre of mass) and m_b/2 on the platform; massless rods."""
    from dataclasses import replace

    half = 0.5 * inertia.m_b
    m_a = inertia.m_a + half
    return replace(
        inertia,
        I_a=inertia.I_a + half * geom.l_a**2,
        m_a=m_a,
        r_ca=(inertia.m_a * inertia.r_ca + half * geom.l_a) / m_a if m_a > 0 else 0.0,
        m_b=0.0,
        m_p=inertia.m_p + 3.0 * half,
    )


def inverse_dynamics(geom, inertia, q, qd, qdd, payload, gravity=None, model="exact"):
    """Motor torques tau (N, 3|4) by Newton-Euler with reaction forces (see above), status
    (N,) as fk_acc's; ``payload`` is (N,) [kg]. ``model="simplified"``: the same bodies
    with each rod pair's mass split (:func:`simplified_inertia`).
    Column 4 (fourth axis, eq. (43)): I_4 qddot_4."""
    if model == "simplified":
        inertia = simplified_inertia(geom, inertia)
    q, qd, qdd = _as_batch(q), _as_batch(qd), _as_batch(qdd)
    payload = np.ascontiguousarray(payload, dtype=np.float64).reshape(-1)
    gravity = inertia.gravity if gravity is None else gravity
    with np.errstate(all="ignore"):
        p, pd, pdd, status = fk_acc(geom, q, qd, qdd)
        status = status.copy()
        status[(status == OK) & ~np.isfinite(payload)] = INVALID
        ok = status == OK
        tau3 = np.full((q.shape[0], 3), np.nan)
        if ok.any():
            tau3[ok] = _reaction_system(
                geom,
                inertia,
                q[ok, :3],
                qd[ok, :3],
                qdd[ok, :3],
                p[ok, :3],
                pd[ok, :3],
                pdd[ok, :3],
                payload[ok],
                gravity,
            )[0]
        tau = _with_fourth(tau3, inertia.I_4 * qdd, ~ok)
    return tau, _finite_outputs(status, [(tau, ~ok)])


def _dynamics_terms(geom, inertia, q, qd, payload):
    """(M(q) (N, 3, 3), h(q, qdot) (N, 3)) with tau = M qddot + h, from one batched inverse
    dynamics call: h at qddot = 0, and M's column k as the torques of qddot = e_k at rest
    minus those of rest (tau is linear in qddot; the velocity terms vanish at rest)."""
    n = q.shape[0]
    zero = np.zeros_like(q)
    rows_q = np.concatenate([q] * 5)
    rows_qd = np.concatenate([qd, zero, zero, zero, zero])
    rows_qdd = np.concatenate([zero, zero] + [np.broadcast_to(e, q.shape) for e in np.eye(3)])
    load = np.concatenate([np.broadcast_to(np.asarray(payload, dtype=np.float64), (n,))] * 5)
    tau = inverse_dynamics(geom, inertia, rows_q, rows_qd, rows_qdd, load)[0].reshape(5, n, 3)
    M = np.stack([tau[2 + k] - tau[1] for k in range(3)], axis=-1)
    return M, tau[0]


def mass_matrix(geom, inertia, q, payload=0.0):
    """M(q) (N, 3, 3) of the crank coordinates (column k: the torques of qddot = e_k)."""
    q = _as_batch(q)[:, :3]
    return _dynamics_terms(geom, inertia, q, np.zeros_like(q), payload)[0]


def forward_dynamics(geom, inertia, q, qd, tau, payload=0.0):
    """qddot (N, 3) of the cranks from the motor torques: M(q) qddot = tau - h(q, qdot)."""
    q, qd, tau = _as_batch(q)[:, :3], _as_batch(qd)[:, :3], _as_batch(tau)[:, :3]
    M, h = _dynamics_terms(geom, inertia, q, qd, payload)
    return np.linalg.solve(M, (tau - h)[..., None])[..., 0]


def simulate(geom, inertia, torque, t_span, q0, qd0, t_eval, payload=0.0, rtol=1e-10, atol=1e-12):
    """Integrate the multibody equations (minimal coordinates q, this module's own mass
    matrix) under motor torques ``torque(t) -> (3,)`` with scipy's DOP853.
    Returns (q (len(t_eval), 3), qd (len(t_eval), 3))."""
    from scipy.integrate import solve_ivp

    def rhs(t, state):
        q, qd = state[:3][None], state[3:][None]
        qdd = forward_dynamics(geom, inertia, q, qd, np.asarray(torque(t))[None, :3], payload)
        return np.concatenate((state[3:], qdd[0]))

    sol = solve_ivp(
        rhs,
        t_span,
        np.concatenate((q0, qd0)),
        method="DOP853",
        t_eval=t_eval,
        rtol=rtol,
        atol=atol,
    )
    if not sol.success:
        raise RuntimeError(f"simulation failed: {sol.message}")
    return sol.y[:3].T, sol.y[3:].T
