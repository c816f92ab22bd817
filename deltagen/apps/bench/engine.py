"""The one measure-and-render path of ``deltagen bench``: a section declares what it times,
these functions time it and render it.

* A throughput table (:class:`Throughput`): per quantity, its inputs (keys of the
  workload), the unit of its first output, its target against the compiled ``_core`` and
  the rows it runs on. Columns, timed round-robin after a warm-up call of each: ``kernel``
  (the generated C function with preallocated outputs, from the section's ``kernel``
  factory; a diagnostic column, n/a when the core is not the cffi one), ``core``
  (``robot._core.<fn>``, fresh numpy outputs: the targets are checked against it), ``api``
  (``robot.<fn>`` with validation) and the baseline, the numpy reference on its first
  ``reference_n`` rows: ``ref_core`` and, if declared, ``ref_api``; the agreement is the
  largest |compiled - reference| of the first output over the reference rows.
* A latency table: pairs (label, compiled call, target) / (label, reference call), each a
  loop of ~25 ms per repeat, timed round-robin; us per call.
* A list of timed calls (:func:`time_calls`): (label, function, arguments, rows), one
  warm-up call each, then round-robin; ns per row.

The record is the dict of :class:`~deltagen.apps.bench.timing.Stat` the sections return
(``report`` writes it as JSON); the rendering is the text or Markdown table below.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from deltagen.apps.bench.timing import (
    Stat,
    Style,
    batch_timer,
    cell,
    interleaved,
    loop_timer,
    ratio,
    verdict,
)

AGREEMENT_TOL = 1e-9  # max abs difference compiled vs reference before a warning

#: the columns of a throughput table in their order: key -> header
COLUMNS = {
    "kernel": "C kernel",
    "core": "compiled _core",
    "api": "compiled API",
    "ref_core": "reference _core",
    "ref_api": "reference API",
}
#: the speedup columns: (baseline column, measured column, header)
SPEEDUPS = (("ref_core", "core", "speedup _core"), ("ref_api", "api", "speedup API"))


@dataclass(frozen=True)
class Throughput:
    """What a throughput table times (module docstring)."""

    quantities: tuple[str, ...]
    #: quantity -> the workload's arrays it takes, in call order
    inputs: Mapping[str, tuple[str, ...]]
    #: quantity -> the unit of its first output (the agreement line)
    units: Mapping[str, str]
    #: quantity -> the target for the compiled _core [ns per row]
    targets: Mapping[str, float]
    #: (core, quantity, input arrays) -> a no-argument call of the C function, or None
    kernel: Callable
    #: the reference runs on at most this many rows
    reference_n: int
    #: also time the reference's public API (``ref_api``)
    reference_api: bool = True
    #: (quantity, workload rows) -> the rows the quantity runs on; None: all of them
    rows: Callable[[str, int], int] | None = None
    #: show the rows of each quantity as a column
    show_rows: bool = False

    def points(self, name: str, n: int) -> int:
        return n if self.rows is None else self.rows(name, n)

    def columns(self) -> list[str]:
        return [c for c in COLUMNS if c != "ref_api" or self.reference_api]


def _first_output(result: Any) -> np.ndarray:
    return np.asarray(result[0] if isinstance(result, tuple) else result)


def measure_throughput(
    section: Throughput, compiled: Any, reference: Any, data: dict, repeats: int
) -> tuple[dict, dict, dict]:
    """({quantity: {column: Stat in ns per row}}, {quantity: (rows, reference rows)},
    {quantity: max |compiled - reference|}); a quantity whose inputs the workload lacks
    (the dynamics of an arm without inertial parameters) is left out."""
    n = data[section.inputs[section.quantities[0]][0]].shape[0]
    stats, sizes, agreement = {}, {}, {}
    for name in section.quantities:
        keys = section.inputs[name]
        if any(k not in data for k in keys):
            continue
        points = section.points(name, n)
        ref_n = min(points, section.reference_n)
        inputs = [np.ascontiguousarray(data[k][:points]) for k in keys]
        ref_inputs = [np.ascontiguousarray(a[:ref_n]) for a in inputs]
        timers = {}
        kernel = section.kernel(compiled._core, name, inputs)  # called once: its warm-up
        if kernel is not None:
            timers["kernel"] = batch_timer(kernel, (), points)
        comp_out = _first_output(getattr(compiled._core, name)(*inputs))[:ref_n].copy()
        ref_out = _first_output(getattr(reference._core, name)(*ref_inputs))
        agreement[name] = float(np.max(np.abs(comp_out - ref_out)))
        del comp_out, ref_out
        for column in section.columns()[1:]:
            robot = compiled if column in ("core", "api") else reference
            fn = getattr(robot._core if column.endswith("core") else robot, name)
            args, rows = (ref_inputs, ref_n) if column.startswith("ref") else (inputs, points)
            if column.endswith("api"):
                fn(*args)  # warm-up (the _core ones ran above)
            timers[column] = batch_timer(fn, args, rows)
        stats[name] = dict(zip(timers, interleaved(list(timers.values()), repeats)))
        sizes[name] = (points, ref_n)
    return stats, sizes, agreement


def render_throughput(section: Throughput, result: dict, style: Style) -> list[str]:
    """The table of :func:`measure_throughput`'s result: {"throughput", "sizes"}."""
    columns = section.columns()
    speedups = [s for s in SPEEDUPS if s[0] in columns]
    header = ["quantity"] + (["N"] if section.show_rows else []) + [COLUMNS[c] for c in columns]
    header += [s[2] for s in speedups] + ["target (_core)"]
    rows = []
    for name in section.quantities:
        if name not in result["throughput"]:
            continue
        c = result["throughput"][name]
        target = section.targets.get(name)
        tcell = "-" if target is None else f"<= {target:g} {verdict(c['core'].median, target)}"
        row = [name] + ([f"{result['sizes'][name][0]:,}"] if section.show_rows else [])
        row += [cell(c.get(column)) for column in columns]
        row += [ratio(c[base], c[measured]) for base, measured, _ in speedups]
        rows.append(row + [tcell])
    return style.table(header, rows)


def measure_latency(calls: Callable, compiled: Any, reference: Any, repeats: int) -> list:
    """[(label, compiled Stat, reference Stat, target)] in ns per call; ``calls(robot)``
    gives [(label, no-argument call, target ns or None)], the same labels for both."""
    rows = []
    for (label, fn, target), (_, ref_fn, _) in zip(calls(compiled), calls(reference)):
        comp, ref = interleaved([loop_timer(fn), loop_timer(ref_fn)], repeats)
        rows.append((label, comp, ref, target))
    return rows


def render_latency(rows: list, style: Style) -> list[str]:
    header = ["call", "compiled", "reference", "speedup", "target (compiled)"]
    out = []
    for label, comp, ref, target in rows:
        tcell = "-" if target is None else f"<= {target / 1000:g} {verdict(comp.median, target)}"
        out.append(
            [style.code(label), cell(comp, 1000.0), cell(ref, 1000.0), ratio(ref, comp), tcell]
        )
    return style.table(header, out)


def render_agreement(agreement: dict, units: Mapping[str, str], style: Style) -> list[str]:
    """The agreement line and, past AGREEMENT_TOL, a warning."""
    text = ", ".join(f"{k} {v:.1e} {units[k]}" for k, v in agreement.items())
    out = [f"{style.bullet}agreement, max |compiled - reference| over the reference points: {text}"]
    bad = [k for k, v in agreement.items() if not v <= AGREEMENT_TOL]
    if bad:
        out.append(
            f"{style.bullet}WARNING: compiled and reference disagree on {', '.join(bad)} "
            f"(> {AGREEMENT_TOL:g}); the compiled timings may measure a broken core"
        )
    return out


def time_calls(calls: list, repeats: int) -> list[tuple[str, Stat]]:
    """[(label, Stat ns per row)] of [(label, function, arguments, rows)]: one warm-up call
    each, then round-robin."""
    for _, fn, args, _rows in calls:
        fn(*args)
    stats = interleaved([batch_timer(fn, args, rows) for _, fn, args, rows in calls], repeats)
    return [(label, s) for (label, _, _, _), s in zip(calls, stats)]
