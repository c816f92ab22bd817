"""The report's printed equations (deltagen.derive.delta.printed) against deltagen's derivation.

Each test names the equation(s) it checks. Where the print is wrong, the test ASSERTS the
disagreement (so the erratum stays pinned) and shows the corrected form agrees; numeric
counter-examples use finite differences of the constraint (1) or of deltagen's fk.
docs/errata.md lists the results.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from helpers import REPO

from deltagen import DeltaRobot
from deltagen.derive.delta import printed as P
from deltagen.derive.delta import symbols as s
from deltagen.derive.delta.acceleration import constraint_acceleration
from deltagen.derive.delta.fk import report_elimination, report_linear_coefficients
from deltagen.derive.delta.ik import crank_equation
from deltagen.derive.delta.velocity import constraint_rate
from deltagen.model.delta import DeltaGeometry


def _symmetric(derivation):
    """The derivations use each chain's own r_i, l_a,i, l_b,i (an asymmetric robot); the
    report's printed equations are for equal chains: compare with those substituted."""

    def symmetric_derivation(*args, **kwargs):
        out = derivation(*args, **kwargs)
        return tuple(s.symmetric(o) for o in out) if isinstance(out, tuple) else s.symmetric(out)

    return symmetric_derivation


constraint_rate = _symmetric(constraint_rate)
constraint_acceleration = _symmetric(constraint_acceleration)
crank_equation = _symmetric(crank_equation)

CHAINS = (0, 1, 2)
DEFAULT = DeltaGeometry.default()
SEED = REPO.parent / "shared" / "seeds" / "000_e75353eb064fd002.txt"


def zero(expr) -> bool:
    """expr == 0 as a rational function, using cos^2 + sin^2 = 1 for theta_i and q_i
    (symbols.on_unit_circle, then the remainder modulo sin^2 + cos^2 - 1, which also
    reduces odd powers of sin that on_unit_circle leaves alone)."""
    expr = sp.cancel(sp.together(sp.expand(expr)))
    num, _ = sp.fraction(expr)
    num = s.on_unit_circle(num)
    for c, sn in list(zip(s.cos_theta, s.sin_theta)) + list(zip(s.cos_q, s.sin_q)):
        if num.has(sn):
            num = sp.rem(num, sn**2 + c**2 - 1, sn)
    return sp.expand(num) == 0


def numeric_subs(geom, i=None):
    """Geometry values for the symbols r, r_a, r_b, l_a, l_b, cos/sin theta_i."""
    d = {s.r: geom.r, s.r_a: geom.r_a, s.r_b: geom.r_b, s.l_a: geom.l_a, s.l_b: geom.l_b}
    for k, th in enumerate(geom.theta):
        d[s.cos_theta[k]] = math.cos(th)
        d[s.sin_theta[k]] = math.sin(th)
    return d


def constraint_numeric(geom, i, p, qi):
    """f_i of eq. (1) from the points B_i and C_i of section 2.1 (numpy, independent)."""
    th = geom.theta[i]
    B = np.array(
        [
            (geom.r_a + geom.l_a * math.cos(qi)) * math.cos(th),
            (geom.r_a + geom.l_a * math.cos(qi)) * math.sin(th),
            -geom.l_a * math.sin(qi),
        ]
    )
    C = np.array([p[0] + geom.r_b * math.cos(th), p[1] + geom.r_b * math.sin(th), p[2]])
    return float(np.dot(B - C, B - C) - geom.l_b**2)


def centres_numeric(geom, q):
    q = np.asarray(q, dtype=float)[:3]
    th = np.asarray(geom.theta)
    R = geom.r + geom.l_a * np.cos(q)
    return np.column_stack([R * np.cos(th), R * np.sin(th), -geom.l_a * np.sin(q)])


def geom_deg(theta_deg, r_a=0.2, r_b=0.045, l_a=0.35, l_b=0.8):
    return DeltaGeometry(
        r_a=r_a, r_b=r_b, l_a=l_a, l_b=l_b, theta=tuple(math.radians(t) for t in theta_deg)
    )


def trajectory(n):
    """Points, velocities, accelerations of eqs. (40)-(42) on a grid of n points in [0, 10] s."""
    t = np.linspace(0.0, P.TRAJECTORY_DURATION, n)
    funcs = []
    for e in (P.eq40_x, P.eq41_y, P.eq42_z):
        funcs.append([sp.lambdify(P.T, sp.diff(e, P.T, k), "numpy") for k in range(3)])
    out = [np.column_stack([np.broadcast_to(f[k](t), t.shape) for f in funcs]) for k in range(3)]
    return t, *out


# ---------------------------------------------------------------- (1)-(5) geometry


@pytest.mark.parametrize("i", CHAINS)
def test_eq1_constraint_and_CB_vector(i):
    q = s.q[i]
    printed = P.eq1_constraint(i, sp.cos(q), sp.sin(q))
    assert sp.expand(printed - s.symmetric(s.constraint(i))) == 0
    # the two printed forms of C_i B_i agree with r = r_a - r_b, and |C_i B_i|^2 - l_b^2 = (1)
    a = P.vector_CB(i, first_form=True)
    b = P.vector_CB(i).subs(s.r, s.r_a - s.r_b)
    assert sp.expand(a - b) == sp.zeros(3, 1)
    assert sp.expand((P.vector_CB(i).T * P.vector_CB(i))[0] - s.l_b**2 - P.eq1_constraint(i)) == 0


@pytest.mark.parametrize("i", CHAINS)
def test_eq2_to_5_sphere_centres(i):
    centre = P.eq3_5_centre(i)
    assert sp.expand(centre - s.symmetric(s.sphere_centre(i))) == sp.zeros(3, 1)
    sphere = P.eq2_sphere(i).subs(dict(zip(P.S[i], centre)))
    assert sp.expand(sphere - P.eq1_constraint(i)) == 0


# --------------------------------------------------------------- (6)-(15) the planes


def test_eq6_to_15_linear_coefficients():
    (du, dv, centres) = report_linear_coefficients()
    assert [list(c) for c in centres] == [list(c) for c in P.S]
    U, V = P.eq8_15_uv()
    for printed, derived in zip(U + V, du + dv):
        assert sp.expand(printed - derived) == 0
    # (6), (7): varsigma_1 - varsigma_k is exactly the printed plane
    e1, e2 = P.eq6_7_planes()
    subs = dict(zip(P.u + P.v, U + V))
    assert sp.expand(P.eq2_sphere(0) - P.eq2_sphere(1) - e1.subs(subs)) == 0
    assert sp.expand(P.eq2_sphere(0) - P.eq2_sphere(2) - e2.subs(subs)) == 0


# ------------------------------------------------------------ (16)-(21) elimination


@pytest.fixture(scope="module")
def elimination():
    """w_1..w_7 of eqs. (16)-(25) derived once for the module (an uncached SymPy solve)."""
    return report_elimination()


def test_eq18_19_agree_and_divisor_is_vertical_centre_plane(elimination):
    d = elimination
    w1, w2, _, _ = P.eq18_21_w()
    assert zero(w1 - d["w1"]) and zero(w2 - d["w2"])
    # divisor v1 u2 - u1 v2 = -4 e_z, e = (S2 - S1) x (S3 - S1): it vanishes only when the
    # plane of the sphere centres is vertical (then z cannot parametrise the line (16)-(17)).
    U, V = P.eq8_15_uv()
    e = (P.S[1] - P.S[0]).cross(P.S[2] - P.S[0])
    assert sp.expand((V[0] * U[1] - U[0] * V[1]) + 4 * e[2]) == 0
    # default 0/120/240 layout, R_i = r + l_a cos q_i: e_z = sqrt(3)/2 (R1 R2 + R2 R3 + R3 R1),
    # which needs some R_i <= 0, i.e. cos q_i <= -r / l_a (q_i >= 116 deg for the default robot)
    R = sp.symbols("R1:4", real=True)
    th = (0, 2 * sp.pi / 3, 4 * sp.pi / 3)
    Sn = [sp.Matrix([R[k] * sp.cos(th[k]), R[k] * sp.sin(th[k]), P.Sz[k]]) for k in CHAINS]
    ez = (Sn[1] - Sn[0]).cross(Sn[2] - Sn[0])[2]
    assert sp.expand(ez - sp.sqrt(3) / 2 * (R[0] * R[1] + R[1] * R[2] + R[2] * R[0])) == 0


def test_eq20_21_equivalent_where_v2_nonzero(elimination):
    d = elimination
    _, _, w3, w4 = P.eq18_21_w_substituted()
    assert zero(w3 - d["w3"]) and zero(w4 - d["w4"])


def test_eq20_21_undefined_at_v2_zero(elimination):
    """At v2 = 0 the printed (20), (21) are 0/0, the derived w3, w4 stay finite."""
    d = elimination
    u, v = P.u, P.v
    w1, w2, w3, w4 = P.eq18_21_w()
    at = {v[1]: 0}
    w1_0, w2_0 = w1.subs(at), w2.subs(at)
    # evaluated in the printed order: w1, w2 first, then (20), (21)
    num3 = sp.numer(sp.together(w3)).subs(at).subs({P.w[0]: w1_0})
    num4 = sp.numer(sp.together(w4)).subs(at).subs({P.w[1]: w2_0})
    assert sp.simplify(num3) == 0 and sp.simplify(num4) == 0  # numerators vanish too
    assert w3.subs(at).subs({P.w[0]: w1_0}) is sp.nan
    assert w4.subs(at).subs({P.w[1]: w2_0}) is sp.nan
    # the derived values there (Cramer, divisor v1 u2 - u1 v2 = -4 e_z):
    assert sp.simplify(d["w3"].subs(at) - (u[0] * v[2] - v[0] * u[2]) / (v[0] * u[1])) == 0
    assert sp.simplify(d["w4"].subs(at) - (u[0] * v[3] - v[0] * u[3]) / (v[0] * u[1])) == 0


@pytest.mark.parametrize(
    "theta",
    [
        # drives at 0, 90, 180 deg: S_y1 = S_y3 = 0 for every pose
        (0, sp.pi / 2, sp.pi),
        # drives at -30, 90, 210 deg (a regular 120-deg layout, numbered differently):
        # v2 = l_a (cos q1 - cos q3), zero whenever q3 = +-q1, e.g. at home q = 0
        (-sp.pi / 6, sp.pi / 2, 7 * sp.pi / 6),
        # the default 0, 120, 240 deg: v2 = -sqrt(3) (r + l_a cos q3), zero only for
        # cos q3 = -r / l_a (q3 = 116 deg for the default robot, far outside the workspace)
        (0, 2 * sp.pi / 3, 4 * sp.pi / 3),
    ],
    ids=["0-90-180", "-30-90-210", "0-120-240"],
)
def test_v2_vanishes_for_real_drive_arrangements(theta):
    th_subs = {}
    for k, th in enumerate(theta):
        th_subs[s.cos_theta[k]] = sp.cos(th)
        th_subs[s.sin_theta[k]] = sp.sin(th)
    v2 = 2 * P.eq3_5_centre(2)[1] - 2 * P.eq3_5_centre(0)[1]  # (13) with (4)
    v2 = sp.expand(v2.subs(th_subs))
    expected = {
        sp.pi: 0,
        7 * sp.pi / 6: s.l_a * (s.cos_q[0] - s.cos_q[2]),
        4 * sp.pi / 3: -sp.sqrt(3) * (s.r + s.l_a * s.cos_q[2]),
    }[theta[2]]
    assert sp.expand(v2 - expected) == 0


@pytest.mark.parametrize(
    "theta_deg, q",
    [((0, 90, 180), (0.1, 0.3, 0.5)), ((330, 90, 210), (0.3, 0.1, -0.3))],
)
def test_fk_regular_where_printed_chain_fails(theta_deg, q):
    """v2 = 0 (up to rounding) at a regular pose: the printed chain (3)-(27) in float64
    is off by centimetres to decimetres, deltagen's fk is exact."""
    geom = geom_deg(theta_deg)
    robot = DeltaRobot.from_geometry(geom)
    q = np.array(q)
    p = robot.fk(q)
    S = centres_numeric(geom, q)
    D = p - S
    assert np.abs((D**2).sum(axis=1) - geom.l_b**2).max() < 1e-14  # on all three spheres
    assert np.allclose(p, DeltaRobot.from_geometry(geom, "reference").fk(q), atol=1e-14)
    # regular: |det(p - S_i)| / l_b^3 and the crank terms far from zero, finite Jacobian
    assert abs(np.linalg.det(D)) / geom.l_b**3 > 0.5
    for i in CHAINS:
        _, jq = constraint_rate(i)
        val = float(
            jq.subs(numeric_subs(geom)).subs(
                {
                    s.x: p[0],
                    s.y: p[1],
                    s.z: p[2],
                    s.cos_q[i]: math.cos(q[i]),
                    s.sin_q[i]: math.sin(q[i]),
                }
            )
        )
        assert abs(val) / (geom.l_a * geom.l_b) > 0.2
    assert np.linalg.cond(robot.jacobian(q)) < 5
    # the lower intersection: the mirror point across the centre plane lies higher
    e = np.cross(S[1] - S[0], S[2] - S[0])
    mirror = p - 2 * np.dot(p - S[0], e) / np.dot(e, e) * e
    assert mirror[2] > p[2]
    # the printed chain
    pp, det = P.evaluate_fk(geom.r, geom.l_a, geom.l_b, geom.theta, q)
    assert abs(det["v"][1]) < 1e-15
    assert np.abs(pp - p).max() > 0.05


def test_printed_fk_chain_works_on_default_robot_trajectory():
    """Default 0/120/240 layout: v2 = -sqrt(3) (r + l_a cos q3) != 0 on the trajectory, so
    the printed chain (3)-(27) with the min root (26) agrees with deltagen's fk."""
    _, pos, _, _ = trajectory(2001)
    robot = DeltaRobot.default()
    q = robot.ik(pos)
    p = robot.fk(q)
    printed = np.array(
        [P.evaluate_fk(DEFAULT.r, DEFAULT.l_a, DEFAULT.l_b, DEFAULT.theta, qq)[0] for qq in q]
    )
    assert np.abs(printed - p).max() < 1e-12


# ---------------------------------------------------------- (22)-(27) the quadratic


def test_eq22_to_25_quadratic(elimination):
    d = elimination
    w5, w6, w7 = P.eq23_25_w()
    assert sp.expand(P.eq22_quadratic() - (w5 * s.z**2 + w6 * s.z + w7)) == 0
    for printed, derived in zip((w5, w6, w7), (d["w5"], d["w6"], d["w7"])):
        assert sp.expand(printed - derived) == 0
    # (22) is varsigma_3 of (2) with (16), (17) inserted
    x16, y17 = P.eq16_17_line()
    assert sp.expand(P.eq22_quadratic() - P.eq2_sphere(2, x16, y17)) == 0


def test_eq26_min_root_is_the_lower_intersection():
    """w5 = w1^2 + w3^2 + 1 >= 1 > 0, so min(...) is -(w6 + sqrt(...)) / (2 w5); the two
    roots are the two mirror images across the centre plane, the min the lower one."""
    w5, _, _ = P.eq23_25_w()
    assert sp.ask(sp.Q.positive(w5))  # real w1, w3
    lo, hi = P.eq26_roots()
    assert sp.expand(hi - lo - sp.sqrt(P.w[5] ** 2 - 4 * P.w[4] * P.w[6]) / P.w[4]) == 0
    rng = np.random.default_rng(7)
    robot = DeltaRobot.default()
    for q in rng.uniform(-0.3, 1.0, size=(20, 3)):
        p, det = P.evaluate_fk(DEFAULT.r, DEFAULT.l_a, DEFAULT.l_b, DEFAULT.theta, q)
        w1, w2, w3, w4, w5n, w6n, w7n = det["w"]
        root = math.sqrt(w6n**2 - 4 * w5n * w7n)
        z_hi = (-w6n + root) / (2 * w5n)
        upper = np.array([w1 * z_hi + w2, w3 * z_hi + w4, z_hi])
        S = det["S"]
        e = np.cross(S[1] - S[0], S[2] - S[0])
        assert np.dot(p - S[0], e) * np.dot(upper - S[0], e) < 0  # opposite sides
        assert upper[2] > p[2]
        p27 = P.eq27_position(lo).subs(dict(zip(P.w, det["w"])))  # (26), (27) symbolically
        assert np.allclose(np.array(p27, dtype=float).ravel(), p, atol=1e-13)
        assert np.allclose(p, robot.fk(q), atol=1e-13)


# ----------------------------------------------------- (28)-(35) velocity level


def _printed_qd_coefficient(i):
    return sp.expand(P.eq28_df_dt(i)).coeff(s.qd[i])


@pytest.mark.parametrize("i", CHAINS)
def test_eq31_33_Jp_rows_agree(i):
    jp_row, _ = constraint_rate(i)
    assert all(zero(a - b) for a, b in zip(P.eq31_33_Jp_row(i), jp_row))
    df = sp.expand(P.eq28_df_dt(i))
    for k, rate in enumerate((s.xd, s.yd, s.zd)):
        assert zero(df.coeff(rate) - jp_row[k])


@pytest.mark.parametrize("i", CHAINS)
def test_eq28_r_term_sign_is_wrong(i):
    """ERRATUM (28): the qdot_i coefficient has -2 l_a r sin q_i, printed +2 l_a r sin q_i."""
    _, jq = constraint_rate(i)
    derived = -jq  # d f_i/dt = J_p pdot + c qdot_i with c = -J_q,ii
    printed = _printed_qd_coefficient(i)
    assert not zero(printed - derived)  # the print disagrees ...
    assert zero(printed - derived - 4 * s.l_a * s.r * s.sin_q[i])  # ... by exactly 4 l_a r sin q_i
    corrected = printed - 4 * s.l_a * s.r * s.sin_q[i]
    assert zero(corrected - derived)
    # independent route: c = d f_i / d q_i = -E sin q + F cos q (crank equation of the IK)
    E, F, _ = crank_equation(i)
    assert zero(derived - (-E * s.sin_q[i] + F * s.cos_q[i]))


@pytest.mark.parametrize("i", CHAINS)
def test_eq34_r_term_sign_is_wrong_and_consistent_with_eq28(i):
    """ERRATUM (34): J_q,ii = -2 l_a (cos q z + sin q sin th y + sin q cos th x - r sin q)."""
    _, jq = constraint_rate(i)
    printed = P.eq34_Jq_ii(i)
    assert not zero(printed - jq)
    assert zero(printed - jq + 4 * s.l_a * s.r * s.sin_q[i])
    corrected = (
        -2
        * s.l_a
        * (
            s.cos_q[i] * s.z
            + s.sin_q[i] * s.sin_theta[i] * s.y
            + s.sin_q[i] * s.cos_theta[i] * s.x
            - s.r * s.sin_q[i]
        )
    )
    assert zero(corrected - jq)
    assert zero(printed + _printed_qd_coefficient(i))  # (34) = -(28): the same slip twice
    assert P.eq35_Jq()[0, 1] == 0 and P.eq35_Jq()[2, 0] == 0  # (35)


def test_eq28_counter_example_finite_differences():
    """Along p(t) = p0 + pd t, q_i(t) = q0 + qd t (default robot, chain 2 at 120 deg) the
    time derivative of f_i of eq. (1) by central differences matches the derived (28),
    not the printed one: the gap is 4 l_a r sin q0 qd."""
    g, i = DEFAULT, 1
    p0, pd = np.array([0.05, -0.1, -0.7]), np.array([0.3, -0.2, 0.5])
    q0, qd = 0.5, 1.3
    h = 1e-5
    fd = (
        constraint_numeric(g, i, p0 + h * pd, q0 + h * qd)
        - constraint_numeric(g, i, p0 - h * pd, q0 - h * qd)
    ) / (2 * h)
    vals = numeric_subs(g)
    vals.update(
        {
            s.x: p0[0],
            s.y: p0[1],
            s.z: p0[2],
            s.xd: pd[0],
            s.yd: pd[1],
            s.zd: pd[2],
            s.qd[i]: qd,
            s.cos_q[i]: math.cos(q0),
            s.sin_q[i]: math.sin(q0),
        }
    )
    printed = float(P.eq28_df_dt(i).subs(vals))
    jp_row, jq = constraint_rate(i)
    derived = float(((jp_row * s.pd)[0] - jq * s.qd[i]).subs(vals))
    gap = 4 * g.l_a * g.r * math.sin(q0) * qd
    assert abs(derived - fd) < 1e-8
    assert abs(printed - fd - gap) < 1e-8
    assert gap > 0.13  # 0.13525: fd = derived = -0.83879, printed = -0.70355


def test_eq30_34_counter_example_platform_velocity():
    """pdot from J_p pdot = J_q qdot with the printed (34) is off by ~0.1 m/s; with the
    corrected (34) it matches finite differences of deltagen's fk and fk_vel."""
    g = DEFAULT
    robot = DeltaRobot.default()
    q = np.array([0.4, 0.2, 0.7])
    qd = np.array([1.0, -2.0, 0.5])
    h = 1e-6
    fd = (robot.fk(q + h * qd) - robot.fk(q - h * qd)) / (2 * h)
    p = robot.fk(q)
    vals = numeric_subs(g)
    vals.update({s.x: p[0], s.y: p[1], s.z: p[2]})
    for i in CHAINS:
        vals.update({s.cos_q[i]: math.cos(q[i]), s.sin_q[i]: math.sin(q[i])})
    Jp = np.array(sp.Matrix.vstack(*[P.eq31_33_Jp_row(i) for i in CHAINS]).subs(vals), dtype=float)
    Jq_printed = np.diag([float(P.eq34_Jq_ii(i).subs(vals)) for i in CHAINS])
    Jq_derived = np.diag([float(constraint_rate(i)[1].subs(vals)) for i in CHAINS])
    pd_printed = np.linalg.solve(Jp, Jq_printed @ qd)
    pd_derived = np.linalg.solve(Jp, Jq_derived @ qd)
    _, pd_fk = robot.fk_vel(q, qd)
    assert np.abs(pd_derived - fd).max() < 1e-8
    assert np.abs(pd_fk - fd).max() < 1e-8
    # fd = (-0.62519, 0.76946, 0.22731) m/s, printed (-0.56403, 0.67485, 0.22527) m/s
    assert np.abs(pd_printed - fd).max() > 0.09  # 0.0946 m/s, 9 % of |pd| = 1.017 m/s


# ------------------------------------------------- (36)-(39) acceleration level


@pytest.mark.parametrize("i", CHAINS)
def test_eq36_37_39_agree(i):
    jp_row, h = constraint_acceleration(i)
    assert zero(P.eq39_h(i) - h)
    assert zero(P.eq36_d2f_dt2(i) - ((jp_row * s.pdd)[0] - h))
    assert all(zero(a - b) for a, b in zip(P.eq31_33_Jp_row(i), jp_row))


def _total_time_derivative(expr, i):
    """d/dt of an expression in x, y, z, xd, yd, zd, q_i (angle) and qd_i."""
    q = s.q[i]
    chain = [
        (s.x, s.xd),
        (s.y, s.yd),
        (s.z, s.zd),
        (s.xd, s.xdd),
        (s.yd, s.ydd),
        (s.zd, s.zdd),
        (q, s.qd[i]),
        (s.qd[i], s.qdd[i]),
    ]
    out = sum(sp.diff(expr, a) * b for a, b in chain)
    return sp.expand(out).subs({sp.cos(q): s.cos_q[i], sp.sin(q): s.sin_q[i]})


@pytest.mark.parametrize("i", CHAINS)
def test_eq36_is_the_derivative_of_corrected_not_printed_eq28(i):
    """(36) carries -s_i r, i.e. it differentiates the CORRECT (28) (-2 l_a r sin q_i);
    d/dt of the printed (28) would give +s_i r. The report is inconsistent with itself."""
    q = s.q[i]
    printed28 = P.eq28_df_dt(i, sp.cos(q), sp.sin(q))
    corrected28 = printed28 - 4 * s.l_a * s.r * sp.sin(q) * s.qd[i]
    target = P.eq36_d2f_dt2(i)
    assert zero(_total_time_derivative(corrected28, i) - target)
    diff = _total_time_derivative(printed28, i) - target
    assert zero(diff - 2 * s.r * P.eq37_s(i))


def test_eq38_39_counter_check_finite_differences():
    """pddot from J_p pddot = h (printed (31)-(33), (39)) matches second differences of
    deltagen's fk along q(t) = q0 + qd t + qdd t^2 / 2."""
    g = DEFAULT
    robot = DeltaRobot.default()
    q0, qd, qdd = np.array([0.4, 0.2, 0.7]), np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, -4.0])
    h = 1e-4
    path = [robot.fk(q0 + k * h * qd + 0.5 * (k * h) ** 2 * qdd) for k in (-1, 0, 1)]
    pdd_fd = (path[0] - 2 * path[1] + path[2]) / h**2
    p, pd, pdd_fk = robot.fk_acc(q0, qd, qdd)
    vals = numeric_subs(g)
    vals.update({s.x: p[0], s.y: p[1], s.z: p[2], s.xd: pd[0], s.yd: pd[1], s.zd: pd[2]})
    for i in CHAINS:
        vals.update(
            {
                s.cos_q[i]: math.cos(q0[i]),
                s.sin_q[i]: math.sin(q0[i]),
                s.qd[i]: qd[i],
                s.qdd[i]: qdd[i],
            }
        )
    Jp = np.array(sp.Matrix.vstack(*[P.eq31_33_Jp_row(i) for i in CHAINS]).subs(vals), dtype=float)
    hv = np.array([float(P.eq39_h(i).subs(vals)) for i in CHAINS])
    pdd_printed = np.linalg.solve(Jp, hv)
    assert np.abs(pdd_printed - pdd_fd).max() < 1e-4
    assert np.abs(pdd_fk - pdd_fd).max() < 1e-4


# ----------------------------------------------------------- (43) the fourth axis


def test_eq43_fourth_axis_identity():
    assert P.eq43_identity == sp.eye(3)
    robot = DeltaRobot.default()
    q = np.array([0.3, 0.5, 0.1, -1.2])
    qd = np.array([0.5, -0.4, 0.2, 2.5])
    qdd = np.array([1.0, 0.5, -2.0, -7.0])
    p, pd, pdd = robot.fk_acc(q, qd, qdd)
    assert (p[3], pd[3], pdd[3]) == (q[3], qd[3], qdd[3])


# ---------------------------------------------------- appendix B MAXIMA script


def test_maxima_script_y_line_is_a_typo():
    """`y: w[2]*z + w[3]` clashes with `x: w[1]*z + w[2]`; the script's own
    solve(eps2, y) gives slope (20) and intercept (21), i.e. y = w3 z + w4 (eq. (17)), and
    only that reproduces the printed (23)-(25)."""
    v1, v2, v3, v4 = P.v
    y_solved = sp.solve(v1 * P.maxima_x + v2 * s.y + v3 * s.z + v4, s.y)[0]
    _, _, w3, w4 = P.eq18_21_w()
    assert sp.expand(y_solved - (w3 * s.z + w4)) == 0
    printed = P.eq23_25_w()
    x16, y17 = P.eq16_17_line()
    assert x16 == P.maxima_x
    assert P.maxima_y != y17
    with_script = sp.Poly(sp.expand(P.eq2_sphere(2, P.maxima_x, P.maxima_y)), s.z).all_coeffs()
    with_eq17 = sp.Poly(sp.expand(P.eq2_sphere(2, x16, y17)), s.z).all_coeffs()
    assert [sp.expand(a - b) for a, b in zip(with_eq17, printed)] == [0, 0, 0]
    assert sp.expand(with_script[0] - printed[0]) != 0  # w1^2 + w2^2 + 1 vs w1^2 + w3^2 + 1


def test_eq29_is_a_duplicated_line_of_eq28():
    if not SEED.exists():
        pytest.skip(f"the delta report is not at {SEED} (docs/sources.md)")
    text = SEED.read_text(encoding="utf-8")
    line29 = next(ln for ln in text.splitlines() if ln.rstrip().endswith("(29)$$"))
    fragment = line29.strip("$ ").rsplit(r"\quad", 1)[0].strip()
    block28 = text[text.index(r"\frac{df_i}{dt}") : text.index("(28)")]
    assert fragment.lstrip("+ ").replace(" ", "") in block28.replace(" ", "")


# --------------------------------------------------- (40)-(42) validation claims


def test_trajectory_peaks_versus_claims():
    """Claimed: speeds up to 8 m/s (holds: peak 7.856 m/s) and accelerations up to
    24 m/s^2 (wrong: peak 244.33 m/s^2, about 10 times more)."""
    t, pos, vel, acc = trajectory(1_000_001)
    speed = np.linalg.norm(vel, axis=1)
    accel = np.linalg.norm(acc, axis=1)
    assert speed.max() == pytest.approx(7.8556, abs=1e-3)
    assert speed.max() <= P.CLAIMED_MAX_SPEED
    assert np.abs(vel).max(axis=0) == pytest.approx([7.8540, 7.8540, 3.1416], abs=1e-3)
    assert accel.max() == pytest.approx(244.33, abs=0.02)
    early, late = t < 5, t >= 5  # (40)/(41) mirror each other: peaks at t = 0.0498 and 9.9502 s
    assert t[np.argmax(np.where(early, accel, 0))] == pytest.approx(0.0498, abs=1e-3)
    assert t[np.argmax(np.where(late, accel, 0))] == pytest.approx(9.9502, abs=1e-3)
    assert np.abs(acc).max(axis=0) == pytest.approx([244.33, 244.33, 98.696], abs=0.02)
    assert accel.max() > 10 * P.CLAIMED_MAX_ACCELERATION
    assert pos[:, 2].min() == pytest.approx(-0.8556) and pos[:, 2].max() == pytest.approx(-0.6556)


def test_trajectory_round_trip_within_precision():
    """The claim 'differences between inverse and direct kinematics within the numerical
    precision' holds for deltagen's default robot: ik -> fk over the whole trajectory."""
    _, pos, _, _ = trajectory(200_001)
    robot = DeltaRobot.default()
    q = robot.ik(pos)
    err = np.abs(robot.fk(q) - pos).max()
    assert err < 1e-14  # 6e-16 m
