"""The delta core's generated C on its own, as a motion-controller user would take it:
strict C99 compiles warning-free, needs only libm and has no global data, and a driver
program (written here, linked with -fsanitize=address,undefined) evaluates batches with NaN
and unreachable rows, sizes that are not a multiple of the block size, 3 and 4 axes, checks
fk/ik round trips and the documented return codes, and runs clean; the 5-axis module, and
several modules in one program. The arm modules: tests/c/test_standalone_serial.py."""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess

import numpy as np
import pytest
from delta_oracles import DEFAULT, KLIPPER, random_q, well_conditioned
from helpers import (
    GCC,
    LIBM,
    STRICT,
    STRICT_SANITIZED,
    c_array,
    check_symbols,
    copy_runtime,
    core_build_flags,
    runtime_sources,
    strict_gcc,
)

from deltagen import paths
from deltagen.native.build import compile_flags
from deltagen.reference import delta as ref
from deltagen.status import INVALID, OK, UNREACHABLE

pytestmark = pytest.mark.skipif(GCC is None, reason="gcc not installed")

#: the vector-math variant of the delta core, tested whatever the machine's build uses
VECTOR_MATH = [*STRICT, "-O3", "-fno-math-errno", "-fopenmp-simd", "-DDELTAGEN_DELTA_VECTOR_MATH"]


def test_runtime_reads_no_arm_switch():
    for path in paths.runtime_dir().glob("deltagen_*.[ch]"):
        assert "VECTOR_MATH" not in path.read_text(), path.name


@pytest.mark.parametrize("opt", ["-O0", "-O2", "-O3"])
def test_strict_c99_compiles_warning_free(objects, opt):
    objects("delta_kinematics.c", [*STRICT, opt])


def test_compiles_warning_free_with_the_build_flags(objects):
    """The flags deltagen.native.build uses for the cffi core (its extension flags, vector
    math included where available), plus -pedantic -Werror (helpers.core_build_flags: the
    object tests/apps/test_export.py links into its package built as the core is)."""
    flags = core_build_flags("deltagen_delta")
    objects("delta_kinematics.c", flags)
    if "-DDELTAGEN_DELTA_VECTOR_MATH" not in flags:  # test the vector-math variant regardless
        objects("delta_kinematics.c", VECTOR_MATH)


@pytest.mark.parametrize("flags", [[*STRICT, "-O2"], VECTOR_MATH], ids=["O2", "vector-math"])
def test_object_needs_only_libm_and_has_no_global_data(objects, flags):
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm not installed")
    obj = objects("delta_kinematics.c", flags)
    table = subprocess.run([nm, str(obj)], capture_output=True, text=True, check=True).stdout
    defined, undefined = {}, set()
    for line in table.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] == "U":
            undefined.add(parts[1])
        elif len(parts) == 3:
            defined[parts[2]] = parts[1]
    functions = {name for name, kind in defined.items() if kind == "T"}
    assert functions == {
        "deltagen_delta_fk",
        "deltagen_delta_fk_vel",
        "deltagen_delta_fk_acc",
        "deltagen_delta_jacobian",
        "deltagen_delta_ik",
        "deltagen_delta_ik_vel",
        "deltagen_delta_ik_acc",
        "deltagen_delta_fk_param_jacobian",
        "deltagen_delta_inverse_dynamics",
        "deltagen_delta_inverse_dynamics_simplified",
    }
    data = {name: kind for name, kind in defined.items() if kind in "DdBbCGgSsVv"}
    assert not data, f"writable global/static data: {data}"
    external = {re.sub(r"^_ZGV\w+?_", "", name) for name in undefined}
    assert external <= LIBM, f"needs more than libm: {sorted(external - LIBM)}"


# ------------------------------------------------------------------------- the driver


def _batch(geom, n_rows, seed):
    """n_rows crank angles (columns q1..q3, phi), expected fk statuses (numpy reference),
    a round-trip flag, and positions for ik with expected statuses."""
    rng = np.random.default_rng(seed)
    q = np.column_stack([random_q(rng, n_rows), rng.uniform(-3, 3, n_rows)])
    unreachable_pool = rng.uniform(-math.pi, math.pi, size=(5000, 3))
    _, s_pool = ref.fk(geom, unreachable_pool)
    unreachable = unreachable_pool[s_pool == UNREACHABLE]
    rows_unreachable = [5, 64, n_rows - 1]
    q[rows_unreachable, :3] = unreachable[:3]
    q[[0, 70], 1] = np.nan
    q[100, 2] = np.inf
    p, status = ref.fk(geom, q[:, :3])
    round_trip = (status == OK) & well_conditioned(geom, q, p)
    targets = np.column_stack([p, rng.uniform(-3, 3, n_rows)])
    targets[[3, 90], :3] = [[0.0, 0.0, -5.0], [2.0, 2.0, -0.5]]  # beyond l_a + l_b
    targets[[7], 0] = -np.inf
    _, s_ik = ref.ik(geom, targets[:, :3])
    assert {OK, UNREACHABLE, INVALID} <= set(status.tolist())
    assert {OK, UNREACHABLE, INVALID} <= set(s_ik.tolist())
    return q, status, round_trip, targets, s_ik


DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "delta_kinematics.h"

#define N %(n)d
%(arrays)s
static int failures = 0;
#define CHECK(cond, ...) do { if (!(cond)) { ++failures; printf("FAIL line %%d: ", __LINE__); \
    printf(__VA_ARGS__); printf("\n"); } } while (0)

static double q_in[N * 4], qd_in[N * 4], qdd_in[N * 4], p_out[N * 4], pd_out[N * 4],
    pdd_out[N * 4], q_back[N * 4], J_out[N * 9], ik_in[N * 4];
static int8_t st[N], st2[N];

static void load(double *dst, const double *src, size_t axes)
{
    for (size_t i = 0; i < N; ++i) {
        for (size_t c = 0; c < axes; ++c) {
            dst[i * axes + c] = src[i * 4 + c];
        }
    }
}

static void run_axes(const deltagen_delta_geometry *g, size_t axes)
{
    load(q_in, Q, axes);
    for (size_t i = 0; i < N * axes; ++i) {
        qd_in[i] = 0.25 * (double)(i %% 7) - 0.5;
        qdd_in[i] = 0.5 * (double)(i %% 5) - 1.0;
    }
    for (size_t i = 0; i < N; ++i) {  /* keep rate inputs finite except where q is not */
        if (!(isfinite(q_in[i * axes]) && isfinite(q_in[i * axes + 1]) && isfinite(q_in[i * axes + 2]))) {
            qd_in[i * axes] = 0.0;
        }
    }
    CHECK(deltagen_delta_fk(g, N, axes, q_in, p_out, st) == 0, "fk rc");
    for (size_t i = 0; i < N; ++i) {
        CHECK(st[i] == FK_STATUS[i], "fk status row %%zu axes %%zu: %%d != %%d", i, axes, st[i], FK_STATUS[i]);
        if (FK_STATUS[i] == DELTAGEN_OK) {
            CHECK(isfinite(p_out[i * axes]) && isfinite(p_out[i * axes + 1]) && isfinite(p_out[i * axes + 2]),
                  "fk row %%zu not finite", i);
            if (axes == 4) {
                CHECK(p_out[i * 4 + 3] == q_in[i * 4 + 3], "fourth axis row %%zu", i);
            }
        } else {
            for (size_t c = 0; c < axes; ++c) {
                CHECK(isnan(p_out[i * axes + c]), "failed fk row %%zu col %%zu not NaN", i, c);
            }
        }
    }
    /* ik of fk: the elbow-out rows come back */
    CHECK(deltagen_delta_ik(g, N, axes, p_out, q_back, st2) == 0, "ik rc");
    for (size_t i = 0; i < N; ++i) {
        if (ROUND_TRIP[i]) {
            CHECK(st2[i] == DELTAGEN_OK, "ik status row %%zu: %%d", i, st2[i]);
            for (size_t c = 0; c < axes; ++c) {
                CHECK(fabs(q_back[i * axes + c] - q_in[i * axes + c]) <= 1e-12,
                      "round trip row %%zu col %%zu: %%.17g vs %%.17g", i, c, q_back[i * axes + c], q_in[i * axes + c]);
            }
        }
        if (FK_STATUS[i] != DELTAGEN_OK) {
            CHECK(st2[i] == DELTAGEN_INVALID, "ik of a NaN row %%zu: %%d", i, st2[i]);
        }
    }
    /* velocity, acceleration, Jacobian: same statuses, J qd = pd, fk_acc's pd = fk_vel's */
    CHECK(deltagen_delta_fk_vel(g, N, axes, q_in, qd_in, p_out, pd_out, st2) == 0, "fk_vel rc");
    CHECK(deltagen_delta_jacobian(g, N, axes, q_in, J_out, st) == 0, "jacobian rc");
    double pd_keep[N * 4];
    memcpy(pd_keep, pd_out, sizeof pd_keep);
    for (size_t i = 0; i < N; ++i) {
        CHECK(st[i] == st2[i], "jacobian vs fk_vel status row %%zu", i);
        if (st[i] == DELTAGEN_OK) {
            for (size_t r = 0; r < 3; ++r) {
                double s = 0.0, scale = 0.0;
                for (size_t c = 0; c < 3; ++c) {
                    s += J_out[i * 9 + r * 3 + c] * qd_in[i * axes + c];
                    scale += fabs(J_out[i * 9 + r * 3 + c] * qd_in[i * axes + c]);
                }
                CHECK(fabs(s - pd_out[i * axes + r]) <= 1e-13 * (scale + 1e-300), "J qd row %%zu", i);
            }
        } else {
            for (size_t k = 0; k < 9; ++k) {
                CHECK(isnan(J_out[i * 9 + k]), "failed J row %%zu not NaN", i);
            }
        }
    }
    CHECK(deltagen_delta_fk_acc(g, N, axes, q_in, qd_in, qdd_in, p_out, pd_out, pdd_out, st2) == 0, "fk_acc rc");
    for (size_t i = 0; i < N; ++i) {
        CHECK(st[i] == st2[i], "fk_acc status row %%zu", i);
        for (size_t c = 0; c < axes; ++c) {
            if (st2[i] == DELTAGEN_OK) {
                CHECK(pd_out[i * axes + c] == pd_keep[i * axes + c] ||
                      fabs(pd_out[i * axes + c] - pd_keep[i * axes + c]) <= 1e-15 * (1.0 + fabs(pd_keep[i * axes + c])),
                      "fk_acc pd row %%zu", i);
                CHECK(isfinite(pdd_out[i * axes + c]), "pdd row %%zu", i);
            } else {
                CHECK(isnan(pdd_out[i * axes + c]), "failed pdd row %%zu not NaN", i);
            }
        }
    }
    /* inverse dynamics, both models: fk_acc's statuses, finite torques where OK, NaN
     * elsewhere; column 4 = I_4 qdd_4 */
    double payload[N], tau_out[N * 4];
    for (size_t i = 0; i < N; ++i) {
        payload[i] = 0.1 * (double)(i %% 4);
    }
    for (int model = 0; model < 2; ++model) {
        CHECK((model ? deltagen_delta_inverse_dynamics_simplified : deltagen_delta_inverse_dynamics)(
                  g, N, axes, q_in, qd_in, qdd_in, payload, tau_out, st) == 0, "inverse_dynamics rc");
        for (size_t i = 0; i < N; ++i) {
            CHECK(st[i] == st2[i], "inverse_dynamics status row %%zu", i);
            for (size_t c = 0; c < 3; ++c) {
                CHECK(st[i] == DELTAGEN_OK ? isfinite(tau_out[i * axes + c]) : isnan(tau_out[i * axes + c]),
                      "tau row %%zu col %%zu", i, c);
            }
            if (axes == 4 && st[i] == DELTAGEN_OK) {
                CHECK(tau_out[i * 4 + 3] == g->I_4 * qdd_in[i * 4 + 3], "tau_4 row %%zu", i);
            }
        }
    }
    CHECK(deltagen_delta_inverse_dynamics(g, 2, 3, q_in, qd_in, qdd_in, NULL, tau_out, st) == -1,
          "inverse_dynamics NULL payload");
    /* ik on positions with unreachable and non-finite rows */
    load(ik_in, P, axes);
    CHECK(deltagen_delta_ik(g, N, axes, ik_in, q_back, st2) == 0, "ik rc");
    for (size_t i = 0; i < N; ++i) {
        CHECK(st2[i] == IK_STATUS[i], "ik status row %%zu axes %%zu: %%d != %%d", i, axes, st2[i], IK_STATUS[i]);
        if (IK_STATUS[i] == DELTAGEN_UNREACHABLE || IK_STATUS[i] == DELTAGEN_INVALID) {
            for (size_t c = 0; c < 3; ++c) {
                CHECK(isnan(q_back[i * axes + c]), "failed ik row %%zu not NaN", i);
            }
        } else if (axes == 4) {
            CHECK(q_back[i * 4 + 3] == ik_in[i * 4 + 3], "ik fourth axis row %%zu", i);
        }
    }
    /* the n-point call equals point-by-point calls (block boundaries are invisible) */
    load(q_in, Q, axes);
    CHECK(deltagen_delta_fk(g, N, axes, q_in, p_out, st) == 0, "fk rc");
    for (size_t i = 0; i < N; ++i) {
        double one[4];
        int8_t s1;
        CHECK(deltagen_delta_fk(g, 1, axes, q_in + i * axes, one, &s1) == 0, "fk(1) rc");
        CHECK(s1 == st[i], "single-point status row %%zu", i);
        for (size_t c = 0; c < axes && s1 == DELTAGEN_OK; ++c) {
            CHECK(fabs(one[c] - p_out[i * axes + c]) <= 1e-15, "single-point fk row %%zu", i);
        }
    }
}

static void return_codes(const deltagen_delta_geometry *g)
{
    double a[8] = {0.1, 0.2, 0.3, 0.4, 0.1, 0.2, 0.3, 0.4}, b[8] = {0}, c[8] = {0};
    double o1[18], o2[8], o3[8];
    int8_t s[2] = {42, 42};
    const size_t bad_axes[] = {0, 1, 2, 5, 9};
    for (size_t k = 0; k < sizeof bad_axes / sizeof bad_axes[0]; ++k) {
        size_t ax = bad_axes[k];
        for (size_t i = 0; i < 18; ++i) o1[i] = 7.0;
        CHECK(deltagen_delta_fk(g, 2, ax, a, o1, s) == -1, "fk axes %%zu", ax);
        CHECK(deltagen_delta_fk_vel(g, 2, ax, a, b, o1, o2, s) == -1, "fk_vel axes %%zu", ax);
        CHECK(deltagen_delta_fk_acc(g, 2, ax, a, b, c, o1, o2, o3, s) == -1, "fk_acc axes %%zu", ax);
        CHECK(deltagen_delta_jacobian(g, 2, ax, a, o1, s) == -1, "jacobian axes %%zu", ax);
        CHECK(deltagen_delta_ik(g, 2, ax, a, o1, s) == -1, "ik axes %%zu", ax);
        CHECK(o1[0] == 7.0 && s[0] == 42, "something was written for axes %%zu", ax);
    }
    /* NULL pointers with n > 0: -1, nothing written */
    CHECK(deltagen_delta_fk(NULL, 2, 3, a, o1, s) == -1, "fk NULL geometry");
    CHECK(deltagen_delta_fk(g, 2, 3, NULL, o1, s) == -1, "fk NULL q");
    CHECK(deltagen_delta_fk(g, 2, 3, a, NULL, s) == -1, "fk NULL p");
    CHECK(deltagen_delta_fk(g, 2, 3, a, o1, NULL) == -1, "fk NULL status");
    CHECK(deltagen_delta_fk_vel(g, 2, 3, a, NULL, o1, o2, s) == -1, "fk_vel NULL qd");
    CHECK(deltagen_delta_fk_vel(g, 2, 3, a, b, o1, NULL, s) == -1, "fk_vel NULL pd");
    CHECK(deltagen_delta_fk_acc(g, 2, 3, a, b, NULL, o1, o2, o3, s) == -1, "fk_acc NULL qdd");
    CHECK(deltagen_delta_fk_acc(g, 2, 3, a, b, c, o1, o2, NULL, s) == -1, "fk_acc NULL pdd");
    CHECK(deltagen_delta_jacobian(g, 2, 3, a, NULL, s) == -1, "jacobian NULL J");
    CHECK(deltagen_delta_jacobian(NULL, 2, 3, a, o1, s) == -1, "jacobian NULL geometry");
    CHECK(deltagen_delta_ik(g, 2, 3, NULL, o1, s) == -1, "ik NULL p");
    CHECK(deltagen_delta_ik(g, 2, 4, a, o1, NULL) == -1, "ik NULL status");
    CHECK(s[0] == 42 && s[1] == 42, "status written on error");
    /* n = 0: nothing to do, success even with NULL arrays */
    CHECK(deltagen_delta_fk(g, 0, 3, NULL, NULL, NULL) == 0, "fk n=0");
    CHECK(deltagen_delta_fk_acc(g, 0, 4, NULL, NULL, NULL, NULL, NULL, NULL, NULL) == 0, "fk_acc n=0");
    CHECK(deltagen_delta_ik(g, 0, 3, NULL, NULL, NULL) == 0, "ik n=0");
}

int main(void)
{
    deltagen_delta_geometry g;
    g.r_a = %(r_a)s;
    g.r_b = %(r_b)s;
    g.l_a = %(l_a)s;
    g.l_b = %(l_b)s;
    for (int i = 0; i < 3; ++i) {
        g.cos_theta[i] = COS_THETA[i];
        g.sin_theta[i] = SIN_THETA[i];
        g.chain_r[i] = g.r_a - g.r_b; /* a symmetric robot: every chain alike */
        g.chain_l_a[i] = g.l_a;
        g.chain_l_b[i] = g.l_b;
    }
    g.singular_tol = 1e-9;
    g.I_a = 0.037;
    g.m_a = 0.6;
    g.r_ca = 0.15;
    g.m_b = 0.2;
    g.m_p = 0.5;
    g.gravity[0] = 0.0;
    g.gravity[1] = 0.0;
    g.gravity[2] = -9.81;
    g.I_4 = 2e-4;
    run_axes(&g, 3);
    run_axes(&g, 4);
    return_codes(&g);
    /* print fk of the batch (3 axes) for the Python side */
    load(q_in, Q, 3);
    deltagen_delta_fk(&g, N, 3, q_in, p_out, st);
    for (size_t i = 0; i < N; ++i) {
        printf("%%d %%a %%a %%a\n", st[i], p_out[i * 3], p_out[i * 3 + 1], p_out[i * 3 + 2]);
    }
    if (failures) {
        printf("%%d FAILURES\n", failures);
        return 1;
    }
    return 0;
}
"""


def _driver_source(geom, n_rows, seed):
    q, status, round_trip, targets, s_ik = _batch(geom, n_rows, seed)
    arrays = "".join(
        [
            c_array("Q", q),
            c_array("FK_STATUS", status, "int8_t"),
            c_array("ROUND_TRIP", round_trip.astype(int), "int"),
            c_array("P", targets),
            c_array("IK_STATUS", s_ik, "int8_t"),
            c_array("COS_THETA", np.cos(geom.theta)),
            c_array("SIN_THETA", np.sin(geom.theta)),
        ]
    )
    source = DRIVER % dict(
        n=n_rows,
        arrays=arrays,
        r_a=geom.r_a.hex(),
        r_b=geom.r_b.hex(),
        l_a=geom.l_a.hex(),
        l_b=geom.l_b.hex(),
    )
    return source, q, status, round_trip


def _build_flags():
    """The cffi build's compile flags and libraries (vector math where available)."""
    args, libraries = compile_flags("deltagen_delta")
    return list(args), [f"-l{lib}" for lib in libraries]


@pytest.mark.slow
@pytest.mark.parametrize(
    "geom,n_rows,variant",
    [
        (DEFAULT, 131, "plain"),
        (KLIPPER, 200, "plain"),
        (DEFAULT, 257, "build-flags"),
    ],
    ids=["default-131-plain", "klipper-200-plain", "default-257-build-flags"],
)
def test_driver_under_sanitizers(source_dir, objects, sanitizers, tmp_path, geom, n_rows, variant):
    assert n_rows % 64 != 0
    source, q, status, round_trip = _driver_source(geom, n_rows, seed=n_rows)
    assert round_trip.sum() > n_rows // 2
    driver = tmp_path / "driver.c"
    driver.write_text(source)
    exe = tmp_path / "driver"
    if variant == "plain":
        # -O0: the plain drivers check memory and UB faults and the numbers, which the
        # sanitizers see at any level (instrumented C compiles ~3x faster than at -O1); the
        # optimised code under the sanitizers is the build-flags variant's (-O3, vector math).
        # The core's instrumented object is tests/c/test_fuzz_sanitizers.py's too
        # (STRICT_SANITIZED: these flags and sanitizers without -g, which shapes no code)
        flags, libs = [*STRICT, "-O0"], ["-lm"]
        core = objects("delta_kinematics.c", STRICT_SANITIZED)
    else:
        flags, libs = _build_flags()
        flags = [*flags, "-pedantic", "-Werror"]
        core = objects("delta_kinematics.c", [*flags, *sanitizers])
    strict_gcc(
        [*flags, *sanitizers, f"-I{source_dir}", str(driver), str(core), "-o", str(exe), *libs],
        cwd=tmp_path,
    )
    env = dict(
        os.environ,
        ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:detect_stack_use_after_return=1",
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
    )
    proc = subprocess.run(
        [str(exe)], capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path
    )
    failures = [
        line for line in proc.stdout.splitlines() if line.startswith("FAIL") or "FAILURES" in line
    ]
    assert proc.returncode == 0, "\n".join(failures[:30]) + proc.stderr[-3000:]
    assert proc.stderr == "", f"sanitizer output:\n{proc.stderr[-3000:]}"
    assert not failures

    # the standalone build's numbers agree with the numpy reference
    lines = proc.stdout.splitlines()
    assert len(lines) == n_rows
    got_status = np.array([int(line.split()[0]) for line in lines])
    got_p = np.array(
        [
            [float.fromhex(v) if v not in ("nan", "-nan") else math.nan for v in line.split()[1:]]
            for line in lines
        ]
    )
    np.testing.assert_array_equal(got_status, status)
    p_ref, _ = ref.fk(geom, q[:, :3])
    ok = status == OK
    np.testing.assert_allclose(got_p[ok], p_ref[ok], rtol=0, atol=1e-12 * geom.size)
    assert np.all(np.isnan(got_p[~ok]))


# ------------------------------------------------- several modules in one program

ONE_PROGRAM = r"""
#include <math.h>
#include <stdio.h>
#include "delta_kinematics.h"
#include "serial_puma560.h"
#include "serial_manutec_h5.h"
#include "serial_delta.h"

int main(void)
{
    deltagen_delta_geometry g = {%(r_a)s, %(r_b)s, %(l_a)s, %(l_b)s,
                                 {%(r_a)s - %(r_b)s, %(r_a)s - %(r_b)s, %(r_a)s - %(r_b)s},
                                 {%(l_a)s, %(l_a)s, %(l_a)s}, {%(l_b)s, %(l_b)s, %(l_b)s},
                                 {%(cos)s}, {%(sin)s}, 1e-9,
                                 0.037, 0.6, 0.15, 0.2, 0.5, {0.0, 0.0, -9.81}, 2e-4};
    double qd[3] = {0.1, 0.2, 0.3}, p[3], T[16], T6[16], J6[36], q6[6] = {0.1, -0.4, 0.3, 0.2, 0.5, -0.1};
    double q4[4] = {0.2, -0.3, 0.1, 0.4}, q0[6], q[6], ep, er;
    int32_t it;
    int8_t s;
    int failures = 0;
    failures += deltagen_delta_fk(&g, 1, 3, qd, p, &s) != 0 || s != DELTAGEN_OK;
    failures += deltagen_puma560_fk_jacobian(1, q6, T6, J6, &s) != 0 || s != DELTAGEN_OK;
    failures += deltagen_manutec_h5_fk(1, q4, T, &s) != 0 || s != DELTAGEN_OK;
    failures += deltagen_delta_arm_fk(1, qd, T, &s) != 0 || s != DELTAGEN_OK;
    failures += deltagen_delta_arm_jacobian(1, qd, J6, &s) != 0 || s != DELTAGEN_OK;
    for (int i = 0; i < 6; ++i) {
        q0[i] = q6[i] + 0.01;
    }
    deltagen_ik_options o = {1e-10, 1e-10, 0.5, 1.0, 0.1, 100, 0, 0, 0, {1, 1, 1, 1, 1, 1}, 0, 0};
    failures += deltagen_puma560_ik_newton(1, &o, T6, q0, NULL, q, &ep, &er, &it, &s) != 0
        || s != DELTAGEN_OK || fabs(q[0] - q6[0]) > 1e-8;
    printf("%%d failures\n", failures);
    return failures;
}
"""


def test_two_arms_the_delta_core_and_an_arm_named_delta_in_one_program(tmp_path):
    """Every exported symbol carries the project prefix: the delta core, two arm modules, a
    user arm named `delta` (its functions become deltagen_delta_arm_*) and the runtime
    compile and link into one program, all headers in one translation unit."""
    from deltagen.codegen.serial import arm_sources
    from deltagen.model.serial import SerialDescription

    for base in ("delta_kinematics", "serial_puma560", "serial_manutec_h5"):
        for ext in (".c", ".h"):
            shutil.copy(paths.generated_dir() / f"{base}{ext}", tmp_path)
    rows = [
        dict(a=0.3, alpha=0.0, d=0.0),
        dict(a=0.2, alpha=0.0, d=0.0),
        dict(a=0.1, alpha=0.0, d=0.0),
    ]
    for file_name, text in arm_sources(
        SerialDescription.from_rows(rows, "standard", name="delta")
    ).items():
        (tmp_path / file_name).write_text(text)
    copy_runtime(tmp_path)
    assert "int deltagen_delta_arm_fk(" in (tmp_path / "serial_delta.h").read_text()
    geom = DEFAULT
    (tmp_path / "main.c").write_text(
        ONE_PROGRAM
        % dict(
            r_a=geom.r_a.hex(),
            r_b=geom.r_b.hex(),
            l_a=geom.l_a.hex(),
            l_b=geom.l_b.hex(),
            cos=", ".join(float(c).hex() for c in np.cos(geom.theta)),
            sin=", ".join(float(s).hex() for s in np.sin(geom.theta)),
        )
    )
    sources = [
        "main.c",
        "delta_kinematics.c",
        "serial_puma560.c",
        "serial_manutec_h5.c",
        "serial_delta.c",
        *runtime_sources(),
    ]
    # -O0: this program checks the symbols' names and the link, not the optimiser (each
    # module's -O2/-O3 compiles are the other tests of tests/c/test_standalone*.py)
    strict_gcc([*STRICT, "-O0", *sources, "-o", "program", "-lm"], cwd=tmp_path)
    proc = subprocess.run(
        [str(tmp_path / "program")], capture_output=True, text=True, timeout=60, cwd=tmp_path
    )
    assert proc.returncode == 0 and proc.stdout.strip() == "0 failures", proc.stdout


def test_runtime_status_codes_are_deltagen_status():
    """The runtime header's status block equals deltagen/status.py and the generated one."""
    from deltagen import status

    header = (paths.runtime_dir() / "deltagen_ik_newton.h").read_text()
    codes = dict(re.findall(r"#define DELTAGEN_([A-Z]+) (\d+)\n", header))
    assert {int(v): k for k, v in codes.items()} == status.STATUS_NAMES
    generated = (paths.generated_dir() / "delta_kinematics.h").read_text()
    block = header[header.index("#ifndef DELTAGEN_STATUS_CODES") :]
    block = block[: block.index("#endif") + 6]
    assert block in generated


@pytest.mark.parametrize("opt", ["-O0", "-O2", "-O3"])
def test_five_axis_module_compiles_strict_and_needs_only_libm(source_dir, objects, opt):
    """The 5-axis machines' module (generated/five_axis_kinematics.c, no runtime C): strict
    C99 -pedantic -Werror at each level, the build's own flags too (compiled once for the
    three levels), only libm symbols undefined, no global data, and one fk, ik and ik_all
    per layout and rotary pair."""
    obj = str(objects("five_axis_kinematics.c", [*STRICT, opt]))
    args, _ = compile_flags("deltagen_five_axis")
    objects("five_axis_kinematics.c", [*args, "-pedantic", "-Werror"])
    check_symbols([obj], source_dir)
    nm = shutil.which("nm")
    if nm is not None:
        table = subprocess.run([nm, obj], capture_output=True, text=True).stdout
        functions = {line.split()[2] for line in table.splitlines() if " T " in line}
        expected = {
            f"deltagen_five_axis_{layout}_{rotary}_{quantity}"
            for layout in ("table_table", "head_head", "table_head")
            for rotary in ("ac", "bc")
            for quantity in ("fk", "ik", "ik_all")
        }
        assert functions == expected
