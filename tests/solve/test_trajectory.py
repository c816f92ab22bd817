"""deltagen.plan.trajectory is a re-export (its docstring): every name it lists is the very
object of the module that defines it (plan.scaling, plan.cartesian, plan.following,
geometry.rotations), so code importing the old module keeps working."""

from __future__ import annotations

import pytest

from deltagen.geometry import rotations
from deltagen.plan import cartesian, following, scaling, trajectory


@pytest.mark.parametrize("name", trajectory.__all__)
def test_every_name_is_its_home_modules_object(name):
    homes = [m for m in (scaling, cartesian, following, rotations) if hasattr(m, name)]
    assert homes, f"{name} is defined in none of the plan modules or geometry.rotations"
    assert all(getattr(trajectory, name) is getattr(m, name) for m in homes)
