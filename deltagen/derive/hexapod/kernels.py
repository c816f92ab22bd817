"""The hexapod's batched kernels: ``ik`` (pose -> leg lengths, closed form), ``jacobian``
(pose -> leg lengths and the leg-length Jacobian dl/d(v, w), which the damped Newton of
the forward kinematics evaluates, codegen/runtime/deltagen_hexapod_fk.c) and
``joint_angles`` (pose -> the angle of each leg against its base and platform joint axes).
"""

from __future__ import annotations

import sympy as sp

from deltagen import status as st
from deltagen.derive.hexapod import legs
from deltagen.derive.hexapod.symbols import LEGS, PARAMETERS, pose_symbols, scale, singular_tol
from deltagen.derive.kernel import Kernel, Port, Stage

_POSE_DOC = (
    "platform pose, the 4x4 homogeneous transform of the platform frame in the base frame, "
    "row-major (R in rows 0-2, columns 0-2; p in column 3 [m]; row 3 is not read)"
)


def _pose_port() -> Port:
    return Port("pose", pose_symbols, _POSE_DOC, "m", width=16)


def _vector_stage(comment: str, name: str, vectors) -> tuple[Stage, list[sp.Matrix]]:
    symbols = [
        sp.Matrix([sp.Symbol(f"{name}{i}_{k}", real=True) for k in "xyz"]) for i in range(LEGS)
    ]
    assignments = tuple((symbols[i][k], vectors[i][k]) for i in range(LEGS) for k in range(3))
    return Stage(comment, assignments), symbols


def _leg_stages():
    d_stage, d = _vector_stage(
        "leg vectors d_i = p + R b_i - a_i (base joint to platform joint)", "d", legs.leg_vectors()
    )
    lengths = sp.symbols(" ".join(f"len{i}" for i in range(LEGS)), positive=True)
    l_stage = Stage(
        "leg lengths l_i = |d_i|", tuple((lengths[i], sp.sqrt(d[i].dot(d[i]))) for i in range(LEGS))
    )
    return d_stage, d, l_stage, lengths


def _outputs(names, values, bad=None):
    outs = sp.symbols(" ".join(f"out_{n}" for n in names), real=True)
    if bad is None:
        return outs, tuple(zip(outs, values))
    return outs, tuple((o, sp.Piecewise((sp.nan, bad), (v, True))) for o, v in zip(outs, values))


def ik_kernel() -> Kernel:
    d_stage, _, l_stage, lengths = _leg_stages()
    out, out_stage = _outputs([f"l{i}" for i in range(LEGS)], lengths)
    return Kernel(
        name="ik",
        doc="Inverse kinematics: platform pose -> leg lengths l_i = |p + R b_i - a_i| "
        "(closed form).",
        inputs=(_pose_port(),),
        outputs=(Port("lengths", out, "leg lengths l_1 .. l_6 [m]", "m", width=LEGS),),
        stages=(d_stage, l_stage, Stage("outputs", out_stage)),
        status=sp.Integer(st.OK),
        parameters=PARAMETERS,
        status_doc="OK; INVALID (a non-finite pose, or lengths that overflow)",
    )


def jacobian_kernel() -> Kernel:
    d_stage, d, l_stage, lengths = _leg_stages()
    short = sp.Symbol("short_leg", real=True)
    limit = singular_tol * scale
    flags = Stage(
        "status flag: a leg of (almost) zero length has no direction",
        ((short, sp.Or(*(lengths[i] <= limit for i in range(LEGS)))),),
    )
    inverse = sp.symbols(" ".join(f"inv_len{i}" for i in range(LEGS)), positive=True)
    inv_stage = Stage("1 / l_i", tuple((inverse[i], 1 / lengths[i]) for i in range(LEGS)))
    u_stage, u = _vector_stage(
        "unit vectors u_i = d_i / l_i", "u", [d[i] * inverse[i] for i in range(LEGS)]
    )
    rb_stage, rb = _vector_stage(
        "platform joints about the platform origin, base frame: R b_i",
        "rb",
        legs.rotated_platform_joints(),
    )
    rows = legs.jacobian_rows(u, rb)
    l_out, l_out_stage = _outputs([f"l{i}" for i in range(LEGS)], lengths)
    J_out, J_out_stage = _outputs(
        [f"J{i}{j}" for i in range(LEGS) for j in range(6)],
        [rows[i][j] for i in range(LEGS) for j in range(6)],
        short,
    )
    status = sp.Piecewise((st.SINGULAR, short), (st.OK, True))
    return Kernel(
        name="jacobian",
        doc="Leg lengths and the leg-length Jacobian J = dl/d(v, w) at a platform pose "
        "(v: velocity of the platform origin, w: angular velocity, both in the base frame); "
        "row i is (u_i, (R b_i) x u_i).",
        inputs=(_pose_port(),),
        outputs=(
            Port("lengths", l_out, "leg lengths l_1 .. l_6 [m]", "m", width=LEGS),
            Port(
                "J",
                J_out,
                "6 x 6 row-major, row i = dl_i/d(vx, vy, vz, wx, wy, wz) [1, m]",
                "1, m",
                width=36,
                matrix=(6, 6),
            ),
        ),
        stages=(
            d_stage,
            l_stage,
            flags,
            inv_stage,
            u_stage,
            rb_stage,
            Stage("outputs (J NaN where a leg has zero length)", (*l_out_stage, *J_out_stage)),
        ),
        status=status,
        parameters=PARAMETERS,
        status_doc="OK; INVALID (a non-finite pose, or outputs that overflow); SINGULAR (a "
        "leg shorter than singular_tol * scale: J NaN, the lengths still given)",
    )


def joint_angles_kernel() -> Kernel:
    d_stage, d, _, _ = _leg_stages()
    base, platform = legs.joint_angle_terms(d)
    names = [f"base{i}" for i in range(LEGS)] + [f"platform{i}" for i in range(LEGS)]
    values = [sp.atan2(s, c) for c, s in (*base, *platform)]
    out, out_stage = _outputs(names, values)
    return Kernel(
        name="joint_angles",
        doc="Joint angles at a platform pose: the angle between leg i and its base joint's "
        "axis n_a,i, and between the leg (pointing to the base) and its platform joint's "
        "axis R n_b,i.",
        inputs=(_pose_port(),),
        outputs=(
            Port(
                "angles",
                out,
                "base joint angles 1 .. 6, then platform joint angles 1 .. 6, in [0, pi] [rad]",
                "rad",
                width=2 * LEGS,
            ),
        ),
        stages=(d_stage, Stage("outputs: atan2(|x cross n|, x . n)", out_stage)),
        status=sp.Integer(st.OK),
        parameters=PARAMETERS,
        status_doc="OK; INVALID (a non-finite pose, or angles that are not finite)",
    )


def all_kernels() -> list[Kernel]:
    return [ik_kernel(), jacobian_kernel(), joint_angles_kernel()]
