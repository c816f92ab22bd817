"""Independent pure-numpy reference kinematics of the linear delta and the tripod.

Written from the geometry of model/linear_delta.py, sharing nothing with the SymPy
derivation or the generated C: the direct kinematics is trilateration in a local frame
(Klipper's mathutil.trilateration and the textbook method: ex along S_2 - S_1, ey in the
centre plane, ez = ex x ey; the point at (u, v, +-w) in that frame), not the Cramer
solution of the derivation.

* Sphere centres S_i and radii r_i: the linear delta's carriage joints
  (tower_x_i, tower_y_i, h_i) with the arm lengths; the tripod's base points A, B, C with
  the strut lengths.
* Side: the linear delta's effector hangs below the carriages (w along -ez where ez points
  up, Klipper's choice); the tripod's point lies above (z > 0) or below its base plane.
* Rates: |p - S_i|^2 = r_i^2 differentiated in time gives D pd = diag(g) qd with rows
  D_i = p - S_i and g_i = D_i,z (a carriage moving along z) or l_i (a strut); twice,
  D pdd = diag(g) qdd + c with c_i = -|pd - hd_i z|^2 or ld_i^2 - |pd|^2; numpy solves.
* Inverse: h_i = z + sqrt(arm_i^2 - (x - tower_x_i)^2 - (y - tower_y_i)^2), l_i = |p - S_i|;
  its rates row by row from the same relations (qd_i = D_i . pd / g_i, ...).

Status rules (as the generated C, derive/linear_delta/kernels.py): INVALID (non-finite
input, or a non-finite output the status does not explain), SINGULAR (collinear centres,
|e|^2 <= (tol L^2)^2, no output), UNREACHABLE (the spheres do not meet; a negative strut),
SINGULAR (|det D| <= tol L^3: p given, rates NaN). ik: UNREACHABLE (an arm cannot reach, or
p on the other side of the centre plane with |det D| > tol L^3), SINGULAR (linear delta: an
arm within tol L of horizontal; tripod: |det D| <= tol L^3), the joints given. L: the mean
arm length, or (|b_x| + |C|) / 2 for the tripod.
"""

from __future__ import annotations

import numpy as np

from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

LINEAR, TRIPOD = "linear_delta", "tripod"


def _scale(kind, g):
    if kind == LINEAR:
        return float(np.mean(g.arm_length))
    return (abs(g.b_x) + float(np.hypot(g.c_x, g.c_y))) / 2.0


def _centres(kind, g, q):
    """(N, 3, 3) sphere centres and (N, 3) radii for joint values q (N, 3)."""
    n = q.shape[0]
    if kind == LINEAR:
        S = np.empty((n, 3, 3))
        S[:, :, 0] = np.array(g.tower_x)
        S[:, :, 1] = np.array(g.tower_y)
        S[:, :, 2] = q
        return S, np.broadcast_to(np.array(g.arm_length), (n, 3))
    S = np.broadcast_to(np.array(g.base_points), (n, 3, 3))
    return S, q


def _side(kind, g):
    return -1.0 if kind == LINEAR else g.side_sign


def _trilaterate(kind, g, q):
    """p (N, 3) (NaN where none), D (N, 3, 3), status (N,) of the fk level."""
    with np.errstate(all="ignore"):
        S, r = _centres(kind, g, q)
        L, tol = _scale(kind, g), g.singular_tol
        s21, s31 = S[:, 1] - S[:, 0], S[:, 2] - S[:, 0]
        normal = np.cross(s21, s31)
        d = np.linalg.norm(s21, axis=1)
        ex = s21 / d[:, None]
        i = np.einsum("nk,nk->n", ex, s31)
        ey = s31 - i[:, None] * ex
        ey /= np.linalg.norm(ey, axis=1)[:, None]
        ez = np.cross(ex, ey)
        j = np.einsum("nk,nk->n", ey, s31)
        r1, r2, r3 = (r[:, k] ** 2 for k in range(3))
        u = (r1 - r2 + d**2) / (2.0 * d)
        v = (r1 - r3 + i**2 + j**2) / (2.0 * j) - i * u / j
        w2 = r1 - u**2 - v**2
        w = _side(kind, g) * np.copysign(np.sqrt(np.maximum(w2, 0.0)), ez[:, 2])
        p = S[:, 0] + u[:, None] * ex + v[:, None] * ey + w[:, None] * ez
        D = p[:, None, :] - S
        det = np.linalg.det(D)
        invalid = ~np.all(np.isfinite(q), axis=1)
        collinear = np.einsum("nk,nk->n", normal, normal) <= (tol * L**2) ** 2
        unreachable = w2 < 0
        if kind == TRIPOD:
            unreachable |= np.any(q < 0, axis=1)
        singular = np.abs(det) <= tol * L**3
    status = np.select(
        [invalid, collinear, unreachable, singular], [INVALID, SINGULAR, UNREACHABLE, SINGULAR], OK
    ).astype(np.int8)
    p[(status == INVALID) | ((status == SINGULAR) & collinear) | (status == UNREACHABLE)] = np.nan
    return p, D, status


def _finite_rule(status, outs):
    """The finite-output rule (deltagen/status.py): a row whose outputs are not all finite,
    beyond the NaNs its status explains, is INVALID with every output NaN."""
    bad = np.zeros(status.shape, bool)
    for out, explained in outs:
        flat = out.reshape(out.shape[0], -1)
        bad |= ~np.all(np.isfinite(flat), axis=1) & ~explained
    status[bad] = INVALID
    for out, _ in outs:
        out[bad] = np.nan
    return status


def fk(kind, g, q):
    q = np.asarray(q, dtype=float).reshape(-1, 3)
    p, _, status = _trilaterate(kind, g, q)
    no_p = status != OK
    no_p &= ~((status == SINGULAR) & np.all(np.isfinite(p), axis=1))
    return p, _finite_rule(status, [(p, no_p)])


def _g(kind, D, q):
    return D[:, :, 2] if kind == LINEAR else q


def _rates(kind, g, q, qd, qdd=None):
    p, D, status = _trilaterate(kind, g, q)
    ok = status == OK
    rates_in = [qd] + ([qdd] if qdd is not None else [])
    for arr in rates_in:
        bad = ~np.all(np.isfinite(arr), axis=1)
        status[bad] = INVALID
        p[bad] = np.nan
        ok &= ~bad
    gv = _g(kind, D, q)
    pd = np.full_like(p, np.nan)
    pdd = np.full_like(p, np.nan)
    with np.errstate(all="ignore"):
        if np.any(ok):
            pd[ok] = np.linalg.solve(D[ok], (gv[ok] * qd[ok])[..., None])[..., 0]
            if qdd is not None:
                if kind == LINEAR:
                    rel = pd[ok][:, None, :] - qd[ok][:, :, None] * np.array([0.0, 0.0, 1.0])
                    c = -np.einsum("nik,nik->ni", rel, rel)
                else:
                    c = qd[ok] ** 2 - np.einsum("nk,nk->n", pd[ok], pd[ok])[:, None]
                rhs = gv[ok] * qdd[ok] + c
                pdd[ok] = np.linalg.solve(D[ok], rhs[..., None])[..., 0]
    no_p = (status != OK) & ~((status == SINGULAR) & np.all(np.isfinite(p), axis=1))
    return p, pd, pdd, status, no_p, ~ok


def fk_vel(kind, g, q, qd):
    q, qd = (np.asarray(a, dtype=float).reshape(-1, 3) for a in (q, qd))
    p, pd, _, status, no_p, no_r = _rates(kind, g, q, qd)
    return p, pd, _finite_rule(status, [(p, no_p), (pd, no_r)])


def fk_acc(kind, g, q, qd, qdd):
    q, qd, qdd = (np.asarray(a, dtype=float).reshape(-1, 3) for a in (q, qd, qdd))
    p, pd, pdd, status, no_p, no_r = _rates(kind, g, q, qd, qdd)
    return p, pd, pdd, _finite_rule(status, [(p, no_p), (pd, no_r), (pdd, no_r)])


def jacobian(kind, g, q):
    q = np.asarray(q, dtype=float).reshape(-1, 3)
    p, D, status = _trilaterate(kind, g, q)
    ok = status == OK
    J = np.full((q.shape[0], 3, 3), np.nan)
    with np.errstate(all="ignore"):
        if np.any(ok):
            J[ok] = np.linalg.solve(D[ok], np.eye(3)[None] * _g(kind, D, q)[ok][:, None, :])
    return J, _finite_rule(status, [(J, ~ok)])


def ik(kind, g, p):
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    L, tol = _scale(kind, g), g.singular_tol
    with np.errstate(all="ignore"):
        invalid = ~np.all(np.isfinite(p), axis=1)
        if kind == LINEAR:
            dx = p[:, 0:1] - np.array(g.tower_x)
            dy = p[:, 1:2] - np.array(g.tower_y)
            rad = np.array(g.arm_length) ** 2 - dx**2 - dy**2
            q = p[:, 2:3] + np.sqrt(rad)
            S = np.stack(
                [np.broadcast_to(g.tower_x, q.shape), np.broadcast_to(g.tower_y, q.shape), q],
                axis=-1,
            )
        else:
            S = np.broadcast_to(np.array(g.base_points), (p.shape[0], 3, 3))
            q = np.linalg.norm(p[:, None, :] - S, axis=2)
        D = p[:, None, :] - S
        det = np.linalg.det(D)
        normal_z = np.cross(S[:, 1] - S[:, 0], S[:, 2] - S[:, 0])[:, 2]
        other = (_side(kind, g) * det * normal_z < 0) & (np.abs(det) > tol * L**3)
        if kind == LINEAR:
            unreachable = np.any(rad < 0, axis=1) | other
            singular = np.any(rad <= (tol * L) ** 2, axis=1)
        else:
            unreachable = other
            singular = np.abs(det) <= tol * L**3
    status = np.select(
        [invalid, unreachable, singular], [INVALID, UNREACHABLE, SINGULAR], OK
    ).astype(np.int8)
    q = np.array(q)
    q[invalid | unreachable] = np.nan
    return q, _finite_rule(status, [(q, invalid | unreachable)])


def _ik_rates(kind, g, p, pd, pdd=None):
    """Joints, rates (and accelerations) from the rows of D pd = diag(g) qd and
    D pdd = diag(g) qdd + c, each row on its own (diag(g) is diagonal)."""
    q, status = ik(kind, g, p)
    with np.errstate(all="ignore"):
        bad = ~np.all(np.isfinite(pd), axis=1)
        if pdd is not None:
            bad |= ~np.all(np.isfinite(pdd), axis=1)
        status[bad] = INVALID
        q[bad] = np.nan
        if kind == LINEAR:
            S = np.stack(
                [np.broadcast_to(g.tower_x, q.shape), np.broadcast_to(g.tower_y, q.shape), q], -1
            )
        else:
            S = np.broadcast_to(np.array(g.base_points), (p.shape[0], 3, 3))
        D = p[:, None, :] - S
        gv = _g(kind, D, q)
        qd = np.einsum("nik,nk->ni", D, pd) / gv
        qdd = None
        if pdd is not None:
            if kind == LINEAR:
                rel = pd[:, None, :] - qd[:, :, None] * np.array([0.0, 0.0, 1.0])
                c = -np.einsum("nik,nik->ni", rel, rel)
            else:
                c = qd**2 - np.einsum("nk,nk->n", pd, pd)[:, None]
            qdd = (np.einsum("nik,nk->ni", D, pdd) - c) / gv
    no_q = (status == INVALID) | (status == UNREACHABLE)
    no_rates = no_q | ((status == SINGULAR) if kind == LINEAR else False)
    outs = [(q, no_q), (qd, no_rates)] + ([(qdd, no_rates)] if qdd is not None else [])
    for out, mask in outs[1:]:
        out[mask] = np.nan
    status = _finite_rule(status, outs)
    return (q, qd, status) if qdd is None else (q, qd, qdd, status)


def ik_vel(kind, g, p, pd):
    p, pd = (np.asarray(a, dtype=float).reshape(-1, 3) for a in (p, pd))
    return _ik_rates(kind, g, p, pd)


def ik_acc(kind, g, p, pd, pdd):
    p, pd, pdd = (np.asarray(a, dtype=float).reshape(-1, 3) for a in (p, pd, pdd))
    return _ik_rates(kind, g, p, pd, pdd)
