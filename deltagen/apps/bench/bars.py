"""The bars of ``deltagen bench`` (``deltagen bench --bars`` runs them alone): every speed
target of the batched kernels measured in one run as a ratio against a baseline measured
in the same run, printed with its target and met / MISSED. A ratio of two timings taken
side by side (round-robin, the minimum of the repeats of each: the least disturbed run of
each on a shared machine) is what a loaded host changes least. Single-threaded measures use
this thread's CPU time (:data:`CLOCK`), not wall time: on a machine whose cores other
processes hold, wall time mostly measures the wait for a core; the threads bar is wall
time (it measures exactly that a second core shortens the wall time).

The bars and their baselines:

* **Puma 560 fk <= 2.0x, jacobian <= 2.5x, inverse dynamics (RNEA) <= 3x the floor.** The
  C kernel (preallocated outputs, ``deltagen_puma560_<fn>``) beside the floor of the same
  rows, both on calls of FLOOR_CALL_N configurations (inputs and outputs in cache: what is
  measured is the per-point work, as the kernels' own speed guards do; a batch of 10^5
  adds the memory traffic of the outputs, which the floor does not write) looped to about
  FLOOR_LOOP_POINTS points per repeat. The floor = trig + arithmetic:

  - *trig*: a hand-written C loop (trig_floor.c, ``deltagen_floor_trig``, compiled by
    native/toolchain.py with the generated modules' flags) that makes, per point, one sine
    and one cosine of each of the kernel's angles (6 for the Puma) in the kernels' own shape:
    row-major input gathered into columns of 64-point blocks, a sine loop and a cosine loop
    per angle that gcc turns into libmvec's 8-lane vector calls (``_ZGVeN8v_sin`` /
    ``_ZGVeN8v_cos`` with AVX-512; the symbols the built loop imports are printed) or
    scalar libm calls where libmvec is absent (said in the output);
  - *arithmetic*: the operation count the generated C states for the kernel ("Cost: N
    operations per point", SymPy's count_ops after common-subexpression elimination, read
    from the module's header) at the machine's vector FMA rate, measured in the same run by
    ``deltagen_floor_fma`` (64 independent ``fma`` chains; 2 operations per FMA): one
    counted operation costs half a lane of an FMA. The kernels are built with -std=c99,
    which does not contract a*b+c into an FMA, so this arithmetic is a lower bound the
    kernels cannot quite reach: the floor is optimistic, never generous.

* **Delta fk >= 12x a column-wise numpy fk.** ``robot._core.fk`` (fresh outputs) beside
  :func:`numpy_fk_columns`: the same three-sphere intersection written on (N,) coordinate
  columns (no per-row loop, no (N, 3, 3) stacks), on the same FLOOR_N rows, after
  :func:`settle_allocator` (numpy's temporaries reused, not fresh pages: numpy at its
  fastest, whatever ran before in the process). Beside it, the delta fk's floor measured in
  the same round-robin as the Puma's (the floor loop on the same rows: 3 sines and 3
  cosines per point; the stated operations at the FMA rate), and the ratio to numpy a
  kernel at that floor would reach: where that is well below 12, no change to the kernel's
  arithmetic or loops can meet the bar on this host, only cheaper trigonometry. (For the
  delta the stated operations include a few loop-invariant ones gcc hoists, l_b,1^2 and
  the radii terms, so its floor is an estimate within a few percent, not a bound. Measured
  on the project's 2-core EPYC: trig 6.7 ns/point, floor 9.1, the C kernel 8.8, _core.fk
  9.7, numpy 94 settled and 150 in a fresh process without it: 10.3x at the floor.)
* **Delta fk_vel <= 1.35x fk, fk_acc <= 1.8x fk.** The C kernels with preallocated outputs
  on the same rows. Beside each, for information only (the verdict stays on the FLOOR_N
  rows), the same ratio in cache: calls of FLOOR_CALL_N rows looped to about
  FLOOR_LOOP_POINTS points, as the Puma floor, timed in the same round-robin. On FLOOR_N
  rows fk hides its memory traffic behind its arithmetic, fk_vel and fk_acc (twice and
  three times fk's bytes) do not hide all of it: the difference of the two ratios is that
  traffic (measured on the project's 2-core EPYC: fk 8.8 ns/point both ways, fk_vel 12.9
  in cache and 14.0 on 10^5 rows, fk_acc 17.0 and 20.1; a numpy copy of the same bytes
  0.8-1.6 ns/point in cache, 1.6-4.6 on 10^5 rows).
* **Puma ik_all of one pose <= 3.7x pinocchio's computeFrameJacobian.** ``arm.ik_all(T)``
  of one (4, 4) pose beside ``pinocchio.computeFrameJacobian(model, data, q, tool,
  LOCAL_WORLD_ALIGNED)`` on the same arm (peers.pinocchio_model), each looped ~10 ms of
  CPU time per repeat.
* **Numeric IK with default options: median <= 0.25x, p95 <= 1.2x rtb's ik_LM.** The same
  IK_TARGETS targets fk(q) (ik.numeric_targets): ``arm.ik(T, method="numeric")`` (a
  failure raises and counts as unsolved) and roboticstoolbox-python's C++
  ``ets().ik_LM(T, tol=5e-21, joint_limits=True)`` (the tolerance that stops it at 1e-10,
  as the IK section), called
  alternately per target; each target's time is the minimum of IK_PASSES passes; median and
  95th percentile over the targets, with both success rates.
* **Two threads >= 1.8x one on THREADS_N rows**, through the public API (``robot.fk(q)``,
  so the Python work after the kernel counts: Amdahl): delta fk and Puma fk (and the Puma
  jacobian, reported, no bar), robots made with threads=1 and threads=2, round-robin, in
  wall time, with the process CPU time beside it. In the same round-robin, the machine's
  own ceiling: the same C kernel on the two halves of the rows in two plain threads vs
  one, on preallocated outputs (the host's cores and memory) and on fresh ones (plus the
  first touch of new pages), so a reader can tell what the host gives from what the API
  loses (:func:`measure_threads`: a missed ratio is "unsettled" while other processes held
  the second core -- measured from /proc/stat, else the load average -- or while the
  host's own fresh-output ceiling is below the target). A machine with fewer than two
  usable cores cannot measure it: the row says so.

A peer that is not importable (pinocchio, roboticstoolbox-python) gives its row "n/a" with
the reason; nothing raises. The default run (``deltagen bench --bars``) takes well under a
minute; ``--n`` smaller than THREADS_N shrinks every workload (the tests run it tiny).
"""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deltagen.apps.bench.timing import Stat, Style, batch_timer, interleaved, loop_timer, num

FLOOR_N = 100_000  # rows of the delta ratios
FLOOR_CALL_N = 1024  # configurations per call of the Puma kernels and the floor loop
FLOOR_LOOP_POINTS = 200_000  # points per repeat of those (calls looped)
THREADS_N = 1_000_000  # rows of the threads bar
IK_TARGETS = 300  # numeric IK targets
IK_PASSES = 3  # passes over the targets; each target's time is its minimum
FMA_ITERATIONS = 20_000  # one FMA-rate repeat: 64 chains x this many updates
SEED = 2108
ARM = "puma560"
ANGLES = 6  # the Puma's revolute joints: one sin and one cos each

#: (bar key, label, relation, target)
TARGETS = {
    "puma_fk_floor": ("Puma fk / floor", "<=", 2.0),
    "puma_jacobian_floor": ("Puma jacobian / floor", "<=", 2.5),
    "puma_rnea_floor": ("Puma inverse dynamics (RNEA) / floor", "<=", 3.0),
    "delta_fk_numpy": ("delta fk: column-wise numpy / deltagen", ">=", 12.0),
    "delta_fk_vel": ("delta fk_vel / fk (C kernels)", "<=", 1.35),
    "delta_fk_acc": ("delta fk_acc / fk (C kernels)", "<=", 1.8),
    "ik_all_pinocchio": ("Puma ik_all one pose / pinocchio computeFrameJacobian", "<=", 3.7),
    "numeric_ik_median": ("numeric IK median / rtb ik_LM median", "<=", 0.25),
    "numeric_ik_p95": ("numeric IK p95 / rtb ik_LM p95", "<=", 1.2),
    "threads_delta_fk": ("delta fk API: threads=1 / threads=2", ">=", 1.8),
    "threads_puma_fk": ("Puma fk API: threads=1 / threads=2", ">=", 1.8),
}
#: the kernels measured against the floor: bar key -> (kernel, its inputs)
FLOOR_KERNELS = {
    "puma_fk_floor": ("fk", ("q",)),
    "puma_jacobian_floor": ("jacobian", ("q",)),
    "puma_rnea_floor": ("inverse_dynamics", ("q", "qd", "qdd")),
}

_FLOOR_CDEF = """
int deltagen_floor_trig(size_t n, size_t angles, const double *q, double *sums);
int deltagen_floor_fma(size_t iterations, double a, double b, double *out);
"""


# ------------------------------------------------------------------------- the floor loop


def floor_module():
    """The compiled trig_floor.c (``.ffi``, ``.lib``), built once per cache key by
    native/build.py with the generated modules' flags."""
    from deltagen.native.build import load_c_source

    return load_c_source(
        Path(__file__).with_name("trig_floor.c"), "deltagen_floor", _FLOOR_CDEF, "deltagen_floor"
    )


def trig_sums(module: Any, q: np.ndarray) -> np.ndarray:
    """(2, angles): the floor loop's sums of sin and of cos of each column of q (N, angles)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    n, angles = q.shape
    sums = np.empty(2 * angles)
    ffi, lib = module.ffi, module.lib
    rc = lib.deltagen_floor_trig(
        n, angles, ffi.from_buffer("double[]", q), ffi.from_buffer("double[]", sums, True)
    )
    if rc != 0:
        raise ValueError(f"the floor loop takes 1 to 16 angles, got {angles}")
    return sums.reshape(2, angles)


def vector_trig(module: Any) -> str:
    """What the built floor loop calls for sin and cos: the libmvec symbols it imports
    (their lane count is in the name: _ZGVeN8v_sin is 8 lanes), else scalar libm."""
    data = Path(module.__file__).read_bytes()
    names = sorted({m.decode() for m in re.findall(rb"_ZGV\w+?_(?:sin|cos|sincos)\b", data)})
    if not names:
        return "scalar libm sin/cos (no libmvec vector calls in this build)"
    lanes = sorted({int(m.group(1)) for m in (re.search(r"N(\d+)", x) for x in names) if m})
    return f"libmvec {' / '.join(names)} ({'/'.join(map(str, lanes))} lanes)"


def kernel_costs(module: str = f"serial_{ARM}") -> dict[str, int]:
    """{C function: operations per point} as the generated header states them."""
    from deltagen.paths import generated_dir

    text = (generated_dir() / f"{module}.h").read_text()
    pattern = re.compile(r"Cost: (\d+) operations per point\.(?:(?!\*/).)*?\*/\s*int (\w+)\(", re.S)
    return {name: int(cost) for cost, name in pattern.findall(text)}


#: The clock of every single-threaded measure here: this thread's CPU time, which leaves
#: out the time the thread waits for a core while other processes hold it (on a loaded
#: shared machine that wait dominates wall time); the threads bar uses wall time.
CLOCK = time.thread_time_ns


def cpu_timer(
    fn: Callable, args: tuple = (), points: int = 1, loops: int = 1
) -> Callable[[], float]:
    """timing.batch_timer on :data:`CLOCK`: CPU ns per point."""
    return batch_timer(fn, args, points, loops, CLOCK)


def cpu_loop_timer(fn: Callable, repeat_ns: int = 10_000_000) -> Callable[[], float]:
    """timing.loop_timer on :data:`CLOCK` for about ``repeat_ns``: CPU ns per call."""
    return loop_timer(fn, repeat_ns, CLOCK)


def _trig_call(module: Any, q: np.ndarray) -> Callable[[], int]:
    """A no-argument call of the floor loop on q (the sums are dropped)."""
    ffi, lib = module.ffi, module.lib
    n, angles = q.shape
    sums = np.empty(2 * angles)
    args = (n, angles, ffi.from_buffer("double[]", q), ffi.from_buffer("double[]", sums, True))
    keep = (q, sums)  # the buffers must outlive the call
    return lambda: (lib.deltagen_floor_trig(*args), keep)[0]


def _fma_timer(module: Any) -> Callable[[], float]:
    """A timer: ns per floating-point operation of the FMA loop (2 per FMA)."""
    ffi, lib = module.ffi, module.lib
    out = np.empty(64)
    args = (FMA_ITERATIONS, 0.999999, 1e-7, ffi.from_buffer("double[]", out, True))
    return cpu_timer(lib.deltagen_floor_fma, args, 2 * 64 * FMA_ITERATIONS)


# ------------------------------------------------------------------------- numpy baseline


#: bytes of the block :func:`settle_allocator` frees: half of glibc's largest dynamic mmap
#: threshold (32 MiB on 64-bit), above any one temporary of the numpy fk on FLOOR_N rows
SETTLE_BYTES = 16 * 1024 * 1024


def settle_allocator() -> None:
    """Put glibc's malloc in the state the column-wise numpy fk is fastest in, whatever ran
    before in this process. Each of its temporaries (0.8 MB on 10^5 rows) is above malloc's
    initial mmap threshold (128 KiB): a fresh mapping, first-touched page by page, until the
    process frees a mapped block, which raises the threshold to that block's size; the
    temporaries then come from the heap and are reused. Which state a process is in depends
    on its history: the same numpy fk measured 93 and 150 ns/point in two fresh processes on
    the project's EPYC. Freeing one SETTLE_BYTES block first gives every run the fast
    state: the stricter baseline. (Elsewhere than glibc, an allocation and a free.)"""
    block = np.empty(SETTLE_BYTES // 8)
    del block


def numpy_fk_columns(geom: Any, q: np.ndarray) -> np.ndarray:
    """Delta fk in numpy on (N,) coordinate columns: the baseline of the ">= 12x" bar.

    Crank i at base angle theta_i puts its elbow (sphere centre) at S_i = ((r_i + l_a cos
    q_i) cos theta_i, (r_i + l_a cos q_i) sin theta_i, -l_a sin q_i) with r_i = r_a - r_b
    (delta report, eqs. (2)-(27)); the platform point is the lower intersection of the three
    spheres |p - S_i| = l_b,i: with a = S_2 - S_1, b = S_3 - S_1, e = a x b, the point
    u0 = (A (b x e) + B (e x a)) / (2 |e|^2) (A = |a|^2 + l_b1^2 - l_b2^2, B likewise)
    lies on both radical planes, and p = S_1 + u0 + t e/|e| with t = -+sqrt(l_b1^2 - |u0|^2)
    against the normal's z. Every product is written per coordinate column; no status
    (the compiled core's rows are all OK here). Returns p (N, 3)."""
    th = np.asarray(geom.theta, dtype=np.float64)
    r = np.asarray(geom.chain_r, dtype=np.float64)
    la = np.asarray(geom.chain("l_a"), dtype=np.float64)
    lb = np.asarray(geom.chain("l_b"), dtype=np.float64)
    offset = np.asarray(geom.q_offset, dtype=np.float64)[:3]
    S = []
    for i in range(3):
        qi = q[:, i] + offset[i] if offset[i] else q[:, i]
        rho = r[i] + la[i] * np.cos(qi)
        S.append((rho * np.cos(th[i]), rho * np.sin(th[i]), -la[i] * np.sin(qi)))
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = S
    ax, ay, az = x2 - x1, y2 - y1, z2 - z1
    bx, by, bz = x3 - x1, y3 - y1, z3 - z1
    ex, ey, ez = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    e2 = ex * ex + ey * ey + ez * ez
    A = ax * ax + ay * ay + az * az + lb[0] ** 2 - lb[1] ** 2
    B = bx * bx + by * by + bz * bz + lb[0] ** 2 - lb[2] ** 2
    # b x e and e x a, per column
    bex, bey, bez = by * ez - bz * ey, bz * ex - bx * ez, bx * ey - by * ex
    eax, eay, eaz = ey * az - ez * ay, ez * ax - ex * az, ex * ay - ey * ax
    half = 0.5 / e2
    ux, uy, uz = (A * bex + B * eax) * half, (A * bey + B * eay) * half, (A * bez + B * eaz) * half
    h = lb[0] ** 2 - (ux * ux + uy * uy + uz * uz)
    norm = np.sqrt(e2)
    t = np.where(ez < 0.0, 1.0, -1.0) * np.sqrt(h) / norm
    p = np.empty((q.shape[0], 3))
    p[:, 0] = x1 + ux + t * ex
    p[:, 1] = y1 + uy + t * ey
    p[:, 2] = z1 + uz + t * ez
    return p


# ------------------------------------------------------------------------- rows


def _load() -> str:
    try:
        return ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except (OSError, AttributeError):
        return "?"


def _row(key: str, measured: str, baseline: str, value: float | None, note: str = "") -> dict:
    label, relation, target = TARGETS[key]
    if value is None or not np.isfinite(value):
        verdict = "n/a"
    elif relation == "<=":
        verdict = "met" if value <= target else "MISSED"
    else:
        verdict = "met" if value >= target else "MISSED"
    return {
        "key": key,
        "bar": label,
        "measured": measured,
        "baseline": baseline,
        "ratio": value,
        "target": f"{relation} {target:g}",
        "verdict": verdict,
        "note": note,
    }


def _ns(stat: Stat) -> str:
    return f"{num(stat.min)} ns"


def _us(ns: float) -> str:
    return f"{num(ns / 1000.0)} us"


def _absent(module: str) -> str | None:
    """None when ``module`` imports, else why not."""
    try:
        __import__(module)
    except Exception as exc:  # noqa: BLE001 - absent or broken: the row says so
        return f"{module} not importable ({type(exc).__name__}); `pip install deltagen[bench]`"
    return None


def measure_floor(arm: Any, n: int, repeats: int) -> tuple[list[dict], dict]:
    """The three Puma-vs-floor rows and the floor's parts."""
    from deltagen.apps.bench.sections import _serial_kernel_callable, sample_serial

    module = floor_module()
    n = min(n, FLOOR_CALL_N)
    loops = max(1, FLOOR_LOOP_POINTS // n)
    data = sample_serial(n, arm, np.random.default_rng(SEED))
    costs = kernel_costs()
    prefix = f"deltagen_{ARM}_"
    kernels = {}
    for key, (name, inputs) in FLOOR_KERNELS.items():
        call = _serial_kernel_callable(arm._core, name, [data[k] for k in inputs])
        if call is not None:
            kernels[key] = cpu_timer(call, (), n, loops)
    q = data["q"]
    trig_timer = cpu_timer(_trig_call(module, q), (), n, loops)
    timers = [trig_timer, _fma_timer(module), *kernels.values()]
    for timer in timers:  # warm-up
        timer()
    trig, fma, *stats = interleaved(timers, repeats)
    rate = 1.0 / fma.min  # operations per ns
    parts = {
        "trig": trig,
        "fma_ns_per_op": fma,
        "ops_per_ns": rate,
        "vector_trig": vector_trig(module),
        "angles": ANGLES,
        "n": n,
    }
    rows = []
    by_key = dict(zip(kernels, stats))
    for key, (name, _) in FLOOR_KERNELS.items():
        ops = costs.get(prefix + name)
        stat = by_key.get(key)
        if stat is None or ops is None:
            rows.append(_row(key, "n/a", "n/a", None, "kernel or its stated cost not found"))
            continue
        floor = trig.min + ops / rate
        parts[f"{name}_ops"] = ops
        rows.append(
            _row(
                key,
                f"C kernel {_ns(stat)}/point",
                f"floor {num(floor)} ns = trig {num(trig.min)} + {ops} ops / {rate:.0f} ops/ns",
                stat.min / floor,
            )
        )
    return rows, parts


def measure_delta(n: int, repeats: int) -> list[dict]:
    """The delta rows: fk against the column-wise numpy fk, fk_vel and fk_acc against fk."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.apps.bench.sections import _kernel_callable, sample_poses

    robot = DeltaRobot.default(backend="compiled", threads=1)
    data = sample_poses(n, [robot._core], np.random.default_rng(SEED))
    q, qd, qdd = data["q"], data["qd"], data["qdd"]
    settle_allocator()
    kernels = {
        name: _kernel_callable(robot._core, name, inputs)
        for name, inputs in (("fk", [q]), ("fk_vel", [q, qd]), ("fk_acc", [q, qd, qdd]))
    }
    p_np = numpy_fk_columns(robot.geometry, q)
    p_dg, _ = robot._core.fk(q)
    agreement = float(np.max(np.abs(p_np - p_dg)))
    names = [k for k, v in kernels.items() if v is not None]
    # in cache, for information: calls of FLOOR_CALL_N rows, looped (module docstring)
    small = min(n, FLOOR_CALL_N)
    loops = max(1, FLOOR_LOOP_POINTS // small)
    inputs = {"fk": ("q",), "fk_vel": ("q", "qd"), "fk_acc": ("q", "qd", "qdd")}
    cached = {
        name: _kernel_callable(
            robot._core, name, [np.ascontiguousarray(data[x][:small]) for x in inputs[name]]
        )
        for name in names
    }
    cached_names = [name for name in names if cached[name] is not None]
    # the floor of each kernel on these rows (module docstring): the floor loop's 3 sines
    # and 3 cosines per point, and the kernel's stated operations at the FMA rate
    module = floor_module()
    costs = kernel_costs("delta_kinematics")
    timers = [
        cpu_timer(robot._core.fk, (q,), n),
        cpu_timer(numpy_fk_columns, (robot.geometry, q), n),
        cpu_timer(_trig_call(module, np.ascontiguousarray(q[:, :3])), (), n),
        _fma_timer(module),
    ]
    timers += [cpu_timer(kernels[k], (), n) for k in names]
    timers += [cpu_timer(cached[k], (), small, loops) for k in cached_names]
    core, numpy_fk, trig, fma, *kstats = interleaved(timers, repeats)
    k = dict(zip(names, kstats[: len(names)]))
    in_cache = dict(zip(cached_names, kstats[len(names) :]))
    rate = 1.0 / fma.min  # operations per ns
    floors = {
        name: trig.min + costs[f"deltagen_delta_{name}"] / rate
        for name in ("fk", "fk_vel", "fk_acc")
        if f"deltagen_delta_{name}" in costs
    }
    note = f"max |numpy - deltagen| {agreement:.1e} m"
    if "fk" in floors:
        note += (
            f"; the fk's floor on these rows {num(floors['fk'])} ns/point = trig "
            f"{num(trig.min)} (3 sin + 3 cos) + {costs['deltagen_delta_fk']} ops / {rate:.0f} "
            f"ops/ns: _core.fk is {core.min / floors['fk']:.2f}x it, and a kernel at the floor "
            f"would reach {numpy_fk.min / floors['fk']:.1f}x numpy"
        )
    rows = [
        _row(
            "delta_fk_numpy",
            f"_core.fk {_ns(core)}/point",
            f"numpy columns {_ns(numpy_fk)}/point",
            numpy_fk.min / core.min,
            note,
        )
    ]
    for key, name in (("delta_fk_vel", "fk_vel"), ("delta_fk_acc", "fk_acc")):
        if name in k and "fk" in k:
            note = f"{n:,} rows a call"
            if name in floors and "fk" in floors:
                note += (
                    f"; the floors' ratio (trig + stated ops) {num(floors[name])} / "
                    f"{num(floors['fk'])} ns: {floors[name] / floors['fk']:.2f}x"
                )
            if name in in_cache and "fk" in in_cache:
                note += (
                    f"; for information, not the bar: in cache ({small:,} rows a call, "
                    f"looped) {name} {_ns(in_cache[name])}/point, fk "
                    f"{_ns(in_cache['fk'])}/point: "
                    f"{in_cache[name].min / in_cache['fk'].min:.2f}x"
                )
            rows.append(
                _row(
                    key,
                    f"{name} kernel {_ns(k[name])}/point",
                    f"fk kernel {_ns(k['fk'])}/point",
                    k[name].min / k["fk"].min,
                    note,
                )
            )
        else:
            rows.append(_row(key, "n/a", "n/a", None, "C kernel not callable (not the cffi core)"))
    return rows


def measure_ik_all(arm: Any, repeats: int) -> dict:
    """ik_all of one pose beside pinocchio's computeFrameJacobian on the same arm."""
    why = _absent("pinocchio")
    if why is not None:
        return _row("ik_all_pinocchio", "n/a", "n/a", None, why)
    import pinocchio as pin

    from deltagen.apps.bench.peers import pinocchio_model

    model, fid = pinocchio_model(arm.description)
    data = model.createData()
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    rng = np.random.default_rng(SEED)
    lim = arm.qlim
    q1 = np.ascontiguousarray(rng.uniform(lim[:, 0], lim[:, 1]))
    T1 = np.ascontiguousarray(arm.fk(q1))
    ours, theirs = interleaved(
        [
            cpu_loop_timer(lambda: arm.ik_all(T1)),
            cpu_loop_timer(lambda: pin.computeFrameJacobian(model, data, q1, fid, world)),
        ],
        repeats,
    )
    return _row(
        "ik_all_pinocchio",
        f"arm.ik_all(T) {_us(ours.min)}",
        f"pinocchio {pin.__version__} computeFrameJacobian {_us(theirs.min)}",
        ours.min / theirs.min,
    )


def measure_numeric_ik(arm: Any, targets: int, passes: int) -> tuple[list[dict], dict]:
    """Numeric IK against rtb's ik_LM on the same targets (module docstring)."""
    from deltagen.apps.bench import ik
    from deltagen.apps.bench.peers import rtb_model
    from deltagen.errors import DeltagenError

    T, _ = ik.numeric_targets(arm, targets)
    why = _absent("roboticstoolbox")
    robot = rtb_model(arm) if why is None else None
    if robot is None:
        why = why or f"rtb has no model of {arm.name}"
        return [
            _row("numeric_ik_median", "n/a", "n/a", None, why),
            _row("numeric_ik_p95", "n/a", "n/a", None, why),
        ], {}
    ets = robot.ets()
    kw = dict(tol=5e-21, joint_limits=True)  # |e| <= 1e-10, as the IK section

    nan_q = np.full(arm.n, np.nan)

    def ours(Ti):  # the default options (errors="raise": a failure raises)
        try:
            return arm.ik(Ti, method="numeric"), True
        except DeltagenError:
            return nan_q, False

    def theirs(Ti):
        return ets.ik_LM(Ti, **kw)

    ours(T[0]), theirs(T[0])  # warm-up (builds the fast path)
    clock = CLOCK
    times = np.full((2, targets), np.inf)
    results: list[list[Any]] = [[None] * targets, [None] * targets]
    import gc

    gc_was = gc.isenabled()
    gc.disable()
    try:
        for p in range(passes):
            for i in range(targets):
                order = (0, 1) if (i + p) % 2 == 0 else (1, 0)
                for side in order:
                    fn = ours if side == 0 else theirs
                    t0 = clock()
                    r = fn(T[i])
                    times[side, i] = min(times[side, i], clock() - t0)
                    results[side][i] = r
    finally:
        if gc_was:
            gc.enable()
    q_dg = np.array([r[0] for r in results[0]])
    ok_dg = np.array([bool(r[1]) for r in results[0]])
    q_rtb = np.array([r.q for r in results[1]])
    ok_rtb = np.array([bool(r.success) for r in results[1]])
    solved = (
        float(np.mean(ik._solved(arm, T, q_dg, ok_dg))),
        float(np.mean(ik._solved(arm, T, q_rtb, ok_rtb))),
    )
    med = np.median(times, axis=1)
    p95 = np.percentile(times, 95, axis=1)
    import roboticstoolbox as rtb

    note = f"solved: deltagen {100 * solved[0]:.1f} %, rtb {100 * solved[1]:.1f} %"
    lib = f"rtb {rtb.__version__} ik_LM"
    rows = [
        _row(
            "numeric_ik_median",
            f"arm.ik numeric {_us(med[0])}",
            f"{lib} {_us(med[1])}",
            med[0] / med[1],
            note,
        ),
        _row(
            "numeric_ik_p95",
            f"arm.ik numeric {_us(p95[0])}",
            f"{lib} {_us(p95[1])}",
            p95[0] / p95[1],
            note,
        ),
    ]
    return rows, {"targets": targets, "passes": passes, "solved": solved}


def _wall_and_cpu_timer(fn: Callable, args: tuple, points: int, cpu: list) -> Callable[[], float]:
    """A timer: one call of ``fn(*args)`` -> wall ns per point; the process CPU time of the
    call (every thread's) is appended to ``cpu``, in ns per point."""

    def timer() -> float:
        c0, t0 = time.process_time_ns(), time.perf_counter_ns()
        fn(*args)
        t1, c1 = time.perf_counter_ns(), time.process_time_ns()
        cpu.append((c1 - c0) / points)
        return (t1 - t0) / points

    return timer


class _Pair:
    """A plain second thread (no pool, no pieces, no numpy): :meth:`run` calls ``theirs`` in
    it while this thread calls ``mine``, and returns when both are done -- the machine's own
    two-thread speed, the baseline of the threads bar's ceiling. An exception of
    ``theirs`` is raised by :meth:`run` (the thread lives on, so no later call waits for
    it forever)."""

    def __init__(self) -> None:
        self._start = threading.Barrier(2)
        self._done = threading.Barrier(2)
        self._job: Callable[[], Any] | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._loop, name="deltagen-bench-pair", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while True:
            self._start.wait()
            job = self._job
            if job is None:
                return
            try:
                job()
            except BaseException as exc:  # noqa: BLE001 - handed to run()'s caller
                self._error = exc
            finally:
                self._done.wait()

    def run(self, mine: Callable[[], Any], theirs: Callable[[], Any]) -> None:
        self._job = theirs
        self._error = None
        self._start.wait()
        try:
            mine()
        finally:
            self._done.wait()
        if self._error is not None:
            raise self._error

    def close(self) -> None:
        self._job = None
        self._start.wait()
        self._thread.join()


def _in_turn(first: Callable[[], Any], second: Callable[[], Any]) -> None:
    """The two halves one after the other in this thread (the ceiling's one-thread side)."""
    first()
    second()


def _busy_seconds() -> float | None:
    """The machine's busy CPU time so far (/proc/stat: user, nice, system, irq, softirq of
    every core), in s; None where /proc/stat cannot be read (not Linux)."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:8]]
        return (sum(fields[:3]) + fields[5] + fields[6]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return None


class OtherCores:
    """A meter of the CPU other processes use while this process's two-thread calls run:
    wrap a timer (``meter(timer)``) and every call of it adds the machine's busy time
    (:func:`_busy_seconds`) less this process's CPU time, over the call's wall time;
    :meth:`cores` is then the cores other processes kept busy during those calls (0 to
    the core count), None where /proc/stat cannot be read. A direct measure of whether the
    second core was free when two threads needed it, where the load average is a
    1-minute mean over everything (/proc/stat counts in clock ticks: summed over the
    repeats, the error averages out)."""

    def __init__(self) -> None:
        self.busy = 0.0
        self.wall = 0.0
        self.readable = True

    def __call__(self, timer: Callable[[], float]) -> Callable[[], float]:
        def metered() -> float:
            b0, c0, w0 = _busy_seconds(), time.process_time(), time.perf_counter()
            value = timer()
            b1, c1, w1 = _busy_seconds(), time.process_time(), time.perf_counter()
            if b0 is None or b1 is None:
                self.readable = False
            else:
                self.busy += b1 - b0 - (c1 - c0)
                self.wall += w1 - w0
            return value

        return metered

    def cores(self) -> float | None:
        if not self.readable or self.wall <= 0.0:
            return None
        # /proc/stat counts whole clock ticks (10 ms) per core: over short calls the busy
        # time is off by up to a tick per core and the quotient can leave 0 .. cores,
        # which no machine can use (a test's 3 short calls read 2.58 of 2 cores)
        return min(float(os.cpu_count() or 1), max(0.0, self.busy / self.wall))


def other_cores() -> OtherCores:
    """A new :class:`OtherCores` meter (the tests replace this factory)."""
    return OtherCores()


def _kernel_halves(robot: Any, kernel: str, q: np.ndarray) -> dict[str, tuple[Callable, Callable]]:
    """The machine's baselines of the threads bar: for each way of giving a kernel its
    outputs, (one thread, two threads): calls of the generated C function on the two halves
    of q (split on a ROW_ALIGN row, as the threads split a batch), one after the other in
    this thread (``one()``) or at once in this thread and a plain second one (``two(pair)``,
    pair a :class:`_Pair`). "preallocated":
    outputs allocated and touched once (no allocation, no page faults in the calls);
    "fresh": the outputs allocated anew in this thread before each call, untouched, as the
    API allocates them (np.empty of the whole batch, then the kernel's writes fault the
    pages in, in whichever thread computes the rows) -- but one C call per half: no
    pieces, no pool, no Python around the kernel. Empty for a core that is not the cffi
    one."""
    from deltagen.native.manifest import output_widths
    from deltagen.native.parallel import ROW_ALIGN

    core = robot._core
    n, axes = q.shape
    half = n // 2 // ROW_ALIGN * ROW_ALIGN
    if half == 0 or not hasattr(core, "_ffi"):
        return {}
    if hasattr(core, "c_function"):  # a serial arm: fn(rows, *inputs, *outputs, status)
        ffi, fn = core.c_function(kernel)
        entry, lead, middle = core.kernel(kernel), (), ()
    else:  # a parallel robot: fn(geometry, rows, axes, *inputs, *outputs, status)
        entry = core._kernels[kernel]
        ffi, fn = core._ffi, getattr(core._lib, entry["function"])
        lead, middle = (core._geometry,), (axes,)
    kinds = [w if isinstance(w, tuple) else (w, "double") for w in output_widths(entry, axes)]
    dtypes = {"double": np.float64, "uint8_t": np.uint8}
    fb = ffi.from_buffer

    def alloc() -> list[np.ndarray]:
        outs = [np.empty((n, w), dtype=dtypes[c]) for w, c in kinds]
        return [*outs, np.empty(n, dtype=np.int8)]

    def rows(outs: list[np.ndarray], lo: int, hi: int) -> int:
        *values, status = outs
        return fn(
            *lead,
            hi - lo,
            *middle,
            fb("double[]", q[lo:hi]),
            *(fb(f"{c}[]", o[lo:hi], require_writable=True) for o, (_, c) in zip(values, kinds)),
            fb("int8_t[]", status[lo:hi], require_writable=True),
        )

    kept = alloc()
    if rows(kept, 0, n) != 0:  # touches the preallocated outputs once
        return {}

    def halves(outs: list[np.ndarray]) -> tuple[Callable, Callable]:
        return (lambda: rows(outs, 0, half), lambda: rows(outs, half, n))

    def fresh_one() -> None:
        _in_turn(*halves(alloc()))

    def fresh_two(pair: _Pair) -> None:
        pair.run(*halves(alloc()))

    first, second = halves(kept)
    return {
        "preallocated": (lambda: _in_turn(first, second), lambda pair: pair.run(first, second)),
        "fresh": (fresh_one, fresh_two),
    }


#: the machine's baselines of the threads bar, in the order they are reported
CEILINGS = ("preallocated", "fresh")


def measure_threads(n: int, repeats: int) -> tuple[list[dict], list]:
    """threads=1 vs threads=2 through the API on n rows: the two bar rows and, for each
    case, a dict of Stats: "one", "two" (API wall ns per row), for each of :data:`CEILINGS`
    "<name>_one", "<name>_two" (the machine's wall ns per row), the process CPU ns per row
    of each of those as "cpu_<key>", and "others" (other processes' cores, or None).

    Wall time is what the bar is about, and it needs the second core free. Beside the API,
    in the same round-robin, the machine's ceilings: the same C kernel run on the two
    halves of the rows, one after the other in one thread and at once in two plain threads
    (:class:`_Pair`), on preallocated outputs (what the host gives: cores, memory
    bandwidth) and on fresh ones (plus the first touch of new pages, which the kernel's
    writes fault in and the OS zeroes: what returning new arrays costs on this host;
    :func:`_kernel_halves`). The API's ratio over the fresh ceiling is what the API's own
    work loses (the pieces, the pool hand-off, the Python before and after the kernel).
    A ratio below the target is "unsettled", not MISSED, when the second core was not free
    -- other processes used at least half a core during the two-thread calls
    (:class:`OtherCores`), or without that measure, the load average (1 min, taken
    before) was at least the usable cores less one half -- or when the fresh ceiling
    itself is below the target (the host, not the API); the note says which. MISSED when
    the host gave the target and the API did not. The API's
    process CPU time (all threads) is recorded too: CPU(threads=1) / (CPU(threads=2) / 2)
    is the speedup two free cores would give at most."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.serial import SerialRobot
    from deltagen.native.parallel import available_cores

    cores = available_cores()
    if cores < 2:
        why = f"this process may use {cores} core: two threads cannot be measured"
        return [
            _row("threads_delta_fk", "n/a", "n/a", None, why),
            _row("threads_puma_fk", "n/a", "n/a", None, why),
        ], []
    rng = np.random.default_rng(SEED)
    delta = {t: DeltaRobot.default(threads=t) for t in (1, 2)}
    arm = {t: SerialRobot.load(ARM, threads=t) for t in (1, 2)}
    q_delta = np.ascontiguousarray(rng.uniform(-0.3, 0.9, (n, 3)))
    lim = arm[1].qlim
    q_arm = np.ascontiguousarray(rng.uniform(lim[:, 0], lim[:, 1], (n, arm[1].n)))
    cases = (
        ("threads_delta_fk", "delta fk", lambda t: delta[t].fk(q_delta), (delta[1], "fk", q_delta)),
        ("threads_puma_fk", f"{ARM} fk", lambda t: arm[t].fk(q_arm), (arm[1], "fk", q_arm)),
        (None, f"{ARM} jacobian", lambda t: arm[t].jacobian(q_arm), (arm[1], "jacobian", q_arm)),
    )
    target = TARGETS["threads_delta_fk"][2]
    rows, raw = [], []
    pair = _Pair()
    try:
        for key, label, call, kernel in cases:
            for t in (1, 2):
                call(t)  # warm-up (starts the pool's thread)
            halves = _kernel_halves(*kernel)
            load = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
            names = ["one", "two"]
            cpu: dict[str, list[float]] = {name: [] for name in names}
            others = other_cores()  # metered over the two-thread calls only
            timers = [
                _wall_and_cpu_timer(call, (1,), n, cpu["one"]),
                others(_wall_and_cpu_timer(call, (2,), n, cpu["two"])),
            ]
            for ceiling_name in CEILINGS:
                if ceiling_name in halves:
                    alone, together = halves[ceiling_name]
                    for side, fn, args in (("one", alone, ()), ("two", together, (pair,))):
                        key_name = f"{ceiling_name}_{side}"
                        names.append(key_name)
                        cpu[key_name] = []
                        timer = _wall_and_cpu_timer(fn, args, n, cpu[key_name])
                        timers.append(others(timer) if side == "two" else timer)
            stats = dict(zip(names, interleaved(timers, repeats)))
            busy = others.cores()
            entry: dict[str, Any] = {"label": label, **stats, "others": busy}
            entry.update({f"cpu_{name}": Stat(values) for name, values in cpu.items()})
            raw.append(entry)
            if key is None:
                continue
            one, two, cpu_one, cpu_two = (
                stats["one"],
                stats["two"],
                entry["cpu_one"],
                entry["cpu_two"],
            )
            ratio = one.min / two.min
            bound = cpu_one.min / (cpu_two.min / 2)
            used = "not measured" if busy is None else f"{busy:.2f} cores"
            note = (
                f"{n:,} rows; load average {load:.2f} on {cores} cores, other processes used "
                f"{used} during the two-thread calls; "
            )
            ceilings = _ceilings(entry)
            for ceiling_name, value in ceilings.items():
                note += f"machine ceiling on {ceiling_name} outputs {value:.2f}x; "
            fresh = ceilings.get("fresh")
            if fresh is not None:
                extra = cpu_two.min / entry["cpu_fresh_two"].min
                note += (
                    f"the API reaches {ratio / fresh:.0%} of the fresh-output ceiling, with "
                    f"{extra:.2f}x its process CPU time on two threads; "
                )
            note += (
                f"CPU time threads=2 / threads=1 {cpu_two.min / cpu_one.min:.2f}: two free cores "
                f"would give about {bound:.2f}x at most (CPU time too is noisy on a loaded "
                "machine)"
            )
            row = _row(key, f"threads=2 {_ns(two)}/row", f"threads=1 {_ns(one)}/row", ratio, note)
            if row["verdict"] == "MISSED":
                reasons = []
                taken = busy >= 0.5 if busy is not None else load >= cores - 0.5
                if taken:
                    reasons.append(
                        "the second core was not free, this wall-time ratio settles nothing"
                    )
                if fresh is not None and fresh < target:
                    reasons.append(
                        f"this host's own two-thread ceiling on fresh outputs ({fresh:.2f}x, "
                        "the C kernel in two plain threads) is below the target: the host, "
                        "not the API, misses it now"
                    )
                if reasons:
                    row["verdict"] = "unsettled"
                    row["note"] += ": " + "; ".join(reasons)
            rows.append(row)
    finally:
        pair.close()
    return rows, raw


def _ceilings(entry: dict) -> dict[str, float]:
    """{ceiling name: one thread / two threads (wall, min)} of a measure_threads entry."""
    return {
        name: entry[f"{name}_one"].min / entry[f"{name}_two"].min
        for name in CEILINGS
        if f"{name}_one" in entry
    }


# ------------------------------------------------------------------------- entry points


def measure(n: int = THREADS_N, repeats: int = 7, oracles: bool = True) -> dict:
    """Every bar (module docstring); ``n`` caps each workload (THREADS_N rows for the
    threads bar, FLOOR_N for the others; IK_TARGETS numeric targets from n >= FLOOR_N on,
    else 20), ``oracles`` False leaves the peers out (their rows say so)."""
    from deltagen.api.serial import SerialRobot

    if n < 1:
        raise ValueError(f"--n must be at least 1, got {n}")
    if repeats < 1:
        raise ValueError(f"--repeats must be at least 1, got {repeats}")
    t_start = time.perf_counter()
    load_before = _load()
    arm = SerialRobot.load(ARM, backend="compiled", threads=1)
    small = min(n, FLOOR_N)
    rows, floor = measure_floor(arm, small, repeats)
    rows += measure_delta(small, repeats)
    skipped = "skipped (DELTAGEN_BENCH_ORACLES=0)"
    if oracles:
        rows.append(measure_ik_all(arm, repeats))
        ik_rows, ik_info = measure_numeric_ik(arm, IK_TARGETS if n >= FLOOR_N else 20, IK_PASSES)
        rows += ik_rows
    else:
        ik_info = {}
        rows += [_row(k, "n/a", "n/a", None, skipped) for k in TARGETS if "ik" in k]
    thread_rows, threads = measure_threads(min(n, THREADS_N), repeats)
    rows += thread_rows
    return {
        "rows": rows,
        "floor": floor,
        "ik": ik_info,
        "threads": threads,
        "threads_n": min(n, THREADS_N),
        "repeats": repeats,
        "load_before": load_before,
        "load_after": _load(),
        "elapsed_s": time.perf_counter() - t_start,
    }


def render(result: dict, markdown: bool) -> list[str]:
    """The bars table and how each ratio was measured."""
    style = Style(markdown)
    bullet = style.bullet
    out = [style.h("Bars: every target as a same-run ratio"), ""]
    header = ["bar", "measured", "same-run baseline", "ratio", "target", "verdict"]
    rows = []
    for r in result["rows"]:
        ratio = "n/a" if r["ratio"] is None else f"{r['ratio']:.2f}x"
        rows.append([r["bar"], r["measured"], r["baseline"], ratio, r["target"], r["verdict"]])
    out += style.table(header, rows)
    out.append("")
    for r in result["rows"]:
        if r["note"]:
            out.append(f"{bullet}{r['bar']}: {r['note']}")
    f = result["floor"]
    if f:
        out.append(
            f"{bullet}floor (trig_floor.c, calls of {f['n']:,} points, as the Puma kernels): per point {f['angles']} sin + "
            f"{f['angles']} cos through {f['vector_trig']}: {num(f['trig'].min)} ns; "
            f"arithmetic = the header's stated operations per point / the measured vector FMA "
            f"rate {f['ops_per_ns']:.0f} ops/ns (2 per FMA; the kernels, built -std=c99, do not "
            "contract to FMA, so the floor is a lower bound)"
        )
    for entry in result["threads"]:
        one, two = entry["one"], entry["two"]
        machine = "".join(
            f"; machine ceiling on {name} outputs (the C kernel in plain threads on halves) "
            f"one thread {_ns(entry[f'{name}_one'])}/row, two {_ns(entry[f'{name}_two'])}/row: "
            f"{value:.2f}x"
            for name, value in _ceilings(entry).items()
        )
        busy = entry["others"]
        used = "" if busy is None else f"; other processes used {busy:.2f} cores meanwhile"
        out.append(
            f"{bullet}threads, {entry['label']} through the API, {result['threads_n']:,} rows: "
            f"wall threads=1 {_ns(one)}/row, threads=2 {_ns(two)}/row (min; medians "
            f"{num(one.median)} / {num(two.median)}): {one.min / two.min:.2f}x{machine}; "
            f"process CPU {_ns(entry['cpu_one'])} / {_ns(entry['cpu_two'])} per row{used}"
        )
    out.append(
        f"{bullet}every ratio from the minimum of {result['repeats']} round-robin repeats "
        "per side, single-threaded measures in thread CPU time (the threads bar in wall "
        f"time) (numeric IK: per target the minimum of {IK_PASSES} alternating passes, "
        f"then median / p95); load average (1, 5, 15 min) {result['load_before']} before, "
        f"{result['load_after']} after; {result['elapsed_s']:.1f} s"
    )
    return out
