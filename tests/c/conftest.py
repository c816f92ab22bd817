"""Fixtures of the tests of the C on its own (tests/c/test_standalone*.py): a private copy of
generated/ and the runtime C, and objects compiled once per test run for each (file, flags)."""

from __future__ import annotations

import pytest
from helpers import private_sources, shared_object


@pytest.fixture(scope="module")
def source_dir(tmp_path_factory):
    """A private copy of generated/ and of the runtime C, so concurrent regeneration cannot
    race the tests."""
    return private_sources(tmp_path_factory.mktemp("generated"))


@pytest.fixture(scope="module")
def objects(source_dir):
    """``compile_object(name, flags)``: the object of ``source_dir/name`` compiled with
    ``flags`` (warning-free, else the test fails with the compiler's text), built once per
    test run for each distinct (file and the headers it includes, flags), whatever the test
    file or pytest-xdist worker that asks (helpers.shared_object): the tests share the
    compiles they have in common (one -O2 object is both compiled warning-free and read by
    nm; tests/codegen/test_render_stack.py reads the frame sizes of the strict -O2 ones)."""
    return lambda name, flags: shared_object(source_dir, name, flags)
