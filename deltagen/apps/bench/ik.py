"""The inverse-kinematics section of ``deltagen bench``: the Puma 560 (targets: ``TARGETS``).

Analytic: poses fk(q) of q uniform within the joint limits; every branch (8) per pose,
through the generated C (``_core.ik_all``), the API (``arm.ik_all``) and the numpy solver
(the reference backend), batched (ns per pose) and for one pose per call (us per call);
plus the share of poses whose original q is among the valid branches and the largest fk
residual of a valid branch.

Numerical: IK_NUMERIC_N targets fk(q) (q uniform within the limits) on the Puma 560 and on a
Panda-like 7-axis arm (PANDA_DH), solved one target per call with default options
(``arm.ik(T, method="numeric")`` as a user would: q0 the middle of the joint ranges, the
default restarts, all in C) and timed per call: success rate (converged to 1e-10 m and rad,
inside the limits, checked with the numpy reference's fk), median, 95th percentile and max
of the time per call; the same targets in one batched call (time / targets); and, when
installed, roboticstoolbox-python's C++ ``ETS.ik_LM`` on the same targets and the same model
(built from the same DH table), tol set so that it too stops at 1e-10.
"""

from __future__ import annotations

import gc
import time
from typing import Any

import numpy as np

from deltagen.apps.bench import general6r as bench_general6r
from deltagen.apps.bench.peers import rtb_model
from deltagen.apps.bench.timing import (
    Stat,
    Style,
    batch_timer,
    interleaved,
    loop_timer,
    table,
    verdict,
)
from deltagen.geometry.limits import wrap_to_pi

IK_ROBOT = "puma560"
IK_ANALYTIC_N = 100_000
IK_REFERENCE_N = 5_000
IK_NUMERIC_N = 1_000
IK_TOL = 1e-10
IK_SEED = 20081208
TARGETS = {
    "analytic_batch_ns": 2000.0,
    "analytic_single_ns": 2000.0,
    "numeric_median_ns": 8000.0,
    "numeric_p95_ns": 40000.0,
    "ur5_batch_ns": 2000.0,  # UR5 closed form, all 8 branches, <= 2 us per pose batched
}
#: The UR family's closed form (three parallel axes, offset wrist): the bundled UR5.
UR_ROBOT = "ur5"


def _in_limit_q(arm, count, rng):
    lim = arm.qlim
    lo, hi = np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi)
    return rng.uniform(lo, hi, size=(count, arm.n))


def _angle_diff(a, b):
    return wrap_to_pi(a - b)


def measure_analytic(compiled, reference, repeats, n=IK_ANALYTIC_N):
    rng = np.random.default_rng(IK_SEED)
    q = _in_limit_q(compiled, n, rng)
    T = np.ascontiguousarray(compiled.fk(q))
    k = len(compiled.analytic_configs())
    ref_n = min(n, IK_REFERENCE_N)
    T_ref = np.ascontiguousarray(T[:ref_n])
    compiled.ik_all(T[:1])  # builds the fast path
    batch = interleaved(
        [
            batch_timer(compiled._core.ik_all, (T, k), n),
            batch_timer(compiled.ik_all, (T,), n),
            batch_timer(reference.ik_all, (T_ref,), ref_n),
        ],
        repeats,
    )
    T1 = T[0].copy()
    single = interleaved(
        [
            loop_timer(lambda: compiled.ik_all(T1)),
            loop_timer(lambda: reference.ik_all(T1)),
            loop_timer(lambda: compiled.ik(T1, singular="allow")),
            loop_timer(lambda: compiled.ik(T1)),
        ],
        repeats,
    )
    q_all, valid = compiled.ik_all(T)
    found = np.all(np.abs(_angle_diff(q_all, q[:, None])) < 1e-8, axis=-1) & valid
    m = min(n, 20_000)
    qv = np.where(valid[:m, :, None], q_all[:m], 0.0).reshape(-1, compiled.n)
    residual = np.abs(compiled.fk(qv).reshape(m, k, 4, 4) - T[:m, None])[valid[:m]]
    return {
        "n": n,
        "ref_n": ref_n,
        "k": k,
        "batch": dict(zip(("kernel", "api", "numpy"), batch)),
        "single": dict(zip(("api", "numpy", "ik", "ik_singular_check"), single)),
        "found": float(np.mean(found.any(axis=1))),
        "valid_per_pose": float(valid.sum(axis=1).mean()),
        "max_residual": float(residual.max()) if residual.size else float("nan"),
    }


#: A Panda-like 7-axis arm: the Denavit-Hartenberg table (modified DH, Craig) and joint
#: limits of the Franka Emika Panda as published in the Franka Control Interface
#: documentation, "Robot and interface specifications"
#: (https://frankaemika.github.io/docs/control_parameters.html), with the flange
#: (d = 0.107 m) as the tool. Kinematics only (no inertials).
PANDA_DH = (
    dict(a=0.0, alpha=0.0, d=0.333, qlim=(-2.8973, 2.8973)),
    dict(a=0.0, alpha=-np.pi / 2, d=0.0, qlim=(-1.7628, 1.7628)),
    dict(a=0.0, alpha=np.pi / 2, d=0.316, qlim=(-2.8973, 2.8973)),
    dict(a=0.0825, alpha=np.pi / 2, d=0.0, qlim=(-3.0718, -0.0698)),
    dict(a=-0.0825, alpha=-np.pi / 2, d=0.384, qlim=(-2.8973, 2.8973)),
    dict(a=0.0, alpha=np.pi / 2, d=0.0, qlim=(-0.0175, 3.7525)),
    dict(a=0.088, alpha=np.pi / 2, d=0.0, qlim=(-2.8973, 2.8973)),
)
PANDA_FLANGE = 0.107  # m, along z of frame 7


def panda_like(threads=1):
    """The 7-axis arm of the numeric IK benchmark (PANDA_DH), compiled."""
    from deltagen.api.serial import SerialRobot

    tool = np.eye(4)
    tool[2, 3] = PANDA_FLANGE
    return SerialRobot.from_dh(
        [dict(row) for row in PANDA_DH],
        "modified",
        name="panda_like",
        tool=tool,
        threads=threads,
    )


def numeric_targets(arm, n, seed=IK_SEED + 1):
    """n reachable in-limit targets fk(q), q uniform within the limits (revolute joints
    within [-pi, pi]), and their q."""
    rng = np.random.default_rng(seed)
    q = _in_limit_q(arm, n, rng)
    return np.ascontiguousarray(arm.fk(q)), q


def _solved(arm, T, qs, ok):
    """Rows solved to IK_TOL (m, rad) within the limits, checked here with the numpy
    reference's fk (independent of the compiled core)."""
    from deltagen.reference import serial as reference

    lim = arm.qlim
    qs = np.where(ok[:, None], qs, 0.0)
    inside = np.all((qs >= lim[:, 0]) & (qs <= lim[:, 1]), axis=-1)
    Tq, _ = reference.fk(arm.description, np.ascontiguousarray(qs))
    err = np.abs(Tq - T)
    # tol is on |dp| (m) and the rotation angle (rad); entries of R are within that
    fits = np.linalg.norm(Tq[:, :3, 3] - T[:, :3, 3], axis=-1) <= IK_TOL * 1.0001
    fits &= np.max(err[:, :3, :3], axis=(-2, -1)) <= 2 * IK_TOL
    return ok & inside & fits


def _time_calls(solve_one, T):
    """Wall and process CPU time per call [ns] of solve_one(T[i]) for every row, and its
    results. The CPU time leaves out the time the process waits for a core on a loaded
    machine (it is what the call itself costs)."""
    n = T.shape[0]
    times = np.empty((2, n))
    results = []
    wall, cpu = time.perf_counter_ns, time.process_time_ns
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for i in range(n):
            c0, t0 = cpu(), wall()
            r = solve_one(T[i])
            t1, c1 = wall(), cpu()
            times[0, i], times[1, i] = t1 - t0, c1 - c0
            results.append(r)
    finally:
        if gc_was:
            gc.enable()
    return times, results


def _stats(times, solved):
    wall, cpu = times
    return {
        "success": float(np.mean(solved)),
        "median_ns": float(np.median(wall)),
        "p95_ns": float(np.percentile(wall, 95)),
        "max_ns": float(wall.max()),
        "cpu_median_ns": float(np.median(cpu)),
        "cpu_p95_ns": float(np.percentile(cpu, 95)),
        "cpu_max_ns": float(cpu.max()),
    }


def measure_numeric(compiled, n=IK_NUMERIC_N, peers=True):
    """Numerical IK with default options, one target per call: deltagen's
    ``arm.ik(T, method="numeric")`` and, if installed, roboticstoolbox's C++ ``ik_LM`` on
    the same targets (its own random restarts, tol set for 1e-10)."""
    T, _ = numeric_targets(compiled, n)
    compiled.ik(T[0], method="numeric", errors="nan")  # warm-up (builds the fast path)

    def one(Ti):
        return compiled.ik(Ti, method="numeric", errors="nan")

    times, res = _time_calls(one, T)
    qs = np.array([r[0] for r in res])
    ok = np.array([bool(r[1]) for r in res])
    out = {"n": n, "deltagen": _stats(times, _solved(compiled, T, qs, ok))}
    t0 = time.perf_counter_ns()
    q_batch, ok_batch = compiled.ik(T, method="numeric", errors="nan")
    out["batch_ns"] = float((time.perf_counter_ns() - t0) / n)
    out["batch_success"] = float(np.mean(_solved(compiled, T, q_batch, ok_batch)))
    robot = rtb_model(compiled) if peers else None
    if robot is not None:
        import roboticstoolbox as rtb

        ets = robot.ets()
        # ik_LM's tol bounds E = 1/2 e^T e; |e| <= 1e-10 needs E <= 5e-21
        kw = dict(tol=5e-21, joint_limits=True)  # its restarts draw from its own generator
        ets.ik_LM(T[0], **kw)
        times_r, res_r = _time_calls(lambda Ti: ets.ik_LM(Ti, **kw), T)
        q_r = np.array([r.q for r in res_r])
        ok_r = np.array([bool(r.success) for r in res_r])
        out["rtb"] = _stats(times_r, _solved(compiled, T, q_r, ok_r))
        out["rtb"]["version"] = rtb.__version__
    return out


def run(
    compiled: Any,
    reference: Any,
    repeats: int,
    analytic_n: int = IK_ANALYTIC_N,
    numeric_n: int = IK_NUMERIC_N,
    peers: bool = True,
) -> dict:
    from deltagen.api.serial import SerialRobot

    ur = SerialRobot.load(UR_ROBOT, backend="compiled", threads=1)
    return {
        "analytic": measure_analytic(compiled, reference, repeats, n=analytic_n),
        "analytic_ur": measure_analytic(ur, ur.with_backend("reference"), repeats, n=analytic_n),
        "numeric": measure_numeric(compiled, n=numeric_n, peers=peers),
        "numeric_7axis": measure_numeric(panda_like(), n=numeric_n, peers=peers),
        "general6r": bench_general6r.measure(
            repeats,
            n=bench_general6r.G6R_N if numeric_n >= IK_NUMERIC_N else 20,
            peers=peers,
            generic=numeric_n >= IK_NUMERIC_N,
        ),
    }


def _us(stat: Stat, scale: float = 1000.0) -> str:
    return f"{stat.median / scale:.3g} [{stat.min / scale:.3g}, {stat.max / scale:.3g}]"


def _closed_form_batch_rows(a: dict, prefix: str, target: str) -> list[list[str]]:
    """The batch rows of a closed-form measurement ``a`` (measure_analytic): the C kernel,
    the API against TARGETS[target] (<= 2 us per pose), the numpy solver."""
    return [
        [
            f"{prefix}all {a['k']} closed-form branches, C kernel `_core.ik_all(T)`, "
            f"batch of {a['n']:,}",
            _us(a["batch"]["kernel"]),
            "-",
        ],
        [
            f"{prefix}all {a['k']} branches, `arm.ik_all(T)`, batch of {a['n']:,}",
            _us(a["batch"]["api"]),
            f"<= 2 {verdict(a['batch']['api'].median, TARGETS[target])}",
        ],
        [
            f"{prefix}all {a['k']} branches, numpy solver (reference backend), "
            f"batch of {a['ref_n']:,}",
            _us(a["batch"]["numpy"]),
            "-",
        ],
    ]


def _closed_form_found(a: dict, bullet: str, what: str) -> str:
    """The bullet saying how often the closed form found the original q."""
    return (
        f"{bullet}{what}: the original q is among the valid branches for "
        f"{100 * a['found']:.3f} % of the poses ({a['valid_per_pose']:.2f} valid branches "
        f"per pose on average); largest fk residual of a valid branch "
        f"{a['max_residual']:.1e}"
    )


def render(result: dict, markdown: bool, name: str) -> list[str]:
    """Lines of the IK section."""
    style = Style(markdown)
    h, bullet = style.h, style.bullet
    a = result["analytic"]
    out = [h(f"{name}: inverse kinematics"), ""]

    rows = _closed_form_batch_rows(a, "", "analytic_batch_ns") + [
        [
            "all branches, `arm.ik_all(T)`, one pose per call",
            _us(a["single"]["api"]),
            f"<= 2 {verdict(a['single']['api'].median, TARGETS['analytic_single_ns'])}",
        ],
        ["all branches, numpy solver, one pose per call", _us(a["single"]["numpy"]), "-"],
        [
            "`arm.ik(T, singular='allow')`, one pose (first valid branch)",
            _us(a["single"]["ik"]),
            "-",
        ],
        [
            "`arm.ik(T)`, one pose (+ the exact-singularity check)",
            _us(a["single"]["ik_singular_check"]),
            "-",
        ],
    ]
    out += table(["call", "us per pose, median [min, max]", "target"], rows, markdown)
    out.append("")
    out.append(_closed_form_found(a, bullet, "closed form"))
    out.append("")
    if result.get("analytic_ur"):
        out += render_ur(result["analytic_ur"], markdown)
        out.append("")
    out += render_numeric(result, markdown, name)
    out.append("")
    out += bench_general6r.render(result.get("general6r") or {}, markdown)
    return out


def render_ur(a: dict, markdown: bool) -> list[str]:
    """Lines of the UR closed-form rows (the target: all 8 branches <= 2 us per pose,
    batched)."""
    bullet = Style(markdown).bullet
    rows = _closed_form_batch_rows(a, f"{UR_ROBOT}: ", "ur5_batch_ns") + [
        [f"{UR_ROBOT}: `arm.ik_all(T)`, one pose per call", _us(a["single"]["api"]), "-"],
    ]
    out = table(["call", "us per pose, median [min, max]", "target"], rows, markdown)
    out.append("")
    out.append(_closed_form_found(a, bullet, "UR closed form"))
    return out


def render_numeric(result: dict, markdown: bool, name: str) -> list[str]:
    """The numerical-IK table: per arm, deltagen's default numeric ik and rtb's ik_LM."""
    rows = []
    for key, arm_name in (("numeric", name), ("numeric_7axis", "panda_like (7 axes)")):
        nm = result.get(key)
        if nm is None:
            continue
        for lib, label in (("deltagen", "deltagen `arm.ik(T, method='numeric')`"), ("rtb", None)):
            r = nm.get(lib)
            if r is None:
                continue
            if label is None:
                label = f"rtb {r['version']} `ETS.ik_LM(T, tol=5e-21)` (C++)"
            target = "-"
            if lib == "deltagen":
                met = (
                    r["median_ns"] <= TARGETS["numeric_median_ns"]
                    and r["p95_ns"] <= TARGETS["numeric_p95_ns"]
                )
                target = "<= 8 / 40 " + ("met" if met else "MISSED")
            rows.append(
                [
                    arm_name,
                    label,
                    f"{100 * r['success']:.1f} %",
                    f"{r['median_ns'] / 1000:.3g} ({r['cpu_median_ns'] / 1000:.3g})",
                    f"{r['p95_ns'] / 1000:.3g} ({r['cpu_p95_ns'] / 1000:.3g})",
                    f"{r['max_ns'] / 1000:.3g} ({r['cpu_max_ns'] / 1000:.3g})",
                    target,
                ]
            )
    if not rows:
        return []
    n = result["numeric"]["n"]
    bullet = Style(markdown).bullet
    out = [
        f"Numerical IK, default options, one target per call: {n:,} targets fk(q), q uniform "
        f"within the limits; solved = converged to {IK_TOL:g} m and rad within the limits, "
        "checked with the numpy reference's fk. Times: wall (process CPU) per call.",
        "",
    ]
    out += table(
        ["arm", "call", "solved", "median us", "p95 us", "max us", "target (median / p95)"],
        rows,
        markdown,
    )
    for key in ("numeric", "numeric_7axis"):
        nm = result.get(key)
        if nm is not None:
            out.append(
                f"{bullet}{key}: the same targets in one batched call: solved "
                f"{100 * nm['batch_success']:.1f} %, {nm['batch_ns'] / 1000:.3g} us per target"
            )
    out.append("")
    return out
