"""What codegen keeps between the modules of one process (docs/architecture.md, section 3):
a kernel lowered in double and then in float does its stage CSE once (only the printing
differs), within a bounded cache."""

from __future__ import annotations

import sympy as sp

from deltagen.codegen import lowering
from deltagen.derive.kernel import Kernel, Port, Stage

x, y, a, b, s = sp.symbols("x y a b s", real=True)


def _kernel() -> Kernel:
    """Two stages with a common subexpression each: a and b share sin(x) cos(y)."""
    shared = sp.sin(x) * sp.cos(y)
    return Kernel(
        name="made_up",
        doc="",
        inputs=(Port("u", (x, y), "", "-", width=2),),
        outputs=(Port("v", (a, b), "", "-", width=2),),
        stages=(
            Stage("", ((s, shared + shared**2),)),
            Stage("", ((a, s * shared + 1), (b, s - shared**3))),
        ),
        status=sp.Integer(0),
    )


def test_double_then_float_lowers_each_stage_once():
    lowering._reduce_cached.cache_clear()
    double = lowering.lower(_kernel(), "double")
    stages = len(double.stages)
    assert lowering._reduce_cached.cache_info().misses == stages
    single = lowering.lower(_kernel(), "float")
    info = lowering._reduce_cached.cache_info()
    assert (info.misses, info.hits) == (stages, stages)  # the float build reused every CSE
    assert info.maxsize == lowering.REDUCED_STAGES_KEPT  # bounded: SymPy trees are kept
    # the same statements, printed for each type (float literals and functions)
    assert [st.name for g in double.stages for st in g.statements] == [
        st.name for g in single.stages for st in g.statements
    ]
    printed = " ".join(st.expr for g in single.stages for st in g.statements)
    assert "sinf(" in printed and "sin(" in " ".join(
        st.expr for g in double.stages for st in g.statements
    )
