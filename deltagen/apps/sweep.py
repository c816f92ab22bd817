"""``deltagen sweep SPEC [--scheduler ADDR] [--out DIR]``: a geometry sweep.

Runs deltagen.sweep (deltagen.api.sweep: the spec, the scores, Dask) and writes into
--out: ``sweep.csv`` (one design per row, the provenance in '# ' header lines) and
``pareto.png`` (usable cylinder volume against the worst condition number, or against the
peak torque when the spec gives a move; the Pareto front joined, infeasible designs grey).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from deltagen.apps.plotting import pyplot

if TYPE_CHECKING:  # deltagen.api.sweep loads when the job runs, not with the parser
    from deltagen.api.sweep import SweepResult


def write_pareto(result: SweepResult, path: str | Path) -> Path:
    """Pareto plot PNG of a sweep (module docstring); the provenance goes in the PNG's
    text metadata."""
    plt = pyplot()
    x = result.columns["cylinder_volume_m3"]
    if result.spec.move is not None:
        yname, ylabel = "peak_torque_Nm", "peak motor torque on the reference move [N m]"
    else:
        yname, ylabel = "worst_condition", "worst condition number of J in the workspace [-]"
    y = result.columns[yname]
    ok = result.feasible
    front = result.pareto(minimise=yname)
    fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
    ax.scatter(x[~ok], y[~ok], s=14, c="0.75", label="infeasible")
    sc = ax.scatter(
        x[ok], y[ok], s=18, c=result.columns["l_b"][ok], cmap="viridis", label="feasible"
    )
    order = np.argsort(x[front])
    ax.plot(x[front][order], y[front][order], "r.-", lw=1.2, ms=9, label="Pareto front")
    ax.set_xlabel("inscribed cylinder volume [m^3]")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{len(result)} designs ({result.spec.design}, seed {result.spec.seed})")
    if ok.any():
        fig.colorbar(sc, ax=ax, label="l_b [m]")
    ax.legend(fontsize=8)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, metadata={"Description": "\n".join(result.header())})
    plt.close(fig)
    return path


def add_parser(subparsers) -> None:
    """`deltagen sweep SPEC.toml ...`."""
    s = subparsers.add_parser(
        "sweep",
        help="geometry sweep of a delta robot on Dask (local cluster by default)",
        description="Score the designs of a sweep spec (TOML: design grid|sobol, n, seed, "
        "[ranges] r_a r_b l_a l_b, [score], [move], [constraints], [inertia]; see "
        "deltagen.api.sweep) by workspace volume, usable cylinder, worst condition number "
        "and peak torque; write sweep.csv and pareto.png to --out. Runs on a local Dask "
        "cluster (every core), or on the cluster at --scheduler / DASK_SCHEDULER_ADDRESS.",
    )
    s.add_argument("spec", help="sweep spec (TOML)")
    s.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler address (tcp://host:port); 'inprocess' runs without Dask; "
        "default: DASK_SCHEDULER_ADDRESS, else a local cluster",
    )
    s.add_argument("--workers", type=int, default=None, help="local cluster: worker processes")
    s.add_argument("--out", default="sweep", help="output folder (default: sweep)")
    s.add_argument("--no-plot", action="store_true", help="skip the Pareto plot")
    s.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args) -> int:
    """`deltagen sweep`: the designs scored, the CSV and the Pareto plot written."""
    from deltagen.api.sweep import sweep

    result = sweep(
        args.spec,
        scheduler=args.scheduler,
        workers=args.workers,
        progress=False if args.quiet else None,
    )
    out = Path(args.out)
    written = [result.to_csv(out / "sweep.csv")]
    if not args.no_plot:
        written.append(write_pareto(result, out / "pareto.png"))
    if not args.quiet:
        front = result.pareto()
        print(
            f"{len(result)} designs in {result.seconds:.1f} s on {result.workers} worker(s): "
            f"{result.designs_per_second:.3g} designs/s, {result.poses_per_second:.3g} poses/s; "
            f"{int(result.feasible.sum())} feasible, {int(front.sum())} on the Pareto front"
        )
        for p in written:
            print(f"wrote {p}")
    return 0
