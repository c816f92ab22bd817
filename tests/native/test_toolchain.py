"""The C toolchain (deltagen/native/toolchain.py): discovery errors name the compiler, a failed
compile carries the compiler's own text, two cffi modules build from two threads at once
without the working directory ever changing (cffi's own ``FFI.compile`` changes it, which
breaks the other threads), and gcc's -fstack-usage lines are read as gcc writes them
(checked against a frame whose size the test fixes: a local array)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
from helpers import GCC

from deltagen.native import toolchain
from deltagen.native.build import BuildError

needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed")


def _tiny_module(tmp_path: Path, name: str, scale: float):
    """A cffi module of one C function f(x) = scale * x + 1, built by the toolchain."""
    import cffi

    folder = tmp_path / name
    folder.mkdir()
    (folder / f"{name}.h").write_text(f"double {name}_f(double x);\n")
    (folder / f"{name}.c").write_text(
        f'#include "{name}.h"\ndouble {name}_f(double x) {{ return {scale!r} * x + 1.0; }}\n'
    )
    ffi = cffi.FFI()
    ffi.cdef(f"double {name}_f(double x);")
    so = toolchain.build_cffi(
        ffi,
        f"_toolchain_test_{name}_{os.getpid()}",
        f'#include "{name}.h"\n',
        [folder / f"{name}.c"],
        folder / "build",
        include_dirs=[folder],
        flags=["-std=c99", "-O2"],
    )
    module = toolchain.import_extension(f"_toolchain_test_{name}_{os.getpid()}", so)
    return getattr(module.lib, f"{name}_f")


@needs_gcc
def test_two_threads_build_two_modules_and_the_working_directory_never_moves(tmp_path):
    start = os.getcwd()
    seen: set[str] = set()
    stop = threading.Event()

    def watch():  # what another thread of the process sees meanwhile
        while not stop.is_set():
            seen.add(os.getcwd())

    results: dict = {}
    errors: list = []

    def build(name, scale):
        try:
            results[name] = _tiny_module(tmp_path, name, scale)
        except Exception as exc:  # reported below
            errors.append(exc)

    watcher = threading.Thread(target=watch)
    watcher.start()
    builders = [
        threading.Thread(target=build, args=("alpha", 2.0)),
        threading.Thread(target=build, args=("beta", -3.0)),
    ]
    for t in builders:
        t.start()
    for t in builders:
        t.join()
    stop.set()
    watcher.join()
    assert not errors, errors
    assert seen == {start}
    assert os.getcwd() == start
    assert results["alpha"](1.5) == 2.0 * 1.5 + 1.0
    assert results["beta"](1.5) == -3.0 * 1.5 + 1.0


def test_a_missing_compiler_is_named(tmp_path, monkeypatch):
    import cffi

    monkeypatch.setenv("CC", "/nonexistent/deltagen-cc")
    assert toolchain.host_compiler() == "/nonexistent/deltagen-cc"
    assert toolchain.find_compiler() is None
    (tmp_path / "x.c").write_text("int x(void) { return 1; }\n")
    ffi = cffi.FFI()
    ffi.cdef("int x(void);")
    with pytest.raises(BuildError, match="/nonexistent/deltagen-cc") as info:
        toolchain.build_cffi(ffi, "_toolchain_missing", "", [tmp_path / "x.c"], tmp_path / "b")
    assert "no C compiler" in str(info.value)


def test_cc_with_flags_is_found_by_its_program(monkeypatch):
    if GCC is None:
        pytest.skip("gcc is not installed")
    monkeypatch.setenv("CC", "gcc -m64")
    assert toolchain.find_compiler() == "gcc -m64"
    assert toolchain.host_command()[:2] == ["gcc", "-m64"]


def test_no_cross_compiler_on_an_empty_path(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert toolchain.cortex_m4_command() is None


@needs_gcc
def test_a_failed_compile_carries_the_compilers_own_text(tmp_path):
    import cffi

    (tmp_path / "broken.c").write_text("double broken(double x) { return x +; }\n")
    ffi = cffi.FFI()
    ffi.cdef("double broken(double x);")
    with pytest.raises(BuildError) as info:
        toolchain.build_cffi(
            ffi, "_toolchain_broken", "double broken(double x);\n", [tmp_path / "broken.c"],
            tmp_path / "build",
        )  # fmt: skip
    text = str(info.value)
    assert "failed (exit" in text
    assert "broken.c:1" in text  # gcc's own file:line of the error
    assert "error" in text


def test_stack_usage_lines_as_gcc_writes_them():
    text = "\n".join(
        [
            "kernels.c:12:5:deltagen_delta_fk\t208\tstatic",
            "kernels.c:40:5:deltagen_delta_ik\t4176\tdynamic,bounded",
            "eigen.c:9:13:hqr.constprop.0\t96\tstatic",  # a clone: no symbol has its name
            "not a stack line",
            "",
        ]
    )
    assert toolchain.parse_stack_usage(text) == {
        "deltagen_delta_fk": (208, "static"),
        "deltagen_delta_ik": (4176, "dynamic"),
    }


@needs_gcc
def test_stack_usage_of_a_frame_the_test_sizes(tmp_path):
    source = tmp_path / "frame.c"
    source.write_text(
        "void sink(double *block);\n"  # a call: not a leaf, so no red zone below the frame
        "double frame(int k) {\n"
        "    double block[512];\n"
        "    sink(block);\n"
        "    return block[k & 511];\n"
        "}\n"
    )
    command = [GCC, "-std=c99", "-O2", "-fstack-usage", "-c", str(source), "-o", "frame.o"]
    proc = toolchain.run(command, tmp_path, "frame.c")
    toolchain.require_success(proc, command, "compiling frame.c")
    usage = toolchain.stack_usage(tmp_path)
    nbytes, kind = usage["frame"]
    assert kind == "static"
    assert 512 * 8 <= nbytes <= 512 * 8 + 256  # the block, plus at most a few spills
