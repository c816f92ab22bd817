"""Symbols of the hexapod kernels: the pose (a 4x4 homogeneous transform, row-major) and
the geometry, which stays symbolic (struct parameters), so one compiled core serves every
hexapod."""

from __future__ import annotations

import sympy as sp

from deltagen.derive.kernel import Parameter

LEGS = 6

#: the pose T (platform frame in the base frame), row-major: T[r][c] = T_rc
T = [[sp.Symbol(f"T{r}{c}", real=True) for c in range(4)] for r in range(4)]
R = sp.Matrix(3, 3, lambda r, c: T[r][c])
p = sp.Matrix([T[0][3], T[1][3], T[2][3]])
pose_symbols = tuple(T[r][c] for r in range(4) for c in range(4))


def _points(name: str) -> list[sp.Matrix]:
    return [sp.Matrix([sp.Symbol(f"{name}{i}_{k}", real=True) for k in "xyz"]) for i in range(LEGS)]


a = _points("a")  # base joints, base frame [m]
b = _points("b")  # platform joints, platform frame [m]
n_a = _points("na")  # base joint axes, base frame (unit)
n_b = _points("nb")  # platform joint axes, platform frame (unit)
scale = sp.Symbol("scale", positive=True)  # size of the robot [m]
singular_tol = sp.Symbol("singular_tol", positive=True)


def _fields(points, field):
    return [Parameter(points[i][k], field, 3 * i + k) for i in range(LEGS) for k in range(3)]


PARAMETERS = (
    *_fields(a, "base_joints"),
    *_fields(b, "platform_joints"),
    *_fields(n_a, "base_axes"),
    *_fields(n_b, "platform_axes"),
    Parameter(scale, "scale"),
    Parameter(singular_tol, "singular_tol"),
)
