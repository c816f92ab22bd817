"""gcc vectorises the batched kernels' loops: the per-point loop of every kernel and its
cos/sin loops, in the delta core and every bundled arm (generated/*.c), compiled with the
build's own flags (native/build.py compile_flags, -O3) and read from gcc's
-fopt-info report (native/vectorisation.py).

Why a test: when gcc stops vectorising a per-point loop every result stays the same and
the kernel gets several times slower; nothing else in the suite notices. The template
marks the loops that must vectorise (``/* loop: points */``, ``/* loop: cos */``,
``/* loop: sin */``); a kernel without a marked loop, or a marked loop gcc leaves scalar,
fails here unless it is in EXEMPT with its reason.

The negative tests inject into the delta module the constructs that stop the vectoriser
(a non-finite guard on values already selected to NaN -- the form gcc 12 rejected with
"no vectype for stmt" -- and an early exit) and check the checker reports them; the
injections keep every line number, so the unchanged kernels' reports come from the cache.
The reports come from compiles without the RTL passes that run after the vectoriser
(vectorisation.AFTER_VECTORISER: a sixth of the CPU on a large unit; a test checks they give the
whole compile's remarks); the arms' modules still take gcc 2-10 s of CPU each at -O3
(reports are cached in DELTAGEN_CACHE), so they are marked slow; the delta core and the
linear delta and tripod cores (small modules) are not.
"""

from __future__ import annotations

import platform
import re
import shutil
import stat

import pytest

from deltagen.native import toolchain, vectorisation
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
SLOW_UNLESS = {"delta_kinematics.c", "linear_delta_kinematics.c", "tripod_kinematics.c"}
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
    remarks = vectorisation.vector_report(text, path)
    assert any(r.kind == "optimized" for r in remarks), "gcc wrote no report: flags not applied?"
    problems = vectorisation.check(text, remarks, exempt=EXEMPT)
    assert not problems, f"{name}: gcc does not vectorise where it must:\n" + "\n".join(problems)


@needs_gcc
@pytest.mark.parametrize("opt", ["-O3", "-O2"])
def test_the_report_without_the_late_rtl_passes_is_the_whole_compiles(opt):
    """The reports above are read from compiles without the RTL passes that run after the
    vectoriser (vectorisation.AFTER_VECTORISER, most of gcc's time); the remarks of the
    whole compile, with every pass, are the same ones, line for line, in a module with
    vectorised and scalar loops (the linear delta core) at both build levels."""
    text, path = _module("linear_delta_kinematics.c")
    cut = vectorisation.vector_report(text, path, opt=opt)
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
    problems = vectorisation.check(bad, vectorisation.vector_report(bad, path), exempt=EXEMPT)
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
    problems = vectorisation.check(bad, vectorisation.vector_report(bad, path), exempt=EXEMPT)
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
def test_a_compiler_that_refuses_the_rtl_cut_is_asked_again_without_it(
    tmp_path, monkeypatch, private_cache
):
    """A gcc that rejects the ``-fdisable-rtl-*`` options (AFTER_VECTORISER) gets the
    unit again without them: the report is then the whole compile's, as the real gcc
    gives it with ``whole=True``."""
    text, path = _module("linear_delta_kinematics.c")
    whole = vectorisation.vector_report(text, path, opt="-O2", whole=True)
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
