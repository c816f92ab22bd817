"""The parameters of a robot family as its compiled core reads them: one table per family
(``DELTA_PARAMETERS`` in ``model/delta.py``, ``LINEAR_DELTA_PARAMETERS`` and
``TRIPOD_PARAMETERS`` in ``model/linear_delta.py``, ``FIVE_AXIS_PARAMETERS`` in
``model/five_axis.py``, ``HEXAPOD_PARAMETERS`` in ``model/hexapod.py``).

Each entry is one field of the family's C parameter struct: its name, unit, length, whether
it holds one value per kinematic chain, its doc line and how to read it from the model
object. The table is the one declaration: codegen prints the struct from it (field order,
array lengths, comments), the manifest (``generated/<module>.kernels.json``) records it, and
the native backends fill the struct from it (:func:`struct_values`), so a field added here
reaches the C struct, the cffi call and the export example together
(docs/architecture.md, "Adding a quantity").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from deltagen.errors import GeometryError


@dataclass(frozen=True)
class RobotParameter:
    """One field of a family's C parameter struct.

    ``count``: the array length (None: a scalar). ``per_chain``: one value per kinematic
    chain (the delta's three arms). ``optional``: when non-empty, ``read`` may return None
    (the value is absent from the model object, e.g. a delta without inertia); the field is
    then left zero and this text says what refuses the call first.
    """

    name: str
    unit: str
    doc: str  # the struct field's comment in the generated header, verbatim
    read: Callable[[Any], Any]
    count: int | None = None
    per_chain: bool = False
    optional: str = ""
    ctype: str = "double"

    @property
    def suffix(self) -> str:
        """The C declarator suffix: ``[3]`` for an array of 3, empty for a scalar."""
        return "" if self.count is None else f"[{self.count}]"

    def manifest(self) -> dict:
        """The entry of this field in a kernel manifest (JSON)."""
        return dict(
            name=self.name,
            ctype=self.ctype,
            count=self.count,
            unit=self.unit,
            per_chain=self.per_chain,
            optional=bool(self.optional),
            doc=self.doc,
        )


def struct_values(table: tuple, obj: Any) -> dict:
    """{field: value} of the struct ``table`` describes, read from the model object ``obj``:
    every field, in order; an array as a list of its ``count`` floats. An optional field
    whose value is absent (None) is left out (the struct keeps its zero); any other absent
    value or wrong length raises :class:`GeometryError`."""
    values: dict = {}
    for parameter in table:
        value = parameter.read(obj)
        if value is None:
            if parameter.optional:
                continue
            raise GeometryError(f"parameter {parameter.name} has no value")
        if parameter.count is None:
            values[parameter.name] = float(value)
            continue
        items = [float(v) for v in value]
        if len(items) != parameter.count:
            raise GeometryError(
                f"parameter {parameter.name} needs {parameter.count} values, got {len(items)}"
            )
        values[parameter.name] = items
    return values
