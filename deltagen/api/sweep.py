"""Geometry sweeps of a delta robot: ``deltagen.sweep(spec)``.

A design is one set of lengths r_a, r_b, l_a, l_b [m] (report Figure 4); the spec gives a
range (low, high) or a fixed value for each, and the design of experiments: ``grid``
(``n`` values per varied length, every combination) or ``sobol`` (``n`` points of a
scrambled Sobol sequence, scipy.stats.qmc, seeded). Each design is scored by
DeltaRobot.workspace (deltagen.api.workspace): usable volume, height range, the largest
inscribed cylinder, the worst condition number in the usable set, and with inertia and a
reference ``move`` the peak motor torque along it (a rest-to-rest straight line with the
quintic time scaling s = 10 t^3 - 15 t^4 + 6 t^5, through inverse_dynamics_from_platform).
Constraints (``column = {min = ..., max = ...}``) mark each design feasible or not.

It runs on Dask: ``scheduler=None`` uses DASK_SCHEDULER_ADDRESS when set, else a local
cluster with one single-threaded worker process per core; an address ("tcp://host:port")
uses that cluster; ``"inprocess"`` runs here without Dask. Designs go to the workers in
chunks of about ``task_seconds`` of kernel work (timed on the first design); every design
is scored independently and deterministically, so the table does not depend on where or
in which chunk it was computed. The compiled delta core takes the geometry at run time,
so each worker process compiles (or loads from the cache) one core and reuses it for
every design.

The result (SweepResult) is a table of numpy columns; to_csv writes it with the spec, the
seed and the deltagen version in its header lines.

Spec (TOML, or the same as a dict)::

    design = "sobol"          # or "grid"
    n = 32                    # sobol: points; grid: values per varied length
    seed = 1
    theta_deg = [0, 120, 240] # optional
    [ranges]                  # [low, high] or one value [m]
    r_a = [0.15, 0.25]
    r_b = 0.045
    l_a = [0.3, 0.4]
    l_b = [0.7, 0.9]
    [score]                   # options of DeltaRobot.workspace
    step = 0.05               # voxel edge [m]
    max_condition = 10
    q_limits_deg = [-90, 90]
    [move]                    # optional: needs [inertia]
    from = [-0.2, 0.0, -0.8]  # [m]
    to = [0.2, 0.0, -0.8]
    duration = 0.25           # [s]
    payload = 0.5             # [kg]
    [constraints]             # any result column
    cylinder_radius_m = { min = 0.25 }
    worst_condition = { max = 8 }
    [inertia]                 # as in a delta robot file (DeltaInertia)
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from deltagen.errors import DeltagenError, GeometryError
from deltagen.inputs import InputError
from deltagen.model.delta import DeltaInertia
from deltagen.model.robot_file import read_toml

LENGTHS = ("r_a", "r_b", "l_a", "l_b")
SCORES = (
    "volume_m3",
    "z_min_m",
    "z_max_m",
    "worst_condition",
    "cylinder_radius_m",
    "cylinder_height_m",
    "cylinder_volume_m3",
    "box_half_width_m",
    "box_height_m",
    "peak_torque_Nm",
    "poses",
)
_TOP = {"design", "n", "seed", "theta_deg", "ranges", "score", "move", "constraints", "inertia"}
_SCORE_KEYS = {"step", "max_condition", "q_limits_deg", "envelope_levels"}


class SweepError(DeltagenError, ValueError):
    """A sweep spec that cannot be run (the message names the key)."""


@dataclass
class SweepSpec:
    """A validated sweep spec (module docstring)."""

    ranges: dict[str, tuple[float, float]]
    design: str = "sobol"
    n: int = 16
    seed: int = 0
    theta_deg: tuple[float, float, float] = (0.0, 120.0, 240.0)
    score: dict[str, Any] = field(default_factory=dict)
    move: dict[str, Any] | None = None
    constraints: dict[str, dict[str, float]] = field(default_factory=dict)
    inertia: dict[str, Any] | None = None
    raw: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> SweepSpec:
        try:
            data = read_toml(path)
        except GeometryError as exc:
            raise SweepError(str(exc)) from None
        return cls.from_mapping(data, source=str(path))

    @classmethod
    def from_mapping(cls, data: dict[str, Any], source: str = "sweep spec") -> SweepSpec:
        if not isinstance(data, dict):
            raise SweepError(f"{source}: expected a table")
        unknown = set(data) - _TOP
        if unknown:
            raise SweepError(f"{source}: unknown keys {sorted(unknown)} (known: {sorted(_TOP)})")
        design = data.get("design", "sobol")
        if design not in ("grid", "sobol"):
            raise SweepError(f"{source}: design must be 'grid' or 'sobol', got {design!r}")
        n, seed = data.get("n", 16), data.get("seed", 0)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise SweepError(f"{source}: n must be a positive integer, got {n!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise SweepError(f"{source}: seed must be a non-negative integer, got {seed!r}")
        raw_ranges = data.get("ranges", {})
        if not isinstance(raw_ranges, dict):
            raise SweepError(f"{source}: [ranges] must be a table")
        bad = set(raw_ranges) - set(LENGTHS)
        if bad:
            raise SweepError(f"{source}: [ranges] knows {LENGTHS}, not {sorted(bad)}")
        ranges = {}
        for key in LENGTHS:
            if key not in raw_ranges:
                raise SweepError(f"{source}: [ranges] needs {key} ([low, high] or a value, m)")
            v = raw_ranges[key]
            pair = v if isinstance(v, list) else [v, v]
            if len(pair) != 2 or not all(_finite(x) for x in pair) or pair[0] > pair[1]:
                raise SweepError(
                    f"{source}: ranges.{key} must be a finite value or [low, high] with "
                    f"low <= high (m), got {v!r}"
                )
            ranges[key] = (float(pair[0]), float(pair[1]))
        theta = data.get("theta_deg", [0.0, 120.0, 240.0])
        if not isinstance(theta, list) or len(theta) != 3 or not all(_finite(t) for t in theta):
            raise SweepError(f"{source}: theta_deg must be 3 numbers (deg), got {theta!r}")
        score = dict(data.get("score", {}))
        bad = set(score) - _SCORE_KEYS
        if bad:
            raise SweepError(f"{source}: [score] knows {sorted(_SCORE_KEYS)}, not {sorted(bad)}")
        inertia = data.get("inertia")
        if inertia is not None:
            try:
                DeltaInertia.from_mapping(inertia, f"{source} [inertia]")
            except GeometryError as exc:
                raise SweepError(str(exc)) from None
        move = data.get("move")
        if move is not None:
            if inertia is None:
                raise SweepError(f"{source}: [move] (peak torque) needs an [inertia] table")
            for key in ("from", "to"):
                v = move.get(key)
                if not isinstance(v, list) or len(v) != 3 or not all(_finite(x) for x in v):
                    raise SweepError(f"{source}: move.{key} must be 3 numbers (m), got {v!r}")
            d = move.get("duration")
            if not _finite(d) or d <= 0:
                raise SweepError(f"{source}: move.duration must be a positive time (s), got {d!r}")
            if not _finite(move.get("payload", 0.0)) or move.get("payload", 0.0) < 0:
                raise SweepError(f"{source}: move.payload must be a mass >= 0 (kg)")
        constraints = data.get("constraints", {})
        for key, bound in constraints.items():
            if key not in SCORES or not isinstance(bound, dict) or not bound:
                raise SweepError(
                    f"{source}: constraints.{key}: a result column ({', '.join(SCORES)}) "
                    "with {{min = ...}} and/or {{max = ...}}"
                )
            if set(bound) - {"min", "max"} or not all(_finite(v) for v in bound.values()):
                raise SweepError(f"{source}: constraints.{key} takes finite min and/or max")
        return cls(
            ranges=ranges,
            design=design,
            n=n,
            seed=seed,
            theta_deg=tuple(float(t) for t in theta),  # type: ignore[arg-type]
            score=score,
            move=move,
            constraints={k: {b: float(v) for b, v in c.items()} for k, c in constraints.items()},
            inertia=inertia,
            raw=copy.deepcopy(data),
        )

    def designs(self) -> np.ndarray:
        """The designs (N, 4): columns r_a, r_b, l_a, l_b [m]."""
        varied = [k for k in LENGTHS if self.ranges[k][0] < self.ranges[k][1]]
        lo = np.array([self.ranges[k][0] for k in LENGTHS])
        hi = np.array([self.ranges[k][1] for k in LENGTHS])
        if not varied:
            return lo[None, :].copy()
        cols = [LENGTHS.index(k) for k in varied]
        if self.design == "grid":
            axes = [np.linspace(lo[c], hi[c], self.n) for c in cols]
            mesh = np.meshgrid(*axes, indexing="ij")
            unit = np.stack([m.ravel() for m in mesh], axis=-1)
            out = np.repeat(lo[None, :], unit.shape[0], axis=0)
            out[:, cols] = unit
            return out
        from scipy.stats import qmc

        sample = qmc.Sobol(d=len(cols), scramble=True, seed=self.seed).random(self.n)
        out = np.repeat(lo[None, :], self.n, axis=0)
        out[:, cols] = lo[cols] + sample * (hi[cols] - lo[cols])
        return out


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _spec_of(spec: Any) -> SweepSpec:
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, dict):
        return SweepSpec.from_mapping(spec)
    if isinstance(spec, (str, os.PathLike)):
        return SweepSpec.from_toml(spec)
    raise InputError("spec must be a SweepSpec, a dict or the path of a TOML file")


# -- scoring one design (runs on the workers) --------------------------------------------


def _quintic_move(move, n=101):
    """p, pd, pdd (n, 3) of a rest-to-rest straight move with s = 10t^3 - 15t^4 + 6t^5."""
    p0, p1 = np.array(move["from"], float), np.array(move["to"], float)
    T = float(move["duration"])
    t = np.linspace(0.0, 1.0, n)[:, None]
    s = 10 * t**3 - 15 * t**4 + 6 * t**5
    sd = (30 * t**2 - 60 * t**3 + 30 * t**4) / T
    sdd = (60 * t - 180 * t**2 + 120 * t**3) / T**2
    d = p1 - p0
    return p0 + s * d, sd * d, sdd * d


def score_design(spec: SweepSpec, lengths: Any) -> dict[str, float]:
    """The score columns (SCORES) of one design (r_a, r_b, l_a, l_b) [m]; NaN scores (and
    poses 0) for a geometry the robot model rejects."""
    from deltagen.api.delta import DeltaRobot

    r_a, r_b, l_a, l_b = (float(v) for v in lengths)
    inertia = DeltaInertia.from_mapping(spec.inertia) if spec.inertia is not None else None
    nan = dict.fromkeys(SCORES, math.nan)
    nan["poses"] = 0.0
    try:
        robot = DeltaRobot(
            r_a,
            r_b,
            l_a,
            l_b,
            tuple(math.radians(t) for t in spec.theta_deg),
            inertia=inertia,
            threads=1,
        )
    except GeometryError:
        return nan
    opts = dict(spec.score)
    step = opts.pop("step", None)
    qdeg = opts.pop("q_limits_deg", None)
    if qdeg is not None:
        opts["q_limits"] = (math.radians(qdeg[0]), math.radians(qdeg[1]))
    ws = robot.workspace(step, progress=False, **opts)
    out = {k: float(v) for k, v in ws.summary().items()}
    out["poses"] = float(ws.settings["poses"])
    out["peak_torque_Nm"] = math.nan
    if spec.move is not None:
        p, pd, pdd = _quintic_move(spec.move)
        tau, valid = robot.inverse_dynamics_from_platform(
            p, pd, pdd, float(spec.move.get("payload", 0.0)), errors="nan"
        )
        if valid.all():
            out["peak_torque_Nm"] = float(np.max(np.abs(tau[:, :3])))
    return {k: out.get(k, math.nan) for k in SCORES}


def score_chunk(spec: SweepSpec, rows: Any) -> np.ndarray:
    """Scores (len(rows), len(SCORES)) of a chunk of designs: one Dask task."""
    return np.array([[score_design(spec, r)[k] for k in SCORES] for r in rows], dtype=float)


# -- the result table --------------------------------------------------------------------


@dataclass
class SweepResult:
    """Designs and their scores: ``columns`` maps a name to a (N,) array; ``feasible`` (N,)
    says which designs meet every constraint (NaN scores never do)."""

    spec: SweepSpec
    columns: dict[str, np.ndarray]
    feasible: np.ndarray
    seconds: float
    workers: int
    version: str

    def __len__(self) -> int:
        return len(self.feasible)

    def pareto(
        self, maximise: str = "cylinder_volume_m3", minimise: str | None = None
    ) -> np.ndarray:
        """Mask (N,) of the feasible designs no other feasible design beats in both
        ``maximise`` and ``minimise`` (default: peak torque when a move is given, else the
        worst condition number)."""
        if minimise is None:
            minimise = "peak_torque_Nm" if self.spec.move is not None else "worst_condition"
        a, b = self.columns[maximise], self.columns[minimise]
        ok = self.feasible & np.isfinite(a) & np.isfinite(b)
        front = np.zeros(len(a), bool)
        for i in np.flatnonzero(ok):
            better = ok & (a >= a[i]) & (b <= b[i]) & ((a > a[i]) | (b < b[i]))
            front[i] = not better.any()
        return front

    @property
    def designs_per_second(self) -> float:
        return len(self) / self.seconds if self.seconds > 0 else math.nan

    @property
    def poses_per_second(self) -> float:
        total = float(np.nansum(self.columns["poses"]))
        return total / self.seconds if self.seconds > 0 else math.nan

    def header(self) -> list[str]:
        """The provenance lines every result file starts with (without the '# ')."""
        return [
            f"deltagen {self.version} sweep",
            f"seed = {self.spec.seed}",
            "spec = " + json.dumps(self.spec.raw, sort_keys=True),
        ]

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        names = list(self.columns)
        with path.open("w", newline="") as fh:
            for line in self.header():
                fh.write(f"# {line}\n")
            w = csv.writer(fh)
            w.writerow(names + ["feasible", "pareto"])
            front = self.pareto()
            for i in range(len(self)):
                w.writerow(
                    [repr(float(self.columns[k][i])) for k in names]
                    + [int(self.feasible[i]), int(front[i])]
                )
        return path


def _feasible(spec: SweepSpec, columns: dict[str, np.ndarray]) -> np.ndarray:
    ok = np.isfinite(columns["volume_m3"]) & (columns["volume_m3"] > 0)
    for key, bound in spec.constraints.items():
        v = columns[key]
        with np.errstate(invalid="ignore"):
            if "min" in bound:
                ok &= v >= bound["min"]
            if "max" in bound:
                ok &= v <= bound["max"]
    return ok


# -- running ------------------------------------------------------------------------------


def sweep(
    spec: Any,
    scheduler: str | None = None,
    *,
    workers: int | None = None,
    task_seconds: float = 1.0,
    progress: bool | None = None,
) -> SweepResult:
    """Score every design of ``spec`` (a SweepSpec, a dict or a TOML path; module
    docstring). scheduler: None (DASK_SCHEDULER_ADDRESS, else a local cluster of
    ``workers`` processes, default every core), "inprocess" (no Dask), or the address of
    a running Dask scheduler."""
    from deltagen import __version__

    spec = _spec_of(spec)
    designs = spec.designs()
    n = len(designs)
    if scheduler is None:
        scheduler = os.environ.get("DASK_SCHEDULER_ADDRESS") or "local"
    t0 = time.perf_counter()
    used = 1
    if scheduler == "inprocess":
        bar = _bar(n, progress)
        rows = []
        for d in designs:
            rows.append(score_chunk(spec, [d]))
            bar.update(1)
        bar.close()
        scores = np.concatenate(rows) if rows else np.zeros((0, len(SCORES)))
    else:
        scores, used = _run_dask(spec, designs, scheduler, workers, task_seconds, progress)
    seconds = time.perf_counter() - t0
    columns = {k: designs[:, i].copy() for i, k in enumerate(LENGTHS)}
    columns.update({k: scores[:, j] for j, k in enumerate(SCORES)})
    return SweepResult(spec, columns, _feasible(spec, columns), seconds, used, __version__)


def _bar(total, show):
    import sys

    if show is None:
        show = sys.stderr.isatty()
    if show:
        try:
            from tqdm import tqdm

            return tqdm(total=total, desc="sweep", unit="design", leave=False, delay=1.0)
        except ImportError:
            pass

    class _Silent:
        def update(self, k):
            pass

        def close(self):
            pass

    return _Silent()


def _run_dask(spec, designs, scheduler, workers, task_seconds, progress):
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as exc:
        raise SweepError(
            "Dask is needed for sweeps on a cluster: pip install 'deltagen[design]' "
            "(or scheduler='inprocess')"
        ) from exc
    # chunk so a task holds ~task_seconds of work, timed on the first design here
    t = time.perf_counter()
    first = score_chunk(spec, designs[:1])
    per_design = max(time.perf_counter() - t, 1e-3)
    size = max(1, int(round(task_seconds / per_design)))
    rest = designs[1:]
    chunks = [rest[i : i + size] for i in range(0, len(rest), size)]
    cluster = None
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # any free port: never clashes with a running cluster
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        used = len(client.scheduler_info().get("workers", {})) or 1
        spec_future = client.scatter(spec, broadcast=True)
        futures = [client.submit(score_chunk, spec_future, c, pure=False) for c in chunks]
        index = {f.key: i for i, f in enumerate(futures)}
        results: list[Any] = [None] * len(futures)
        bar = _bar(len(designs), progress)
        bar.update(1)
        for fut in as_completed(futures):
            results[index[fut.key]] = fut.result()
            bar.update(len(chunks[index[fut.key]]))
        bar.close()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return np.concatenate([first] + results), used
