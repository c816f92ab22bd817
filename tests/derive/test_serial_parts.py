"""A new arm's module is built in parts (derive.serial.kernels.PARTS, native/serial.py):
each part's C holds exactly its own kernels, every kernel of the complete module (what
`deltagen generate` writes) is in exactly one part, and its C text there is the complete
module's, so a kernel built on demand gives the complete module's results bit for bit."""

from __future__ import annotations

import re

from helpers import PARTS_ROWS

from deltagen import SerialRobot
from deltagen.codegen.serial import arm_sources
from deltagen.derive.serial.kernels import PARTS
from deltagen.native.units import _DEFINITION


def _functions(sources: dict[str, str]) -> dict[str, list[str]]:
    """C function name -> its definition's lines (to the closing brace at column 0)."""
    (text,) = [t for f, t in sources.items() if f.endswith(".c")]
    lines = text.split("\n")
    out = {}
    for i, line in enumerate(lines):
        if _DEFINITION.match(line):  # a top-level definition, as the build splits them
            name = re.match(r"^[^(]*?\b(\w+)\s*\(", line).group(1)
            out[name] = lines[i : lines.index("}", i) + 1]
    return out


def test_every_kernel_is_in_one_part_with_the_complete_modules_c():
    """On two links with inertia: the same twelve kernels as the three-link arm (checked:
    no closed form either way), half its SymPy time (17 s instead of 34 s)."""
    desc = SerialRobot.from_dh(
        PARTS_ROWS[:2], "standard", name="parts_arm", backend="reference"
    ).description
    assert desc.n == 2 and desc.has_inertia
    complete = _functions(arm_sources(desc))
    # every kernel of every part is there (ik_all only for arms with a closed form)
    every = {f"deltagen_parts_arm_{k}" for ks in PARTS.values() for k in ks if k != "ik_all"}
    assert every <= set(complete), every - set(complete)
    seen: dict[str, str] = {}
    for part, kernels in PARTS.items():
        part_desc = desc.without_inertia() if part in ("first", "later") else desc
        functions = _functions(arm_sources(part_desc, part))
        expected = {f"deltagen_parts_arm_{k}" for k in kernels}
        if part == "first":
            expected.add("deltagen_parts_arm_ik_newton")
        if part == "mass":
            expected.add("deltagen_parts_arm_forward_dynamics")
        expected &= set(complete)  # ik_all: only where a closed form exists
        assert set(functions) == expected, part
        for name, lines in functions.items():
            assert name not in seen, (name, part, seen.get(name))
            seen[name] = part
            assert lines == complete[name], name  # the same C, so the same bits
    assert set(seen) == set(complete)


def test_a_part_is_never_served_as_the_whole_module():
    """The cache keys and names which part a module holds (native/build.py): the same
    folder loaded as a part and as the whole module are two entries, and a new arm's
    first-part module, loaded first, never answers a request for the complete module,
    which has every kernel."""
    from deltagen.codegen.serial import base_name, c_prefix
    from deltagen.native import build
    from deltagen.native import serial as native_serial

    desc = SerialRobot.from_dh(
        PARTS_ROWS[:2], "standard", name="partkey_arm", backend="reference"
    ).description.without_inertia()
    folder = native_serial.source_dir(desc, part="first")
    name, prefix = base_name(desc), c_prefix(desc)
    as_whole = build._module_inputs(name, prefix, folder, "-O2")[0]
    as_first = build._module_inputs(name, prefix, folder, "-O2", part="first")[0]
    assert as_first != as_whole and as_first.startswith(f"_deltagen_{name}_first_")
    first = native_serial._load(desc, part="first")
    assert not hasattr(first.lib, f"{prefix}_jacobian_dot")  # a part: not every kernel
    complete = native_serial.complete_module(desc)
    assert complete is not first
    for kernel in (*PARTS["first"], "jacobian_dot"):  # (no closed form: no ik_all)
        assert hasattr(complete.lib, f"{prefix}_{kernel}"), kernel
