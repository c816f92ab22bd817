"""The batched kernels of the linear delta (module ``linear_delta_kinematics``, prefix
``deltagen_linear_delta``) and of the tripod (``tripod_kinematics``, ``deltagen_tripod``).

Direct kinematics: the three-sphere intersection of the rotary delta
(derive/delta/fk.py ``intersection_stages``, the delta report's method), with the carriage
joints C_i = (tower_x_i, tower_y_i, h_i) and the arm lengths as centres and radii (the
effector hangs below the carriages: the lower intersection, as Klipper's trilateration
takes), or the tripod's fixed base points A, B, C and the strut lengths (the side of the
base plane chosen at run time, tripodkins' forward flag). Inverse kinematics in closed
form: h_i = z + sqrt(arm_i^2 - (x - tower_x_i)^2 - (y - tower_y_i)^2) (Klipper's delta
kinematics), l_i = |p - S_i| (tripodkins).

Status rules (identical in the numpy reference, reference/linear_delta.py):
  INVALID      an input of the row is NaN or infinite (and, as every kernel, finite inputs
               whose outputs overflow: codegen.lowering.guard_outputs)
  SINGULAR     centres collinear: |e|^2 <= (tol L^2)^2         (no output)
  UNREACHABLE  the spheres do not meet (h^2 < 0), or (tripod) a negative strut length
  SINGULAR     |det D| <= tol L^3, D rows p - S_i                (p given, rates NaN)
  (ik) UNREACHABLE where an arm cannot reach (negative radicand), or the target lies on the
       other side of the centre plane than the direct kinematics chooses (|det D| > tol L^3);
       SINGULAR (linear delta) where an arm is within tol L of horizontal (carriage rate
       infinite), (tripod) where p lies within tol L^3 / |e| of the base plane
  (ik_vel, ik_acc) the status of ik; the joint rates NaN unless OK (linear delta) or unless
       the joints are given (tripod: its rates exist at the base-plane singularity)
with L the mean arm length (linear delta) or the base size (|b_x| + |C|) / 2 (tripod).
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from deltagen import status as st
from deltagen.derive.delta import fk as fkd
from deltagen.derive.delta import symbols as ds
from deltagen.derive.delta import velocity as vel
from deltagen.derive.delta.kernels import fk_status
from deltagen.derive.functions import AllFinite
from deltagen.derive.kernel import Kernel, Parameter, Port, Stage
from deltagen.derive.linear_delta import rates
from deltagen.derive.linear_delta import symbols as s

collinear_limit, det_limit, ik_limit, centre_normal_z = sp.symbols(
    "collinear_limit det_limit ik_limit centre_normal_z", real=True
)
invalid, collinear, unreachable, singular = sp.symbols("invalid collinear unreachable singular")
radicand = sp.symbols("radicand1:4", real=True)
LINEAR, TRIPOD = "linear_delta", "tripod"

PARAMETERS = {
    LINEAR: (
        *(Parameter(s.tower_x[i], "tower_x", i) for i in range(3)),
        *(Parameter(s.tower_y[i], "tower_y", i) for i in range(3)),
        *(Parameter(s.arm[i], "arm_length", i) for i in range(3)),
        Parameter(s.singular_tol, "singular_tol"),
    ),
    TRIPOD: (
        Parameter(s.b_x, "b_x"),
        Parameter(s.c_x, "c_x"),
        Parameter(s.c_y, "c_y"),
        Parameter(s.side, "side"),
        Parameter(s.singular_tol, "singular_tol"),
    ),
}

_SCALE = {
    LINEAR: sum(s.arm) / 3,
    TRIPOD: (sp.Abs(s.b_x) + sp.sqrt(s.c_x**2 + s.c_y**2)) / 2,
}

#: the centre plane's normal z, (S_2 - S_1) x (S_3 - S_1) . z: a constant of either machine
_NORMAL_Z = {
    LINEAR: (s.tower_x[1] - s.tower_x[0]) * (s.tower_y[2] - s.tower_y[0])
    - (s.tower_y[1] - s.tower_y[0]) * (s.tower_x[2] - s.tower_x[0]),
    TRIPOD: s.b_x * s.c_y,
}


def _setup(kind):
    L = s.length_scale
    return (
        Stage(
            "the singularity thresholds scaled to the machine (L: "
            + ("mean arm length" if kind == LINEAR else "base size")
            + ") and the centre plane's normal (z)",
            (
                (L, _SCALE[kind]),
                (collinear_limit, (s.singular_tol * L**2) ** 2),
                (det_limit, s.singular_tol * L**3),
                (ik_limit, (s.singular_tol * L) ** 2),
                (centre_normal_z, _NORMAL_Z[kind]),
            ),
        ),
    )


def _centres(kind):
    if kind == LINEAR:
        return [s.carriage(i) for i in range(3)], list(s.arm)
    return [s.tripod_base(i) for i in range(3)], list(s.strut)


def _fk_stages(kind):
    centres, radii = _centres(kind)
    if kind == LINEAR:
        return fkd.intersection_stages(
            centres, radii, -1, "sphere centres: the carriage joints C_i = (tower, h_i)"
        )
    return fkd.intersection_stages(centres, radii, s.side, "sphere centres: base points A, B, C")


_JOINTS = {
    LINEAR: (
        (s.h, "h", "carriage heights h_1..h_3 along the towers [m]", "m"),
        (s.hd, "hd", "carriage velocities [m/s]", "m/s"),
        (s.hdd, "hdd", "carriage accelerations [m/s^2]", "m/s^2"),
    ),
    TRIPOD: (
        (s.strut, "l", "strut lengths |AD|, |BD|, |CD| (tripodkins' joints 0..2) [m]", "m"),
        (s.ld, "ld", "strut length rates [m/s]", "m/s"),
        (s.ldd, "ldd", "strut length accelerations [m/s^2]", "m/s^2"),
    ),
}

_POSITIONS = (
    ((ds.x, ds.y, ds.z), "p", "point p = (x, y, z) in the base frame [m]", "m"),
    ((ds.xd, ds.yd, ds.zd), "pd", "velocity of p [m/s]", "m/s"),
    ((ds.xdd, ds.ydd, ds.zdd), "pdd", "acceleration of p [m/s^2]", "m/s^2"),
)


def _port(entry):
    symbols, name, doc, unit = entry
    return Port(name, tuple(symbols), doc, unit, width=3)


def _masked(names, values, bad):
    outs = sp.symbols(" ".join(f"out_{n}" for n in names), real=True)
    return outs, tuple((o, sp.Piecewise((sp.nan, bad), (v, True))) for o, v in zip(outs, values))


def _fk_level(kind, levels):
    inputs = [v for entry in _JOINTS[kind][:levels] for v in entry[0]]
    apart = fkd.h_sq < 0 if kind == LINEAR else sp.Or(fkd.h_sq < 0, *(q < 0 for q in s.strut))
    return fk_status(AllFinite(*inputs), apart, collinear_limit, det_limit)


_FK_STATUS_DOC = (
    "OK; INVALID (non-finite input); UNREACHABLE (spheres do not meet{extra}); SINGULAR "
    "(|det D| / L^3 <= singular_tol, D rows p - S_i, or collinear centres (no output))"
)


def _fk_doc(kind):
    return _FK_STATUS_DOC.format(extra="" if kind == LINEAR else ", or a negative strut length")


def _fk_kernel(kind, levels, name, doc):
    flags, status, no_p, no_rates = _fk_level(kind, levels)
    outs, ports, assignments = [], [], ()
    for level in range(levels):
        symbols, pname, pdoc, unit = _POSITIONS[level]
        names = [f"{str(v)}" for v in symbols]
        out, stage = _masked(names, symbols, no_p if level == 0 else no_rates)
        assignments += stage
        ports.append(Port(pname, out, pdoc, unit, width=3))
        outs.append(out)
    stages = tuple(_fk_stages(kind)) + (flags,)
    if levels > 1:
        stages += rates.rate_stages(kind) + (rates.velocity_stage(kind),)
    if levels > 2:
        stages += (rates.acceleration_stage(kind),)
    stages += (Stage("outputs (NaN where the status says they do not exist)", assignments),)
    return Kernel(
        name=name,
        doc=doc,
        inputs=tuple(_port(e) for e in _JOINTS[kind][:levels]),
        outputs=tuple(ports),
        stages=stages,
        status=status,
        parameters=PARAMETERS[kind],
        setup=_setup(kind),
        status_doc=_fk_doc(kind)
        + (
            "; p is still given where only det D is small"
            if levels == 1
            else "; the rates are NaN unless OK"
        ),
    )


def _jacobian_kernel(kind):
    flags, status, _, no_rates = _fk_level(kind, 1)
    names = [f"J{i + 1}{j + 1}" for i in range(3) for j in range(3)]
    J_out, J_stage = _masked(names, list(vel.J), no_rates)
    return Kernel(
        name="jacobian",
        doc="Jacobian J = D^-1 diag(g), row-major 3x3 per point: pdot = J qdot.",
        inputs=(_port(_JOINTS[kind][0]),),
        outputs=(
            Port(
                "J", J_out, "Jacobian d p / d q, row-major 3x3 [m/m]", "1", width=9, matrix=(3, 3)
            ),
        ),
        stages=tuple(_fk_stages(kind))
        + (flags,)
        + rates.rate_stages(kind, with_jacobian=True)
        + (Stage("outputs (NaN unless OK)", J_stage),),
        status=status,
        parameters=PARAMETERS[kind],
        setup=_setup(kind),
        status_doc=_fk_doc(kind) + "; J is NaN unless OK",
    )


def _inverse_rate_stages(kind, levels):
    """qdot_i = D_i . pdot / g_i and qddot_i = (D_i . pddot - c_i) / g_i: the rows of
    D pdot = diag(g) qdot and D pddot = diag(g) qddot + c (derive/linear_delta/rates.py),
    solved for the joints (diag(g) is diagonal)."""
    rates_, accels = (s.hd, s.hdd) if kind == LINEAR else (s.ld, s.ldd)
    stages = [rates.g_stage(kind)]
    velocity = [(rates_[i], vel.D[i, :].dot(ds.pd) / rates.g[i]) for i in range(3)]
    stages.append(Stage("joint rates qdot_i = D_i . pdot / g_i", tuple(velocity)))
    if levels > 2:
        c_terms = [(rates.c[i], rates.c_value(kind, i)) for i in range(3)]
        accel = [(accels[i], (vel.D[i, :].dot(ds.pdd) - rates.c[i]) / rates.g[i]) for i in range(3)]
        stages.append(
            Stage("joint accelerations qddot_i = (D_i . pddot - c_i) / g_i", tuple(c_terms + accel))
        )
    return tuple(stages)


def _ik_kernel(kind, levels=1):
    centres, _ = _centres(kind)
    if kind == LINEAR:
        joint_values = [
            (radicand[i], s.arm[i] ** 2 - (ds.x - s.tower_x[i]) ** 2 - (ds.y - s.tower_y[i]) ** 2)
            for i in range(3)
        ] + [(s.h[i], ds.z + sp.sqrt(radicand[i])) for i in range(3)]
        comment = "carriage heights h_i = z + sqrt(arm_i^2 - dx_i^2 - dy_i^2) (Klipper's delta)"
    else:
        joint_values = [
            (s.strut[i], sp.sqrt((ds.p - s.tripod_base(i)).dot(ds.p - s.tripod_base(i))))
            for i in range(3)
        ]
        comment = "strut lengths l_i = |p - S_i| (tripodkins' inverse)"
    centre_pairs = tuple((fkd.S[i][k], centres[i][k]) for i in range(3) for k in range(3))
    mode = Stage(
        "the side of the centre plane p lies on: det of the rows p - S_i",
        (*vel.rows_stage().assignments, (fkd.det_D, vel.D.det())),
    )
    # the direct kinematics returns the intersection with det_D e_z of the sign of `side`
    chosen = -1 if kind == LINEAR else s.side
    other_side = sp.And(chosen * fkd.det_D * centre_normal_z < 0, sp.Abs(fkd.det_D) > det_limit)
    if kind == LINEAR:
        no_reach = sp.Or(*(radicand[i] < 0 for i in range(3)), other_side)
        near = sp.Or(*(radicand[i] <= ik_limit for i in range(3)))
    else:
        no_reach, near = other_side, sp.Abs(fkd.det_D) <= det_limit
    inputs = [v for entry in _POSITIONS[:levels] for v in entry[0]]
    flags = Stage(
        "status flags: non-finite input, unreachable (or the other side), singular",
        (
            (invalid, sp.Not(AllFinite(*inputs))),
            (unreachable, no_reach),
            (singular, near),
        ),
    )
    status = sp.Piecewise(
        (st.INVALID, invalid), (st.UNREACHABLE, unreachable), (st.SINGULAR, singular), (st.OK, True)
    )
    no_q = sp.Or(invalid, unreachable)
    # the joint rates are infinite where a linear delta's arm lies horizontal (g_i = 0, the
    # SINGULAR of its ik); a tripod's exist at its base-plane singularity (g_i = l_i)
    no_rates = sp.Or(no_q, singular) if kind == LINEAR else no_q
    ports, out_pairs = [], ()
    for level in range(levels):
        symbols, pname, pdoc, unit = _JOINTS[kind][level]
        outs, stage = _masked([str(q) for q in symbols], symbols, no_q if level == 0 else no_rates)
        out_pairs += stage
        ports.append(Port(pname, outs, pdoc, unit, width=3))
    what = (
        "carriage heights h (Klipper's delta kinematics)"
        if kind == LINEAR
        else "strut lengths l (tripodkins)"
    )
    name, doc = {
        1: ("ik", f"Inverse kinematics: point p -> {what}."),
        2: ("ik_vel", f"Inverse kinematics at velocity level: (p, pdot) -> {what} and rates."),
        3: (
            "ik_acc",
            f"Inverse kinematics at acceleration level: (p, pdot, pddot) -> {what}, "
            "rates and accelerations.",
        ),
    }[levels]
    return Kernel(
        name=name,
        doc=doc,
        inputs=tuple(Port(n_, sy, d, u, width=3) for sy, n_, d, u in _POSITIONS[:levels]),
        outputs=tuple(ports),
        stages=(
            Stage(comment, tuple(joint_values)),
            Stage("sphere centres S_i", centre_pairs),
            mode,
            flags,
            *(_inverse_rate_stages(kind, levels) if levels > 1 else ()),
            Stage("outputs (NaN where the status says they do not exist)", out_pairs),
        ),
        status=status,
        parameters=PARAMETERS[kind],
        setup=_setup(kind),
        status_doc="OK; INVALID (non-finite input); UNREACHABLE ("
        + ("an arm cannot reach, or " if kind == LINEAR else "")
        + "p on the other side of the centre plane than the direct kinematics returns); "
        "SINGULAR ("
        + (
            "an arm within singular_tol of horizontal"
            if kind == LINEAR
            else "p within tolerance of the base plane"
        )
        + "; the joints are still given)"
        + (
            ""
            if levels == 1
            else "; the rates are NaN unless OK"
            if kind == LINEAR
            else "; the rates are given wherever the joints are"
        ),
    )


@cache
def all_kernels(kind: str) -> tuple:
    """fk, fk_vel, fk_acc, jacobian, ik, ik_vel and ik_acc of ``kind`` ("linear_delta" or
    "tripod")."""
    what = "carriage heights h" if kind == LINEAR else "strut lengths l"
    return (
        _fk_kernel(kind, 1, "fk", f"Direct kinematics: {what} -> point p (three spheres)."),
        _fk_kernel(kind, 2, "fk_vel", f"Velocity level: ({what}, rates) -> (p, pdot)."),
        _fk_kernel(
            kind,
            3,
            "fk_acc",
            f"Acceleration level: ({what}, rates, accelerations) -> (p, pdot, pddot).",
        ),
        _jacobian_kernel(kind),
        _ik_kernel(kind),
        _ik_kernel(kind, 2),
        _ik_kernel(kind, 3),
    )
