"""The line layout of generated C: every line at most :data:`WIDTH` characters.

SymPy prints each assignment on one line (some reach thousands of characters), and the
templates write each signature and doc line whole. :func:`wrap_c` breaks the long ones
where C allows a line break without a change of meaning: at a space, or after ``*``, ``,``
or ``(`` between tokens of code; at a space inside a comment; and with a backslash inside a
preprocessor directive. Only whitespace changes, so the compiled code, the operation counts
and the results are those of the unwrapped text. Continuation lines are indented 8 columns
deeper than the line they continue (comment lines: aligned under the comment's text).
"""

from __future__ import annotations

import re

#: Longest line the generated C has (the templates and the printer keep the text; this
#: module only breaks it).
WIDTH = 120

#: Where code breaks: at a space (the space is dropped); inside a run of code longer than
#: a line, after ``*``, ``,`` or ``(`` (never inside a comment's ``*/``).
_SPACE = re.compile(r"(?= +)")
_INNER_BREAK = re.compile(r"(?<=[*,(])(?!/)")
#: A function's signature (at column 0) breaks between its parameters.
_SIGNATURE = re.compile(r"^[A-Za-z_][\w *]*\(")
_PARAMETER = re.compile(r"(?<=, )")
#: A doc line of a port ("` * q         in,  n x axes: ...`"): continuations align after ": ".
_PORT_DOC = re.compile(r"^(\s*\*\s+\w+\s+(?:in|out|in/out)\b[^:]*:\s)")


def wrap_c(text: str, width: int = WIDTH) -> str:
    """``text`` (C source or header) with every line longer than ``width`` broken (module
    docstring); lines within the width are returned unchanged."""
    out = []
    in_comment = False
    for line in text.split("\n"):
        if len(line) > width and '"' not in line:
            out.extend(_wrap_line(line, width, in_comment))
        else:
            out.append(line)
        in_comment = _comment_open_after(line, in_comment)
    return "\n".join(out)


def _comment_open_after(line: str, in_comment: bool) -> bool:
    """Whether a block comment is still open at the end of ``line``."""
    position = 0
    while True:
        if in_comment:
            end = line.find("*/", position)
            if end < 0:
                return True
            in_comment, position = False, end + 2
        else:
            start = line.find("/*", position)
            if start < 0:
                return False
            in_comment, position = True, start + 2


def _wrap_line(line: str, width: int, in_comment: bool) -> list[str]:
    indent = line[: len(line) - len(line.lstrip())]
    body = line.strip()
    if body.startswith("#"):
        return _wrap_words(line, width, indent + " " * 8, suffix=" \\")
    if in_comment or body.startswith(("/*", "*")):
        star = indent + ("*" if body.startswith("*") else " *")
        found = _PORT_DOC.match(line)
        lead = star + " " * (len(found.group(1)) - len(star) if found else 4)
        return _wrap_words(line, width, lead)
    return _wrap_code(line, width, indent + " " * 8)


def _wrap_words(line: str, width: int, lead: str, suffix: str = "") -> list[str]:
    """Break at spaces (comments; preprocessor lines with ``suffix`` " \\")."""
    indent = line[: len(line) - len(line.lstrip())]
    words = line.strip().split(" ")
    lines, current = [], indent + words[0]
    for word in words[1:]:
        if word and len(current) + 1 + len(word) + len(suffix) > width and current.strip():
            lines.append(current + suffix)
            current = lead + word
        else:
            current = f"{current} {word}"
    lines.append(current)
    return lines


def _wrap_code(line: str, width: int, lead: str) -> list[str]:
    """Greedy break of one line of code: at spaces, and inside a run too long for a line."""
    indent = line[: len(line) - len(line.lstrip())]
    lines, current = [], indent
    first = _PARAMETER if _SIGNATURE.match(line) else _SPACE
    for piece in _pieces(line.strip(), width - len(lead), first):
        joined = current + piece if current.strip() else current + piece.lstrip()
        if len(joined) > width and current.strip():
            lines.append(current.rstrip())
            current = lead + piece.lstrip()
        else:
            current = joined
    lines.append(current.rstrip())
    return lines


def _pieces(code: str, room: int, first: re.Pattern) -> list[str]:
    """``code`` cut at ``first`` (a piece keeps its leading space, dropped where it starts a
    line); a piece longer than ``room`` is cut again at spaces, then after ``*``, ``,``,
    ``(``."""
    pieces = [code]
    for where in (first, _SPACE, _INNER_BREAK):
        pieces = [
            p for piece in pieces for p in (_split(piece, where) if len(piece) > room else [piece])
        ]
    return pieces


def _split(text: str, where: re.Pattern) -> list[str]:
    cuts = [0, *(m.start() for m in where.finditer(text) if m.start() > 0), len(text)]
    return [text[a:b] for a, b in zip(cuts, cuts[1:]) if b > a]
