"""The linear delta's and the tripod's generated C on their own, as a printer firmware or
a motion controller would take them: strict C99 (-std=c99 -pedantic -Wall -Wextra -Werror)
compiles warning-free at -O0/-O2/-O3, the objects need only libm and hold no global data,
and a driver written here, linked with -fsanitize=address,undefined (at -O0: the
sanitizers check every access at any level), evaluates batches
whose size is not a multiple of the block (with NaN and unreachable rows), checks the fk/ik
round trip and the documented return codes (-1 for a NULL pointer, 0 for n == 0) and runs
clean."""

from __future__ import annotations

import shutil
import subprocess

import pytest
from helpers import GCC, strict_gcc

pytestmark = pytest.mark.skipif(GCC is None, reason="gcc not installed")

STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"]
MODULES = ("linear_delta_kinematics", "tripod_kinematics")
LIBM = {"sqrt", "copysign", "fabs", "pow"}


# source_dir (the private copy of generated/) and objects (each (file, flags) compiled once
# per module, warning-free or the test fails): tests/c/conftest.py


@pytest.mark.parametrize("opt", ["-O0", "-O2", "-O3"])
@pytest.mark.parametrize("module", MODULES)
def test_strict_c99_compiles_warning_free(objects, module, opt):
    objects(f"{module}.c", [*STRICT, opt])


@pytest.mark.parametrize("module", MODULES)
def test_object_needs_only_libm_and_has_no_global_data(objects, module):
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm not installed")
    obj = objects(f"{module}.c", [*STRICT, "-O2"])  # the -O2 object compiled warning-free above
    table = subprocess.run([nm, str(obj)], capture_output=True, text=True).stdout
    undefined, kinds = set(), set()
    for line in table.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] == "U":
            undefined.add(parts[1])
        elif len(parts) == 3:
            kinds.add(parts[1])
    assert undefined <= LIBM, undefined - LIBM
    assert kinds <= {"T", "t", "r", "R"}, kinds  # code and constants only: no data, no bss


DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "linear_delta_kinematics.h"
#include "tripod_kinematics.h"

#define N 131  /* not a multiple of the block (64) */

static int fail(const char *what) { fprintf(stderr, "FAIL %s\n", what); return 1; }

int main(void)
{
    deltagen_linear_delta_geometry ld = {
        {-0.0866025403784, 0.0866025403784, 0.0}, {-0.05, -0.05, 0.1}, {0.25, 0.25, 0.25}, 1e-9};
    deltagen_tripod_geometry tp = {1.0, 0.5, 0.8, 1.0, 1e-9};
    double *p = malloc(sizeof(double) * 3 * N), *q = malloc(sizeof(double) * 3 * N);
    double *back = malloc(sizeof(double) * 3 * N), *J = malloc(sizeof(double) * 9 * N);
    int8_t *status = malloc(N), *status2 = malloc(N);
    if (!p || !q || !back || !J || !status || !status2) return fail("malloc");
    for (int pass = 0; pass < 2; ++pass) {
        for (int k = 0; k < N; ++k) {
            double t = 0.05 * k;
            p[3 * k + 0] = 0.05 * cos(t);
            p[3 * k + 1] = 0.05 * sin(t);
            p[3 * k + 2] = pass == 0 ? 0.1 + 0.001 * k : 0.3 + 0.002 * k;
        }
        p[3 * 7 + 0] = NAN;          /* INVALID */
        if (pass == 0) p[3 * 11 + 0] = 5.0;  /* UNREACHABLE: out of the arms' reach */
        else p[3 * 11 + 2] = -1.0;           /* UNREACHABLE: the other side of the base */
        int rc = pass == 0 ? deltagen_linear_delta_ik(&ld, N, p, q, status)
                           : deltagen_tripod_ik(&tp, N, p, q, status);
        if (rc != 0) return fail("ik rc");
        if (status[7] != DELTAGEN_INVALID || status[11] != DELTAGEN_UNREACHABLE) return fail("ik status");
        rc = pass == 0 ? deltagen_linear_delta_fk(&ld, N, q, back, status2)
                       : deltagen_tripod_fk(&tp, N, q, back, status2);
        if (rc != 0) return fail("fk rc");
        for (int k = 0; k < N; ++k) {
            if (status[k] != DELTAGEN_OK) continue;
            if (status2[k] != DELTAGEN_OK) return fail("fk status");
            for (int c = 0; c < 3; ++c)
                if (fabs(back[3 * k + c] - p[3 * k + c]) > 1e-12) return fail("round trip");
        }
        rc = pass == 0 ? deltagen_linear_delta_jacobian(&ld, N, q, J, status2)
                       : deltagen_tripod_jacobian(&tp, N, q, J, status2);
        if (rc != 0 || status2[7] != DELTAGEN_INVALID) return fail("jacobian");
    }
    if (deltagen_linear_delta_fk(&ld, 0, NULL, NULL, NULL) != 0) return fail("n == 0");
    if (deltagen_linear_delta_fk(NULL, 1, q, p, status) != -1) return fail("NULL geometry");
    if (deltagen_tripod_ik(&tp, 1, NULL, q, status) != -1) return fail("NULL input");
    free(p); free(q); free(back); free(J); free(status); free(status2);
    printf("ok\n");
    return 0;
}
"""


def test_sanitized_driver(source_dir, tmp_path):
    (tmp_path / "driver.c").write_text(DRIVER)
    sources = [str(source_dir / f"{m}.c") for m in MODULES]
    # -O0: the driver checks memory and UB faults and numbers, not optimised code (the -O2 and
    # -O3 objects are the tests above); instrumented C compiles ~3x faster than at -O1
    flags = [*STRICT, "-O0", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    strict_gcc(
        [*flags, f"-I{source_dir}", "driver.c", *sources, "-lm", "-o", "driver"], cwd=tmp_path
    )
    run = subprocess.run(["./driver"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stdout + run.stderr
