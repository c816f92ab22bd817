"""What codegen keeps between the modules of one process (docs/architecture.md, sections 3
and 4): a kernel lowered in double and then in float does its stage CSE once (only the
printing differs), within a bounded cache; the Jinja environment is one per real type and
template folder, and an edited template is still read again."""

from __future__ import annotations

import os
import shutil

import sympy as sp

from deltagen import paths
from deltagen.codegen import lowering, render
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


def test_one_environment_per_real_type_and_template_folder(tmp_path, monkeypatch):
    double, single = render.environment("double"), render.environment("float")
    assert render.environment("double") is double and render.environment("float") is single
    assert double is not single
    assert double.filters["ctype"]("double") == "double"
    assert single.filters["ctype"]("double") == "float"
    assert single.filters["ctype"]("uint8_t") == "uint8_t"
    copy = tmp_path / "templates"
    shutil.copytree(paths.template_dir(), copy)
    monkeypatch.setattr(render, "template_dir", lambda: copy)
    other = render.environment("double")
    assert other is not double and other.loader.searchpath == [str(copy)]


def test_an_edited_template_is_read_again(tmp_path, monkeypatch):
    """The shared environment parses a template once, and again when its file changes."""
    copy = tmp_path / "templates"
    copy.mkdir()
    page = copy / "page.txt.j2"
    page.write_text("first {{ value }}\n")
    monkeypatch.setattr(render, "template_dir", lambda: copy)
    assert render.environment().get_template("page.txt.j2").render(value=1) == "first 1\n"
    page.write_text("second {{ value }}\n")
    stamp = page.stat().st_mtime + 10  # a later modification time, whatever the clock's grain
    os.utime(page, (stamp, stamp))
    assert render.environment().get_template("page.txt.j2").render(value=2) == "second 2\n"


def test_one_printer_per_real_type_and_thread_prints_as_a_fresh_one():
    """to_c keeps one KernelPrinter per real type and thread (a printer made per statement
    cost ~18 % of a lowering whose CSE is cached); what it prints, statement after
    statement, in double and float interleaved and from another thread, is what a fresh
    printer prints."""
    import threading

    from sympy.codegen.ast import float32, real

    from deltagen.codegen import printer

    def fresh(expr, real_type):
        settings = {"type_aliases": {real: float32}} if real_type == "float" else {}
        return printer.KernelPrinter(settings).doprint(printer.expand_small_powers(expr))

    exprs = [
        sp.sin(x) * y**3 + sp.Float(1e-300),
        sp.Piecewise((1, x > 0), (0, True)),
        sp.sqrt(x**2 + y**2) / sp.pi,
        sp.atan2(y, x) - sp.Max(x, y),
    ]
    cases = [(e, rt) for e in exprs for rt in ("float", "double")]
    expected = [fresh(e, rt) for e, rt in cases]
    assert [printer.to_c(e, rt) for e, rt in cases] == expected
    assert any("F" in text for text in expected) and "sinf(" in expected[0]
    assert printer._printer("double") is printer._printer("double")
    seen = []
    thread = threading.Thread(
        target=lambda: seen.append(
            ([printer.to_c(e, rt) for e, rt in cases], printer._printer("double"))
        )
    )
    thread.start()
    thread.join()
    assert seen[0][0] == expected and seen[0][1] is not printer._printer("double")
