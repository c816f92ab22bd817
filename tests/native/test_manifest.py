"""The kernel manifests and the parameter tables against the C they describe.

Independent evidence: the checked-in C declarations (generated/*.cdef.h, what cffi compiles
against), parsed here from their text: each parameter struct by cffi's own C parser
(ffi.typeof(...).fields), each function's argument list by a regular expression. The
manifest (generated/*.kernels.json) and the parameter tables (model/) must name the same
fields and the same ports, in the same order, with the same C types and lengths. A table
with a field dropped is shown to fail, where cffi alone would zero-fill the missing field.
"""

from __future__ import annotations

import dataclasses
import json
import re
from types import SimpleNamespace

import cffi
import pytest
import sympy as sp

from deltagen.codegen.render import kernel_manifest
from deltagen.derive.kernel import Kernel, Parameter, Port, Stage
from deltagen.errors import GeometryError, ManifestError
from deltagen.model.delta import DELTA_PARAMETERS, DeltaGeometry
from deltagen.model.five_axis import FIVE_AXIS_PARAMETERS, MachineDescription
from deltagen.model.hexapod import HEXAPOD_PARAMETERS, HexapodGeometry
from deltagen.model.linear_delta import (
    LINEAR_DELTA_PARAMETERS,
    TRIPOD_PARAMETERS,
    LinearDeltaGeometry,
    TripodGeometry,
)
from deltagen.model.parameters import struct_values
from deltagen.native.manifest import fill_struct, kernels, manifest, struct_mismatch
from deltagen.paths import generated_dir

# module file stem -> (struct, parameter table, a model object of the family)
FAMILIES = {
    "delta_kinematics": ("deltagen_delta_geometry", DELTA_PARAMETERS, DeltaGeometry.default()),
    "linear_delta_kinematics": (
        "deltagen_linear_delta_geometry",
        LINEAR_DELTA_PARAMETERS,
        LinearDeltaGeometry.default(),
    ),
    "tripod_kinematics": ("deltagen_tripod_geometry", TRIPOD_PARAMETERS, TripodGeometry.default()),
    "five_axis_kinematics": (
        "deltagen_five_axis_geometry",
        FIVE_AXIS_PARAMETERS,
        MachineDescription("table-table", "AC", tool_length=0.1, tilt_pivot=(0.0, 0.0, 0.05)),
    ),
    "hexapod_kinematics": (
        "deltagen_hexapod_geometry",
        HEXAPOD_PARAMETERS,
        HexapodGeometry.genhexkins(),
    ),
}
MODULES = sorted(p.name[: -len(".kernels.json")] for p in generated_dir().glob("*.kernels.json"))


def _cdef(module: str) -> str:
    return (generated_dir() / f"{module}.cdef.h").read_text()


def _struct_ffi(module: str, text: str | None = None) -> cffi.FFI:
    """A cffi FFI that knows only the module's parameter struct, parsed from its cdef text."""
    text = _cdef(module) if text is None else text
    found = re.search(r"typedef struct \w+ \{.*?\} \w+;", text, re.DOTALL)
    assert found, module
    ffi = cffi.FFI()
    ffi.cdef(found.group(0))
    return ffi


def test_every_module_has_a_manifest():
    """One manifest per checked-in module (a C file without one would leave its widths to be
    written by hand again)."""
    stems = sorted(p.name[: -len(".cdef.h")] for p in generated_dir().glob("*.cdef.h"))
    assert MODULES == stems
    assert set(FAMILIES) <= set(MODULES)


@pytest.mark.parametrize("module", sorted(FAMILIES))
def test_struct_fields_agree_with_the_parameter_table(module):
    struct, table, _ = FAMILIES[module]
    ffi = _struct_ffi(module)
    assert struct_mismatch(ffi, struct, table) == []
    fields = ffi.typeof(struct).fields
    assert [name for name, _ in fields] == [p.name for p in table]
    for (name, field), parameter in zip(fields, table):
        length = field.type.length if field.type.kind == "array" else None
        assert length == parameter.count, name
    # the manifest records the same table
    recorded = manifest(module)["struct"]
    assert recorded["name"] == struct
    assert recorded["fields"] == [p.manifest() for p in table]


@pytest.mark.parametrize("module", sorted(FAMILIES))
def test_struct_values_fill_every_field(module):
    """The values a backend passes: every field of the C struct, with the table's lengths
    (a delta without inertia leaves only the fields marked optional out)."""
    struct, table, obj = FAMILIES[module]
    ffi = _struct_ffi(module)
    values = struct_values(table, obj)
    assert list(values) == [name for name, _ in ffi.typeof(struct).fields]
    cdata = fill_struct(ffi, struct, table, obj)
    for name, value in values.items():
        got = getattr(cdata, name)
        assert (list(got) if isinstance(value, list) else got) == value, name


def test_a_delta_without_inertia_leaves_out_only_the_optional_fields():
    g = dataclasses.replace(DeltaGeometry.default(), inertia=None)
    left_out = {p.name for p in DELTA_PARAMETERS} - set(struct_values(DELTA_PARAMETERS, g))
    assert left_out == {p.name for p in DELTA_PARAMETERS if p.optional}
    assert left_out == {"I_a", "m_a", "r_ca", "m_b", "m_p", "gravity", "I_4"}


def test_a_dropped_field_fails_where_cffi_would_zero_fill():
    """cffi fills a struct from a dict without the key l_b: l_b silently 0. A parameter table
    without l_b, or a C struct without it, is refused instead."""
    struct, table, g = FAMILIES["delta_kinematics"]
    ffi = _struct_ffi("delta_kinematics")
    values = struct_values(table, g)
    del values["l_b"]
    assert ffi.new(f"{struct} *", values).l_b == 0.0  # what the check guards against
    dropped = tuple(p for p in table if p.name != "l_b")
    problems = struct_mismatch(ffi, struct, dropped)
    assert problems == ["l_b is in the C struct but not in the parameter table"]
    with pytest.raises(ManifestError, match="l_b is in the C struct but not in the parameter"):
        fill_struct(ffi, struct, dropped, g)
    # the other way: a C struct without l_b (a stale module) against the full table
    text = re.sub(r"\n\s*double l_b;", "", _cdef("delta_kinematics"))
    stale = _struct_ffi("delta_kinematics", text)
    assert struct_mismatch(stale, struct, table) == [
        "l_b is in the parameter table but not in the C struct"
    ]
    with pytest.raises(ManifestError):
        fill_struct(stale, struct, table, g)


def test_a_wrong_length_or_order_fails():
    struct, table, g = FAMILIES["delta_kinematics"]
    ffi = _struct_ffi("delta_kinematics")
    swapped = (table[1], table[0], *table[2:])
    assert "orders its fields" in struct_mismatch(ffi, struct, swapped)[0]
    text = _cdef("delta_kinematics").replace("double chain_r[3];", "double chain_r[4];")
    assert struct_mismatch(_struct_ffi("delta_kinematics", text), struct, table) == [
        "chain_r is double[4] in the C struct but double[3] in the parameter table"
    ]
    short = SimpleNamespace(**{"chain_r": (1.0, 2.0)})
    with pytest.raises(GeometryError, match="chain_r needs 3 values, got 2"):
        struct_values((table[4],), short)


_FUNCTION = re.compile(r"^int (\w+)\((.*?)\);", re.MULTILINE | re.DOTALL)


def _signatures(module: str) -> dict[str, list[tuple[str, str]]]:
    """{C function: [(type, name), ...]} of the module's cdef text."""
    out = {}
    for name, args in _FUNCTION.findall(_cdef(module)):
        parameters = []
        for arg in " ".join(args.split()).split(", "):
            ctype, _, pname = arg.rpartition(" ")
            stars = len(pname) - len(pname.lstrip("*"))
            parameters.append((ctype + " " + "*" * stars, pname.lstrip("*")))
        out[name] = parameters
    return out


@pytest.mark.parametrize("module", MODULES)
def test_manifest_ports_are_the_c_arguments(module):
    """Each function of the manifest is declared in the module's C with, in order: the
    geometry (when the module has a struct), the row count, the axes count (the delta), one
    const pointer per input port and one pointer per output port of the port's C type, and
    the status."""
    recorded = manifest(module)
    signatures = _signatures(module)
    assert recorded["functions"], module
    for entry in recorded["functions"]:
        args = signatures[entry["function"]]
        head = []
        if recorded["struct"] is not None:
            head.append((f"const {recorded['struct']['name']} *", "geometry"))
        head.append(("size_t ", "n"))
        if recorded["axes"]:
            head.append(("size_t ", "axes"))
        ports = [(f"const {p['ctype']} *", p["name"]) for p in entry["inputs"]]
        ports += [(f"{p['ctype']} *", p["name"]) for p in entry["outputs"]]
        assert args == [*head, *ports, ("int8_t *", "status")], entry["function"]
        for port in entry["inputs"] + entry["outputs"]:
            if port["matrix"] is not None and port["width"] != "axes":
                size = 1
                for extent in port["matrix"]:
                    size *= extent
                assert size == port["width"], (entry["function"], port["name"])


def test_kernels_reads_one_module():
    """The public reading (deltagen.native.manifest.kernels), as the bench uses it."""
    delta = kernels("delta_kinematics")
    assert delta["jacobian"]["function"] == "deltagen_delta_jacobian"
    assert [p["name"] for p in delta["fk_vel"]["inputs"]] == ["q", "qd"]
    assert delta["jacobian"]["outputs"][0]["matrix"] == [3, 3]
    assert [(p["name"], p["width"]) for p in delta["inverse_dynamics"]["inputs"]] == [
        ("q", "axes"),
        ("qd", "axes"),
        ("qdd", "axes"),
        ("payload", 1),
    ]
    with pytest.raises(ManifestError, match="deltagen generate"):
        kernels("no_such_module")


def test_a_kernel_reading_an_undeclared_field_is_refused():
    """The derivation's struct reads (derive.kernel.Parameter) must be fields of the table:
    a kernel reading l_c (no such field) or l_b[0] (a scalar) cannot be rendered."""
    from deltagen.codegen.delta import UNIT

    x, y = sp.symbols("x y", real=True)

    def lowered(parameter):
        kernel = Kernel(
            name="probe",
            doc="",
            inputs=(Port("x", (x,), "", "m", width=1),),
            outputs=(Port("y", (y,), "", "m", width=1),),
            stages=(Stage("", ((y, x),)),),
            status=sp.Integer(0),
            parameters=(parameter,),
        )
        return [SimpleNamespace(kernel=kernel, real_type="double")]

    text = kernel_manifest(UNIT, lowered(Parameter(x, "chain_l_b", 2)))
    assert json.loads(text)["functions"][0]["name"] == "probe"
    for bad in (Parameter(x, "l_c"), Parameter(x, "l_b", 0), Parameter(x, "chain_l_b", 3)):
        with pytest.raises(ValueError, match="does not declare"):
            kernel_manifest(UNIT, lowered(bad))


def test_the_manifest_is_what_the_generator_writes():
    """Deterministic: the checked-in manifest is the rendering of today's kernels (the
    linear delta's, a few seconds; `deltagen generate --check` covers every module)."""
    from deltagen.codegen.linear_delta import linear_delta_sources

    name = "linear_delta_kinematics.kernels.json"
    first, second = linear_delta_sources()[name], linear_delta_sources()[name]
    assert first == second == (generated_dir() / name).read_text()
