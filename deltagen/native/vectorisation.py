"""Which loops of a generated C module gcc vectorises, read from gcc's own report.

The batched kernels are fast because gcc turns their per-point loops into vector code; a
change to the generated C (or to the compiler) that stops it costs a factor of several in
speed while every result stays the same. This module makes that visible:

* The template (codegen/templates/source.c.j2) names the loops that must vectorise by a
  comment on their ``for`` line: ``/* loop: cos */``, ``/* loop: sin */``,
  ``/* loop: atan2 */`` (codegen/render.py atan2_loops) and ``/* loop: points */`` (the
  kinematics, one point per iteration). :func:`marked_loops`
  finds them and the kernel (top-level function) each belongs to.
* :func:`vector_report` compiles the module as the build does (native/build.py: the same
  flags from :func:`~deltagen.native.build.compile_flags`, one translation unit per kernel
  behind a ``#line`` directive so gcc names the module's own lines, the units in
  parallel) with ``-fopt-info-vec-optimized-missed`` added and the costly RTL passes that
  run after the vectoriser switched off (AFTER_VECTORISER), and returns gcc's remarks. gcc
  reports a vectorised loop as ``file:line:column: optimized: loop vectorized using N byte
  vectors`` at the line of its ``for`` (GCC manual, "Developer Options", -fopt-info).
  Reports are cached under the build cache, keyed by the unit's text, the flags and the
  compiler's version.
* :func:`build_report` reads the same remarks without a compile of its own where the
  module's build kept them (native/build.py vector_reports, with DELTAGEN_VECTOR_REPORTS
  on): the whole compile of each unit, every pass included.
* :func:`check` compares the two: every marked loop must have a "loop vectorized" remark;
  a kernel with no marked loop, or a marked loop that is not vectorised, is a problem
  unless the caller exempts it by name (with a reason), and an exemption that is not
  needed is a problem too, so the list stays exact.

Only gcc writes this report; :func:`unavailable` says why a check cannot run here.
"""

from __future__ import annotations

import hashlib
import platform
import re
import shlex
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path

from deltagen.native import build, toolchain
from deltagen.native import units as unit_split

#: the comment that names a loop the vectoriser must handle, on the loop's ``for`` line
MARKER = re.compile(r"^(?P<indent>\s*)for \(.*\{\s*/\* loop: (?P<role>[a-z0-9_]+) \*/\s*$")
_REMARK = re.compile(
    r"^(?P<file>[^:\n]+):(?P<line>\d+):(?P<column>\d+): (?P<kind>optimized|missed|note): "
    r"(?P<message>.*)$",
    re.MULTILINE,
)
_FUNCTION_NAME = re.compile(r"\b(\w+)\s*\(")
_PREFIX = re.compile(r"defined\((\w+)_VECTOR_MATH\)")
REPORT_FLAG = build.VECTOR_REPORT_FLAG
VECTORISED = "loop vectorized"
#: gcc's RTL passes that dominate the compile of a kernel (register allocation, combine,
#: CSE, copy propagation: 80-85 % of the CPU of a large unit at -O3), switched off for the
#: report: the vectoriser is a GIMPLE pass that runs before every RTL pass, so they cannot
#: change its remarks, and the object is thrown away (GCC manual, "Developer Options":
#: -fdisable-rtl-<pass>). A compiler that refuses them is asked again without them.
AFTER_VECTORISER = (
    "-fdisable-rtl-ira",
    "-fdisable-rtl-reload",
    "-fdisable-rtl-combine",
    "-fdisable-rtl-cse1",
    "-fdisable-rtl-cse2",
    "-fdisable-rtl-cprop1",
    "-fdisable-rtl-cprop2",
    "-fdisable-rtl-cprop3",
)


@dataclass(frozen=True)
class Loop:
    """A marked loop: its kernel (function name without the module's prefix), its role
    (the marker's word), the line of its ``for`` and of its closing brace (1-based)."""

    kernel: str
    role: str
    line: int
    end: int


@dataclass(frozen=True)
class Remark:
    line: int
    column: int
    kind: str  # "optimized" or "missed"
    message: str


def module_prefix(text: str) -> str:
    """The C prefix of a generated module (``deltagen_delta``), read from its
    ``<PREFIX>_VECTOR_MATH`` guard."""
    found = _PREFIX.search(text)
    if found is None:
        raise ValueError("not a generated module: no <PREFIX>_VECTOR_MATH guard")
    return found.group(1).lower()


def kernels(text: str, prefix: str) -> list[tuple[str, int, int]]:
    """(kernel name without ``prefix_``, first line, last line) of every top-level function
    definition of a generated module, in order (the layout build.split_units reads)."""
    units = unit_split.split_units(text)
    if units is None:
        raise ValueError("the module's layout is not one build.split_units recognises")
    out = []
    for first, lines in units[1]:
        name = _FUNCTION_NAME.search(lines[0])
        assert name is not None  # split_units starts a kernel at "name("
        short = name.group(1).removeprefix(prefix + "_")
        out.append((short, first, first + len(lines) - 1))
    return out


def marked_loops(text: str, prefix: str) -> list[Loop]:
    """Every loop carrying a ``/* loop: <role> */`` comment, with its kernel and extent."""
    lines = text.split("\n")
    spans = kernels(text, prefix)
    loops = []
    for i, line in enumerate(lines):
        found = MARKER.match(line)
        if not found:
            continue
        number = i + 1
        kernel = next((k for k, a, b in spans if a <= number <= b), None)
        if kernel is None:
            raise ValueError(f"line {number}: a marked loop outside every kernel")
        close = found.group("indent") + "}"
        end = next((j + 1 for j in range(i + 1, len(lines)) if lines[j] == close), None)
        if end is None:
            raise ValueError(f"line {number}: no closing brace at the loop's indentation")
        loops.append(Loop(kernel, found.group("role"), number, end))
    return loops


def unavailable() -> str | None:
    """Why gcc's vectoriser report cannot be had here (None when it can): the report is
    gcc's, and the flags and expectations are those of x86-64."""
    if platform.machine() not in ("x86_64", "AMD64"):
        return f"the vectorisation check covers x86-64 builds; this machine is {platform.machine()}"
    try:
        version = toolchain.compiler_version()
    except (toolchain.BuildError, OSError) as exc:  # not found, failed, timed out, not runnable
        return f"no C compiler to ask ({exc})"
    if not toolchain.says_gcc(version):
        return f"the compiler is not gcc ({version.splitlines()[0]!r}): no -fopt-info report"
    if not toolchain.vector_math_available():
        return "no libmvec here: the build compiles scalar cos/sin, which cannot vectorise"
    return None


def _report_command(prefix: str, directory: Path, opt: str) -> list[str]:
    args, _ = toolchain.compile_flags(prefix, opt)
    include = [f"-I{directory}", f"-I{build.runtime_dir()}"]
    # -fsyntax-only would stop before the optimisers run: compile to an object, discard it
    return toolchain.host_command() + toolchain.extension_flags() + args + include + [REPORT_FLAG]


def vector_report(
    text: str,
    source: str | Path,
    prefix: str | None = None,
    opt: str = "-O3",
    whole: bool = False,
    only: Collection[int] | None = None,
) -> list[Remark]:
    """gcc's vectoriser remarks (optimized and missed) on the lines of ``text``, the C of a
    generated module whose header and the files it includes are in ``source``'s folder
    (``source``: the module's path; only its folder and name are used), compiled one
    kernel per unit as native/build.py compiles it, without the RTL passes of
    AFTER_VECTORISER unless ``whole``; ``only``: the first lines of the kernels to compile
    (None: every kernel)."""
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    source = Path(source).resolve()
    prefix = prefix or module_prefix(text)
    units = unit_split.split_units(text)
    if units is None:
        raise ValueError(f"{source.name}: layout not recognised by build.split_units")
    preamble, pieces = units
    if only is not None:
        pieces = [piece for piece in pieces if piece[0] in only]
    command = _report_command(prefix, source.parent, opt)
    version = toolchain.compiler_version()
    # the headers a unit includes are compiled into it (the module's own; the runtime's,
    # whose inline functions run inside the kernels' loops): a changed header is a new
    # report, in a cache kept between runs as in a fresh one
    own = source.with_suffix(".h")
    headers = [own.name + "\0" + (own.read_text() if own.is_file() else "")]
    headers += [
        f.name + "\0" + f.read_text() for f in build.runtime_files([text]) if f.suffix == ".h"
    ]
    cache = build.usable_cache_dir() / "vector-reports"
    cache.mkdir(exist_ok=True)

    def one(piece) -> str:
        unit = unit_split._unit_text(source, preamble, piece)
        words = [unit, shlex.join(command), version, "whole" if whole else "cut", *headers]
        key = hashlib.sha256("\0".join(words).encode())
        stored = cache / f"{key.hexdigest()[:24]}.txt"
        if stored.is_file():
            return stored.read_text()
        with tempfile.TemporaryDirectory(prefix="deltagen-vec.") as work:
            path = Path(work) / f"{source.stem}.unit.c"
            path.write_text(unit)
            what = f"{source.name} (line {piece[0]}) for its vectoriser report"
            for cut in ((),) if whole else (AFTER_VECTORISER, ()):
                unit_command = [*command, *cut, "-c", str(path), "-o", str(Path(work) / "unit.o")]
                proc = toolchain.run(unit_command, work, what)
                if proc.returncode == 0:
                    break
            toolchain.require_success(proc, unit_command, f"compiling {what}")
        partial = stored.with_suffix(f".{id(piece)}.tmp")
        partial.write_text(proc.stderr)
        partial.replace(stored)  # whole or absent: a reader never sees half a report
        return proc.stderr

    order = sorted(pieces, key=lambda piece: -sum(map(len, piece[1])))  # largest first
    with ThreadPoolExecutor(max_workers=build._build_jobs()) as pool:
        outputs = list(pool.map(one, order))
    return parse(outputs, source.name)


def build_report(text: str, source: str | Path, prefix: str | None = None) -> list[Remark] | None:
    """gcc's vectoriser remarks on the lines of ``text``, the checked-in module
    ``source`` (generated/<name>.c, read by the caller), as the module's own build kept them
    (native/build.py :func:`~deltagen.native.build.vector_reports`: the module loaded through
    the build cache at -O3, built first when it is not there): the whole compile of each unit
    with the build's flags (split per kernel or as one unit, as the build chose), no compile
    of its own. None when the cache entry holds no report (built with
    DELTAGEN_VECTOR_REPORTS off) or not one per unit of ``text``."""
    source = Path(source).resolve()
    prefix = prefix or module_prefix(text)
    units = unit_split.split_units(text)
    if units is None:
        raise ValueError(f"{source.name}: layout not recognised by build.split_units")
    reports = build.vector_reports(source.stem, prefix, source.parent)
    split = {f"{source.stem}.unit{k:03d}.c" for k in range(len(units[1]))}
    if reports is None or set(reports) not in (split, {source.name}):  # split, or one unit
        return None
    return parse(list(reports.values()), source.name)


def parse(outputs: list[str], name: str) -> list[Remark]:
    """The remarks of gcc's -fopt-info texts ``outputs`` on the lines of the file ``name``
    (the module: a unit names it in its ``#line`` directives), without duplicates, sorted."""
    remarks = set()
    for output in outputs:
        for found in _REMARK.finditer(output):
            if Path(found.group("file")).name != name or found.group("kind") == "note":
                continue  # remarks on the runtime headers' inline functions
            remarks.add(
                Remark(
                    int(found.group("line")),
                    int(found.group("column")),
                    found.group("kind"),
                    found.group("message").strip(),
                )
            )
    return sorted(remarks, key=lambda r: (r.line, r.column, r.kind, r.message))


def check(
    text: str,
    remarks: list[Remark],
    prefix: str | None = None,
    exempt: Mapping[str, str] | None = None,
    used: set[str] | None = None,
) -> list[str]:
    """Problems of one module (empty: every kernel vectorises where it must). ``exempt``
    maps ``"<kernel>"`` or ``"<prefix>_<kernel>"`` (one module's kernel only) (a kernel
    with no marked loop: not a per-point kernel) or
    ``"<kernel>/<role>"`` (a marked loop gcc may leave scalar) to the reason; the keys this
    module needed are added to ``used`` (the caller reports keys no module needed). An
    exempt loop that is vectorised is a problem: its exemption is stale."""
    prefix = prefix or module_prefix(text)
    exempt = exempt or {}
    used = set() if used is None else used
    vectorised = {r.line for r in remarks if r.kind == "optimized" and VECTORISED in r.message}
    loops = marked_loops(text, prefix)
    problems = []
    for kernel, first, _ in kernels(text, prefix):
        if any(loop.kernel == kernel for loop in loops):
            continue
        qualified = f"{prefix}_{kernel}"  # one module's kernel, e.g. deltagen_hexapod_fk
        if kernel in exempt or qualified in exempt:
            used.add(kernel if kernel in exempt else qualified)
        else:
            problems.append(
                f"{prefix}_{kernel} (line {first}) has no loop marked `/* loop: ... */`: a "
                "batched kernel's per-point loop must carry the marker (the template "
                "source.c.j2 writes it), or the kernel must be exempted with a reason"
            )
    for loop in loops:
        key = f"{loop.kernel}/{loop.role}"
        name = f"{prefix}_{loop.kernel}"
        if loop.line in vectorised:
            if key in exempt:
                used.add(key)
                problems.append(
                    f"{name}: the {loop.role} loop at line {loop.line} is vectorised but "
                    f"exempted as {key!r} ({exempt[key]}): remove the stale exemption"
                )
            continue
        if key in exempt:
            used.add(key)
            continue
        reasons = [
            f"line {r.line}: {r.message}"
            for r in remarks
            if r.kind == "missed"
            and loop.line <= r.line <= loop.end
            and ("not vectorized" in r.message or "couldn't vectorize" in r.message)
        ]
        reasons = list(dict.fromkeys(reasons))[:4]
        problems.append(
            f"{name}: the {loop.role} loop at line {loop.line} is not vectorised"
            + (f" (gcc: {'; '.join(reasons)})" if reasons else " (gcc gave no reason)")
        )
    return problems
