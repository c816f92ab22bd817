"""`deltagen bench`: throughput (ns per point) and single-pose latency of the delta
kinematics, compiled C core vs the numpy reference, measured in one run.

Throughput. N random reachable poses of ``DeltaRobot.default()`` (crank angles uniform in
[-0.3, 0.9] rad, velocities and accelerations uniform, platform positions from fk for ik;
every row checked OK so no call raises). Each quantity is timed at three levels:

* ``C kernel``: the generated C function called directly with preallocated outputs
  (the core's own loop, no numpy allocation); a diagnostic column.
* ``_core``: the raw batched backend ``robot._core.<fn>`` ((N, 3) float64 C-contiguous in,
  fresh output arrays out); the throughput targets are checked against this column.
* ``API``: the public method ``robot.<fn>`` with argument validation and status checks.

The reference runs on the first ``min(N, 200 000)`` of the same poses (it is tens of times slower)
and is reported per point as well. Every cell is the median over ``--repeats`` timed calls
after one warm-up call, with [min, max] of those repeats; time.perf_counter_ns, garbage
collector off while timing, and the columns of a row timed round-robin (repeat 1 of every
column, then repeat 2, ...) so that load from other processes on a shared machine hits
them alike. Speedups are ratios of medians measured in this run.

Latency. One single-pose call from Python (``robot.fk(q)`` with a (3,) ndarray and with a
list, ``robot.ik(p)`` likewise, and the raw ``robot._core`` call on a (1, 3) array), looped
so that one repeat lasts ~25 ms; median of the repeats in microseconds per call.

Serial arm. The same measurements for the Puma560 (``SerialRobot.load("puma560")``, six
revolute joints, q uniform within its joint limits, qd uniform): fk, frames, jacobian and
jacobian_dot per configuration (frames and jacobian_dot on the first ``min(N, 250 000)``
configurations: frames writes 1 KiB per configuration), the numpy reference on the first
``min(N, 100 000)``, and single-pose latency. When importable, the same run then times
roboticstoolbox-python's Puma560 (``rtb.models.DH.Puma560()``: the Python ``DHRobot`` calls and
the C++ ``ETS`` fast path) and pinocchio (a model built here from the Puma560's DH table),
each library call interleaved with the matching deltagen call, and prints the ratio
library / deltagen and their agreement. ``pip install deltagen[bench]`` brings both; they are
skipped (and named as absent) otherwise, or on request (``DELTAGEN_BENCH_ORACLES=0``).

The tables above are single-threaded: the robots are made with ``threads=1`` (the C core is
a plain loop; ``-fopenmp-simd`` only vectorises, it starts no threads) and the reference
uses numpy ufuncs and batched 3x3 solves, so OPENBLAS_NUM_THREADS / OMP_NUM_THREADS make no
difference.

All cores. A last section times delta fk, Puma560 fk and Puma560 jacobian through
``robot._core`` with ``threads=1`` and with the default thread count (DELTAGEN_THREADS, else
the available cores; native.parallel splits batches of at least 2 x MIN_ROWS_PER_THREAD
rows into row chunks on a thread pool), round-robin, and prints the speedup.

Other machine families. The linear delta's, the tripod's, the hexapod's and a 5-axis
machine's cores beside the rotary delta's fk and ik (``bench_families``), ns per point
through ``_core``, threads=1.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sysconfig
import time

import numpy as np

from deltagen import status as st
from deltagen.apps.bench.timing import Stat, batch_timer, interleaved, loop_timer, table
from deltagen.geometry.rotations import rot_axis
from deltagen.inputs import check_memory

QUANTITIES = ("fk", "fk_vel", "fk_acc", "jacobian", "ik", "inverse_dynamics")
#: The throughput targets for the compiled core [ns per point].
TARGETS_NS = {"fk": 12.0, "fk_vel": 12.0, "fk_acc": 16.0, "ik": 20.0, "inverse_dynamics": 30.0}
#: The targets for one single-pose call from Python [ns]: fk and ik.
SINGLE_TARGET_NS = {"fk": 600.0, "ik": 1500.0}
REFERENCE_N = 200_000
Q_RANGE = (-0.3, 0.9)  # rad; well inside the default robot's workspace
QD_RANGE = (-2.0, 2.0)  # rad/s
QDD_RANGE = (-20.0, 20.0)  # rad/s^2
SEED = 2008
AGREEMENT_TOL = 1e-9  # max abs difference compiled vs reference before a warning

# name -> (inputs, number of outputs, output width or None for the input width)
_SIGNATURES = {
    "fk": (("q",), 1, None),
    "fk_vel": (("q", "qd"), 2, None),
    "fk_acc": (("q", "qd", "qdd"), 3, None),
    "jacobian": (("q",), 1, 9),
    "ik": (("p",), 1, None),
    "inverse_dynamics": (("q", "qd", "qdd", "payload"), 1, None),  # exact model
}
_UNITS = {
    "fk": "m",
    "fk_vel": "m/s",
    "fk_acc": "m/s^2",
    "jacobian": "m/rad",
    "ik": "rad",
    "inverse_dynamics": "N m",
}
PAYLOAD_RANGE = (0.0, 2.0)  # kg


# ------------------------------------------------------------------------- timing


# ------------------------------------------------------------------------- inputs


def _valid_rows(core, q, qd, qdd):
    """Rows that are OK for every quantity (fk_acc covers fk, fk_vel and jacobian) and
    whose fk position gives an OK ik; also returns that position."""
    _, _, _, s_acc = core.fk_acc(q, qd, qdd)
    p, s_fk = core.fk(q)
    _, s_jac = core.jacobian(q)
    p_safe = np.ascontiguousarray(np.where(np.isfinite(p), p, 0.0))
    _, s_ik = core.ik(p_safe)
    ok = (s_acc == st.OK) & (s_fk == st.OK) & (s_jac == st.OK) & (s_ik == st.OK)
    return ok, p


def sample_poses(n: int, cores, rng) -> dict[str, np.ndarray]:
    """n rows of q, qd, qdd and p = fk(q), all OK for every core in ``cores``."""
    parts = {k: [] for k in ("q", "qd", "qdd", "p", "payload")}
    have, tries = 0, 0
    while have < n:
        tries += 1
        if tries > 50:
            raise RuntimeError("could not sample valid poses (is the C core broken?)")
        m = int((n - have) * 1.05) + 64
        q = rng.uniform(*Q_RANGE, (m, 3))
        qd = rng.uniform(*QD_RANGE, (m, 3))
        qdd = rng.uniform(*QDD_RANGE, (m, 3))
        ok = np.ones(m, dtype=bool)
        p = None
        for core in cores:
            ok_c, p_c = _valid_rows(core, q, qd, qdd)
            ok &= ok_c
            p = p_c if p is None else p  # positions from the first core (compiled)
        take = np.flatnonzero(ok)[: n - have]
        payload = rng.uniform(*PAYLOAD_RANGE, m)
        for key, arr in (("q", q), ("qd", qd), ("qdd", qdd), ("p", p), ("payload", payload)):
            parts[key].append(arr[take])
        have += take.size
    return {k: np.ascontiguousarray(np.concatenate(v)) for k, v in parts.items()}


def _prefix(poses: dict, n: int) -> dict:
    return {k: np.ascontiguousarray(v[:n]) for k, v in poses.items()}


# ------------------------------------------------------------------------- measurements


def _kernel_callable(core, name: str, inputs: list[np.ndarray]):
    """A no-argument call of the generated C function with preallocated outputs, or None
    if the core is not the cffi one or its ABI is not the expected one."""
    try:
        ffi, lib, geometry = core._ffi, core._lib, core._geometry
        _, n_out, width = _SIGNATURES[name]
        n, axes = inputs[0].shape
        outs = [np.empty((n, width or axes)) for _ in range(n_out)]
        status = np.empty(n, dtype=np.int8)
        fb = ffi.from_buffer
        cargs = (
            geometry,
            n,
            axes,
            *(fb("double[]", a) for a in inputs),
            *(fb("double[]", o, require_writable=True) for o in outs),
            fb("int8_t[]", status, require_writable=True),
        )
        fn = getattr(lib, f"deltagen_delta_{name}")
        if fn(*cargs) != 0:
            return None
        keep = (inputs, outs, status)  # the buffers must outlive the call object
        return lambda: (fn(*cargs), keep)[0]
    except Exception:  # noqa: BLE001 - a diagnostic column; the others still run
        return None


def _first_output(result):
    return np.asarray(result[0] if isinstance(result, tuple) else result)


def _measure_throughput(compiled, reference, poses, ref_poses, repeats):
    """({quantity: {column: Stat in ns/point}}, {quantity: max |compiled - reference|}).

    Per quantity, one warm-up call of each column (whose first outputs give the
    agreement), then the timed calls round-robin over the columns."""
    n, ref_n = poses["q"].shape[0], ref_poses["q"].shape[0]
    stats, agreement = {}, {}
    for name in QUANTITIES:
        inputs = [poses[k] for k in _SIGNATURES[name][0]]
        ref_inputs = [ref_poses[k] for k in _SIGNATURES[name][0]]
        columns = {}
        kernel = _kernel_callable(compiled._core, name, inputs)
        if kernel is not None:
            kernel()
            columns["kernel"] = batch_timer(kernel, (), n)
        comp_out = _first_output(getattr(compiled._core, name)(*inputs))[:ref_n].copy()
        ref_out = _first_output(getattr(reference._core, name)(*ref_inputs))
        agreement[name] = float(np.max(np.abs(comp_out - ref_out)))
        del comp_out, ref_out
        for label, robot, args, points in (
            ("core", compiled._core, inputs, n),
            ("api", compiled, inputs, n),
            ("ref_core", reference._core, ref_inputs, ref_n),
            ("ref_api", reference, ref_inputs, ref_n),
        ):
            fn = getattr(robot, name)
            if label.endswith("api"):
                fn(*args)  # warm-up (the _core ones ran above)
            columns[label] = batch_timer(fn, args, points)
        stats[name] = dict(zip(columns, interleaved(list(columns.values()), repeats)))
    return stats, agreement


def _latency_calls(robot, q1, p1):
    ql, pl = [float(v) for v in q1], [float(v) for v in p1]
    q2, p2 = np.ascontiguousarray(q1[None, :]), np.ascontiguousarray(p1[None, :])
    fk, ik = SINGLE_TARGET_NS["fk"], SINGLE_TARGET_NS["ik"]
    return [
        ("robot.fk(q), q ndarray (3,)", lambda: robot.fk(q1), fk),
        ("robot.fk(q), q list of 3 floats", lambda: robot.fk(ql), fk),
        ("robot.ik(p), p ndarray (3,)", lambda: robot.ik(p1), ik),
        ("robot.ik(p), p list of 3 floats", lambda: robot.ik(pl), ik),
        ("robot.fk_vel(q, qd), ndarrays (3,)", lambda: robot.fk_vel(q1, q1), None),
        ("robot.fk_acc(q, qd, qdd), ndarrays (3,)", lambda: robot.fk_acc(q1, q1, q1), None),
        ("robot.jacobian(q), q ndarray (3,)", lambda: robot.jacobian(q1), None),
        (
            "robot.inverse_dynamics(q, qd, qdd, 0.5), ndarrays (3,)",
            lambda: robot.inverse_dynamics(q1, q1, q1, 0.5),
            None,
        ),
        ("robot._core.fk(q), q (1, 3)", lambda: robot._core.fk(q2), None),
        ("robot._core.ik(p), p (1, 3)", lambda: robot._core.ik(p2), None),
    ]


def _measure_latency(compiled, reference, q1, p1, repeats):
    """[(label, compiled Stat, reference Stat, has target)] in ns per call."""
    rows = []
    for (label, fn, target), (_, ref_fn, _) in zip(
        _latency_calls(compiled, q1, p1), _latency_calls(reference, q1, p1)
    ):
        comp, ref = interleaved([loop_timer(fn), loop_timer(ref_fn)], repeats)
        rows.append((label, comp, ref, target))
    return rows


# ------------------------------------------------------------------------- serial arm

SERIAL_ROBOT = "puma560"
SERIAL_QUANTITIES = (
    "fk",
    "frames",
    "jacobian",
    "jacobian_dot",
    "inverse_dynamics",
    "mass_matrix",
    "forward_dynamics",
)
#: The serial-arm throughput targets for the compiled core [ns per configuration].
SERIAL_TARGETS_NS = {"fk": 30.0, "jacobian": 50.0, "inverse_dynamics": 150.0}
#: The targets for one single-pose serial call from Python [ns].
SERIAL_SINGLE_TARGET_NS = {"fk": 600.0, "jacobian": 500.0}
SERIAL_REFERENCE_N = 100_000
#: frames (n + 2 matrices, 1 KiB per configuration) and jacobian_dot run on fewer points
SERIAL_SMALL_N = 250_000
SERIAL_QD_RANGE = (-2.0, 2.0)  # rad/s
SERIAL_QDD_RANGE = (-5.0, 5.0)  # rad/s^2
RTB_PY_BATCH_N = 2_000  # DHRobot.fkine on a batch is a Python loop (~50 us per configuration)
RTB_C_BATCH_N = 100_000  # ETS.eval (C++) on a batch, ~1 us per configuration
RTB_SE3_BATCH_N = 20_000  # ETS.fkine on a batch: C++ then one SE3 per configuration
ORACLE_AGREEMENT_N = 200  # configurations compared with each library
ORACLE_TOL = 1e-12

_SERIAL_INPUTS = {
    "fk": ("q",),
    "frames": ("q",),
    "jacobian": ("q",),
    "jacobian_dot": ("q", "qd"),
    "inverse_dynamics": ("q", "qd", "qdd"),
    "mass_matrix": ("q",),
    "forward_dynamics": ("q", "qd", "tau"),
}
_SERIAL_UNITS = {
    "fk": "m",
    "frames": "m",
    "jacobian": "m/rad",
    "jacobian_dot": "m/(rad s)",
    "inverse_dynamics": "N m",
    "mass_matrix": "kg m^2",
    "forward_dynamics": "rad/s^2",
}


def _serial_width(name: str, n: int) -> int:
    return {
        "fk": 16,
        "frames": 16 * (n + 2),
        "jacobian": 6 * n,
        "jacobian_dot": 6 * n,
        "inverse_dynamics": n,
        "mass_matrix": n * n,
        "forward_dynamics": n,
    }[name]


def _serial_points(name: str, n: int) -> int:
    return n if name in ("fk", "jacobian") else min(n, SERIAL_SMALL_N)


def sample_serial(n: int, robot, rng) -> dict[str, np.ndarray]:
    """n configurations q uniform within the arm's joint limits, rates qd and accelerations
    qdd (C-contiguous); for arms with inertial parameters also tau, the numpy reference's
    inverse dynamics of (q, qd, qdd) on the first SERIAL_SMALL_N (forward dynamics input)."""
    lim = robot.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (n, robot.n))
    qd = rng.uniform(*SERIAL_QD_RANGE, (n, robot.n))
    qdd = rng.uniform(*SERIAL_QDD_RANGE, (n, robot.n))
    out = {"q": np.ascontiguousarray(q), "qd": np.ascontiguousarray(qd)}
    out["qdd"] = np.ascontiguousarray(qdd)
    if robot.description.has_inertia:
        from deltagen.reference import serial as reference

        m = min(n, SERIAL_SMALL_N)
        tau, _ = reference.inverse_dynamics(robot.description, q[:m], qd[:m], qdd[:m])
        out["tau"] = np.ascontiguousarray(tau)
    return out


def _serial_kernel_callable(core, name: str, inputs: list[np.ndarray]):
    """A no-argument call of the arm's generated C function ``deltagen_<robot>_<name>`` with
    preallocated outputs, or None if the core is not the cffi one."""
    try:
        ffi, fn = core.c_function(name)
        points, axes = inputs[0].shape
        out = np.empty((points, _serial_width(name, axes)))
        status = np.empty(points, dtype=np.int8)
        fb = ffi.from_buffer
        cargs = (
            points,
            *(fb("double[]", a) for a in inputs),
            fb("double[]", out, require_writable=True),
            fb("int8_t[]", status, require_writable=True),
        )
        if fn(*cargs) != 0 or not (status == st.OK).all():
            return None
        keep = (inputs, out, status)  # the buffers must outlive the call object
        return lambda: (fn(*cargs), keep)[0]
    except Exception:  # noqa: BLE001 - a diagnostic column; the others still run
        return None


def _measure_serial_throughput(compiled, reference, data, repeats):
    """({quantity: {column: Stat}}, {quantity: (points, reference points)},
    {quantity: max |compiled - reference|}); columns kernel, core, api, ref_core."""
    n = data["q"].shape[0]
    stats, sizes, agreement = {}, {}, {}
    for name in SERIAL_QUANTITIES:
        if any(k not in data for k in _SERIAL_INPUTS[name]):
            continue  # dynamics of an arm without inertial parameters
        points = _serial_points(name, n)
        ref_n = min(points, SERIAL_REFERENCE_N)
        inputs = [np.ascontiguousarray(data[k][:points]) for k in _SERIAL_INPUTS[name]]
        ref_inputs = [np.ascontiguousarray(a[:ref_n]) for a in inputs]
        columns = {}
        kernel = _serial_kernel_callable(compiled._core, name, inputs)
        if kernel is not None:
            columns["kernel"] = batch_timer(kernel, (), points)
        comp_out = getattr(compiled._core, name)(*inputs)[0][:ref_n].copy()
        ref_out = getattr(reference._core, name)(*ref_inputs)[0]
        agreement[name] = float(np.max(np.abs(comp_out - ref_out)))
        del comp_out, ref_out
        api = getattr(compiled, name)
        api(*inputs)  # warm-up (the _core ones ran above)
        columns["core"] = batch_timer(getattr(compiled._core, name), inputs, points)
        columns["api"] = batch_timer(api, inputs, points)
        columns["ref_core"] = batch_timer(getattr(reference._core, name), ref_inputs, ref_n)
        stats[name] = dict(zip(columns, interleaved(list(columns.values()), repeats)))
        sizes[name] = (points, ref_n)
    return stats, sizes, agreement


def _serial_latency_calls(robot, q1):
    n = q1.shape[0]
    ql = [float(v) for v in q1]
    q2 = np.ascontiguousarray(q1[None, :])
    fk, jac = SERIAL_SINGLE_TARGET_NS["fk"], SERIAL_SINGLE_TARGET_NS["jacobian"]
    return [
        (f"robot.fk(q), q ndarray ({n},)", lambda: robot.fk(q1), fk),
        (f"robot.fk(q), q list of {n} floats", lambda: robot.fk(ql), fk),
        (f"robot.jacobian(q), q ndarray ({n},)", lambda: robot.jacobian(q1), jac),
        (f"robot._core.fk(q), q (1, {n})", lambda: robot._core.fk(q2), None),
        (f"robot._core.jacobian(q), q (1, {n})", lambda: robot._core.jacobian(q2), None),
        (
            f"robot.inverse_dynamics(q, qd, qdd), ndarrays ({n},)",
            lambda: robot.inverse_dynamics(q1, q1, q1),
            None,
        ),
    ]


def _measure_serial_latency(compiled, reference, q1, repeats):
    """[(label, compiled Stat, reference Stat, has target)] in ns per call."""
    rows = []
    for (label, fn, target), (_, ref_fn, _) in zip(
        _serial_latency_calls(compiled, q1), _serial_latency_calls(reference, q1)
    ):
        comp, ref = interleaved([loop_timer(fn), loop_timer(ref_fn)], repeats)
        rows.append((label, comp, ref, target))
    return rows


# ------------------------------------------------------------------------- other libraries


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


def _rtb_oracle(compiled, q, repeats):
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
    rows = [
        _pair(
            lib,
            "DHRobot.fkine(q) -> SE3 (Python)",
            lambda: puma.fkine(q1),
            fk1,
            lambda: compiled.fk(q1),
            repeats,
        ),
        _pair(
            lib,
            "ETS.fkine(q) -> SE3 (C++ fknm)",
            lambda: ets.fkine(q1),
            fk1,
            lambda: compiled.fk(q1),
            repeats,
        ),
        _pair(
            lib,
            "ETS.eval(q) -> ndarray (C++ fknm)",
            lambda: ets.eval(q1),
            fk1,
            lambda: compiled.fk(q1),
            repeats,
        ),
        _pair(
            lib,
            "DHRobot.jacob0(q) (Python)",
            lambda: puma.jacob0(q1),
            jac1,
            lambda: compiled.jacobian(q1),
            repeats,
        ),
        _pair(
            lib,
            "ETS.jacob0(q) (C++ fknm)",
            lambda: ets.jacob0(q1),
            jac1,
            lambda: compiled.jacobian(q1),
            repeats,
        ),
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


def _pinocchio_oracle(compiled, q, repeats):
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

    rows = [
        _pair(
            lib,
            "forwardKinematics + updateFramePlacements",
            fk_update,
            fk1,
            lambda: compiled.fk(q1),
            repeats,
        ),
        _pair(
            lib,
            "framesForwardKinematics + oMf[tool].homogeneous",
            fk_pose,
            fk1,
            lambda: compiled.fk(q1),
            repeats,
        ),
        _pair(
            lib,
            "computeJointJacobians + getFrameJacobian",
            jac_get,
            jac1,
            lambda: compiled.jacobian(q1),
            repeats,
        ),
        _pair(
            lib,
            "computeFrameJacobian(q, tool)",
            lambda: pin.computeFrameJacobian(model, data, q1, fid, world),
            jac1,
            lambda: compiled.jacobian(q1),
            repeats,
        ),
    ]
    if compiled.description.has_inertia:
        dyn_rows, dyn_agree = _pinocchio_dynamics(pin, model, compiled, q, repeats)
        rows += dyn_rows
        agree.update(dyn_agree)
    return rows, agree, []


PIN_BATCH_N = 2_000  # pinocchio's per-configuration calls looped from Python


def _pinocchio_dynamics(pin, model, compiled, q, repeats):
    """rnea / crba / aba beside inverse_dynamics / mass_matrix / forward_dynamics: single
    calls, Python-looped batches against the batched C core, and agreement (relative to
    max(1, |value|); pinocchio has no friction: the Puma's is added to its rnea)."""
    data = model.createData()
    n = compiled.n
    rng = np.random.default_rng(SEED + 1)
    m = min(PIN_BATCH_N, q.shape[0])
    qb = np.ascontiguousarray(q[:m])
    qdb = np.ascontiguousarray(rng.uniform(*SERIAL_QD_RANGE, (m, n)))
    qddb = np.ascontiguousarray(rng.uniform(*SERIAL_QDD_RANGE, (m, n)))
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

    rows = [
        _pair(
            lib,
            "rnea(q, v, a)",
            lambda: pin.rnea(model, data, q1, qd1, qdd1),
            f"robot.inverse_dynamics(q, qd, qdd), ndarrays ({n},)",
            lambda: compiled.inverse_dynamics(q1, qd1, qdd1),
            repeats,
        ),
        _pair(
            lib,
            "crba(q)",
            lambda: pin.crba(model, data, q1),
            f"robot.mass_matrix(q), q ndarray ({n},)",
            lambda: compiled.mass_matrix(q1),
            repeats,
        ),
        _pair(
            lib,
            "aba(q, v, tau)",
            lambda: pin.aba(model, data, q1, qd1, tau1),
            f"robot.forward_dynamics(q, qd, tau), ndarrays ({n},)",
            lambda: compiled.forward_dynamics(q1, qd1, tau1),
            repeats,
        ),
        _pair(
            lib,
            f"rnea looped over {m:,} configurations",
            loop(lambda i: pin.rnea(model, data, qb[i], qdb[i], qddb[i])),
            "robot._core.inverse_dynamics(q, qd, qdd), (N, 6)",
            lambda: core.inverse_dynamics(qb, qdb, qddb),
            repeats,
            unit="ns",
            points=m,
        ),
        _pair(
            lib,
            f"crba looped over {m:,} configurations",
            loop(lambda i: pin.crba(model, data, qb[i])),
            "robot._core.mass_matrix(q), (N, 6)",
            lambda: core.mass_matrix(qb),
            repeats,
            unit="ns",
            points=m,
        ),
        _pair(
            lib,
            f"aba looped over {m:,} configurations",
            loop(lambda i: pin.aba(model, data, qb[i], qdb[i], taub[i])),
            "robot._core.forward_dynamics(q, qd, tau), (N, 6)",
            lambda: core.forward_dynamics(qb, qdb, taub),
            repeats,
            unit="ns",
            points=m,
        ),
    ]
    return rows, agree


def _library_versions() -> dict[str, str | None]:
    from importlib import metadata

    out = {}
    for dist in ("roboticstoolbox-python", "pin"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def _measure_oracles(compiled, q, repeats, enabled=True):
    """{"rows": [...], "agreement": {library: {what: max abs diff}}, "notes": [...],
    "absent": [text]} for roboticstoolbox-python and pinocchio, each when importable."""
    result = {"rows": [], "agreement": {}, "notes": [], "absent": []}
    if not enabled:
        result["absent"].append(
            "roboticstoolbox-python and pinocchio skipped (DELTAGEN_BENCH_ORACLES=0)"
        )
        return result
    for label, module, measure in (
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
        rows, agree, notes = measure(compiled, q, repeats)
        result["rows"] += rows
        result["agreement"][label] = agree
        result["notes"] += notes
    return result


def run_serial(n: int, repeats: int, oracles: bool = True) -> dict:
    """The serial-arm section (see the module docstring)."""
    from deltagen.api.serial import SerialRobot

    compiled = SerialRobot.load(SERIAL_ROBOT, backend="compiled", threads=1)
    reference = compiled.with_backend("reference")
    data = sample_serial(n, compiled, np.random.default_rng(SEED))
    throughput, sizes, agreement = _measure_serial_throughput(compiled, reference, data, repeats)
    latency = _measure_serial_latency(compiled, reference, data["q"][0].copy(), repeats)
    others = _measure_oracles(compiled, data["q"], repeats, enabled=oracles)
    from deltagen.apps.bench import ik as bench_ik

    # the full IK workload for real runs; a small one for quick (test) runs
    ik = bench_ik.run(
        compiled,
        reference,
        repeats,
        analytic_n=min(n, bench_ik.IK_ANALYTIC_N),
        numeric_n=bench_ik.IK_NUMERIC_N if n >= 100_000 else 20,
        peers=oracles,
    )
    return {
        "robot": compiled,
        "n": n,
        "sizes": sizes,
        "throughput": throughput,
        "agreement": agreement,
        "latency": latency,
        "oracles": others,
        "ik": ik,
    }


# ------------------------------------------------------------------------- machine


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _compiler() -> str:
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=10)
        first = out.stdout.splitlines()[0].strip() if out.stdout else ""
        return f"{cc}: {first}" if first else cc
    except (OSError, subprocess.SubprocessError, IndexError):
        return cc


def _build_name(robot) -> str:
    lib = getattr(robot._core, "_lib", None)
    name = getattr(lib, "__name__", "") or ""
    return name.removesuffix(".lib") or "?"


def _load() -> str:
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except (OSError, AttributeError):
        return "?"


def machine_info(compiled_robot) -> list[tuple[str, str]]:
    from deltagen.native.build import compile_flags

    args, libraries = compile_flags("delta")
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    import cffi

    return [
        ("CPU", _cpu_model()),
        (
            "cores",
            f"{os.cpu_count()} logical ({usable} usable by this process); "
            "all measurements single-threaded",
        ),
        ("OS", f"{platform.system()} {platform.release()} {platform.machine()}"),
        ("Python", f"{platform.python_implementation()} {platform.python_version()}"),
        ("numpy / cffi", f"{np.__version__} / {cffi.__version__}"),
        ("compiler", _compiler()),
        (
            "C flags",
            " ".join(args) + "  (libraries: " + " ".join(f"-l{x}" for x in libraries) + ")",
        ),
        ("C build", _build_name(compiled_robot)),
    ]


# ------------------------------------------------------------------------- formatting


def _num(v: float) -> str:
    if not np.isfinite(v):
        return "?"
    if v >= 1000:
        return f"{v:,.0f}"
    if v >= 100:
        return f"{v:.0f}"
    if v >= 10:
        return f"{v:.1f}"
    return f"{v:.2f}"


def _cell(s: Stat | None, scale: float = 1.0) -> str:
    if s is None:
        return "n/a"
    return f"{_num(s.median / scale)} [{_num(s.min / scale)}, {_num(s.max / scale)}]"


def _ratio(ref: Stat | None, comp: Stat | None) -> str:
    if ref is None or comp is None or comp.median <= 0:
        return "n/a"
    r = ref.median / comp.median
    return f"{r:.0f}x" if r >= 10 else f"{r:.1f}x" if r >= 1 else f"{r:.2f}x"


def _verdict(value: float, target: float) -> str:
    return "met" if value <= target else "MISSED"


def render(result: dict, markdown: bool) -> str:
    n, ref_n, repeats = result["n"], result["ref_n"], result["repeats"]
    out: list[str] = []
    h = (lambda t: f"### {t}") if markdown else (lambda t: f"== {t} ==")
    bullet = "- " if markdown else "  "

    out.append(h("deltagen bench"))
    out.append("")
    for key, value in result["machine"]:
        v = f"`{value}`" if markdown and key.startswith("C ") else value
        out.append(f"{bullet}{key}: {v}")
    out.append(
        f"{bullet}load average (1 min): {result['load_before']} before, "
        f"{result['load_after']} after"
    )
    out.append(
        f"{bullet}workload: DeltaRobot.default(), q uniform in [{Q_RANGE[0]}, {Q_RANGE[1]}]"
        f" rad, qd in [{QD_RANGE[0]}, {QD_RANGE[1]}] rad/s, qdd in "
        f"[{QDD_RANGE[0]}, {QDD_RANGE[1]}] rad/s^2, payload in [{PAYLOAD_RANGE[0]}, "
        f"{PAYLOAD_RANGE[1]}] kg, p = fk(q); every row OK; seed {SEED}"
    )
    out.append(
        f"{bullet}N = {n:,} points (compiled), {ref_n:,} points (reference, scaled per "
        f"point); median [min, max] of {repeats} repeats after a warm-up call, the columns "
        "of a row timed round-robin"
    )
    out.append("")

    out.append(h("Throughput, ns per point"))
    out.append("")
    header = [
        "quantity",
        "C kernel",
        "compiled _core",
        "compiled API",
        "reference _core",
        "reference API",
        "speedup _core",
        "speedup API",
        "target (_core)",
    ]
    rows = []
    for name in QUANTITIES:
        c = result["throughput"][name]
        target = TARGETS_NS.get(name)
        tcell = "-" if target is None else f"<= {target:g} {_verdict(c['core'].median, target)}"
        rows.append(
            [
                name,
                _cell(c.get("kernel")),
                _cell(c["core"]),
                _cell(c["api"]),
                _cell(c["ref_core"]),
                _cell(c["ref_api"]),
                _ratio(c["ref_core"], c["core"]),
                _ratio(c["ref_api"], c["api"]),
                tcell,
            ]
        )
    out += table(header, rows, markdown)
    out.append("")

    out.append(h("Single-pose latency, us per call"))
    out.append("")
    header = ["call", "compiled", "reference", "speedup", "target (compiled)"]
    rows = []
    for label, comp, ref, target in result["latency"]:
        tcell = "-" if target is None else f"<= {target / 1000:g} {_verdict(comp.median, target)}"
        lab = f"`{label}`" if markdown else label
        rows.append([lab, _cell(comp, 1000.0), _cell(ref, 1000.0), _ratio(ref, comp), tcell])
    out += table(header, rows, markdown)
    out.append("")

    agree = ", ".join(f"{k} {v:.1e} {_UNITS[k]}" for k, v in result["agreement"].items())
    out.append(f"{bullet}agreement, max |compiled - reference| over the reference points: {agree}")
    bad = [k for k, v in result["agreement"].items() if not v <= AGREEMENT_TOL]
    if bad:
        out.append(
            f"{bullet}WARNING: compiled and reference disagree on {', '.join(bad)} "
            f"(> {AGREEMENT_TOL:g}); the compiled timings may measure a broken core"
        )
    out.append(
        f"{bullet}C kernel = generated C function with preallocated outputs; _core = "
        "robot._core.<fn> (fresh numpy outputs); API = robot.<fn> with validation. "
        "Targets are checked against the compiled _core median."
    )
    out.append(
        f"{bullet}single-threaded (threads=1; all cores: last section): the reference uses "
        "numpy ufuncs, so OPENBLAS/OMP thread settings are irrelevant"
    )
    if result.get("serial") is not None:
        out.append("")
        out += _render_serial(result["serial"], repeats, markdown)
    if result.get("threads") is not None:
        out.append("")
        out += _render_threads(result["threads"], markdown)
    if result.get("families") is not None:
        from deltagen.apps.bench import families as bench_families

        out.append("")
        out += bench_families.render(result["families"], markdown)
    out.append(f"{bullet}total bench time {result['elapsed_s']:.1f} s")
    return "\n".join(out)


def _render_serial(serial: dict, repeats: int, markdown: bool) -> list[str]:
    robot, n = serial["robot"], serial["n"]
    out: list[str] = []
    h = (lambda t: f"### {t}") if markdown else (lambda t: f"== {t} ==")
    bullet = "- " if markdown else "  "
    code = (lambda t: f"`{t}`") if markdown else (lambda t: t)
    lim = ", ".join(f"[{lo:.3g}, {hi:.3g}]" for lo, hi in robot.qlim)
    small = {name: pts for name, (pts, _) in serial["sizes"].items()}

    conv = robot.description.convention
    out.append(h(f"Serial arm: {robot.name} ({robot.n} joints, {conv} DH)"))
    out.append("")
    out.append(
        f"{bullet}workload: {code(f'SerialRobot.load({robot.name!r})')}, q uniform within "
        f"the joint limits ({lim}) rad, qd uniform in [{SERIAL_QD_RANGE[0]}, "
        f"{SERIAL_QD_RANGE[1]}] rad/s; seed {SEED}"
    )
    out.append(
        f"{bullet}N = {n:,} configurations for fk and jacobian, "
        f"{small['frames']:,} for frames, jacobian_dot and the dynamics; reference on the first "
        f"{min(n, SERIAL_REFERENCE_N):,} (scaled per configuration); median [min, max] "
        f"of {repeats} repeats, columns round-robin"
    )
    out.append("")
    out.append(h(f"{robot.name}: throughput, ns per configuration"))
    out.append("")
    header = [
        "quantity",
        "N",
        "C kernel",
        "compiled _core",
        "compiled API",
        "reference _core",
        "speedup _core",
        "target (_core)",
    ]
    rows = []
    for name in SERIAL_QUANTITIES:
        if name not in serial["throughput"]:
            continue
        c = serial["throughput"][name]
        target = SERIAL_TARGETS_NS.get(name)
        tcell = "-" if target is None else f"<= {target:g} {_verdict(c['core'].median, target)}"
        rows.append(
            [
                name,
                f"{serial['sizes'][name][0]:,}",
                _cell(c.get("kernel")),
                _cell(c["core"]),
                _cell(c["api"]),
                _cell(c["ref_core"]),
                _ratio(c["ref_core"], c["core"]),
                tcell,
            ]
        )
    out += table(header, rows, markdown)
    out.append("")

    out.append(h(f"{robot.name}: single-pose latency, us per call"))
    out.append("")
    header = ["call", "compiled", "reference", "speedup", "target (compiled)"]
    rows = []
    for label, comp, ref, target in serial["latency"]:
        tcell = "-" if target is None else f"<= {target / 1000:g} {_verdict(comp.median, target)}"
        rows.append(
            [code(label), _cell(comp, 1000.0), _cell(ref, 1000.0), _ratio(ref, comp), tcell]
        )
    out += table(header, rows, markdown)
    out.append("")
    agree = ", ".join(f"{k} {v:.1e} {_SERIAL_UNITS[k]}" for k, v in serial["agreement"].items())
    out.append(f"{bullet}agreement, max |compiled - reference| over the reference points: {agree}")
    bad = [k for k, v in serial["agreement"].items() if not v <= AGREEMENT_TOL]
    if bad:
        out.append(
            f"{bullet}WARNING: compiled and reference disagree on {', '.join(bad)} "
            f"(> {AGREEMENT_TOL:g}); the compiled timings may measure a broken core"
        )

    others = serial["oracles"]
    if others["rows"]:
        out.append("")
        for unit, title, scale in (
            ("us", "single call, us per call", 1000.0),
            ("ns", "batch, ns per configuration", 1.0),
        ):
            rows = []
            for r in others["rows"]:
                if r["unit"] != unit:
                    continue
                rows.append(
                    [
                        r["library"],
                        code(r["call"]),
                        _cell(r["lib"], scale),
                        code(r["dg_call"]),
                        _cell(r["dg"], scale),
                        _ratio(r["lib"], r["dg"]),
                    ]
                )
            if not rows:
                continue
            out.append(h(f"{robot.name} vs other libraries: {title}"))
            out.append("")
            out += table(
                [
                    "library",
                    "call",
                    "library time",
                    "deltagen call",
                    "deltagen time (compiled)",
                    "library / deltagen",
                ],
                rows,
                markdown,
            )
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
    out.append("")
    if serial.get("ik") is not None:
        from deltagen.apps.bench import ik as bench_ik

        out += bench_ik.render(serial["ik"], markdown, robot.name)
    return out


# ------------------------------------------------------------------------- all cores


def run_threads(n: int, repeats: int) -> dict:
    """threads=1 vs the default thread count on delta fk, Puma560 fk and jacobian (_core)."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.serial import SerialRobot
    from deltagen.native import parallel

    threads = parallel.resolve_threads(None)
    rng = np.random.default_rng(SEED)
    delta = {t: DeltaRobot.default(threads=t) for t in (1, threads)}
    arm = {t: SerialRobot.load(SERIAL_ROBOT, threads=t) for t in (1, threads)}
    q_delta = np.ascontiguousarray(rng.uniform(*Q_RANGE, (n, 3)))
    lim = arm[1].qlim
    q_arm = np.ascontiguousarray(lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((n, arm[1].n)))
    rows = []
    for label, robots, fn, q in (
        ("delta fk", delta, "fk", q_delta),
        (f"{SERIAL_ROBOT} fk", arm, "fk", q_arm),
        (f"{SERIAL_ROBOT} jacobian", arm, "jacobian", q_arm),
    ):
        calls = [getattr(robots[t]._core, fn) for t in (1, threads)]
        for call in calls:
            call(q)  # warm-up (and the pool's threads)
        one, many = interleaved([batch_timer(c, (q,), n) for c in calls], repeats)
        rows.append((label, one, many))
    return {
        "threads": threads,
        "chunks": len(parallel.chunks(n, threads)),
        "n": n,
        "rows": rows,
        "load": _load(),
    }


def _render_threads(result: dict, markdown: bool) -> list[str]:
    h = (lambda t: f"### {t}") if markdown else (lambda t: f"== {t} ==")
    bullet = "- " if markdown else "  "
    k = result["threads"]
    out = [h(f"All cores: threads=1 vs threads={k}, _core, ns per item"), ""]
    header = ["quantity", "threads=1", f"threads={k}", "speedup"]
    out += table(
        header,
        [
            [label, _cell(one), _cell(many), _ratio(one, many)]
            for label, one, many in result["rows"]
        ],
        markdown,
    )
    out.append("")
    from deltagen.native import parallel

    out.append(
        f"{bullet}threads: DELTAGEN_THREADS, else the available cores = {k}; N = "
        f"{result['n']:,} rows in {result['chunks']} chunk(s) (batches below "
        f"{2 * parallel.MIN_ROWS_PER_THREAD:,} rows run in one call); load average (1 min) "
        f"{result['load']} after this section"
    )
    return out


# ------------------------------------------------------------------------- entry point


BYTES_PER_POINT = 8 * (3 + 3 + 1 + 6 + 16 + 6 + 6) * 2


def measure(
    n: int = 1_000_000, repeats: int = 7, serial: bool = True, oracles: bool = True
) -> dict:
    """Measure everything; returns the raw result (see :func:`render`). ``serial`` adds the
    Puma560 section, ``oracles`` its comparison with roboticstoolbox-python / pinocchio."""
    from deltagen.api.delta import DeltaRobot

    if n < 1:
        raise ValueError(f"--n must be at least 1, got {n}")
    if repeats < 1:
        raise ValueError(f"--repeats must be at least 1, got {repeats}")
    # per point: the delta's inputs and outputs, the Puma 560's q, poses (4x4), rates and
    # flags, and the peers' copies
    check_memory(n * BYTES_PER_POINT, f"a batch of --n = {n} points", "choose a smaller --n")
    t_start = time.perf_counter()
    load_before = _load()
    compiled = DeltaRobot.default(backend="compiled", threads=1)  # builds the C core if needed
    reference = DeltaRobot.default(backend="reference")
    ref_n = min(n, REFERENCE_N)

    rng = np.random.default_rng(SEED)
    head = sample_poses(ref_n, [compiled._core, reference._core], rng)  # OK for both
    tail = sample_poses(n - ref_n, [compiled._core], rng) if n > ref_n else None
    poses = head if tail is None else {k: np.concatenate([head[k], tail[k]]) for k in head}
    poses = {k: np.ascontiguousarray(v) for k, v in poses.items()}
    del head, tail

    ref_poses = _prefix(poses, ref_n)
    throughput, agreement = _measure_throughput(compiled, reference, poses, ref_poses, repeats)
    del ref_poses

    latency = _measure_latency(
        compiled, reference, poses["q"][0].copy(), poses["p"][0].copy(), repeats
    )
    del poses
    serial_result = run_serial(n, repeats, oracles) if serial else None
    threads_result = run_threads(n, repeats) if serial else None
    from deltagen.apps.bench import families as bench_families

    families = bench_families.run(n, repeats)
    machine = machine_info(compiled)
    if serial_result is not None:
        machine.append(("C build (serial)", _build_name(serial_result["robot"])))
        if oracles:
            versions = _library_versions()
            machine.append(
                (
                    "other libraries",
                    ", ".join(f"{k} {v or 'not installed'}" for k, v in versions.items()),
                )
            )
    return {
        "n": n,
        "ref_n": ref_n,
        "repeats": repeats,
        "machine": machine,
        "throughput": throughput,
        "latency": latency,
        "agreement": agreement,
        "serial": serial_result,
        "threads": threads_result,
        "families": families,
        "load_before": load_before,
        "load_after": _load(),
        "elapsed_s": time.perf_counter() - t_start,
    }
