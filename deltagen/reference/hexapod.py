"""The hexapod in numpy, written from the model (model/hexapod.py), never from the
derivation: the compiled core is checked against it, and ``backend="reference"`` runs on it.

Each function takes the geometry first and then the compiled core's arrays (poses (N, 16),
leg lengths (N, 6), C-contiguous float64), and returns what the compiled core returns, the
per-point status last (api/base.ReferenceCore gives the API the compiled core's call
signatures from these).

Written differently on purpose: the platform joints are mapped by homogeneous transforms
(T @ [b_i, 1]), the Jacobian rows use the moment arm p_i - p of the world-frame joint
(not R b_i), the joint angles use arccos of normalised dot products, and the forward
kinematics is SciPy's least-squares solver (trust-region reflective) on the pose
parametrised as (p, rotation vector of R R_guess^T), not the damped Newton of the C
runtime (whose options tol, damping, max_step and max_iter it therefore does not read;
``warm_start`` it honours: each point starts from the previous point's pose where that one
converged).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from deltagen.geometry.rotations import rot_exp
from deltagen.status import INVALID, OK, UNREACHABLE

#: the reference fk's acceptance: max_i |l_i(pose) - l_i| [m]
FK_TOL = 1e-13


def _homogeneous_platform_joints(g):
    return np.hstack([np.array(g.platform_joints), np.ones((6, 1))])  # (6, 4)


def platform_points(g, T):
    """World positions of the platform joints, (N, 6, 3), from poses (N, 4, 4)."""
    return np.einsum("nrc,jc->njr", T, _homogeneous_platform_joints(g))[..., :3]


def leg_lengths(g, T):
    """Leg lengths (N, 6) of poses (N, 4, 4)."""
    return np.linalg.norm(platform_points(g, T) - np.array(g.base_joints), axis=-1)


def _status(*outs):
    """OK where every output of a row is finite, else INVALID (the finite-output rule)."""
    finite = np.ones(len(outs[0]), dtype=bool)
    for out in outs:
        finite &= np.all(np.isfinite(out.reshape(len(out), -1)), axis=1)
    return np.where(finite, OK, INVALID).astype(np.int8)


def ik(g, pose):
    """Leg lengths (N, 6) and status of poses (N, 16)."""
    with np.errstate(all="ignore"):
        lengths = leg_lengths(g, pose.reshape(-1, 4, 4))
    return lengths, _status(lengths)


def jacobian(g, pose):
    """Leg lengths (N, 6), dl/d(v, w) (N, 6, 6) (w in the base frame, v of the platform
    origin) and status of poses (N, 16)."""
    T = pose.reshape(-1, 4, 4)
    with np.errstate(all="ignore"):
        pts = platform_points(g, T)
        legs = pts - np.array(g.base_joints)
        lengths = np.linalg.norm(legs, axis=-1)
        u = legs / lengths[..., None]
        arm = pts - T[:, None, :3, 3]
        J = np.concatenate([u, np.cross(arm, u)], axis=-1)
    return lengths, J, _status(J)


def joint_angles(g, pose):
    """(N, 12): base joint angles, then platform joint angles [rad], and status."""
    T = pose.reshape(-1, 4, 4)
    with np.errstate(all="ignore"):
        legs = platform_points(g, T) - np.array(g.base_joints)
        u = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
        nb = np.einsum("nrc,jc->njr", T[:, :3, :3], np.array(g.platform_axes))
        base = np.arccos(np.clip(np.sum(u * np.array(g.base_axes), axis=-1), -1, 1))
        plat = np.arccos(np.clip(np.sum(-u * nb, axis=-1), -1, 1))
        angles = np.concatenate([base, plat], axis=-1)
    return angles, _status(angles)


def _solve_one(g, l_k, T0):
    """The pose (4, 4) of leg lengths l_k (6,) from T0 by least squares, or None."""

    def pose(x):
        T = np.eye(4)
        T[:3, :3] = rot_exp(x[3:]) @ T0[:3, :3]
        T[:3, 3] = T0[:3, 3] + x[:3]
        return T

    def residual(x):
        return leg_lengths(g, pose(x)[None])[0] - l_k

    sol = least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return pose(sol.x) if np.max(np.abs(residual(sol.x))) <= FK_TOL else None


def fk(g, lengths, guess, tol=None, damping=None, max_step=None, max_iter=None, warm_start=False):
    """Poses (N, 16), residuals max_i |l_i(pose) - l_i| (N,) [m], iterations (N,) (0: the
    reference does not count them) and status of leg lengths (N, 6) from start poses
    (N, 16): one least-squares solve per point, UNREACHABLE where the residual stays above
    FK_TOL, INVALID for non-finite lengths. The C Newton's options (tol, damping, max_step,
    max_iter) are accepted for the compiled core's signature and not read."""
    lengths = np.asarray(lengths, dtype=float)
    starts = np.asarray(guess, dtype=float).reshape(-1, 4, 4)
    n = len(lengths)
    out = np.full((n, 4, 4), np.nan)
    status = np.full(n, UNREACHABLE, dtype=np.int8)
    finite = np.all(np.isfinite(lengths), axis=1)
    status[~finite] = INVALID
    previous = None
    for k in range(n):
        if not finite[k]:
            previous = None
            continue
        start = previous if warm_start and previous is not None else starts[k]
        found = previous = _solve_one(g, lengths[k], start)
        if found is not None:
            out[k] = found
            status[k] = OK
    with np.errstate(all="ignore"):
        residual = np.max(np.abs(leg_lengths(g, out) - lengths), axis=1)
    return out.reshape(n, 16), residual, np.zeros(n, dtype=np.int32), status
