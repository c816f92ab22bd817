"""Fixtures of the tests of the C on its own (tests/c/test_standalone*.py): a private copy of
generated/ and the runtime C, and objects compiled once per test file for each (file, flags)."""

from __future__ import annotations

import shutil

import pytest
from helpers import strict_gcc

from deltagen import paths


@pytest.fixture(scope="module")
def source_dir(tmp_path_factory):
    """A private copy of generated/ and of the runtime C, so concurrent regeneration cannot
    race the tests."""
    copy = tmp_path_factory.mktemp("generated")
    for path in paths.generated_dir().glob("*.[ch]"):
        shutil.copy(path, copy / path.name)
    for path in paths.runtime_dir().glob("deltagen_*.[ch]"):
        shutil.copy(path, copy / path.name)
    return copy


@pytest.fixture(scope="module")
def objects(source_dir):
    """``compile_object(name, flags)``: the object of ``source_dir/name`` compiled with
    ``flags`` (warning-free, else the test fails with the compiler's text), built once per
    module for each distinct (file, flags): the tests of a file share the compiles they have
    in common (one -O2 object is both compiled warning-free and read by nm)."""
    built = {}

    def compile_object(name, flags):
        key = (name, tuple(flags))
        if key not in built:
            obj = source_dir / f"{name[:-2]}.{len(built)}.o"
            strict_gcc([*flags, "-c", name, "-o", obj.name], cwd=source_dir)
            built[key] = obj
        return built[key]

    return compile_object
