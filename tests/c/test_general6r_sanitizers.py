"""The general 6R C (codegen/runtime/deltagen_general6r.c, deltagen_eigen.c) under
AddressSanitizer and UndefinedBehaviorSanitizer: a driver links them, built with
-fsanitize=address,undefined -fno-sanitize-recover=all -Werror, and runs
deltagen_general6r_starts on poses of a random arm and of the Jaco-like shifted UR5 (with
NaN, huge and non-rigid poses mixed in), deltagen_eigvals_batch on fuzzed matrices (NaN,
inf, huge, subnormal, zero) of every size 1..30, and deltagen_general6r_finish. Every array
is heap-allocated with exactly the documented size. Checks: the run is clean and its
results equal those of the cffi module (the same C, other flags: to 1e-9)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from helpers import GCC, STRICT_SANITIZED, copy_runtime, random_6r_arm, shared_object

from deltagen import SerialRobot
from deltagen.solve import general6r

pytestmark = [pytest.mark.skipif(GCC is None, reason="gcc not installed"), pytest.mark.slow]
native_g6r = pytest.importorskip("deltagen.native.general6r")


DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "deltagen_general6r.h"

/* usage: driver IN OUT. IN (doubles): the arm struct's fields in declaration order (ints
 * as doubles), then count, count x 16 T; then m, n, m x n x n matrices; then N, S,
 * N x S x 6 qs, N x S conv, 12 qlim. OUT: q, margin, status; wr, wi, status; fitted, q,
 * valid, found (all as doubles). */
static double *in;
static size_t at;
static double next(void) { return in[at++]; }
static double *take(size_t k)
{
    double *p = malloc((k ? k : 1) * sizeof(double));
    memcpy(p, in + at, k * sizeof(double));
    at += k;
    return p;
}
static void put(FILE *f, const double *p, size_t k) { fwrite(p, sizeof(double), k, f); }
static void put_int(FILE *f, const int *p, size_t k)
{
    for (size_t i = 0; i < k; ++i) {
        double d = p[i];
        fwrite(&d, sizeof d, 1, f);
    }
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    in = malloc((size_t)size);
    if (fread(in, 1, (size_t)size, f) != (size_t)size) {
        return 3;
    }
    fclose(f);
    FILE *out = fopen(argv[2], "wb");

    deltagen_general6r_arm *arm = malloc(sizeof *arm);
    double *p;
    p = take(16); memcpy(arm->T0inv, p, sizeof arm->T0inv); free(p);
    p = take(18); memcpy(arm->w, p, sizeof arm->w); free(p);
    p = take(18); memcpy(arm->o, p, sizeof arm->o); free(p);
    for (int j = 0; j < 6; ++j) arm->order[j] = (int)next();
    arm->shift = (int)next();
    arm->reverse = (int)next();
    arm->left_mode = (int)next();
    p = take(378); memcpy(arm->left_fixed, p, sizeof arm->left_fixed); free(p);
    p = take(3); memcpy(arm->delta, p, sizeof arm->delta); free(p);
    p = take(81); memcpy(arm->B2inv, p, sizeof arm->B2inv); free(p);
    p = take(729); memcpy(arm->B3inv, p, sizeof arm->B3inv); free(p);
    p = take(729); memcpy(arm->half3, p, sizeof arm->half3); free(p);
    double *start = take(12);
    const double cond = next(), imag_tol = next();
    const int count = (int)next();
    double *T = take((size_t)count * 16);
    double *q = malloc((size_t)count * 96 * sizeof(double));
    double *margin = malloc((size_t)count * sizeof(double));
    int *status = malloc((size_t)count * sizeof(int));
    deltagen_general6r_starts(T, count, arm, cond, imag_tol, start, q, margin, status);
    put(out, q, (size_t)count * 96);
    put(out, margin, (size_t)count);
    put_int(out, status, (size_t)count);

    const int m = (int)next(), n = (int)next();
    double *A = take((size_t)m * n * n);
    double *wr = malloc((size_t)m * n * sizeof(double)), *wi = malloc((size_t)m * n * sizeof(double));
    int *st = malloc((size_t)m * sizeof(int));
    deltagen_eigvals_batch(A, m, n, wr, wi, st);
    put(out, wr, (size_t)m * n);
    put(out, wi, (size_t)m * n);
    put_int(out, st, (size_t)m);

    const int N = (int)next(), S = (int)next();
    double *qs = take((size_t)N * S * 6);
    double *convd = take((size_t)N * S);
    unsigned char *conv = malloc((size_t)N * S);
    for (size_t i = 0; i < (size_t)N * S; ++i) conv[i] = (unsigned char)convd[i];
    double *qlim = take(12);
    double *fitted = malloc((size_t)N * S * 6 * sizeof(double));
    double *qo = malloc((size_t)N * 96 * sizeof(double));
    unsigned char *valid = malloc((size_t)N * 16);
    int *found = malloc((size_t)N * sizeof(int));
    deltagen_general6r_finish(qs, conv, N, S, qlim, 1, fitted, qo, valid, found);
    put(out, qo, (size_t)N * 96);
    for (size_t i = 0; i < (size_t)N * 16; ++i) {
        double d = valid[i];
        put(out, &d, 1);
    }
    put_int(out, found, (size_t)N);
    fclose(out);
    free(arm); free(start); free(T); free(q); free(margin); free(status); free(A); free(wr);
    free(wi); free(st); free(qs); free(convd); free(conv); free(qlim); free(fitted); free(qo);
    free(valid); free(found); free(in);
    return 0;
}
"""


def _arm_fields(g):
    nat = g._native().struct
    fields = [nat.T0inv, nat.w, nat.o]
    out = [np.array(list(x)) for x in fields]
    out.append(np.array(list(nat.order), dtype=float))
    out.append(np.array([nat.shift, nat.reverse, nat.left_mode], dtype=float))
    out += [np.array(list(x)) for x in (nat.left_fixed, nat.delta, nat.B2inv, nat.B3inv)]
    out.append(np.array(list(nat.half3)))
    return out


def _fuzz(rng, shape):
    x = rng.standard_normal(shape)
    specials = np.array([np.nan, np.inf, -np.inf, 1e300, 1e-310, 0.0, -0.0, 1e155])
    hit = rng.random(shape) < 0.02
    x[hit] = rng.choice(specials, hit.sum())
    return x


@pytest.mark.parametrize("which", ["random", "ur5"])
def test_general6r_c_under_sanitizers(which, tmp_path):
    if which == "ur5":
        arm = SerialRobot.load("ur5", backend="reference")
    else:
        arm = random_6r_arm(17, "san6r")
    (g,), _ = arm._general()
    rng = np.random.default_rng(18)
    T = arm.fk(rng.uniform(-np.pi, np.pi, (24, 6)))
    T[3, 0, 1] = np.nan
    T[5, :3, 3] = 1e300
    T[7, :3, :3] *= 1.5  # not a rotation
    cond, imag_tol = general6r.COND_STANDARD, g.imag_tol
    mats = [_fuzz(rng, (8, n, n)) for n in (1, 2, 3, 5, 13, 24, 30)]
    qs = _fuzz(rng, (6, 20, 6)) * 2.0
    conv = (rng.random((6, 20)) < 0.7).astype(float)
    qlim = np.array([[-2.5, 2.5], [-np.inf, np.inf]] + [[-np.pi, np.pi]] * 4)
    copy_runtime(tmp_path)  # all of it: the objects' keys are the other drivers' (below)
    results = []
    for A in mats:
        work = tmp_path / f"n{A.shape[1]}"
        work.mkdir()
        blob = np.concatenate(
            _arm_fields(g)
            + [general6r._START, [cond, imag_tol, float(T.shape[0])], T.ravel()]
            + [[float(A.shape[0]), float(A.shape[1])], A.ravel()]
            + [[6.0, 20.0], qs.ravel(), conv.ravel(), qlim.ravel()]
        )
        (work / "in.bin").write_bytes(blob.astype("<f8").tobytes())
        results.append((A, work))
    (tmp_path / "driver.c").write_text(DRIVER)
    # the runtime's instrumented objects: built once per test run, warning-free, for both
    # arms and the other sanitized drivers of tests/c/ (helpers.shared_object)
    runtime = [
        str(shared_object(tmp_path, f"{name}.c", STRICT_SANITIZED))
        for name in ("deltagen_general6r", "deltagen_eigen", "deltagen_linalg")
    ]
    build = subprocess.run(
        [GCC, *STRICT_SANITIZED, "driver.c", *runtime, "-o", "driver", "-lm"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0 and not build.stderr.strip(), build.stderr[-3000:]
    qn, mn, sn = g._native().starts(T, cond, imag_tol, general6r._START)
    fq, fv, ff = native_g6r.finish(qs, conv.astype(bool), qlim, True)
    for A, work in results:
        run = subprocess.run(
            [str(tmp_path / "driver"), "in.bin", "out.bin"],
            cwd=work,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert run.returncode == 0 and not run.stderr.strip(), run.stderr[-3000:]
        out = np.fromfile(work / "out.bin", dtype="<f8")
        N, m, n = T.shape[0], A.shape[0], A.shape[1]
        parts = np.split(out, np.cumsum([N * 96, N, N, m * n, m * n, m, 6 * 96, 6 * 16]))
        q, margin, status, wr, wi, st, q2, valid, found = parts
        assert np.array_equal(status, sn) and np.array_equal(np.isnan(q), np.isnan(qn.ravel()))
        ok = np.isfinite(q)
        assert np.allclose(q[ok], qn.ravel()[ok], rtol=0, atol=1e-9)
        assert np.allclose(margin, mn, equal_nan=True)
        lam, stc = native_g6r.eigvals(A)
        assert np.array_equal(st, stc)
        good = stc == 0
        assert (st[~good] != 0).all() and np.isnan(wr.reshape(m, n)[~good]).all()
        for i in np.flatnonzero(good):  # the same eigenvalues (other flags: to rounding)
            a = np.sort_complex(wr.reshape(m, n)[i] + 1j * wi.reshape(m, n)[i])
            b = np.sort_complex(lam[i])
            assert np.allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())
        assert np.array_equal(found, ff) and np.array_equal(valid.reshape(6, 16), fv)
        assert np.array_equal(np.isnan(q2), np.isnan(fq.ravel()))
