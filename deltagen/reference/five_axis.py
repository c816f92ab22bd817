"""The numpy reference of the 5-axis machines, written from model/five_axis.py (its
docstring gives the chain), not from the derivation: rotation matrices per point and their
products, the tilt from the direction's polar angle, C as the difference of the direction's azimuth and
the tilted tool's azimuth. Same signatures as native/five_axis.py's CompiledFiveAxis:
(N, w) float64 in, outputs and an int8 status out."""

from __future__ import annotations

import numpy as np

from deltagen import status as st


def _rz(c):
    cc, sc = np.cos(c), np.sin(c)
    R = np.zeros(c.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = cc, -sc, sc, cc
    R[..., 2, 2] = 1.0
    return R


def _rtilt(axis, t):
    ct, s = np.cos(t), np.sin(t)
    R = np.zeros(t.shape + (3, 3))
    if axis == "A":
        R[..., 0, 0] = 1.0
        R[..., 1, 1], R[..., 1, 2], R[..., 2, 1], R[..., 2, 2] = ct, -s, s, ct
    else:
        R[..., 1, 1] = 1.0
        R[..., 0, 0], R[..., 0, 2], R[..., 2, 0], R[..., 2, 2] = ct, s, -s, ct
    return R


def _axes(desc, t, c):
    """(R_hc, R_ht, R_tc, R_tt) per point, as the layout places the axes."""
    eye = np.broadcast_to(np.eye(3), t.shape + (3, 3))
    Rc, Rt = _rz(c), _rtilt(desc.tilt_axis, t)
    return {
        "table-table": (eye, eye, Rc, Rt),
        "head-head": (Rc, Rt, eye, eye),
        "table-head": (eye, Rt, Rc, eye),
    }[desc.layout]


def _mv(R, v):
    return np.einsum("...ij,...j->...i", R, v)


def _mtv(R, v):
    return np.einsum("...ji,...j->...i", R, v)


def fk(desc, j):
    """Tool tip p (N, 3) and tool axis d (N, 3) in the workpiece frame, status (N,)."""
    j = np.asarray(j, dtype=float)
    with np.errstate(all="ignore"):
        t, c = j[:, 3], j[:, 4]
        R_hc, R_ht, R_tc, R_tt = _axes(desc, t, c)
        e_z = np.array([0.0, 0.0, 1.0])
        d_m = _mv(R_hc, _mv(R_ht, np.broadcast_to(e_z, j[:, :3].shape)))
        h, g = np.array(desc.head_pivot), np.array(desc.spindle_offset)
        m = j[:, :3] + _mv(R_hc, h + _mv(R_ht, np.broadcast_to(g, j[:, :3].shape)))
        m = m - desc.tool_length * d_m
        pc, pt = np.array(desc.c_pivot), np.array(desc.tilt_pivot)
        p = pc + _mv(R_tc, pt - pc + _mv(R_tt, m - pt))
        d = _mv(R_tc, _mv(R_tt, d_m))
        status = np.where(np.abs(np.sin(t)) <= desc.singular_tol, st.SINGULAR, st.OK)
    return _finish([p, d], np.all(np.isfinite(j), axis=1), status)


def _finish(outs, finite_in, status):
    status = np.where(finite_in, status, st.INVALID).astype(np.int8)
    ok_out = np.ones(len(status), dtype=bool)
    for o in outs:
        ok_out &= np.all(np.isfinite(o.reshape(len(status), -1)), axis=1)
    status[(status != st.INVALID) & ~ok_out] = st.INVALID
    for o in outs:
        o[status == st.INVALID] = np.nan
    return (*outs, status)


def _joints(desc, p, d_unit, t, c):
    """x, y, z putting the tool tip at p with the rotary angles t, c: the chain undone."""
    R_hc, R_ht, R_tc, R_tt = _axes(desc, t, c)
    pc, pt = np.array(desc.c_pivot), np.array(desc.tilt_pivot)
    m = pt + _mtv(R_tt, pc - pt + _mtv(R_tc, p - pc))
    e_z = np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape)
    h, g = np.array(desc.head_pivot), np.array(desc.spindle_offset)
    d_m = _mv(R_hc, _mv(R_ht, e_z))
    return m - _mv(R_hc, h + _mv(R_ht, np.broadcast_to(g, p.shape))) + desc.tool_length * d_m


def ik_all(desc, p, d, j_prev):
    """Both rotary branches (N, 2, 5): branch 1 with sin(tilt) >= 0, branch 2 <= 0; C at
    the turn nearest j_prev's C, or j_prev's C where the tool axis is parallel to C; which
    branches lie within the tilt's travel (N, 2); the status (UNREACHABLE: neither)."""
    p, d, j_prev = (np.asarray(a, dtype=float) for a in (p, d, j_prev))
    n = p.shape[0]
    with np.errstate(all="ignore"):
        length = np.linalg.norm(d / np.max(np.abs(d), axis=1, keepdims=True), axis=1)
        u = d / np.max(np.abs(d), axis=1, keepdims=True) / length[:, None]
        horizontal = np.hypot(u[:, 0], u[:, 1])
        singular = horizontal <= desc.singular_tol
        c_prev = j_prev[:, 4]
        out = np.empty((n, 2, 5))
        azimuth = np.arctan2(u[:, 1], u[:, 0])
        for k, sign in enumerate((1.0, -1.0)):
            t = sign * np.arctan2(horizontal, u[:, 2])
            # the tilted tool's azimuth: R_x(t) e_z = (0, -sin t, .), R_y(t) e_z = (sin t, 0, .)
            tool = np.arctan2(-sign, 0.0) if desc.tilt_axis == "A" else np.arctan2(0.0, sign)
            c = azimuth - tool
            c = c + 2 * np.pi * np.round((c_prev - c) / (2 * np.pi))
            c = np.where(singular, c_prev, c)
            out[:, k, 3], out[:, k, 4] = t, c
            out[:, k, :3] = _joints(desc, p, u, t, c)
    finite = np.all(np.isfinite(np.hstack([p, d, j_prev])), axis=1) & (length > 0)
    lo, hi = desc.tilt_limits
    within = (out[:, :, 3] >= lo) & (out[:, :, 3] <= hi)
    status = np.where(~within.any(axis=1), st.UNREACHABLE, np.where(singular, st.SINGULAR, st.OK))
    (out, status) = _finish([out], finite, status)
    return out, within & (status != st.INVALID)[:, None], status


def ik(desc, p, d, j_prev):
    """The branch of ik_all within the tilt's travel nearest j_prev's tilt and C (sum of
    squared differences; the first branch on a tie); NaN where neither is within."""
    both, within, status = ik_all(desc, p, d, j_prev)
    cost = ((both[:, :, 3:] - np.asarray(j_prev, dtype=float)[:, None, 3:]) ** 2).sum(axis=2)
    cost = np.where(within, cost, np.inf)
    pick = np.where(cost[:, 0] <= cost[:, 1], 0, 1)
    out = both[np.arange(len(pick)), pick]
    out[status == st.UNREACHABLE] = np.nan
    return out, status
