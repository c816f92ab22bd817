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

Checks before anything runs: every key of the spec against one schema (``_SCHEMA``: its
type, shape and range; the message names the key, e.g. "score.q_limits_deg"), the design
table and one design's workspace grid against the memory budget (deltagen.inputs,
DELTAGEN_MAX_MEMORY), ``workers`` (a positive integer), and a scheduler address by a probe
(probe_scheduler: it must answer like a Dask scheduler within DELTAGEN_CONNECT_TIMEOUT, default
10 s) before Dask connects with the same timeout.

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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from deltagen.api.workspace import MIN_ENVELOPE_LEVELS, check_delta_grid, delta_default_box
from deltagen.errors import DeltagenError, GeometryError
from deltagen.inputs import InputError, check_integer, check_memory, check_real, is_real
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
            data = read_toml(path, "sweep spec")
        except GeometryError as exc:
            raise SweepError(str(exc)) from None
        return cls.from_mapping(data, source=str(path))

    @classmethod
    def from_mapping(cls, data: dict[str, Any], source: str = "sweep spec") -> SweepSpec:
        """The spec checked against the schema (_SCHEMA: every key's type, shape and range,
        the key named in the message) and against the memory budget."""
        if isinstance(data, dict) and "ranges" not in data:
            raise SweepError(
                f"{source}: [ranges] needs {', '.join(LENGTHS)} ([low, high] or a value, m)"
            )
        checked = _table(_SCHEMA, top=True)(data, source)
        if "move" in checked and "inertia" not in checked:
            raise SweepError(f"{source}: [move] (peak torque) needs an [inertia] table")
        spec = cls(
            ranges=checked["ranges"],
            design=checked.get("design", "sobol"),
            n=checked.get("n", 16),
            seed=checked.get("seed", 0),
            theta_deg=checked.get("theta_deg", (0.0, 120.0, 240.0)),
            score=checked.get("score", {}),
            move=checked.get("move"),
            constraints=checked.get("constraints", {}),
            inertia=data.get("inertia"),
            raw=copy.deepcopy(_plain(data)),
        )
        spec.check_resources(source)
        return spec

    def design_count(self) -> int:
        """How many designs designs() gives (exact, without making them)."""
        varied = sum(1 for k in LENGTHS if self.ranges[k][0] < self.ranges[k][1])
        if not varied:
            return 1
        return self.n**varied if self.design == "grid" else self.n

    def check_resources(self, source: str = "sweep spec") -> None:
        """SweepError (naming the key and the size) when the design table, or one design's
        workspace grid at score.step, would exceed the memory budget
        (deltagen.inputs.memory_limit, DELTAGEN_MAX_MEMORY)."""
        count = self.design_count()
        what = (
            f"n = {self.n} values per varied length (grid: {count:.3g} designs)"
            if self.design == "grid"
            else f"n = {count:.3g} designs"
        )
        try:
            check_memory(
                float(count) * BYTES_PER_DESIGN,
                f"{source}: {what}, whose table",
                "choose a smaller n",
            )
            step = self.score.get("step")
            if step is not None:  # the largest design's grid (default step: size / 40)
                hi = {k: self.ranges[k][1] for k in LENGTHS}
                lo_r_b = self.ranges["r_b"][0]
                box = delta_default_box(hi["r_a"], lo_r_b, hi["l_a"], hi["l_b"])
                check_delta_grid(box, step, "score.step", source)
        except InputError as exc:
            raise SweepError(str(exc)) from None

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


# -- the spec's schema: every key's type, shape and range ----------------------------------
#
# A checker takes (value, where) -- where names the key, e.g. "spec.toml: score.step" -- and
# returns the value normalised (floats, tuples) or raises SweepError naming the key.

Check = Callable[[Any, str], Any]


def _as_sweep_error(check: Callable[[], Any]) -> Any:
    try:
        return check()
    except InputError as exc:
        raise SweepError(str(exc)) from None


def _real(low: float | None = None, low_open: bool = False, unit: str = "") -> Check:
    return lambda v, where: _as_sweep_error(
        lambda: check_real(v, where, low=low, low_open=low_open, unit=unit)
    )


def _integer(low: int) -> Check:
    return lambda v, where: _as_sweep_error(lambda: check_integer(v, where, low=low))


def _choice(*options: str) -> Check:
    def check(v: Any, where: str) -> str:
        if not isinstance(v, str) or v not in options:
            raise SweepError(f"{where} must be {' or '.join(repr(o) for o in options)}, got {v!r}")
        return v

    return check


def _reals(count: int, unit: str) -> Check:
    def check(v: Any, where: str) -> tuple[float, ...]:
        if not isinstance(v, (list, tuple)) or len(v) != count:
            raise SweepError(f"{where} must be {count} numbers [{unit}], got {v!r}")
        return tuple(_real(unit=unit)(x, f"{where}[{i}]") for i, x in enumerate(v))

    return check


def _interval(unit: str, scalar_ok: bool) -> Check:
    """[low, high] with low < high (scalar_ok: or one value, low = high allowed)."""

    def check(v: Any, where: str) -> tuple[float, float]:
        if scalar_ok and is_real(v):
            x = _real(unit=unit)(v, where)
            return (x, x)
        shape = "a value or [low, high]" if scalar_ok else "[low, high]"
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise SweepError(f"{where} must be {shape} [{unit}], got {v!r}")
        low, high = (_real(unit=unit)(x, f"{where}[{i}]") for i, x in enumerate(v))
        if low > high or (low == high and not scalar_ok):
            relation = "<=" if scalar_ok else "<"
            raise SweepError(f"{where} must have low {relation} high [{unit}], got {v!r}")
        return (low, high)

    return check


def _table(fields: dict[str, Check], required: tuple[str, ...] = (), top: bool = False) -> Check:
    """A TOML table with the keys of ``fields`` (each checked), ``required`` among them;
    ``top``: the spec itself (its keys are named "source: key", nested ones "source: a.b")."""

    def check(v: Any, where: str) -> dict[str, Any]:
        if not isinstance(v, dict):
            raise SweepError(f"{where} must be a table, got {v!r}")
        unknown = set(v) - set(fields)
        if unknown:
            raise SweepError(
                f"{where}: unknown keys {sorted(map(str, unknown))} (known: {sorted(fields)})"
            )
        for key in required:
            if key not in v:
                raise SweepError(f"{where} needs {key}")
        return {k: fields[k](x, f"{where}: {k}" if top else f"{where}.{k}") for k, x in v.items()}

    return check


def _inertia(v: Any, where: str) -> Any:
    try:
        DeltaInertia.from_mapping(v, where)
    except GeometryError as exc:
        raise SweepError(str(exc)) from None
    return v


def _constraints(v: Any, where: str) -> dict[str, dict[str, float]]:
    if not isinstance(v, dict):
        raise SweepError(f"{where} must be a table, got {v!r}")
    out = {}
    for key, bound in v.items():
        if key not in SCORES or not isinstance(bound, dict) or not bound:
            raise SweepError(
                f"{where}.{key}: a result column ({', '.join(SCORES)}) "
                "with {min = ...} and/or {max = ...}"
            )
        out[key] = _table({"min": _real(), "max": _real()})(bound, f"{where}.{key}")
    return out


_SCHEMA: dict[str, Check] = {
    "design": _choice("grid", "sobol"),
    "n": _integer(1),
    "seed": _integer(0),
    "theta_deg": _reals(3, "deg"),
    "ranges": _table({k: _interval("m", scalar_ok=True) for k in LENGTHS}, required=LENGTHS),
    "score": _table(
        {
            "step": _real(0.0, low_open=True, unit="m"),
            "max_condition": _real(1.0),
            "q_limits_deg": _interval("deg", scalar_ok=False),
            "envelope_levels": _integer(MIN_ENVELOPE_LEVELS),
        }
    ),
    "move": _table(
        {
            "from": _reals(3, "m"),
            "to": _reals(3, "m"),
            "duration": _real(0.0, low_open=True, unit="s"),
            "payload": _real(0.0, unit="kg"),
        },
        required=("from", "to", "duration"),
    ),
    "constraints": _constraints,
    "inertia": _inertia,
}
#: Bytes per design of a sweep: the design table, its score rows (each chunk's and the
#: joined), the result columns and the CSV row being written.
BYTES_PER_DESIGN = 8 * (len(LENGTHS) + 3 * len(SCORES) + len(LENGTHS) + len(SCORES) + 2)


def _plain(value: Any) -> Any:
    """A spec value as plain Python (numpy scalars as int/float) for the JSON header."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


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
    if workers is not None:
        workers = _as_sweep_error(lambda: check_integer(workers, "workers", low=1))
    task_seconds = _as_sweep_error(
        lambda: check_real(task_seconds, "task_seconds", low=0.0, low_open=True, unit="s")
    )
    if scheduler is not None and not isinstance(scheduler, str):
        raise SweepError(f"scheduler must be an address, 'inprocess' or None, got {scheduler!r}")
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
        if workers is not None:
            raise SweepError(
                f"workers ({workers}) sizes a local cluster; the cluster at {scheduler} has "
                "its own workers"
            )
        client = connect(scheduler)
    try:
        # chunk so a task holds ~task_seconds of work, timed on the first design here
        # (after connecting: a bad address fails at once)
        t = time.perf_counter()
        first = score_chunk(spec, designs[:1])
        per_design = max(time.perf_counter() - t, 1e-3)
        size = max(1, int(round(task_seconds / per_design)))
        rest = designs[1:]
        chunks = [rest[i : i + size] for i in range(0, len(rest), size)]
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


#: Seconds to wait for a Dask scheduler to answer (connection and handshake);
#: DELTAGEN_CONNECT_TIMEOUT overrides it (seconds; not a DASK_ variable, which Dask would
#: read into its own configuration).
CONNECT_TIMEOUT = 10.0
#: The largest first message a Dask scheduler opens with: its handshake (a few hundred
#: bytes of msgpack) behind an 8-byte little-endian length (distributed.comm.tcp).
_MAX_HANDSHAKE = 1 << 20


def _connect_timeout() -> float:
    text = os.environ.get("DELTAGEN_CONNECT_TIMEOUT")
    if text is None or text.strip() == "":
        return CONNECT_TIMEOUT
    try:
        value = float(text.strip().rstrip("s"))
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise SweepError(
            f"DELTAGEN_CONNECT_TIMEOUT must be a positive number of seconds, got {text!r}; unset "
            f"it for {CONNECT_TIMEOUT:g} s"
        )
    return value


def probe_scheduler(address: str, timeout: float) -> None:
    """SweepError unless something at the TCP ``address`` answers like a Dask scheduler
    within ``timeout`` seconds: a scheduler opens with its handshake, a small message behind
    an 8-byte little-endian length. Anything else (an SSH or HTTP banner, silence, a closed
    port) is refused here, before Dask reads the banner's first bytes as a length and tries
    to allocate that much (exabytes for text). Addresses other than tcp:// (tls://, ws://,
    inproc://) are left to Dask and its timeout."""
    import socket
    import struct
    from urllib.parse import urlsplit

    text = address if "://" in address else f"tcp://{address}"
    parts = urlsplit(text)
    if parts.scheme != "tcp":
        return
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if not host or port is None:
        raise SweepError(f"scheduler address {address!r}: expected tcp://host:port")
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            head = b""
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        raise SweepError(
            f"no Dask scheduler answered at {address} within {timeout:g} s (something "
            "accepted the connection but sent nothing); check the address, or set "
            "DELTAGEN_CONNECT_TIMEOUT"
        ) from None
    except OSError as exc:
        raise SweepError(
            f"cannot connect to the Dask scheduler at {address}: {exc.strerror or exc}"
        ) from None
    if len(head) < 8:
        raise SweepError(
            f"{address} closed the connection without a Dask handshake: not a Dask scheduler"
        )
    (length,) = struct.unpack("<Q", head)
    if not 0 < length <= _MAX_HANDSHAKE:
        raise SweepError(
            f"{address} answered, but not as a Dask scheduler (it began with {head!r}); "
            "check the address and port (a scheduler listens on 8786 by default)"
        )


def connect(address: str) -> Any:
    """A dask.distributed Client of the scheduler at ``address``: probed first
    (probe_scheduler), then connected with a timeout; every failure a SweepError naming
    the address."""
    from dask.distributed import Client

    timeout = _connect_timeout()
    probe_scheduler(address, timeout)
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError, MemoryError, ValueError, TypeError) as exc:
        raise SweepError(
            f"cannot connect to the Dask scheduler at {address} within {timeout:g} s: "
            f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
        ) from None
