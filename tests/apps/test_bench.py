"""Smoke test of `deltagen bench` at a tiny size: it runs, exits 0 and names every
quantity it measures. No timing assertions (shared machines are noisy).

The comparison with roboticstoolbox-python / pinocchio (in the `test` extra, so CI has them;
optional for users, `deltagen[bench]`) is switched off in the command-line runs
(DELTAGEN_BENCH_ORACLES=0) and exercised on its own at a tiny size when a library is
importable."""

from __future__ import annotations

import importlib.util

import pytest

from deltagen.apps.bench import compare as bench_compare
from deltagen.apps.bench import peers, sections, timing
from deltagen.cli import main

QUANTITIES = ("fk", "fk_vel", "fk_acc", "jacobian", "ik")
SERIAL_QUANTITIES = ("fk", "frames", "jacobian", "jacobian_dot")
HAVE_ORACLE = any(importlib.util.find_spec(m) is not None for m in ("roboticstoolbox", "pinocchio"))


def _rows(text: str) -> dict[str, str]:
    """First cell of each table row -> the whole line."""
    rows = {}
    for line in text.splitlines():
        cells = (
            [c.strip() for c in line.strip().strip("|").split("|")] if "|" in line else line.split()
        )
        if cells and cells[0]:
            rows.setdefault(cells[0], line)
    return rows


@pytest.fixture(scope="module")
def _measurements():
    """{kwargs: sections.measure result} kept for the module (see measured_once)."""
    return {}


@pytest.fixture
def measured_once(monkeypatch, _measurements):
    """sections.measure run once per size for the module: the text and the markdown run
    below render (and write) the same measurement (each measured the whole bench, 12 s
    warm, before). Patched for the test that asks only, so no other test of the module
    gets a memoised measurement; {kwargs: result} of the runs."""
    measure = sections.measure

    def once(**kwargs):
        key = tuple(sorted(kwargs.items()))
        if key not in _measurements:
            _measurements[key] = measure(**kwargs)
        return _measurements[key]

    monkeypatch.setattr(sections, "measure", once)
    return _measurements


@pytest.mark.parametrize("markdown", [False, True], ids=["text", "markdown"])
def test_bench_runs_and_names_every_quantity(
    capsys, monkeypatch, markdown, tmp_path, measured_once
):
    monkeypatch.setenv("DELTAGEN_BENCH_ORACLES", "0")
    argv = ["bench", "--n", "2000", "--repeats", "2"] + (["--markdown"] if markdown else [])
    files = {k: tmp_path / f"bench.{k}" for k in ("json", "png")}
    readme = tmp_path / "README.md"
    readme.write_text("# x\n\n<!-- bench:begin -->\nold\n<!-- bench:end -->\n\ntail\n")
    if markdown:  # the files: JSON, PNG, the README section
        argv += ["--json", str(files["json"]), "--png", str(files["png"]), "--readme", str(readme)]
    assert main(argv) == 0
    assert len(measured_once) == 1  # the command measured through sections.measure
    out = capsys.readouterr().out
    if markdown:
        import json

        data = json.loads(files["json"].read_text())
        assert data["n"] == 2000 and data["markdown"].strip() == out.strip()
        # `bench --compare FILE` reads every measure it shows from such a file
        stored = bench_compare.from_json(files["json"])
        assert all(v is not None and v > 0 for v in stored.values()), stored
        assert data["throughput"]["fk"]["core"]["median"] > 0
        numeric = data["serial"]["ik"]["numeric"]["deltagen"]
        assert numeric["success"] == 1.0 and numeric["median_ns"] > 0
        assert data["serial"]["ik"]["numeric_7axis"]["deltagen"]["success"] == 1.0
        assert files["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        text = readme.read_text()
        assert "old" not in text and text.startswith("# x") and text.endswith("tail\n")
        assert out.strip() in text
    delta_part, _, serial_part = out.partition("Serial arm: puma560")
    assert serial_part, "no serial-arm section"
    # the other families' cores beside the rotary delta's, in the same run
    rows = ("rotary delta fk", "linear delta fk", "linear delta fk_acc", "tripod ik")
    rows += ("hexapod ik", "hexapod fk (Newton from home)", "5-axis xyzac_trt ik_all")
    for row in rows:
        assert row in serial_part, f"no row {row!r} of the other machine families"
    # the UR closed-form row: per-pose batched time against its 2 us target
    ur_row = next(line for line in serial_part.splitlines() if "ur5: all 8 branches" in line)
    assert "<= 2 " in ur_row
    rows = _rows(delta_part)
    for name in QUANTITIES:
        assert name in rows, f"no throughput row for {name}"
        # every column measured: the raw C kernel too (n/a when its symbol is not found)
        assert "n/a" not in rows[name], f"a column of {name} was not measured: {rows[name]}"
    for column in (
        "C kernel",
        "compiled _core",
        "compiled API",
        "reference _core",
        "reference API",
        "speedup _core",
        "speedup API",
        "target",
    ):
        assert column in out
    for call in (
        "robot.fk(q), q ndarray (3,)",
        "robot.fk(q), q list of 3 floats",
        "robot.ik(p), p ndarray (3,)",
        "robot.ik(p), p list of 3 floats",
        "robot._core.fk(q)",
        "robot._core.ik(p)",
    ):
        assert call in out
    for target in ("<= 12", "<= 16", "<= 20", "<= 30", "<= 1.5", "<= 0.6"):
        assert target in out
    for fact in (
        "CPU",
        "cores",
        "Python",
        "numpy",
        "C flags",
        "-O3",
        "ns per point",
        "us per call",
        "N = 2,000",
        "2 repeats",
        "agreement",
    ):
        assert fact in out
    assert "WARNING" not in out  # compiled and reference agree on the sampled poses
    if markdown:
        assert "|---|" in out
        assert any(line.startswith("| fk_acc |") for line in out.splitlines())

    # the serial arm (Puma560)
    rows = _rows(serial_part)
    for name in SERIAL_QUANTITIES:
        assert name in rows, f"no serial throughput row for {name}"
    for call in (
        "robot.fk(q), q ndarray (6,)",
        "robot.fk(q), q list of 6 floats",
        "robot.jacobian(q), q ndarray (6,)",
        "robot._core.fk(q), q (1, 6)",
        "robot._core.jacobian(q), q (1, 6)",
    ):
        assert call in serial_part
    for target in ("<= 30", "<= 50", "<= 0.6 ", "<= 0.5 "):
        assert target in serial_part
    for fact in (
        "ns per configuration",
        "us per call",
        "N = 2,000",
        "C kernel",
        "reference _core",
        "agreement",
        "DELTAGEN_BENCH_ORACLES=0",
    ):
        assert fact in serial_part
    assert "total bench time" in serial_part
    # all cores: threads=1 against the default thread count
    threads_part = serial_part.partition("All cores: threads=1 vs threads=")[2]
    assert threads_part, "no all-cores section"
    for name in ("delta fk", "puma560 fk", "puma560 jacobian"):
        assert any(line.strip("| ").startswith(name) for line in threads_part.splitlines()), name
    assert "speedup" in threads_part and "DELTAGEN_THREADS" in threads_part


def test_sampled_poses_are_valid_for_both_backends():
    import numpy as np

    from deltagen import DeltaRobot
    from deltagen.status import OK

    compiled, reference = DeltaRobot.default(), DeltaRobot.default(backend="reference")
    poses = sections.sample_poses(500, [compiled._core, reference._core], np.random.default_rng(0))
    assert poses["payload"].shape == (500,) and (poses["payload"] >= 0).all()
    assert all(
        v.shape == (500, 3) and v.flags.c_contiguous for k, v in poses.items() if k != "payload"
    )
    for robot in (compiled, reference):
        assert (robot._core.fk_acc(poses["q"], poses["qd"], poses["qdd"])[-1] == OK).all()
        assert (robot._core.ik(poses["p"])[-1] == OK).all()


@pytest.mark.parametrize("argv", [["--n", "0"], ["--repeats", "0"]])
def test_bad_sizes_are_rejected(capsys, argv):
    assert main(["bench", *argv]) == 2
    assert "must be at least 1" in capsys.readouterr().err


def test_serial_poses_are_within_limits():
    import numpy as np

    from deltagen.api.serial import SerialRobot

    robot = SerialRobot.load(sections.SERIAL_ROBOT)
    data = sections.sample_serial(300, robot, np.random.default_rng(0))
    assert data["q"].shape == data["qd"].shape == (300, robot.n)
    assert data["q"].flags.c_contiguous and robot.within_limits(data["q"]).all()


@pytest.fixture(scope="module")
def tiny_oracle_run():
    """The serial section with the rtb / pinocchio comparison at a tiny size, measured once
    for both renderings below (each measurement built the libraries' models anew)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(timing, "LATENCY_REPEAT_NS", 1_000_000)
        for name in ("RTB_PY_BATCH_N", "RTB_C_BATCH_N", "RTB_SE3_BATCH_N"):
            mp.setattr(peers, name, 50)
        return sections.run_serial(300, 1, oracles=True)


@pytest.mark.skipif(not HAVE_ORACLE, reason="neither roboticstoolbox-python nor pinocchio")
@pytest.mark.parametrize("markdown", [False, True], ids=["text", "markdown"])
def test_oracle_section_at_tiny_size(tiny_oracle_run, markdown):
    """The rtb / pinocchio comparison runs, pairs every library call with a deltagen call
    and finds them in agreement (sizes shrunk: this checks the wiring, not the speed)."""
    serial = tiny_oracle_run
    others = serial["oracles"]
    if not others["rows"]:
        pytest.skip("; ".join(others["absent"]))  # installed but not importable
    assert others["agreement"]
    for row in others["rows"]:
        assert row["lib"].median > 0 and row["dg"].median > 0
        assert row["dg_call"].startswith("robot.")
    for library, agree in others["agreement"].items():
        assert all(v <= peers.ORACLE_TOL for v in agree.values()), (library, agree)
    text = "\n".join(sections.render_serial(serial, 1, markdown))
    assert "vs other libraries" in text and "library / deltagen" in text
    assert "WARNING" not in text
    for library, label in (("roboticstoolbox-python", "rtb "), ("pinocchio", "pinocchio ")):
        measured = any(key.startswith(library) for key in others["agreement"])
        assert (
            label in text
            if measured
            else any(library in line and "not importable" in line for line in text.splitlines())
        )


def test_oracle_section_names_absent_libraries(monkeypatch):
    """Without the libraries the section says so and measures nothing."""
    import sys

    for module in ("roboticstoolbox", "pinocchio"):
        monkeypatch.setitem(sys.modules, module, None)  # import raises ImportError
    others = peers.measure(None, None, 1, rates=None)
    assert others["rows"] == [] and others["agreement"] == {}
    assert len(others["absent"]) == 2
    assert all("not importable" in t and "deltagen[bench]" in t for t in others["absent"])


def test_the_package_parser_is_the_commands(capsys):
    """apps.bench.add_parser declares exactly the options and help of `deltagen bench`, and
    run is what the command calls."""
    import argparse

    from deltagen.apps import bench as package

    assert main(["bench", "--help"]) == 0
    cli_help = capsys.readouterr().out
    sub = argparse.ArgumentParser(prog="deltagen").add_subparsers()
    parser = package.add_parser(sub)
    assert parser.format_help() == cli_help
    assert parser.parse_args(["--n", "5"]).func is package.run
