"""The C toolchain: the one place deltagen finds a compiler, chooses its flags, runs it and
reads what it reports -- for the build cache (native/build.py), the hand-written extension
(``load_extension``), the speed guards (native/vectorisation.py, native/instructions.py) and
the exported packages (apps/export.py).

* **Discovery**: :func:`host_command` is the interpreter's own shared-object command
  (``LDSHARED``, with ``$CC`` honoured as setuptools does), used for everything that is
  loaded into this process; :func:`find_compiler` is the plain compiler an exported package
  is measured with (``$CC``, else cc, gcc or clang on PATH); :data:`CORTEX_M4` the
  cross-compiler of the Cortex-M4F stack column.
* **Flags**: :func:`compile_flags` (the generated modules: IEEE kept, no -ffast-math) and
  :func:`extension_flags` (what an extension build of this interpreter adds).
* **Running**: :func:`run` starts one compiler as a subprocess with absolute paths, a
  timeout and no standard input; a missing compiler or a timeout is a :class:`BuildError`
  naming the compiler; :func:`require_success` turns a failed run into one holding the
  command and the compiler's own text.
* **cffi without chdir**: :func:`build_cffi` has cffi write the wrapper C only
  (``cffi.recompiler.make_c_source``) and compiles and links it here. cffi's own
  ``FFI.compile`` changes the process's working directory while it builds, which breaks
  every other thread that opens a relative path (tests/native/test_toolchain.py builds from two
  threads at once).
* **Stack use**: :func:`parse_stack_usage` reads gcc's ``-fstack-usage`` (``.su``) lines.
"""

from __future__ import annotations

import functools
import os
import platform
import re
import shlex
import sys
import sysconfig
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import subprocess

from deltagen.errors import DeltagenError
from deltagen.inputs import env_flag

# shutil, subprocess and cffi are imported where a compiler is sought or run: a warm load
# needs none of them

#: Seconds one compiler run may take before the build gives up.
TIMEOUT_S = 600
#: How much of a compiler's message an error keeps (its end: the first error is usually
#: repeated there, and the last lines say why it stopped).
MESSAGE_CHARS = 4000


class BuildError(DeltagenError, RuntimeError):
    """The C core could not be built or loaded; backend="reference" still works."""


# ---------------------------------------------------------------- discovery


def host_command() -> list[str]:
    """The interpreter's own shared-object link command (compile and link in one step):
    ``$LDSHARED`` or the interpreter's, its compiler replaced by ``$CC`` when that is set
    (as setuptools does)."""
    command = os.environ.get("LDSHARED") or sysconfig.get_config_var("LDSHARED") or "cc -shared"
    parts = shlex.split(command)
    cc = os.environ.get("CC")
    if cc:
        parts = shlex.split(cc) + parts[1:]
    return parts


def host_compiler() -> str:
    """The program :func:`host_command` runs (e.g. ``gcc``)."""
    return host_command()[0]


def compiler_identity() -> str:
    """What names the host compiler in a cache key."""
    return " ".join(host_command())


def find_compiler() -> str | None:
    """The plain C compiler a package is built with outside Python: ``$CC`` (its words: a
    command may carry flags), else cc, gcc or clang on PATH; None when there is none."""
    import shutil

    candidates = [os.environ["CC"]] if os.environ.get("CC") else ["cc", "gcc", "clang"]
    for name in candidates:
        words = shlex.split(name)
        if words and shutil.which(words[0]):
            return name
    return None


#: The Cortex-M4F cross-compiler and its target flags (the exported README's second stack
#: column).
CORTEX_M4 = (
    "arm-none-eabi-gcc",
    "-mcpu=cortex-m4",
    "-mthumb",
    "-mfloat-abi=hard",
    "-mfpu=fpv4-sp-d16",
)


def cortex_m4_command() -> list[str] | None:
    """:data:`CORTEX_M4` when arm-none-eabi-gcc is on PATH, else None."""
    import shutil

    return list(CORTEX_M4) if shutil.which(CORTEX_M4[0]) else None


def compiler_version(program: str | None = None) -> str:
    """The ``--version`` text of ``program`` (default: the host compiler,
    :func:`host_compiler`); BuildError when it cannot be run or fails."""
    command = [program or host_compiler(), "--version"]
    proc = run(command, None, shlex.join(command), timeout=60)
    require_success(proc, command, f"asking {command[0]} its version")
    return proc.stdout


def says_gcc(version: str) -> bool:
    """True when a compiler's ``--version`` text is gcc's."""
    text = version.lower()
    return "gcc" in text or "free software foundation" in text


def is_gcc() -> bool:
    """True when the host compiler (:func:`host_compiler`) says it is gcc (asked once per
    program name); False when it is another or cannot be asked."""
    return _is_gcc(host_compiler())


@functools.lru_cache(maxsize=8)
def _is_gcc(program: str) -> bool:
    try:
        return says_gcc(compiler_version(program))
    except (BuildError, OSError):  # not found, failed, timed out, not executable
        return False


# ---------------------------------------------------------------- flags


@functools.lru_cache(maxsize=1)
def vector_math_available() -> bool:
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
    """(extra compile args, libraries) of a generated module. IEEE semantics are kept (no
    -ffast-math): NaN for unreachable points must survive. -fno-math-errno lets sqrt
    vectorise. ``opt``: one of OPT_LEVELS."""
    if opt not in OPT_LEVELS:
        raise ValueError(f"opt must be one of {OPT_LEVELS}, not {opt!r}")
    args = ["-std=c99", opt, "-fno-math-errno", "-Wall", "-Wextra"]
    if opt == "-O2":
        args.append("-fvect-cost-model=dynamic")  # vectorised per-point loops (OPT_LEVELS)
    libraries = ["m"]
    if env_flag("DELTAGEN_NATIVE", True, "off: no -march=native, a module for any x86-64 CPU"):
        args.append("-march=native")
    if vector_math_available():
        args += ["-fopenmp-simd", f"-D{prefix.upper()}_VECTOR_MATH"]
        libraries.insert(0, "mvec")
    return args, libraries


def extension_flags() -> list[str]:
    """What an extension build of this interpreter adds to every compile (CCSHARED, -fwrapv,
    -DNDEBUG), minus -g: the module build, the lean extension, the packages compiled for a
    measurement and the native/ checks that compile a module as the build does."""
    return [*shlex.split(sysconfig.get_config_var("CCSHARED") or "-fPIC"), "-fwrapv", "-DNDEBUG"]


def python_include() -> str:
    """The folder of Python.h."""
    return sysconfig.get_paths()["include"]


# ---------------------------------------------------------------- running


def run(
    command: list[str], cwd: Path | str | None, what: str, timeout: float | None = None
) -> subprocess.CompletedProcess[str]:
    """Run one compiler (or a program it built) in ``cwd`` (None: this process's folder, for
    a run that reads and writes no file) with ``timeout`` seconds (default
    :data:`TIMEOUT_S`), output captured, no standard input: the CompletedProcess. BuildError
    naming the program when it is not found, or naming ``what`` when it took too long."""
    import subprocess

    limit = TIMEOUT_S if timeout is None else timeout
    try:
        return subprocess.run(
            command,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=limit,
            stdin=subprocess.DEVNULL,
        )
    except FileNotFoundError as exc:
        raise BuildError(
            f"no C compiler: {command[0]!r} was not found (set CC, or use "
            "backend='reference', which needs none)"
        ) from exc
    except subprocess.TimeoutExpired as exc:
        raise BuildError(f"compiling {what} took over {limit} s; gave up") from exc


def message(proc: subprocess.CompletedProcess[str]) -> str:
    """The compiler's own text of a run (its standard error, else its output), stripped."""
    return (proc.stderr or proc.stdout or "").strip()


def require_success(proc: subprocess.CompletedProcess[str], command: list[str], what: str) -> None:
    """BuildError "<what> failed (exit N)" with the command and the end of the compiler's own
    text when ``proc`` failed."""
    if proc.returncode != 0:
        raise BuildError(
            f"{what} failed (exit {proc.returncode}):\n"
            f"{shlex.join(command)}\n{message(proc)[-MESSAGE_CHARS:]}"
        )


def compile_and_link(
    sources: list[Path],
    so_path: Path,
    work: Path,
    flags: list[str],
    libraries: list[str],
    what: str,
    jobs: int = 1,
    prebuilt: Sequence[Callable[[], Path]] = (),
    extra: Callable[[Path], list[str]] | None = None,
) -> tuple[list[list[str]], list[str]]:
    """Compile ``sources`` to objects in ``work`` (``jobs`` compilers at once, largest source
    first) and link them into the shared object ``so_path`` with the host command, ``flags``
    and ``-l<libraries>``; returns (the compile commands in source order, the link command).
    ``prebuilt``: calls that each return an object file made elsewhere (e.g. the build
    cache's runtime objects, native/build.py), run in the same pool before the compiles and
    linked after the sources' objects, in their order. ``extra``: flags one source's compile
    adds (e.g. the build's vectoriser report of a module's unit). BuildError with the compiler's text
    when a unit does not compile (each distinct message once: an error in a shared preamble
    is every unit's) or the link fails."""
    base = host_command() + flags
    objects = {src: work / f"{src.stem}.o" for src in sources}
    commands = {
        src: base + (extra(src) if extra else []) + ["-c", str(src), "-o", str(objects[src])]
        for src in sources
    }
    # largest first: the longest compile starts at once, the small ones fill the gaps
    order = sorted(sources, key=lambda src: -src.stat().st_size)
    tasks = [*prebuilt, *(functools.partial(run, commands[src], work, src.name) for src in order)]
    if jobs > 1 and len(tasks) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            done = list(pool.map(lambda task: task(), tasks))
    else:
        done = [task() for task in tasks]
    made, done = done[: len(prebuilt)], done[len(prebuilt) :]
    procs = dict(zip(order, done))
    failed = [src for src in sources if procs[src].returncode != 0]
    if failed:
        first = procs[failed[0]]
        texts = "\n".join(dict.fromkeys(message(procs[src]) for src in failed))
        raise BuildError(
            f"compiling {what} failed (exit {first.returncode}):\n"
            f"{shlex.join(commands[failed[0]])}\n{texts[-MESSAGE_CHARS:]}"
        )
    link = (
        base
        + [str(objects[src]) for src in sources]
        + [str(obj) for obj in made]
        + ["-o", str(so_path)]
        + [f"-l{lib}" for lib in libraries]
    )
    require_success(run(link, work, so_path.name), link, f"linking {what}")
    return [commands[src] for src in sources], link


def write_cffi_wrapper(ffi: Any, module_name: str, preamble: str, path: Path) -> Path:
    """The cffi wrapper C of ``ffi`` (its cdef done) for the module ``module_name``, with
    ``preamble`` (the #includes of the real declarations) written to ``path``: cffi writes
    the C only, nothing is compiled and the working directory is left alone."""
    from cffi.recompiler import make_c_source

    make_c_source(ffi, module_name, preamble, str(path))
    return path


def build_cffi(
    ffi: Any,
    module_name: str,
    preamble: str,
    sources: Iterable[Path | str],
    out_dir: Path | str,
    include_dirs: Iterable[Path | str] = (),
    flags: Sequence[str] = (),
    libraries: Sequence[str] = ("m",),
) -> Path:
    """Build the cffi module ``module_name`` of ``ffi`` (its cdef done; ``preamble``: the C
    its wrapper starts with) and the C files ``sources`` into ``out_dir`` (created), with
    the host command, :func:`extension_flags`, ``flags``, ``-I<include_dirs>`` and the
    Python headers: the shared object's path. The working directory is never changed (the
    module doc), so threads may build at once; BuildError with the compiler's own text."""
    from importlib.machinery import EXTENSION_SUFFIXES

    out_dir = Path(out_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    wrapper = write_cffi_wrapper(ffi, module_name, preamble, out_dir / f"{module_name}.c")
    include = [f"-I{Path(d).resolve()}" for d in include_dirs] + [f"-I{python_include()}"]
    so_path = out_dir / f"{module_name}{EXTENSION_SUFFIXES[0]}"
    compile_and_link(
        [wrapper, *(Path(s).resolve() for s in sources)],
        so_path,
        out_dir,
        [*extension_flags(), *flags, *include],
        list(libraries),
        module_name,
    )
    return so_path


def import_extension(module_name: str, path: Path) -> ModuleType:
    """Import the extension module ``module_name`` from the shared object ``path``;
    BuildError naming the file when the dynamic loader refuses it."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    try:
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    except ImportError as exc:
        raise BuildError(
            f"the compiled core {path} does not load ({exc}); delete {path.parent} to rebuild it"
        ) from exc
    return module


# ---------------------------------------------------------------- stack use

#: One line of gcc's -fstack-usage output: ``file.c:LINE:COL:function<TAB>bytes<TAB>kind``,
#: kind static, dynamic or bounded ("dynamic,bounded" reads as dynamic). A function name that
#: is not a C identifier (a clone such as ``f.constprop.0``) is skipped: no symbol has it.
_STACK_LINE = re.compile(r".*:(\w+)\t(\d+)\t(\w+)")


def parse_stack_usage(text: str) -> dict[str, tuple[int, str]]:
    """{function: (bytes, kind)} of the lines of a ``.su`` file (gcc -fstack-usage); lines
    of another shape are skipped."""
    usage = {}
    for line in text.splitlines():
        found = _STACK_LINE.match(line)
        if found:
            usage[found.group(1)] = (int(found.group(2)), found.group(3))
    return usage


def stack_usage(folder: Path) -> dict[str, tuple[int, str]]:
    """:func:`parse_stack_usage` of every ``.su`` file in ``folder``."""
    usage: dict[str, tuple[int, str]] = {}
    for su in sorted(Path(folder).glob("*.su")):
        usage.update(parse_stack_usage(su.read_text()))
    return usage
