"""codegen/render.py's split of a per-point loop at its atan2 calls (``atan2_loops``): what
goes where, and when a function is left whole. That a lone point then gets a batch row's
bits is checked on the compiled delta in tests/native/test_lean.py."""

from __future__ import annotations

import re

import pytest

from deltagen.codegen.delta import UNIT
from deltagen.codegen.lowering import LoweredStage, Statement, lower
from deltagen.codegen.render import atan2_loops, direct_stores, function_context, whole_loop
from deltagen.derive.delta.kernels import all_kernels


def _names(expr: str) -> set:
    return set(re.findall(r"\w+", expr))


@pytest.fixture(scope="module")
def delta_ik_functions():
    fns = {}
    for kernel in all_kernels():
        if kernel.name.startswith("ik"):
            fn = function_context(lower(kernel))
            direct_stores(fn, UNIT.axes_choices)
            whole_loop(fn)
            atan2_loops(fn)
            fns[kernel.name] = fn
    assert set(fns) == {"ik", "ik_vel", "ik_acc"}
    return fns


@pytest.mark.parametrize("name", ["ik", "ik_vel", "ik_acc"])
def test_the_delta_ik_splits_into_a_loop_atan2_loops_and_a_finishing_loop(delta_ik_functions, name):
    fn = delta_ik_functions[name]
    original = [st for stage in fn["stages"] for st in stage.statements]
    first, second = fn["parts"]
    calls = {call["name"] for call in fn["atan2"]}
    assert calls == {st.name for st in original if st.expr.startswith("atan2(")}
    assert len(calls) == 3
    in_first = [st.name for stage in first["stages"] for st in stage.statements]
    in_second = [st.name for stage in second["stages"] for st in stage.statements]
    # every statement once: in the first loop, the second, or as an atan2 loop
    assert sorted(in_first + in_second + sorted(calls)) == sorted(st.name for st in original)
    # the first loop reads no angle from atan2; the second calls no atan2
    for stage in first["stages"]:
        for st in stage.statements:
            assert not _names(st.expr) & calls, st
    assert not any("atan2" in st.expr for stage in second["stages"] for st in stage.statements)
    # the atan2 arguments and the carried values are written by the first loop
    written = {c.name for c in first["carry_out"]}
    assert set(fn["atan2_arguments"]) <= written and set(fn["atan2_arguments"]) <= set(in_first)
    assert {c.name for c in second["carry_in"]} <= written
    assert second["atan2_in"] == [call["name"] for call in fn["atan2"]]
    # the angles are outputs: every store and the status are in the finishing loop
    assert second["status"] and not first["status"]
    assert {s["name"] for s in second["stores"]} == {s["name"] for s in fn["stores"]}
    # what the finishing loop reads of the first loop's values is carried to it
    carried = {c.name for c in second["carry_in"]}
    for stage in second["stages"]:
        for st in stage.statements:
            assert _names(st.expr) & set(in_first) <= carried, st


def _fn(statements, stores=("q",), status="bad"):
    """A function context of one stage with ``statements`` [(name, expr)]."""
    fn = dict(
        stages=[LoweredStage("s", tuple(Statement(n, e) for n, e in statements))],
        stores=[
            dict(name=s, port="out", column=i, width=1, ctype="double", ref=f"{s}_b[k]")
            for i, s in enumerate(stores)
        ],
        status=status,
        fourth_outputs=[],
        loads=[dict(name="x", used=True)],
    )
    whole_loop(fn)
    return fn


def test_a_function_whose_atan2_reads_another_atan2_stays_whole():
    fn = _fn(
        [
            ("a", "x*x"),
            ("b", "atan2(a, x)"),
            ("c", "b*2"),
            ("q", "atan2(c, a)"),
            ("bad", "isnan(q)"),
        ]
    )
    atan2_loops(fn)
    assert len(fn["parts"]) == 1 and "atan2" not in fn


def test_an_atan2_of_an_expression_or_an_input_gets_its_arguments_named():
    """The five-axis ik's ``atan2(ex, -ey)``: the arguments become statements of the first
    loop (``<angle>_y``, ``<angle>_x``), kept in columns for the atan2 loop."""
    fn = _fn([("a", "x*x"), ("q", "atan2(a + 1.0, x)"), ("bad", "isnan(q)")])
    atan2_loops(fn)
    first, second = fn["parts"]
    assert fn["atan2"] == [dict(name="q", function="atan2", y="q_y", x="q_x")]
    statements = {st.name: st.expr for stage in first["stages"] for st in stage.statements}
    assert statements == {"a": "x*x", "q_y": "a + 1.0", "q_x": "x"}
    assert [c.name for c in first["carry_out"]] == ["q_y", "q_x"]


def test_a_function_with_an_atan2_the_split_cannot_take_stays_whole():
    """One atan2 alone and one inside a larger expression: splitting at the first would
    leave the second in the first loop, scalar for a lone point."""
    fn = _fn(
        [
            ("a", "x*x"),
            ("b", "a - 1.0"),
            ("q0", "atan2(a, b)"),
            ("q1", "2.0*atan2(b, a)"),
            ("bad", "isnan(q0 + q1)"),
        ],
        stores=("q0", "q1"),
    )
    atan2_loops(fn)
    assert len(fn["parts"]) == 1


def test_two_calls_in_one_expression_are_not_one_call():
    fn = _fn([("a", "x*x"), ("q", "atan2(a, x) + atan2(x, a)"), ("bad", "isnan(q)")])
    atan2_loops(fn)
    assert len(fn["parts"]) == 1


def test_a_split_carries_what_the_finishing_loop_reads():
    fn = _fn(
        [
            ("a", "x*x"),
            ("y", "a - 1.0"),
            ("q0", "atan2(y, a)"),
            ("q", "q0 + a"),
            ("bad", "isnan(q)"),
        ]
    )
    atan2_loops(fn)
    first, second = fn["parts"]
    assert [st.name for stage in first["stages"] for st in stage.statements] == ["a", "y"]
    assert [st.name for stage in second["stages"] for st in stage.statements] == ["q", "bad"]
    # a: an atan2 argument read by q too (carried in); y: an argument only (a column)
    assert [c.name for c in second["carry_in"]] == ["a"]
    assert [c.name for c in first["carry_out"]] == ["a", "y"]
    assert fn["atan2"] == [dict(name="q0", function="atan2", y="y", x="a")]
