"""Build stage: compile a generated C module (and the runtime C it needs) into a cffi
extension module, cached on disk under a key of everything that shapes the binary.

How the cache stays sound (tests/native/test_build_cache.py puts each point under faults):

* **One build per key at a time**, from threads and processes alike: a lock per key, a
  ``threading.Lock`` inside the process and an exclusive ``flock`` on a lock file across
  processes. The first caller builds; the others wait and then load its result.
* **No working-directory changes**: cffi only writes the wrapper C
  (``FFI.emit_c_code``); the compiler is run here as one subprocess with absolute paths
  (cffi's own ``compile`` changes the process's working directory, which breaks other
  threads).
* **Verified artifacts**: a build happens in a private temporary folder; the shared object's
  size and SHA-256 go into a manifest next to it, and the folder is renamed into place in
  one atomic step. Before loading, the manifest is checked against the file: a truncated,
  empty, garbage or missing artifact is moved aside and rebuilt, never handed to the
  dynamic loader (a truncated ``.so`` kills a process with SIGBUS).
* **Clear errors**: a failed build raises :class:`BuildError` with the compiler's own error
  text; a successful build's warnings never reach the user's terminal. A cache path that is
  not a directory or is not writable gets an error naming the path.
* **Parallel translation units** (a new arm's cold load): a module's C is split at build time
  at its top-level function definitions (one kernel per unit, :func:`split_units`), each
  unit being the file's preamble (includes, declarations, macros) and one kernel behind a
  ``#line`` directive, so a compiler message names the module's own file and line. The
  units, cffi's wrapper and the runtime .c files compile to objects on every core the
  process may use (``os.sched_getaffinity``; ``DELTAGEN_BUILD_JOBS`` caps it), largest
  first, then link into one shared object. No flag changes and no unit sees another's
  code: with FMA contraction off (-std=c99, no -ffast-math) a kernel gives the same bits
  in its own unit as in the whole file (tests/native/test_build_split.py). A file whose layout
  the splitter does not recognise (a ``static`` definition, a preprocessor line or other
  file-scope code between kernels) is compiled as one unit.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import re
import shlex
import sys
import sysconfig
import threading
from pathlib import Path

from deltagen.errors import DeltagenError
from deltagen.inputs import env_flag, env_positive_int
from deltagen.paths import cache_dir, generated_dir, runtime_dir

# cffi, shutil, subprocess, tempfile and concurrent.futures are imported where a build
# runs: a warm load needs none of them (25 ms of imports)

_LOADED: dict[str, object] = {}
_GUARD = threading.Lock()  # guards _KEY_LOCKS and _LOADED
_KEY_LOCKS: dict[str, threading.Lock] = {}
_MANIFEST = "manifest.json"
_BUILD_TIMEOUT_S = 600


class BuildError(DeltagenError, RuntimeError):
    """The C core could not be built or loaded; backend="reference" still works."""


@functools.lru_cache(maxsize=1)
def _vector_math_available() -> bool:
    """glibc's vector math library (libmvec) is present: asked once per process, first by
    loading it (the dynamic loader searches what ldconfig lists), else by
    ctypes.util.find_library, whose import and ldconfig run cost a warm load 15 ms."""
    if not (sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")):
        return False
    import ctypes

    try:
        ctypes.CDLL("libmvec.so.1")
        return True
    except OSError:
        import ctypes.util

        return ctypes.util.find_library("mvec") is not None


#: Optimisation levels a module may be built with: -O3 (checked-in modules, the default) and
#: -O2 (arm modules rendered at run time, native/serial.py: gcc 12 compiles the UR5's
#: kinematics module in 13 s of CPU instead of 17 s; their outputs were checked bit for bit
#: against -O3 -- fk, frames, Jacobian, its derivative, ik_all, ik_newton, the dynamics).
#: -O2 gets -fvect-cost-model=dynamic, -O3's model: gcc 12's -O2 default ("very-cheap")
#: leaves every per-point loop scalar (found by native/vectorisation.py); with it they
#: vectorise as at -O3, for 13 s of compile instead of 5 (frames and coriolis take most).
#: Without -ffast-math and with -std=c99, which turns FMA contraction off, neither level may
#: change a floating-point result; the vector cos/sin/atan2 of the `omp simd` loops are used
#: at both levels.
OPT_LEVELS = ("-O3", "-O2")


def compile_flags(prefix: str, opt: str = "-O3") -> tuple[list[str], list[str]]:
    """(extra compile args, libraries). IEEE semantics are kept (no -ffast-math): NaN for
    unreachable points must survive. -fno-math-errno lets sqrt vectorise. ``opt``: one of
    OPT_LEVELS."""
    if opt not in OPT_LEVELS:
        raise ValueError(f"opt must be one of {OPT_LEVELS}, not {opt!r}")
    args = ["-std=c99", opt, "-fno-math-errno", "-Wall", "-Wextra"]
    if opt == "-O2":
        args.append("-fvect-cost-model=dynamic")  # vectorised per-point loops (OPT_LEVELS)
    libraries = ["m"]
    if env_flag("DELTAGEN_NATIVE", True, "off: no -march=native, a module for any x86-64 CPU"):
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


#: a top-level function definition: the start of a kernel (generated C puts return type,
#: name and "(" at column 0 and indents everything inside a function)
_DEFINITION = re.compile(r"^(?!(?:static|extern|typedef)\b)[A-Za-z_][A-Za-z0-9_ *]*?\b\w+\s*\(")


def split_units(text: str) -> tuple[list[str], list[tuple[int, list[str]]]] | None:
    """The preamble of a C file (its lines before the first top-level function definition)
    and its kernels as (first line number, lines), each running to the next definition;
    None when the file's layout is not one the split can keep exact: no definition, a
    ``static`` one (invisible to the other units), a preprocessor line or other file-scope
    code at column 0 between the kernels (only definitions, ``{``/``}``, comments and
    blank lines may start there)."""
    lines = text.split("\n")
    starts = [i for i, line in enumerate(lines) if _DEFINITION.match(line)]
    if len(starts) < 2:
        return None
    in_comment = False
    for i in range(starts[0], len(lines)):
        line = lines[i]
        if in_comment:
            in_comment = "*/" not in line
            continue
        if not line or line[0] in " \t{}" or i in starts:
            continue
        if line.startswith("/*"):
            in_comment = "*/" not in line
            continue
        if line.startswith("//"):
            continue
        return None
    bounds = [*starts, len(lines)]
    kernels = [(start + 1, lines[start:end]) for start, end in zip(bounds, bounds[1:])]
    return lines[: starts[0]], kernels


def _unit_text(source: Path, preamble: list[str], kernel: tuple[int, list[str]]) -> str:
    """One translation unit: the preamble and one kernel, each behind a ``#line`` naming
    the whole file's path and line (so diagnostics read as they would for the whole file)."""
    name = json.dumps(str(source))  # a C string literal: quotes and backslashes escaped
    first, body = kernel
    return "\n".join([f"#line 1 {name}", *preamble, f"#line {first} {name}", *body]) + "\n"


def write_units(source: Path, text: str, work: Path, split: bool = True) -> list[Path]:
    """The translation units of the C file ``source`` (its ``text``) to compile: one per
    kernel (split_units), written into ``work`` behind ``#line``s naming ``source``; or
    ``source`` itself when ``split`` is False or the layout cannot be split."""
    units = split_units(text) if split else None
    if units is None:
        return [source]
    preamble, kernels = units
    written = []
    for k, kernel in enumerate(kernels):
        unit = work / f"{source.stem}.unit{k:03d}.c"
        unit.write_text(_unit_text(source, preamble, kernel))
        written.append(unit)
    return written


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
            _compiler_identity(),
            "units: per kernel" if split else "units: one",
        ]
        + [f.name + "\0" + text for f, text in runtime.items()]
        + ([] if part == "all" else [f"part: {part}"])
    )
    key = hashlib.sha256(key_material.encode()).hexdigest()[:16]
    label = "" if part == "all" else f"{part}_"
    return f"_deltagen_{base_name}_{label}{key}", texts, files, runtime, args, libraries


def is_built(
    base_name: str,
    prefix: str,
    directory: Path | None = None,
    opt: str = "-O3",
    split: bool = True,
    part: str = "all",
) -> bool:
    """True when :func:`load` would find the module compiled (loaded in this process or a
    verified artifact in the cache): loading it costs no compiler run."""
    module_name = _module_inputs(base_name, prefix, directory, opt, split, part)[0]
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
    split: bool = True,
    part: str = "all",
):
    """Return the compiled cffi module (``.ffi``, ``.lib``) of <directory>/<base_name>.c
    (generated/ by default) and the runtime C it includes (codegen/runtime/, compiled
    beside it), built with the optimisation level ``opt`` (OPT_LEVELS); ``split``: one
    translation unit per kernel, compiled in parallel (False: the file as one unit; the
    same results bit for bit, two cache entries); ``part``: which part of a module built
    in parts the folder holds ("all": the whole module), its own cache entry."""
    module_name, texts, files, runtime, args, libraries = _module_inputs(
        base_name, prefix, directory, opt, split, part
    )
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
        key_lock = _KEY_LOCKS.setdefault(module_name, threading.Lock())
    with key_lock:
        with _GUARD:
            if module_name in _LOADED:
                return _LOADED[module_name]
        root = usable_cache_dir()
        target = root / module_name
        shared_object = target / f"{module_name}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
        with _process_lock(root, module_name):
            if not _verified(target, shared_object):
                _discard(target)
                build(target, shared_object.name)
            module = _import(module_name, shared_object)
        with _GUARD:
            _LOADED[module_name] = module
        return module


def _import(module_name: str, shared_object: Path):
    spec = importlib.util.spec_from_file_location(module_name, shared_object)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except ImportError as exc:
        raise BuildError(
            f"the compiled core {shared_object} does not load ({exc}); delete "
            f"{shared_object.parent} to rebuild it"
        ) from exc
    return module


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


def extension_flags() -> list[str]:
    """What an extension build of this interpreter adds to every compile (CCSHARED, -fwrapv,
    -DNDEBUG), minus -g: the module build, the lean extension and the native/ checks that
    compile a module as the build does."""
    return [*shlex.split(sysconfig.get_config_var("CCSHARED") or "-fPIC"), "-fwrapv", "-DNDEBUG"]


def _compiler_command() -> list[str]:
    """The interpreter's own shared-object link command (compile and link in one step)."""
    command = os.environ.get("LDSHARED") or sysconfig.get_config_var("LDSHARED") or "cc -shared"
    parts = shlex.split(command)
    cc = os.environ.get("CC")
    if cc:  # honour CC like setuptools does
        parts = shlex.split(cc) + parts[1:]
    return parts


def _compiler_identity() -> str:
    return " ".join(_compiler_command())


def _run_compiler(command: list[str], work: Path, what: str):
    import subprocess

    try:
        return subprocess.run(
            command,
            cwd=work,
            capture_output=True,
            text=True,
            timeout=_BUILD_TIMEOUT_S,
            stdin=subprocess.DEVNULL,
        )
    except FileNotFoundError as exc:
        raise BuildError(
            f"no C compiler: {command[0]!r} was not found (set CC, or use "
            "backend='reference', which needs none)"
        ) from exc
    except subprocess.TimeoutExpired as exc:
        raise BuildError(f"compiling {what} took over {_BUILD_TIMEOUT_S} s; gave up") from exc


def _build(
    module_name, target: Path, so_name: str, texts, files, runtime, args, libraries, split=True
) -> None:
    import shutil
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    import cffi
    from cffi.recompiler import make_c_source

    work = Path(tempfile.mkdtemp(prefix=f"{module_name}.", dir=target.parent))
    try:
        for ext in (".c", ".h"):
            (work / files[ext].name).write_text(texts[ext])
        for f, text in runtime.items():  # copies: the compiled text is the hashed text
            (work / f.name).write_text(text)
        ffi = cffi.FFI()
        ffi.cdef(runtime_cdef(runtime) + texts[".cdef.h"])
        wrapper = work / f"{module_name}.c"
        # cffi writes the wrapper C only; the compiler runs below (no chdir, no printing)
        make_c_source(ffi, module_name, f'#include "{files[".h"].name}"', str(wrapper))
        out = work / "out"
        out.mkdir()
        include = [f"-I{work}", f"-I{sysconfig.get_paths()['include']}"]
        ccshared = extension_flags()
        module_c = work / files[".c"].name
        sources = [wrapper, *write_units(module_c, texts[".c"], work, split)]
        sources += [work / f.name for f in runtime if f.suffix == ".c"]
        objects = {src: work / f"{src.stem}.o" for src in sources}
        compiler = _compiler_command() + ccshared + args + include
        commands = {src: compiler + ["-c", str(src), "-o", str(objects[src])] for src in sources}
        # largest first: the longest compile starts at once, the small ones fill the gaps
        order = sorted(sources, key=lambda src: -src.stat().st_size)
        with ThreadPoolExecutor(max_workers=_build_jobs()) as pool:
            procs = dict(
                zip(
                    order,
                    pool.map(lambda src: _run_compiler(commands[src], work, src.name), order),
                )
            )
        failed = [src for src in sources if procs[src].returncode != 0]
        if failed:
            first = procs[failed[0]]
            # each distinct message once (an error in the preamble is every unit's)
            texts_failed = "\n".join(
                dict.fromkeys(
                    (procs[src].stderr or procs[src].stdout or "").strip() for src in failed
                )
            )
            raise BuildError(
                f"compiling {files['.c'].name} failed (exit {first.returncode}):\n"
                f"{shlex.join(commands[failed[0]])}\n{texts_failed[-4000:]}"
            )
        link = (
            _compiler_command()
            + ccshared
            + args
            + [str(objects[src]) for src in sources]
            + ["-o", str(out / so_name)]
            + [f"-l{lib}" for lib in libraries]
        )
        proc = _run_compiler(link, work, so_name)
        if proc.returncode != 0:
            text = (proc.stderr or proc.stdout or "").strip()
            raise BuildError(
                f"linking {files['.c'].name} failed (exit {proc.returncode}):\n"
                f"{shlex.join(link)}\n{text[-4000:]}"
            )
        _publish(out / so_name, target, link, [commands[src] for src in sources])
    finally:
        shutil.rmtree(work, ignore_errors=True)


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


def load_extension(source: Path, base_name: str):
    """Compile and import a hand-written CPython extension (one .c file using Python.h and
    the numpy C API, e.g. native/lean_ext.c), cached and verified like the generated
    modules: the key covers its text, the flags, the interpreter, numpy and the compiler.
    The module's init function is named by the build (``-DDELTAGEN_LEAN_INIT=PyInit_<name>``
    and ``DELTAGEN_LEAN_NAME``), so each key's module has its own name. BuildError when
    it cannot be built (no compiler, no Python.h) or loaded."""
    text = Path(source).read_text()
    numpy_include, numpy_version = _numpy_include()
    python_include = sysconfig.get_paths()["include"]
    args = ["-std=c99", "-O2", "-Wall", "-Wextra"]
    key_material = "\0".join(
        [
            text,
            " ".join(args),
            sys.version,
            sysconfig.get_platform(),
            numpy_version,
            numpy_include,
            python_include,
            _compiler_identity(),
        ]
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
            command = (
                _compiler_command()
                + extension_flags()
                + args
                + [
                    f"-DDELTAGEN_LEAN_INIT=PyInit_{module_name}",
                    f'-DDELTAGEN_LEAN_NAME="{module_name}"',
                    f"-I{python_include}",
                    f"-I{numpy_include}",
                    str(work / name),
                    "-o",
                    str(out / so_name),
                ]
            )
            proc = _run_compiler(command, work, name)
            if proc.returncode != 0:
                message = (proc.stderr or proc.stdout or "").strip()
                raise BuildError(
                    f"compiling {name} failed (exit {proc.returncode}):\n"
                    f"{shlex.join(command)}\n{message[-4000:]}"
                )
            _publish(out / so_name, target, command)
        finally:
            shutil.rmtree(work, ignore_errors=True)

    return _load_cached(module_name, build)
