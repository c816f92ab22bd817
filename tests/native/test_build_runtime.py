"""The runtime C compiled once (native/build.py, "The runtime compiled once"): each runtime
.c file a module needs is an object file of its own in the build cache, keyed by its text,
the runtime headers it reads, its flags and the compiler, reused by every module that links
it, rebuilt (never linked) when damaged, and bit for bit the object a compile with the
module's own flags gives.

Tiny modules (one function over the runtime's Gauss elimination, codegen/runtime/
deltagen_linalg.c) stand in for robot cores; each test has a private cache, so each cold
build compiles the runtime afresh (a fraction of a second). The numbers are checked against
numpy's solver.
"""

from __future__ import annotations

import shutil
import threading

import numpy as np
import pytest

from deltagen import paths
from deltagen.native import build, toolchain

TINY_C = """#include "tiny.h"
#include "deltagen_linalg.h"
int tiny_gauss(double *A, int s, double *b) { return deltagen_gauss(A, (size_t)s, b); }
"""
TINY_H = "int tiny_gauss(double *A, int s, double *b);\n"


def _tiny(folder, tag: str):
    """A tiny module in ``folder`` whose text (a comment) is unique to ``tag``: its own
    module key, so loading it is a cold build of the module."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tiny.c").write_text(f"/* {tag} */\n" + TINY_C)
    (folder / "tiny.h").write_text(TINY_H)
    (folder / "tiny.cdef.h").write_text(TINY_H)
    return folder


def _solves(module) -> None:
    """The module's Gauss elimination solves a random 4 x 4 system as numpy does."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 4)) + 4 * np.eye(4)
    b = rng.normal(size=4)
    ffi = module.ffi
    a_c, b_c = np.ascontiguousarray(A.copy()), b.copy()
    status = module.lib.tiny_gauss(
        ffi.from_buffer("double[]", a_c), 4, ffi.from_buffer("double[]", b_c)
    )
    assert status == 0
    np.testing.assert_allclose(b_c, np.linalg.solve(A, b), rtol=1e-12, atol=1e-12)


def _objects(cache, stem="deltagen_linalg"):
    """The cache entries of the runtime objects of ``stem``."""
    return sorted(p for p in cache.iterdir() if p.name.startswith(f"_deltagen_runtime_{stem}_"))


def _object(cache):
    (entry,) = _objects(cache)
    return entry / "deltagen_linalg.o"


def test_one_object_is_linked_into_two_modules(tmp_path, private_cache):
    first = build.load("tiny", "tiny", _tiny(tmp_path / "a", "first"), opt="-O2")
    obj = _object(private_cache)
    stamp = obj.stat().st_ino, obj.stat().st_mtime_ns
    second = build.load("tiny", "tiny", _tiny(tmp_path / "b", "second"), opt="-O2")
    assert first is not second
    _solves(first)
    _solves(second)
    # the second module was linked from the first one's object: one entry, not rewritten
    assert _object(private_cache) == obj
    assert (obj.stat().st_ino, obj.stat().st_mtime_ns) == stamp
    assert build._verified(obj.parent, obj)
    modules = [p for p in private_cache.iterdir() if p.name.startswith("_deltagen_tiny_")]
    assert len(modules) == 2


def test_threads_building_two_modules_at_once_share_one_object(tmp_path, private_cache):
    barrier = threading.Barrier(3)
    modules, errors = [], []

    def worker(k):
        try:
            barrier.wait()
            modules.append(build.load("tiny", "tiny", _tiny(tmp_path / str(k), f"thread {k}")))
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert errors == []
    for module in modules:
        _solves(module)
    assert len(_objects(private_cache)) == 1
    assert not [p for p in private_cache.iterdir() if ".bad." in p.name]


def test_a_changed_level_or_flag_gives_another_object(tmp_path, private_cache, monkeypatch):
    build.load("tiny", "tiny", _tiny(tmp_path / "a", "levels"), opt="-O2")
    build.load("tiny", "tiny", _tiny(tmp_path / "a", "levels"), opt="-O3")
    assert len(_objects(private_cache)) == 2
    commands = [(e / "manifest.json").read_text() for e in _objects(private_cache)]
    assert sum("-O2" in c for c in commands) == 1 and sum("-O3" in c for c in commands) == 1
    # no -march=native: another flag, another object
    monkeypatch.setenv("DELTAGEN_NATIVE", "0")
    _solves(build.load("tiny", "tiny", _tiny(tmp_path / "b", "portable"), opt="-O2"))
    assert len(_objects(private_cache)) == 3


def test_a_changed_runtime_text_gives_another_object(tmp_path, private_cache, monkeypatch):
    _solves(build.load("tiny", "tiny", _tiny(tmp_path / "a", "text"), opt="-O2"))
    before = _object(private_cache)
    edited = tmp_path / "runtime"
    shutil.copytree(paths.runtime_dir(), edited)
    source = edited / "deltagen_linalg.c"
    source.write_text(source.read_text() + "\n/* an edit */\n")
    monkeypatch.setattr(build, "runtime_dir", lambda: edited)
    # the same module text: the runtime's text is in the module's key too
    _solves(build.load("tiny", "tiny", _tiny(tmp_path / "a", "text"), opt="-O2"))
    entries = _objects(private_cache)
    assert len(entries) == 2 and before.parent in entries
    # and in a header the .c reads
    header = edited / "deltagen_linalg.h"
    header.write_text(header.read_text() + "\n/* an edit */\n")
    _solves(build.load("tiny", "tiny", _tiny(tmp_path / "a", "text"), opt="-O2"))
    assert len(_objects(private_cache)) == 3


@pytest.mark.parametrize("fault", ["truncated", "garbage", "missing_object", "missing_manifest"])
def test_a_damaged_object_is_rebuilt_not_linked(tmp_path, private_cache, fault):
    build.load("tiny", "tiny", _tiny(tmp_path / "a", f"{fault} a"), opt="-O2")
    obj = _object(private_cache)
    good = obj.read_bytes()
    if fault == "truncated":
        obj.write_bytes(good[: len(good) // 3])
    elif fault == "garbage":
        obj.write_bytes(bytes(len(good)))
    elif fault == "missing_object":
        obj.unlink()
    else:
        (obj.parent / "manifest.json").unlink()
    # a damaged object links (a truncated one fails the link, zeros give a module without
    # the symbol) or is linked silently; the build must rebuild it instead
    module = build.load("tiny", "tiny", _tiny(tmp_path / "b", f"{fault} b"), opt="-O2")
    _solves(module)
    rebuilt = _object(private_cache)
    assert build._verified(rebuilt.parent, rebuilt)
    assert rebuilt.read_bytes() == good  # the compiler is deterministic: the same object


@pytest.mark.parametrize("opt", build.OPT_LEVELS)
def test_the_object_is_the_per_module_compile_bit_for_bit(tmp_path, private_cache, opt):
    """The shared object's flags leave out the module's own ``-D<PREFIX>_VECTOR_MATH``
    (build.runtime_flags): the runtime reads no module's macro, so its object is the one a
    compile with the module's full flags gives, byte for byte (the modules' bits unchanged)."""
    build.load("tiny", "tiny", _tiny(tmp_path / "a", f"bits {opt}"), opt=opt)
    work = tmp_path / "by_hand"
    shutil.copytree(paths.runtime_dir(), work)
    args, _ = build.compile_flags("tiny", opt)
    command = [
        *toolchain.host_command(),
        *build.extension_flags(),
        *args,
        f"-I{work}",
        f"-I{toolchain.python_include()}",
        "-c",
        str(work / "deltagen_linalg.c"),
        "-o",
        str(work / "by_hand.o"),
    ]
    proc = toolchain.run(command, work, "deltagen_linalg.c")
    toolchain.require_success(proc, command, "compiling deltagen_linalg.c by hand")
    assert (work / "by_hand.o").read_bytes() == _object(private_cache).read_bytes()


def test_a_runtime_object_that_does_not_compile_names_the_file(
    tmp_path, private_cache, monkeypatch
):
    edited = tmp_path / "runtime"
    shutil.copytree(paths.runtime_dir(), edited)
    source = edited / "deltagen_linalg.c"
    source.write_text(source.read_text() + "\nthis is not C;\n")
    monkeypatch.setattr(build, "runtime_dir", lambda: edited)
    with pytest.raises(build.BuildError, match="deltagen_linalg.c") as info:
        build.load("tiny", "tiny", _tiny(tmp_path / "a", "broken"), opt="-O2")
    assert "this is not C" in str(info.value) or "error" in str(info.value)
    assert _objects(private_cache) == []  # nothing half-written published


def test_an_object_that_changes_while_copied_is_rebuilt_not_linked(
    tmp_path, private_cache, monkeypatch
):
    """The entry verifies, then its bytes change before the copy the link reads is taken
    (another process truncating it, say): the copy fails its manifest check, so the entry
    is moved aside and rebuilt under the same locks, and the module links the rebuilt
    object (native/build.py, "The runtime compiled once": the linked file is a copy
    checked against the manifest)."""
    build.load("tiny", "tiny", _tiny(tmp_path / "a", "copied a"), opt="-O2")
    good = _object(private_cache).read_bytes()
    copyfile = shutil.copyfile
    damaged = []

    def copy_after_damage(src, dst, *args, **kwargs):
        if str(src).endswith("deltagen_linalg.o") and not damaged:
            damaged.append(src)
            with open(src, "r+b") as f:  # the entry's own file, after it verified
                f.truncate(len(good) // 3)
        return copyfile(src, dst, *args, **kwargs)

    monkeypatch.setattr(shutil, "copyfile", copy_after_damage)
    module = build.load("tiny", "tiny", _tiny(tmp_path / "b", "copied b"), opt="-O2")
    assert len(damaged) == 1  # the damage happened, inside the build of module b
    _solves(module)
    rebuilt = _object(private_cache)
    assert build._verified(rebuilt.parent, rebuilt)
    assert rebuilt.read_bytes() == good


# builds a tiny module over the runtime in a subprocess (the cache from DELTAGEN_CACHE)
RUNTIME_LOADER = """
import sys
from deltagen.native import build
module = build.load("tiny", "tiny", sys.argv[1], opt="-O2")
print(module.lib.tiny_gauss)
"""


def test_processes_building_two_modules_at_once_share_one_object(tmp_path, private_cache):
    """Two processes each cold-build their own module at once; both need the runtime
    object: one builds it under the lock file, the other waits and links it (the module
    doc, "One build per key at a time")."""
    import os
    import subprocess
    import sys

    folders = [_tiny(tmp_path / str(k), f"process {k}") for k in range(2)]
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", RUNTIME_LOADER, str(folder)],
            env=dict(os.environ, DELTAGEN_CACHE=str(private_cache)),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for folder in folders
    ]
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err[-2000:]
        assert "tiny_gauss" in out
    (entry,) = _objects(private_cache)
    assert build._verified(entry, entry / "deltagen_linalg.o")
    assert not [p for p in private_cache.iterdir() if ".bad." in p.name]
    for folder in folders:  # and each module solves, loaded here from the cache
        _solves(build.load("tiny", "tiny", folder, opt="-O2"))
