"""`deltagen bench`'s section on the three-sphere machines: the linear delta's and the
tripod's compiled cores beside the rotary delta's, ns per point through ``robot._core``
(fresh numpy outputs, threads=1), timed round-robin in one run so the ratios hold on a
shared machine.

Workloads: the rotary delta as the main table (``DeltaRobot.default()``, crank angles
uniform in [-0.3, 0.9] rad); the linear delta of robots/linear_delta.toml (Klipper's
example-delta.cfg) on effector points within 0.1 m of the axis, 0.05 .. 0.25 m above the
bed, and the tripod of robots/tripod.toml on points above its base triangle; joint values
from ik, rates uniform in [-1, 1]; every row OK.
"""

from __future__ import annotations

import numpy as np

from deltagen.apps.timing import Stat, batch_timer, interleaved, table

SEED = 7


def _points(kind: str, n: int, rng) -> np.ndarray:
    if kind == "linear_delta":
        r = 0.1 * np.sqrt(rng.uniform(0, 1, n))
        t = rng.uniform(0, 2 * np.pi, n)
        return np.c_[r * np.cos(t), r * np.sin(t), rng.uniform(0.05, 0.25, n)]
    return np.c_[rng.uniform(0.2, 0.8, n), rng.uniform(0.1, 0.6, n), rng.uniform(0.3, 1.2, n)]


def run(n: int, repeats: int) -> dict:
    """{"n": n, "rows": [(label, Stat ns/point), ...]}."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.linear_delta import LinearDelta, Tripod
    from deltagen.paths import robots_dir

    rng = np.random.default_rng(SEED)
    rotary = DeltaRobot.default(threads=1)
    q_rot = np.ascontiguousarray(rng.uniform(-0.3, 0.9, (n, 3)))
    p_rot = np.ascontiguousarray(rotary._core.fk(q_rot)[0])
    calls: list = [
        ("rotary delta fk", rotary._core.fk, (q_rot,)),
        ("rotary delta ik", rotary._core.ik, (p_rot,)),
    ]
    machines = (
        ("linear delta", LinearDelta.from_toml(robots_dir() / "linear_delta.toml", threads=1)),
        ("tripod", Tripod.from_toml(robots_dir() / "tripod.toml", threads=1)),
    )
    for label, robot in machines:
        p = np.ascontiguousarray(_points(robot.kind, n, rng))
        q = np.ascontiguousarray(robot._core.ik(p)[0])
        qd = np.ascontiguousarray(rng.uniform(-1, 1, (n, 3)))
        qdd = np.ascontiguousarray(rng.uniform(-1, 1, (n, 3)))
        core = robot._core
        calls += [
            (f"{label} fk", core.fk, (q,)),
            (f"{label} ik", core.ik, (p,)),
            (f"{label} jacobian", core.jacobian, (q,)),
            (f"{label} fk_vel", core.fk_vel, (q, qd)),
            (f"{label} fk_acc", core.fk_acc, (q, qd, qdd)),
        ]
    for _, fn, args in calls:
        fn(*args)  # warm-up
    stats = interleaved([batch_timer(fn, args, n) for _, fn, args in calls], repeats)
    return {"n": n, "rows": [(label, s) for (label, _, _), s in zip(calls, stats)]}


def render(result: dict, markdown: bool) -> list[str]:
    h = (lambda t: f"### {t}") if markdown else (lambda t: f"== {t} ==")
    bullet = "- " if markdown else "  "
    out = [h("Three-sphere machines: rotary delta, linear delta, tripod, _core ns per point"), ""]

    def cell(s: Stat) -> str:
        return f"{s.median:.1f} [{s.min:.1f}, {s.max:.1f}]"

    out += table(["quantity", "ns per point"], [[k, cell(s)] for k, s in result["rows"]], markdown)
    out.append("")
    out.append(
        f"{bullet}N = {result['n']:,} points each, threads=1, round-robin; the linear delta "
        "of robots/linear_delta.toml, the tripod of robots/tripod.toml (apps/bench_three_spheres.py)"
    )
    return out
