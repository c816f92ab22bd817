"""Cold and warm load of an arm, against the load targets: loading a new 6- or 7-axis URDF
(derive, emit, compile) takes <= 10 s, a warm load <= 50 ms; 20 joints <= 20 s.

Each measurement runs in a fresh interpreter (``python -c``) so nothing of an earlier load
is in memory:

* **cold**: an empty build cache (a new temporary DELTAGEN_CACHE per measurement): SymPy
  derives the arm, the C is rendered and compiled. CPU = the process's and its children's
  (the compiler's) user + system time over the load; wall = its clock time.
* **warm, first**: a second fresh process on the cache the cold one filled: the first load
  (parse the description, check the cache, dlopen).
* **warm, second**: a second load of the same arm in that process.

``import deltagen`` is timed apart (it is paid once per process). Bytecode is written and
used (PYTHONDONTWRITEBYTECODE is dropped), as for an installed package. Arms: the bundled URDFs
``robots/ur5.urdf`` (6 axes) and ``robots/panda.urdf`` (7 axes) loaded under a name of their
own (``name="<stem>_new"``: not the checked-in module of the bundled robot, so the load is a
new arm's) and CHAIN20, a 20-joint standard-DH chain.

``--call KERNEL`` (inverse_dynamics, forward_dynamics, mass_matrix, coriolis, ik_all or
jacobian_dot) also times the first call of that kernel after the cold load, in the cold
process (a new arm derives and compiles the part of its module that holds the kernel on
its first call, native/serial.py): ``call_cpu`` / ``call_wall``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: a 20-joint standard-DH chain (revolute, alternating twists, no special structure beyond
#: that): the arm of the 20-joint load target
CHAIN20 = tuple(
    dict(
        a=0.05 + 0.01 * (i % 5),
        alpha=(1.5707963267948966 if i % 2 else -1.5707963267948966),
        d=0.1 + 0.02 * (i % 3),
        offset=0.0,
        qlim=(-2.8, 2.8),
    )
    for i in range(20)
)

ARMS = ("ur5.urdf", "panda.urdf", "chain20")

_CHILD = r"""
import json, os, resource, sys, time
def usage():
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime
arm_name = sys.argv[1]
w0, c0 = time.perf_counter(), usage()
import deltagen
from deltagen.api.serial import SerialRobot
from deltagen.paths import robots_dir
w1, c1 = time.perf_counter(), usage()
def load():
    if arm_name == "chain20":
        from deltagen.apps.bench.load import CHAIN20
        return SerialRobot.from_dh(CHAIN20, "standard", name="chain20")
    path = robots_dir() / arm_name
    return SerialRobot.from_urdf(path, name=path.stem + "_new")
arm = load()
w2, c2 = time.perf_counter(), usage()
call = sys.argv[2] if len(sys.argv) > 2 else ""
call_wall = call_cpu = 0.0
if call:
    import numpy as np
    q = np.full(arm.n, 0.3)
    args = {"inverse_dynamics": (q, q, q), "forward_dynamics": (q, q, q), "coriolis": (q, q),
            "jacobian_dot": (q, q), "ik_all": (arm.fk(q),)}.get(call, (q,))
    wa, ca = time.perf_counter(), usage()
    getattr(arm, call)(*args)
    call_wall, call_cpu = time.perf_counter() - wa, usage() - ca
w2b, c2b = time.perf_counter(), usage()
arm = load()
w3, c3 = time.perf_counter(), usage()
print(json.dumps(dict(import_wall=w1 - w0, import_cpu=c1 - c0, first_wall=w2 - w1,
                      first_cpu=c2 - c1, second_wall=w3 - w2b, second_cpu=c3 - c2b,
                      call_wall=call_wall, call_cpu=call_cpu)))
"""


def _run(arm: str, cache: Path, env_extra: dict | None = None, call: str = "") -> dict:
    env = dict(os.environ, DELTAGEN_CACHE=str(cache))
    # an installed package has its bytecode: without it every import compiles the source
    # (70 ms of a warm load)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if env_extra:
        env.update(env_extra)
    root = Path(__file__).resolve().parents[3]
    env["PYTHONPATH"] = str(root) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, arm, call],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(arm: str, env_extra: dict | None = None, call: str = "") -> dict:
    """One cold load (fresh cache) and one warm process on that cache: seconds. ``call``:
    a kernel whose first call after the cold load is timed too (call_cpu, call_wall)."""
    cache = Path(tempfile.mkdtemp(prefix="deltagen-load-"))
    try:
        cold = _run(arm, cache, env_extra, call)
        warm = _run(arm, cache, env_extra)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return {
        "arm": arm,
        "cold_cpu": cold["first_cpu"],
        "cold_wall": cold["first_wall"],
        "warm_first_cpu": warm["first_cpu"],
        "warm_first_wall": warm["first_wall"],
        "warm_second_cpu": warm["second_cpu"],
        "warm_second_wall": warm["second_wall"],
        "import_wall": warm["import_wall"],
        **(
            {"call": call, "call_cpu": cold["call_cpu"], "call_wall": cold["call_wall"]}
            if call
            else {}
        ),
        "load_avg": os.getloadavg()[0],
    }


def _median(values):
    values = sorted(values)
    return values[len(values) // 2]


def table(results: list[dict]) -> str:
    """Markdown: per arm, the median [min, max] of its runs, seconds (cold) and ms (warm)."""
    lines = [
        "| arm | cold CPU s | cold wall s | warm 1st load CPU ms | warm 1st wall ms "
        "| 2nd load CPU ms | 2nd wall ms | runs | load avg |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for arm in dict.fromkeys(r["arm"] for r in results):
        runs = [r for r in results if r["arm"] == arm]

        def cell(key, scale, digits, runs=runs):
            v = [r[key] * scale for r in runs]
            return f"{_median(v):.{digits}f} [{min(v):.{digits}f}, {max(v):.{digits}f}]"

        lines.append(
            f"| {arm} | {cell('cold_cpu', 1, 1)} | {cell('cold_wall', 1, 1)} "
            f"| {cell('warm_first_cpu', 1e3, 0)} | {cell('warm_first_wall', 1e3, 0)} "
            f"| {cell('warm_second_cpu', 1e3, 0)} | {cell('warm_second_wall', 1e3, 0)} "
            f"| {len(runs)} | {min(r['load_avg'] for r in runs):.1f}-"
            f"{max(r['load_avg'] for r in runs):.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """``python -m deltagen.apps.bench.load [--repeats R] [--call KERNEL] [ARM ...]``: JSON
    lines per measurement (arms round-robin, R rounds), then the Markdown table."""
    args = list(sys.argv[1:] if argv is None else argv)
    repeats, call = 1, ""
    while args[:1] in (["--repeats"], ["--call"]):
        if args[0] == "--repeats":
            repeats = int(args[1])
        else:
            call = args[1]
        args = args[2:]
    arms = args or list(ARMS)
    results = []
    for _ in range(repeats):
        for arm in arms:
            results.append(measure(arm, call=call))
            print(json.dumps(results[-1]), flush=True)
    print(table(results))
    if call:
        for arm in arms:
            cpu = [r["call_cpu"] for r in results if r["arm"] == arm]
            wall = [r["call_wall"] for r in results if r["arm"] == arm]
            print(
                f"first {call} after the cold load of {arm}: CPU {_median(cpu):.1f} s "
                f"[{min(cpu):.1f}, {max(cpu):.1f}], wall {_median(wall):.1f} s "
                f"[{min(wall):.1f}, {max(wall):.1f}]"
            )


if __name__ == "__main__":
    main()
