"""Geometry sweeps: deltagen.sweep in-process and on a Dask cluster.

* the designs of a grid and of a Sobol spec (bounds, count, the seed reproduces them);
* one design's scores equal DeltaRobot.workspace of that robot, and the peak torque on the
  reference move equals inverse_dynamics_from_platform along a move built here;
* a sweep on a local ``distributed`` cluster of 2 worker processes gives the in-process
  table bit for bit;
* the CSV carries the seed, the spec and the version; the Pareto mask is non-dominated.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import deltagen
from deltagen import DeltaRobot, SweepSpec
from deltagen.api.sweep import SCORES, SweepError, score_design

INERTIA = {"I_a": 0.037, "m_a": 0.6, "r_ca": 0.15, "m_b": 0.2, "m_p": 0.5}
SPEC = {
    "design": "sobol",
    "n": 4,
    "seed": 3,
    "ranges": {"r_a": [0.15, 0.25], "r_b": 0.045, "l_a": [0.3, 0.4], "l_b": [0.7, 0.9]},
    "score": {"step": 0.12, "envelope_levels": 10},
    "move": {"from": [-0.2, 0.0, -0.8], "to": [0.2, 0.0, -0.8], "duration": 0.25, "payload": 0.5},
    "inertia": INERTIA,
    "constraints": {"cylinder_radius_m": {"min": 0.3}, "worst_condition": {"max": 9.0}},
}


def test_designs_grid_and_sobol():
    grid = SweepSpec.from_mapping({**SPEC, "design": "grid", "n": 3}).designs()
    assert grid.shape == (27, 4)
    assert set(np.round(grid[:, 0], 12)) == {0.15, 0.2, 0.25}
    assert np.all(grid[:, 1] == 0.045)
    a = SweepSpec.from_mapping({**SPEC, "n": 16}).designs()
    b = SweepSpec.from_mapping({**SPEC, "n": 16}).designs()
    c = SweepSpec.from_mapping({**SPEC, "n": 16, "seed": 4}).designs()
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.all((a[:, 0] >= 0.15) & (a[:, 0] <= 0.25) & (a[:, 3] >= 0.7) & (a[:, 3] <= 0.9))
    # a Sobol sample fills each dimension evenly: one point per sixteenth
    assert sorted(np.floor((a[:, 2] - 0.3) / 0.1 * 16).astype(int)) == list(range(16))


def test_one_design_scores_as_its_workspace_and_move():
    spec = SweepSpec.from_mapping(SPEC)
    lengths = (0.2, 0.045, 0.35, 0.8)
    got = score_design(spec, lengths)
    robot = DeltaRobot(*lengths, inertia=deltagen.DeltaInertia(**INERTIA))
    ws = robot.workspace(0.12, envelope_levels=10)
    assert got["volume_m3"] == ws.volume
    assert got["cylinder_radius_m"] == ws.cylinder.size
    assert got["worst_condition"] == ws.worst_condition
    # the move built here again: a quintic rest-to-rest line, sampled at 101 points
    t = np.linspace(0, 1, 101)[:, None]
    T, d = 0.25, np.array([0.4, 0.0, 0.0])
    p = np.array([-0.2, 0, -0.8]) + (10 * t**3 - 15 * t**4 + 6 * t**5) * d
    pd = (30 * t**2 - 60 * t**3 + 30 * t**4) / T * d
    pdd = (60 * t - 180 * t**2 + 120 * t**3) / T**2 * d
    # velocity by finite differences of p, as a check of the rates used
    np.testing.assert_allclose(np.gradient(p[:, 0], T / 100)[1:-1], pd[1:-1, 0], atol=0.05)
    tau = robot.inverse_dynamics_from_platform(p, pd, pdd, 0.5)
    assert got["peak_torque_Nm"] == pytest.approx(np.abs(tau).max(), rel=1e-12)


def test_rejected_geometry_scores_nan_and_is_infeasible():
    spec = SweepSpec.from_mapping(
        {
            **SPEC,
            "design": "grid",
            "n": 1,
            "ranges": {"r_a": 2.0, "r_b": 0.0, "l_a": 0.1, "l_b": 0.1},
        }
    )
    res = deltagen.sweep(spec, "inprocess")
    assert len(res) == 1 and math.isnan(res.columns["volume_m3"][0]) and not res.feasible[0]


@pytest.mark.parametrize(
    "bad, match",
    [
        ({"design": "random"}, "design"),
        ({"n": 0}, "n must"),
        ({"ranges": {"r_a": [0.3, 0.2], "r_b": 0.0, "l_a": 0.3, "l_b": 0.8}}, "ranges.r_a"),
        ({"constraints": {"speed": {"min": 1}}}, "constraints.speed"),
        ({"inertia": None, "move": SPEC["move"]}, "inertia"),
        ({"colour": 1}, "unknown keys"),
    ],
)
def test_bad_specs_name_the_key(bad, match):
    spec = {k: v for k, v in {**SPEC, **bad}.items() if v is not None}
    with pytest.raises(SweepError, match=match):
        SweepSpec.from_mapping(spec)


@pytest.fixture(scope="module")
def in_process():
    return deltagen.sweep(SPEC, "inprocess", progress=False)


def test_pareto_front_is_not_dominated(in_process):
    res = in_process
    front = res.pareto()
    a, b = res.columns["cylinder_volume_m3"], res.columns["peak_torque_Nm"]
    ok = res.feasible
    for i in range(len(res)):
        dominated = np.any(ok & (a >= a[i]) & (b <= b[i]) & ((a > a[i]) | (b < b[i])))
        assert front[i] == (ok[i] and not dominated)
    assert np.array_equal(
        res.feasible,
        np.isfinite(a)
        & (res.columns["cylinder_radius_m"] >= 0.3)
        & (res.columns["worst_condition"] <= 9.0),
    )


def test_csv_carries_seed_spec_and_version(in_process, tmp_path):
    path = in_process.to_csv(tmp_path / "s.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == f"# deltagen {deltagen.__version__} sweep"
    assert lines[1] == "# seed = 3"
    assert json.loads(lines[2].removeprefix("# spec = ")) == SPEC
    import csv

    rows = list(csv.DictReader(line for line in lines if not line.startswith("#")))
    assert len(rows) == 4
    for key in ("r_a", "volume_m3", "peak_torque_Nm"):
        np.testing.assert_array_equal([float(r[key]) for r in rows], in_process.columns[key])


def test_pareto_png_is_written(in_process, tmp_path):
    pytest.importorskip("matplotlib")
    from deltagen.apps.sweep import write_pareto

    png = write_pareto(in_process, tmp_path / "p.png")
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 5_000
    assert f"deltagen {deltagen.__version__}".encode() in png.read_bytes()


@pytest.mark.slow  # starts a 2-process Dask cluster (~20-40 s on 2 busy cores)
def test_sweep_on_a_local_dask_cluster_equals_in_process(in_process):
    pytest.importorskip("dask.distributed")
    # task_seconds tiny: one design per task, so the rows come from both workers
    res = deltagen.sweep(SPEC, workers=2, task_seconds=1e-6, progress=False)
    assert res.workers == 2
    for key in in_process.columns:
        np.testing.assert_array_equal(res.columns[key], in_process.columns[key], err_msg=key)
    assert np.array_equal(res.feasible, in_process.feasible)
    assert set(SCORES) <= set(res.columns)


def test_cli_sweep_writes_csv_and_pareto(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    from deltagen.cli import main

    spec = tmp_path / "spec.toml"
    spec.write_text(
        'design = "grid"\nn = 2\nseed = 5\n[ranges]\nr_a = [0.18, 0.22]\nr_b = 0.045\n'
        "l_a = 0.35\nl_b = 0.8\n[score]\nstep = 0.12\nenvelope_levels = 8\n"
    )
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--scheduler", "inprocess", "--out", str(out)]) == 0
    assert "2 designs" in capsys.readouterr().out
    text = (out / "sweep.csv").read_text()
    assert "# seed = 5" in text and (out / "pareto.png").stat().st_size > 0
    bad = tmp_path / "bad.toml"
    bad.write_text('design = "grid"\n')
    assert main(["sweep", str(bad), "--scheduler", "inprocess", "--out", str(out)]) == 2
    assert "[ranges] needs r_a" in capsys.readouterr().err


@pytest.mark.slow  # a 2-process Dask cluster started here, reached by its address
def test_sweep_on_a_running_cluster_from_dask_scheduler_address(in_process, monkeypatch):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler_address)
        res = deltagen.sweep(SPEC, task_seconds=1e-6, progress=False)
        assert res.workers == 2
        # the cluster outlives the sweep (it was not started by it)
        assert len(cluster.scheduler_info["workers"]) == 2
    for key in in_process.columns:
        np.testing.assert_array_equal(res.columns[key], in_process.columns[key], err_msg=key)
