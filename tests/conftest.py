"""Shared fixtures of every stage folder (tests/<stage>/test_*.py; plain helpers are in
tests/helpers.py): the three test geometries and their robots on both backends, the bundled
arms loaded once per session, the 7-axis arm, a private build cache."""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# CI must be reproducible: the same examples on every run (explore locally with
# HYPOTHESIS_PROFILE=explore).
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("explore", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

TESTS = Path(__file__).resolve().parent


def suite_cache_dir() -> Path:
    """The build cache of the test run, never the user's (~/.cache/deltagen or their own
    DELTAGEN_CACHE, which may hold modules of another deltagen or another CPU):
    $DELTAGEN_TEST_CACHE when set (e.g. a fresh folder in CI), else this checkout's own
    folder under the system's temporary directory, shared by the pytest-xdist workers and
    kept between runs (a module's key covers everything that shapes it, native/build.py)."""
    raw = os.environ.get("DELTAGEN_TEST_CACHE")
    if raw:
        return Path(os.path.abspath(os.path.expanduser(raw)))
    checkout = hashlib.sha256(str(TESTS.parent).encode()).hexdigest()[:12]
    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"deltagen-test-cache-{user}-{checkout}"


# Set before deltagen is imported, so nothing can resolve the user's cache first; every
# subprocess a test starts inherits it.
os.environ["DELTAGEN_CACHE"] = str(suite_cache_dir())
# pytest-xdist workers already keep every core busy: a build in one runs one compiler at a
# time, and so compiles its module as one unit (native/build.py: the bits of the split
# build, which tests/native/test_build_split.py builds; 15-20 % less compiler CPU)
_CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) >= (_CORES or 1):
    os.environ.setdefault("DELTAGEN_BUILD_JOBS", "1")
# the builds of the checked-in modules keep gcc's vectoriser remarks beside them (the same
# bits; tests/native/test_vectorisation.py reads them instead of compiling the module again)
os.environ.setdefault("DELTAGEN_VECTOR_REPORTS", "1")
if str(TESTS) not in sys.path:  # delta_oracles, helpers importable under any --import-mode
    sys.path.insert(0, str(TESTS))

from delta_oracles import GEOMETRIES  # noqa: E402

from deltagen import DeltaRobot  # noqa: E402 - after the sys.path set-up above

REPO = TESTS.parent


def pytest_addoption(parser):
    parser.addoption(
        "--update-baselines",
        action="store_true",
        default=False,
        help="rewrite tests/baselines/ from this run (as DELTAGEN_UPDATE_BASELINES=1 does) "
        "instead of comparing with it",
    )
    parser.addoption(
        "--update-generated",
        action="store_true",
        default=False,
        help="rewrite the stale files of generated/ from this run (as `deltagen generate` does, "
        "or DELTAGEN_UPDATE_GENERATED=1) instead of failing on them",
    )


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session", params=list(GEOMETRIES), ids=list(GEOMETRIES))
def geometry(request):
    """Each test geometry in turn (default, Klipper-like, irregular)."""
    return GEOMETRIES[request.param]


@pytest.fixture(scope="session")
def robot(geometry):
    """The compiled robot of :func:`geometry`."""
    return DeltaRobot.from_geometry(geometry, backend="compiled")


@pytest.fixture(scope="session")
def reference_robot(geometry):
    return DeltaRobot.from_geometry(geometry, backend="reference")


@pytest.fixture(scope="session")
def default_robot():
    return DeltaRobot.default()


@pytest.fixture(scope="session")
def default_reference_robot():
    return DeltaRobot.default(backend="reference")


@pytest.fixture
def rng(request):
    """A generator seeded by the test's name: reproducible, different per test."""
    seed = zlib.crc32(request.node.nodeid.encode())
    return np.random.default_rng(seed)


@pytest.fixture(scope="session")
def serial_arms():
    """``get(name, backend="compiled")``: a bundled arm, loaded once per session (and
    worker) whatever the test file that asks for it."""
    from deltagen import SerialRobot

    loaded = {}

    def get(name, backend="compiled"):
        if (name, backend) not in loaded:
            loaded[name, backend] = SerialRobot.load(name, backend=backend)
        return loaded[name, backend]

    return get


@pytest.fixture(scope="session")
def puma7():
    """The redundant 7-axis Puma of tests/helpers.py PUMA7_ROWS, compiled once."""
    from helpers import PUMA7_ROWS

    from deltagen import SerialRobot

    return SerialRobot.from_dh([dict(r) for r in PUMA7_ROWS], "standard", name="puma7_test")


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    """An empty build cache of this test's own (DELTAGEN_CACHE set for it and its
    subprocesses)."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("DELTAGEN_CACHE", str(folder))
    return folder


@pytest.fixture(scope="session")
def sanitizers(tmp_path_factory):
    """tests/helpers.py SANITIZE, after a probe program built and run with them (once per
    worker): skip, naming why, where the toolchain has no ASan/UBSan runtime."""
    import subprocess

    from helpers import GCC, SANITIZE

    if GCC is None:
        pytest.skip("gcc not installed")
    work = tmp_path_factory.mktemp("sanitizer_probe")
    (work / "probe.c").write_text("int main(void) { return 0; }\n")
    build = subprocess.run(
        [GCC, *SANITIZE, str(work / "probe.c"), "-o", str(work / "probe")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    if build.returncode != 0:
        pytest.skip(f"no sanitizer runtime: {build.stderr[-300:]}")
    run = subprocess.run([str(work / "probe")], capture_output=True, text=True, timeout=60)
    if run.returncode != 0 or run.stderr:
        pytest.skip(f"sanitized programs cannot run here: {run.stderr[-300:]}")
    return SANITIZE
