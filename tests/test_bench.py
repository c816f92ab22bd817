"""Smoke test of `deltagen bench` at a tiny size: it runs, exits 0 and names every
quantity it measures. No timing assertions (shared machines are noisy)."""

from __future__ import annotations

import pytest

from deltagen import bench
from deltagen.cli import main

QUANTITIES = ("fk", "fk_vel", "fk_acc", "jacobian", "ik")


def _rows(text: str) -> dict[str, str]:
    """First cell of each table row -> the whole line."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if "|" in line \
            else line.split()
        if cells and cells[0]:
            rows.setdefault(cells[0], line)
    return rows


@pytest.mark.parametrize("markdown", [False, True], ids=["text", "markdown"])
def test_bench_runs_and_names_every_quantity(capsys, markdown):
    argv = ["bench", "--n", "2000", "--repeats", "2"] + (["--markdown"] if markdown else [])
    assert main(argv) == 0
    out = capsys.readouterr().out
    rows = _rows(out)
    for name in QUANTITIES:
        assert name in rows, f"no throughput row for {name}"
    for column in ("C kernel", "compiled _core", "compiled API", "reference _core",
                   "reference API", "speedup _core", "speedup API", "target"):
        assert column in out
    for call in ("robot.fk(q), q ndarray (3,)", "robot.fk(q), q list of 3 floats",
                 "robot.ik(p), p ndarray (3,)", "robot.ik(p), p list of 3 floats",
                 "robot._core.fk(q)", "robot._core.ik(p)"):
        assert call in out
    for target in ("<= 12", "<= 18", "<= 25", "<= 20", "<= 1.5"):
        assert target in out
    for fact in ("CPU", "cores", "Python", "numpy", "C flags", "-O3", "ns per point",
                 "us per call", "N = 2,000", "2 repeats", "agreement"):
        assert fact in out
    assert "WARNING" not in out  # compiled and reference agree on the sampled poses
    if markdown:
        assert "|---|" in out
        assert any(line.startswith("| fk_acc |") for line in out.splitlines())


def test_sampled_poses_are_valid_for_both_backends():
    import numpy as np

    from deltagen import DeltaRobot
    from deltagen.status import OK

    compiled, reference = DeltaRobot.default(), DeltaRobot.default(backend="reference")
    poses = bench.sample_poses(500, [compiled._core, reference._core],
                               np.random.default_rng(0))
    assert all(v.shape == (500, 3) and v.flags.c_contiguous for v in poses.values())
    for robot in (compiled, reference):
        assert (robot._core.fk_acc(poses["q"], poses["qd"], poses["qdd"])[-1] == OK).all()
        assert (robot._core.ik(poses["p"])[-1] == OK).all()


@pytest.mark.parametrize("argv", [["--n", "0"], ["--repeats", "0"]])
def test_bad_sizes_are_rejected(capsys, argv):
    assert main(["bench", *argv]) == 2
    assert "must be at least 1" in capsys.readouterr().err
