"""The general-6R rows of ``deltagen bench``: all (up to 16) solutions of a general 6R arm,
reported in us per pose, against the targets <= 50 us batched and <= 100 us single.

Arms: a generic 6R arm (GENERIC_DH: a standard-DH table, no closed form; the
unshifted Raghavan-Roth arrangement) and the bundled UR5 forced onto the complete solver
(``method="complete"``: a shifted arrangement whose left side is the rigid motion of a
fixed one), both compiled. Poses fk(q), q uniform within the limits. Calls:
``arm.ik_all(T, method="complete")`` (solve/general6r.py: every solution, 16 slots) on a
batch (us per pose) and on one (4, 4) pose per call (us per call), timed round-robin, wall
clock and process CPU time (the targets are judged on the wall clock's median);
the share of poses whose q is among the valid solutions and the largest fk residual of a
valid one; and, where roboticstoolbox-python is installed, its C++ ``ETS.ik_LM`` (one
solution per call, its own restarts, tol for 1e-10) on the same targets for scale.

The split (module docstring of solve/general6r.py): on a compiled arm the per-pose
algebra and the eigen step are hand-written C (codegen/runtime/deltagen_general6r.c, one
arm-independent module; its 24 x 24 eigenvalues by deltagen_eigen.c's Hessenberg + Francis
QR), the Newton polish is the arm's generated C (called from there through a function
pointer), the limits fit and the duplicates C too: one C call per batch, or per pose
(deltagen_general6r_solve); only the poses the C path declines (QZ per pose where M2 is
ill conditioned) go through numpy. Beside
each arm's ``ik_all`` rows, the same solver with the numpy/LAPACK engine (``engine=
"numpy"``: the path before the C one, still the reference backend's) in the same run.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

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
from deltagen.solve import general6r


def _cpu_timer(fn: Callable, calls: int, points: int) -> Callable[[], float]:
    """A timer: ``fn()`` called ``calls`` times -> process CPU ns per point (leaves out
    the time the process waits for a core on a loaded machine)."""

    def timer():
        t0 = time.process_time_ns()
        for _ in range(calls):
            fn()
        return (time.process_time_ns() - t0) / (calls * points)

    return timer


G6R_N = 2000
G6R_SEED = 616
TARGETS_US = {"batch": 50.0, "single": 100.0}

#: a generic 6R arm: a standard-DH table with no special structure (no twist a multiple of
#: pi / 2, no zero length or offset: no neighbouring axes meet or are parallel)
GENERIC_DH = (
    dict(a=0.4735, alpha=-2.2314, d=0.2106, offset=0.3311, qlim=(-np.pi, np.pi)),
    dict(a=0.6127, alpha=1.0468, d=-0.3184, offset=-0.7260, qlim=(-np.pi, np.pi)),
    dict(a=0.2291, alpha=-0.5826, d=0.1377, offset=0.5120, qlim=(-np.pi, np.pi)),
    dict(a=0.5513, alpha=2.6071, d=-0.0921, offset=-0.2043, qlim=(-np.pi, np.pi)),
    dict(a=0.1872, alpha=-1.4233, d=0.4108, offset=0.8731, qlim=(-np.pi, np.pi)),
    dict(a=0.3346, alpha=0.7719, d=-0.2655, offset=-0.4418, qlim=(-np.pi, np.pi)),
)


def generic_arm(threads=1):
    from deltagen.api.serial import SerialRobot

    return SerialRobot.from_dh(
        [dict(r) for r in GENERIC_DH], "standard", name="generic6r", threads=threads
    )


def jaco_arm(threads=1):
    """roboticstoolbox's DH model of the Kinova Jaco (reversed joints; its neighbouring
    axes meet, so a shifted arrangement of the elimination), compiled; None without rtb."""
    try:
        import roboticstoolbox as rtb
    except ImportError:
        return None
    from deltagen.api.serial import SerialRobot

    rows = []
    for link in rtb.models.DH.Jaco().links:
        row = dict(a=float(link.a), alpha=float(link.alpha), d=float(link.d))
        row.update(offset=float(link.offset), flip=bool(link.isflip))
        if link.qlim is not None:
            row["qlim"] = (float(link.qlim[0]), float(link.qlim[1]))
        rows.append(row)
    return SerialRobot.from_dh(rows, "standard", name="jaco", threads=threads)


def _arms(generic: bool) -> list:
    from deltagen.api.serial import SerialRobot

    ur5 = SerialRobot.load("ur5", backend="compiled", threads=1)
    if not generic:
        return [ur5]
    return [a for a in (generic_arm(), ur5, jaco_arm()) if a is not None]


def _poses(arm, n):
    lim = arm.qlim
    rng = np.random.default_rng(G6R_SEED)
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (n, arm.n))
    return q, np.ascontiguousarray(arm.fk(q))


def measure(repeats: int, n: int = G6R_N, peers: bool = True, generic: bool = True) -> dict:
    """``generic``: also the generic arm (its C is built on first use, ~10-50 s; quick runs
    leave it out). {arm name: {"batch": Stat ns/pose, "single": Stat ns/call, "found", "max_residual",
    "valid_per_pose", "n"[, "rtb_ik_LM": Stat ns/call, "rtb_version"]}}."""
    out = {}
    for arm in _arms(generic):
        q, T = _poses(arm, n)
        T1 = T[0].copy()

        def batch(T=T, arm=arm):
            return arm.ik_all(T, method="complete")

        def single(T1=T1, arm=arm):
            return arm.ik_all(T1, method="complete")

        Q, valid = batch()  # warm-up: eliminations chosen, cores built
        elim = arm._general()[0]

        def batch_np(T=T, arm=arm, elim=elim):
            return general6r.solve(arm, T, elim, engine="numpy")

        def single_np(T1=T1[None], arm=arm, elim=elim):
            return general6r.solve(arm, T1, elim, engine="numpy")

        timers = [
            batch_timer(batch, (), n),
            loop_timer(single),
            _cpu_timer(batch, 1, n),
            _cpu_timer(single, 20, 1),
            _cpu_timer(batch_np, 1, n),
            _cpu_timer(single_np, 5, 1),
        ]
        robot = None
        if peers:
            robot = rtb_model(arm)  # (None for an arm with reversed joints: Jaco's own below)
            if arm.name == "jaco":
                import roboticstoolbox as rtb

                robot = rtb.models.DH.Jaco()
        if robot is not None:
            ets = robot.ets()
            kw = dict(tol=5e-21, joint_limits=True)
            timers.append(loop_timer(lambda ets=ets, T1=T1, kw=kw: ets.ik_LM(T1, **kw)))
        stats = interleaved(timers, repeats)
        err = np.abs(wrap_to_pi(Q - q[:, None])).max(axis=-1)
        found = np.any(valid & (err < 1e-6), axis=1)
        Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
        res = np.abs(Tq - T[:, None]).max(axis=(-1, -2))[valid]
        row = {
            "n": n,
            "batch": stats[0],
            "single": stats[1],
            "batch_cpu": stats[2],
            "single_cpu": stats[3],
            "engine": general6r.eigen_engine(arm),
            "batch_cpu_numpy": stats[4],
            "single_cpu_numpy": stats[5],
            "found": float(found.mean()),
            "valid_per_pose": float(valid.sum(axis=1).mean()),
            "max_residual": float(res.max()) if res.size else float("nan"),
        }
        if robot is not None:
            import roboticstoolbox as rtb

            row["rtb_ik_LM"], row["rtb_version"] = stats[6], rtb.__version__
        out[arm.name] = row
    return out


def _us(stat: Stat) -> str:
    return f"{stat.median / 1000:.4g} [{stat.min / 1000:.4g}, {stat.max / 1000:.4g}]"


def render(result: dict, markdown: bool) -> list[str]:
    """Lines of the general-6R table."""
    if not result:
        return []
    rows = []
    for name, r in result.items():
        for key, label in (("batch", f"batch of {r['n']:,}"), ("single", "one pose per call")):
            rows.append(
                [
                    name,
                    f"general 6R `ik_all(T, method='complete')`, all 16, {label}",
                    _us(r[key]),
                    f"{r[key + '_cpu'].median / 1000:.4g}",
                    f"<= {TARGETS_US[key]:g} {verdict(r[key].median / 1000, TARGETS_US[key])}",
                ]
            )
        for key, label in (("batch", f"batch of {r['n']:,}"), ("single", "one pose per call")):
            if key + "_cpu_numpy" in r:
                rows.append(
                    [
                        name,
                        f"  the same, numpy/LAPACK engine (before the C path), {label}",
                        "-",
                        f"{r[key + '_cpu_numpy'].median / 1000:.4g}",
                        "-",
                    ]
                )
        if "rtb_ik_LM" in r:
            rows.append(
                [
                    name,
                    f"rtb {r['rtb_version']} `ETS.ik_LM(T, tol=5e-21)` (C++), one solution",
                    _us(r["rtb_ik_LM"]),
                    "-",
                    "-",
                ]
            )
    bullet = Style(markdown).bullet
    out = [
        "General 6R, every solution (solve/general6r.py: Raghavan-Roth elimination; "
        "per-pose algebra and the 24 x 24 eigenproblem in hand-written C "
        "(Hessenberg + Francis QR), Newton polish in the arm's C):",
        "",
    ]
    header = ["arm", "call", "us per pose, median [min, max]", "CPU us, median", "target"]
    out += table(header, rows, markdown)
    for name, r in result.items():
        out.append(
            f"{bullet}{name}: original q among the valid solutions on "
            f"{100 * r['found']:.2f} % of {r['n']:,} poses ({r['valid_per_pose']:.2f} valid "
            f"per pose); largest fk residual of a valid solution {r['max_residual']:.1e}"
        )
    out.append("")
    return out
