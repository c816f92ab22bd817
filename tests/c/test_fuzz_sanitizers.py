"""The generated C under AddressSanitizer and UndefinedBehaviorSanitizer with fuzzed inputs:
one driver program links the delta core, the Puma 560 module and the runtime
(generated/*.c, codegen/runtime/*.c), built with -fsanitize=address,undefined
-fno-sanitize-recover=all -Wall -Wextra -Werror, and is run on random batches -- ordinary
values mixed with NaN, +-inf, huge (1e155, 1e300, 1.7e308), subnormal and -0.0 entries --
of n = 0, 1, block size +- 1 and sizes that are not a multiple of the block size. Every
array it hands the kernels is heap-allocated with exactly the documented size, so any read
or write past a row is a sanitizer error.

Each run writes every output and status to a file; the checks here: the run is clean, every
status is a documented code, OK rows are finite (the finite-output rule), INVALID rows are
NaN, and OK rows agree with the numpy reference (tests/c/test_standalone.py holds the
hand-written delta driver with exact expectations; this one is the fuzzing complement)."""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest
from delta_oracles import DEFAULT
from helpers import GCC, STRICT_SANITIZED, compile_c, shared_object

from deltagen import paths
from deltagen.reference import delta as ref_delta
from deltagen.reference import serial as ref_serial
from deltagen.status import INVALID, OK, STATUS_NAMES

pytestmark = [pytest.mark.skipif(GCC is None, reason="gcc not installed"), pytest.mark.slow]

SIZES = (0, 1, 2, 63, 64, 65, 131)  # the block is 64 points
ARM = "puma560"
NJ, BRANCHES = 6, 8
MODULES = ("delta_kinematics.c", f"serial_{ARM}.c")

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "delta_kinematics.h"
#include "serial_puma560.h"

#define NJ %(nj)d
#define BRANCHES %(branches)d

/* usage: driver IN OUT. IN: n (as a double), then n x 4 q, qd, qdd, p; n x 6 q6, qd6;
 * n x 16 T. OUT: every output and status (statuses as doubles), in the order below. */
static FILE *out;

static double *take(FILE *in, size_t count)
{
    double *a = malloc(count ? count * sizeof(double) : 1);
    if (a == NULL || fread(a, sizeof(double), count, in) != count) {
        fprintf(stderr, "short input\n");
        exit(2);
    }
    return a;
}

static double *fresh(size_t count)  /* exactly count doubles, poisoned */
{
    double *a = malloc(count ? count * sizeof(double) : 1);
    for (size_t i = 0; i < count; ++i) {
        a[i] = 12345.0;
    }
    return a;
}

static void put(const double *a, size_t count)
{
    fwrite(a, sizeof(double), count, out);
}

static void put_status(const int8_t *s, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        const double v = (double)s[i];
        fwrite(&v, sizeof(double), 1, out);
    }
}

static double *narrow(const double *rows4, size_t n, size_t axes)  /* n x 4 -> n x axes */
{
    double *a = fresh(n * axes);
    for (size_t i = 0; i < n; ++i) {
        for (size_t c = 0; c < axes; ++c) {
            a[i * axes + c] = rows4[i * 4 + c];
        }
    }
    return a;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        return 2;
    }
    FILE *in = fopen(argv[1], "rb");
    out = fopen(argv[2], "wb");
    if (in == NULL || out == NULL) {
        return 2;
    }
    double n_d;
    if (fread(&n_d, sizeof n_d, 1, in) != 1) {
        return 2;
    }
    const size_t n = (size_t)n_d;
    double *q4 = take(in, 4 * n), *qd4 = take(in, 4 * n), *qdd4 = take(in, 4 * n);
    double *p4 = take(in, 4 * n), *q6 = take(in, NJ * n), *qd6 = take(in, NJ * n);
    double *T = take(in, 16 * n);
    int8_t *st = malloc(n ? n : 1);
    int rc = 0;

    deltagen_delta_geometry g = {%(r_a)s, %(r_b)s, %(l_a)s, %(l_b)s,
        {%(r_a)s - %(r_b)s, %(r_a)s - %(r_b)s, %(r_a)s - %(r_b)s},  /* per chain: symmetric */
        {%(l_a)s, %(l_a)s, %(l_a)s}, {%(l_b)s, %(l_b)s, %(l_b)s}, {%(cos)s}, {%(sin)s}, 1e-9,
        0.01, 1.0, 0.1, 0.2, 0.5, {0.0, 0.0, -9.81}, 0.0};  /* inertia: unused here */
    for (size_t axes = 3; axes <= 4; ++axes) {
        double *q = narrow(q4, n, axes), *qd = narrow(qd4, n, axes), *qdd = narrow(qdd4, n, axes);
        double *p_in = narrow(p4, n, axes);
        double *p = fresh(n * axes), *pd = fresh(n * axes), *pdd = fresh(n * axes);
        double *J = fresh(9 * n), *q_out = fresh(n * axes);
        rc |= deltagen_delta_fk(&g, n, axes, q, p, st);
        put(p, n * axes); put_status(st, n);
        rc |= deltagen_delta_fk_vel(&g, n, axes, q, qd, p, pd, st);
        put(p, n * axes); put(pd, n * axes); put_status(st, n);
        rc |= deltagen_delta_fk_acc(&g, n, axes, q, qd, qdd, p, pd, pdd, st);
        put(p, n * axes); put(pd, n * axes); put(pdd, n * axes); put_status(st, n);
        rc |= deltagen_delta_jacobian(&g, n, axes, q, J, st);
        put(J, 9 * n); put_status(st, n);
        rc |= deltagen_delta_ik(&g, n, axes, p_in, q_out, st);
        put(q_out, n * axes); put_status(st, n);
        free(q); free(qd); free(qdd); free(p_in); free(p); free(pd); free(pdd); free(J);
        free(q_out);
    }

    double *T_out = fresh(16 * n), *F = fresh(16 * (NJ + 2) * n), *J6 = fresh(6 * NJ * n);
    double *Jd = fresh(6 * NJ * n), *q_all = fresh(BRANCHES * NJ * n);
    uint8_t *valid = malloc(n ? BRANCHES * n : 1);
    rc |= deltagen_puma560_fk(n, q6, T_out, st);
    put(T_out, 16 * n); put_status(st, n);
    rc |= deltagen_puma560_frames(n, q6, F, st);
    put(F, 16 * (NJ + 2) * n); put_status(st, n);
    rc |= deltagen_puma560_jacobian(n, q6, J6, st);
    put(J6, 6 * NJ * n); put_status(st, n);
    rc |= deltagen_puma560_fk_jacobian(n, q6, T_out, J6, st);
    put(T_out, 16 * n); put(J6, 6 * NJ * n); put_status(st, n);
    rc |= deltagen_puma560_jacobian_dot(n, q6, qd6, Jd, st);
    put(Jd, 6 * NJ * n); put_status(st, n);
    rc |= deltagen_puma560_ik_all(n, T, q_all, valid, st);
    put(q_all, BRANCHES * NJ * n);
    for (size_t i = 0; i < BRANCHES * n; ++i) {
        const double v = valid[i];
        fwrite(&v, sizeof v, 1, out);
    }
    put_status(st, n);

    deltagen_ik_options o = {1e-10, 1e-10, 0.5, 1.0, 0.1, 50, 0, 1, 1, {1, 1, 1, 1, 1, 1}, 0, 0};
    const double qlim[2 * NJ] = {-3, 3, -3, 3, -3, 3, -3, 3, -3, 3, -3, 3};
    double *q_ik = fresh(NJ * n), *ep = fresh(n), *er = fresh(n);
    int32_t *it = malloc(n ? n * sizeof(int32_t) : 1);
    rc |= deltagen_puma560_ik_newton(n, &o, T, q6, qlim, q_ik, ep, er, it, st);
    put(q_ik, NJ * n); put(ep, n); put(er, n); put_status(st, n);

    free(q4); free(qd4); free(qdd4); free(p4); free(q6); free(qd6); free(T); free(st);
    free(T_out); free(F); free(J6); free(Jd); free(q_all); free(valid); free(q_ik); free(ep);
    free(er); free(it);
    fclose(in);
    fclose(out);
    return rc == 0 ? 0 : 3;
}
"""

SPECIAL = np.array(
    [np.nan, np.inf, -np.inf, 1e155, -1e155, 1e300, -1e300, 1.7e308, 5e-324, -2.5e-310, -0.0]
)


def _sprinkle(rng, a, rate=0.08):
    """Replace about ``rate`` of the entries of ``a`` by special values."""
    mask = rng.random(a.shape) < rate
    a[mask] = rng.choice(SPECIAL, size=int(mask.sum()))
    return a


def _inputs(n, seed):
    rng = np.random.default_rng(seed)
    q4 = _sprinkle(rng, rng.uniform(-1.0, 2.0, (n, 4)))
    qd4 = _sprinkle(rng, rng.normal(size=(n, 4)))
    qdd4 = _sprinkle(rng, rng.normal(size=(n, 4)))
    p4 = rng.uniform(-0.5, 0.5, (n, 4)) + [0.0, 0.0, -0.8, 0.0]
    p4 = _sprinkle(rng, p4)
    q6 = _sprinkle(rng, rng.uniform(-2.5, 2.5, (n, NJ)))
    qd6 = _sprinkle(rng, rng.normal(size=(n, NJ)))
    from deltagen.model.serial import SerialDescription

    desc = SerialDescription.from_toml(paths.robots_dir() / f"{ARM}.toml")
    T, _ = ref_serial.fk(desc, rng.uniform(-2.5, 2.5, (n, NJ)))
    T = T.reshape(n, 16)
    _sprinkle(rng, T[:, :12], 0.03)
    return desc, dict(q4=q4, qd4=qd4, qdd4=qdd4, p4=p4, q6=q6, qd6=qd6, T=T)


class _Reader:
    def __init__(self, data):
        self.data, self.at = data, 0

    def __call__(self, *shape):
        count = int(np.prod(shape))
        part = self.data[self.at : self.at + count]
        self.at += count
        return part.reshape(shape)


def _check(name, status, *outputs):
    """Documented codes; OK rows finite (the finite-output rule); INVALID rows NaN."""
    assert set(np.unique(status).astype(int)) <= set(STATUS_NAMES), name
    ok = status == OK
    for out in outputs:
        flat = out if out.ndim == 2 else out.reshape(len(status), 1)
        assert np.all(np.isfinite(flat[ok])), f"{name}: non-finite value in an OK row"
        assert np.all(np.isnan(flat[status == INVALID])), f"{name}: INVALID row not NaN"


@pytest.fixture(scope="module")
def driver(tmp_path_factory, sanitizers):
    work = tmp_path_factory.mktemp("c_fuzz")
    for name in MODULES:
        for ext in (".c", ".h"):
            shutil.copy(paths.generated_dir() / name.replace(".c", ext), work)
    for path in paths.runtime_dir().glob("deltagen_*.[ch]"):
        shutil.copy(path, work)
    g = DEFAULT
    (work / "driver.c").write_text(
        DRIVER
        % dict(
            r_a=g.r_a.hex(),
            r_b=g.r_b.hex(),
            l_a=g.l_a.hex(),
            l_b=g.l_b.hex(),
            cos=", ".join(float(np.cos(t)).hex() for t in g.theta),
            sin=", ".join(float(np.sin(t)).hex() for t in g.theta),
            nj=NJ,
            branches=BRANCHES,
        )
    )
    # the instrumented objects of the modules and the runtime are built once per run (the
    # Puma's is shared with tests/derive/test_ik_closed_form.py's driver, the delta core's
    # and the runtime's with tests/c/test_standalone*.py's)
    modules = [shared_object(work, name, STRICT_SANITIZED) for name in MODULES]
    runtime = [shared_object(work, p.name, STRICT_SANITIZED) for p in work.glob("deltagen_*.c")]
    sources = ["driver.c", *modules, *sorted(runtime)]
    return compile_c(sources, work / "driver", flags=STRICT_SANITIZED, cwd=work, sanitize=True)


@pytest.mark.parametrize("n", SIZES)
def test_fuzzed_batches_under_sanitizers(driver, tmp_path, n):
    desc, x = _inputs(n, seed=1000 + n)
    blob = np.concatenate([[float(n)], *(x[k].ravel() for k in x)])
    (tmp_path / "in.bin").write_bytes(blob.astype("<f8").tobytes())
    env = dict(
        os.environ,
        ASAN_OPTIONS="detect_leaks=1:detect_stack_use_after_return=1",
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
    )
    proc = subprocess.run(
        [str(driver), "in.bin", "out.bin"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr == "", proc.stderr[-3000:]
    read = _Reader(np.frombuffer((tmp_path / "out.bin").read_bytes(), dtype="<f8"))
    g = DEFAULT
    for axes in (3, 4):
        q, qd, qdd, p_in = (x[k][:, :axes] for k in ("q4", "qd4", "qdd4", "p4"))
        p, s = read(n, axes), read(n)
        _check("fk", s, p)
        p_ref, s_ref = ref_delta.fk(g, q)
        both = (s == OK) & (s_ref == OK)
        np.testing.assert_allclose(p[both], p_ref[both], rtol=0, atol=1e-9 * g.size)
        p, pd, s = read(n, axes), read(n, axes), read(n)
        _check("fk_vel", s, p, pd)
        p, pd, pdd, s = read(n, axes), read(n, axes), read(n, axes), read(n)
        _check("fk_acc", s, p, pd, pdd)
        J, s = read(n, 9), read(n)
        _check("jacobian", s, J)
        q_out, s = read(n, axes), read(n)
        _check("ik", s, q_out)
        q_ref, s_ref = ref_delta.ik(g, p_in)
        both = (s == OK) & (s_ref == OK)
        np.testing.assert_allclose(q_out[both], q_ref[both], rtol=0, atol=1e-9)
    T, s = read(n, 16), read(n)
    _check("fk", s, T)
    T_ref, s_ref = ref_serial.fk(desc, x["q6"])
    both = (s == OK) & (s_ref == OK)
    np.testing.assert_allclose(T[both], T_ref.reshape(n, 16)[both], rtol=0, atol=1e-9)
    F, s = read(n, 16 * (NJ + 2)), read(n)
    _check("frames", s, F)
    J, s = read(n, 6 * NJ), read(n)
    _check("jacobian", s, J)
    T2, J2, s2 = read(n, 16), read(n, 6 * NJ), read(n)
    _check("fk_jacobian", s2, T2, J2)
    np.testing.assert_array_equal(s2, s)
    Jd, s = read(n, 6 * NJ), read(n)
    _check("jacobian_dot", s, Jd)
    q_all, valid, s = read(n, BRANCHES * NJ), read(n, BRANCHES), read(n)
    assert set(np.unique(valid)) <= {0.0, 1.0}
    branches = q_all.reshape(n, BRANCHES, NJ)
    assert np.all(np.isfinite(branches[valid == 1])), "ik_all: a valid branch not finite"
    assert np.all(np.isnan(q_all[s == INVALID]))
    assert np.all((s == OK) == valid.any(axis=1)) if n else True
    q_ik, ep, er, s = read(n, NJ), read(n), read(n), read(n)
    _check("ik_newton", s, q_ik, ep, er)
    assert read.at == read.data.size
