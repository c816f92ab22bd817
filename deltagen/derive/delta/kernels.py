"""The five batched kernels of the delta core, assembled from the derivations:
fk (eqs. (2)-(27)), fk_vel (+ (28)-(35)), fk_acc (+ (36)-(39)), jacobian (eq. (30)) and
ik (closed-form inverse), each with the fourth axis of eq. (43) as a pass-through column.

Status rules (identical in the numpy reference, see deltagen/status.py):
  INVALID      an input of the row is NaN or infinite
  SINGULAR     centres S_i collinear: |e| < tol l_b^2  (no output)
  UNREACHABLE  the spheres do not meet: h^2 < 0          (no output)
  SINGULAR     |det D| < tol l_b^3, D rows p - S_i        (p given, derivatives NaN)
  (ik) UNREACHABLE if a chain's rho^2 - G^2 < 0, or if the target lies in the other assembly
       mode (det D e_z > 0 with |det D| > tol l_b^3: fk would return the mirror point);
       SINGULAR if rho^2 - G^2 < (2 tol l_a l_b)^2, or if |det D| <= tol l_b^3 (the parallel
       singularity, where fk(q) is SINGULAR too; centres collinear included: fk has no p there)
  INVALID      (every kernel, added by codegen.lowering.guard_outputs) an output the status
               gives is not finite: finite inputs that overflow; the row is all NaN
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from deltagen import status as st
from deltagen.derive.delta import acceleration as acc
from deltagen.derive.delta import calibration as cal
from deltagen.derive.delta import dynamics as dyn
from deltagen.derive.delta import fk as fkd
from deltagen.derive.delta import ik as ikd
from deltagen.derive.delta import inverse_rates as irs
from deltagen.derive.delta import symbols as s
from deltagen.derive.delta import velocity as vel
from deltagen.derive.functions import AllFinite
from deltagen.derive.kernel import Angle, Kernel, Parameter, Port, Stage

collinear_limit, det_limit, jq_limit = sp.symbols(
    "collinear_limit det_limit jq_limit", positive=True
)

PARAMETERS = (
    Parameter(s.r_a, "r_a"),
    Parameter(s.r_b, "r_b"),
    Parameter(s.l_a, "l_a"),
    Parameter(s.l_b, "l_b"),
    *(Parameter(s.cos_theta[i], "cos_theta", i) for i in range(3)),
    *(Parameter(s.chain_r[i], "chain_r", i) for i in range(3)),
    *(Parameter(s.chain_l_a[i], "chain_l_a", i) for i in range(3)),
    *(Parameter(s.chain_l_b[i], "chain_l_b", i) for i in range(3)),
    *(Parameter(s.sin_theta[i], "sin_theta", i) for i in range(3)),
    Parameter(s.singular_tol, "singular_tol"),
    # inertia (read by the dynamics kernels only)
    Parameter(dyn.I_a, "I_a"),
    Parameter(dyn.m_a, "m_a"),
    Parameter(dyn.r_ca, "r_ca"),
    Parameter(dyn.m_b, "m_b"),
    Parameter(dyn.m_p, "m_p"),
    *(Parameter(dyn.gravity[k], "gravity", k) for k in range(3)),
    Parameter(dyn.I_4, "I_4"),
)

SETUP = (
    Stage(
        "r = r_a - r_b (eq. (1)) and the singularity thresholds scaled to the robot",
        (
            (s.r, s.r_a - s.r_b),
            (collinear_limit, (s.singular_tol * s.l_b**2) ** 2),
            (det_limit, s.singular_tol * s.l_b**3),
            (jq_limit, (2 * s.singular_tol * s.l_a * s.l_b) ** 2),
        ),
    ),
    Stage(
        "the coefficients of each chain's E_i, F_i, G_i free of p (derive/delta/ik.py)",
        ikd.crank_constants(),
    ),
)

ANGLES = tuple(Angle(s.q[i], s.cos_q[i], s.sin_q[i]) for i in range(3))


# fourth axis, eq. (43): its angle and rates ride along in column 4 (0 when axes == 3)
q4, qd4, qdd4 = sp.symbols("q4 qd4 qdd4", real=True)
phi = sp.Symbol("phi", real=True)


def _masked(names, values, bad):
    """Output stage: each value, or NaN where ``bad`` holds."""
    outs = sp.symbols(" ".join(f"out_{n}" for n in names), real=True)
    return outs, tuple((o, sp.Piecewise((sp.nan, bad), (v, True))) for o, v in zip(outs, values))


def _q_port():
    return Port(
        "q",
        s.q,
        "crank angles q_1..q_3 (eq. (1), positive = crank down) [rad]; "
        "column 4: fourth-axis angle q_4 [rad]",
        "rad",
        fourth=q4,
    )


def _p_port():
    return Port("p", (s.x, s.y, s.z), "platform position [m]; column 4: phi [rad]", "m", fourth=phi)


def _ik_q_output(no_q):
    """(port, assignments) of the inverse kinematics' crank angles q, NaN where ``no_q``."""
    q_out, q_stage = _masked(("q1", "q2", "q3", "q4"), (*s.q, phi), no_q)
    port = Port(
        "q",
        q_out[:3],
        "crank angles [rad]; column 4: q_4 = phi, eq. (43) [rad]",
        "rad",
        fourth=q_out[3],
    )
    return port, q_stage


def _qd_port():
    return Port(
        "qd", s.qd, "crank rates qdot [rad/s]; column 4: qdot_4 [rad/s]", "rad/s", fourth=qd4
    )


def _qdd_port():
    return Port(
        "qdd",
        s.qdd,
        "crank accelerations qddot [rad/s^2]; column 4: qddot_4 [rad/s^2]",
        "rad/s^2",
        fourth=qdd4,
    )


invalid, collinear, unreachable, singular = sp.symbols("invalid collinear unreachable singular")


def _fk_level(inputs_finite):
    """Status flags, status and masks shared by the fk-level kernels."""
    return fk_status(inputs_finite, fkd.h_sq < 0, collinear_limit, det_limit)


def fk_status(inputs_finite, apart, collinear_limit, det_limit):
    """(flags stage, status, no_position, no_rates) of a three-sphere direct kinematics (the
    rotary delta's, the linear delta's, the tripod's): INVALID for a non-finite input,
    SINGULAR for collinear centres (|e|^2 <= collinear_limit, no position), UNREACHABLE
    where ``apart`` (the spheres do not meet), SINGULAR where |det D| <= det_limit (the
    position is given, its rates are not)."""
    flags = Stage(
        "status flags: non-finite input, collinear centres, spheres apart, det J_p ~ 0",
        (
            (invalid, sp.Not(inputs_finite)),
            (collinear, fkd.e_sq <= collinear_limit),
            (unreachable, apart),
            (singular, sp.Abs(fkd.det_D) <= det_limit),
        ),
    )
    status = sp.Piecewise(
        (st.INVALID, invalid),
        (st.SINGULAR, collinear),
        (st.UNREACHABLE, unreachable),
        (st.SINGULAR, singular),
        (st.OK, True),
    )
    no_position = sp.Or(invalid, collinear, unreachable)
    no_rates = sp.Or(no_position, singular)
    return flags, status, no_position, no_rates


_FK_STATUS_DOC = (
    "OK; INVALID (non-finite input); UNREACHABLE (spheres do not meet); "
    "SINGULAR (|det J_p| / (8 l_b^3) <= singular_tol, or collinear sphere centres "
    "(no output))"
)


def _outputs(no_p, no_rates, levels):
    """Masked output symbols and their stage for p (and pdot, pddot), column 4 included."""
    names = [("x", "y", "z", "phi"), ("xd", "yd", "zd", "phid"), ("xdd", "ydd", "zdd", "phidd")]
    values = [(s.x, s.y, s.z, q4), (s.xd, s.yd, s.zd, qd4), (s.xdd, s.ydd, s.zdd, qdd4)]
    ports, assignments = [], ()
    docs = [
        (
            "p",
            "platform position x, y, z of P in the base frame O [m]; column 4: "
            "fourth-axis angle phi = q_4, eq. (43) [rad]",
            "m",
        ),
        ("pd", "platform velocity [m/s]; column 4: phidot = qdot_4 [rad/s]", "m/s"),
        ("pdd", "platform acceleration [m/s^2]; column 4: phiddot = qddot_4 [rad/s^2]", "m/s^2"),
    ]
    for level in range(levels):
        outs, stage = _masked(names[level], values[level], no_p if level == 0 else no_rates)
        assignments += stage
        name, doc, unit = docs[level]
        ports.append(Port(name, outs[:3], doc, unit, fourth=outs[3]))
    return tuple(ports), Stage("outputs (NaN where the status says they do not exist)", assignments)


def _direct_kernel(
    name: str,
    doc: str,
    inputs: tuple[Port, ...],
    outputs: tuple[Port, ...],
    flags: Stage,
    status: sp.Basic,
    stages: tuple[Stage, ...],
    outputs_doc: str,
) -> Kernel:
    """A kernel that starts from the direct kinematics (fk, its rates, J, the parameter
    Jacobian, the dynamics): the fk stages, the ``flags`` stage of _fk_level, then
    ``stages``; its ``status`` is _fk_level's, whose doc _FK_STATUS_DOC is completed by
    ``outputs_doc`` (what the outputs are where the status is not OK)."""
    return Kernel(
        name=name,
        doc=doc,
        inputs=inputs,
        outputs=outputs,
        stages=tuple(fkd.fk_stages()) + (flags,) + stages,
        status=status,
        parameters=PARAMETERS,
        setup=SETUP,
        angles=ANGLES,
        status_doc=f"{_FK_STATUS_DOC}; {outputs_doc}",
    )


@cache
def fk_kernel() -> Kernel:
    flags, status, no_p, no_rates = _fk_level(AllFinite(*s.q, q4))
    ports, outputs = _outputs(no_p, no_rates, 1)
    return _direct_kernel(
        name="fk",
        doc="Direct kinematics: crank angles q -> platform position p, eqs. (2)-(27).",
        inputs=(_q_port(),),
        outputs=ports,
        flags=flags,
        status=status,
        stages=(outputs,),
        outputs_doc="p is still given where only det J_p is small",
    )


def _rate_stages(with_jacobian=False):
    stages = (vel.rod_rows_stage(), vel.jq_stage(), vel.inverse_stage())
    return stages + ((vel.jacobian_stage(),) if with_jacobian else ())


@cache
def jacobian_kernel() -> Kernel:
    flags, status, _, no_rates = _fk_level(AllFinite(*s.q, q4))
    names = [f"J{i + 1}{j + 1}" for i in range(3) for j in range(3)]
    J_out, J_stage = _masked(names, list(vel.J), no_rates)
    return _direct_kernel(
        name="jacobian",
        doc="Jacobian J = J_p^-1 J_q of eq. (30), row-major 3x3 per point: pdot = J qdot.",
        inputs=(_q_port(),),
        outputs=(
            Port(
                "J",
                J_out,
                "Jacobian d p / d q, row-major 3x3 [m/rad]",
                "m/rad",
                width=9,
                matrix=(3, 3),
            ),
        ),
        flags=flags,
        status=status,
        stages=_rate_stages(with_jacobian=True) + (Stage("outputs (NaN unless OK)", J_stage),),
        outputs_doc="J is NaN unless OK",
    )


@cache
def fk_vel_kernel() -> Kernel:
    flags, status, no_p, no_rates = _fk_level(AllFinite(*s.q, q4, *s.qd, qd4))
    ports, outputs = _outputs(no_p, no_rates, 2)
    return _direct_kernel(
        name="fk_vel",
        doc="Direct kinematics at velocity level: (q, qdot) -> (p, pdot), eqs. (2)-(35).",
        inputs=(_q_port(), _qd_port()),
        outputs=ports,
        flags=flags,
        status=status,
        stages=_rate_stages() + (vel.velocity_stage(), outputs),
        outputs_doc="pd is NaN unless OK",
    )


@cache
def fk_acc_kernel() -> Kernel:
    flags, status, no_p, no_rates = _fk_level(AllFinite(*s.q, q4, *s.qd, qd4, *s.qdd, qdd4))
    ports, outputs = _outputs(no_p, no_rates, 3)
    return _direct_kernel(
        name="fk_acc",
        doc="Direct kinematics at acceleration level: (q, qdot, qddot) -> (p, pdot, pddot), "
        "eqs. (2)-(39).",
        inputs=(_q_port(), _qd_port(), _qdd_port()),
        outputs=ports,
        flags=flags,
        status=status,
        stages=_rate_stages()
        + (vel.velocity_stage(), acc.h_stage(), acc.acceleration_stage(), outputs),
        outputs_doc="pd and pdd are NaN unless OK",
    )


centre_normal_z = sp.Symbol("centre_normal_z", real=True)


def _assembly_stage() -> Stage:
    """The side of the sphere-centre plane the target lies on, from the crank angles the
    inverse found: det_D = det of the rows p - S_i (D of rows_stage) and the z component of
    the plane's normal e = (S_2 - S_1) x (S_3 - S_1). The direct kinematics takes the
    intersection with det_D e_z < 0 (derive/delta/fk.py, eq. (26): the lower one)."""
    a = fkd.S[1] - fkd.S[0]
    b = fkd.S[2] - fkd.S[0]
    return Stage(
        "assembly mode: det of the rows p - S_i and the centre plane's normal (z)",
        (
            (fkd.det_D, vel.D.det()),
            (centre_normal_z, a[0] * b[1] - a[1] * b[0]),
        ),
    )


def _other_assembly_mode():
    """True where every crank reaches the target but the platform would sit on the other
    side of the centre plane (the other assembly mode, beyond a parallel singularity): the
    direct kinematics would not return the target, so the inverse has no solution in the
    robot's working mode. Within det_limit of the plane (the singularity) it counts as
    reachable: both intersections meet there."""
    return sp.And(fkd.det_D * centre_normal_z > 0, sp.Abs(fkd.det_D) > det_limit)


rho_sq = ikd.rho_sq  # E_i^2 + F_i^2 (derive/delta/ik.py)
scaled_det_D, scaled_normal_z, rho_sq_product = sp.symbols(
    "scaled_det_D scaled_normal_z rho_sq_product", real=True
)
row_cross_z = sp.symbols("row_cross_z23 row_cross_z31 row_cross_z12", real=True)
# setup: the parts of the scaled rows free of p and q, r_i (cos, sin) theta_i and
# l_a,i (cos, sin) theta_i
centre_offset = [sp.symbols(f"centre_x0_{i + 1} centre_y0_{i + 1}", real=True) for i in range(3)]
crank_axis = [sp.symbols(f"crank_x_{i + 1} crank_y_{i + 1}", real=True) for i in range(3)]


def _scaled_assembly_constants() -> Stage:
    """Setup of _scaled_assembly_stage: per chain r_i (cos, sin) theta_i and l_a,i (cos,
    sin) theta_i (eqs. (3)-(5): S_i = (r_i + l_a,i cos q_i) (cos, sin) theta_i in x, y)."""
    pairs = []
    for i in range(3):
        pairs += [
            (centre_offset[i][0], s.chain_r[i] * s.cos_theta[i]),
            (centre_offset[i][1], s.chain_r[i] * s.sin_theta[i]),
            (crank_axis[i][0], s.chain_l_a[i] * s.cos_theta[i]),
            (crank_axis[i][1], s.chain_l_a[i] * s.sin_theta[i]),
        ]
    return Stage(
        "the scaled rows' constants: r_i (cos, sin) theta_i, l_a,i (cos, sin) theta_i "
        "(eqs. (3)-(5))",
        tuple(pairs),
    )


def _scaled_assembly_stage() -> Stage:
    """_assembly_stage without a division: the inverse's atan2 arguments are (X_i, Y_i) =
    rho_i^2 (cos q_i, sin q_i) (derive/delta/inverse_rates.py), so the rows of D scaled
    by rho_i^2, u~_i = rho_i^2 (p - S_i) with S_i of eqs. (3)-(5), are polynomials in them:
        u~_i = (rho_i^2 (x - r_i cos theta_i) - l_a,i cos theta_i X_i,
                rho_i^2 (y - r_i sin theta_i) - l_a,i sin theta_i X_i,
                rho_i^2 z + l_a,i Y_i).
    With P = rho_1^2 rho_2^2 rho_3^2 (> 0, so signs are kept) and C~_i the z component of
    the cross product of the other two rows' x, y parts (row_cross_z[i] leaves row i out),
    P det_D = sum_i u~_i,z C~_i (det_D expanded along its z column), and, from
    e = (S_2 - S_1) x (S_3 - S_1) = u_1 x u_2 + u_2 x u_3 + u_3 x u_1 (u_i = p - S_i),
    P e_z = sum_i rho_i^2 C~_i. The z column is rho_i^2 z + l_a,i Y_i, so
    P det_D = z (P e_z) + sum_i l_a,i Y_i C~_i: the z column itself is never formed (one
    multiplication instead of three rows' six operations), and the x, y entries take two
    multiplications each with r_i, l_a,i times (cos, sin) theta_i from the setup
    (_scaled_assembly_constants). det_D e_z > 0 and |det_D| > det_limit read
    (P det_D)(P e_z) > 0 and |P det_D| > det_limit P (the batched ik, which needs no
    cos q_i, sin q_i: three divisions fewer per point; the rate kernels divide, they need
    them). 32 multiplications per point, against 40 when the rows' z column and the
    scaled centres S~_i = rho_i^2 S_i were formed."""
    pairs = []
    p = sp.Matrix([s.x, s.y, s.z])
    rows = sp.Matrix(3, 2, lambda i, k: sp.Symbol(f"Dt{i + 1}{k + 1}", real=True))
    coords = (s.x, s.y)
    for i in range(3):
        for k in range(2):
            entry = rho_sq[i] * (coords[k] - centre_offset[i][k]) - crank_axis[i][k] * irs.ik_x[i]
            pairs.append((rows[i, k], entry))
    # each entry is rho_i^2 (p - S_i) with cos q_i, sin q_i = (X_i, Y_i) / rho_i^2
    setup = {sym: value for sym, value in _scaled_assembly_constants().assignments}
    trig = [
        {s.cos_q[i]: irs.ik_x[i] / rho_sq[i], s.sin_q[i]: irs.ik_y[i] / rho_sq[i]} for i in range(3)
    ]
    z_column = [rho_sq[i] * s.z + s.chain_l_a[i] * irs.ik_y[i] for i in range(3)]
    for i in range(3):
        unscaled = p - s.sphere_centre(i).subs(trig[i])
        scaled = [pairs[2 * i][1].subs(setup), pairs[2 * i + 1][1].subs(setup), z_column[i]]
        assert sp.simplify(sp.Matrix(scaled) - rho_sq[i] * unscaled) == sp.zeros(3, 1)

    def cross_z(u, v):
        return u[0] * v[1] - u[1] * v[0]

    # (u~_2 x u~_3)_z, (u~_3 x u~_1)_z, (u~_1 x u~_2)_z: row_cross_z[i] leaves row i out
    crosses = [cross_z(rows[(i + 1) % 3, :], rows[(i + 2) % 3, :]) for i in range(3)]
    pairs += list(zip(row_cross_z, crosses))
    normal = sum(rho_sq[i] * row_cross_z[i] for i in range(3))
    det = s.z * scaled_normal_z + sum(
        s.chain_l_a[i] * irs.ik_y[i] * row_cross_z[i] for i in range(3)
    )
    # the identities the sums rest on, checked on the unnamed expressions: the z-column
    # expansion of det[u~_1; u~_2; u~_3], and P det_D read through P e_z
    full = sp.Matrix(3, 3, lambda i, k: rows[i, k] if k < 2 else z_column[i])
    by_cross = dict(zip(row_cross_z, crosses))
    expanded = det.subs(scaled_normal_z, normal).subs(by_cross)
    assert sp.expand(expanded - full.det()) == 0
    u = [p - s.sphere_centre(i) for i in range(3)]
    e = (u[1] - u[0]).cross(u[2] - u[0])  # (S_2 - S_1) x (S_3 - S_1), S_i = p - u_i
    e_from_rows = sum((u[i].cross(u[(i + 1) % 3]) for i in range(3)), sp.zeros(3, 1))
    assert sp.expand(e - e_from_rows) == sp.zeros(3, 1)
    pairs += [
        (scaled_normal_z, normal),
        (scaled_det_D, det),
        (rho_sq_product, rho_sq[0] * rho_sq[1] * rho_sq[2]),
    ]
    return Stage(
        "assembly mode without divisions: x, y of the rows rho_i^2 (p - S_i), P e_z and "
        "P det_D = z P e_z + sum l_a,i Y_i C~_i, P = prod rho_i^2",
        tuple(pairs),
    )


def _other_assembly_mode_scaled():
    """_other_assembly_mode in the scaled quantities of _scaled_assembly_stage."""
    return sp.And(
        scaled_det_D * scaled_normal_z > 0,
        sp.Abs(scaled_det_D) > det_limit * rho_sq_product,
    )


_IK_UNREACHABLE_DOC = (
    "UNREACHABLE (a crank cannot reach, or only in the other assembly mode: the platform "
    "above the centre plane of the spheres, where the direct kinematics would not return p)"
)


@cache
def ik_kernel() -> Kernel:
    finite = AllFinite(s.x, s.y, s.z, phi)
    flags = Stage(
        "status flags: non-finite input, a crank cannot reach or the target lies in the other "
        "assembly mode, a crank at its reach limit",
        (
            (invalid, sp.Not(finite)),
            (
                unreachable,
                sp.Or(*(ikd.disc[i] < 0 for i in range(3)), _other_assembly_mode_scaled()),
            ),
            (
                singular,
                sp.Or(
                    *(ikd.disc[i] <= jq_limit for i in range(3)),
                    sp.Abs(scaled_det_D) <= det_limit * rho_sq_product,
                ),
            ),
        ),
    )
    status = sp.Piecewise(
        (st.INVALID, invalid),
        (st.UNREACHABLE, unreachable),
        (st.SINGULAR, singular),
        (st.OK, True),
    )
    q_port, q_stage = _ik_q_output(sp.Or(invalid, unreachable))
    return Kernel(
        name="ik",
        doc="Inverse kinematics (elbow-out): platform position p -> crank angles q in (-pi, pi].",
        inputs=(_p_port(),),
        outputs=(q_port,),
        stages=(
            *irs.ik_stages_with_trig()[:-1],  # q needs no cos q_i, sin q_i: no divisions
            _scaled_assembly_stage(),
            flags,
            Stage("outputs (NaN where unreachable)", q_stage),
        ),
        status=status,
        parameters=PARAMETERS,
        setup=SETUP + (_scaled_assembly_constants(),),
        status_doc=f"OK; INVALID (non-finite input); {_IK_UNREACHABLE_DOC}; "
        "SINGULAR (|J_q,ii| / (2 l_a l_b) <= singular_tol; q is still given)",
    )


def _inverse_rates(with_acceleration: bool) -> Kernel:
    """ik_vel / ik_acc: (p, pdot[, pddot]) -> (q, qdot[, qddot]), eqs. (28)-(39)."""
    phid, phidd = sp.symbols("phid phidd", real=True)
    inputs = [
        _p_port(),
        Port(
            "pd",
            (s.xd, s.yd, s.zd),
            "platform velocity [m/s]; column 4: phidot [rad/s]",
            "m/s",
            fourth=phid,
        ),
    ]
    finite = [s.x, s.y, s.z, phi, s.xd, s.yd, s.zd, phid]
    if with_acceleration:
        inputs.append(
            Port(
                "pdd",
                (s.xdd, s.ydd, s.zdd),
                "platform acceleration [m/s^2]; column 4: phiddot [rad/s^2]",
                "m/s^2",
                fourth=phidd,
            )
        )
        finite += [s.xdd, s.ydd, s.zdd, phidd]
    flags = Stage(
        "status flags: non-finite input, a crank cannot reach, J_q singular (crank and rod "
        "in line)",
        (
            (invalid, sp.Not(AllFinite(*finite))),
            (
                unreachable,
                sp.Or(*(ikd.disc[i] < 0 for i in range(3)), _other_assembly_mode()),
            ),
            (
                singular,
                sp.Or(
                    *(ikd.disc[i] <= jq_limit for i in range(3)),
                    sp.Abs(fkd.det_D) <= det_limit,
                ),
            ),
        ),
    )
    status = sp.Piecewise(
        (st.INVALID, invalid),
        (st.UNREACHABLE, unreachable),
        (st.SINGULAR, singular),
        (st.OK, True),
    )
    no_q = sp.Or(invalid, unreachable)
    no_rates = sp.Or(no_q, singular)
    q_port, q_stage = _ik_q_output(no_q)
    qd_out, qd_stage = _masked(("qd1", "qd2", "qd3", "qd4"), (*s.qd, phid), no_rates)
    outputs = [
        q_port,
        Port(
            "qd",
            qd_out[:3],
            "crank rates [rad/s]; column 4: qdot_4 = phidot [rad/s]",
            "rad/s",
            fourth=qd_out[3],
        ),
    ]
    out_stage = q_stage + qd_stage
    if with_acceleration:
        qdd_out, qdd_stage = _masked(("qdd1", "qdd2", "qdd3", "qdd4"), (*s.qdd, phidd), no_rates)
        outputs.append(
            Port(
                "qdd",
                qdd_out[:3],
                "crank accelerations [rad/s^2]; column 4: qddot_4 = phiddot [rad/s^2]",
                "rad/s^2",
                fourth=qdd_out[3],
            )
        )
        out_stage += qdd_stage
    stages = irs.rate_stages(with_acceleration)
    # the flags need only the discriminants: place them after the inverse's first stages
    return Kernel(
        name="ik_acc" if with_acceleration else "ik_vel",
        doc=(
            "Inverse kinematics at acceleration level (elbow-out): (p, pdot, pddot) -> "
            "(q, qdot, qddot), qdot = J_q^-1 J_p pdot and its time derivative, eqs. (28)-(39)."
            if with_acceleration
            else "Inverse kinematics at velocity level (elbow-out): (p, pdot) -> (q, qdot), "
            "qdot = J_q^-1 J_p pdot, eqs. (28)-(35)."
        ),
        inputs=tuple(inputs),
        outputs=tuple(outputs),
        stages=(
            *stages,
            _assembly_stage(),
            flags,
            Stage("outputs (q NaN where unreachable, rates NaN unless OK)", out_stage),
        ),
        status=status,
        parameters=PARAMETERS,
        setup=SETUP,
        status_doc=f"OK; INVALID (non-finite input); {_IK_UNREACHABLE_DOC}; "
        "SINGULAR (|J_q,ii| / (2 l_a l_b) <= singular_tol: q is given, the rates are NaN)",
    )


@cache
def ik_vel_kernel() -> Kernel:
    return _inverse_rates(False)


@cache
def ik_acc_kernel() -> Kernel:
    return _inverse_rates(True)


@cache
def fk_param_jacobian_kernel() -> Kernel:
    flags, status, no_p, no_rates = _fk_level(AllFinite(*s.q, q4))
    ports, outputs = _outputs(no_p, no_rates, 1)
    names = [str(sym) for sym in cal.dp]
    G_out, G_stage = _masked(names, list(cal.dp), no_rates)
    return _direct_kernel(
        name="fk_param_jacobian",
        doc="Direct kinematics and the sensitivity of p to the chain parameters (calibration): "
        "q -> p, dp/d(r_i, l_a,i, l_b,i, theta_i, q_i) by the implicit function theorem on "
        "eq. (1) (deltagen/derive/delta/calibration.py).",
        inputs=(_q_port(),),
        outputs=(
            *ports,
            Port(
                "G",
                G_out,
                "dp/dpi, 15 parameters x 3 coordinates per point: parameters r_1..3, "
                "l_a,1..3, l_b,1..3 [m/m], theta_1..3, q_1..3 [m/rad]; r_i = r_a,i - r_b,i",
                "m/m, m/rad",
                width=45,
            ),
        ),
        flags=flags,
        status=status,
        stages=_rate_stages()
        + (
            cal.partials_stage(),
            cal.sensitivity_stage(),
            Stage("outputs (p as fk; G NaN unless OK)", outputs.assignments + G_stage),
        ),
        outputs_doc="G is NaN unless OK",
    )


def _payload_port():
    return Port(
        "payload",
        (dyn.payload,),
        "mass carried by the platform besides m_p, per point [kg]",
        "kg",
        width=1,
    )


def _inverse_dynamics(model: str) -> Kernel:
    flags, status, _, no_rates = _fk_level(
        AllFinite(*s.q, q4, *s.qd, qd4, *s.qdd, qdd4, dyn.payload)
    )
    tau_out, tau_stage = _masked(("tau1", "tau2", "tau3", "tau4"), (*dyn.tau, tau4), no_rates)
    tau_fourth = Stage(
        "fourth axis, eq. (43): decoupled, tau_4 = I_4 qddot_4", ((tau4, dyn.I_4 * qdd4),)
    )
    what = (
        "exact rigid-body model (cranks, rod pairs as slender rods with their rotation, "
        "platform + payload)"
        if model == "exact"
        else "simplified model (each rod pair's mass half on the crank tip, half on the "
        "platform; no rod rotation)"
    )
    return _direct_kernel(
        name="inverse_dynamics" if model == "exact" else "inverse_dynamics_simplified",
        doc=f"Inverse dynamics, {what}: (q, qdot, qddot, payload) -> motor torques tau, by "
        "virtual work with J of eq. (30) and pddot of eq. (38) (deltagen/derive/delta/dynamics.py).",
        inputs=(_q_port(), _qd_port(), _qdd_port(), _payload_port()),
        outputs=(
            Port(
                "tau",
                tau_out[:3],
                "motor torques about the drive axes, positive turning the crank down [N m]; "
                "column 4: fourth-axis torque [N m]",
                "N m",
                fourth=tau_out[3],
            ),
        ),
        flags=flags,
        status=status,
        stages=_rate_stages()
        + (
            vel.velocity_stage(),
            _acceleration_and_crank_tips(),
            dyn.force_stage(model),
            dyn.tau_stage(model, vel.adjD, vel.jq, vel.inv_det),
            tau_fourth,
            Stage("outputs (NaN unless OK)", tau_stage),
        ),
        outputs_doc="tau is NaN unless OK",
    )


tau4 = sp.Symbol("tau4", real=True)


def _acceleration_and_crank_tips() -> Stage:
    """pddot (eqs. (38)-(39)) and the crank tips' motion in one stage, so that their common
    terms (l_a sin q_i qdot_i^2, ...) are evaluated once (about 30 operations less)."""
    stages = (acc.h_stage(), acc.acceleration_stage(), dyn.crank_tip_stage())
    return Stage(
        "; ".join(stage.comment for stage in stages),
        tuple(a for stage in stages for a in stage.assignments),
    )


@cache
def inverse_dynamics_kernel() -> Kernel:
    return _inverse_dynamics("exact")


@cache
def inverse_dynamics_simplified_kernel() -> Kernel:
    return _inverse_dynamics("simplified")


def all_kernels():
    return (
        fk_kernel(),
        fk_vel_kernel(),
        fk_acc_kernel(),
        jacobian_kernel(),
        ik_kernel(),
        ik_vel_kernel(),
        ik_acc_kernel(),
        fk_param_jacobian_kernel(),
        inverse_dynamics_kernel(),
        inverse_dynamics_simplified_kernel(),
    )
