"""`deltagen bench`: throughput (ns per point) and single-pose latency of the delta
kinematics, compiled C core vs the numpy reference, measured in one run.

Throughput. N random reachable poses of ``DeltaRobot.default()`` (crank angles uniform in
[-0.3, 0.9] rad, velocities and accelerations uniform, platform positions from fk for ik;
every row checked OK so no call raises). Each quantity is timed at three levels:

* ``C kernel``: the generated C function called directly with preallocated outputs
  (the core's own loop, no numpy allocation); a diagnostic column.
* ``_core``: the raw batched backend ``robot._core.<fn>`` ((N, 3) float64 C-contiguous in,
  fresh output arrays out); the throughput targets are checked against this column.
* ``API``: the public method ``robot.<fn>`` with argument validation and status checks.

The reference runs on the first ``min(N, 200 000)`` of the same poses (it is tens of times slower)
and is reported per point as well. Every cell is the median over ``--repeats`` timed calls
after one warm-up call, with [min, max] of those repeats; time.perf_counter_ns, garbage
collector off while timing, and the columns of a row timed round-robin (repeat 1 of every
column, then repeat 2, ...) so that load from other processes on a shared machine hits
them alike. Speedups are ratios of medians measured in this run.

Latency. One single-pose call from Python (``robot.fk(q)`` with a (3,) ndarray and with a
list, ``robot.ik(p)`` likewise, and the raw ``robot._core`` call on a (1, 3) array), looped
so that one repeat lasts ~25 ms; median of the repeats in microseconds per call.

Serial arm. The same measurements for the Puma560 (``SerialRobot.load("puma560")``, six
revolute joints, q uniform within its joint limits, qd uniform): fk, frames, jacobian and
jacobian_dot per configuration (frames and jacobian_dot on the first ``min(N, 250 000)``
configurations: frames writes 1 KiB per configuration), the numpy reference on the first
``min(N, 100 000)``, and single-pose latency. When importable, the same run then times
roboticstoolbox-python's Puma560 (``rtb.models.DH.Puma560()``: the Python ``DHRobot`` calls and
the C++ ``ETS`` fast path) and pinocchio (a model built here from the Puma560's DH table),
each library call interleaved with the matching deltagen call, and prints the ratio
library / deltagen and their agreement. ``pip install deltagen[bench]`` brings both; they are
skipped (and named as absent) otherwise, or on request (``DELTAGEN_BENCH_ORACLES=0``).

The tables above are single-threaded: the robots are made with ``threads=1`` (the C core is
a plain loop; ``-fopenmp-simd`` only vectorises, it starts no threads) and the reference
uses numpy ufuncs and batched 3x3 solves, so OPENBLAS_NUM_THREADS / OMP_NUM_THREADS make no
difference.

All cores. A last section times delta fk, Puma560 fk and Puma560 jacobian through
``robot._core`` with ``threads=1`` and with the default thread count (DELTAGEN_THREADS, else
the available cores; native.parallel splits batches of at least 2 x MIN_ROWS_PER_THREAD
rows into row chunks on a thread pool), round-robin, and prints the speedup.

Other machine families. The linear delta's, the tripod's, the hexapod's and a 5-axis
machine's cores beside the rotary delta's fk and ik (``families``), ns per point
through ``_core``, threads=1.

Bars. Last, every speed target of the batched kernels as a same-run ratio with met /
MISSED (``bars``; ``deltagen bench --bars`` runs it alone).

Each table is declared here (``DELTA`` and ``SERIAL``: quantities, inputs, units, targets,
rows, the C-kernel call and the reference baseline; the latency calls) and timed and
rendered by ``engine``; the peer libraries are ``peers``, inverse kinematics ``ik``.
"""

from __future__ import annotations

import os
import platform
import subprocess
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from deltagen import status as st
from deltagen.apps.bench import bars, engine, families, ik, peers
from deltagen.apps.bench.engine import Throughput
from deltagen.apps.bench.timing import Style, cell, ratio
from deltagen.inputs import check_memory
from deltagen.native.manifest import kernels, output_widths
from deltagen.native.toolchain import host_compiler

QUANTITIES = ("fk", "fk_vel", "fk_acc", "jacobian", "ik", "inverse_dynamics")
#: The throughput targets for the compiled core [ns per point].
TARGETS_NS = {"fk": 12.0, "fk_vel": 12.0, "fk_acc": 16.0, "ik": 20.0, "inverse_dynamics": 30.0}
#: The targets for one single-pose call from Python [ns]: fk and ik.
SINGLE_TARGET_NS = {"fk": 600.0, "ik": 1500.0}
REFERENCE_N = 200_000
Q_RANGE = (-0.3, 0.9)  # rad; well inside the default robot's workspace
QD_RANGE = (-2.0, 2.0)  # rad/s
QDD_RANGE = (-20.0, 20.0)  # rad/s^2
SEED = 2008

#: the rotary delta's batched C kernels as generated/delta_kinematics.kernels.json declares
#: them (C function, input ports, output widths and units)
_DELTA_KERNELS = kernels("delta_kinematics")
# the unit of each quantity's first output, the one the agreement line compares (fk_vel's
# and fk_acc's is the position p, m)
_UNITS = {name: _DELTA_KERNELS[name]["outputs"][0]["unit"] for name in QUANTITIES}
PAYLOAD_RANGE = (0.0, 2.0)  # kg


# ------------------------------------------------------------------------- inputs


def _valid_rows(core, q, qd, qdd):
    """Rows that are OK for every quantity (fk_acc covers fk, fk_vel and jacobian) and
    whose fk position gives an OK ik; also returns that position."""
    _, _, _, s_acc = core.fk_acc(q, qd, qdd)
    p, s_fk = core.fk(q)
    _, s_jac = core.jacobian(q)
    p_safe = np.ascontiguousarray(np.where(np.isfinite(p), p, 0.0))
    _, s_ik = core.ik(p_safe)
    ok = (s_acc == st.OK) & (s_fk == st.OK) & (s_jac == st.OK) & (s_ik == st.OK)
    return ok, p


def sample_poses(n: int, cores: Sequence, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """n rows of q, qd, qdd and p = fk(q), all OK for every core in ``cores``."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("q", "qd", "qdd", "p", "payload")}
    have, tries = 0, 0
    while have < n:
        tries += 1
        if tries > 50:
            raise RuntimeError("could not sample valid poses (is the C core broken?)")
        m = int((n - have) * 1.05) + 64
        q = rng.uniform(*Q_RANGE, (m, 3))
        qd = rng.uniform(*QD_RANGE, (m, 3))
        qdd = rng.uniform(*QDD_RANGE, (m, 3))
        ok = np.ones(m, dtype=bool)
        p = None
        for core in cores:
            ok_c, p_c = _valid_rows(core, q, qd, qdd)
            ok &= ok_c
            p = p_c if p is None else p  # positions from the first core (compiled)
        assert p is not None, "sample_poses needs at least one core"
        take = np.flatnonzero(ok)[: n - have]
        payload = rng.uniform(*PAYLOAD_RANGE, m)
        for key, arr in (("q", q), ("qd", qd), ("qdd", qdd), ("p", p), ("payload", payload)):
            parts[key].append(arr[take])
        have += take.size
    return {k: np.ascontiguousarray(np.concatenate(v)) for k, v in parts.items()}


# ------------------------------------------------------------------------- measurements


def _c_call(
    ffi, fn, lead: tuple, inputs: list[np.ndarray], widths, all_ok: bool
) -> Callable | None:
    """A no-argument call of the generated C function ``fn(*lead, inputs..., outputs...,
    status)`` with preallocated outputs (``widths`` per point), or None where a first call
    returns non-zero (or, with ``all_ok``, leaves a point not OK)."""
    points = inputs[0].shape[0]
    outs = [np.empty((points, width)) for width in widths]
    status = np.empty(points, dtype=np.int8)
    fb = ffi.from_buffer
    cargs = (
        *lead,
        *(fb("double[]", a) for a in inputs),
        *(fb("double[]", o, require_writable=True) for o in outs),
        fb("int8_t[]", status, require_writable=True),
    )
    if fn(*cargs) != 0 or (all_ok and not (status == st.OK).all()):
        return None
    keep = (inputs, outs, status)  # the buffers must outlive the call object
    return lambda: (fn(*cargs), keep)[0]


def _kernel_callable(core: Any, name: str, inputs: list[np.ndarray]) -> Callable | None:
    """_c_call of the delta's generated C function, or None if the core is not the cffi one
    or its ABI is not the expected one."""
    try:
        entry = _DELTA_KERNELS[name]
        n, axes = inputs[0].shape
        fn = getattr(core._lib, entry["function"])
        lead = (core._geometry, n, axes)
        return _c_call(core._ffi, fn, lead, inputs, output_widths(entry, axes), False)
    except Exception:  # noqa: BLE001 - a diagnostic column; the others still run
        return None


#: the rotary delta's throughput table: every quantity on all N points, the reference (core
#: and API) on the first REFERENCE_N
DELTA = Throughput(
    quantities=QUANTITIES,
    inputs={name: tuple(p["name"] for p in _DELTA_KERNELS[name]["inputs"]) for name in QUANTITIES},
    units=_UNITS,
    targets=TARGETS_NS,
    kernel=_kernel_callable,
    reference_n=REFERENCE_N,
)


def _latency_calls(robot, q1, p1):
    ql, pl = [float(v) for v in q1], [float(v) for v in p1]
    q2, p2 = np.ascontiguousarray(q1[None, :]), np.ascontiguousarray(p1[None, :])
    fk, ik = SINGLE_TARGET_NS["fk"], SINGLE_TARGET_NS["ik"]
    return [
        ("robot.fk(q), q ndarray (3,)", lambda: robot.fk(q1), fk),
        ("robot.fk(q), q list of 3 floats", lambda: robot.fk(ql), fk),
        ("robot.ik(p), p ndarray (3,)", lambda: robot.ik(p1), ik),
        ("robot.ik(p), p list of 3 floats", lambda: robot.ik(pl), ik),
        ("robot.fk_vel(q, qd), ndarrays (3,)", lambda: robot.fk_vel(q1, q1), None),
        ("robot.fk_acc(q, qd, qdd), ndarrays (3,)", lambda: robot.fk_acc(q1, q1, q1), None),
        ("robot.jacobian(q), q ndarray (3,)", lambda: robot.jacobian(q1), None),
        (
            "robot.inverse_dynamics(q, qd, qdd, 0.5), ndarrays (3,)",
            lambda: robot.inverse_dynamics(q1, q1, q1, 0.5),
            None,
        ),
        ("robot._core.fk(q), q (1, 3)", lambda: robot._core.fk(q2), None),
        ("robot._core.ik(p), p (1, 3)", lambda: robot._core.ik(p2), None),
    ]


# ------------------------------------------------------------------------- serial arm

SERIAL_ROBOT = "puma560"
SERIAL_QUANTITIES = (
    "fk",
    "frames",
    "jacobian",
    "jacobian_dot",
    "inverse_dynamics",
    "mass_matrix",
    "forward_dynamics",
)
#: The serial-arm throughput targets for the compiled core [ns per configuration].
SERIAL_TARGETS_NS = {"fk": 30.0, "jacobian": 50.0, "inverse_dynamics": 150.0}
#: The targets for one single-pose serial call from Python [ns].
SERIAL_SINGLE_TARGET_NS = {"fk": 600.0, "jacobian": 500.0}
SERIAL_REFERENCE_N = 100_000
#: frames (n + 2 matrices, 1 KiB per configuration) and jacobian_dot run on fewer points
SERIAL_SMALL_N = 250_000
SERIAL_QD_RANGE = (-2.0, 2.0)  # rad/s
SERIAL_QDD_RANGE = (-5.0, 5.0)  # rad/s^2

_SERIAL_INPUTS = {
    "fk": ("q",),
    "frames": ("q",),
    "jacobian": ("q",),
    "jacobian_dot": ("q", "qd"),
    "inverse_dynamics": ("q", "qd", "qdd"),
    "mass_matrix": ("q",),
    "forward_dynamics": ("q", "qd", "tau"),
}
_SERIAL_UNITS = {
    "fk": "m",
    "frames": "m",
    "jacobian": "m/rad",
    "jacobian_dot": "m/(rad s)",
    "inverse_dynamics": "N m",
    "mass_matrix": "kg m^2",
    "forward_dynamics": "rad/s^2",
}


def _serial_points(name: str, n: int) -> int:
    return n if name in ("fk", "jacobian") else min(n, SERIAL_SMALL_N)


def sample_serial(n: int, robot: Any, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """n configurations q uniform within the arm's joint limits, rates qd and accelerations
    qdd (C-contiguous); for arms with inertial parameters also tau, the numpy reference's
    inverse dynamics of (q, qd, qdd) on the first SERIAL_SMALL_N (forward dynamics input)."""
    lim = robot.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (n, robot.n))
    qd = rng.uniform(*SERIAL_QD_RANGE, (n, robot.n))
    qdd = rng.uniform(*SERIAL_QDD_RANGE, (n, robot.n))
    out = {"q": np.ascontiguousarray(q), "qd": np.ascontiguousarray(qd)}
    out["qdd"] = np.ascontiguousarray(qdd)
    if robot.description.has_inertia:
        from deltagen.reference import serial as reference

        m = min(n, SERIAL_SMALL_N)
        tau, _ = reference.inverse_dynamics(robot.description, q[:m], qd[:m], qdd[:m])
        out["tau"] = np.ascontiguousarray(tau)
    return out


def _serial_kernel_callable(core: Any, name: str, inputs: list[np.ndarray]) -> Callable | None:
    """_c_call of the arm's generated C function ``deltagen_<robot>_<name>`` (every point
    OK), or None if the core is not the cffi one."""
    try:
        ffi, fn = core.c_function(name)
        points, axes = inputs[0].shape
        (width,) = output_widths(core.kernel(name), axes)  # generated/<arm>.kernels.json
        return _c_call(ffi, fn, (points,), inputs, (width,), True)
    except Exception:  # noqa: BLE001 - a diagnostic column; the others still run
        return None


#: the serial arm's throughput table: fk and jacobian on all N configurations, the others
#: on the first SERIAL_SMALL_N, the reference's _core on the first SERIAL_REFERENCE_N
SERIAL = Throughput(
    quantities=SERIAL_QUANTITIES,
    inputs=_SERIAL_INPUTS,
    units=_SERIAL_UNITS,
    targets=SERIAL_TARGETS_NS,
    kernel=_serial_kernel_callable,
    reference_n=SERIAL_REFERENCE_N,
    reference_api=False,
    rows=_serial_points,
    show_rows=True,
)


def _serial_latency_calls(robot, q1):
    n = q1.shape[0]
    ql = [float(v) for v in q1]
    q2 = np.ascontiguousarray(q1[None, :])
    fk, jac = SERIAL_SINGLE_TARGET_NS["fk"], SERIAL_SINGLE_TARGET_NS["jacobian"]
    return [
        (f"robot.fk(q), q ndarray ({n},)", lambda: robot.fk(q1), fk),
        (f"robot.fk(q), q list of {n} floats", lambda: robot.fk(ql), fk),
        (f"robot.jacobian(q), q ndarray ({n},)", lambda: robot.jacobian(q1), jac),
        (f"robot._core.fk(q), q (1, {n})", lambda: robot._core.fk(q2), None),
        (f"robot._core.jacobian(q), q (1, {n})", lambda: robot._core.jacobian(q2), None),
        (
            f"robot.inverse_dynamics(q, qd, qdd), ndarrays ({n},)",
            lambda: robot.inverse_dynamics(q1, q1, q1),
            None,
        ),
    ]


def run_serial(n: int, repeats: int, oracles: bool = True) -> dict:
    """The serial-arm section (see the module docstring)."""
    from deltagen.api.serial import SerialRobot

    compiled = SerialRobot.load(SERIAL_ROBOT, backend="compiled", threads=1)
    reference = compiled.with_backend("reference")
    data = sample_serial(n, compiled, np.random.default_rng(SEED))
    throughput, sizes, agreement = engine.measure_throughput(
        SERIAL, compiled, reference, data, repeats
    )
    q1 = data["q"][0].copy()
    latency = engine.measure_latency(
        lambda robot: _serial_latency_calls(robot, q1), compiled, reference, repeats
    )
    rates = (SERIAL_QD_RANGE, SERIAL_QDD_RANGE, SEED + 1)
    others = peers.measure(compiled, data["q"], repeats, rates, enabled=oracles)
    # the full IK workload for real runs; a small one for quick (test) runs
    ik_result = ik.run(
        compiled,
        reference,
        repeats,
        analytic_n=min(n, ik.IK_ANALYTIC_N),
        numeric_n=ik.IK_NUMERIC_N if n >= 100_000 else 20,
        peers=oracles,
    )
    return {
        "robot": compiled,
        "n": n,
        "sizes": sizes,
        "throughput": throughput,
        "agreement": agreement,
        "latency": latency,
        "oracles": others,
        "ik": ik_result,
    }


# ------------------------------------------------------------------------- machine


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _compiler() -> str:
    """The host compiler the cores are built with (native.toolchain) and its version line."""
    cc = host_compiler()
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=10)
        first = out.stdout.splitlines()[0].strip() if out.stdout else ""
        return f"{cc}: {first}" if first else cc
    except (OSError, subprocess.SubprocessError, IndexError):
        return cc


def _build_name(robot: Any) -> str:
    lib = getattr(robot._core, "_lib", None)
    name = getattr(lib, "__name__", "") or ""
    return name.removesuffix(".lib") or "?"


def _load() -> str:
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except (OSError, AttributeError):
        return "?"


def machine_info(compiled_robot: Any) -> list[tuple[str, str]]:
    from deltagen.native.build import compile_flags

    args, libraries = compile_flags("delta")
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 1
    import cffi

    return [
        ("CPU", _cpu_model()),
        (
            "cores",
            f"{os.cpu_count()} logical ({usable} usable by this process); "
            "all measurements single-threaded",
        ),
        ("OS", f"{platform.system()} {platform.release()} {platform.machine()}"),
        ("Python", f"{platform.python_implementation()} {platform.python_version()}"),
        ("numpy / cffi", f"{np.__version__} / {cffi.__version__}"),
        ("compiler", _compiler()),
        (
            "C flags",
            " ".join(args) + "  (libraries: " + " ".join(f"-l{x}" for x in libraries) + ")",
        ),
        ("C build", _build_name(compiled_robot)),
    ]


def render(result: dict, markdown: bool) -> str:
    """The text (or Markdown) of a :func:`measure` result: every section's tables."""
    n, ref_n, repeats = result["n"], result["ref_n"], result["repeats"]
    style = Style(markdown)
    h, bullet = style.h, style.bullet
    out: list[str] = [h("deltagen bench"), ""]
    for key, value in result["machine"]:
        v = f"`{value}`" if markdown and key.startswith("C ") else value
        out.append(f"{bullet}{key}: {v}")
    out.append(
        f"{bullet}load average (1 min): {result['load_before']} before, "
        f"{result['load_after']} after"
    )
    out.append(
        f"{bullet}workload: DeltaRobot.default(), q uniform in [{Q_RANGE[0]}, {Q_RANGE[1]}]"
        f" rad, qd in [{QD_RANGE[0]}, {QD_RANGE[1]}] rad/s, qdd in "
        f"[{QDD_RANGE[0]}, {QDD_RANGE[1]}] rad/s^2, payload in [{PAYLOAD_RANGE[0]}, "
        f"{PAYLOAD_RANGE[1]}] kg, p = fk(q); every row OK; seed {SEED}"
    )
    out.append(
        f"{bullet}N = {n:,} points (compiled), {ref_n:,} points (reference, scaled per "
        f"point); median [min, max] of {repeats} repeats after a warm-up call, the columns "
        "of a row timed round-robin"
    )
    out += ["", h("Throughput, ns per point"), ""]
    out += engine.render_throughput(DELTA, result, style)
    out += ["", h("Single-pose latency, us per call"), ""]
    out += engine.render_latency(result["latency"], style)
    out.append("")
    out += engine.render_agreement(result["agreement"], DELTA.units, style)
    out.append(
        f"{bullet}C kernel = generated C function with preallocated outputs; _core = "
        "robot._core.<fn> (fresh numpy outputs); API = robot.<fn> with validation. "
        "Targets are checked against the compiled _core median."
    )
    out.append(
        f"{bullet}single-threaded (threads=1; all cores: last section): the reference uses "
        "numpy ufuncs, so OPENBLAS/OMP thread settings are irrelevant"
    )
    if result.get("serial") is not None:
        out.append("")
        out += render_serial(result["serial"], repeats, markdown)
    if result.get("threads") is not None:
        out.append("")
        out += _render_threads(result["threads"], style)
    if result.get("families") is not None:
        out.append("")
        out += families.render(result["families"], markdown)
    if result.get("bars") is not None:
        out.append("")
        out += bars.render(result["bars"], markdown)
        out.append("")
    out.append(f"{bullet}total bench time {result['elapsed_s']:.1f} s")
    return "\n".join(out)


def render_serial(serial: dict, repeats: int, markdown: bool) -> list[str]:
    """The serial arm's section: workload, throughput, latency, peers and IK."""
    robot, n = serial["robot"], serial["n"]
    style = Style(markdown)
    h, bullet, code = style.h, style.bullet, style.code
    lim = ", ".join(f"[{lo:.3g}, {hi:.3g}]" for lo, hi in robot.qlim)
    small = {name: pts for name, (pts, _) in serial["sizes"].items()}
    conv = robot.description.convention
    out = [h(f"Serial arm: {robot.name} ({robot.n} joints, {conv} DH)"), ""]
    out.append(
        f"{bullet}workload: {code(f'SerialRobot.load({robot.name!r})')}, q uniform within "
        f"the joint limits ({lim}) rad, qd uniform in [{SERIAL_QD_RANGE[0]}, "
        f"{SERIAL_QD_RANGE[1]}] rad/s; seed {SEED}"
    )
    out.append(
        f"{bullet}N = {n:,} configurations for fk and jacobian, "
        f"{small['frames']:,} for frames, jacobian_dot and the dynamics; reference on the first "
        f"{min(n, SERIAL_REFERENCE_N):,} (scaled per configuration); median [min, max] "
        f"of {repeats} repeats, columns round-robin"
    )
    out += ["", h(f"{robot.name}: throughput, ns per configuration"), ""]
    out += engine.render_throughput(SERIAL, serial, style)
    out += ["", h(f"{robot.name}: single-pose latency, us per call"), ""]
    out += engine.render_latency(serial["latency"], style)
    out.append("")
    out += engine.render_agreement(serial["agreement"], SERIAL.units, style)
    out += peers.render(serial["oracles"], robot.name, n, style)
    out.append("")
    if serial.get("ik") is not None:
        out += ik.render(serial["ik"], markdown, robot.name)
    return out


# ------------------------------------------------------------------------- all cores


def run_threads(n: int, repeats: int) -> dict:
    """threads=1 vs the default thread count on delta fk, Puma560 fk and jacobian (_core)."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.serial import SerialRobot
    from deltagen.native import parallel

    threads = parallel.resolve_threads(None)
    rng = np.random.default_rng(SEED)
    delta = {t: DeltaRobot.default(threads=t) for t in (1, threads)}
    arm = {t: SerialRobot.load(SERIAL_ROBOT, threads=t) for t in (1, threads)}
    q_delta = np.ascontiguousarray(rng.uniform(*Q_RANGE, (n, 3)))
    lim = arm[1].qlim
    q_arm = np.ascontiguousarray(lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((n, arm[1].n)))
    rows = []
    for label, robots, fn, q in (
        ("delta fk", delta, "fk", q_delta),
        (f"{SERIAL_ROBOT} fk", arm, "fk", q_arm),
        (f"{SERIAL_ROBOT} jacobian", arm, "jacobian", q_arm),
    ):
        # the warm-up call also starts the pool's threads
        calls = [(t, getattr(robots[t]._core, fn), (q,), n) for t in (1, threads)]
        (_, one), (_, many) = engine.time_calls(calls, repeats)
        rows.append((label, one, many))
    return {
        "threads": threads,
        "chunks": len(parallel.chunks(n, threads)),
        "n": n,
        "rows": rows,
        "load": _load(),
    }


def _render_threads(result: dict, style: Style) -> list[str]:
    from deltagen.native import parallel

    k = result["threads"]
    out = [style.h(f"All cores: threads=1 vs threads={k}, _core, ns per item"), ""]
    header = ["quantity", "threads=1", f"threads={k}", "speedup"]
    rows = [[label, cell(one), cell(many), ratio(one, many)] for label, one, many in result["rows"]]
    out += style.table(header, rows)
    out.append("")
    out.append(
        f"{style.bullet}threads: DELTAGEN_THREADS, else the available cores = {k}; N = "
        f"{result['n']:,} rows in {result['chunks']} chunk(s) (batches below "
        f"{2 * parallel.MIN_ROWS_PER_THREAD:,} rows run in one call); load average (1 min) "
        f"{result['load']} after this section"
    )
    return out


# ------------------------------------------------------------------------- entry point


BYTES_PER_POINT = 8 * (3 + 3 + 1 + 6 + 16 + 6 + 6) * 2


def measure(
    n: int = 1_000_000, repeats: int = 7, serial: bool = True, oracles: bool = True
) -> dict:
    """Measure everything; returns the raw result (see :func:`render`). ``serial`` adds the
    Puma560 section, ``oracles`` its comparison with roboticstoolbox-python / pinocchio."""
    from deltagen.api.delta import DeltaRobot

    if n < 1:
        raise ValueError(f"--n must be at least 1, got {n}")
    if repeats < 1:
        raise ValueError(f"--repeats must be at least 1, got {repeats}")
    # per point: the delta's inputs and outputs, the Puma 560's q, poses (4x4), rates and
    # flags, and the peers' copies
    check_memory(n * BYTES_PER_POINT, f"a batch of --n = {n} points", "choose a smaller --n")
    t_start = time.perf_counter()
    load_before = _load()
    compiled = DeltaRobot.default(backend="compiled", threads=1)  # builds the C core if needed
    reference = DeltaRobot.default(backend="reference")
    ref_n = min(n, REFERENCE_N)

    rng = np.random.default_rng(SEED)
    head = sample_poses(ref_n, [compiled._core, reference._core], rng)  # OK for both
    tail = sample_poses(n - ref_n, [compiled._core], rng) if n > ref_n else None
    poses = head if tail is None else {k: np.concatenate([head[k], tail[k]]) for k in head}
    poses = {k: np.ascontiguousarray(v) for k, v in poses.items()}
    del head, tail

    throughput, _, agreement = engine.measure_throughput(DELTA, compiled, reference, poses, repeats)
    q1, p1 = poses["q"][0].copy(), poses["p"][0].copy()
    latency = engine.measure_latency(
        lambda robot: _latency_calls(robot, q1, p1), compiled, reference, repeats
    )
    del poses
    serial_result = run_serial(n, repeats, oracles) if serial else None
    threads_result = run_threads(n, repeats) if serial else None
    families_result = families.run(n, repeats)
    bars_result = bars.measure(n=n, repeats=repeats, oracles=oracles) if serial else None
    machine = machine_info(compiled)
    if serial_result is not None:
        machine.append(("C build (serial)", _build_name(serial_result["robot"])))
        if oracles:
            versions = peers.library_versions()
            machine.append(
                (
                    "other libraries",
                    ", ".join(f"{k} {v or 'not installed'}" for k, v in versions.items()),
                )
            )
    return {
        "n": n,
        "ref_n": ref_n,
        "repeats": repeats,
        "machine": machine,
        "throughput": throughput,
        "latency": latency,
        "agreement": agreement,
        "serial": serial_result,
        "threads": threads_result,
        "families": families_result,
        "bars": bars_result,
        "load_before": load_before,
        "load_after": _load(),
        "elapsed_s": time.perf_counter() - t_start,
    }
