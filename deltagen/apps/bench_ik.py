"""The inverse-kinematics section of ``deltagen bench``: the Puma 560 (issue 4's targets).

Analytic: poses fk(q) of q uniform within the joint limits; every branch (8) per pose,
through the generated C (``_core.ik_all``), the API (``arm.ik_all``) and the numpy solver
(the reference backend), batched (ns per pose) and for one pose per call (us per call);
plus the share of poses whose original q is among the valid branches and the largest fk
residual of a valid branch.

Numerical: IK_NUMERIC_N targets fk(q) (q uniform within the limits), solved one target per
call (``arm.ik(T, method="numeric", ...)`` as a user would; q0 = the middle of the joint
ranges, random restarts allowed) and timed per call: success rate (converged to 1e-10 m and
rad, inside the limits, fk residual checked here), median and 95th percentile of the time
per solve; and the same targets in one batched call (time / targets).
"""

from __future__ import annotations

import gc
import time

import numpy as np

from deltagen.apps.timing import Stat, batch_timer, interleaved, loop_timer, table
from deltagen.geometry.limits import wrap_to_pi

IK_ROBOT = "puma560"
IK_ANALYTIC_N = 100_000
IK_REFERENCE_N = 5_000
IK_NUMERIC_N = 1_000
IK_RESTARTS = 50
IK_TOL = 1e-10
IK_SEED = 20081208
TARGETS = {"analytic_batch_ns": 2000.0, "analytic_single_ns": 5000.0, "numeric_median_ns": 10000.0}


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


def measure_numeric(compiled, n=IK_NUMERIC_N, restarts=IK_RESTARTS):
    rng = np.random.default_rng(IK_SEED + 1)
    q = _in_limit_q(compiled, n, rng)
    T = np.ascontiguousarray(compiled.fk(q))
    lim = compiled.qlim
    # solve()'s default tolerance is IK_TOL (1e-10 m and rad)
    options = dict(method="numeric", errors="nan", restarts=restarts, seed=0)
    compiled.ik(T[0], **options)  # warm-up

    def success(qs, ok):
        qs = np.where(ok[:, None], qs, 0.0)
        inside = np.all((qs >= lim[:, 0]) & (qs <= lim[:, 1]), axis=-1)
        err = np.abs(compiled.fk(qs) - T)
        # tol is on |dp| (m) and the rotation angle (rad); entries of R are within that
        fits = np.max(err[:, :3, 3], axis=-1) <= IK_TOL * 1.0001
        fits &= np.max(err[:, :3, :3], axis=(-2, -1)) <= 2 * IK_TOL
        return ok & inside & fits

    times = np.empty(n)
    q_single = np.empty((n, compiled.n))
    ok_single = np.empty(n, dtype=bool)
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for i in range(n):
            t0 = time.perf_counter_ns()
            qi, oki = compiled.ik(T[i], **options)
            times[i] = time.perf_counter_ns() - t0
            q_single[i], ok_single[i] = qi, oki
        t0 = time.perf_counter_ns()
        q_batch, ok_batch = compiled.ik(T, **options)
        batch_ns = (time.perf_counter_ns() - t0) / n
    finally:
        if gc_was:
            gc.enable()
    return {
        "n": n,
        "restarts": restarts,
        "single_success": float(np.mean(success(q_single, ok_single))),
        "median_ns": float(np.median(times)),
        "p95_ns": float(np.percentile(times, 95)),
        "max_ns": float(times.max()),
        "batch_success": float(np.mean(success(q_batch, ok_batch))),
        "batch_ns": float(batch_ns),
    }


def run(compiled, reference, repeats, analytic_n=IK_ANALYTIC_N, numeric_n=IK_NUMERIC_N) -> dict:
    return {
        "analytic": measure_analytic(compiled, reference, repeats, n=analytic_n),
        "numeric": measure_numeric(compiled, n=numeric_n),
    }


def _us(stat: Stat, scale=1000.0) -> str:
    return f"{stat.median / scale:.3g} [{stat.min / scale:.3g}, {stat.max / scale:.3g}]"


def render(result: dict, markdown: bool, name: str) -> list[str]:
    """Lines of the IK section."""
    h = (lambda t: f"### {t}") if markdown else (lambda t: f"== {t} ==")
    bullet = "- " if markdown else "  "
    a, nm = result["analytic"], result["numeric"]
    out = [h(f"{name}: inverse kinematics"), ""]

    def verdict(value, target):
        return "met" if value <= target else "MISSED"

    rows = [
        [
            f"all {a['k']} closed-form branches, C kernel `_core.ik_all(T)`, batch of {a['n']:,}",
            _us(a["batch"]["kernel"]),
            "-",
        ],
        [
            f"all {a['k']} branches, `arm.ik_all(T)`, batch of {a['n']:,}",
            _us(a["batch"]["api"]),
            f"<= 2 {verdict(a['batch']['api'].median, TARGETS['analytic_batch_ns'])}",
        ],
        [
            f"all {a['k']} branches, numpy solver (reference backend), batch of {a['ref_n']:,}",
            _us(a["batch"]["numpy"]),
            "-",
        ],
        [
            "all branches, `arm.ik_all(T)`, one pose per call",
            _us(a["single"]["api"]),
            f"<= 5 {verdict(a['single']['api'].median, TARGETS['analytic_single_ns'])}",
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
    out.append(
        f"{bullet}closed form: the original q is among the valid branches for "
        f"{100 * a['found']:.3f} % of the poses ({a['valid_per_pose']:.2f} valid branches "
        f"per pose on average); largest fk residual of a valid branch "
        f"{a['max_residual']:.1e}"
    )
    out.append(
        f"{bullet}numerical IK, {nm['n']:,} targets fk(q), q uniform in the limits, "
        f"start at mid-range, up to {nm['restarts']} random restarts, tol {IK_TOL:g} m "
        f"and rad: one target per call: success {100 * nm['single_success']:.1f} %, "
        f"median {nm['median_ns'] / 1000:.3g} us, p95 {nm['p95_ns'] / 1000:.3g} us, "
        f"max {nm['max_ns'] / 1000:.3g} us per solve (target: median <= 10 us, "
        f"{verdict(nm['median_ns'], TARGETS['numeric_median_ns'])}); one batched call: "
        f"success {100 * nm['batch_success']:.1f} %, {nm['batch_ns'] / 1000:.3g} us per "
        "target"
    )
    out.append("")
    return out
