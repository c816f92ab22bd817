"""The kernel manifests of the generated modules, as the compiled backends read them.

`deltagen generate` writes ``generated/<module>.kernels.json`` beside each module's C
(codegen.render.kernel_manifest): per C function its input and output ports (name, width,
C type, unit, doc, matrix shape) and the parameter struct's fields (from the family's
parameter table, model/parameters.py). The backends take their output widths and shapes
from it instead of writing them again, and fill the parameter struct with
:func:`fill_struct`, which refuses a struct whose compiled fields differ from the table
(cffi would leave a missing field zero).

:func:`kernels` is the public reading: ``kernels("delta_kinematics")["fk"]["outputs"]``.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

from deltagen.errors import ManifestError
from deltagen.model.parameters import struct_values
from deltagen.paths import generated_dir


@functools.cache
def _read(path: str) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ManifestError(
            f"no kernel manifest {path}: run `deltagen generate` (it writes one per module)"
        ) from None


def manifest(module: str, folder: Path | None = None) -> dict:
    """The whole manifest of ``module`` (a file stem such as ``delta_kinematics`` or
    ``serial_ur5``) in ``folder`` (generated/ by default; a serial arm's cache folder)."""
    folder = generated_dir() if folder is None else Path(folder)
    return _read(str(folder / f"{module}.kernels.json"))


def kernels(module: str, folder: Path | None = None) -> dict[str, dict]:
    """{kernel name: entry} of a module's batched C functions: each entry has ``function``
    (the C symbol), ``doc``, ``status_doc``, ``inputs`` and ``outputs`` (lists of ports:
    ``name``, ``width`` (an int, or "axes" for the delta's 3|4 columns), ``ctype``,
    ``unit``, ``doc``, ``matrix``: [rows, columns] of a matrix output or None)."""
    return {entry["name"]: entry for entry in manifest(module, folder)["functions"]}


def output_widths(entry: dict, axes: int | None = None) -> tuple:
    """The row length of each output of a kernel entry (``axes`` for an "axes" port), as
    ``width`` or ``(width, ctype)`` for a non-double output (a 0/1 flag)."""
    widths = []
    for port in entry["outputs"]:
        width = axes if port["width"] == "axes" else port["width"]
        widths.append(width if port["ctype"] == "double" else (width, port["ctype"]))
    return tuple(widths)


def point_shape(port: dict, axes: int = 3) -> tuple:
    """The shape of one point of a port: its matrix shape, else (width,)."""
    if port["matrix"] is not None:
        return tuple(port["matrix"])
    return (axes if port["width"] == "axes" else port["width"],)


def reshape_outputs(entry: dict, outputs) -> list:
    """A kernel's batched outputs (N, width) with each matrix port reshaped to (N, rows,
    columns) (its ``matrix``); the others as they are."""
    return [
        out if port["matrix"] is None else out.reshape(-1, *port["matrix"])
        for out, port in zip(outputs, entry["outputs"])
    ]


def struct_mismatch(ffi, struct_name: str, table: tuple) -> list[str]:
    """The differences between the compiled struct ``struct_name`` (its cffi declaration)
    and the parameter table: fields missing on either side, another order, another array
    length or C type. Empty when they agree."""
    fields = ffi.typeof(struct_name).fields
    compiled = [name for name, _ in fields]
    declared = [p.name for p in table]
    problems = []
    for name in declared:
        if name not in compiled:
            problems.append(f"{name} is in the parameter table but not in the C struct")
    for name in compiled:
        if name not in declared:
            problems.append(f"{name} is in the C struct but not in the parameter table")
    if not problems and compiled != declared:
        problems.append(f"the C struct orders its fields {compiled}, the table {declared}")
    types = dict(fields)
    for p in table:
        if p.name not in types:
            continue
        ctype = types[p.name].type
        length = ctype.length if ctype.kind == "array" else None
        element = ctype.item.cname if ctype.kind == "array" else ctype.cname
        if length != p.count or element != p.ctype:
            problems.append(
                f"{p.name} is {element}{'' if length is None else f'[{length}]'} in the C "
                f"struct but {p.ctype}{p.suffix} in the parameter table"
            )
    return problems


def fill_struct(ffi, struct_name: str, table: tuple, obj):
    """A new cffi ``struct_name *`` filled from the model object ``obj`` through its
    parameter table (model.parameters.struct_values: a GeometryError when a value the table
    does not mark optional is absent). ManifestError when the compiled struct and the table
    disagree (:func:`struct_mismatch`)."""
    problems = struct_mismatch(ffi, struct_name, table)
    if problems:
        raise ManifestError(
            f"{struct_name} and its parameter table disagree: " + "; ".join(problems)
        )
    return ffi.new(f"{struct_name} *", struct_values(table, obj))
