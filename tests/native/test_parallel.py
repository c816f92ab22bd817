"""All cores on batches (native.parallel): a batched call split into row chunks across
threads gives the single-threaded answer bit for bit, for every batched kernel, from
several Python threads at once; threads= and DELTAGEN_THREADS are checked.

The tests lower MIN_ROWS_PER_THREAD so that batches of a few dozen rows are split (the
real threshold, 20000 rows, would make them slow); the split logic is the same."""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from deltagen import DeltaRobot, InputError, SerialRobot
from deltagen.model.delta import DeltaInertia
from deltagen.native import parallel
from deltagen.native.build import load, runtime_cdef, runtime_files
from deltagen.paths import generated_dir

SMALL = parallel.ROW_ALIGN  # rows per thread in these tests (256): N_SPLIT -> 3 chunks
N_SPLIT = 3 * SMALL + 37  # not a multiple of a chunk, of a block or of ROW_ALIGN
SIZES = [0, 1, N_SPLIT]


@pytest.fixture
def small_chunks(monkeypatch):
    monkeypatch.setattr(parallel, "MIN_ROWS_PER_THREAD", SMALL)


@pytest.fixture(scope="module")
def delta():
    return DeltaRobot(
        0.22,
        0.05,
        0.3,
        0.75,
        theta=tuple(math.radians(t) for t in (10, 100, 250)),
        inertia=DeltaInertia(
            I_a=0.02, m_a=0.9, r_ca=0.11, m_b=0.35, m_p=0.8, gravity=(0.5, -1.2, -9.7), I_4=1e-3
        ),
    )


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560")


def _same(a, b):
    """Bit for bit: equal arrays (NaN where NaN), same dtype, same shape."""
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()


def _with_threads(robot, threads, call):
    before = robot.threads
    robot.threads = threads
    try:
        return call()
    finally:
        robot.threads = before


def _delta_calls(delta, N, seed=0):
    rng = np.random.default_rng(seed)
    # a mix of reachable, unreachable and non-finite rows: statuses must agree too
    q = rng.uniform(-0.6, 1.6, (N, 3))
    qd, qdd = rng.normal(size=(N, 3)), rng.normal(size=(N, 3))
    p = np.column_stack(
        (rng.uniform(-0.4, 0.4, N), rng.uniform(-0.4, 0.4, N), rng.uniform(-1.1, -0.2, N))
    )
    payload = rng.uniform(0.0, 2.0, N)
    if N > 3:
        q[3, 1] = np.nan
        p[2, 0] = np.inf
    return {
        "fk": lambda: delta.fk(q, errors="nan"),
        "fk_vel": lambda: delta.fk_vel(q, qd, errors="nan"),
        "fk_acc": lambda: delta.fk_acc(q, qd, qdd, errors="nan"),
        "jacobian": lambda: delta.jacobian(q, errors="nan"),
        "ik": lambda: delta.ik(p, errors="nan"),
        "inverse_dynamics": lambda: delta.inverse_dynamics(
            q, qd, qdd, payload=payload, errors="nan"
        ),
        "inverse_dynamics_simplified": lambda: delta.inverse_dynamics(
            q, qd, qdd, payload=payload, model="simplified", errors="nan"
        ),
    }


def _puma_calls(puma, N, seed=0):
    rng = np.random.default_rng(seed)
    lim = puma.qlim
    q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((N, puma.n))
    qd = rng.normal(size=(N, puma.n))
    if N > 3:
        q[3, 2] = np.nan
    T = puma.fk(np.nan_to_num(q), errors="nan")[0]
    q0 = np.clip(q + rng.normal(scale=0.3, size=q.shape), lim[:, 0], lim[:, 1])
    q0 = np.nan_to_num(q0)
    return {
        "fk": lambda: puma.fk(q, errors="nan"),
        "frames": lambda: puma.frames(q, errors="nan"),
        "jacobian": lambda: puma.jacobian(q, errors="nan"),
        "jacobian_dot": lambda: puma.jacobian_dot(q, qd, errors="nan"),
        "ik_all": lambda: puma.ik_all(T),
        # the C Newton kernel, restarts drawn in Python for the unconverged rows; max_iter=4
        # leaves ~660 of 805 rows to restart, so the restart batches are split too
        "ik_numeric": lambda: puma.ik(
            T, q0=q0, method="numeric", errors="nan", restarts=3, seed=5, max_iter=4
        ),
    }


@pytest.mark.parametrize("N", SIZES)
@pytest.mark.parametrize(
    "name",
    ["fk", "fk_vel", "fk_acc", "jacobian", "ik", "inverse_dynamics", "inverse_dynamics_simplified"],
)
def test_delta_threaded_equals_single_threaded(small_chunks, delta, name, N):
    assert len(parallel.chunks(N, 3)) == (3 if N == N_SPLIT else 1)
    call = _delta_calls(delta, N)[name]
    one = _with_threads(delta, 1, call)
    for threads in (2, 3):
        _same(_with_threads(delta, threads, call), one)


@pytest.mark.parametrize("N", SIZES)
@pytest.mark.parametrize(
    "name", ["fk", "frames", "jacobian", "jacobian_dot", "ik_all", "ik_numeric"]
)
def test_serial_threaded_equals_single_threaded(small_chunks, puma, name, N):
    call = _puma_calls(puma, N)[name]
    one = _with_threads(puma, 1, call)
    for threads in (2, 3):
        _same(_with_threads(puma, threads, call), one)


def test_the_batch_is_really_split(small_chunks):
    """The chunks cover the rows once, in order, and run on more than one thread."""
    align = parallel.ROW_ALIGN
    n = 3 * align + 5
    parts = parallel.chunks(n, 3)
    assert parts == [(0, align), (align, 2 * align), (2 * align, n)]
    assert parallel.chunks(n, 100) == parts  # at most n // MIN_ROWS_PER_THREAD chunks
    assert len(parallel.chunks(N_SPLIT, 2)) == 2 and len(parallel.chunks(N_SPLIT, 3)) == 3
    assert parallel.chunks(SMALL, 4) == [(0, SMALL)]  # below 2 x SMALL rows: one chunk
    seen, names = [], set()
    gate = threading.Barrier(3, timeout=10)  # all three chunks must be running at once

    def call(lo, hi):
        gate.wait()
        seen.append((lo, hi))
        names.add(threading.current_thread().name)
        return 0

    assert parallel.run_rows(n, 3, call) == 0
    assert sorted(seen) == parts
    assert len(names) == 3
    assert parallel.run_rows(n, 3, lambda lo, hi: 4 if lo else 0) == 4  # a chunk's rc


@pytest.mark.parametrize("threads", [2, 3, 8])
@pytest.mark.parametrize("n", [1_000_003, 1_000_000, 140_000, 2 * 65536 + 1])
def test_large_batches_are_shared_out_in_aligned_shrinking_pieces(n, threads):
    """A batch of more than PIECE_ROWS rows per chunk is cut into pieces covering the rows
    once, in order, every inner bound on ROW_ALIGN; the pieces never grow along the batch
    (but for the last, which takes the remainder), none is above PIECE_ROWS or (but the
    last) below MIN_PIECE_ROWS, and each is the rows left over the chunk count, rounded
    down to ROW_ALIGN and clamped (guided self-scheduling, written out here as a
    recursion on the rows left)."""
    align, top, bottom = parallel.ROW_ALIGN, parallel.PIECE_ROWS, parallel.MIN_PIECE_ROWS
    workers = len(parallel.chunks(n, threads))
    ranges = parallel.pieces(n, threads)
    if n <= workers * top:
        assert ranges == parallel.chunks(n, threads)
        return
    assert ranges[0][0] == 0 and ranges[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
    assert all(lo % align == 0 for lo, _ in ranges)
    sizes = [hi - lo for lo, hi in ranges]
    assert all(bottom <= s <= top for s in sizes[:-1])
    assert all(a >= b for a, b in zip(sizes[:-2], sizes[1:-1]))  # shrinking
    assert bottom <= sizes[-1] < 2 * bottom or len(sizes) == 1
    for lo, hi in ranges[:-1]:
        left = n - lo
        assert hi - lo == min(top, max(bottom, left // workers // align * align))
    # the tail: the last pieces are small, so a thread never waits for a whole big piece
    assert sizes[-2] == bottom or sizes[-2] < 2 * bottom
    assert sizes[0] == top


def test_small_batches_keep_their_chunks():
    small = 2 * parallel.MIN_ROWS_PER_THREAD + 7
    assert parallel.pieces(small, 2) == parallel.chunks(small, 2)
    assert parallel.pieces(1_000_003, 1) == [(0, 1_000_003)]
    assert parallel.pieces(2 * parallel.PIECE_ROWS, 2) == parallel.chunks(
        2 * parallel.PIECE_ROWS, 2
    )


def test_the_piece_sizes_are_aligned_constants():
    """PIECE_ROWS and MIN_PIECE_ROWS are multiples of ROW_ALIGN (so are the bounds built on
    them), and the smallest piece is well below the largest."""
    assert parallel.PIECE_ROWS % parallel.ROW_ALIGN == 0
    assert parallel.MIN_PIECE_ROWS % parallel.ROW_ALIGN == 0
    assert parallel.ROW_ALIGN <= parallel.MIN_PIECE_ROWS < parallel.PIECE_ROWS


def test_a_thread_that_waits_for_a_core_does_not_hold_up_the_batch(monkeypatch):
    """Dynamic sharing: while a pool thread is stuck in its piece (as when another process
    holds its core), the caller takes every other piece; with one fixed chunk per thread
    it would do half and wait."""
    monkeypatch.setattr(parallel, "MIN_ROWS_PER_THREAD", SMALL)
    monkeypatch.setattr(parallel, "PIECE_ROWS", SMALL)
    monkeypatch.setattr(parallel, "MIN_PIECE_ROWS", SMALL)
    n = 8 * SMALL
    ranges = parallel.pieces(n, 2)
    assert len(ranges) == 8
    caller = threading.current_thread()
    lock, release = threading.Lock(), threading.Event()
    seen: dict[tuple[int, int], bool] = {}

    def call(lo, hi):
        mine = threading.current_thread() is caller
        with lock:
            seen[(lo, hi)] = mine
            if sum(seen.values()) == len(ranges) - 1:
                release.set()  # the caller did every piece but the stuck one
        if not mine:
            assert release.wait(10), "the caller did not take the other pieces"
        return 0

    assert parallel.run_rows(n, 2, call) == 0
    assert sorted(seen) == ranges
    assert sum(seen.values()) >= len(ranges) - 1


def test_an_error_in_the_callers_chunk_waits_for_the_others(small_chunks):
    """The buffers stay in use until every chunk is done, even when one chunk raises."""
    done = threading.Event()
    started = threading.Barrier(2, timeout=10)

    def call(lo, hi):
        started.wait()
        if lo == 0:
            raise RuntimeError("boom")
        threading.Event().wait(0.05)  # still writing when the caller's chunk fails
        done.set()
        return 0

    with pytest.raises(RuntimeError, match="boom"):
        parallel.run_rows(2 * parallel.ROW_ALIGN + 3, 2, call)
    assert done.is_set()


def test_row_align_is_a_multiple_of_every_kernel_block():
    """Chunks that start on a block boundary keep each row's vector/scalar path."""
    import re

    from deltagen.codegen.render import Unit

    blocks = {
        int(m)
        for path in generated_dir().glob("*.c")
        for m in re.findall(r"#define DELTAGEN_\w+_BLOCK (\d+)", path.read_text())
    }
    blocks.add(Unit.block)
    assert blocks and all(parallel.ROW_ALIGN % b == 0 for b in blocks), blocks


def test_concurrent_callers_get_their_own_answers(small_chunks, delta, puma):
    """Several Python threads share the one pool: each gets exactly its own result."""
    N = 4 * SMALL + 3
    delta.threads = puma.threads = 2
    try:
        jobs = []
        for seed in range(6):
            dc, pc = _delta_calls(delta, N, seed), _puma_calls(puma, N, seed)
            for call in (dc["fk_acc"], dc["inverse_dynamics"], pc["jacobian"], pc["ik_all"]):
                jobs.append(call)
        expected = [_with_threads(delta, 1, lambda c=c: _with_threads(puma, 1, c)) for c in jobs]
        with ThreadPoolExecutor(max_workers=6) as callers:
            for _ in range(3):
                got = list(callers.map(lambda c: c(), jobs))
                for a, b in zip(got, expected):
                    _same(a, b)
    finally:
        delta.threads = puma.threads = None


@pytest.mark.parametrize("bad", [0, -2, 1.5, "2", True, np.float64(2.0)])
def test_threads_must_be_a_positive_integer(bad):
    with pytest.raises(InputError, match="threads must be a positive integer"):
        DeltaRobot.default(threads=bad)
    with pytest.raises(InputError, match="threads must be a positive integer"):
        SerialRobot.load("puma560", threads=bad)
    robot = DeltaRobot.default()
    with pytest.raises(InputError, match="threads must be a positive integer"):
        robot.threads = bad


def test_threads_is_kept_by_derived_robots():
    robot = DeltaRobot.default(threads=3)
    assert robot.with_backend("reference").threads == 3
    assert robot.with_inertia(None).threads == 3
    arm = SerialRobot.load("puma560", threads=2)
    assert arm.with_backend("compiled").threads == 2
    assert arm._core.threads == 2
    arm.threads = None
    assert arm._core.threads is None


@pytest.mark.parametrize("text", ["0", "-1", "two", "1.5", "2x"])
def test_deltagen_threads_is_checked(monkeypatch, small_chunks, delta, text):
    monkeypatch.setenv("DELTAGEN_THREADS", text)
    with pytest.raises(InputError, match="DELTAGEN_THREADS must be a positive integer"):
        delta.fk(np.zeros((N_SPLIT, 3)))  # a robot made before the variable was set
    with pytest.raises(InputError, match="DELTAGEN_THREADS must be a positive integer"):
        SerialRobot.load("puma560")  # a new robot: at once, whatever its batches
    assert DeltaRobot.default(threads=2).threads == 2  # threads= does not read it


def test_deltagen_threads_and_the_default(monkeypatch):
    monkeypatch.setenv("DELTAGEN_THREADS", " 3 ")
    assert parallel.resolve_threads(None) == 3
    assert parallel.resolve_threads(1) == 1  # threads= wins over the variable
    monkeypatch.delenv("DELTAGEN_THREADS")
    assert parallel.resolve_threads(None) == parallel.available_cores() >= 1


def test_the_compiled_wrappers_release_the_gil():
    """cffi's API-mode wrapper (what native.build compiles) drops the GIL around every C
    call: the condition for real parallelism."""
    from cffi import FFI
    from cffi.recompiler import make_c_source

    load("delta_kinematics", "deltagen_delta")  # the module must build
    cdef = (generated_dir() / "delta_kinematics.cdef.h").read_text()
    texts = [(generated_dir() / f"delta_kinematics{e}").read_text() for e in (".c", ".h")]
    runtime = {f: f.read_text() for f in runtime_files(texts)}
    ffi = FFI()
    ffi.cdef(runtime_cdef(runtime) + cdef)
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "wrapper.c"
        make_c_source(ffi, "_probe", '#include "delta_kinematics.h"', str(out))
        wrapper = out.read_text()
    body = wrapper[wrapper.index("_cffi_f_deltagen_delta_fk(") :]
    body = body[: body.index("\n}\n")]
    assert "Py_BEGIN_ALLOW_THREADS" in body and "Py_END_ALLOW_THREADS" in body
    begin, end = body.index("Py_BEGIN_ALLOW_THREADS"), body.index("Py_END_ALLOW_THREADS")
    assert "result = deltagen_delta_fk(" in body[begin:end]  # the C call runs without the GIL


def test_the_all_ok_shortcut_after_the_threads(delta):
    """_finish reads "every row OK" as "no status nonzero" (one pass, no (N,) temporary),
    which holds because OK is 0; errors="nan" still gives the per-row flags of the lead
    shape, all True when every row is OK and False exactly on the failing rows."""
    from deltagen import status as st

    assert st.OK == 0 and all(v != 0 for v in (st.UNREACHABLE, st.SINGULAR, st.INVALID))
    q = np.tile(np.array([0.2, 0.3, 0.4]), (2, 3, 1))
    p, ok = delta.fk(q, errors="nan")
    assert ok.shape == (2, 3) and ok.dtype == bool and ok.all() and np.isfinite(p).all()
    q[1, 2, 0] = np.nan
    p, ok = delta.fk(q, errors="nan")
    assert ok.tolist() == [[True] * 3, [True, True, False]]
    assert np.isnan(p[1, 2]).all() and np.isfinite(p[ok]).all()
    with pytest.raises(InputError, match=r"NaN or infinite values in rows \[5\]"):
        delta.fk(q)


# The measurement runs in a fresh interpreter: in a long pytest worker the allocator may
# hand back pages an earlier test already touched (another library's malloc settings, a
# retained heap), and then no thread faults anything in and the claim cannot be observed.
_FIRST_TOUCH = """
import json, resource, threading
import numpy as np
from cffi import FFI
from deltagen.native import parallel

ffi = FFI()
n = 4 * parallel.PIECE_ROWS  # 32 MB of (n, 16) outputs
q = np.zeros((n, 1))
met = threading.Barrier(2, timeout=10)
first = threading.local()
faults = []

def fake_kernel(geometry, rows, q_rows, out, status):
    if not getattr(first, "done", False):  # each thread's first piece waits for the
        first.done = True  # other's: both threads take pieces
        met.wait()
    before = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    np.frombuffer(ffi.buffer(out), dtype=np.float64)[:] = 1.0
    np.frombuffer(ffi.buffer(status), dtype=np.int8)[:] = 0
    after = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    faults.append((threading.current_thread().name, after - before))
    return 0

caller = threading.current_thread().name
start = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
out, status = parallel.run_batch(ffi, fake_kernel, None, [q], [16], 2)
outside = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt - start
outside -= sum(f for name, f in faults if name == caller)
print(json.dumps({"ok": bool((out == 1.0).all() and (status == 0).all()), "faults": faults,
                  "outside": outside, "pieces": len(parallel.pieces(n, 2))}))
"""


@pytest.mark.skipif(not hasattr(__import__("resource"), "RUSAGE_THREAD"), reason="Linux only")
def test_fresh_outputs_are_first_touched_by_the_threads_that_compute_them():
    """run_batch allocates its outputs without touching them, so a fresh page is faulted
    in (and zeroed by the OS) by the kernel's own write, in whichever thread computes those
    rows: that work is shared by the threads, not done by the caller alone before them
    (a fill or a zeroing pass in run_batch would do it in the caller). A fake kernel writes
    its rows and counts the minor page faults of its own thread (getrusage RUSAGE_THREAD):
    both threads fault pages in, and the caller faults few outside its
    pieces. Measured in a fresh interpreter (_FIRST_TOUCH)."""
    import json
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", _FIRST_TOUCH], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    faults = [tuple(f) for f in result["faults"]]
    outside = result["outside"]
    assert result["ok"]
    assert len(faults) == result["pieces"] >= 4
    # each thread faulted fresh pages in (not every piece: with transparent huge pages one
    # 2 MiB fault may cover a small tail piece a neighbour's write already faulted in)
    per_thread: dict[str, int] = {}
    for name, f in faults:
        per_thread[name] = per_thread.get(name, 0) + f
    assert len(per_thread) == 2 and all(f > 0 for f in per_thread.values()), faults
    assert outside < sum(f for _, f in faults) / 4, (outside, faults)


def _makespan(ranges, speeds, delays):
    """When the last of the threads finishes, taking ``ranges`` in order as run_rows does
    (whichever thread is free first takes the next piece): thread i starts at delays[i]
    and computes speeds[i] rows per time unit."""
    import heapq

    free = [(delay, i) for i, delay in enumerate(delays)]
    heapq.heapify(free)
    end = list(delays)
    for lo, hi in ranges:
        t, i = heapq.heappop(free)
        end[i] = t + (hi - lo) / speeds[i]
        heapq.heappush(free, (end[i], i))
    return max(end)


@pytest.mark.parametrize("n", [1_000_000, 3_000_001])
@pytest.mark.parametrize("slower", [1.0, 0.95, 0.9, 0.8, 0.6])
@pytest.mark.parametrize("late", [0.0, 5000.0])
def test_a_slightly_slower_thread_costs_at_most_one_small_piece(n, slower, late):
    """The pieces' tail: with one thread slower than the other (another process on its
    core for a while) or starting late (the pool's wake-up), the batch ends at most one
    MIN_PIECE_ROWS piece of the slower thread after the ideal split (both threads busy to
    the same end, n = (T - 0) * 1 + (T - late) * slower). Pieces of one size (64 Ki rows)
    miss this by up to a whole piece: 1e6 rows with a 10 % slower thread end 5.6 % late."""
    speeds, delays = [1.0, slower], [0.0, late]
    ideal = (n + late * slower) / (1.0 + slower)
    finish = _makespan(parallel.pieces(n, 2), speeds, delays)
    assert finish <= ideal + parallel.MIN_PIECE_ROWS / slower
