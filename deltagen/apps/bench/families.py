"""`deltagen bench`'s section on the other machine families: the linear delta's, the
tripod's, the hexapod's and a 5-axis machine's compiled cores beside the rotary delta's, ns
per point through ``robot._core`` (fresh numpy outputs, threads=1), timed round-robin in
one run so the ratios hold on a shared machine.

Workloads: the rotary delta as the main table (``DeltaRobot.default()``, crank angles
uniform in [-0.3, 0.9] rad); the linear delta of robots/linear_delta.toml (Klipper's
example-delta.cfg) on effector points within 0.1 m of the axis, 0.05 .. 0.25 m above the
bed, and the tripod of robots/tripod.toml on points above its base triangle; joint values
from ik, rates uniform in [-1, 1]; every row OK. The hexapod (LinuxCNC genhexkins'
geometry) on poses within 0.05 m and 0.1 rad of home, its fk by the damped Newton from the
home pose on N / 20 points (a few microseconds each); the 5-axis machine ``xyzac_trt`` on
joints within its travel, ik from fk's tool tip and axis with the joints as the previous
ones.
"""

from __future__ import annotations

import numpy as np

from deltagen.apps.bench import engine
from deltagen.apps.bench.timing import Style, cell

SEED = 7


def _points(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
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
        ("rotary delta fk", rotary._core.fk, (q_rot,), n),
        ("rotary delta ik", rotary._core.ik, (p_rot,), n),
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
            (f"{label} fk", core.fk, (q,), n),
            (f"{label} ik", core.ik, (p,), n),
            (f"{label} jacobian", core.jacobian, (q,), n),
            (f"{label} fk_vel", core.fk_vel, (q, qd), n),
            (f"{label} fk_acc", core.fk_acc, (q, qd, qdd), n),
        ]
    calls += _hexapod_calls(n, rng) + _machine_calls(n, rng)
    return {"n": n, "rows": engine.time_calls(calls, repeats)}


def _hexapod_calls(n: int, rng: np.random.Generator) -> list:
    from deltagen.api import hexapod as hx

    robot = hx.Hexapod.genhexkins()
    core = robot._core
    T = robot.pose(
        robot.home[:3, 3] + rng.uniform(-0.05, 0.05, (n, 3)), rpy=rng.uniform(-0.1, 0.1, (n, 3))
    )
    flat = np.ascontiguousarray(T.reshape(n, 16))
    lengths = np.ascontiguousarray(core.ik(flat)[0])
    m = max(n // 20, 1)
    home = np.ascontiguousarray(np.broadcast_to(robot.home.reshape(16), (m, 16)))
    fk_args = (lengths[:m], home, hx.FK_TOL, hx.FK_DAMPING, hx.FK_MAX_STEP, hx.FK_MAX_ITER)
    return [
        ("hexapod ik", core.ik, (flat,), n),
        ("hexapod jacobian", core.jacobian, (flat,), n),
        ("hexapod fk (Newton from home)", core.fk, fk_args, m),
    ]


def _machine_calls(n: int, rng: np.random.Generator) -> list:
    from deltagen.api.five_axis import FiveAxisMachine

    robot = FiveAxisMachine.load("xyzac_trt")
    core = robot._core
    lo, hi = np.array([-0.2, -0.2, -0.2, -1.0, -3.0]), np.array([0.2, 0.2, 0.2, 1.0, 3.0])
    j = np.ascontiguousarray(rng.uniform(lo, hi, (n, 5)))
    p, d, _ = core.fk(j)
    p, d = np.ascontiguousarray(p), np.ascontiguousarray(d)
    return [
        ("5-axis xyzac_trt fk", core.fk, (j,), n),
        ("5-axis xyzac_trt ik", core.ik, (p, d, j), n),
        ("5-axis xyzac_trt ik_all", core.ik_all, (p, d, j), n),
    ]


def render(result: dict, markdown: bool) -> list[str]:
    style = Style(markdown)
    out = [style.h("Other machine families beside the rotary delta, _core ns per point"), ""]
    out += style.table(["quantity", "ns per point"], [[k, cell(s)] for k, s in result["rows"]])
    out.append("")
    out.append(
        f"{style.bullet}N = {result['n']:,} points each (the hexapod's fk: N / 20), threads=1, "
        "round-robin; the linear delta of robots/linear_delta.toml, the tripod of "
        "robots/tripod.toml, the hexapod of LinuxCNC genhexkins, the 5-axis machine xyzac_trt "
        "(apps/bench/families.py)"
    )
    return out
