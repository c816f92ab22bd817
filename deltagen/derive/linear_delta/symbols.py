"""SymPy symbols of the linear delta and of the tripod (names become C identifiers).

Linear delta: tower i stands vertically at (tower_x_i, tower_y_i) (its radius and angle,
model/linear_delta.py); its carriage rides at height h_i, and an arm of length arm_i joins
the carriage C_i = (tower_x_i, tower_y_i, h_i) to the effector point p (Klipper's delta
kinematics: the effector offset is folded into the tower radius). |p - C_i| = arm_i.

Tripod (LinuxCNC tripodkins): base points A = (0, 0, 0), B = (b_x, 0, 0),
C = (c_x, c_y, 0); struts of lengths l_1, l_2, l_3 from A, B, C to the point p;
|p - A| = l_1, |p - B| = l_2, |p - C| = l_3. ``side`` (+1 or -1) picks the solution above
or below the base plane (tripodkins' forward flag: 0 above, 1 below).

Positions and rates of p reuse the rotary delta's x, y, z symbols (derive/delta/symbols.py):
the sphere-intersection stages assign them.
"""

import sympy as sp

# linear delta geometry (run-time parameters)
tower_x = sp.symbols("tower_x1:4", real=True)
tower_y = sp.symbols("tower_y1:4", real=True)
arm = sp.symbols("arm1:4", positive=True)
singular_tol = sp.Symbol("singular_tol", nonnegative=True)
length_scale = sp.Symbol("length_scale", positive=True)  # set-up: the thresholds' length

# linear delta joints: carriage heights and their rates
h = sp.symbols("h1:4", real=True)
hd = sp.symbols("hd1:4", real=True)
hdd = sp.symbols("hdd1:4", real=True)

# tripod geometry
b_x, c_x, c_y = sp.symbols("base_b_x base_c_x base_c_y", real=True)  # not a, b: the edges
side = sp.Symbol("side", real=True)

# tripod joints: strut lengths and their rates
strut = sp.symbols("l1:4", real=True)
ld = sp.symbols("ld1:4", real=True)
ldd = sp.symbols("ldd1:4", real=True)


def carriage(i: int, height=None) -> sp.Matrix:
    """C_i: the carriage joint of tower i at height h_i."""
    return sp.Matrix([tower_x[i], tower_y[i], h[i] if height is None else height])


def tripod_base(i: int) -> sp.Matrix:
    """A, B, C of tripodkins: the base points of struts 1, 2, 3."""
    return [sp.Matrix([0, 0, 0]), sp.Matrix([b_x, 0, 0]), sp.Matrix([c_x, c_y, 0])][i]
