"""Timing and tables of ``deltagen bench``: timers (one batch call, a calibrated loop),
round-robin repeats with the collector off, medians, cells, and text/markdown tables."""

from __future__ import annotations

import gc
import math
import statistics
import time
from collections.abc import Callable, Sequence

LATENCY_REPEAT_NS = 25_000_000  # target duration of one latency repeat


def batch_timer(
    fn: Callable,
    args: Sequence,
    points: int,
    loops: int = 1,
    clock: Callable[[], int] = time.perf_counter_ns,
) -> Callable[[], float]:
    """A timer: ``fn(*args)`` (one call on ``points`` points, the result dropped) called
    ``loops`` times -> ns per point on ``clock`` (wall time unless told)."""

    def timer():
        t0 = clock()
        for _ in range(loops):
            fn(*args)
        return (clock() - t0) / (points * loops)

    return timer


def loop_timer(
    fn,
    repeat_ns: int = LATENCY_REPEAT_NS,
    clock: Callable[[], int] = time.perf_counter_ns,
) -> Callable[[], float]:
    """A timer: ``fn()`` looped for ~``repeat_ns`` of ``clock`` -> ns per call (the loop
    count calibrated here, after a warm-up call)."""
    fn()
    loops = 1
    while True:
        t0 = clock()
        for _ in range(loops):
            fn()
        elapsed = clock() - t0
        if elapsed >= repeat_ns // 10 or loops >= 1 << 20:
            break
        loops *= 4
    return batch_timer(fn, (), 1, max(1, round(loops * repeat_ns / max(elapsed, 1))), clock)


def interleaved(timers: list, repeats: int) -> list[Stat]:
    """Run the timers round-robin ``repeats`` times (so a load change on a shared machine
    hits every column alike), garbage collector off; one Stat per timer."""
    samples: list[list[float]] = [[] for _ in timers]
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats):
            for i, timer in enumerate(timers):
                samples[i].append(timer())
    finally:
        if gc_was_enabled:
            gc.enable()
    return [Stat(v) for v in samples]


class Stat:
    """Median and spread of one measurement, in ns (per point or per call)."""

    def __init__(self, values):
        self.values = list(values)
        self.median = statistics.median(self.values)
        self.min = min(self.values)
        self.max = max(self.values)


def table(header: Sequence[str], rows: Sequence[Sequence[str]], markdown: bool) -> list[str]:
    if markdown:
        lines = [
            "| " + " | ".join(header) + " |",
            "|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|",
        ]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return lines
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    fmt = lambda r: "  ".join(  # noqa: E731
        (c.ljust(w) if i == 0 else c.rjust(w)) for i, (c, w) in enumerate(zip(r, widths))
    )
    return [fmt(header), fmt(["-" * w for w in widths])] + [fmt(r) for r in rows]


# ------------------------------------------------------------------------- cells


def num(v: float) -> str:
    """A time with as many digits as it deserves ("?" when not finite)."""
    if not math.isfinite(v):
        return "?"
    if v >= 1000:
        return f"{v:,.0f}"
    if v >= 100:
        return f"{v:.0f}"
    if v >= 10:
        return f"{v:.1f}"
    return f"{v:.2f}"


def cell(s: Stat | None, scale: float = 1.0) -> str:
    """ "median [min, max]" of a measurement divided by ``scale``; "n/a" if not measured."""
    if s is None:
        return "n/a"
    return f"{num(s.median / scale)} [{num(s.min / scale)}, {num(s.max / scale)}]"


def ratio(base: Stat | None, measured: Stat | None) -> str:
    """base / measured of the medians (a speedup when base is the slower one)."""
    if base is None or measured is None or measured.median <= 0:
        return "n/a"
    r = base.median / measured.median
    return f"{r:.0f}x" if r >= 10 else f"{r:.1f}x" if r >= 1 else f"{r:.2f}x"


def verdict(value: float, target: float) -> str:
    return "met" if value <= target else "MISSED"


class Style:
    """Headings, bullets and code spans of the text or the Markdown rendering."""

    def __init__(self, markdown: bool):
        self.markdown = markdown
        self.bullet = "- " if markdown else "  "

    def h(self, title: str) -> str:
        return f"### {title}" if self.markdown else f"== {title} =="

    def code(self, text: str) -> str:
        return f"`{text}`" if self.markdown else text

    def table(self, header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
        return table(header, rows, self.markdown)
