"""``deltagen bench``: throughput and one-pose latency of the compiled cores beside the
numpy reference and the peer libraries, measured in one run (docs/architecture.md, "The
benchmark").

One measure-and-render path: a section declares what it times (the kernels, their rows,
the baseline, the units) and ``engine`` runs it round-robin, records it and renders its
tables; ``report`` writes the record as JSON, a PNG and the README section.

* ``sections``: the rotary delta's and the Puma 560's declarations (workloads, inputs,
  units, targets), the all-cores section and the run of every section.
* ``engine``: the declared throughput table (C kernel, ``_core``, API, reference
  columns), the single-call latency table, a list of timed calls, and their rendering.
* ``timing``: timers (one batch call, a calibrated loop), round-robin repeats with the
  collector off, medians, cells and text/markdown tables.
* ``peers``: roboticstoolbox-python and pinocchio on the same arm, inputs and process.
* ``ik``: inverse kinematics (closed form, numeric); ``general6r``: the general-6R
  solver's rows; ``families``: the linear delta's, the tripod's, the hexapod's and a
  5-axis machine's cores beside the rotary delta's.
* ``load``: cold and warm load of an arm (``python -m deltagen.apps.bench.load``).
* ``compare``: ``--compare REF``, this tree beside another commit or a stored run.
* ``report``: JSON, PNG and the README section of a run.
* ``bars``: every speed target of the batched kernels as a same-run ratio (the trig floor
  of trig_floor.c, a column-wise numpy delta fk, fk_vel/fk_acc vs fk, ik_all vs pinocchio,
  numeric IK vs rtb, two threads vs one), met / MISSED; ``--bars`` runs it alone.

The command: :func:`add_parser` adds ``bench`` to the CLI's subcommands, :func:`run` runs it
(exit 0; a bad size raises ValueError, which the CLI reports with exit 2).
"""

from __future__ import annotations

import argparse
from typing import Any


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """The ``bench`` subcommand and its options on the CLI's ``subparsers``."""
    b = subparsers.add_parser("bench", help="throughput and latency, compiled vs reference")
    b.add_argument("--n", type=int, default=1_000_000, help="batch size (default 10^6)")
    b.add_argument("--repeats", type=int, default=7, help="repeats per measurement (median)")
    b.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    b.add_argument("--json", metavar="FILE", help="write the whole result as JSON")
    b.add_argument(
        "--png", metavar="FILE", help="bar chart, deltagen vs peers, log ns per item (matplotlib)"
    )
    b.add_argument(
        "--readme",
        metavar="FILE",
        help="replace FILE's <!-- bench:begin --> ... <!-- bench:end --> section with the run",
    )
    b.add_argument(
        "--compare",
        metavar="REF",
        help="instead: this tree's batched throughput beside REF's, a git commit (measured "
        "from a temporary worktree, fresh processes, alternating rounds) or a `bench --json` "
        "file; prints measure / ref / this / this/ref",
    )
    b.add_argument(
        "--rounds", type=int, default=4, help="with --compare: processes per side (median)"
    )
    b.add_argument(
        "--bars",
        action="store_true",
        help="instead: only the bars, every speed target as a same-run ratio with met/MISSED "
        "(--n caps the workloads; well under a minute at the default)",
    )
    b.set_defaults(func=run)
    return b


def _oracles_wanted(args: argparse.Namespace) -> bool:
    """roboticstoolbox-python / pinocchio are timed unless --no-oracles (where the command
    line offers it) or DELTAGEN_BENCH_ORACLES=0."""
    from deltagen.inputs import env_flag

    if getattr(args, "no_oracles", False):
        return False
    return env_flag(
        "DELTAGEN_BENCH_ORACLES", True, "off: roboticstoolbox-python and pinocchio not timed"
    )


def run(args: argparse.Namespace) -> int:
    """``deltagen bench`` with the options of :func:`add_parser`: print the tables, write
    the files asked for; ``--compare REF`` instead prints this tree beside REF."""
    import sys

    if getattr(args, "compare", None):
        from deltagen.apps.bench import compare

        return compare.main(args)
    from deltagen.apps.bench import sections

    if getattr(args, "bars", False):
        return _run_bars(args)
    result = sections.measure(n=args.n, repeats=args.repeats, oracles=_oracles_wanted(args))
    print(sections.render(result, markdown=bool(getattr(args, "markdown", False))))
    sys.stdout.flush()
    json_file, png_file, readme = (getattr(args, k, None) for k in ("json", "png", "readme"))
    if json_file or png_file or readme:
        from deltagen.apps.bench import report

        text = sections.render(result, markdown=True)
        if json_file:
            report.write_json(result, text, json_file)
        if png_file:
            import json

            report.write_png(json.loads(json.dumps(report.plain(result))), png_file)
        if readme:
            report.update_readme(readme, text)
    return 0


def _run_bars(args: argparse.Namespace) -> int:
    """``deltagen bench --bars``: the bars section alone, printed and written as asked."""
    from deltagen.apps.bench import bars

    result = bars.measure(n=args.n, repeats=args.repeats, oracles=_oracles_wanted(args))
    print("\n".join(bars.render(result, markdown=bool(getattr(args, "markdown", False)))))
    json_file, readme = getattr(args, "json", None), getattr(args, "readme", None)
    if json_file or readme:
        from deltagen.apps.bench import report

        text = "\n".join(bars.render(result, markdown=True))
        if json_file:
            report.write_json({"bars": result}, text, json_file)
        if readme:
            report.update_readme(
                readme,
                text,
                (report.BARS_BEGIN, report.BARS_END),
                "deltagen bench --bars --markdown --readme README.md",
            )
    return 0
