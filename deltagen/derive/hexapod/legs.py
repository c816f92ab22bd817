"""The legs of a hexapod at a pose (R, p): the leg vectors d_i = p + R b_i - a_i (base
joint to platform joint, base frame), the lengths l_i = |d_i|, the unit vectors
u_i = d_i / l_i, the leg-length Jacobian and the joint angles.

Leg-length Jacobian (the platform twist (v, w): v the velocity of the platform origin, w
the angular velocity, both in the base frame): the platform joint moves at
v + w x (R b_i), so dl_i/dt = u_i . (v + w x R b_i) = u_i . v + ((R b_i) x u_i) . w, and
row i of J is (u_i^T, ((R b_i) x u_i)^T) (the same rows as LinuxCNC genhexkins' inverse
Jacobian, there with the points named the other way round).
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.hexapod.symbols import LEGS, R, a, b, n_a, n_b, p


def leg_vectors() -> list[sp.Matrix]:
    """d_i = p + R b_i - a_i (3-vectors of expressions in the pose and the joints)."""
    return [p + R * b[i] - a[i] for i in range(LEGS)]


def rotated_platform_joints() -> list[sp.Matrix]:
    """R b_i: the platform joints relative to the platform origin, in the base frame."""
    return [R * b[i] for i in range(LEGS)]


def jacobian_rows(u, rb) -> list[list[sp.Expr]]:
    """Row i of dl/d(v, w): (u_i, rb_i x u_i), from the unit vectors u_i and R b_i."""
    return [[*u[i], *rb[i].cross(u[i])] for i in range(LEGS)]


def joint_angle_terms(d) -> tuple[list, list]:
    """(cos-side, sin-side) pairs of the joint angles: at the base the angle between d_i and
    n_a,i, at the platform between -d_i and R n_b,i; each angle is atan2(|x cross n|, x . n)
    (accurate near 0 and pi, unlike acos of the normalised dot product)."""
    base, platform = [], []
    for i in range(LEGS):
        for x, n, out in ((d[i], n_a[i], base), (-d[i], R * n_b[i], platform)):
            c = x.cross(n)
            out.append((x.dot(n), sp.sqrt(c.dot(c))))
    return base, platform
