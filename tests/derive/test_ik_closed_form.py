"""The closed-form IK emitted as C (deltagen/derive/serial/ik_closed_form.py, `deltagen_<arm>_ik_all`).

Evidence: the numpy solver of solve/analytic.py through the reference backend (the same
recipe, derive/serial/ik_recipes.py, on numpy arrays, but its own forward-kinematics check
on the product-of-exponentials model and its own limits fit: this compares the back ends,
not the closed form); forward kinematics of every valid branch and the configuration the
pose was made from among the valid branches (independent of the recipe: a wrong step in it
fails here and in tests/solve); the C alone under ASan/UBSan on poses with NaN, infinite,
unreachable and non-rigid rows."""

from __future__ import annotations

import math
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers import STRICT_SANITIZED, compile_c, shared_object
from hypothesis import example, given, settings
from hypothesis import strategies as hst

from deltagen import SerialRobot, paths
from deltagen.api.serial import bundled_robots
from deltagen.derive.serial.ik_closed_form import SUPPORTED, compiled_structure
from deltagen.status import INVALID, OK, UNREACHABLE

CENTRAL_WRIST = ("puma560", "motoman_up6", "manutec_r15")
C_ARMS = CENTRAL_WRIST + ("miskolc_rrrr", "lecture_scara", "manutec_h5", "bosch_sr800")


@pytest.fixture(scope="module", params=C_ARMS)
def arms(request, serial_arms):
    return (serial_arms(request.param), serial_arms(request.param, "reference"))


def _in_limit_q(arm, count, seed):
    rng = np.random.default_rng(seed)
    lim = arm.qlim
    lo, hi = np.maximum(lim[:, 0], -math.pi), np.minimum(lim[:, 1], math.pi)
    return rng.uniform(lo, hi, size=(count, arm.n))


def _angle_diff(a, b):
    return np.remainder(a - b + math.pi, 2 * math.pi) - math.pi


def test_kernel_exists_exactly_for_the_supported_structures():
    for name in bundled_robots():
        arm = SerialRobot.load(name, backend="reference")
        solver = arm._analytic()
        has_c = compiled_structure(arm.description) is not None
        assert has_c == (solver is not None and solver.structure in SUPPORTED), name
        header = (paths.generated_dir() / f"serial_{name}.h").read_text()
        assert (f"deltagen_{name}_ik_all(" in header) == has_c, name
    assert {
        n
        for n in bundled_robots()
        if compiled_structure(SerialRobot.load(n, backend="reference").description)
    } >= set(C_ARMS)


def test_c_matches_numpy_solver_on_random_poses(arms):
    compiled, reference = arms
    q = _in_limit_q(compiled, 20000, seed=7)
    T = compiled.fk(q)
    qc, vc = compiled.ik_all(T)
    qn, vn = reference.ik_all(T)
    np.testing.assert_array_equal(vc, vn)
    np.testing.assert_array_equal(np.isfinite(qc), np.isfinite(qn))
    both = np.isfinite(qc)
    # near the stretched elbow arccos is ill-conditioned (ik_analytic docstring): 1e-6
    assert np.max(np.abs(_angle_diff(qc, qn)[both])) < 1e-6
    # every valid branch reproduces the pose (the C's own check uses 1e-8)
    Tb = compiled.fk(np.where(both, qc, 0.0).reshape(-1, compiled.n)).reshape(T.shape[0], -1, 4, 4)
    err = np.abs(Tb - T[:, None])[vc]
    assert err.max() < 1e-10
    # the configuration the pose came from is among the valid branches
    hit = np.all(np.abs(_angle_diff(qc, q[:, None])) < 1e-6, axis=-1) & vc
    assert np.mean(hit.any(axis=1)) > 0.999
    assert np.all(vc.any(axis=1))


def test_limits_and_nan_semantics(arms):
    compiled, _ = arms
    q = _in_limit_q(compiled, 2000, seed=11)
    qc, vc = compiled.ik_all(compiled.fk(q))
    lim = compiled.qlim
    finite = np.all(np.isfinite(qc), axis=-1)
    inside = np.all((qc >= lim[:, 0]) & (qc <= lim[:, 1]), axis=-1)
    np.testing.assert_array_equal(vc, finite & inside)  # valid = solved and inside
    assert np.all(np.isfinite(qc) | np.isnan(qc))
    assert np.all(np.isfinite(qc).all(-1) | np.isnan(qc).all(-1))  # a branch is all or nothing


def test_status_codes_for_unreachable_invalid_and_non_rigid_rows():
    arm = SerialRobot.load("puma560")
    core = arm._core
    T = np.tile(arm.fk(np.array([0.1, 0.7, -0.5, 0.3, 0.4, 0.2])), (5, 1, 1))
    T[1, :3, 3] += [5.0, 0.0, 0.0]  # far out of reach
    T[2, 0, 3] = np.nan
    T[3, 1, 1] = np.inf
    T[4, :3, :3] *= 1.01  # not a rotation: no branch reproduces it
    q, valid, status = core.ik_all(np.ascontiguousarray(T), 8)
    assert status.tolist() == [OK, UNREACHABLE, INVALID, INVALID, UNREACHABLE]
    assert valid[0].any() and not valid[1:].any()
    assert np.all(np.isnan(q[1:]))


def test_wrist_singular_pose_is_solved():
    """q5 = 0: axes 4 and 6 in line; q4 is set to 0 and q6 takes the whole turn."""
    arm = SerialRobot.load("puma560")
    q = np.array([0.2, 0.6, -0.8, 0.7, 0.0, -0.4])
    T = arm.fk(q)
    qc, vc = arm.ik_all(T)
    assert vc.any()
    for k in np.flatnonzero(vc):
        np.testing.assert_allclose(arm.fk(qc[k]), T, atol=1e-12)
    assert np.any(np.abs(qc[vc][:, 3]) < 1e-12)


def test_single_pose_fast_path_equals_batch():
    arm = SerialRobot.load("puma560")
    q = _in_limit_q(arm, 50, seed=3)
    T = arm.fk(q)
    qb, vb = arm.ik_all(T)
    for i in range(len(T)):
        qs, vs = arm.ik_all(T[i])  # after the first batched call: the fast path
        np.testing.assert_array_equal(vs, vb[i])
        np.testing.assert_array_equal(qs, qb[i])
        # a non-contiguous or list input takes the general path: same answer
        qg, vg = arm.ik_all(np.asfortranarray(T[i]))
        np.testing.assert_array_equal(qg, qb[i])
        qg, vg = arm.ik_all(T[i].tolist())
        np.testing.assert_array_equal(vg, vb[i])
        if vb[i].any():
            k = int(np.argmax(vb[i]))
            np.testing.assert_array_equal(arm.ik(T[i]), qb[i, k])
            name = arm.analytic_configs()[k]
            np.testing.assert_array_equal(arm.ik(T[i], config=name), qb[i, k])


def test_fast_path_leaves_errors_to_the_general_path():
    from deltagen import UnreachableError
    from deltagen.inputs import InputError

    arm = SerialRobot.load("puma560")
    T = arm.fk(np.zeros(6))
    arm.ik_all(T[None])
    bad = T.copy()
    bad[3, 3] = 2.0
    with pytest.raises(InputError, match="rigid"):
        arm.ik(bad)
    q, valid = arm.ik_all(bad)
    assert not valid.any()
    far = T.copy()
    far[0, 3] = 9.0
    with pytest.raises(UnreachableError):
        arm.ik(far)
    with pytest.raises(InputError, match="unknown configuration"):
        arm.ik(T, config="sideways")


@settings(max_examples=60, deadline=None)
@given(hst.lists(hst.floats(-1.0, 1.0), min_size=6, max_size=6))
# q4 exactly at its lower limit: the branch came back 1.04e-12 below it (geometry.limits)
@example(unit=[0.0, 0.0, 0.0, -1.0, -0.5, 0.0])
# ... and with q5 = -0.0068 rad, where its rounding (1.8e-10) exceeds LIMIT_TOL
@example(unit=[0.0, 0.0, 0.0, -1.0, -0.0068 / 1.745329, 0.0])
def test_property_pose_of_q_is_solved_back(unit):
    arm = SerialRobot.load("puma560")
    lim = arm.qlim
    q = lim[:, 0] + (np.array(unit) + 1.0) / 2.0 * (lim[:, 1] - lim[:, 0])
    T = arm.fk(q)
    qc, vc = arm.ik_all(T)
    assert vc.any()
    for k in np.flatnonzero(vc):
        np.testing.assert_allclose(arm.fk(qc[k]), T, rtol=0, atol=1e-10)
    close = np.all(np.abs(_angle_diff(qc, q)) < 1e-6, axis=-1) & vc
    # the original is among the branches unless q5 ~ 0 (q4 and q6 are not unique there), or
    # q4 or q6 lies on a limit closer than its rounding near the wrist singularity: the
    # closed form gives q4, q6 to ~1e-12 / |sin q5| (1.8e-10 at q5 = -0.0068), and a value
    # more than LIMIT_TOL (1e-10) outside a limit is outside (geometry/limits.py)
    wrist_error = 1e-11 / max(abs(math.sin(q[4])), 1e-300)
    on_limit = any(min(abs(q[j] - lim[j, 0]), abs(q[j] - lim[j, 1])) < wrist_error for j in (3, 5))
    assert close.any() or abs(q[4]) < 1e-6 or on_limit


# ------------------------------------------------------------ the C alone, sanitized


DRIVER = r"""
#include <stdio.h>
#include <math.h>
#include "serial_puma560.h"

#define N %(n)d
static const double T_IN[N * 16] = {%(poses)s};

int main(void) {
    static double q[N * 48];
    static uint8_t valid[N * 8];
    static int8_t status[N];
    int failures = 0;
    if (deltagen_puma560_ik_all(N, T_IN, q, valid, status) != 0) {
        printf("FAIL rc\n");
        return 1;
    }
    if (deltagen_puma560_ik_all(N, NULL, q, valid, status) != -1) {
        printf("FAIL NULL T accepted\n");
        failures++;
    }
    if (deltagen_puma560_ik_all(0, NULL, NULL, NULL, NULL) != 0) {
        printf("FAIL n = 0\n");
        failures++;
    }
    for (size_t i = 0; i < N; ++i) {
        printf("%%d", (int)status[i]);
        for (size_t b = 0; b < 8; ++b) {
            printf(" %%d", valid[i * 8 + b] == 1);
        }
        for (size_t c = 0; c < 48; ++c) {
            printf(" %%a", q[i * 48 + c]);
        }
        printf("\n");
    }
    return failures;
}
"""


@pytest.mark.slow
def test_ik_all_alone_under_sanitizers(tmp_path, sanitizers):
    arm = SerialRobot.load("puma560")
    q = _in_limit_q(arm, 150, seed=5)
    T = arm.fk(q)
    T[10, :3, 3] += 4.0
    T[20, 2, 2] = np.nan
    T[30, 0, 3] = -np.inf
    T[40, :3, :3] *= 0.9
    T[50, :3, 3] = 1e300
    poses = ", ".join(
        float(x).hex()
        if np.isfinite(x)
        else ("NAN" if np.isnan(x) else ("INFINITY" if x > 0 else "-INFINITY"))
        for x in T.reshape(-1)
    )
    for name in ("serial_puma560.c", "serial_puma560.h"):
        shutil.copy(paths.generated_dir() / name, tmp_path)
    runtime = sorted(paths.runtime_dir().glob("deltagen_*.[ch]"))  # the module's ik_newton needs it
    for path in runtime:
        shutil.copy(path, tmp_path)
    (tmp_path / "driver.c").write_text(DRIVER % dict(n=len(T), poses=poses))
    # the module's instrumented object (strict C99 at -O0: 3x faster to compile than at
    # -O1, the sanitizers see every access either way) is the one
    # tests/c/test_fuzz_sanitizers.py's driver links: built once per run
    module = shared_object(tmp_path, "serial_puma560.c", STRICT_SANITIZED)
    runtime_c = [p.name for p in runtime if p.suffix == ".c"]
    flags = ["-std=c99", "-O0", "-Wall", "-Wextra", "-Werror", *sanitizers]
    compile_c(["driver.c", module, *runtime_c], tmp_path / "driver", flags=flags, cwd=tmp_path)
    env = dict(os.environ, UBSAN_OPTIONS="halt_on_error=1")
    run = subprocess.run(
        [str(tmp_path / "driver")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    assert run.stderr == ""
    rows = [line.split() for line in run.stdout.splitlines()]
    status = np.array([int(r[0]) for r in rows])
    valid = np.array([[v == "1" for v in r[1:9]] for r in rows])
    q_c = np.array(
        [[float.fromhex(v) if "nan" not in v else math.nan for v in r[9:]] for r in rows]
    ).reshape(len(T), 8, 6)
    assert status[20] == INVALID and status[30] == INVALID
    assert status[10] == UNREACHABLE and status[40] == UNREACHABLE and status[50] == UNREACHABLE
    # the standalone build at -O1 agrees with the numpy solver
    ref = SerialRobot.load("puma560", backend="reference")
    safe = np.where(np.isfinite(T), T, 0.0)
    safe[:, 3] = [0, 0, 0, 1]
    q_n, v_n = ref._analytic().solve(safe)
    rows_ok = np.isin(status, (OK, UNREACHABLE))
    np.testing.assert_array_equal(valid[rows_ok], v_n[rows_ok])
    both = np.isfinite(q_c) & np.isfinite(q_n)
    assert np.max(np.abs(_angle_diff(q_c, q_n)[both])) < 1e-6


# ------------------------------------------------------------ exact singular targets


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_exactly_singular_target_raises_or_masks(backend):
    """q5 = 0 (axes 4 and 6 in line): the branch that reaches the pose there has no unique
    q4, q6. Raise mode: SingularityError naming the row; nan mode: NaN and False;
    singular='allow': a solution that reaches the pose."""
    from deltagen import SingularityError
    from deltagen.inputs import InputError

    arm = SerialRobot.load("puma560", backend=backend)
    regular = np.array([0.3, 0.5, -0.4, 0.2, 0.6, -0.3])
    wrist = np.array([0.3, 0.5, -0.4, 0.2, 0.0, -0.3])
    T = arm.fk(np.stack([regular, wrist]))
    k_wrist = int(
        np.flatnonzero(
            np.all(np.abs(_angle_diff(arm.ik_all(T[1])[0][:, [0, 1, 2]], wrist[:3])) < 1e-9, -1)
            & (np.abs(arm.ik_all(T[1])[0][:, 4]) < 1e-9)
        )[0]
    )
    config = arm.analytic_configs()[k_wrist]
    for target in (T[1], T[1].copy(order="F")):  # fast path and general path
        with pytest.raises(SingularityError, match="singularity") as info:
            arm.ik(target, config=config)
        assert info.value.rows.tolist() == [0]
    q, ok = arm.ik(T, config=config, errors="nan")
    assert not ok[1] and np.all(np.isnan(q[1]))
    q1 = arm.ik(T[1], config=config, singular="allow")
    np.testing.assert_allclose(arm.fk(q1), T[1], atol=1e-12)
    # numerical IK converging onto the singular target is reported the same way
    with pytest.raises(SingularityError):
        arm.ik(T[1], q0=wrist + 0.01, method="numeric")
    assert arm.condition_number(wrist) > 1e12
    with pytest.raises(InputError, match="singular"):
        arm.ik(T[0], singular="maybe")


# ------------------------------------------------- numerical ik: the single-target path


def test_numeric_single_target_path_equals_general_path():
    """arm.ik(T, method="numeric") for one (4, 4) array takes ik_numeric.single_solver;
    its answer must be the general path's (which an explicit default option forces)."""
    from deltagen.solve import numeric as ik_numeric

    arm = SerialRobot.load("puma560")
    q = _in_limit_q(arm, 60, seed=21)
    T = arm.fk(q)
    mid = arm._start(None, 1)[0]
    for i in range(len(T)):
        fast = arm.ik(T[i], method="numeric", errors="nan", restarts=30, seed=1)
        general = arm.ik(T[i], method="numeric", errors="nan", restarts=30, seed=1, tol=1e-10)
        np.testing.assert_array_equal(fast[0], general[0])
        assert bool(fast[1]) == bool(general[1])
        if fast[1]:
            np.testing.assert_allclose(arm.fk(fast[0]), T[i], rtol=0, atol=1e-9)
        q0 = q[i] + 0.05
        np.testing.assert_array_equal(
            arm.ik(T[i], q0=q0, method="numeric"), arm.ik(T[i], q0=q0.tolist(), method="numeric")
        )
    # the fast path's first attempt is solve()'s first attempt
    single = ik_numeric.single_solver(arm)
    res = ik_numeric.solve(arm, T, np.tile(mid, (len(T), 1)), restarts=0)
    for i in range(len(T)):
        got = single(np.ascontiguousarray(T[i]), np.ascontiguousarray(mid), 0)
        if res.converged[i]:
            np.testing.assert_array_equal(got, res.q[i])
        else:
            assert got is None


def test_numeric_single_target_errors_come_from_the_general_path():
    from deltagen import UnreachableError
    from deltagen.inputs import InputError

    arm = SerialRobot.load("puma560")
    T = arm.fk(np.array([0.1, 0.4, -0.3, 0.2, 0.5, 0.1]))
    arm.ik(T, method="numeric")
    far = T.copy()
    far[0, 3] = 5.0
    with pytest.raises(UnreachableError):
        arm.ik(far, method="numeric")
    q, ok = arm.ik(far, method="numeric", errors="nan")
    assert not ok and np.all(np.isnan(q))
    bad = T.copy()
    bad[1, 1] = np.nan
    with pytest.raises(InputError, match=r"NaN or infinite values in rows \[0\]"):
        arm.ik(bad, method="numeric")
    with pytest.raises(InputError):
        arm.ik(T, method="numeric", restarts=-1)
