"""`deltagen bench --compare REF`: this tree's batched throughput beside a stored
`bench --json` run (fast) and beside a git commit (slow: the commit's modules are built in
a worktree of their own). No timing is asserted: the tests check that every measure is
measured on each side, that the ratio column is this / ref, and the errors."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest

from deltagen.apps.bench import compare as bench_compare
from deltagen.cli import main

SMALL = ["--n", "300", "--repeats", "1", "--rounds", "1"]


def _stored_run(path, delta_ns=10.0, arm_ns=100.0):
    """A `bench --json` file's shape (apps/bench/report.plain), the parts --compare reads."""
    stat = lambda v: {"median": v, "min": v, "max": v, "values": [v]}  # noqa: E731
    data = {
        "n": 1000,
        "throughput": {
            q: {"core": stat(1.0), "api": stat(delta_ns)}
            for q in ("fk", "fk_vel", "fk_acc", "jacobian", "ik", "inverse_dynamics")
        },
        "serial": {
            "throughput": {
                q: {"core": stat(1.0), "api": stat(arm_ns)}
                for q in ("fk", "frames", "jacobian", "jacobian_dot", "inverse_dynamics")
            }
        },
    }
    path.write_text(json.dumps(data))
    return path


def _table(out: str) -> dict[str, list[str]]:
    rows = {}
    for line in out.splitlines():
        cells = line.split()
        if len(cells) == 5 and cells[0] in ("delta", "puma560"):
            rows[f"{cells[0]} {cells[1]}"] = cells[2:]
    return rows


def test_compare_with_a_stored_run(tmp_path, capsys):
    ref = _stored_run(tmp_path / "bench.json")
    assert main(["bench", "--compare", str(ref), *SMALL]) == 0
    out = capsys.readouterr().out
    assert f"ref: {ref} (stored run)" in out and "this/ref" in out
    rows = _table(out)
    assert set(rows) == set(bench_compare.MEASURES)
    for label, (ref_cell, this_cell, ratio) in rows.items():
        assert this_cell != "n/a", f"{label} was not measured on this tree"
        if label in ("puma560 mass_matrix", "puma560 forward_dynamics"):
            assert ref_cell == "n/a" and ratio == "n/a"  # not in the stored run
            continue
        expected = 10.0 if label.startswith("delta") else 100.0
        assert float(ref_cell) == expected
        assert float(ratio) == pytest.approx(float(this_cell) / expected, abs=0.006)


def test_stored_run_errors(tmp_path, capsys):
    missing = tmp_path / "none.json"
    assert main(["bench", "--compare", str(missing), *SMALL]) == 2
    assert "not a readable `deltagen bench --json` file" in capsys.readouterr().err
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"rows": []}))
    assert main(["bench", "--compare", str(other), *SMALL]) == 2
    assert "no 'throughput' section" in capsys.readouterr().err


def test_unknown_commit(capsys):
    if shutil.which("git") is None or not (bench_compare.this_tree() / ".git").exists():
        pytest.skip("this tree is not a git checkout")
    assert main(["bench", "--compare", "no-such-ref-anywhere", *SMALL]) == 2
    assert "git rev-parse" in capsys.readouterr().err


def test_render_marks_missing_cells():
    rows = {label: (None, None) for label in bench_compare.MEASURES}
    rows["delta fk"] = (20.0, 10.0)
    text = bench_compare.render(
        {"ref": "r", "this": "t", "n": 10, "repeats": 1, "rounds": 1, "rows": rows}
    )
    table = _table(text)
    assert table["delta fk"] == ["20.00", "10.00", "0.50"]
    assert table["delta ik"] == ["n/a", "n/a", "n/a"]


def _share_built_modules(tree, commit):
    """Hard-link this tree's compiled delta core and Puma 560 modules (what the probe loads,
    built here first) and the Puma's rendered part sources into the cache --compare gives
    the commit's worktree. A
    module's cache key covers everything that shapes its binary (native/build.py), so the
    worktree loads them only where the commit's generated/ and build flags equal this
    tree's (a clean checkout of HEAD); otherwise it builds its own, as in use."""
    import os

    from deltagen import DeltaRobot, SerialRobot
    from deltagen.native.build import usable_cache_dir

    DeltaRobot.default(backend="compiled").fk([[0.1, 0.2, 0.3]])
    SerialRobot.load("puma560", backend="compiled").mass_matrix([[0.0] * 6])
    cache = usable_cache_dir()
    ref_cache = cache / f"compare-{commit[:16]}"
    # the built modules (a complete one has its manifest) and the rendered C of the
    # Puma's parts (a complete folder has its .cdef.h) a cold load builds them from
    wanted = ("_deltagen_delta_kinematics_", "_deltagen_serial_puma560_", "_deltagen_lean_")
    entries = [e for e in cache.glob("_deltagen_*") if (e / "manifest.json").is_file()]
    entries += [e for e in cache.glob("sources/serial_puma560_*") if any(e.glob("*.cdef.h"))]
    for entry in entries:
        target = ref_cache / entry.relative_to(cache)
        if entry.name.startswith(wanted + ("serial_puma560_",)) and not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copytree(entry, target, copy_function=os.link)


@pytest.mark.slow
def test_compare_with_a_commit(capsys):
    """HEAD measured from a temporary worktree beside this tree: every measure on both
    sides, and the worktree is gone afterwards. The worktree's modules come from this
    tree's cache where their keys match (_share_built_modules): the comparison, not the
    build cache (tests/native/test_build_cache.py), is under test here."""
    tree = bench_compare.this_tree()
    if shutil.which("git") is None or not (tree / ".git").exists():
        pytest.skip("this tree is not a git checkout")
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=tree, capture_output=True, text=True, check=True
    ).stdout.strip()
    _share_built_modules(tree, commit)
    assert main(["bench", "--compare", "HEAD", *SMALL]) == 0
    out = capsys.readouterr().out
    assert f"ref: HEAD ({commit[:10]})" in out
    rows = _table(out)
    assert set(rows) == set(bench_compare.MEASURES)
    for label, cells in rows.items():
        assert "n/a" not in cells, (label, cells)
    listed = subprocess.run(
        ["git", "worktree", "list"], cwd=tree, capture_output=True, text=True
    ).stdout
    assert "deltagen-ref-" not in listed


def test_the_checked_in_run_is_readable():
    """docs/bench.json, written by an earlier version of `deltagen bench --json`, still gives
    every measure --compare shows (the record's format is unchanged)."""
    stored = bench_compare.from_json(bench_compare.this_tree() / "docs" / "bench.json")
    assert set(stored) == set(bench_compare.MEASURES)
    assert all(v is not None and v > 0 for v in stored.values()), stored
