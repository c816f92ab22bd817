"""The peer libraries of ``deltagen bench``: roboticstoolbox-python's Puma560
(``rtb.models.DH.Puma560()``: the Python ``DHRobot`` calls and the C++ ``ETS`` fast path) and
pinocchio (a model built here from the arm's DH table), each library call timed round-robin
with the matching deltagen call on the same inputs in the same process, with their
agreement. ``pip install deltagen[bench]`` brings both; each is skipped (and named as
absent) when it is not importable, or on request (``DELTAGEN_BENCH_ORACLES=0``).
"""

from __future__ import annotations

import numpy as np

from deltagen.apps.bench.timing import Style, batch_timer, cell, interleaved, loop_timer, ratio
from deltagen.geometry.rotations import rot_axis

RTB_PY_BATCH_N = 2_000  # DHRobot.fkine on a batch is a Python loop (~50 us per configuration)
RTB_C_BATCH_N = 100_000  # ETS.eval (C++) on a batch, ~1 us per configuration
RTB_SE3_BATCH_N = 20_000  # ETS.fkine on a batch: C++ then one SE3 per configuration
ORACLE_AGREEMENT_N = 200  # configurations compared with each library
ORACLE_TOL = 1e-12


def _tz(dz: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = dz
    return T


def _pair(library, call, lib_fn, dg_call, dg_fn, repeats, unit="us", points=1):
    """One comparison row: the library call and the deltagen call timed round-robin."""
    if unit == "us":
        timers = [loop_timer(lib_fn), loop_timer(dg_fn)]
    else:
        lib_fn(), dg_fn()  # warm-up
        timers = [batch_timer(lib_fn, (), points), batch_timer(dg_fn, (), points)]
    lib, dg = interleaved(timers, repeats)
    return {
        "library": library,
        "call": call,
        "lib": lib,
        "dg_call": dg_call,
        "dg": dg,
        "unit": unit,
        "points": points,
    }


def _rtb_oracle(compiled, q, repeats, rates):
    """roboticstoolbox-python's Puma560: rows, agreement notes (raises ImportError)."""
    import roboticstoolbox as rtb

    puma = rtb.models.DH.Puma560()
    ets = puma.ets()
    n = compiled.n
    q1 = np.ascontiguousarray(q[0])
    # rtb puts the shoulder d1 = 26.45 in above the mount; deltagen's file may round it:
    # both are standard DH, so T_rtb = Trans_z(d1_rtb - d1_deltagen) T_deltagen and the
    # base-frame geometric Jacobians are equal.
    d1_dg, d1_rtb = compiled.description.joints[0].d, float(puma.links[0].d)
    shift = _tz(d1_rtb - d1_dg)
    m = min(ORACLE_AGREEMENT_N, q.shape[0])
    T_dg = compiled.fk(q[:m])
    T_rtb = np.array([T.A for T in puma.fkine(q[:m])])
    T_ets = ets.eval(q[:m])
    J_dg = compiled.jacobian(q[:m])
    J_rtb = np.array([puma.jacob0(row) for row in q[:m]])
    J_ets = np.array([ets.jacob0(row) for row in q[:m]])
    agree = {
        "fk (DHRobot.fkine)": float(np.max(np.abs(shift @ T_dg - T_rtb))),
        "fk (ETS.eval)": float(np.max(np.abs(shift @ T_dg - T_ets))),
        "jacobian (DHRobot.jacob0)": float(np.max(np.abs(J_dg - J_rtb))),
        "jacobian (ETS.jacob0)": float(np.max(np.abs(J_dg - J_ets))),
    }
    notes = []
    if d1_dg != d1_rtb:
        notes.append(
            f"d1: deltagen {d1_dg:.10g} m, rtb {d1_rtb:.10g} m (26.45 in); fk compared "
            f"as Trans_z({d1_rtb - d1_dg:+.3g} m) T_deltagen"
        )

    lib = f"rtb {rtb.__version__}"
    fk1, jac1 = f"robot.fk(q), q ndarray ({n},)", f"robot.jacobian(q), q ndarray ({n},)"
    fk_dg, jac_dg = (fk1, lambda: compiled.fk(q1)), (jac1, lambda: compiled.jacobian(q1))
    singles = (
        ("DHRobot.fkine(q) -> SE3 (Python)", lambda: puma.fkine(q1), fk_dg),
        ("ETS.fkine(q) -> SE3 (C++ fknm)", lambda: ets.fkine(q1), fk_dg),
        ("ETS.eval(q) -> ndarray (C++ fknm)", lambda: ets.eval(q1), fk_dg),
        ("DHRobot.jacob0(q) (Python)", lambda: puma.jacob0(q1), jac_dg),
        ("ETS.jacob0(q) (C++ fknm)", lambda: ets.jacob0(q1), jac_dg),
    )
    rows = [
        _pair(lib, call, lib_fn, dg_call, dg_fn, repeats)
        for call, lib_fn, (dg_call, dg_fn) in singles
    ]
    for call, fn, size in (
        ("DHRobot.fkine(Q) -> SE3 of N values (Python loop)", puma.fkine, RTB_PY_BATCH_N),
        ("ETS.fkine(Q) -> SE3 of N values (C++ + SE3s)", ets.fkine, RTB_SE3_BATCH_N),
        ("ETS.eval(Q) -> ndarray (N, 4, 4) (C++ fknm)", ets.eval, RTB_C_BATCH_N),
    ):
        size = min(size, q.shape[0])
        Q = np.ascontiguousarray(q[:size])
        rows.append(
            _pair(
                lib,
                call,
                lambda f=fn, Q=Q: f(Q),
                f"robot.fk(Q), Q ({size:,}, {n})",
                lambda Q=Q: compiled.fk(Q),
                repeats,
                unit="ns",
                points=size,
            )
        )
    return rows, agree, notes


def pinocchio_model(description):
    """A pinocchio Model of a standard-DH arm and the id of its tool frame: joint i is a
    revolute (prismatic) joint about (along) z_{i-1}, placed at the fixed part
    Trans_z(d) Trans_x(a) Rot_x(alpha) of the link before it; the tool frame sits on the
    last joint at the last fixed part times the tool transform. With inertial parameters,
    link i's body is appended at frame i (that fixed part), with armature and gravity."""
    import pinocchio as pin

    if description.convention != "standard":
        raise ValueError("pinocchio_model handles standard DH only")
    model = pin.Model()
    parent = 0
    placement = pin.SE3(description.base[:3, :3].copy(), description.base[:3, 3].copy())
    for i, joint in enumerate(description.joints):
        # A_i = Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha) with theta = q + offset
        # (revolute) or d = q + offset (prismatic): the constant part before the joint's own
        # motion, Rot_z(offset) or Rot_z(theta) Trans_z(offset), goes into its placement
        turn = joint.offset if joint.revolute else joint.theta
        shift = 0.0 if joint.revolute else joint.offset
        pre = pin.SE3(rot_axis("z", turn), np.array([0.0, 0.0, shift]))
        if joint.sign == 1.0:
            kind = pin.JointModelRZ() if joint.revolute else pin.JointModelPZ()
        elif joint.revolute:  # a reversed joint turns / slides about -z
            kind = pin.JointModelRevoluteUnaligned(np.array([0.0, 0.0, -1.0]))
        else:
            kind = pin.JointModelPrismaticUnaligned(np.array([0.0, 0.0, -1.0]))
        parent = model.addJoint(parent, kind, placement * pre, f"joint{i + 1}")
        placement = pin.SE3(
            rot_axis("x", joint.alpha), np.array([joint.a, 0.0, joint.d if joint.revolute else 0.0])
        )
        if description.has_inertia:  # link i's inertials live in frame i = this placement
            x = joint.inertial
            model.appendBodyToJoint(
                parent, pin.Inertia(x.mass, np.array(x.com), x.inertia_matrix), placement
            )
    if description.has_inertia:
        model.armature = np.array([j.inertial.armature for j in description.joints])
        model.gravity.linear = np.array(description.gravity)
    tool = placement * pin.SE3(description.tool[:3, :3].copy(), description.tool[:3, 3].copy())
    fid = model.addFrame(pin.Frame("tool", parent, 0, tool, pin.FrameType.OP_FRAME))
    return model, fid


def _pinocchio_oracle(compiled, q, repeats, rates):
    """pinocchio on the same DH table: rows, agreement (raises ImportError)."""
    import pinocchio as pin

    model, fid = pinocchio_model(compiled.description)
    data = model.createData()
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED  # base axes, tool point: deltagen's J
    m = min(ORACLE_AGREEMENT_N, q.shape[0])
    err_T = err_J = 0.0
    T_dg, J_dg = compiled.fk(q[:m]), compiled.jacobian(q[:m])
    for k in range(m):
        pin.forwardKinematics(model, data, q[k])
        pin.updateFramePlacements(model, data)
        err_T = max(err_T, float(np.max(np.abs(data.oMf[fid].homogeneous - T_dg[k]))))
        pin.computeJointJacobians(model, data, q[k])
        J = pin.getFrameJacobian(model, data, fid, world)
        err_J = max(err_J, float(np.max(np.abs(J - J_dg[k]))))
    agree = {"fk (oMf[tool])": err_T, "jacobian (getFrameJacobian)": err_J}

    n, q1 = compiled.n, np.ascontiguousarray(q[0])
    fk1, jac1 = f"robot.fk(q), q ndarray ({n},)", f"robot.jacobian(q), q ndarray ({n},)"
    lib = f"pinocchio {pin.__version__}"

    def fk_update():
        pin.forwardKinematics(model, data, q1)
        pin.updateFramePlacements(model, data)

    def fk_pose():
        pin.framesForwardKinematics(model, data, q1)
        return data.oMf[fid].homogeneous

    def jac_get():
        pin.computeJointJacobians(model, data, q1)
        return pin.getFrameJacobian(model, data, fid, world)

    fk_dg, jac_dg = (fk1, lambda: compiled.fk(q1)), (jac1, lambda: compiled.jacobian(q1))
    singles = (
        ("forwardKinematics + updateFramePlacements", fk_update, fk_dg),
        ("framesForwardKinematics + oMf[tool].homogeneous", fk_pose, fk_dg),
        ("computeJointJacobians + getFrameJacobian", jac_get, jac_dg),
        (
            "computeFrameJacobian(q, tool)",
            lambda: pin.computeFrameJacobian(model, data, q1, fid, world),
            jac_dg,
        ),
    )
    rows = [
        _pair(lib, call, lib_fn, dg_call, dg_fn, repeats)
        for call, lib_fn, (dg_call, dg_fn) in singles
    ]
    if compiled.description.has_inertia:
        dyn_rows, dyn_agree = _pinocchio_dynamics(pin, model, compiled, q, repeats, rates)
        rows += dyn_rows
        agree.update(dyn_agree)
    return rows, agree, []


PIN_BATCH_N = 2_000  # pinocchio's per-configuration calls looped from Python


def _pinocchio_dynamics(pin, model, compiled, q, repeats, rates):
    """rnea / crba / aba beside inverse_dynamics / mass_matrix / forward_dynamics: single
    calls, Python-looped batches against the batched C core, and agreement (relative to
    max(1, |value|); pinocchio has no friction: the Puma's is added to its rnea)."""
    data = model.createData()
    n = compiled.n
    qd_range, qdd_range, seed = rates
    rng = np.random.default_rng(seed)
    m = min(PIN_BATCH_N, q.shape[0])
    qb = np.ascontiguousarray(q[:m])
    qdb = np.ascontiguousarray(rng.uniform(*qd_range, (m, n)))
    qddb = np.ascontiguousarray(rng.uniform(*qdd_range, (m, n)))
    desc = compiled.description
    viscous = np.array([j.inertial.viscous for j in desc.joints])
    plus = np.array([j.inertial.coulomb[0] for j in desc.joints])
    minus = np.array([j.inertial.coulomb[1] for j in desc.joints])
    friction = viscous * qdb + np.where(qdb > 0, plus, np.where(qdb < 0, minus, 0.0))
    k = min(ORACLE_AGREEMENT_N, m)
    tau_dg = compiled.inverse_dynamics(qb[:k], qdb[:k], qddb[:k])
    M_dg = compiled.mass_matrix(qb[:k])
    rigid = tau_dg - friction[:k]  # what pinocchio's aba takes
    qdd_dg = compiled.forward_dynamics(qb[:k], qdb[:k], tau_dg)
    err = {"rnea": 0.0, "crba": 0.0, "aba": 0.0}
    for i in range(k):
        tau = pin.rnea(model, data, qb[i], qdb[i], qddb[i]) + friction[i]
        M = pin.crba(model, data, qb[i])
        M = np.triu(M) + np.triu(M, 1).T
        qdd = pin.aba(model, data, qb[i], qdb[i], rigid[i])
        for key, a, b in (("rnea", tau, tau_dg[i]), ("crba", M, M_dg[i]), ("aba", qdd, qdd_dg[i])):
            err[key] = max(err[key], float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(a)))))
    agree = {
        "inverse_dynamics (rnea + friction, relative)": err["rnea"],
        "mass_matrix (crba, relative)": err["crba"],
        "forward_dynamics (aba, relative)": err["aba"],
    }
    lib = f"pinocchio {pin.__version__}"
    q1, qd1, qdd1 = qb[0].copy(), qdb[0].copy(), qddb[0].copy()
    tau1 = compiled.inverse_dynamics(q1, qd1, qdd1)
    core = compiled._core
    taub = compiled.inverse_dynamics(qb, qdb, qddb)

    def loop(fn):
        def run():
            for i in range(m):
                fn(i)

        return run

    singles = (
        (
            "rnea(q, v, a)",
            lambda: pin.rnea(model, data, q1, qd1, qdd1),
            f"robot.inverse_dynamics(q, qd, qdd), ndarrays ({n},)",
            lambda: compiled.inverse_dynamics(q1, qd1, qdd1),
        ),
        (
            "crba(q)",
            lambda: pin.crba(model, data, q1),
            f"robot.mass_matrix(q), q ndarray ({n},)",
            lambda: compiled.mass_matrix(q1),
        ),
        (
            "aba(q, v, tau)",
            lambda: pin.aba(model, data, q1, qd1, tau1),
            f"robot.forward_dynamics(q, qd, tau), ndarrays ({n},)",
            lambda: compiled.forward_dynamics(q1, qd1, tau1),
        ),
    )
    batches = (
        (
            "rnea",
            lambda i: pin.rnea(model, data, qb[i], qdb[i], qddb[i]),
            "robot._core.inverse_dynamics(q, qd, qdd), (N, 6)",
            lambda: core.inverse_dynamics(qb, qdb, qddb),
        ),
        (
            "crba",
            lambda i: pin.crba(model, data, qb[i]),
            "robot._core.mass_matrix(q), (N, 6)",
            lambda: core.mass_matrix(qb),
        ),
        (
            "aba",
            lambda i: pin.aba(model, data, qb[i], qdb[i], taub[i]),
            "robot._core.forward_dynamics(q, qd, tau), (N, 6)",
            lambda: core.forward_dynamics(qb, qdb, taub),
        ),
    )
    rows = [_pair(lib, *row, repeats) for row in singles]
    rows += [
        _pair(
            lib,
            f"{name} looped over {m:,} configurations",
            loop(one),
            dg_call,
            dg_fn,
            repeats,
            unit="ns",
            points=m,
        )
        for name, one, dg_call, dg_fn in batches
    ]
    return rows, agree


def library_versions() -> dict[str, str | None]:
    from importlib import metadata

    out: dict[str, str | None] = {}
    for dist in ("roboticstoolbox-python", "pin"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def measure(compiled, q, repeats, rates, enabled=True):
    """{"rows": [...], "agreement": {library: {what: max abs diff}}, "notes": [...],
    "absent": [text]} for roboticstoolbox-python and pinocchio, each when importable, on the
    arm's configurations ``q``; ``rates``: (qd range, qdd range, seed) of the dynamics'
    inputs."""
    result = {"rows": [], "agreement": {}, "notes": [], "absent": []}
    if not enabled:
        result["absent"].append(
            "roboticstoolbox-python and pinocchio skipped (DELTAGEN_BENCH_ORACLES=0)"
        )
        return result
    for label, module, measure_one in (
        ("roboticstoolbox-python", "roboticstoolbox", _rtb_oracle),
        ("pinocchio (pip: pin)", "pinocchio", _pinocchio_oracle),
    ):
        try:
            __import__(module)
        except Exception as exc:  # noqa: BLE001 - absent or broken: say so, go on
            result["absent"].append(
                f"{label} not importable ({type(exc).__name__}); `pip install deltagen[bench]`"
            )
            continue
        rows, agree, notes = measure_one(compiled, q, repeats, rates)
        result["rows"] += rows
        result["agreement"][label] = agree
        result["notes"] += notes
    return result


def rtb_model(arm):
    """roboticstoolbox-python DHRobot of a standard- or modified-DH deltagen arm of revolute
    joints (same table, offsets, limits, base and tool), or None if rtb is missing."""
    try:
        import roboticstoolbox as rtb
        import spatialmath as sm
    except ImportError:
        return None
    d = arm.description
    if d.convention not in ("standard", "modified") or not all(j.revolute for j in d.joints):
        return None
    link = rtb.RevoluteDH if d.convention == "standard" else rtb.RevoluteMDH
    links = [
        link(d=j.d, a=j.a, alpha=j.alpha, offset=j.offset, qlim=list(lim))
        for j, lim in zip(d.joints, arm.qlim)
    ]
    return rtb.DHRobot(
        links, base=sm.SE3(np.array(d.base)), tool=sm.SE3(np.array(d.tool)), name=d.name
    )


def render(others: dict, robot_name: str, n: int, style: Style) -> list[str]:
    """The tables beside the other libraries (single calls, batches), their agreement and
    the libraries not measured."""
    out: list[str] = []
    code, bullet = style.code, style.bullet
    if others["rows"]:
        out.append("")
        for unit, title, scale in (
            ("us", "single call, us per call", 1000.0),
            ("ns", "batch, ns per configuration", 1.0),
        ):
            rows = [
                [
                    r["library"],
                    code(r["call"]),
                    cell(r["lib"], scale),
                    code(r["dg_call"]),
                    cell(r["dg"], scale),
                    ratio(r["lib"], r["dg"]),
                ]
                for r in others["rows"]
                if r["unit"] == unit
            ]
            if not rows:
                continue
            out.append(style.h(f"{robot_name} vs other libraries: {title}"))
            out.append("")
            header = ["library", "call", "library time", "deltagen call"]
            header += ["deltagen time (compiled)", "library / deltagen"]
            out += style.table(header, rows)
            out.append("")
        for library, agree in others["agreement"].items():
            text = ", ".join(f"{k} {v:.1e}" for k, v in agree.items())
            out.append(
                f"{bullet}agreement with {library}, max |deltagen - library| over "
                f"{min(ORACLE_AGREEMENT_N, n)} configurations: {text}"
            )
            bad = [k for k, v in agree.items() if not v <= ORACLE_TOL]
            if bad:
                out.append(
                    f"{bullet}WARNING: deltagen and {library} disagree on "
                    f"{', '.join(bad)} (> {ORACLE_TOL:g})"
                )
        for note in others["notes"]:
            out.append(f"{bullet}{note}")
        out.append(
            f"{bullet}each library call is timed round-robin with the deltagen call beside "
            "it (single calls looped ~25 ms per repeat; batches on the same "
            "configurations)"
        )
    for text in others["absent"]:
        out.append(f"{bullet}{text}")
    return out
