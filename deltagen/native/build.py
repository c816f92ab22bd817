"""Build stage: compile a generated C module (and the runtime C it needs) into a cffi
extension module, cached on disk under a key of everything that shapes the binary. The
compiler, its flags and its runs are the toolchain's (native/toolchain.py); the split into
translation units is native/units.py; this module keeps the cache.

How the cache stays sound (tests/native/test_build_cache.py puts each point under faults):

* **One build per key at a time**, from threads and processes alike: a lock per key, a
  ``threading.Lock`` inside the process and an exclusive ``flock`` on a lock file across
  processes. The first caller builds; the others wait and then load its result.
* **No working-directory changes**: cffi only writes the wrapper C and the toolchain runs
  the compiler as subprocesses with absolute paths (toolchain.py: cffi's own ``compile``
  changes the process's working directory, which breaks other threads).
* **Verified artifacts**: a build happens in a private temporary folder; the shared object's
  size and SHA-256 go into a manifest next to it, and the folder is renamed into place in
  one atomic step. Before loading, the manifest is checked against the file: a truncated,
  empty, garbage or missing artifact is moved aside and rebuilt, never handed to the
  dynamic loader (a truncated ``.so`` kills a process with SIGBUS).
* **Clear errors**: a failed build raises :class:`BuildError` with the compiler's own error
  text; a successful build's warnings never reach the user's terminal. A cache path that is
  not a directory or is not writable gets an error naming the path.
* **Parallel translation units** (a new arm's cold load): a module's C is split at its
  kernels (native/units.py, tests/native/test_build_split.py); the units and cffi's wrapper
  compile to objects on every core the process may use (``os.sched_getaffinity``;
  ``DELTAGEN_BUILD_JOBS`` caps it), largest first, then link into one shared object. With
  one compiler at a time there is nothing to run in parallel, and the file compiles as one
  unit: the same bits (tests/native/test_build_split.py), 15-20 % less compiler CPU (the
  units each parse the preamble and headers again; CONTRIBUTING.md, "Where the suite's
  time goes").
* **The runtime compiled once**: each runtime .c a module needs (codegen/runtime/, e.g. the
  damped Newton IK, 2 s of gcc) is an object file of its own in the cache, keyed by its
  text, the runtime headers it reads, its flags and the compiler, built under the same lock,
  manifest and atomic rename as a module and linked into every module that needs it
  (tests/native/test_build_runtime.py). Its flags are the modules' own at that level
  (:func:`runtime_flags`); the one flag a module adds for itself, its ``-D<PREFIX>_VECTOR_MATH``,
  names a macro the runtime never reads, so the object's bits are the ones a per-module
  compile gave. A damaged object is rebuilt, never linked: the linked file is a copy
  checked against the manifest.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.machinery
import json
import os
import re
import shlex
import sys
import sysconfig
import threading
from pathlib import Path

from deltagen.inputs import env_flag, env_positive_int
from deltagen.native import toolchain
from deltagen.native.toolchain import OPT_LEVELS as OPT_LEVELS
from deltagen.native.toolchain import BuildError as BuildError
from deltagen.native.toolchain import compile_flags as compile_flags
from deltagen.native.toolchain import extension_flags as extension_flags
from deltagen.native.units import split_units as split_units
from deltagen.native.units import write_units
from deltagen.paths import cache_dir, generated_dir, runtime_dir

# cffi, shutil, tempfile and the toolchain's subprocess and concurrent.futures are imported
# where a build runs: a warm load needs none of them (25 ms of imports)

_LOADED: dict[str, object] = {}
_GUARD = threading.Lock()  # guards _KEY_LOCKS and _LOADED
_KEY_LOCKS: dict[str, threading.Lock] = {}
_MANIFEST = "manifest.json"

#: The host compiler's command (the toolchain's; the speed guards and tests read it here).
_compiler_command = toolchain.host_command
_vector_math_available = toolchain.vector_math_available


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
    return "".join(
        part for f, text in runtime.items() if f.suffix == ".h" for part in _CFFI_PART.findall(text)
    )


def usable_cache_dir() -> Path:
    """The build cache folder, absolute, created if needed; BuildError naming the path when
    it is not a directory or cannot be written."""
    root = cache_dir()
    source = "DELTAGEN_CACHE" if os.environ.get("DELTAGEN_CACHE") else "the build cache"
    if root.exists() and not root.is_dir():
        raise BuildError(
            f"{source} {root} is not a directory; point DELTAGEN_CACHE at a "
            "writable folder (backend='reference' needs no cache)"
        )
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BuildError(
            f"{source} {root} cannot be created ({exc.strerror}); point "
            "DELTAGEN_CACHE at a writable folder"
        ) from exc
    if not os.access(root, os.W_OK | os.X_OK):
        raise BuildError(
            f"{source} {root} is not writable; point DELTAGEN_CACHE at a "
            "writable folder (backend='reference' needs no cache)"
        )
    return root


def _build_jobs() -> int:
    """How many compilers run at once: the cores this process may use, at most
    DELTAGEN_BUILD_JOBS when that is set (a positive integer; anything else is an
    InputError, as for DELTAGEN_THREADS)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    jobs = env_positive_int(
        "DELTAGEN_BUILD_JOBS",
        "the compilers a build may run at once",
        "use every available core",
    )
    return max(1, cores) if jobs is None else min(max(1, cores), jobs)


def _module_inputs(
    base_name: str,
    prefix: str,
    directory: Path | None,
    opt: str = "-O3",
    split: bool = True,
    part: str = "all",
):
    """Everything that shapes the binary of <directory>/<base_name>.c, and the cache's
    module name keyed by it (``split``: the module's kernels compiled as separate units;
    ``part``: "all", or which part of a module built in parts the folder holds -- in the
    key and the name, so a part is never the module asked for as a whole)."""
    directory = Path(directory) if directory else generated_dir()
    files = {ext: directory / f"{base_name}{ext}" for ext in (".c", ".h", ".cdef.h")}
    for path in files.values():
        if not path.is_file():
            raise BuildError(f"generated source {path} is missing: run `deltagen generate`")
    texts = {ext: path.read_text() for ext, path in files.items()}
    runtime = {f: f.read_text() for f in runtime_files([texts[".c"], texts[".h"]])}
    args, libraries = compile_flags(prefix, opt)
    key_material = "\0".join(
        [
            texts[".c"],
            texts[".h"],
            texts[".cdef.h"],
            " ".join(args),
            " ".join(libraries),
            sys.version,
            sysconfig.get_platform(),
            _cffi_version(),
            toolchain.compiler_identity(),
            "units: per kernel" if split else "units: one",
        ]
        + [f.name + "\0" + text for f, text in runtime.items()]
        + ([] if part == "all" else [f"part: {part}"])
        # an entry that keeps gcc's remarks is its own entry: one built with the switch off
        # (the same bits) is never taken for it, in a cache kept between runs
        + (["vector reports: kept"] if _keeps_vector_reports(directory, opt) else [])
    )
    key = hashlib.sha256(key_material.encode()).hexdigest()[:16]
    label = "" if part == "all" else f"{part}_"
    return f"_deltagen_{base_name}_{label}{key}", texts, files, runtime, args, libraries


def is_built(
    base_name: str,
    prefix: str,
    directory: Path | None = None,
    opt: str = "-O3",
    split: bool | None = None,
    part: str = "all",
) -> bool:
    """True when :func:`load` would find the module compiled (loaded in this process or a
    verified artifact in the cache): loading it costs no compiler run. ``split`` None:
    split or as one unit, whichever is there."""
    if split is None:
        return any(is_built(base_name, prefix, directory, opt, s, part) for s in (True, False))
    return _available(_module_inputs(base_name, prefix, directory, opt, split, part)[0])


def _available(module_name: str) -> bool:
    """True when the module of a cache key is loaded in this process or a verified artifact
    in the cache."""
    with _GUARD:
        if module_name in _LOADED:
            return True
    target = usable_cache_dir() / module_name
    shared_object = target / f"{module_name}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
    return _verified(target, shared_object)


def load(
    base_name: str,
    prefix: str,
    directory: Path | None = None,
    opt: str = "-O3",
    split: bool | None = None,
    part: str = "all",
):
    """Return the compiled cffi module (``.ffi``, ``.lib``) of <directory>/<base_name>.c
    (generated/ by default) and the runtime C it includes (codegen/runtime/, compiled
    beside it), built with the optimisation level ``opt`` (OPT_LEVELS); ``split``: one
    translation unit per kernel, compiled in parallel (False: the file as one unit; the
    same results bit for bit, two cache entries; None: whichever of the two the cache
    holds, else split when more than one compiler may run at once); ``part``: which part
    of a module built in parts the folder holds ("all": the whole module), its own cache
    entry."""
    if split is None:  # either build serves: the one in the cache, else the one for the cores
        split = _build_jobs() > 1
        inputs = _module_inputs(base_name, prefix, directory, opt, split, part)
        if not _available(inputs[0]):
            other = _module_inputs(base_name, prefix, directory, opt, not split, part)
            if _available(other[0]):
                split, inputs = not split, other
    else:
        inputs = _module_inputs(base_name, prefix, directory, opt, split, part)
    module_name, texts, files, runtime, args, libraries = inputs
    return _load_cached(
        module_name,
        lambda target, so_name: _build(
            module_name, target, so_name, texts, files, runtime, args, libraries, split
        ),
    )


def _load_cached(module_name: str, build):
    """The module of a cache key: loaded in this process already, else imported from a
    verified artifact in the cache, else built first by ``build(target, so_name)`` -- one
    build per key at a time across threads and processes (the module doc)."""
    with _GUARD:
        if module_name in _LOADED:
            return _LOADED[module_name]
    with _locked_entry(module_name) as root:
        with _GUARD:  # another thread of this process loaded it while this one waited
            if module_name in _LOADED:
                return _LOADED[module_name]
        target = root / module_name
        shared_object = target / f"{module_name}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
        _ensure_built(target, shared_object, lambda t: build(t, shared_object.name))
        module = _import(module_name, shared_object)
    with _GUARD:
        _LOADED[module_name] = module
    return module


@contextlib.contextmanager
def _locked_entry(key: str):
    """Hold both locks of the cache key ``key`` (this process's thread lock, then the lock
    file across processes) and yield the cache root: the one place a cache entry is
    checked, built or read (the module doc, "One build per key at a time")."""
    with _GUARD:
        key_lock = _KEY_LOCKS.setdefault(key, threading.Lock())
    with key_lock:
        root = usable_cache_dir()
        with _process_lock(root, key):
            yield root


def _ensure_built(target: Path, artifact: Path, build) -> None:
    """With the entry's locks held (:func:`_locked_entry`): leave ``target`` alone when its
    manifest matches ``artifact``, else move it aside and ``build(target)`` it afresh -- a
    damaged entry is rebuilt, never used."""
    if not _verified(target, artifact):
        _discard(target)
        build(target)


def _import(module_name: str, shared_object: Path):
    return toolchain.import_extension(module_name, shared_object)


@contextlib.contextmanager
def _process_lock(root: Path, module_name: str):
    """Exclusive lock across processes for one cache key (a no-op where flock is missing)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: threads are still serialised by the key lock
        yield
        return
    locks = root / "locks"
    locks.mkdir(exist_ok=True)
    with open(locks / f"{module_name}.lock", "a+b") as handle:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _verified(target: Path, shared_object: Path) -> bool:
    """True when the artifact is complete: its manifest names its exact size and hash."""
    try:
        manifest = json.loads((target / _MANIFEST).read_text())
        return (
            shared_object.is_file()
            and shared_object.stat().st_size == manifest["size"]
            and _digest(shared_object) == manifest["sha256"]
        )
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _discard(target: Path) -> None:
    """Move a bad or partial artifact out of the way (a rename, so a process that still has
    it mapped keeps its pages), then delete it."""
    if not target.exists() and not target.is_symlink():
        return
    trash = target.with_name(f"{target.name}.bad.{os.getpid()}.{threading.get_ident()}")
    try:
        os.replace(target, trash)
    except OSError:
        trash = target
    if trash.is_dir() and not trash.is_symlink():
        import shutil

        shutil.rmtree(trash, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            trash.unlink()


def _cffi_version() -> str:
    # the C backend's version: cffi refuses to import with any other, and the backend is
    # loaded anyway with the module (importing cffi itself costs a warm load 9 ms)
    import _cffi_backend

    return _cffi_backend.__version__


def _build(
    module_name, target: Path, so_name: str, texts, files, runtime, args, libraries, split=True
) -> None:
    import shutil
    import tempfile

    import cffi

    work = Path(tempfile.mkdtemp(prefix=f"{module_name}.", dir=target.parent))
    try:
        for ext in (".c", ".h"):
            (work / files[ext].name).write_text(texts[ext])
        for f, text in runtime.items():  # copies: the compiled text is the hashed text
            (work / f.name).write_text(text)
        ffi = cffi.FFI()
        ffi.cdef(runtime_cdef(runtime) + texts[".cdef.h"])
        wrapper = toolchain.write_cffi_wrapper(
            ffi, module_name, f'#include "{files[".h"].name}"', work / f"{module_name}.c"
        )
        out = work / "out"
        out.mkdir()
        module_c = work / files[".c"].name
        sources = [wrapper, *write_units(module_c, texts[".c"], work, split)]
        flags = [*extension_flags(), *args, f"-I{work}", f"-I{toolchain.python_include()}"]
        opt = next(a for a in args if a in OPT_LEVELS)
        objects = [
            functools.partial(_runtime_object, f, opt, work) for f in runtime if f.suffix == ".c"
        ]
        units = set(sources[1:])
        keep = _keeps_vector_reports(files[".c"].parent, opt)

        def report(src: Path) -> list[str]:  # gcc appends to the file: a fresh one per unit
            return [f"{VECTOR_REPORT_FLAG}={out / (src.stem + VECTOR_REPORT_SUFFIX)}"]

        compiled, link = toolchain.compile_and_link(
            sources,
            out / so_name,
            work,
            flags,
            libraries,
            files[".c"].name,
            _build_jobs(),
            prebuilt=objects,
            extra=(lambda src: report(src) if src in units else []) if keep else None,
        )
        _publish(out / so_name, target, link, compiled)
    finally:
        shutil.rmtree(work, ignore_errors=True)


#: gcc's option that writes its vectoriser remarks (loops vectorised, and why others were
#: not) to a file (GCC manual, "Developer Options", -fopt-info); :data:`VECTOR_REPORT_SUFFIX`
#: names each unit's file beside the module in its cache entry
VECTOR_REPORT_FLAG = "-fopt-info-vec-optimized-missed"
VECTOR_REPORT_SUFFIX = ".vec.txt"


def _keeps_vector_reports(directory: Path, opt: str) -> bool:
    """True when a build of a module in ``directory`` at ``opt`` keeps gcc's vectoriser
    remarks of each of its units beside it (:func:`vector_reports`): a checked-in module
    (generated/) at -O3, built by gcc, with the switch DELTAGEN_VECTOR_REPORTS on (the test
    suite's conftest turns it on: tests/native/test_vectorisation.py reads them instead of
    compiling the module again). Off by default: the remarks change no bit of the module
    (tests/native/test_vectorisation.py) but cost gcc about a tenth more CPU (CONTRIBUTING.md,
    "Speed guards"). On, the module's cache key says so (:func:`_module_inputs`), so an entry
    built with it off, in a cache kept between runs, is not read as one without remarks."""
    if opt != "-O3" or Path(directory).resolve() != generated_dir().resolve():
        return False
    if not env_flag("DELTAGEN_VECTOR_REPORTS", False, "keep gcc's vectoriser remarks"):
        return False
    return toolchain.is_gcc()


def vector_reports(
    base_name: str, prefix: str, directory: Path | None = None, opt: str = "-O3"
) -> dict[str, str] | None:
    """{unit file name (<base_name>.unitNNN.c, or <base_name>.c built as one unit): gcc's
    vectoriser remarks} that the build of <directory>/<base_name>.c kept beside the module (:func:`_keeps_vector_reports`), the module loaded first as
    :func:`load` loads it (built when the cache has no verified entry); None when its cache
    entry holds none (built with the switch off, or not by gcc)."""
    module = load(base_name, prefix, directory, opt)
    # the entry of the module load found or built: split or one unit (load's ``split``)
    found = sorted(Path(module.__file__).parent.glob(f"*{VECTOR_REPORT_SUFFIX}"))
    if not found:
        return None
    return {f.name.removesuffix(VECTOR_REPORT_SUFFIX) + ".c": f.read_text() for f in found}


def runtime_flags(opt: str = "-O3") -> list[str]:
    """The compile flags of a runtime object at the level ``opt``: the generated modules'
    (:func:`compile_flags` with the runtime's own prefix, ``deltagen``, and what an extension
    build adds); the runtime's headers and Python's are added as ``-I``."""
    return [*extension_flags(), *compile_flags("deltagen", opt)[0]]


def _runtime_object(source: Path, opt: str, work: Path, flags: list[str] | None = None) -> Path:
    """The object file of the runtime C file ``source`` (codegen/runtime/) compiled with
    :func:`runtime_flags` at ``opt`` (or with ``flags``: e.g. the instruction counts' fixed
    -march, native/instructions.py), from the build cache (built first when missing or
    damaged, one build per key across threads and processes), copied into ``work`` under
    the name ``<stem>.o`` and checked against the manifest there (the module doc)."""
    import shutil

    text = source.read_text()
    headers = {f: f.read_text() for f in runtime_files([text]) if f.suffix == ".h"}
    flags = runtime_flags(opt) if flags is None else list(flags)
    include = toolchain.python_include()
    key_material = "\0".join(
        [
            text,
            " ".join(flags),
            include,
            sysconfig.get_platform(),
            toolchain.compiler_identity(),
        ]
        + [f.name + "\0" + header for f, header in headers.items()]
    )
    key = hashlib.sha256(key_material.encode()).hexdigest()[:16]
    entry = f"_deltagen_runtime_{source.stem}_{key}"
    object_name = f"{source.stem}.o"

    def build_object(target: Path) -> None:
        import tempfile

        scratch = Path(tempfile.mkdtemp(prefix=f"{entry}.", dir=target.parent))
        try:
            for f, content in [(source, text), *headers.items()]:
                (scratch / f.name).write_text(content)  # the compiled text is the hashed text
            out = scratch / "out"
            out.mkdir()
            command = [
                *toolchain.host_command(),
                *flags,
                f"-I{scratch}",
                f"-I{include}",
                "-c",
                str(scratch / source.name),
                "-o",
                str(out / object_name),
            ]
            proc = toolchain.run(command, scratch, source.name)
            toolchain.require_success(proc, command, f"compiling {source.name}")
            _publish(out / object_name, target, command)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)

    copy = work / object_name
    with _locked_entry(entry) as root:
        target = root / entry
        for _attempt in range(2):
            _ensure_built(target, target / object_name, build_object)
            shutil.copyfile(target / object_name, copy)
            if _verified(target, copy):  # the linked bytes are the manifest's
                return copy
            _discard(target)
    raise BuildError(f"the runtime object {target / object_name} changed while it was copied")


def _publish(built: Path, target: Path, command: list[str], compile_commands=()) -> None:
    """Write the manifest of ``built`` (size, SHA-256, the commands) beside it and rename its
    folder to ``target`` in one atomic step: a reader sees the whole folder or none."""
    manifest = {
        "size": built.stat().st_size,
        "sha256": _digest(built),
        "command": shlex.join(command),
    }
    if compile_commands:
        manifest["compile"] = [shlex.join(c) for c in compile_commands]
    (built.parent / _MANIFEST).write_text(json.dumps(manifest, indent=1))
    os.replace(built.parent, target)


def _numpy_include() -> tuple[str, str]:
    import numpy

    return numpy.get_include(), numpy.__version__


def _load_hand_written(source: Path, base_name: str, key_parts: list[str], compile_into):
    """Compile and import one hand-written C file, cached and verified like the generated
    modules: the module is named by a key over the file's text, ``key_parts`` (flags and
    the versions the build depends on), the interpreter, the platform and the compiler.
    ``compile_into(c_file, out, module_name, so_name)`` builds the file's copy in a private
    folder into ``out`` and returns (the built library, the command to record)."""
    text = Path(source).read_text()
    key_material = "\0".join(
        [text, *key_parts, sys.version, sysconfig.get_platform(), toolchain.compiler_identity()]
    )
    module_name = f"_{base_name}_{hashlib.sha256(key_material.encode()).hexdigest()[:16]}"
    name = Path(source).name

    def build(target: Path, so_name: str) -> None:
        import shutil
        import tempfile

        work = Path(tempfile.mkdtemp(prefix=f"{module_name}.", dir=target.parent))
        try:
            (work / name).write_text(text)  # the compiled text is the hashed text
            out = work / "out"
            out.mkdir()
            built, command = compile_into(work / name, out, module_name, so_name)
            _publish(built, target, command)
        finally:
            shutil.rmtree(work, ignore_errors=True)

    return _load_cached(module_name, build)


def load_extension(source: Path, base_name: str):
    """Compile and import a hand-written CPython extension (one .c file using Python.h and
    the numpy C API, e.g. native/lean_ext.c), cached and verified like the generated
    modules: the key covers its text, the flags, the interpreter, numpy and the compiler.
    The module's init function is named by the build (``-DDELTAGEN_LEAN_INIT=PyInit_<name>``
    and ``DELTAGEN_LEAN_NAME``), so each key's module has its own name. BuildError when
    it cannot be built (no compiler, no Python.h) or loaded."""
    numpy_include, numpy_version = _numpy_include()
    python_include = toolchain.python_include()
    args = ["-std=c99", "-O2", "-Wall", "-Wextra"]

    def compile_into(c_file: Path, out: Path, module_name: str, so_name: str):
        command = (
            toolchain.host_command()
            + extension_flags()
            + args
            + [
                f"-DDELTAGEN_LEAN_INIT=PyInit_{module_name}",
                f'-DDELTAGEN_LEAN_NAME="{module_name}"',
                f"-I{python_include}",
                f"-I{numpy_include}",
                str(c_file),
                "-o",
                str(out / so_name),
            ]
        )
        proc = toolchain.run(command, c_file.parent, c_file.name)
        toolchain.require_success(proc, command, f"compiling {c_file.name}")
        return out / so_name, command

    key = [" ".join(args), numpy_version, numpy_include, python_include]
    return _load_hand_written(source, base_name, key, compile_into)


def load_c_source(source: Path, base_name: str, cdef: str, prefix: str):
    """Compile and import one hand-written C file (no Python.h: a cffi module over the
    functions ``cdef`` declares, e.g. the benchmark's floor loops, apps/bench/trig_floor.c)
    with the generated modules' flags (:func:`compile_flags` of ``prefix``: the same
    -march, vector math and IEEE rules), cached and verified like them: the key covers the
    text, the cdef, the flags, the interpreter, cffi and the compiler. The module's
    ``.ffi`` / ``.lib``; BuildError when it cannot be built or loaded."""
    import cffi

    args, libraries = compile_flags(prefix)

    def compile_into(c_file: Path, out: Path, module_name: str, so_name: str):
        ffi = cffi.FFI()
        ffi.cdef(cdef)
        # the wrapper sees the declarations it wraps
        so_path = toolchain.build_cffi(
            ffi, module_name, cdef, [c_file], out, flags=args, libraries=libraries
        )
        if so_path.name != so_name:
            so_path = so_path.rename(so_path.with_name(so_name))
        return so_path, [*toolchain.host_command(), *args, c_file.name]

    key = [cdef, " ".join(args), " ".join(libraries), _cffi_version()]
    return _load_hand_written(source, base_name, key, compile_into)
