"""The translation-unit splitter of the build (native/build.py): a generated module's C split
at its top-level function definitions, one kernel per unit, each unit being the file's
preamble (includes, declarations, macros) and one kernel behind a ``#line`` directive, so a
compiler message names the module's own file and line. No unit sees another's code and no
flag changes: with FMA contraction off (-std=c99, no -ffast-math) a kernel gives the same
bits in its own unit as in the whole file (tests/native/test_build_split.py). A file whose layout
the splitter does not recognise (a ``static`` definition, a preprocessor line or other
file-scope code between kernels) is compiled as one unit.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

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
