"""Shared fixtures: the three test geometries and their robots on both backends."""

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
if str(TESTS) not in sys.path:  # delta_oracles is importable under any --import-mode
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
