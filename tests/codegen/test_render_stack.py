"""The stack figures of the generated headers ("Stack: ... N bytes at 64, plus scalars and
spills: allow M % more", codegen/render.py ``stack_use``) against the compiler's own frame
sizes (gcc -O2 -fstack-usage, of the strict objects tests/c/ builds): every frame is at
least its block arrays and at most the stated margin more. The delta core and two arms with the largest frames relative to their
arrays (the delta's ik, the Panda's Coriolis matrix) are compiled."""

from __future__ import annotations

import re

import pytest
from helpers import GCC, STRICT, private_sources, shared_object

from deltagen.codegen.render import STACK_MARGIN_PERCENT, stack_margin_percent

pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is needed to measure frames")

#: "Stack: ... \n * <bytes> bytes (...) at <block>, plus scalars ..." then the signature.
_FIGURE = re.compile(
    r"\* Stack: [^\n]*\n \* (\d+) bytes [^\n]*allow (\d+) % more\.\n \*/\n\w+ (\w+)\("
)


@pytest.fixture(scope="module")
def source_dir(tmp_path_factory):
    """A private copy of generated/ and the runtime C (the headers the modules include)."""
    return private_sources(tmp_path_factory.mktemp("generated"))


def _frames(source_dir, module) -> dict[str, int]:
    """gcc's frame size of each function of ``module`` at -O2: the strict object tests/c/
    compiles (helpers.shared_object keeps its -fstack-usage figures), built once per run."""
    obj = shared_object(source_dir, f"{module}.c", [*STRICT, "-O2"])
    frames = {}
    for line in obj.with_suffix(".su").read_text().splitlines():
        where, nbytes, _kind = line.split("\t")
        frames[where.rsplit(":", 1)[-1]] = int(nbytes)
    return frames


@pytest.mark.parametrize("module", ["delta_kinematics", "serial_puma560", "serial_panda"])
def test_each_frame_is_its_arrays_plus_at_most_the_stated_margin(module, source_dir):
    figures = {
        name: (int(nbytes), int(margin))
        for nbytes, margin, name in _FIGURE.findall((source_dir / f"{module}.h").read_text())
    }
    assert len(figures) >= 5, "the header's stack figures were not found"
    frames = _frames(source_dir, module)
    source_text = (source_dir / f"{module}.c").read_text()
    for name, (nbytes, margin) in figures.items():
        block = int(re.search(r"#define \w+_BLOCK (\d+)", source_text).group(1))
        assert margin == stack_margin_percent(block, nbytes) >= STACK_MARGIN_PERCENT
        assert nbytes <= frames[name] <= nbytes * (1 + margin / 100), (name, frames[name], nbytes)
