"""The hexapod in numpy, written from the model (model/hexapod.py), never from the
derivation: the compiled core is checked against it.

Written differently on purpose: the platform joints are mapped by homogeneous transforms
(T @ [b_i, 1]), the Jacobian rows use the moment arm p_i - p of the world-frame joint
(not R b_i), the joint angles use arccos of normalised dot products, and the forward
kinematics is SciPy's least-squares solver (trust-region reflective) on the pose
parametrised as (p, rotation vector of R R_guess^T), not the damped Newton of the C
runtime.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from deltagen.geometry.rotations import rot_exp
from deltagen.status import OK, UNREACHABLE


class ReferenceHexapod:
    def __init__(self, geometry):
        self.g = geometry
        self.a = np.array(geometry.base_joints)  # (6, 3)
        self.b_h = np.hstack([np.array(geometry.platform_joints), np.ones((6, 1))])  # (6, 4)
        self.n_a = np.array(geometry.base_axes)
        self.n_b = np.array(geometry.platform_axes)

    def platform_points(self, T):
        """World positions of the platform joints, (N, 6, 3), from poses (N, 4, 4)."""
        return np.einsum("nrc,jc->njr", T, self.b_h)[..., :3]

    def ik(self, T):
        """Leg lengths (N, 6) of poses (N, 4, 4)."""
        return np.linalg.norm(self.platform_points(T) - self.a, axis=-1)

    def jacobian(self, T):
        """dl/d(v, w) (N, 6, 6), w in the base frame, v of the platform origin."""
        pts = self.platform_points(T)
        legs = pts - self.a
        u = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
        arm = pts - T[:, None, :3, 3]
        return np.concatenate([u, np.cross(arm, u)], axis=-1)

    def joint_angles(self, T):
        """(N, 12): base joint angles, then platform joint angles [rad]."""
        legs = self.platform_points(T) - self.a
        u = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
        nb = np.einsum("nrc,jc->njr", T[:, :3, :3], self.n_b)
        base = np.arccos(np.clip(np.sum(u * self.n_a, axis=-1), -1, 1))
        plat = np.arccos(np.clip(np.sum(-u * nb, axis=-1), -1, 1))
        return np.concatenate([base, plat], axis=-1)

    def fk(self, lengths, guess, tol=1e-13):
        """Poses (N, 4, 4) and status of leg lengths (N, 6) from start poses (N, 4, 4), one
        least-squares solve per point; UNREACHABLE where the residual stays above ``tol``."""
        lengths = np.asarray(lengths, dtype=float)
        out = np.full((len(lengths), 4, 4), np.nan)
        status = np.full(len(lengths), UNREACHABLE, dtype=np.int8)
        for k, (l_k, T0) in enumerate(zip(lengths, guess)):

            def pose(x, T0=T0):
                T = np.eye(4)
                T[:3, :3] = rot_exp(x[3:]) @ T0[:3, :3]
                T[:3, 3] = T0[:3, 3] + x[:3]
                return T

            def residual(x, l_k=l_k, pose=pose):
                return self.ik(pose(x)[None])[0] - l_k

            sol = least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15)
            if np.max(np.abs(residual(sol.x))) <= tol:
                out[k] = pose(sol.x)
                status[k] = OK
        return out, status
