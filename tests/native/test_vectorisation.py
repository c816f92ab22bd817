"""gcc vectorises the batched kernels' loops: the per-point loop of every kernel and its
cos/sin loops, in the delta core and every bundled arm (generated/*.c), compiled with the
build's own flags (native/build.py compile_flags, -O3) and read from gcc's
-fopt-info report (native/vectorisation.py).

Why a test: when gcc stops vectorising a per-point loop every result stays the same and
the kernel gets several times slower; nothing else in the suite notices. The template
marks the loops that must vectorise (``/* loop: points */``, ``/* loop: cos */``,
``/* loop: sin */``); a kernel without a marked loop, or a marked loop gcc leaves scalar,
fails here unless it is in EXEMPT with its reason.

Where the remarks come from: the parallel machines' cores (FROM_BUILD: the delta, linear
delta, tripod, hexapod and five-axis modules, which their robot classes load whole at -O3)
are loaded through the build cache as the suite loads them, and their remarks are the ones
that build kept beside each unit (build.vector_reports; tests/conftest.py turns
DELTAGEN_VECTOR_REPORTS on): no compile of their own where the suite builds them anyway.
The bundled arms' checked-in modules are compiled at -O3 by nothing else (an arm loads its
kernels in parts at -O2, native/serial.py; the whole -O3 build costs gcc 2-4 times the
report's compile), so their reports come from compiles of their own without the RTL passes
that run after the vectoriser (vectorisation.AFTER_VECTORISER; a test checks that they give
the whole compile's remarks, and at -O3 that the whole compile is the build's), cached in
DELTAGEN_CACHE. Those take gcc 1-6 s of CPU per arm, so they are marked slow; the cores,
read from their builds, are not.

The negative tests inject into the delta module the constructs that stop the vectoriser
(a non-finite guard on values already selected to NaN -- the form gcc 12 rejected with
"no vectype for stmt" -- and an early exit) and check the checker reports them; they
compile the changed text themselves, and the injections keep every line number, so the
unchanged kernels' reports come from the cache.
"""

from __future__ import annotations

import platform
import re
import shutil
import stat
import subprocess

import pytest

from deltagen.inputs import env_flag
from deltagen.native import build, toolchain, vectorisation
from deltagen.paths import generated_dir

#: kernels (or "kernel/loop") gcc may leave scalar, and why
EXEMPT = {
    "ik_all/points": (
        "the closed-form IK keeps or drops each of its branches' solutions under conditions "
        "(gcc: 'control flow in loop'); its cos/sin loops still vectorise"
    ),
    "ik_newton": (
        "not a per-point kernel: a wrapper handing fk_jacobian to the runtime's iterative "
        "damped-Newton solver (codegen/runtime/deltagen_ik_newton.c), which converges per point"
    ),
    "deltagen_hexapod_fk": (
        "not a per-point kernel: the hexapod's wrapper handing its jacobian kernel to the "
        "runtime's damped Newton (codegen/runtime/deltagen_hexapod_fk.c), iterating per point"
    ),
    "deltagen_hexapod_fk_legs": "a one-line adapter: the hexapod's jacobian kernel behind a const void * geometry",
    "forward_dynamics": (
        "a wrapper: the mass_matrix and nonlinear_effects kernels it calls are checked here; "
        "it then calls the runtime's Cholesky solver (deltagen_linalg.c) once per point"
    ),
}

MODULES = sorted(p.name for p in generated_dir().glob("*.c"))
#: the modules a robot class loads whole at -O3 (native/delta.py, linear_delta.py,
#: hexapod.py, five_axis.py): their remarks are the ones the suite's own build of the
#: module kept (build.vector_reports; conftest turns DELTAGEN_VECTOR_REPORTS on). A bundled
#: arm loads its kernels in parts at -O2 (native/serial.py), so nothing else compiles its
#: checked-in module at -O3: its report is a compile of its own, without the late RTL passes
FROM_BUILD = {
    "delta_kinematics.c",
    "five_axis_kinematics.c",
    "hexapod_kinematics.c",
    "linear_delta_kinematics.c",
    "tripod_kinematics.c",
}
SLOW_UNLESS = FROM_BUILD
REASON = vectorisation.unavailable()
needs_gcc = pytest.mark.skipif(REASON is not None, reason=str(REASON))


def _module(name: str) -> tuple[str, object]:
    path = generated_dir() / name
    return path.read_text(), path


def test_every_bundled_module_is_covered():
    assert "delta_kinematics.c" in MODULES
    assert {"serial_puma560.c", "serial_ur5.c"} <= set(MODULES)


def test_exemptions_name_real_kernels():
    """Each exemption names a kernel (and marked loop) some bundled module has: a renamed
    kernel cannot leave a dead exemption behind."""
    found = set()
    for name in MODULES:
        text, _ = _module(name)
        prefix = vectorisation.module_prefix(text)
        for k, _, _ in vectorisation.kernels(text, prefix):
            found |= {k, f"{prefix}_{k}"}
        found |= {f"{loop.kernel}/{loop.role}" for loop in vectorisation.marked_loops(text, prefix)}
    assert set(EXEMPT) <= found, sorted(set(EXEMPT) - found)


def test_marked_loops_of_the_delta_core():
    """The markers the check relies on: every delta kernel has a points loop (one per row
    length where it stores the caller's rows itself: codegen/render.py direct_stores; the
    inverse kinematics two, split at their three atan2 loops: atan2_loops), fk has a cos
    and a sin loop per crank angle, and each loop's extent is its body."""
    text, _ = _module("delta_kinematics.c")
    loops = vectorisation.marked_loops(text, "deltagen_delta")
    kernels = [k for k, _, _ in vectorisation.kernels(text, "deltagen_delta")]
    assert "fk" in kernels and "ik" in kernels and "inverse_dynamics" in kernels
    for kernel in kernels:
        roles = [lp.role for lp in loops if lp.kernel == kernel]
        if kernel.startswith("ik"):
            assert roles.count("points") == 4 and roles.count("atan2") == 3, kernel
        else:
            assert roles.count("points") in (1, 2) and "atan2" not in roles, kernel
    fk = [lp for lp in loops if lp.kernel == "fk"]
    assert sorted(lp.role for lp in fk) == ["cos"] * 3 + ["points"] * 2 + ["sin"] * 3
    lines = text.split("\n")
    for lp in loops:
        assert lines[lp.line - 1].lstrip().startswith("for (size_t k = 0;")
        assert lines[lp.end - 1].strip() == "}" and lp.end > lp.line + 1


def test_a_kernel_without_a_marked_loop_fails_by_default():
    """A new kernel whose loop lost (or never had) the marker is a problem unless exempted;
    no compiler needed: the report is empty."""
    text, _ = _module("delta_kinematics.c")
    unmarked = re.sub(r"  /\* loop: \w+ \*/", "", text)
    problems = vectorisation.check(unmarked, [], exempt=EXEMPT)
    assert len(problems) == 10 and all("has no loop marked" in p for p in problems)
    assert any(p.startswith("deltagen_delta_fk ") for p in problems)


def test_a_stale_exemption_fails():
    """An exempt loop that gcc does vectorise is reported, so EXEMPT stays exact."""
    text, _ = _module("delta_kinematics.c")
    loops = vectorisation.marked_loops(text, "deltagen_delta")
    remarks = [
        vectorisation.Remark(lp.line, 30, "optimized", "loop vectorized using 32 byte vectors")
        for lp in loops
    ]
    assert vectorisation.check(text, remarks, exempt=EXEMPT) == []
    problems = vectorisation.check(text, remarks, exempt={"ik/points": "pretend"})
    # one problem per points loop of ik (one per row length)
    ik_points = [lp for lp in loops if lp.kernel == "ik" and lp.role == "points"]
    assert len(problems) == len(ik_points) >= 1
    assert all("stale exemption" in p and "_ik:" in p for p in problems)
    # and without the remark for fk's points loop, that loop is reported
    fk_points = next(lp for lp in loops if lp.kernel == "fk" and lp.role == "points")
    problems = vectorisation.check(text, [r for r in remarks if r.line != fk_points.line])
    assert problems == [
        f"deltagen_delta_fk: the points loop at line {fk_points.line} is not vectorised "
        "(gcc gave no reason)"
    ]


@needs_gcc
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=() if n in SLOW_UNLESS else pytest.mark.slow, id=n.removesuffix(".c"))
        for n in MODULES
    ],
)
def test_batched_kernels_vectorise(name):
    text, path = _module(name)
    remarks = vectorisation.build_report(text, path) if name in FROM_BUILD else None
    if name in FROM_BUILD and env_flag("DELTAGEN_VECTOR_REPORTS", False, "the build's remarks"):
        assert remarks is not None, f"{name}: its build kept no remarks of its units"
    if remarks is None:  # an arm, or a cache entry built with the switch off
        remarks = vectorisation.vector_report(text, path)
    assert any(r.kind == "optimized" for r in remarks), "gcc wrote no report: flags not applied?"
    problems = vectorisation.check(text, remarks, exempt=EXEMPT)
    assert not problems, f"{name}: gcc does not vectorise where it must:\n" + "\n".join(problems)


@needs_gcc
@pytest.mark.parametrize("opt", ["-O3", "-O2"])
def test_the_report_without_the_late_rtl_passes_is_the_whole_compiles(opt):
    """The arms' reports above are read from compiles without the RTL passes that run after
    the vectoriser (vectorisation.AFTER_VECTORISER, most of gcc's time); the remarks of the
    whole compile, with every pass, are the same ones, line for line, in a module with
    vectorised and scalar loops (the linear delta core) at both build levels. At -O3 the
    whole compile is the module's own build, whose remarks the other cores' checks read
    (FROM_BUILD): the two kinds of report agree."""
    text, path = _module("linear_delta_kinematics.c")
    cut = vectorisation.vector_report(text, path, opt=opt)
    whole = vectorisation.build_report(text, path) if opt == "-O3" else None
    if whole is None:  # -O2 (no build of this module at that level), or the switch off
        whole = vectorisation.vector_report(text, path, opt=opt, whole=True)
    assert cut == whole
    assert any(r.kind == "optimized" and vectorisation.VECTORISED in r.message for r in cut)
    assert any(r.kind == "missed" for r in cut)


@needs_gcc
def test_a_run_time_arm_module_vectorises_at_its_level():
    """Arms rendered at run time (URDF, DH files) are built at -O2 (native/serial.py);
    gcc 12's -O2 cost model alone left all their per-point loops scalar. The smallest
    bundled arm stands for them here, at that level."""
    text, path = _module("serial_lecture_scara.c")
    remarks = vectorisation.vector_report(text, path, opt="-O2")
    problems = vectorisation.check(text, remarks, exempt=EXEMPT)
    assert not problems, "at -O2:\n" + "\n".join(problems)


def _inject(text: str, kernel: str, find: str, change) -> str:
    """``text`` with ``change(line)`` applied to the first line of the ``kernel``'s points
    loop that contains ``find`` (same number of lines: other kernels' units are unchanged)."""
    loops = vectorisation.marked_loops(text, "deltagen_delta")
    loop = next(lp for lp in loops if lp.kernel == kernel and lp.role == "points")
    lines = text.split("\n")
    i = next(i for i in range(loop.line, loop.end) if find in lines[i])
    lines[i] = change(lines[i])
    return "\n".join(lines)


def _report(bad: str, path) -> list[vectorisation.Remark]:
    """gcc's remarks on ``bad``, the delta module with lines changed in place (_inject):
    the changed kernels compiled for the report, the others' remarks those of the module's
    own build (their lines are the same), or every kernel compiled where the build kept
    no report."""
    built = vectorisation.build_report(path.read_text(), path)
    if built is None:
        return vectorisation.vector_report(bad, path)
    old = dict(build.split_units(path.read_text())[1])
    spans = vectorisation.kernels(bad, "deltagen_delta")
    changed = [
        (a, b)
        for (_, a, b), (first, lines) in zip(spans, build.split_units(bad)[1])
        if old.get(first) != lines
    ]
    fresh = vectorisation.vector_report(bad, path, only={a for a, _ in changed})
    kept = [r for r in built if not any(a <= r.line <= b for a, b in changed)]
    return sorted(set(kept) | set(fresh), key=lambda r: (r.line, r.column, r.kind, r.message))


@needs_gcc
def test_the_old_finite_guard_is_caught():
    """The guard form that stopped gcc 12 (isfinite of an output already selected to NaN:
    the finite-output rule before it was rewritten; docs/architecture.md, "The finite-output
    guard") injected into fk's points loop: the check names fk's points loop and gcc's
    reason; the other kernels still pass."""
    text, path = _module("delta_kinematics.c")
    old = "isfinite((((collinear) | (invalid) | (unreachable)) ? NAN : {}))"
    bad = _inject(
        text,
        "fk",
        "const int nonfinite_output",
        lambda line: re.sub(r"isfinite\((x|y|z)\)", lambda m: old.format(m.group(1)), line),
    )
    assert bad != text and bad.count("\n") == text.count("\n")
    problems = vectorisation.check(bad, _report(bad, path), exempt=EXEMPT)
    assert len(problems) == 1, problems
    assert problems[0].startswith("deltagen_delta_fk: the points loop at line")
    assert "not vectorised (gcc:" in problems[0]


@needs_gcc
def test_an_early_exit_is_caught():
    """A data-dependent ``break`` in ik's points loop and in one of fk's cos loops."""
    text, path = _module("delta_kinematics.c")
    bad = _inject(text, "ik", "const double x = ", lambda line: line + " if (x > 1e300) break;")
    lines = bad.split("\n")
    cos_loop = next(
        lp
        for lp in vectorisation.marked_loops(bad, "deltagen_delta")
        if lp.kernel == "fk_vel" and lp.role == "cos"
    )
    lines[cos_loop.line] += " if (q1_b[k] > 1e300) break;"
    bad = "\n".join(lines)
    problems = vectorisation.check(bad, _report(bad, path), exempt=EXEMPT)
    assert len(problems) == 2, problems
    assert problems[0].startswith(f"deltagen_delta_fk_vel: the cos loop at line {cos_loop.line}")
    assert problems[1].startswith("deltagen_delta_ik: the points loop at line")


def _fake_compiler(folder, body: str) -> str:
    """An executable shell script in ``folder`` standing for the compiler (``$CC``)."""
    script = folder / "fake-cc"
    script.write_text("#!/bin/sh\n" + body)
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    return str(script)


x86_64_only = pytest.mark.skipif(
    platform.machine() not in ("x86_64", "AMD64"), reason="the check covers x86-64 builds only"
)


@x86_64_only
@pytest.mark.parametrize("how", ["missing", "fails", "not_executable"])
def test_unavailable_names_a_compiler_it_cannot_ask(tmp_path, monkeypatch, how):
    """No compiler, one whose ``--version`` fails, one that cannot be run: a reason, never
    an exception (the tests above are skipped with it)."""
    if how == "missing":
        cc = str(tmp_path / "no-such-cc")
    elif how == "fails":
        cc = _fake_compiler(tmp_path, "echo 'fake-cc: broken' >&2\nexit 3\n")
    else:
        cc = str(tmp_path / "plain-file")
        (tmp_path / "plain-file").write_text("not a program\n")
    monkeypatch.setenv("CC", cc)
    reason = vectorisation.unavailable()
    assert isinstance(reason, str) and reason.startswith("no C compiler to ask"), reason
    if how == "fails":
        assert "exit 3" in reason and "fake-cc: broken" in reason


@x86_64_only
def test_unavailable_names_a_compiler_that_is_not_gcc(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", _fake_compiler(tmp_path, "echo 'clang version 17.0.6'\n"))
    reason = vectorisation.unavailable()
    assert reason is not None and "not gcc" in reason and "clang version 17" in reason


@needs_gcc
def test_a_compiler_that_refuses_the_rtl_cut_is_asked_again_without_it(tmp_path, monkeypatch):
    """A gcc that rejects the ``-fdisable-rtl-*`` options (AFTER_VECTORISER) gets the
    unit again without them: the report is then the whole compile's, as the real gcc
    gives it with ``whole=True`` (from the suite's cache: the -O2 case above asks for the
    same one; the fake compiler's units compile in an empty cache of their own)."""
    text, path = _module("linear_delta_kinematics.c")
    whole = vectorisation.vector_report(text, path, opt="-O2", whole=True)
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / "cache"))
    real = shutil.which(toolchain.host_compiler())
    assert real is not None
    log = tmp_path / "calls.log"
    body = (
        f'case "$*" in *-fdisable-rtl-*) echo cut >> "{log}"; '
        'echo "error: unrecognized option" >&2; exit 1;; esac\n'
        f'case "$*" in *" -c "*) echo plain >> "{log}";; esac\n'
        f'exec "{real}" "$@"\n'
    )
    monkeypatch.setenv("CC", _fake_compiler(tmp_path, body))
    retried = vectorisation.vector_report(text, path, opt="-O2")
    assert retried == whole
    calls = log.read_text().split()
    units = len(vectorisation.kernels(text, "deltagen_linear_delta"))
    assert calls.count("cut") == units and calls.count("plain") == units


@needs_gcc
def test_a_unit_that_does_not_compile_names_the_module_and_line(
    tmp_path, monkeypatch, private_cache
):
    """A unit gcc rejects with and without the RTL cut: BuildError naming the module, the
    unit's first line and the compiler's own text."""
    body = 'case "$*" in *" -c "*) echo "error: refused by the fake compiler" >&2; exit 1;; esac\n'
    body += f'exec "{shutil.which(toolchain.host_compiler())}" "$@"\n'
    monkeypatch.setenv("CC", _fake_compiler(tmp_path, body))
    text, path = _module("linear_delta_kinematics.c")
    with pytest.raises(toolchain.BuildError) as info:
        vectorisation.vector_report(text, path)
    message = str(info.value)
    assert "linear_delta_kinematics.c (line " in message and "vectoriser report" in message
    assert "refused by the fake compiler" in message


LOOPS_C = """#include "loops.h"

int loops_scale(size_t n, const double *x, double *y)
{
    for (size_t k = 0; k < n; ++k) {  /* loop: points */
        y[k] = 2.0 * x[k] + 1.0;
    }
    return 0;
}

int loops_first_big(size_t n, const double *x, double *y)
{
    for (size_t k = 0; k < n; ++k) {  /* loop: points */
        y[k] = x[k] * x[k];
        if (x[k] > 1e300) break;
    }
    return 0;
}
"""
LOOPS_H = (
    "#include <stddef.h>\n"
    "int loops_scale(size_t n, const double *x, double *y);\n"
    "int loops_first_big(size_t n, const double *x, double *y);\n"
)


def _machine_code(shared_object, functions: list[str]) -> str:
    """The instructions of ``functions`` in ``shared_object`` with their bytes, without
    addresses (objdump, binutils: installed with gcc)."""
    objdump = shutil.which("objdump")
    if objdump is None:
        pytest.skip("objdump (binutils) is not installed")
    out = [
        subprocess.run(
            [objdump, "-d", "--no-addresses", f"--disassemble={name}", str(shared_object)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.split(f"<{name}>:", 1)[1]
        for name in functions
    ]
    assert all(len(text.splitlines()) > 3 for text in out), out
    return "".join(out)


@needs_gcc
def test_the_build_keeps_a_report_per_unit_when_asked_and_the_same_bits(tmp_path, monkeypatch):
    """With DELTAGEN_VECTOR_REPORTS on, the build of a checked-in module (generated/, here a
    two-kernel stand-in) at -O3 keeps gcc's remarks of each unit beside the module: the
    vectorised loop and the one with an early exit, each named at its line, as check()
    reads them; the shared object is the one built with the switch off, bit for bit. Off,
    or at -O2, the entry holds none. In a cache kept between runs (the suite's), an entry
    built with the switch off is not taken for one with remarks: the switch on keys its own."""
    folder = tmp_path / "generated"
    folder.mkdir()
    (folder / "loops.c").write_text(LOOPS_C)
    (folder / "loops.h").write_text(LOOPS_H)
    (folder / "loops.cdef.h").write_text(LOOPS_H.split("\n", 1)[1])
    monkeypatch.setattr(build, "generated_dir", lambda: folder)
    monkeypatch.setattr(build, "_build_jobs", lambda: 2)  # split into units (one job: one)
    code, reports = {}, {}
    for switch, opt in (("0", "-O3"), ("1", "-O3"), ("1", "-O2")):
        monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / f"cache{switch}{opt}"))
        monkeypatch.setenv("DELTAGEN_VECTOR_REPORTS", switch)
        monkeypatch.setattr(build, "_LOADED", {})  # a fresh build in each cache
        reports[switch, opt] = build.vector_reports("loops", "loops", folder, opt)
        (entry,) = (tmp_path / f"cache{switch}{opt}").glob("_deltagen_loops_*")
        (shared_object,) = entry.glob("*.so")
        code[switch, opt] = _machine_code(shared_object, ["loops_scale", "loops_first_big"])
    assert reports["0", "-O3"] is None and reports["1", "-O2"] is None
    # the kernels' instructions, byte for byte (the files differ in the module's name)
    assert code["0", "-O3"] == code["1", "-O3"] != code["1", "-O2"]
    assert sorted(reports["1", "-O3"]) == ["loops.unit000.c", "loops.unit001.c"]
    remarks = vectorisation.parse(list(reports["1", "-O3"].values()), "loops.c")
    problems = vectorisation.check(LOOPS_C, remarks, prefix="loops")
    assert len(problems) == 1, problems
    assert problems[0].startswith("loops_first_big: the points loop at line 13 is not vectorised")
    assert "not vectorized: control flow in loop" in problems[0]  # gcc's reason, kept too
    assert any(r.line == 5 and vectorisation.VECTORISED in r.message for r in remarks)
    # one cache, first a run with the switch off, then one with it on
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / "kept"))
    for switch in ("0", "1"):
        monkeypatch.setenv("DELTAGEN_VECTOR_REPORTS", switch)
        monkeypatch.setattr(build, "_LOADED", {})  # a new process
        kept = build.vector_reports("loops", "loops", folder)
    assert kept is not None and vectorisation.parse(list(kept.values()), "loops.c") == remarks


@needs_gcc
def test_a_changed_runtime_header_is_a_new_report(tmp_path, monkeypatch):
    """The reports of the bundled arms are cached between runs (vectorisation.vector_report)
    under a key that covers the runtime headers the module includes: their inline functions
    run inside the kernels' loops. A header whose function stops the vectoriser (a call of
    an opaque function) gives the missed loop, not the cached report of the old header."""
    runtime = tmp_path / "runtime"
    runtime.mkdir()
    monkeypatch.setattr(build, "runtime_dir", lambda: runtime)
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "generated"
    folder.mkdir()
    text = LOOPS_C.replace('#include "loops.h"', '#include "loops.h"\n#include "deltagen_twice.h"')
    text = text.replace("y[k] = 2.0 * x[k] + 1.0;", "y[k] = deltagen_twice(x[k]);")
    (folder / "loops.c").write_text(text)
    (folder / "loops.h").write_text(LOOPS_H)
    header = runtime / "deltagen_twice.h"
    scale = next(lp for lp in vectorisation.marked_loops(text, "loops") if lp.kernel == "scale")
    vectorised = []
    for body in (
        "return 2.0 * x;",
        "if (x > 1e300) { deltagen_note(); }\n    return 2.0 * x;",
    ):
        header.write_text(
            "void deltagen_note(void);\n"
            f"static inline double deltagen_twice(double x)\n{{\n    {body}\n}}\n"
        )
        remarks = vectorisation.vector_report(text, folder / "loops.c", prefix="loops")
        vectorised.append(
            any(r.line == scale.line and vectorisation.VECTORISED in r.message for r in remarks)
        )
    assert vectorised == [True, False]
