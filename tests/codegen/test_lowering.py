"""codegen.lowering.guard_outputs: an output that passes an input through is not tested for
finiteness a second time where the INVALID flag already tests that input; every other
output still is (tests/api/test_nonfinite.py holds the rule itself)."""

from __future__ import annotations

import sympy as sp

from deltagen.codegen.lowering import guard_outputs
from deltagen.derive.functions import AllFinite
from deltagen.derive.kernel import Kernel, Port, Stage

x, y, w, a, b, c, invalid, bad = sp.symbols("x y w a b c invalid bad", real=True)


def _kernel(flag_covers: tuple, mask) -> Kernel:
    """Inputs x, y (and w); outputs a = x y, b = x passed through, c = w passed through,
    each NaN where ``mask`` holds; invalid = not AllFinite(*flag_covers)."""
    return Kernel(
        name="made_up",
        doc="",
        inputs=(Port("u", (x, y, w), "", "-", width=3),),
        outputs=(Port("v", (a, b, c), "", "-", width=3),),
        stages=(
            Stage(
                "",
                (
                    (invalid, sp.Not(AllFinite(*flag_covers))),
                    (bad, x < 0),
                    (a, sp.Piecewise((sp.nan, mask), (x * y, True))),
                    (b, sp.Piecewise((sp.nan, mask), (x, True))),
                    (c, sp.Piecewise((sp.nan, mask), (w, True))),
                ),
            ),
        ),
        status=sp.Piecewise((3, invalid), (1, bad), (0, True)),
    )


def _tested(kernel: Kernel) -> set:
    """The values the guard's finiteness test reads."""
    (_, rule), *_ = guard_outputs(kernel).stages[-1].assignments
    return {arg for f in rule.atoms(AllFinite) for arg in f.args}


def test_pass_through_inputs_the_invalid_flag_covers_are_not_tested_again():
    kernel = _kernel((x, y, w), sp.Or(invalid, bad))
    assert _tested(kernel) == {x * y}


def test_an_input_the_flag_does_not_test_is_still_tested():
    kernel = _kernel((x, y), sp.Or(invalid, bad))  # w is not among the flag's inputs
    assert _tested(kernel) == {x * y, w}


def test_a_mask_without_the_flag_tests_every_output():
    kernel = _kernel((x, y, w), bad)  # NaN only where bad: invalid rows are not masked
    assert _tested(kernel) == {x * y, x, w}
