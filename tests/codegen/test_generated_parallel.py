"""generated/ is current, module by module: each checked-in module of the parallel
machines (the delta, the linear delta, the tripod, the 5-axis machine, the hexapod) is
rendered alone and compared with its files, and generated/ holds nothing but the modules
the generator renders. With tests/codegen/test_generated_serial_*.py this is what
`deltagen generate --check` checks, in parallel; `pytest --update-generated` rewrites."""

from __future__ import annotations

import pytest
from helpers import compare_or_update_generated, generated_stems, update_generated

from deltagen.paths import generated_dir

PARALLEL = [stem for stem in generated_stems() if not stem.startswith("serial_")]


def test_generated_holds_only_rendered_modules():
    """Every file of generated/ is ``<stem>.<ext>`` of a module the generator renders (a
    removed robot's module or a hand-made file is stray), and every module has files."""
    stems = set(generated_stems())
    files = sorted(p.name for p in generated_dir().iterdir())
    stray = [name for name in files if name.split(".", 1)[0] not in stems]
    assert stray == [], f"stray files in generated/ (delete them): {stray}"
    assert {name.split(".", 1)[0] for name in files} == stems
    assert set(PARALLEL) == {
        "delta_kinematics",
        "linear_delta_kinematics",
        "tripod_kinematics",
        "five_axis_kinematics",
        "hexapod_kinematics",
    }


@pytest.mark.parametrize("stem", PARALLEL)
def test_module_is_current(stem, request):
    compare_or_update_generated(stem, update_generated(request.config))
