"""The arm modules of generated/ (and arms of more than 6 joints) on their own, as a
motion-controller user would take them with the runtime C: strict C99 compiles
warning-free, needs only libm and has no global data; the IK driver (written here, linked
with -fsanitize=address,undefined) runs deltagen_<arm>_ik_newton clean. The delta core's
module is tests/c/test_standalone.py."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers import (
    GCC,
    GCC_REQUIRED,
    LIBM,
    STRICT,
    STRICT_SANITIZED,
    c_array,
    check_symbols,
    copy_runtime,
    long_arm,
    runtime_flags,
    runtime_sources,
    strict_gcc,
    vector_math_flags,
)

from deltagen import paths
from deltagen.native.build import compile_flags, runtime_files

pytestmark = pytest.mark.skipif(GCC is None, reason="gcc not installed")

RUNTIME_SOURCES = runtime_sources()


def _serial_sources():
    return sorted(p.name for p in paths.generated_dir().glob("serial_*.c"))


def _runtime_of(source_dir, name):
    """The runtime .c files the module ``name`` includes (what build.py compiles beside it
    and an export ships)."""
    texts = [(source_dir / name.replace(".c", ext)).read_text() for ext in (".c", ".h")]
    return sorted(f.name for f in runtime_files(texts) if f.suffix == ".c")


# Which compile proves what for the arm modules. The optimiser's warnings (maybe-
# uninitialized, array bounds) need -O2 or more; -pedantic's are the front end's, so -O0
# gives them all:
# * every module: strict C99 -pedantic -Werror at -O2 (its scalar-libm branch), read by nm,
#   and its vector-math branch (#if ..._VECTOR_MATH) through the front end at -O0;
# * BUILD_FLAGS_ARM: the build's own flags (-O3, -march=native, vector math where libmvec
#   is present) with -pedantic -Werror, read by nm: one module with every kernel kind, the
#   kernels of every arm coming from the same templates (codegen/templates/);
# * the long arms (7 and 9 joints): -O2, and the vector-math branch at -O3, both with
#   -Warray-bounds=2 (arrays sized by the joint count, trig loops padded to the lanes).
# (The build's flags on every bundled module cost 5-55 s of compiling each.)

#: the module with every kernel kind (kinematics, closed-form ik_all, ik_newton, inverse and
#: forward dynamics with the runtime's Cholesky) at the smallest compile cost
BUILD_FLAGS_ARM = "serial_miskolc_rrrr.c"


@pytest.mark.parametrize("name", _serial_sources())
def test_serial_modules_compile_strict_and_need_only_libm(name, source_dir, objects):
    """Every checked-in arm module with the runtime: strict C99 -pedantic -Werror at -O2,
    its vector-math branch at -O0 (the front end's checks), only libm symbols undefined, no
    global data (the runtime's objects are built once for every arm)."""
    prefix = "deltagen_" + name[len("serial_") : -2]
    runtime = _runtime_of(source_dir, name)
    assert "deltagen_linalg.c" in runtime
    strict = [objects(source, [*STRICT, "-O2"]) for source in [name, *runtime]]
    objects(name, [*STRICT, "-O0", *vector_math_flags(prefix)])
    check_symbols(strict, source_dir)


def test_the_build_flags_arm_holds_every_kernel_kind():
    """BUILD_FLAGS_ARM stands for every arm's kernels only while it has them all."""
    generated = paths.generated_dir()

    def functions(path):
        return {entry["name"] for entry in json.loads(path.read_text())["functions"]}

    every = set().union(*map(functions, generated.glob("serial_*.kernels.json")))
    assert functions(generated / BUILD_FLAGS_ARM.replace(".c", ".kernels.json")) == every
    assert "deltagen_ik_newton(" in (generated / BUILD_FLAGS_ARM).read_text()


def test_an_arm_module_compiles_with_the_build_flags_and_needs_only_libm(source_dir, objects):
    """BUILD_FLAGS_ARM and its runtime with the flags deltagen.native.build uses for the
    cffi core (-O3, -march=native, vector math where available) plus -pedantic -Werror:
    warning-free, only libm (its vector variants too) undefined, no global data."""
    args, _ = compile_flags("deltagen_" + BUILD_FLAGS_ARM[len("serial_") : -2])
    built = [objects(BUILD_FLAGS_ARM, [*args, "-pedantic", "-Werror"])]
    built += [
        objects(source, [*runtime_flags(args), "-pedantic", "-Werror"])
        for source in _runtime_of(source_dir, BUILD_FLAGS_ARM)
    ]
    check_symbols(built, source_dir)


def test_the_strict_compiles_fail_on_what_c99_or_the_optimiser_rejects(source_dir, objects):
    """The checks above can fail: a GNU statement expression (not C99) appended to an arm
    module fails its -O0 front-end check; a value that is uninitialised when a loop does not
    run passes -O0 and fails -O2 (-Wmaybe-uninitialized)."""
    module = (source_dir / "serial_lecture_prp.c").read_text()
    (source_dir / "not_c99.c").write_text(module + "int deltagen_x(void) { return ({ 1; }); }\n")
    with pytest.raises(AssertionError, match="ISO C forbids braced-groups"):
        objects("not_c99.c", [*STRICT, "-O0"])
    (source_dir / "uninitialised.c").write_text(
        module + "double deltagen_y(const double *x, int n)\n"
        "{ double v; for (int i = 0; i < n; ++i) { v = x[i]; } return v; }\n"
    )
    objects("uninitialised.c", [*STRICT, "-O0"])  # the front end does not see it
    with pytest.raises(AssertionError, match="uninitialized"):
        objects("uninitialised.c", [*STRICT, "-O2"])


def test_general6r_runtime_compiles_strict(source_dir, objects):
    """The general-6R solver's C (host side, one module for every arm; no arm module or
    export includes it): strict C99 warning-free, no global data, libm and GCC's four."""
    built = [
        objects(source, [*STRICT, "-O2"])
        for source in ("deltagen_eigen.c", "deltagen_general6r.c", "deltagen_linalg.c")
    ]
    check_symbols(built, source_dir, allowed=LIBM | GCC_REQUIRED)


@pytest.fixture(scope="module")
def long_arms(source_dir):
    """``render(n_joints)``: the long arm's description (helpers.long_arm), its module
    rendered into ``source_dir`` once per file, for the strict compiles and the IK driver."""
    from deltagen.codegen.serial import arm_sources

    rendered = {}

    def render(n_joints):
        if n_joints not in rendered:
            desc = long_arm(n_joints)
            for file_name, text in arm_sources(desc).items():
                (source_dir / file_name).write_text(text)
            rendered[n_joints] = desc
        return rendered[n_joints]

    return render


@pytest.mark.parametrize("n_joints", [7, 9])
def test_long_arms_compile_warning_free(n_joints, source_dir, objects, long_arms):
    """Arms with more than 6 joints: the module and the runtime compile with -Werror and
    -Warray-bounds=2 at -O2, and with the vector-math branch (trig loops padded to the
    vector lanes) at -O3: arrays sized by the joint count work for any count (the runtime,
    the same for every arm, is compiled once for both)."""
    desc = long_arms(n_joints)
    source = f"serial_{desc.name}.c"
    vector = [*STRICT, "-O3", "-Warray-bounds=2", *vector_math_flags(f"deltagen_{desc.name}")]
    for flags in ([*STRICT, "-O2", "-Warray-bounds=2"], vector):
        objects(source, flags)
        for runtime in _runtime_of(source_dir, source):
            objects(runtime, runtime_flags(flags))


IK_DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include "serial_%(name)s.h"

#define N %(n)d
#define NJ %(nj)d
%(arrays)s
static int failures = 0;
#define CHECK(cond, ...) do { if (!(cond)) { ++failures; printf("FAIL line %%d: ", __LINE__); \
    printf(__VA_ARGS__); printf("\n"); } } while (0)

static double q[N * NJ], ep[N], er[N], T[N * 16];
static int32_t it[N];
static int8_t st[N], st2[N];

int main(void)
{
    deltagen_ik_options o = {1e-10, 1e-10, 0.5, 1.0, 0.1, 100, 0, 1, 1, {1, 1, 1, 1, 1, 1}, 0, 0};
    CHECK(deltagen_%(name)s_ik_newton(N, &o, TT, Q0, QLIM, q, ep, er, it, st) == 0, "rc");
    CHECK(deltagen_%(name)s_fk(N, q, T, st2) == 0, "fk rc");
    int ok = 0;
    for (size_t i = 0; i < N; ++i) {
        if (BAD[i]) {
            CHECK(st[i] == DELTAGEN_INVALID && isnan(q[i * NJ]) && isnan(ep[i]) && it[i] == 0,
                  "row %%zu not INVALID", i);
            continue;
        }
        CHECK(st[i] == DELTAGEN_OK || st[i] == DELTAGEN_UNREACHABLE, "row %%zu status %%d", i, st[i]);
        for (size_t j = 0; j < NJ; ++j) {
            CHECK(q[i * NJ + j] >= QLIM[2 * j] && q[i * NJ + j] <= QLIM[2 * j + 1], "row %%zu limits", i);
        }
        if (st[i] == DELTAGEN_OK) {
            ++ok;
            CHECK(ep[i] <= 1e-10 && er[i] <= 1e-10, "row %%zu errors", i);
            for (size_t c = 0; c < 3; ++c) {
                CHECK(fabs(T[i * 16 + 4 * c + 3] - TT[i * 16 + 4 * c + 3]) <= 1e-10, "row %%zu p", i);
            }
        }
    }
    CHECK(ok >= N / 2, "only %%d converged", ok);
    /* documented return codes: bad options, NULL pointers, n = 0 */
    int8_t s1 = 42;
    double q1[NJ] = {0}, e1 = 7.0, e2 = 7.0;
    int32_t i1;
    deltagen_ik_options bad = o;
    bad.tol_p = -1.0;
    CHECK(deltagen_%(name)s_ik_newton(1, &bad, TT, Q0, QLIM, q1, &e1, &e2, &i1, &s1) == -1, "tol_p");
    bad = o;
    bad.mask[0] = 2;
    CHECK(deltagen_%(name)s_ik_newton(1, &bad, TT, Q0, QLIM, q1, &e1, &e2, &i1, &s1) == -1, "mask");
    bad = o;
    bad.max_iter = -1;
    CHECK(deltagen_%(name)s_ik_newton(1, &bad, TT, Q0, QLIM, q1, &e1, &e2, &i1, &s1) == -1, "max_iter");
    CHECK(deltagen_%(name)s_ik_newton(1, NULL, TT, Q0, QLIM, q1, &e1, &e2, &i1, &s1) == -1, "NULL options");
    CHECK(deltagen_%(name)s_ik_newton(1, &o, NULL, Q0, QLIM, q1, &e1, &e2, &i1, &s1) == -1, "NULL T");
    CHECK(deltagen_%(name)s_ik_newton(1, &o, TT, Q0, QLIM, q1, &e1, &e2, &i1, NULL) == -1, "NULL status");
    CHECK(s1 == 42 && e1 == 7.0, "written on error");
    CHECK(deltagen_%(name)s_ik_newton(0, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL) == 0, "n=0");
    /* no limits (qlim NULL), a mask, no step limit: still runs clean */
    o.step_limit = INFINITY;
    o.mask[3] = o.mask[4] = 0;
    CHECK(deltagen_%(name)s_ik_newton(N, &o, TT, Q0, NULL, q, ep, er, it, st) == 0, "rc no limits");
    if (failures) {
        printf("%%d FAILURES\n", failures);
        return 1;
    }
    return 0;
}
"""


@pytest.mark.slow
# the Puma module (with its dynamics) runs ik_newton under the sanitizers in
# tests/c/test_fuzz_sanitizers.py; compiling it twice more under ASan costs ~80 s
@pytest.mark.parametrize("name", ["manutec_h5", "long7", "long9"])
def test_ik_newton_driver_under_sanitizers(
    sanitizers, tmp_path, name, source_dir, objects, long_arms
):
    """deltagen_<arm>_ik_newton (the generated wrapper and the runtime solver) on its own, linked with
    ASan/UBSan: converged rows reproduce their targets through the module's fk and stay
    within the limits, non-finite rows are INVALID, bad options and NULL pointers give -1
    and write nothing. long7 and long9 are redundant arms (7 and 9 joints)."""
    from deltagen.api.serial import SerialRobot
    from deltagen.reference import serial as reference

    if name.startswith("long"):
        arm = SerialRobot(long_arms(int(name[4:])), backend="reference")
        for ext in (".c", ".h"):
            shutil.copy(source_dir / f"serial_{name}{ext}", tmp_path)
    else:
        arm = SerialRobot.load(name, backend="reference")
        for ext in (".c", ".h"):
            shutil.copy(paths.generated_dir() / f"serial_{name}{ext}", tmp_path)
    copy_runtime(tmp_path)
    n_rows, nj = 70, arm.n
    rng = np.random.default_rng(7)
    lo, hi = arm.qlim.T
    q_true = lo + (hi - lo) * rng.random((n_rows, nj))
    T, _ = reference.fk(arm.description, q_true)
    q0 = np.clip(q_true + rng.normal(0, 0.1, q_true.shape), lo, hi)
    bad = np.zeros(n_rows, dtype=int)
    T[3, 0, 3] = np.nan
    q0[10, 1] = np.inf
    bad[[3, 10]] = 1
    arrays = "".join(
        [
            c_array("TT", T),
            c_array("Q0", q0),
            c_array("QLIM", arm.qlim),
            c_array("BAD", bad, "int"),
        ]
    )
    source = IK_DRIVER % dict(name=name, n=n_rows, nj=nj, arrays=arrays)
    if nj < 6:
        source = source.replace("{1, 1, 1, 1, 1, 1}}", "{1, 1, 1, 0, 0, 1}}")
    (tmp_path / "driver.c").write_text(source)
    module = f"serial_{name}.c"
    if name.startswith("long"):
        # the long arms' generated kernels are big and tested elsewhere: instrumenting them
        # (-g) costs minutes, so the runtime and the driver alone run under the sanitizers
        # (the module's object is the -O2 one of test_long_arms_compile_warning_free)
        module = str(objects(module, [*STRICT, "-O2", "-Warray-bounds=2"]))
    # the runtime's instrumented objects, built once per test run for every driver that
    # links them (tests/c/test_fuzz_sanitizers.py's too): STRICT_SANITIZED, the flags below
    # but -g, which shapes no code
    runtime = [str(objects(source, STRICT_SANITIZED)) for source in RUNTIME_SOURCES]
    strict_gcc(
        # -O0: an instrumented module compiles ~3x faster than at -O1 (same checks at run time)
        [*STRICT, "-O0", *sanitizers, "driver.c", module, *runtime, "-o", "driver", "-lm"],
        cwd=tmp_path,
    )
    env = dict(
        os.environ,
        ASAN_OPTIONS="detect_leaks=1:detect_stack_use_after_return=1",
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
    )
    proc = subprocess.run(
        [str(tmp_path / "driver")],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.stderr == "", proc.stderr[-3000:]
