"""Tables of poses for the command line: one reader and one writer, for CSV and NPY, used by
every command that reads or writes a batch (``deltagen fk | ik --input/--output``).

A table has named columns. What a command needs is a :class:`Columns` layout (required
names, optional names, whether a headerless file may give them by position); extra
columns (``valid``, the ``T11 .. T44`` of a serial arm's pose) are ignored, so every
command reads what the others write.

CSV
    Comma-separated (or whitespace-separated) numbers, one row per line. A header line
    names the columns: plain (``q1,q2,q3``) or numpy's ``savetxt`` style (``# q1,q2,q3``,
    comma-separated). Other lines starting with ``#`` and blank lines are skipped. Without a header, the
    columns are taken by position, and their number must fit the layout exactly. Names
    match case-insensitively. Written with a plain header line and ``%.17g`` numbers (exact
    round trip); ``valid`` is 1 or 0.
NPY
    Recognised by its magic bytes, not its file name. A *structured* array of shape (N,)
    whose field names are the column names is matched by name (this is what deltagen
    writes: float64 fields, ``valid`` as bool); a plain 2-D numeric array (N, k) is taken by
    position like a headerless CSV. ``structured_to_unstructured`` of
    ``numpy.lib.recfunctions`` turns a written table into a plain (N, k) array.

Every problem is an :class:`~deltagen.inputs.InputError` whose one-line message names the
file and what is wrong with it.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from deltagen.inputs import InputError, read_regular_file

NPY_MAGIC = b"\x93NUMPY"
CSV_SUFFIXES = (".csv", ".txt")


@dataclass(frozen=True)
class Columns:
    """A layout a command can read: ``required`` names, then ``optional`` trailing names
    (all or a leading part of them may be present); ``positional``: a file without names
    may give the columns in this order."""

    required: tuple
    optional: tuple = ()
    positional: bool = True

    def describe(self) -> str:
        text = ",".join(self.required)
        return text + (f"[,{','.join(self.optional)}]" if self.optional else "")

    def widths(self) -> list[int]:
        return [len(self.required) + k for k in range(len(self.optional) + 1)]


def output_format(path) -> str:
    """ "npy" or "csv" from an output file name (extensions are case-insensitive)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".npy":
        return "npy"
    if suffix in CSV_SUFFIXES:
        return "csv"
    raise InputError(f"--output {path}: use a file name ending in .csv, .txt or .npy")


def read_table(path, layouts, what: str) -> tuple[np.ndarray, int, tuple]:
    """Read ``path`` for the first of ``layouts`` it satisfies.

    Returns (data (N, k) float64 in the layout's column order, the index of the layout,
    the names of the k columns). ``what`` says who reads (for messages, e.g. "fk of puma560").
    """
    path = Path(path)
    raw = read_regular_file(path, "input file")
    if raw.startswith(NPY_MAGIC):
        names, columns = _npy_columns(path, raw)
    elif raw.startswith(b"PK\x03\x04"):
        raise InputError(f"{path}: an .npz archive; save one array with numpy.save (.npy)")
    else:
        names, columns = _csv_columns(path, raw)
    if columns.shape[0] == 0:
        raise InputError(f"{path}: no data rows")
    if names is None:
        for index, layout in enumerate(layouts):
            if layout.positional and columns.shape[1] in layout.widths():
                width = columns.shape[1]
                chosen = (layout.required + layout.optional)[:width]
                return columns, index, chosen
        expected = " or ".join(
            f"{lay.describe()} ({_widths_text(lay)} columns)" for lay in layouts if lay.positional
        )
        raise InputError(
            f"{path}: {columns.shape[1]} columns without names; {what} reads "
            f"{expected}, or name the columns in a header line"
        )
    lookup = {}
    for k, name in enumerate(names):
        key = name.strip().lower()
        if key and key in lookup:
            raise InputError(f"{path}: column {name.strip()!r} appears twice")
        lookup[key] = k
    for index, layout in enumerate(layouts):
        if all(n.lower() in lookup for n in layout.required):
            chosen = list(layout.required)
            for extra in layout.optional:
                if extra.lower() not in lookup:
                    break
                chosen.append(extra)
            picked = [lookup[n.lower()] for n in chosen]
            data = columns[:, picked]
            return np.ascontiguousarray(data, dtype=np.float64), index, tuple(chosen)
    shown = ",".join(n.strip() for n in names)
    expected = " or ".join(lay.describe() for lay in layouts)
    missing = [n for n in layouts[-1].required if n.lower() not in lookup]
    raise InputError(
        f"{path}: the columns are named {shown}; {what} needs {expected} "
        f"(missing {','.join(missing)})"
    )


def _widths_text(layout) -> str:
    return " or ".join(str(w) for w in layout.widths())


def _npy_columns(path, raw):
    try:
        arr = np.load(io.BytesIO(raw), allow_pickle=False)
    except Exception as exc:  # numpy raises ValueError, EOFError, ... for broken files
        raise InputError(f"{path}: not a readable .npy file ({_one_line(exc)})") from None
    if arr.dtype.names:
        if arr.ndim != 1:
            raise InputError(f"{path}: a structured array must have shape (N,), got {arr.shape}")
        names, columns = [], np.full((arr.shape[0], len(arr.dtype.names)), np.nan)
        for k, name in enumerate(arr.dtype.names):
            field = arr.dtype.fields[name][0]
            usable = not field.shape and field.kind in "biuf"
            names.append(name if usable else "")  # unusable: an error only when needed
            if usable:
                columns[:, k] = arr[name]
        return names, columns
    if arr.dtype.kind not in "iuf":
        raise InputError(f"{path}: the array must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise InputError(
            f"{path}: the array must be 2-D (one pose per row, one column per "
            f"coordinate), got shape {arr.shape}"
        )
    return None, np.asarray(arr, dtype=np.float64)


def _one_line(exc) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split(line: str) -> list[str]:
    if "," in line:
        return [t.strip() for t in line.split(",")]
    return line.split()


def _csv_columns(path, raw):
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text (CSV) file or an .npy file") from None
    if "\x00" in text:
        raise InputError(f"{path}: not a text (CSV) file or an .npy file")
    names = None
    header_line = None
    rows = []
    width = None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        commented = stripped.startswith("#")
        tokens = _split(stripped.lstrip("#").strip())
        numbers = [_is_number(t) for t in tokens]
        if commented:
            if (
                not rows
                and "," in stripped
                and not any(numbers)
                and all(t and " " not in t and len(t) <= 40 for t in tokens)
            ):
                names, header_line = tokens, number  # numpy's savetxt header: "# x,y,z"
            continue  # any other comment
        if not all(numbers):
            if rows or any(numbers) or header_line is not None:
                raise InputError(f"{path}: line {number}: {_bad_token(tokens)} is not a number")
            names, header_line = tokens, number  # a plain header line: "x,y,z"
            continue
        if width is None:
            width = len(tokens)
            if names is not None and len(names) != width:
                raise InputError(
                    f"{path}: line {number} has {width} values, the header "
                    f"(line {header_line}) names {len(names)} columns"
                )
        elif len(tokens) != width:
            raise InputError(
                f"{path}: line {number} has {len(tokens)} values, the lines before have {width}"
            )
        rows.append([float(t) for t in tokens])
    if not rows:
        raise InputError(f"{path}: no data rows")
    return names, np.array(rows, dtype=np.float64)


def _bad_token(tokens) -> str:
    for t in tokens:
        if not _is_number(t):
            return repr(t[:40]) if t else "an empty value"
    return "a value"


def write_table(target, names, data, valid) -> None:
    """Write columns ``names`` of ``data`` (N, k) and a final ``valid`` column.

    ``target``: a path (.npy: structured array; .csv/.txt: CSV) or a text stream (CSV)."""
    data = np.asarray(data, dtype=np.float64).reshape(len(valid), len(names))
    valid = np.asarray(valid, dtype=bool).reshape(-1)
    if isinstance(target, (str, Path)) and output_format(target) == "npy":
        dtype = np.dtype([(n, np.float64) for n in names] + [("valid", np.bool_)])
        table = np.empty(len(valid), dtype=dtype)
        for k, n in enumerate(names):
            table[n] = data[:, k]
        table["valid"] = valid
        with open(target, "wb") as f:  # np.save(name) would append .npy to x.NPY
            np.save(f, table, allow_pickle=False)
        return
    lines = [",".join(list(names) + ["valid"])]
    for row, ok in zip(data, valid):
        lines.append(
            ",".join(_format(v) for v in row) + ("," if len(row) else "") + ("1" if ok else "0")
        )
    text = "\n".join(lines) + "\n"
    if isinstance(target, (str, Path)):
        with open(target, "w") as f:
            f.write(text)
    else:
        target.write(text)


def _format(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return f"{value:.17g}"
