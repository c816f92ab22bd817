"""SymPy symbols of the delta robot, named as in the delta report (Figure 4).

Geometry stays symbolic (r_a, r_b, l_a, l_b and cos/sin of theta_i), so one compiled core
serves every geometry at run time. The crank angles enter only through cos q_i and sin q_i,
which the generated C evaluates in separate vectorisable loops.
"""

import sympy as sp

# geometry (run-time parameters of the C core)
r_a, r_b, l_a, l_b = sp.symbols("r_a r_b l_a l_b", positive=True)
r = sp.Symbol("r", real=True)  # r = r_a - r_b (eq. (1))
cos_theta = sp.symbols("cos_theta1:4", real=True)
sin_theta = sp.symbols("sin_theta1:4", real=True)
singular_tol = sp.Symbol("singular_tol", nonnegative=True)
# per-chain geometry of an asymmetric robot (the kinematics use these; for a symmetric one
# every chain holds r = r_a - r_b, l_a and l_b)
chain_r = sp.symbols("chain_r1:4", real=True)  # r_i = r_a,i - r_b,i
chain_l_a = sp.symbols("chain_l_a1:4", positive=True)
chain_l_b = sp.symbols("chain_l_b1:4", positive=True)


def symmetric(expr):
    """``expr`` with every chain's r_i, l_a,i, l_b,i replaced by the symmetric r, l_a, l_b
    (for comparisons with the report's printed equations)."""
    rules = {}
    for i in range(3):
        rules.update({chain_r[i]: r, chain_l_a[i]: l_a, chain_l_b[i]: l_b})
    return expr.subs(rules) if hasattr(expr, "subs") else expr


# joint space, per point
q = sp.symbols("q1:4", real=True)
cos_q = sp.symbols("cos_q1:4", real=True)
sin_q = sp.symbols("sin_q1:4", real=True)
qd = sp.symbols("qd1:4", real=True)
qdd = sp.symbols("qdd1:4", real=True)

# task space, per point
x, y, z = sp.symbols("x y z", real=True)
xd, yd, zd = sp.symbols("xd yd zd", real=True)
xdd, ydd, zdd = sp.symbols("xdd ydd zdd", real=True)
p = sp.Matrix([x, y, z])
pd = sp.Matrix([xd, yd, zd])
pdd = sp.Matrix([xdd, ydd, zdd])

# time, for differentiating the constraints
t = sp.Symbol("t", real=True)


def sphere_centre(i: int, cq=None, sq=None) -> sp.Matrix:
    """S_i of eqs. (3)-(5): B_i shifted by r_b towards the platform."""
    cq = cos_q[i] if cq is None else cq
    sq = sin_q[i] if sq is None else sq
    radius = chain_r[i] + chain_l_a[i] * cq
    return sp.Matrix([radius * cos_theta[i], radius * sin_theta[i], -chain_l_a[i] * sq])


def constraint(i: int, px=x, py=y, pz=z, qi=None) -> sp.Expr:
    """f_i of eq. (1) with q_i as an angle: |C_i B_i|^2 - l_b^2 (chain i's own r, l_a,
    l_b)."""
    qi = q[i] if qi is None else qi
    radius = chain_r[i] + chain_l_a[i] * sp.cos(qi)
    return (
        (radius * cos_theta[i] - px) ** 2
        + (radius * sin_theta[i] - py) ** 2
        + (-chain_l_a[i] * sp.sin(qi) - pz) ** 2
        - chain_l_b[i] ** 2
    )


def on_unit_circle(expr) -> sp.Expr:
    """Use cos^2 + sin^2 = 1 for every theta_i and q_i (symbols cos_*, sin_*)."""
    rules = {}
    for c, sn in list(zip(cos_theta, sin_theta)) + list(zip(cos_q, sin_q)):
        rules[sn**2] = 1 - c**2
    return sp.expand(sp.expand(expr).subs(rules))
