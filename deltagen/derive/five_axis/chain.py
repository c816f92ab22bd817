"""The 5-axis machine's rigid chain, symbolic: rotations, the tool tip and tool axis in the
workpiece frame (direct kinematics) and their closed-form inverse, for each layout and
rotary pair of deltagen/model/five_axis.py (its docstring gives the frames and the chain).

The geometry stays symbolic (the parameter struct of the generated module): one compiled
module serves every machine; the layout and the rotary pair choose the function.

Inverse of the tool axis. In every layout d = R_z(c) R_tilt(tilt) e_z, so
d_z = cos(tilt) and the horizontal part of d is sin(tilt) R_z(c) u, with u = (0, -1) for A
(R_x(tilt) e_z = (0, -sin, cos)) and u = (1, 0) for B (R_y(tilt) e_z = (sin, 0, cos)).
With rho = |(d_x, d_y)| of the unit d, the two branches s = +1, -1 are
tilt = atan2(s rho, d_z) and c = atan2(s (u_x d_y - u_y d_x), s (u_x d_x + u_y d_y)), the
angle that turns s u onto (d_x, d_y). Where rho <= singular_tol the tool axis is parallel
to the C axis and c is undetermined: it keeps the previous value (no division by rho: its
cosine and sine are those of the previous c). Otherwise c takes the turn nearest the
previous c: c + 2 pi rint((c_prev - c) / (2 pi)) (C99 rint: to nearest, ties to even).
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.functions import Fabs, Ge, Le, NearestInteger
from deltagen.model.five_axis import LAYOUTS, ROTARIES

# joints and their cosines and sines
x, y, z, tilt, c = sp.symbols("x y z tilt c", real=True)
cos_tilt, sin_tilt, cos_c, sin_c = sp.symbols("cos_tilt sin_tilt cos_c sin_c", real=True)
# the inverse's inputs: tool tip and tool axis in W, the previous joints
px, py, pz, dx, dy, dz = sp.symbols("px py pz dx dy dz", real=True)
prev = sp.symbols("x_prev y_prev z_prev tilt_prev c_prev", real=True)
cos_c_prev, sin_c_prev = sp.symbols("cos_c_prev sin_c_prev", real=True)

# the geometry (parameter struct): points [m], tool length [m], tolerance
c_pivot = sp.Matrix(sp.symbols("c_pivot0:3", real=True))
tilt_pivot = sp.Matrix(sp.symbols("tilt_pivot0:3", real=True))
head_pivot = sp.Matrix(sp.symbols("head_pivot0:3", real=True))
spindle_offset = sp.Matrix(sp.symbols("spindle_offset0:3", real=True))
tool_length = sp.Symbol("tool_length", real=True)
singular_tol = sp.Symbol("singular_tol", positive=True)
tilt_min, tilt_max = sp.symbols("tilt_min tilt_max", real=True)

E_Z = sp.Matrix([0, 0, 1])

#: per tilt axis: the horizontal unit vector u with R_tilt(tilt) e_z = (sin u, cos)
U = {"A": (0, -1), "B": (1, 0)}


def rot_z(cos, sin) -> sp.Matrix:
    return sp.Matrix([[cos, -sin, 0], [sin, cos, 0], [0, 0, 1]])


def rot_tilt(axis: str, cos, sin) -> sp.Matrix:
    """R_x (A) or R_y (B) by the angle of cosine ``cos`` and sine ``sin``."""
    if axis == "A":
        return sp.Matrix([[1, 0, 0], [0, cos, -sin], [0, sin, cos]])
    return sp.Matrix([[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]])


def rotations(layout: str, rotary: str, ct, st, cc, sc):
    """(R_hc, R_ht, R_tc, R_tt): C and tilt in the head or under the table, identity
    where the layout has no such axis (model/five_axis.py)."""
    if layout not in LAYOUTS or rotary not in ROTARIES:
        raise ValueError(f"no machine {layout} {rotary}")
    eye = sp.eye(3)
    Rc, Rt = rot_z(cc, sc), rot_tilt(rotary[0], ct, st)
    if layout == "table-table":
        return eye, eye, Rc, Rt
    if layout == "head-head":
        return Rc, Rt, eye, eye
    return eye, Rt, Rc, eye  # table-head


def forward(layout: str, rotary: str, joints, ct, st, cc, sc):
    """Tool tip w and tool axis d in the workpiece frame (3-vectors)."""
    R_hc, R_ht, R_tc, R_tt = rotations(layout, rotary, ct, st, cc, sc)
    d_m = R_hc * R_ht * E_Z
    m = sp.Matrix(joints) + R_hc * (head_pivot + R_ht * spindle_offset) - tool_length * d_m
    w = c_pivot + R_tc * (tilt_pivot - c_pivot + R_tt * (m - tilt_pivot))
    return w, R_tc * R_tt * d_m


def joints_of(layout: str, rotary: str, w, ct, st, cc, sc):
    """x, y, z that put the tool tip at w for the rotary angles of the given cosines and
    sines: the chain of ``forward`` undone (rotations transposed)."""
    R_hc, R_ht, R_tc, R_tt = rotations(layout, rotary, ct, st, cc, sc)
    d_m = R_hc * R_ht * E_Z
    m = tilt_pivot + R_tt.T * (c_pivot - tilt_pivot + R_tc.T * (sp.Matrix(w) - c_pivot))
    return m - R_hc * (head_pivot + R_ht * spindle_offset) + tool_length * d_m


def _larger(a, b):
    """max(a, b) as a select (C fmax keeps NaN rules that stop gcc's vectoriser; a NaN
    input is INVALID anyway)."""
    return sp.Piecewise((a, Ge(a, b)), (b, True))


def unit_direction():
    """(e, zero, assignments): the direction scaled by its largest component, then
    normalised (no overflow for large d); ``zero`` is True where d = 0 (no direction).
    Each select and each divisor is a symbol of its own: a division inside a select is
    control flow to gcc, and CSE would square d before scaling it."""
    names = "d_xy_max d_max d_max_safe inv_max d_norm d_norm_safe sx sy sz ex ey ez"
    d_xy, d_max, d_safe, inv_max, norm, norm_safe, sx, sy, sz, ex, ey, ez = sp.symbols(
        names, real=True
    )
    zero = sp.Symbol("zero_direction")
    assignments = (
        (d_xy, _larger(Fabs(dx), Fabs(dy))),
        (d_max, _larger(d_xy, Fabs(dz))),
        (zero, Le(d_max, 0)),
        (d_safe, sp.Piecewise((1, zero), (d_max, True))),
        (inv_max, 1 / d_safe),
        (sx, dx * inv_max),
        (sy, dy * inv_max),
        (sz, dz * inv_max),
        (norm, sp.sqrt(sx**2 + sy**2 + sz**2)),
        (norm_safe, sp.Piecewise((1, zero), (norm, True))),
        (ex, sx / norm_safe),
        (ey, sy / norm_safe),
        (ez, sz / norm_safe),
    )
    return (ex, ey, ez), zero, assignments


def branch(layout: str, rotary: str, e, rho, singular, sign: int, tag: str):
    """One rotary branch (sign +1: sin(tilt) >= 0, -1: <= 0): its assignments and the
    symbols of x, y, z, tilt, c."""
    ex, ey, ez = e
    ux, uy = U[rotary[0]]
    t, cr, cw, co, cc, sc, rho_safe = sp.symbols(
        f"tilt_{tag} c_raw_{tag} c_turn_{tag} c_{tag} cos_c_{tag} sin_c_{tag} rho_safe_{tag}",
        real=True,
    )
    yy = sign * (ux * ey - uy * ex)
    xx = sign * (ux * ex + uy * ey)
    two_pi = 2 * sp.pi
    assignments = [
        (t, sp.atan2(sign * rho, ez)),
        (cr, sp.atan2(yy, xx)),
        (cw, cr + two_pi * NearestInteger((prev[4] - cr) / two_pi)),
        (co, sp.Piecewise((prev[4], singular), (cw, True))),
        (rho_safe, sp.Piecewise((1, singular), (rho, True))),
        (cc, sp.Piecewise((cos_c_prev, singular), (xx / rho_safe, True))),
        (sc, sp.Piecewise((sin_c_prev, singular), (yy / rho_safe, True))),
    ]
    xyz = joints_of(layout, rotary, (px, py, pz), ez, sign * rho, cc, sc)
    names = sp.symbols(f"x_{tag} y_{tag} z_{tag}", real=True)
    assignments += list(zip(names, xyz))
    return tuple(assignments), (*names, t, co)
