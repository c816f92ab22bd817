"""`deltagen bench --bars`: the section runs and renders at a tiny size, its floor loop
(apps/bench/trig_floor.c) computes the sums it claims (against numpy's sin and cos), its
column-wise numpy delta fk is the delta's fk (against the numpy reference, written per row
and with (N, 3, 3) stacks), and a missing peer library or a single core gives an "n/a" row
with the reason, never an exception. No timing assertions."""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys

import numpy as np
import pytest

from deltagen.apps.bench import bars
from deltagen.cli import main
from deltagen.paths import generated_dir

VERDICTS = {"met", "MISSED", "n/a", "unsettled"}


@pytest.fixture(scope="module")
def floor():
    return bars.floor_module()


@pytest.mark.parametrize(("n", "angles"), [(1, 6), (1000, 6), (64 * 3 + 5, 3), (77, 16)])
def test_the_floor_loop_sums_numpys_sin_and_cos(floor, n, angles):
    """Every point's sine and cosine of every angle, summed per angle: numpy's sums (the
    block remainder and the padded lanes must add nothing)."""
    q = np.random.default_rng(n).uniform(-np.pi, np.pi, (n, angles))
    sums = bars.trig_sums(floor, q)
    np.testing.assert_allclose(sums[0], np.sin(q).sum(axis=0), rtol=0, atol=1e-12 * n)
    np.testing.assert_allclose(sums[1], np.cos(q).sum(axis=0), rtol=0, atol=1e-12 * n)


def test_the_fma_loop_runs_its_chains(floor):
    """deltagen_floor_fma: 64 chains acc_i = i / 64, each updated acc = acc a + b k times
    (the recursion written out here; fma rounds once, a*b+c twice: within 1e-15)."""
    a, b, k = 0.75, 0.125, 5
    out = np.empty(64)
    ffi, lib = floor.ffi, floor.lib
    assert lib.deltagen_floor_fma(k, a, b, ffi.from_buffer("double[]", out, True)) == 0
    expected = np.arange(64) / 64
    for _ in range(k):
        expected = expected * a + b
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-15)


def test_the_floor_loop_refuses_too_many_angles(floor):
    with pytest.raises(ValueError, match="1 to 16 angles"):
        bars.trig_sums(floor, np.zeros((4, 17)))


def test_the_floor_says_which_sin_and_cos_it_calls(floor, tmp_path):
    from deltagen.native.toolchain import vector_math_available

    text = bars.vector_trig(floor)
    if vector_math_available():
        assert text.startswith("libmvec _ZGV") and "lanes" in text
    fake = tmp_path / "scalar.so"  # a build without libmvec imports no _ZGV symbol
    fake.write_bytes(b"\x7fELF sin cos sincos")
    assert bars.vector_trig(type("M", (), {"__file__": str(fake)})).startswith("scalar libm")


def test_without_libmvec_the_floor_is_scalar_and_says_so(monkeypatch):
    """A build without vector math (no libmvec: compile_flags leaves out -fopenmp-simd)
    calls scalar sin and cos, names them so, and sums the same."""
    from deltagen.native import toolchain

    monkeypatch.setattr(toolchain, "vector_math_available", lambda: False)
    scalar = bars.floor_module()
    assert bars.vector_trig(scalar).startswith("scalar libm")
    q = np.random.default_rng(3).uniform(-3.0, 3.0, (300, 6))
    np.testing.assert_allclose(bars.trig_sums(scalar, q)[0], np.sin(q).sum(axis=0), atol=1e-12)


def test_the_stated_costs_are_read_for_every_floor_kernel():
    costs = bars.kernel_costs()
    for name, _ in bars.FLOOR_KERNELS.values():
        assert costs[f"deltagen_{bars.ARM}_{name}"] > 0
    assert costs["deltagen_puma560_fk"] < costs["deltagen_puma560_inverse_dynamics"]


def test_the_column_wise_numpy_fk_is_the_delta_fk():
    from deltagen.api.delta import DeltaRobot
    from deltagen.reference import delta as reference

    robot = DeltaRobot.default(backend="reference")
    q = np.random.default_rng(7).uniform(-0.3, 0.9, (500, 3))
    p_ref, status = reference.fk(robot.geometry, q)
    assert (status == 0).all()
    np.testing.assert_allclose(bars.numpy_fk_columns(robot.geometry, q), p_ref, atol=1e-12)


class _Tagged:
    """A kernel call that says which kernel it is (the fake timer below reads it)."""

    def __init__(self, call, kernel):
        self.call, self.kernel = call, kernel

    def __call__(self):
        return self.call()


_FAULTS = """
import resource, sys
import numpy as np
from deltagen.apps.bench import bars
from deltagen.api.delta import DeltaRobot
robot = DeltaRobot.default(backend="reference")
q = np.tile([0.2, 0.4, 0.1], (bars.FLOOR_N, 1))
if sys.argv[1] == "settled":
    bars.settle_allocator()
for _ in range(2):
    bars.numpy_fk_columns(robot.geometry, q)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
bars.numpy_fk_columns(robot.geometry, q)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
    reason="glibc's dynamic mmap threshold is what settle_allocator sets",
)
def test_after_settle_allocator_the_numpy_baseline_reuses_its_memory():
    """The numpy fk's baseline is measured in the allocator state it is fastest in: in a
    fresh interpreter its third call on FLOOR_N rows first-touches thousands of fresh pages
    (page faults, which a process's history decides: 93 vs 150 ns/point measured), after
    settle_allocator none (its temporaries come from the heap, reused)."""
    faults = {
        how: int(
            subprocess.run(
                [sys.executable, "-c", _FAULTS, how], capture_output=True, text=True, check=True
            ).stdout
        )
        for how in ("fresh", "settled")
    }
    assert faults["fresh"] > 1000, faults  # the state the bar must not be measured in
    assert faults["settled"] < 50, faults


def test_the_delta_rate_bars_judge_their_own_rows_and_show_the_in_cache_ratio(monkeypatch):
    """fk_vel / fk and fk_acc / fk are judged on the bar's rows; the in-cache ratio (calls
    of FLOOR_CALL_N rows) is in the note, labelled as information. The timers are replaced
    so that the two measures disagree about each verdict."""
    from deltagen.apps.bench import sections

    real = sections._kernel_callable
    monkeypatch.setattr(
        sections, "_kernel_callable", lambda core, name, ins: _Tagged(real(core, name, ins), name)
    )
    n, small = 2000, bars.FLOOR_CALL_N
    times = {
        ("fk", n): 10.0,
        ("fk_vel", n): 20.0,  # 2.0x: MISSED on the bar's rows
        ("fk_acc", n): 15.0,  # 1.5x: met
        ("fk", small): 10.0,
        ("fk_vel", small): 12.0,  # 1.2x in cache: would be met
        ("fk_acc", small): 30.0,  # 3.0x in cache: would be MISSED
    }

    def timer(fn, args=(), points=1, loops=1):
        kernel = getattr(fn, "kernel", None)
        if fn is bars.numpy_fk_columns:
            return lambda: 500.0
        return lambda: 1.0 if kernel is None else times[(kernel, points)]

    monkeypatch.setattr(bars, "cpu_timer", timer)
    rows = {r["key"]: r for r in bars.measure_delta(n, 2)}
    vel, acc = rows["delta_fk_vel"], rows["delta_fk_acc"]
    assert (vel["ratio"], vel["verdict"]) == (2.0, "MISSED")
    assert (acc["ratio"], acc["verdict"]) == (1.5, "met")
    label = f"for information, not the bar: in cache ({small:,} rows a call, looped)"
    assert label in vel["note"] and vel["note"].endswith(": 1.20x")
    assert label in acc["note"] and acc["note"].endswith(": 3.00x")
    assert vel["note"].startswith(f"{n:,} rows a call")
    # the floors: every other timer (the trig loop, the FMA rate) reads 1 ns here, so a
    # kernel's floor is 1 + its stated operations (generated/delta_kinematics.h: "Cost:");
    # numpy 500 ns
    header = (generated_dir() / "delta_kinematics.h").read_text()
    stated = dict(
        (name, int(cost))
        for cost, name in re.findall(
            r"Cost: (\d+) operations per point\.[^/]*?\*/\s*int (\w+)\(", header
        )
    )
    fk_floor = 1 + stated["deltagen_delta_fk"]
    assert "; the floors' ratio (trig + stated ops) " in vel["note"]
    assert (
        f"{(1 + stated['deltagen_delta_fk_vel']) / fk_floor:.2f}x; for information" in vel["note"]
    )
    assert (
        f"{(1 + stated['deltagen_delta_fk_acc']) / fk_floor:.2f}x; for information" in acc["note"]
    )
    assert (
        f"a kernel at the floor would reach {500 / fk_floor:.1f}x numpy"
        in rows["delta_fk_numpy"]["note"]
    )


def _check(result):
    keys = [r["key"] for r in result["rows"]]
    assert keys == list(bars.TARGETS), keys
    for r in result["rows"]:
        assert r["verdict"] in VERDICTS
        if r["verdict"] == "n/a":
            assert r["note"], r  # an n/a row says why
        else:
            assert r["ratio"] > 0


def test_the_bars_run_and_render_at_a_tiny_size(capsys, tmp_path):
    out_json = tmp_path / "bars.json"
    readme = tmp_path / "README.md"
    full = "<!-- bench:begin -->\nthe full run\n<!-- bench:end -->\n"
    readme.write_text(f"# x\n{full}<!-- bench-bars:begin -->\nold\n<!-- bench-bars:end -->\nend\n")
    argv = ["bench", "--bars", "--n", "3000", "--repeats", "1", "--markdown"]
    assert main([*argv, "--json", str(out_json), "--readme", str(readme)]) == 0
    text = capsys.readouterr().out
    for label, _, _ in bars.TARGETS.values():
        assert label in text
    assert "floor (trig_floor.c" in text and "load average" in text
    data = json.loads(out_json.read_text())
    assert data["markdown"].strip() == text.strip()
    assert [r["key"] for r in data["bars"]["rows"]] == list(bars.TARGETS)
    section = readme.read_text()
    assert full in section and "old" not in section and section.endswith("end\n")
    assert text.strip() in section  # the bars' own section, the full run's left alone


def test_missing_peers_and_one_core_are_rows_not_errors(monkeypatch):
    import deltagen.native.parallel as parallel

    for module in ("roboticstoolbox", "pinocchio"):
        monkeypatch.setitem(sys.modules, module, None)  # import raises ImportError
    monkeypatch.setattr(parallel, "available_cores", lambda: 1)
    result = bars.measure(n=500, repeats=1)
    _check(result)
    rows = {r["key"]: r for r in result["rows"]}
    for key in ("ik_all_pinocchio", "numeric_ik_median", "numeric_ik_p95"):
        assert rows[key]["verdict"] == "n/a" and "not importable" in rows[key]["note"]
    for key in ("threads_delta_fk", "threads_puma_fk"):
        assert rows[key]["verdict"] == "n/a" and "1 core" in rows[key]["note"]
    text = "\n".join(bars.render(result, markdown=False))
    assert text.count("n/a") >= 5


def test_oracles_off_skips_the_peer_rows():
    result = bars.measure(n=300, repeats=1, oracles=False)
    _check(result)
    assert all(
        "skipped" in r["note"] for r in result["rows"] if r["key"].startswith(("ik_", "numeric"))
    )


@pytest.mark.parametrize(
    ("busy", "load", "solo", "verdict", "why"),
    [
        (1.5, 0.0, 20.0, "unsettled", "second core was not free"),  # others held a core
        (0.1, 9.0, 20.0, "MISSED", None),  # the measured use wins over the load average
        (None, 9.0, 20.0, "unsettled", "second core was not free"),  # no /proc/stat: load
        (None, 0.0, 20.0, "MISSED", None),
        (0.0, 0.0, 12.0, "unsettled", "the host, not the API"),  # the machine gives 1.2x
    ],
)
def test_a_missed_threads_bar_says_whether_the_host_or_the_api_missed(
    monkeypatch, busy, load, solo, verdict, why
):
    """An API wall-time ratio of 1.0 (< 1.8) beside the machine's ceiling (the C kernel on
    two plain threads, same run): MISSED only when the second core was free (other
    processes' measured use, else the load average) and the ceiling reached the target."""
    import os

    from deltagen.native import parallel

    monkeypatch.setattr(parallel, "available_cores", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (load, load, load))

    class Meter:  # other processes' cores during the two-thread calls: given
        def __call__(self, timer):
            return timer

        def cores(self):
            return busy

    monkeypatch.setattr(bars, "other_cores", Meter)
    # API threads=1, threads=2; machine on preallocated outputs one, two; on fresh one, two
    walls = [10.0, 10.0, 2 * solo, 10.0, solo, 10.0]

    def fixed_wall_times(timers, repeats):  # each call runs once; the times are given
        assert len(timers) == 6  # the API's two and the machine's four, round-robin
        for timer in timers:
            timer()
        return [bars.Stat([wall]) for wall in walls]

    monkeypatch.setattr(bars, "interleaved", fixed_wall_times)
    rows, raw = bars.measure_threads(1000, 1)
    assert [r["verdict"] for r in rows] == [verdict, verdict]
    for r in rows:
        assert "CPU time" in r["note"]
        assert f"machine ceiling on preallocated outputs {2 * solo / 10.0:.2f}x" in r["note"]
        assert f"machine ceiling on fresh outputs {solo / 10.0:.2f}x" in r["note"]
        assert f"the API reaches {10.0 / solo:.0%} of the fresh-output ceiling, with " in r["note"]
        assert "x its process CPU time on two threads" in r["note"]
        assert why is None or why in r["note"]
    assert len(raw) == 3
    for entry in raw:
        assert entry["fresh_one"].min == solo and entry["preallocated_two"].min == 10.0
        assert {f"cpu_{k}" for k in ("one", "two", "fresh_one", "preallocated_two")} <= set(entry)
    text = "\n".join(bars.render({**_tiny_result(), "threads": raw}, markdown=False))
    assert text.count("machine ceiling on fresh outputs") == 3


def _tiny_result():
    return {
        "rows": [],
        "floor": {},
        "threads_n": 1000,
        "repeats": 1,
        "load_before": "0",
        "load_after": "0",
        "elapsed_s": 0.0,
    }


def test_the_machine_ceiling_runs_the_two_halves_at_once_in_two_threads():
    """_Pair: the two calls run at the same time (each waits for the other inside), in this
    thread and in another one; the other's exception is raised here and the pair still
    works; close() ends the other thread."""
    import threading

    pair = bars._Pair()
    met = threading.Barrier(2, timeout=10)
    names = []

    def call():
        names.append(threading.current_thread().name)
        met.wait()  # fails (BrokenBarrierError) unless the other call runs at the same time

    for _ in range(3):
        pair.run(call, call)
    assert names.count(threading.current_thread().name) == 3 and len(set(names)) == 2

    def fails():
        raise ArithmeticError("in the other thread")

    with pytest.raises(ArithmeticError, match="other thread"):
        pair.run(lambda: None, fails)
    pair.run(call, call)  # the other thread is still there
    pair.close()
    assert not pair._thread.is_alive()


def test_other_processes_cpu_is_measured_or_none(monkeypatch):
    """OtherCores: over the calls it wraps, a share of the machine (0 .. cores) where
    /proc/stat is readable, None where it is not or nothing was metered (never an
    exception); the wrapped timer's value passes through."""
    meter = bars.other_cores()
    assert meter.cores() is None  # nothing metered yet
    timer = meter(lambda: sum(range(200_000)) * 0.0 + 7.0)
    assert [timer() for _ in range(3)] == [7.0] * 3
    used = meter.cores()
    if os.path.exists("/proc/stat"):
        assert used is not None and 0.0 <= used <= (os.cpu_count() or 1)
    else:
        assert used is None

    def unreadable(*args, **kwargs):
        raise OSError("no /proc here")

    monkeypatch.setattr(bars, "open", unreadable, raising=False)
    blind = bars.other_cores()
    assert blind(lambda: 1.0)() == 1.0 and blind.cores() is None


def test_other_processes_cpu_stays_within_the_machine(monkeypatch):
    """/proc/stat counts whole ticks: over a short call the busy time read can exceed what
    the cores could do (or fall below this process's own CPU time); the share reported is
    bounded by 0 and the core count, never beyond."""
    ticks = iter([0.0, 10.0, 10.0, 10.0])  # 10 s of busy time in the first call, 0 in the second
    monkeypatch.setattr(bars, "_busy_seconds", lambda: next(ticks))
    meter = bars.other_cores()
    meter(lambda: 0.0)()
    assert meter.cores() == float(os.cpu_count() or 1)
    below = bars.other_cores()
    below(lambda: sum(range(100_000)) * 0.0)()  # busy 0, this process's CPU > 0
    assert below.cores() == 0.0


def test_the_machine_ceilings_run_the_kernels_on_both_halves(monkeypatch):
    """_kernel_halves: for the delta (geometry-taking kernels) and the Puma (plain ones),
    both ceilings run in one thread and in two; the halves split on a ROW_ALIGN row and
    cover every row once (a recording kernel stands in for the C function's rows)."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.api.serial import SerialRobot
    from deltagen.native.parallel import ROW_ALIGN

    n = 3 * ROW_ALIGN + 17
    q = np.random.default_rng(1).uniform(-0.3, 0.9, (n, 6))
    pair = bars._Pair()
    try:
        for robot, width in ((DeltaRobot.default(threads=1), 3), (SerialRobot.load("puma560"), 6)):
            halves = bars._kernel_halves(robot, "fk", np.ascontiguousarray(q[:, :width]))
            assert set(halves) == set(bars.CEILINGS)
            for one, two in halves.values():
                one()
                two(pair)
        arm = SerialRobot.load("puma560")
        ffi, _ = arm._core.c_function("fk")
        calls = []

        def recording(rows, *buffers):
            calls.append(rows)
            return 0

        monkeypatch.setattr(arm._core, "c_function", lambda name: (ffi, recording))
        halves = bars._kernel_halves(arm, "fk", np.ascontiguousarray(q))
        assert calls == [n]  # the preallocated outputs touched once, every row
        for one, two in halves.values():
            calls.clear()
            one()
            assert calls == [ROW_ALIGN, n - ROW_ALIGN]  # half of n, down to ROW_ALIGN
            calls.clear()
            two(pair)
            assert sorted(calls) == [ROW_ALIGN, n - ROW_ALIGN]
    finally:
        pair.close()
    assert bars._kernel_halves(DeltaRobot.default(backend="reference"), "fk", q[:, :3]) == {}
