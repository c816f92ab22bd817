"""The compiled Newton engine of numerical IK (<arm>_ik_newton in each generated arm module,
``ik_numeric.solve(..., engine="c")``).

The evidence is independent of the C routine: every solution is checked with the numpy
reference kinematics (deltagen.reference.serial), joint limits are checked here, and the
numpy engine (a separate implementation of the same iteration) must land on the same
solution from the same near start.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import random_q, reference_fk, rotation_angle

from deltagen import status as st
from deltagen.api.serial import SerialRobot
from deltagen.inputs import InputError
from deltagen.reference import serial as reference
from deltagen.solve import numeric as ikn

SIX_AXIS = ("puma560", "motoman_up6", "manutec_r15")
TOL = 1e-10


@pytest.fixture(scope="module")
def arms(serial_arms):
    return serial_arms


def _check(arm, res, T, rows=None, tol=TOL):
    """Converged rows: within the limits, and the reference fk reproduces T to tol."""
    c = res.converged if rows is None else rows
    assert arm.within_limits(res.q[c]).all()
    Tq = reference_fk(arm, res.q[c])
    dp = np.linalg.norm(Tq[:, :3, 3] - T[c][:, :3, 3], axis=1)
    dr = rotation_angle(Tq[:, :3, :3], T[c][:, :3, :3])
    assert dp.max(initial=0) <= tol + 1e-13, dp.max()
    assert dr.max(initial=0) <= tol + 1e-13, dr.max()


def test_fk_jacobian_kernel_matches_fk_and_jacobian(arms, rng):
    for name in SIX_AXIS + ("manutec_h5", "lecture_prp"):
        arm = arms(name)
        q = random_q(arm, rng, 257)
        q[5, 0] = np.nan
        T, J, status = arm._core.fk_jacobian(np.ascontiguousarray(q))
        T1, s1 = arm._core.fk(q)
        J1, _ = arm._core.jacobian(q)
        np.testing.assert_array_equal(status, s1)
        assert status[5] == st.INVALID and np.isnan(T[5]).all() and np.isnan(J[5]).all()
        ok = status == st.OK
        np.testing.assert_allclose(T[ok], T1[ok], rtol=0, atol=1e-15)
        np.testing.assert_allclose(J[ok], J1[ok], rtol=0, atol=1e-15)


@pytest.mark.parametrize("start", ["random", "qz"])
@pytest.mark.parametrize("name", SIX_AXIS)
def test_six_axis_1000_targets_all_converge(arms, name, start, rng):
    """1000 random reachable in-limit targets, cold starts (random in-limit or "qz"),
    restarts: 100 %, within the limits, fk round trip to 1e-10 (reference fk)."""
    arm = arms(name)
    q_true = random_q(arm, rng, 1000)
    T = reference_fk(arm, q_true)
    q0 = random_q(arm, rng, 1000) if start == "random" else arm.configuration("qz")
    res = ikn.solve(arm, T, q0, restarts=60, seed=5, engine="c")
    assert res.converged.all(), np.flatnonzero(~res.converged)
    assert np.all(res.position_error <= TOL) and np.all(res.rotation_error <= TOL)
    _check(arm, res, T)


@pytest.mark.parametrize("name", SIX_AXIS)
def test_c_and_numpy_engines_agree_from_a_near_start(arms, name, rng):
    """Same targets, same near starts: both engines converge to the same branch (the
    start's), i.e. the same q to well below the tolerance's effect on q."""
    arm = arms(name)
    q_true = random_q(arm, rng, 400, margin=0.05)
    T = reference_fk(arm, q_true)
    lo, hi = arm.qlim.T
    q0 = np.clip(q_true + rng.normal(0.0, 0.05, q_true.shape), lo, hi)
    rc = ikn.solve(arm, T, q0, engine="c")
    rn = ikn.solve(arm, T, q0, engine="numpy")
    both = rc.converged & rn.converged
    assert both.mean() > 0.97
    _check(arm, rc, T)
    _check(arm, rn, T)
    same = np.abs(rc.q - rn.q).max(axis=1) < 1e-7
    assert same[both].mean() > 0.97, np.flatnonzero(both & ~same)
    # and the branch is the start's: mostly q_true itself
    assert np.mean(np.abs(rc.q - q_true).max(axis=1) < 1e-6) > 0.95


def test_scara_with_mask(arms, rng):
    """manutec_h5 (4 axes): the default mask vx vy vz wz, and position only."""
    arm = arms("manutec_h5")
    q_true = random_q(arm, rng, 1000, margin=0.02)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, random_q(arm, rng, 1000), restarts=30, engine="c")
    assert res.mask.tolist() == [1, 1, 1, 0, 0, 1]
    assert res.converged.all()
    _check(arm, res, T)
    res = ikn.solve(
        arm, T, random_q(arm, rng, 1000), restarts=30, engine="c", mask=[1, 1, 1, 0, 0, 0]
    )
    assert res.converged.all() and arm.within_limits(res.q).all()
    Tq = reference_fk(arm, res.q)
    assert np.abs(Tq[:, :3, 3] - T[:, :3, 3]).max() <= 1e-10


def test_under_actuated_planar_and_rrrr(arms, rng):
    for name in ("lecture_scara", "miskolc_rrrr", "bosch_sr800"):
        arm = arms(name)
        q_true = random_q(arm, rng, 300, margin=0.02)
        T = reference_fk(arm, q_true)
        res = ikn.solve(arm, T, random_q(arm, rng, 300), restarts=30, engine="c")
        assert res.converged.all(), (name, np.flatnonzero(~res.converged))
        m = res.mask
        Tq = reference_fk(arm, res.q)
        assert arm.within_limits(res.q).all()
        assert np.abs((Tq[:, :3, 3] - T[:, :3, 3])[:, m[:3]]).max(initial=0) <= 1e-10


def test_redundant_seven_axis(puma7, rng):
    """n = 7 > k = 6: the J J^T form (minimum-norm step)."""
    arm = puma7
    q_true = random_q(arm, rng, 500)
    T = reference_fk(arm, q_true)
    res = ikn.solve(arm, T, random_q(arm, rng, 500), restarts=40, engine="c")
    assert res.converged.all()
    _check(arm, res, T)
    # one step from a near start: the damped minimum-norm step J^T (J J^T + lambda^2 I)^-1 dx
    # (C: Cholesky) equals the numpy engine's (damped SVD), and pinv(J) dx computed here up
    # to the small damping lambda^2 = 0.1 |dx|^2
    q0 = q_true[:50] + 1e-4 * rng.standard_normal((50, 7))
    kw = dict(max_iter=1, restarts=0, step_limit=None, respect_limits=False)
    one = ikn.solve(arm, T[:50], q0, engine="c", **kw)
    one_np = ikn.solve(arm, T[:50], q0, engine="numpy", **kw)
    assert np.allclose(one.q, one_np.q, rtol=0, atol=1e-12)
    J, _ = reference.jacobian(arm.description, q0)
    T0 = reference_fk(arm, q0)
    dx = np.concatenate(
        [
            T[:50, :3, 3] - T0[:, :3, 3],
            ikn.rotation_vector(T[:50, :3, :3] @ np.swapaxes(T0[:, :3, :3], 1, 2)),
        ],
        1,
    )
    expected = np.einsum("nij,nj->ni", np.linalg.pinv(J), dx)
    well = np.linalg.cond(J) < 100
    assert well.sum() > 10
    assert np.allclose((one.q - q0)[well], expected[well], rtol=0, atol=1e-8)
    assert np.abs(one.q - q0).max() > 1e-5


def test_non_finite_rows_are_invalid(arms, rng):
    arm = arms("puma560")
    q_true = random_q(arm, rng, 8)
    T = reference_fk(arm, q_true).copy()
    q0 = q_true + 0.01
    T[1, 0, 3] = np.nan
    T[4, 2, 2] = np.inf
    q0[6, 2] = -np.inf
    res = ikn.solve(arm, T, q0, restarts=3, engine="c")
    bad = np.zeros(8, dtype=bool)
    bad[[1, 4, 6]] = True
    assert not res.converged[bad].any() and np.isnan(res.q[bad]).all()
    assert np.all(res.iterations[bad] == 0)
    assert res.converged[~bad].all()
    # the raw C routine marks them INVALID
    core = arm._core
    opts = core.ik_options(
        tol_p=TOL,
        tol_r=TOL,
        step_limit=0.5,
        damping=1.0,
        base_damping=0.1,
        max_iter=50,
        stall_window=0,
        respect_limits=True,
        free_first=True,
        mask=[1] * 6,
        restarts=0,
        seed=0,
    )
    q, ep, er, it, status = core.ik_newton(
        opts,
        np.ascontiguousarray(T.reshape(-1, 4, 4)),
        np.ascontiguousarray(q0),
        np.ascontiguousarray(arm.qlim),
    )
    assert np.all(status[bad] == st.INVALID) and np.all(status[~bad] == st.OK)
    assert np.isnan(q[bad]).all() and np.isnan(ep[bad]).all() and np.all(it[bad] == 0)


def test_unreachable_rows_return_the_best_q(arms, rng):
    arm = arms("puma560")
    T = np.tile(np.eye(4), (10, 1, 1))
    T[:, :3, 3] = [3.0, 0.0, 0.5]
    res = ikn.solve(arm, T, random_q(arm, rng, 10), max_iter=40, restarts=2, engine="c")
    assert not res.converged.any()
    assert np.isfinite(res.q).all() and arm.within_limits(res.q).all()
    assert np.all(res.iterations <= 3 * 40)
    Tq = reference_fk(arm, res.q)
    assert np.allclose(
        res.position_error, np.linalg.norm(Tq[:, :3, 3] - T[:, :3, 3], axis=1), rtol=1e-9
    )


def test_engine_selection_and_bad_options(arms):
    arm = arms("puma560")
    T = arm.fk(arm.configuration("qn"))
    with pytest.raises(InputError):
        ikn.solve(arm, T, np.zeros(6), engine="fortran")
    for kwargs in (
        dict(jacobian="fd"),
        dict(jacobian="geometric"),
        dict(damping=None),
        dict(null_space=0.5),
    ):
        with pytest.raises(InputError):
            ikn.solve(arm, T, np.zeros(6), engine="c", **kwargs)
        ikn.solve(arm, T, np.zeros(6), **kwargs)  # auto: falls back to numpy
    ref = SerialRobot.load("puma560", backend="reference")
    with pytest.raises(InputError):
        ikn.solve(ref, T, np.zeros(6), engine="c")
    assert ikn.solve(ref, T, arm.configuration("qn") + 0.01).converged
    # the C routine itself refuses bad options (-1, nothing written)
    core = arm._core
    base = dict(
        tol_p=TOL,
        tol_r=TOL,
        step_limit=0.5,
        damping=1.0,
        base_damping=0.1,
        max_iter=50,
        stall_window=0,
        respect_limits=True,
        free_first=True,
        mask=[1] * 6,
        restarts=0,
        seed=0,
    )
    args = (np.ascontiguousarray(T.reshape(1, 4, 4)), np.zeros((1, 6)), None)
    for bad in (
        dict(tol_p=-1.0),
        dict(tol_r=math.nan),
        dict(step_limit=0.0),
        dict(damping=-1.0),
        dict(base_damping=math.inf),
        dict(max_iter=-1),
        dict(stall_window=-3),
        dict(restarts=-1),
        dict(mask=[0] * 6),
    ):
        with pytest.raises(RuntimeError):
            core.ik_newton(core.ik_options(**{**base, **bad}), *args)
    q, *_, status = core.ik_newton(core.ik_options(**base), *args)
    assert status[0] in (st.OK, st.UNREACHABLE)


def test_serial_robot_ik_numeric_uses_the_c_engine(arms, rng):
    arm = arms("puma560")
    q_true = random_q(arm, rng, 50)
    T = reference_fk(arm, q_true)
    q = arm.ik(T, method="numeric", q0=arm.configuration("qz"), restarts=60, seed=1)
    assert arm.within_limits(q).all()
    Tq = reference_fk(arm, q)
    assert np.abs(Tq - T).max() <= 1e-9
    q_np = arm.ik(T, method="numeric", q0=q, engine="numpy")
    assert np.abs(q_np - q).max() < 1e-9  # q is a solution: both stop at once
