"""All cores on batches: one batched C call split into contiguous row chunks that run on
threads at once.

Why threads and not OpenMP: the generated C must stay standalone (C99, libm only,
reentrant, no globals) for users who drop it into a motion controller; an OpenMP runtime
(libgomp) would be a new dependency of that C and of every build. (``-fopenmp-simd``,
used by the build for vector math, is a compile-time pragma only and links no runtime.)
Instead the kernels stay single-threaded and the caller splits the rows: cffi's
out-of-line API-mode modules (``native.build`` writes them with ``make_c_source``) wrap
every C call in ``Py_BEGIN_ALLOW_THREADS`` / ``Py_END_ALLOW_THREADS``, so the chunks
really run in parallel. Every kernel treats each row on its own (per-point status, no
state between rows), so a chunk writes its own rows of the shared output buffers. For
the result to be bit-for-bit the single-threaded one, every chunk but the last starts and
ends on a multiple of :data:`ROW_ALIGN` rows: the kernels work in blocks of
``<PREFIX>_BLOCK`` rows (64 for the parallel robots, 16 for the serial arms;
both divide ROW_ALIGN), and within a block a row goes through the vector loop
(libmvec's sin/cos/sqrt) or the scalar remainder (libm's), which may differ in the last
bit; aligned chunks put every row at the same place of the same block as one call would.

Sharing (:func:`run_rows`): a batch of more than PIECE_ROWS rows per chunk is cut into
pieces that the threads take in turn from a shared counter, not into one fixed chunk per
thread. On the project's 2-core shared machine a fixed half per thread made threads=2
0.5-0.8x threads=1 through the API at 10^5-10^6 rows whenever other processes held a core
(load average 6-7; ``deltagen bench --bars``): the caller finished its half and then
waited for a pool thread still waiting for a core. With pieces the thread that runs takes
the work.

The pieces shrink towards the end of the batch (guided self-scheduling, Polychronopoulos &
Kuck, "Guided self-scheduling", IEEE Trans. Computers C-36(12), 1987: each piece is the
rows left divided by the threads, here capped at PIECE_ROWS and floored at
MIN_PIECE_ROWS). With pieces of one size, a thread that is a little slower than the other
(another process on its core for a moment) is still inside its last full piece when the
other runs out of work: the call waits for up to one whole piece (~0.6 ms of delta fk,
~2 ms of Puma fk at 64 Ki rows). Simulated as run_rows shares the pieces (the free thread
takes the next; tests/native/test_parallel.py), 10^6 rows with one thread 5 % / 10 %
slower end 2.6 % / 5.6 % after the ideal split with 16 equal pieces, 0.5 % / 0.2 % with
the shrinking tail, which bounds the wait by one MIN_PIECE_ROWS piece (~40-150 us) at the
cost of a few more pieces (19 instead of 16 at 10^6 rows; each ~5 us of Python: the
counter, the cffi buffers).

Threshold (:data:`MIN_ROWS_PER_THREAD`): a chunk must amortise the hand-off to a pool
thread. Measured on the project's 2-core shared machine (load average 1.4): splitting a
no-op call in two costs 55 us median (p90 99 us: submit, wake-up, join); delta fk costs
9 ns/row on an idle core (README benchmark) and 45-60 ns/row with the other core busy, so
a 20000-row chunk is 0.18-1.2 ms of work, 3-20x the hand-off. Splits of 2000-10000 rows
measured 0.6-0.9x (slower) at that load; at 10^5-10^6 rows, 1.5-1.9x with the second
core free and ~0.95x while another job held it (README, "All cores on batches"). A batch
of N rows uses ``min(threads, N // MIN_ROWS_PER_THREAD)`` chunks, so splitting starts at
40000 rows.

How many threads: ``threads=`` on the robot (DeltaRobot / SerialRobot), else the
``DELTAGEN_THREADS`` environment variable (a positive integer), else the cores this
process may run on (``os.sched_getaffinity`` where present, else ``os.cpu_count()``).

The pool is one per process, created on first use, shared by every robot and safe to
call from several Python threads at once (the caller runs one chunk itself and waits for
the others; pool threads only run C kernels and never submit work, so no call can wait
on itself). After ``fork`` the child gets a fresh pool.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait

import numpy as np

from deltagen.inputs import InputError, env_positive_int, is_integer

MIN_ROWS_PER_THREAD = 20000
#: the largest piece of a large batch (a multiple of ROW_ALIGN): the threads share the
#: pieces out as they get to them (run_rows); 64 Ki rows of Puma fk are ~2 ms of work,
#: ~1000x a cffi call
PIECE_ROWS = 65536
#: the smallest piece (a multiple of ROW_ALIGN) of the batch's shrinking tail: 4 Ki rows are
#: 40-150 us of delta or Puma fk, ~10-30x the ~5 us a piece costs in Python
MIN_PIECE_ROWS = 4096
# a multiple of every generated module's <PREFIX>_BLOCK (codegen.render.Unit.block, 64);
# tests/native/test_parallel.py checks it against generated/
ROW_ALIGN = 256
_MAX_POOL_THREADS = 64  # pool threads are started only when needed, up to this many

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def available_cores() -> int:
    """The cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_threads(threads, source: str = "threads"):
    """None (the default: DELTAGEN_THREADS or the available cores) or a positive int;
    InputError otherwise. With None, DELTAGEN_THREADS is checked now too (a robot made
    under a bad value fails at once, not at its first large batch)."""
    if threads is None:
        resolve_threads(None)
        return None
    if not is_integer(threads) or threads < 1:
        raise InputError(
            f"{source} must be a positive integer (or None for every available core), "
            f"got {threads!r}"
        )
    return int(threads)


def resolve_threads(threads: int | None) -> int:
    """The thread count of one call: ``threads`` when given, else DELTAGEN_THREADS (checked:
    a positive integer), else :func:`available_cores`."""
    if threads is not None:
        return threads
    value = env_positive_int(
        "DELTAGEN_THREADS", "the threads a batched call may use", "use every available core"
    )
    return available_cores() if value is None else value


def _get_pool() -> ThreadPoolExecutor:
    global _pool
    pool = _pool
    if pool is None:
        with _pool_lock:
            if _pool is None:
                _pool = ThreadPoolExecutor(
                    max_workers=_MAX_POOL_THREADS, thread_name_prefix="deltagen"
                )
            pool = _pool
    return pool


def _forget_pool_after_fork() -> None:  # the parent's threads do not exist in the child
    global _pool, _pool_lock
    _pool = None
    _pool_lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_after_fork)


def chunks(n: int, threads: int | None) -> list[tuple[int, int]]:
    """The contiguous row ranges [(lo, hi), ...] a batch of n rows is split into."""
    count = max(1, min(resolve_threads(threads), n // MIN_ROWS_PER_THREAD))
    inner = {n * i // count // ROW_ALIGN * ROW_ALIGN for i in range(1, count)}
    bounds = [0, *sorted(inner - {0, n}), n]
    return list(zip(bounds[:-1], bounds[1:]))


def pieces(n: int, threads: int | None) -> list[tuple[int, int]]:
    """The row ranges the threads of one batch share out, in the order they are taken
    (:func:`run_rows`): the :func:`chunks` themselves, or -- for a batch of more than
    PIECE_ROWS rows per chunk -- guided pieces: each the rows left divided by the chunk
    count, rounded down to ROW_ALIGN, at most PIECE_ROWS and at least MIN_PIECE_ROWS (the
    last piece takes a remainder smaller than that), so every inner bound is a multiple of
    ROW_ALIGN and the pieces shrink towards the end of the batch (module docstring)."""
    parts = chunks(n, threads)
    workers = len(parts)
    if workers == 1 or n <= workers * PIECE_ROWS:
        return parts
    ranges = []
    lo = 0
    while lo < n:
        size = (n - lo) // workers // ROW_ALIGN * ROW_ALIGN
        size = min(PIECE_ROWS, max(MIN_PIECE_ROWS, size))
        hi = n if n - lo - size < MIN_PIECE_ROWS else lo + size
        ranges.append((lo, hi))
        lo = hi
    return ranges


def run_rows(n: int, threads: int | None, call: Callable[[int, int], int]) -> int:
    """Run ``call(lo, hi)`` (one C kernel call on rows lo..hi of the batch's buffers; returns
    the kernel's rc) over the whole batch, split across threads; the first nonzero rc (in
    row order), or 0. Small batches (and threads=1) make exactly one call, in the caller's
    thread.

    The caller and ``len(chunks(n, threads)) - 1`` pool threads take the :func:`pieces` in
    row order from a shared counter until none is left (dynamic sharing): a thread that
    waits for a core -- the other core busy with another process on a shared machine --
    takes fewer pieces instead of holding everyone up at the join, so two threads are never
    much slower than one. Which thread computes a row changes no bit (ROW_ALIGN). After an
    exception no new piece is started; the caller waits for every running one before it
    re-raises (the buffers stay in use until then)."""
    if n < 2 * MIN_ROWS_PER_THREAD or threads == 1:
        return call(0, n)
    workers = len(chunks(n, threads))
    if workers == 1:
        return call(0, n)
    ranges = pieces(n, threads)
    rcs = [0] * len(ranges)
    taken = iter(range(len(ranges)))
    lock = threading.Lock()
    failed = threading.Event()

    def work() -> None:
        while not failed.is_set():
            with lock:
                i = next(taken, None)
            if i is None:
                return
            try:
                rcs[i] = call(*ranges[i])
            except BaseException:
                failed.set()
                raise

    pool = _get_pool()
    futures = [pool.submit(work) for _ in range(workers - 1)]
    try:
        work()
    finally:  # every piece is done with the buffers before the caller goes on
        wait(futures)
    for f in futures:
        f.result()  # a pool thread's exception
    return next((rc for rc in rcs if rc != 0), 0)


def run_batch(ffi, fn, geometry, inputs, widths, threads, leading=()) -> tuple:
    """(*outputs, status) of ``fn(geometry, rows, *leading, *inputs, *outputs, status)``, the
    calling convention of every struct-taking generated kernel, over the batch: inputs are
    (N, ...) C-contiguous float64, outputs (N, w) float64 for each w of ``widths`` ((w,
    "uint8_t"): a 0/1 flag output, uint8), status (N,) int8; the rows are split across threads
    (:func:`run_rows`). A nonzero rc is a bug (the Python layer validates first):
    RuntimeError."""
    n = inputs[0].shape[0]
    fb = ffi.from_buffer
    kinds = [w if isinstance(w, tuple) else (w, "double") for w in widths]
    outs = [np.empty((n, w), dtype=_DTYPES[ctype]) for w, ctype in kinds]
    ctypes = [f"{ctype}[]" for _, ctype in kinds]
    status = np.empty(n, dtype=np.int8)

    def call(lo, hi):
        return fn(
            geometry,
            hi - lo,
            *leading,
            *(fb("double[]", a[lo:hi]) for a in inputs),
            *(fb(c, o[lo:hi], require_writable=True) for o, c in zip(outs, ctypes)),
            fb("int8_t[]", status[lo:hi], require_writable=True),
        )

    check_rc(run_rows(n, threads, call))
    return (*outs, status)


#: numpy element type of each C element type an output port may have (derive.kernel.Port)
_DTYPES = {"double": np.float64, "uint8_t": np.uint8}


def check_rc(rc: int) -> None:
    """RuntimeError for a kernel's nonzero rc: the Python layer validates first, so this is a
    bug, not bad input."""
    if rc != 0:
        raise RuntimeError(f"C core rejected its arguments (rc={rc})")
