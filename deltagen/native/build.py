"""Build stage: cffi (API mode) compiles checked-in generated C into an extension module,
cached on disk under a key of the sources, the compiler flags and the interpreter, so a
changed source never loads a stale module."""

from __future__ import annotations

import ctypes.util
import hashlib
import importlib.machinery
import importlib.util
import os
import platform
import re
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

from deltagen.errors import DeltagenError
from deltagen.paths import cache_dir, generated_dir, runtime_dir

_LOADED: dict[str, object] = {}


class BuildError(DeltagenError, RuntimeError):
    """The C core could not be compiled (no compiler?); backend="reference" still works."""


def _vector_math_available() -> bool:
    return (
        sys.platform.startswith("linux")
        and platform.machine() in ("x86_64", "AMD64")
        and ctypes.util.find_library("mvec") is not None
    )


def compile_flags(prefix: str) -> tuple[list[str], list[str]]:
    """(extra compile args, libraries). IEEE semantics are kept (no -ffast-math): NaN for
    unreachable points must survive. -fno-math-errno lets sqrt vectorise."""
    args = ["-std=c99", "-O3", "-fno-math-errno", "-Wall", "-Wextra"]
    libraries = ["m"]
    if os.environ.get("DELTAGEN_NATIVE", "1") != "0":
        args.append("-march=native")
    if _vector_math_available():
        args += ["-fopenmp-simd", f"-D{prefix.upper()}_VECTOR_MATH"]
        libraries.insert(0, "mvec")
    return args, libraries


_INCLUDE = re.compile(r'^\s*#\s*include\s+"([A-Za-z0-9_]+\.h)"', re.MULTILINE)
_CFFI_PART = re.compile(r"/\* cffi: begin[^*]*\*/(.*?)/\* cffi: end \*/", re.DOTALL)


def runtime_files(texts) -> list[Path]:
    """The runtime headers (codegen/runtime/) that the given C texts include, directly or
    through other runtime files, each followed by its .c when it has one."""
    directory = runtime_dir()
    found: list[Path] = []
    pending = list(texts)
    while pending:
        for name in _INCLUDE.findall(pending.pop()):
            header = directory / name
            if header.is_file() and header not in found:
                found.append(header)
                pending.append(header.read_text())
                source = header.with_suffix(".c")
                if source.is_file():
                    found.append(source)
                    pending.append(source.read_text())
    return found


def runtime_cdef(runtime: dict) -> str:
    """The declarations cffi needs from the runtime headers ({path: text}): the part of each
    between its ``cffi: begin`` and ``cffi: end`` comments (types declared once, in C)."""
    return "".join(part for f, text in runtime.items() if f.suffix == ".h"
                   for part in _CFFI_PART.findall(text))


def load(base_name: str, prefix: str, directory: Path | None = None):
    """Return the compiled cffi module (``.ffi``, ``.lib``) of generated/<base_name>.c and
    the runtime C it includes (codegen/runtime/, compiled beside it)."""
    directory = Path(directory) if directory else generated_dir()
    files = {ext: directory / f"{base_name}{ext}" for ext in (".c", ".h", ".cdef.h")}
    for path in files.values():
        if not path.is_file():
            raise BuildError(f"generated source {path} is missing: run `deltagen generate`")
    texts = {ext: path.read_text() for ext, path in files.items()}
    runtime = {f: f.read_text() for f in runtime_files([texts[".c"], texts[".h"]])}
    args, libraries = compile_flags(prefix)
    key_material = "\0".join(
        [texts[".c"], texts[".h"], texts[".cdef.h"], *(f.name + text for f, text in runtime.items()),
         " ".join(args), " ".join(libraries), sys.version, sysconfig.get_platform(),
         _cffi_version()]
    )
    key = hashlib.sha256(key_material.encode()).hexdigest()[:16]
    module_name = f"_deltagen_{base_name}_{key}"
    if module_name in _LOADED:
        return _LOADED[module_name]
    target = cache_dir() / module_name
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    built = target / f"{module_name}{suffix}"
    if not built.is_file():
        _compile(module_name, target, texts, files[".c"].name, files[".h"].name, runtime,
                 args, libraries)
    spec = importlib.util.spec_from_file_location(module_name, built)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    _LOADED[module_name] = module
    return module


def _cffi_version() -> str:
    import cffi

    return cffi.__version__


def _compile(module_name, target: Path, texts, c_name, h_name, runtime, args, libraries) -> None:
    import cffi

    target.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"{module_name}.", dir=target.parent))
    try:
        (work / c_name).write_text(texts[".c"])
        (work / h_name).write_text(texts[".h"])
        for f in runtime:  # copies: the compiled text is the hashed text
            (work / f.name).write_text(runtime[f])
        ffi = cffi.FFI()
        ffi.cdef(runtime_cdef(runtime) + texts[".cdef.h"])
        ffi.set_source(
            module_name,
            f'#include "{h_name}"',
            sources=[str(work / c_name), *(str(work / f.name) for f in runtime if f.suffix == ".c")],
            include_dirs=[str(work)],
            extra_compile_args=args,
            libraries=libraries,
        )
        try:
            built = ffi.compile(tmpdir=str(work), verbose=False)
        except Exception as exc:  # distutils/setuptools raise several types
            raise BuildError(
                f"compiling the C core failed ({exc}); is a C compiler installed? "
                "backend='reference' works without one"
            ) from exc
        final = work / "out"
        final.mkdir()
        shutil.move(built, final / Path(built).name)
        try:
            os.rename(final, target)
        except OSError:
            if not target.is_dir():  # lost a race to another process: theirs is as good
                raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
