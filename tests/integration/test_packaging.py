"""The project's packaging habits: `python -m deltagen` runs the CLI, the version is written
once, and the optional `plot` extra fails with a clear message when matplotlib is absent."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import pytest
from helpers import REPO

import deltagen
from deltagen import cli
from deltagen.apps import plotting

ROOT = REPO


def test_python_m_deltagen_runs_the_cli():
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "deltagen",
            "fk",
            "default",
            "--backend",
            "reference",
            "0.1",
            "0.2",
            "0.3",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("p = [")
    done = subprocess.run(
        [sys.executable, "-m", "deltagen", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and "usage: deltagen" in done.stdout


def test_version_is_written_once():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in meta["project"]
    assert "version" in meta["project"]["dynamic"]
    assert meta["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "deltagen.__version__"}
    assert deltagen.__version__.count(".") == 2


def test_license_is_an_spdx_string_with_its_file():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"
    assert "MIT License" in (ROOT / "LICENSE").read_text()


def test_matplotlib_is_optional():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert not any(d.startswith("matplotlib") for d in meta["project"]["dependencies"])
    assert any(d.startswith("matplotlib") for d in meta["project"]["optional-dependencies"]["plot"])


@pytest.fixture
def no_matplotlib(monkeypatch):
    """Imports of matplotlib fail, as in an environment without the `plot` extra."""
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` -> ImportError


def test_pyplot_without_matplotlib_names_the_extra(no_matplotlib):
    with pytest.raises(ImportError, match=r"pip install 'deltagen\[plot\]'") as info:
        plotting.pyplot()
    assert str(info.value) == "matplotlib is needed for plots: pip install 'deltagen[plot]'"


def test_validate_without_matplotlib_says_so_before_the_run(no_matplotlib, tmp_path, capsys):
    rc = cli.main(
        [
            "validate",
            "--rate",
            "50",
            "--duration",
            "0.2",
            "--backend",
            "reference",
            "--quiet",
            "--out",
            str(tmp_path),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2
    assert (
        "deltagen validate: error: matplotlib is needed for plots: pip install "
        "'deltagen[plot]'" in err
    )
    assert "Traceback" not in err
    assert not (tmp_path / "validation.csv").exists()  # stopped before the work
    # --no-plot needs no matplotlib
    rc = cli.main(
        [
            "validate",
            "--rate",
            "50",
            "--duration",
            "0.2",
            "--backend",
            "reference",
            "--quiet",
            "--no-plot",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    assert (tmp_path / "validation.csv").exists()


def test_demo_without_matplotlib_says_so(no_matplotlib, tmp_path, capsys):
    rc = cli.main(["demo", "miskolc-pick-and-place", "--out", str(tmp_path)])
    assert rc == 2
    assert "matplotlib is needed for plots: pip install 'deltagen[plot]'" in capsys.readouterr().err
    # the lecture's table is text: it needs no matplotlib without --out
    assert cli.main(["demo", "lecture-scara"]) == 0


def test_ci_prints_the_slowest_tests():
    """`make test` (what .ci/run runs) prints pytest's slowest tests: --durations in the
    pytest options of pyproject.toml, which the Makefile's pytest command does not override,
    so each CI log records which tests dominate the suite's time."""
    import shlex

    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]
    durations = [a for a in shlex.split(options["ini_options"]["addopts"]) if "durations" in a]
    assert durations and int(durations[0].split("=")[1]) >= 10, durations
    makefile = (ROOT / "Makefile").read_text()
    assert "make test" in (ROOT / ".ci" / "run").read_text()
    assert "-p no:terminal" not in makefile
    assert "-o addopts" not in makefile and "--override-ini" not in makefile
