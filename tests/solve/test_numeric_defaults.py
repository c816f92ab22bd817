"""Numerical IK with default options solves every reachable in-limit target.

Evidence independent of the solver: the targets are fk(q) of q drawn within the limits
(so a solution exists), and each answer is checked with the numpy reference's fk (written
from the model, not from the derivation) to 1e-10 m and rad, and against the joint limits.
Two arms: the Puma 560 and a Panda-like 7-axis arm (apps/bench/ik.PANDA_DH, the Franka
documentation's table). The restarts run in C from a deterministic sequence, so the same
call gives the same answer bit for bit, and one target per call gives the batch's row.
"""

from __future__ import annotations

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.apps.bench.ik import numeric_targets, panda_like
from deltagen.reference import serial as reference
from deltagen.solve import numeric as ikn

TOL = 1e-10
TARGETS = 150


@pytest.fixture(scope="module")
def arms():
    return {"puma560": SerialRobot.load("puma560", threads=1), "panda_like": panda_like()}


def _check_solved(arm, T, q):
    lim = arm.qlim
    assert np.all((q >= lim[:, 0]) & (q <= lim[:, 1]))
    Tq, status = reference.fk(arm.description, np.ascontiguousarray(q))
    assert np.all(status == 0)
    dp = np.linalg.norm(Tq[:, :3, 3] - T[:, :3, 3], axis=1)
    dr = np.linalg.norm(
        ikn.rotation_vector(T[:, :3, :3] @ np.swapaxes(Tq[:, :3, :3], 1, 2)), axis=1
    )
    assert dp.max() <= TOL * 1.0001 and dr.max() <= TOL * 1.0001


@pytest.mark.parametrize("name", ["puma560", "panda_like"])
def test_default_numeric_ik_solves_every_reachable_target(arms, name):
    arm = arms[name]
    T, _ = numeric_targets(arm, TARGETS, seed=12)
    q = arm.ik(T, method="numeric", singular="allow")  # defaults; raises if any row fails
    _check_solved(arm, T, q)
    # deterministic: the same call, the same bits
    assert np.array_equal(arm.ik(T, method="numeric", singular="allow"), q)
    # one target per call (the single-pose fast path) = the batch's row, bit for bit
    for i in range(0, TARGETS, 5):
        qi = arm.ik(T[i], method="numeric", singular="allow")
        assert np.array_equal(qi, q[i])


def test_restarts_run_in_c_and_give_up_on_unreachable_targets(arms):
    """One C call runs every attempt: an unreachable target reports iterations over all
    attempts (more than one attempt's max_iter), the best in-limit q and no convergence;
    restarts=0 keeps to one attempt."""
    arm = arms["puma560"]
    T = np.eye(4)
    T[:3, 3] = [3.0, 0.0, 0.5]
    res = ikn.solve(arm, T, None, max_iter=20)
    assert not res.converged and arm.within_limits(res.q)
    assert 20 < res.iterations <= (ikn.RESTARTS + 1) * 20
    one = ikn.solve(arm, T, None, max_iter=20, restarts=0)
    assert one.iterations <= 20
    # the seed picks another stretch of the sequence: still solves, deterministically
    Tr, _ = numeric_targets(arm, 40, seed=3)
    a = ikn.solve(arm, Tr, arm._start(None, (40,)), seed=7)
    b = ikn.solve(arm, Tr, arm._start(None, (40,)), seed=7)
    assert a.converged.all() and np.array_equal(a.q, b.q)
    _check_solved(arm, Tr, a.q)


def test_the_defaults_are_written_once_and_unknown_options_are_named(arms):
    """solve() with no options equals solve() given every default of DEFAULTS spelled out
    (so the table is the one the solver uses), ik(method="numeric") takes the same set,
    and an unknown option is an InputError naming it (not Python's TypeError)."""
    from deltagen.inputs import InputError

    arm = arms["puma560"]
    T, _ = numeric_targets(arm, 8, seed=5)
    plain = ikn.solve(arm, T)
    spelled = ikn.solve(arm, T, **ikn.DEFAULTS)
    assert np.array_equal(plain.q, spelled.q, equal_nan=True)
    assert np.array_equal(plain.converged, spelled.converged)
    assert ikn.OPTIONS == tuple(ikn.DEFAULTS)
    with pytest.raises(InputError, match="tolerance"):
        ikn.solve(arm, T, tolerance=1e-9)
    with pytest.raises(InputError, match="tolerance"):
        ikn.check_options(arm, tolerance=1e-9)


def test_the_one_pose_solver_reads_the_defaults_table(arms, monkeypatch):
    """single_solver (ik's one-pose path) takes solve()'s defaults from DEFAULTS, not from a
    copy of its own: with the table changed (tol 1e-4, max_iter 3) a one-pose call gives
    the batch's row bit for bit, and None where the batch did not converge."""
    arm = arms["puma560"]
    T, _ = numeric_targets(arm, 12, seed=8)
    q0 = np.ascontiguousarray(arm._start(None, (1,))[0])
    monkeypatch.setitem(ikn.DEFAULTS, "tol", 1e-4)
    monkeypatch.setitem(ikn.DEFAULTS, "max_iter", 3)
    batch = ikn.solve(arm, T, q0)
    one = ikn.single_solver(arm)
    for i in range(len(T)):
        qi = one(np.ascontiguousarray(T[i]), q0)
        if batch.converged[i]:
            assert qi is not None and np.array_equal(qi, batch.q[i])
        else:
            assert qi is None
