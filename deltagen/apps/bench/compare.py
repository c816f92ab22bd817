"""`deltagen bench --compare REF`: the batched throughput of this tree beside that of REF,
measured in one run on this machine, as a table measure / ref / this / this/ref.

Absolute times on a shared machine drift from minute to minute; a ratio of two trees
measured in the same minutes does not, which is what a change's review needs.

REF is either

* a git commit (any name ``git rev-parse`` takes) of the repository this tree is in: it is
  checked out as a temporary git worktree and both trees are measured in fresh Python
  processes (each importing its own ``deltagen``, each with its own ``DELTAGEN_CACHE`` so
  neither loads the other's compiled modules), alternating REF / this for ``rounds``
  rounds after one warm-up process per side (which also builds the modules), with one
  thread (``DELTAGEN_THREADS=1``); each cell is the median over the rounds of each
  process's median; or
* a JSON file written by ``deltagen bench --json``: its public-API medians (the "compiled
  API" column) are the REF side, this tree is measured as above.

Every measure is the public API on a batch, nanoseconds per point: the delta's fk, fk_vel,
fk_acc, jacobian, ik and inverse_dynamics and the Puma 560's fk, frames, jacobian,
jacobian_dot, inverse_dynamics, mass_matrix and forward_dynamics, on the workloads of
``deltagen bench`` (apps/bench/sections.py: crank angles in [-0.3, 0.9] rad, the arm within its joint
limits). The probe that a process runs uses only the public API that every version has, so
an old commit can be measured with it; a measure its version lacks is shown as n/a.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from deltagen.apps.bench.sections import QUANTITIES, SERIAL_QUANTITIES, SERIAL_ROBOT, SERIAL_SMALL_N
from deltagen.errors import DeltagenError
from deltagen.inputs import read_regular_file

#: measures (label) -> (robot, method, JSON section, JSON quantity): the batched quantities
#: of ``deltagen bench`` (apps/bench/sections.py), so that a stored JSON has every one
MEASURES = {
    **{f"delta {q}": ("delta", q, "throughput", q) for q in QUANTITIES},
    **{f"{SERIAL_ROBOT} {q}": (SERIAL_ROBOT, q, "serial", q) for q in SERIAL_QUANTITIES},
}
SMALL_N = SERIAL_SMALL_N  # frames, jacobian_dot and the arm's dynamics

# Runs in a fresh interpreter whose sys.path starts with the measured tree: public API
# only, one JSON line {label: ns per point or null} on stdout.
PROBE = r"""
import json, sys, time
import numpy as np
from deltagen import DeltaRobot, SerialRobot

n, repeats, small = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
wanted = json.loads(sys.argv[4])
rng = np.random.default_rng(2008)

def median_ns(fn, args, points):
    fn(*args)
    times = []
    for _ in range(repeats):
        t = time.perf_counter_ns()
        fn(*args)
        times.append((time.perf_counter_ns() - t) / points)
    return float(np.median(times))

delta = DeltaRobot.default()
q = rng.uniform(-0.3, 0.9, (n, 3))
qd = rng.uniform(-2.0, 2.0, (n, 3))
qdd = rng.uniform(-20.0, 20.0, (n, 3))
payload = rng.uniform(0.0, 2.0, n)
p = delta.fk(q)
delta_args = {"fk": (q,), "fk_vel": (q, qd), "fk_acc": (q, qd, qdd), "jacobian": (q,),
              "ik": (p,), "inverse_dynamics": (q, qd, qdd, payload)}
arm = SerialRobot.load("puma560")
lim = np.asarray(arm.qlim)
aq = rng.uniform(lim[:, 0], lim[:, 1], (n, arm.n))
aqd = rng.uniform(-2.0, 2.0, (n, arm.n))
aqdd = rng.uniform(-5.0, 5.0, (n, arm.n))
s = slice(0, min(n, small))
arm_args = {"fk": (aq,), "jacobian": (aq,), "frames": (aq[s],), "jacobian_dot": (aq[s], aqd[s]),
            "inverse_dynamics": (aq[s], aqd[s], aqdd[s]), "mass_matrix": (aq[s],)}
out = {}
for label, (robot, method) in wanted.items():
    try:
        if robot == "delta":
            args, fn = delta_args[method], getattr(delta, method)
        else:
            if method == "forward_dynamics":
                tau = arm.inverse_dynamics(*arm_args["inverse_dynamics"])
                arm_args[method] = (aq[s], aqd[s], tau)
            args, fn = arm_args[method], getattr(arm, method)
        out[label] = median_ns(fn, args, len(args[0]))
    except Exception as exc:  # a method this version lacks, or cannot run
        print(f"{label}: {type(exc).__name__}: {exc}", file=sys.stderr)
        out[label] = None
print(json.dumps(out))
"""


class CompareError(DeltagenError, RuntimeError):
    """REF cannot be measured or read."""


def this_tree() -> Path:
    """The folder whose ``deltagen`` package this process imported (this file is
    deltagen/apps/bench/compare.py in it)."""
    return Path(__file__).resolve().parents[3]


def _git(args: list[str], cwd: Path) -> str:
    try:
        proc = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=120)
    except FileNotFoundError as exc:
        raise CompareError("git is not installed: --compare takes a JSON file then") from exc
    if proc.returncode != 0:
        raise CompareError(f"git {' '.join(args)} failed: {proc.stderr.strip()}")
    return proc.stdout.strip()


def from_json(path: str | Path) -> dict[str, float | None]:
    """The REF side from a `deltagen bench --json` file: {label: ns per point or None}."""
    try:
        data = json.loads(read_regular_file(path, "bench --json file").decode("utf-8"))
    except (OSError, ValueError) as exc:  # InputError is a ValueError
        raise CompareError(f"{path}: not a readable `deltagen bench --json` file ({exc})") from exc
    if not isinstance(data, dict) or "throughput" not in data:
        raise CompareError(f"{path}: no 'throughput' section: not `deltagen bench --json` output")
    out: dict[str, float | None] = {}
    for label, (_, _, section, quantity) in MEASURES.items():
        part = data.get(section) or {}
        if section == "serial":
            part = part.get("throughput") or {}
        cell = (part.get(quantity) or {}).get("api") or {}
        value = cell.get("median")
        out[label] = float(value) if isinstance(value, (int, float)) else None
    return out


def probe(tree: Path, cache: Path, n: int, repeats: int) -> dict[str, float | None]:
    """One fresh process measuring the ``deltagen`` of ``tree`` (module doc)."""
    env = dict(os.environ, DELTAGEN_CACHE=str(cache), DELTAGEN_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([str(tree), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    wanted = {label: [robot, method] for label, (robot, method, _, _) in MEASURES.items()}
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(n), str(repeats), str(SMALL_N), json.dumps(wanted)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
    )
    if proc.returncode != 0:
        raise CompareError(
            f"measuring {tree} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
        )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def median_of(runs: list[dict]) -> dict[str, float | None]:
    out = {}
    for label in MEASURES:
        values = [float(v) for r in runs if (v := r.get(label)) is not None]
        out[label] = statistics.median(values) if values else None
    return out


def compare(
    ref: str, n: int, repeats: int, rounds: int, log: Callable[[str], None] | None = None
) -> dict:
    """{"ref": label, "this": label, "rows": {measure: (ref ns, this ns)}, ...}."""
    if rounds < 1:
        raise ValueError(f"--rounds must be at least 1, got {rounds}")
    from deltagen.native.build import usable_cache_dir

    log = log or (lambda text: None)
    tree = this_tree()
    this_cache = usable_cache_dir()
    sides = [("this", tree, this_cache)]
    ref_values = None
    worktree = None
    if ref.endswith(".json") or Path(ref).is_file():
        ref_values = from_json(ref)
        ref_label = f"{ref} (stored run)"
    else:
        commit = _git(["rev-parse", "--verify", f"{ref}^{{commit}}"], tree)
        worktree = Path(tempfile.mkdtemp(prefix=f"deltagen-ref-{commit[:10]}."))
        _git(["worktree", "add", "--detach", "--force", str(worktree), commit], tree)
        ref_cache = usable_cache_dir() / f"compare-{commit[:16]}"
        sides.insert(0, ("ref", worktree, ref_cache))
        ref_label = f"{ref} ({commit[:10]})"
    try:
        runs: dict[str, list[dict]] = {tag: [] for tag, _, _ in sides}
        for tag, path, cache in sides:  # warm-up: builds the modules, loads the caches
            log(f"warm-up ({tag}: {path})")
            probe(path, cache, min(n, 1000), 1)
        for r in range(rounds):
            for tag, path, cache in sides:
                log(f"round {r + 1}/{rounds}: {tag}")
                runs[tag].append(probe(path, cache, n, repeats))
    finally:
        if worktree is not None:
            subprocess.run(
                ["git", "worktree", "remove", "--force", str(worktree)],
                cwd=tree,
                capture_output=True,
            )
    this_values = median_of(runs["this"])
    if ref_values is None:
        ref_values = median_of(runs["ref"])
    return {
        "ref": ref_label,
        "this": str(tree),
        "n": n,
        "repeats": repeats,
        "rounds": rounds,
        "rows": {label: (ref_values.get(label), this_values.get(label)) for label in MEASURES},
    }


def render(result: dict, markdown: bool = False) -> str:
    from deltagen.apps.bench.timing import Style, table

    rows = []
    for label, (ref, this) in result["rows"].items():
        ratio = f"{this / ref:.2f}" if ref and this else "n/a"
        rows.append(
            [
                label,
                "n/a" if ref is None else f"{ref:.2f}",
                "n/a" if this is None else f"{this:.2f}",
                ratio,
            ]
        )
    bullet = Style(markdown).bullet
    out = [
        f"{bullet}ref: {result['ref']}",
        f"{bullet}this: {result['this']}",
        f"{bullet}ns per point, public API on batches of {result['n']:,} (frames, "
        f"jacobian_dot and the arm's dynamics on {min(result['n'], SMALL_N):,}), one thread; "
        f"median of {result['rounds']} fresh processes per side, alternating, each the median "
        f"of {result['repeats']} calls; this/ref < 1: this tree is faster",
        "",
    ]
    out += table(["measure", "ref", "this", "this/ref"], rows, markdown)
    return "\n".join(out)


def main(args: argparse.Namespace) -> int:
    def log(text: str) -> None:
        print(f"bench --compare: {text}", file=sys.stderr, flush=True)

    try:
        result = compare(args.compare, args.n, args.repeats, args.rounds, log)
    except CompareError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(render(result, markdown=bool(getattr(args, "markdown", False))))
    return 0
