"""`deltagen bench --json FILE --png FILE --readme FILE`: the benchmark's result as data, as
a bar chart, and as the README's benchmark section.

* JSON: the whole result of :func:`deltagen.apps.bench.run`, made plain -- every timing
  (a :class:`~deltagen.apps.timing.Stat`) becomes {"median", "min", "max", "values"} in ns,
  robots become their names, numpy numbers and arrays become numbers and lists -- plus the
  rendered Markdown, so that a reader (or a later README update) needs nothing but the file.
* PNG: one horizontal bar per comparison, log scale, ns per item (per call, or per point
  of a batch): deltagen beside roboticstoolbox-python and pinocchio on the same robot and
  inputs in the same process (the rows of the "beside other libraries" table), and the
  numeric IK per call beside rtb's ik_LM.
* README: the text between ``<!-- bench:begin -->`` and ``<!-- bench:end -->`` is
  replaced by the Markdown of the run (machine, load average before and after, tables),
  so the README's benchmark section is always one run's output, never edited by hand;
  ``--bars --readme`` replaces the section between ``<!-- bench-bars:begin -->`` and
  ``<!-- bench-bars:end -->`` with the bars alone.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from deltagen.apps.bench.timing import Stat
from deltagen.inputs import read_regular_file

BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"


def plain(value: Any) -> Any:
    """A JSON-able copy of a bench result (see the module docstring)."""
    if isinstance(value, Stat):
        return {
            "median": value.median,
            "min": value.min,
            "max": value.max,
            "values": [float(v) for v in value.values],
        }
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, (str, int, bool)) or value is None:
        return value
    name = getattr(value, "name", None)  # a robot
    return str(name) if name is not None else repr(value)


def write_json(result: dict, markdown: str, path: str | Path) -> None:
    data = plain(result)
    data["markdown"] = markdown
    Path(path).write_text(json.dumps(data, indent=1) + "\n")


def comparisons(data: dict) -> list[tuple[str, str, float, float]]:
    """(label, unit, library ns, deltagen ns) of every peer comparison in a plain result."""
    rows = []
    serial = data.get("serial") or {}
    for row in (serial.get("oracles") or {}).get("rows", []):
        per = "per point" if row.get("unit") == "ns" else "per call"
        rows.append(
            (
                f"{row['library']}: {row['call']}",
                per,
                float(row["lib"]["median"]),
                float(row["dg"]["median"]),
            )
        )
    ik = serial.get("ik") or {}
    for key, arm in (("numeric", "Puma 560"), ("numeric_7axis", "7-axis")):
        nm = ik.get(key) or {}
        if "rtb" in nm and "deltagen" in nm:
            rows.append(
                (
                    f"numeric IK {arm}: rtb ik_LM vs arm.ik(method='numeric'), median",
                    "per call",
                    float(nm["rtb"]["median_ns"]),
                    float(nm["deltagen"]["median_ns"]),
                )
            )
    return rows


def write_png(data: dict, path: str | Path) -> None:
    """The bar chart (module docstring); needs matplotlib (the ``plot`` extra)."""
    from deltagen.apps.plotting import pyplot

    plt = pyplot()
    rows = comparisons(data)
    if not rows:
        rows = [("no peer library installed (pip install deltagen[bench])", "", 1.0, 1.0)]
    height = 0.6 + 0.42 * len(rows)
    fig, ax = plt.subplots(figsize=(10, height + 1.2))
    y = np.arange(len(rows))
    lib = [r[2] for r in rows]
    dg = [r[3] for r in rows]
    ax.barh(y - 0.2, lib, height=0.38, label="library", color="#999999")
    ax.barh(y + 0.2, dg, height=0.38, label="deltagen", color="#1f77b4")
    ax.set_yticks(y)
    ax.set_yticklabels([f"{r[0]} ({r[1]})" for r in rows], fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("ns per item (log scale; less is faster)")
    load = data.get("load_before", "")
    ax.set_title(f"deltagen bench: same robot, same inputs, same process (load {load})", fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: the README section of ``deltagen bench --bars --readme`` (the bars alone)
BARS_BEGIN, BARS_END = "<!-- bench-bars:begin -->", "<!-- bench-bars:end -->"


def update_readme(
    path: str | Path,
    markdown: str,
    markers: tuple[str, str] = (BEGIN, END),
    command: str = "deltagen bench --markdown --readme README.md",
) -> None:
    """Replace the README's generated section between ``markers`` (the benchmark's, by
    default) with ``markdown``."""
    begin, end = markers
    path = Path(path)
    text = read_regular_file(path, "--readme file").decode("utf-8")
    if begin not in text or end not in text:
        raise ValueError(f"{path} has no {begin} ... {end} section to replace")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    note = f"<!-- generated by `{command}`: do not edit by hand -->\n"
    path.write_text(head + begin + "\n" + note + markdown.rstrip() + "\n" + end + tail)
