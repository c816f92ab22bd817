"""The lean one-pose paths (native/lean.py) give the batch path's numbers bit for bit.

Each quantity is evaluated for a batch of random states (the kernels' SIMD loop) and then
row by row through the one-pose call, which must be taken (the batch machinery is made to
fail while it runs) and must equal the batch's row exactly. The delta's inverse kinematics
(ik, ik_vel, ik_acc) evaluate atan2 in padded loops of their own (codegen/render.py,
atan2_loops), so they too equal the long batch's row bit for bit. The serial ik_all / ik
call atan2 in their vectorised kinematics loop, which is not padded: a lone pose may differ
from a batch row in a vector lane by the last bits of atan2, so there the one-pose call
equals a batch of one row exactly and the long batch's row to rounding (1e-12 for the 8
branches of ik_all).
Inputs the lean path does not take (lists of numpy scalars, non-contiguous views,
big-endian arrays) give the same numbers through the general path. Errors on bad single inputs are those of the batch path
(tests/api/test_checks.py covers that for every method).
"""

from __future__ import annotations

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot

ROWS = 64


@pytest.fixture(scope="module")
def delta():
    return DeltaRobot.from_toml("robots/default_delta.toml", threads=1)


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560", threads=1)


def _no_batch(monkeypatch, core):
    """Make the batch machinery fail: a call that reaches it did not take the lean path."""

    def refuse(*args, **kwargs):
        raise AssertionError("the one-pose call went through the batch path")

    monkeypatch.setattr(core, "_run", refuse)


def _states(rng, n, lo=-0.3, hi=0.9):
    return (
        rng.uniform(lo, hi, (ROWS, n)),
        rng.uniform(-2, 2, (ROWS, n)),
        rng.uniform(-20, 20, (ROWS, n)),
    )


def test_delta_one_pose_equals_the_batch_row(delta, monkeypatch):
    rng = np.random.default_rng(12)
    q, qd, qdd = _states(rng, 3)
    p = delta.fk(q)
    payload = 0.25
    pd = delta.fk_vel(q, qd)[1]
    pdd = delta.fk_acc(q, qd, qdd)[2]
    batch = {
        "fk": (delta.fk(q),),
        "ik": (delta.ik(p),),
        "fk_vel": delta.fk_vel(q, qd),
        "fk_acc": delta.fk_acc(q, qd, qdd),
        "jacobian": (delta.jacobian(q),),
        "id": (delta.inverse_dynamics(q, qd, qdd, payload),),
        "id_s": (delta.inverse_dynamics(q, qd, qdd, payload, model="simplified"),),
    }
    # the rates of the inverse kinematics have no lean path: one row through the kernel
    rates = {"ik_vel": delta.ik_vel(p, pd), "ik_acc": delta.ik_acc(p, pd, pdd)}
    for i in range(ROWS):
        for one, many in zip(delta.ik_vel(p[i], pd[i]), rates["ik_vel"]):
            assert np.array_equal(one, many[i]), ("ik_vel", i)
        for one, many in zip(delta.ik_acc(p[i], pd[i], pdd[i]), rates["ik_acc"]):
            assert np.array_equal(one, many[i]), ("ik_acc", i)
    _no_batch(monkeypatch, delta._core)
    for i in range(ROWS):
        single = {
            "fk": (delta.fk(q[i]),),
            "ik": (delta.ik(p[i]),),
            "fk_vel": delta.fk_vel(q[i], qd[i]),
            "fk_acc": delta.fk_acc(q[i], qd[i], qdd[i]),
            "jacobian": (delta.jacobian(q[i]),),
            "id": (delta.inverse_dynamics(q[i], qd[i], qdd[i], payload),),
            "id_s": (delta.inverse_dynamics(q[i], qd[i], qdd[i], payload, "simplified"),),
        }
        for name, outs in single.items():
            assert len(outs) == len(batch[name])
            for one, many in zip(outs, batch[name]):
                assert one.shape == many.shape[1:], name
                assert np.array_equal(one, many[i]), (name, i)
    # lists of Python floats take the lean path as well
    assert np.array_equal(delta.fk(q[3].tolist()), batch["fk"][0][3])


def test_delta_inputs_the_lean_path_leaves_to_the_general_one(delta):
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.3, 0.9, (4, 3))
    expected = delta.fk(q)
    wide = np.zeros((3, 2))
    wide[:, 0] = q[1]
    assert np.array_equal(delta.fk(wide[:, 0]), expected[1])  # a strided view
    assert np.array_equal(delta.fk(q[2].astype(">f8")), expected[2])  # big-endian
    assert np.array_equal(delta.fk([np.float64(v) for v in q[0]]), expected[0])
    tau = delta.inverse_dynamics(q, q, q, payload=np.float64(0.5))
    assert np.array_equal(delta.inverse_dynamics(q[0], q[0], q[0], np.float64(0.5)), tau[0])
    assert np.array_equal(delta.inverse_dynamics(q[0], q[0], q[0], 0.5), tau[0])


def test_serial_one_configuration_equals_the_batch_row(puma, monkeypatch):
    rng = np.random.default_rng(13)
    lim = puma.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (ROWS, 6))
    qd, qdd = rng.uniform(-2, 2, (ROWS, 6)), rng.uniform(-20, 20, (ROWS, 6))
    T = puma.fk(q)
    J = puma.jacobian(q)
    q_long, valid_long = puma.ik_all(T)
    one_row = [puma.ik_all(T[i : i + 1]) for i in range(ROWS)]  # batches of one row
    q_all = np.array([r[0][0] for r in one_row])
    valid = np.array([r[1][0] for r in one_row])
    assert np.array_equal(valid, valid_long)
    assert np.abs(np.where(valid[..., None], q_all - q_long, 0.0)).max() <= 1e-12
    q_ik = np.array([puma.ik(T[i : i + 1], singular="allow")[0] for i in range(ROWS)])
    tau = puma.inverse_dynamics(q, qd, qdd)
    M = puma.mass_matrix(q)
    qdd_fd = puma.forward_dynamics(q, qd, tau)
    puma.ik_all(T[0])  # makes the closed form's one-pose path
    _no_batch(monkeypatch, puma._core)
    for i in range(ROWS):
        assert np.array_equal(puma.fk(q[i]), T[i])
        assert np.array_equal(puma.jacobian(q[i]), J[i])
        qa, va = puma.ik_all(T[i])
        assert np.array_equal(qa, q_all[i], equal_nan=True) and np.array_equal(va, valid[i])
        assert va.dtype == np.bool_
        assert np.array_equal(puma.ik(T[i], singular="allow"), q_ik[i])
        assert np.array_equal(puma.inverse_dynamics(q[i], qd[i], qdd[i]), tau[i])
        assert np.array_equal(puma.mass_matrix(q[i]), M[i])
        assert np.array_equal(puma.forward_dynamics(q[i], qd[i], tau[i]), qdd_fd[i])
    assert np.array_equal(puma.fk(tuple(q[5].tolist())), T[5])
    lists = (q[4].tolist(), qd[4].tolist(), tuple(qdd[4].tolist()))
    assert np.array_equal(puma.inverse_dynamics(*lists), tau[4])


@pytest.mark.parametrize("layout", ["table-table", "head-head", "table-head"])
def test_five_axis_one_pose_equals_the_batch_row(layout):
    """The 5-axis ik and ik_all evaluate atan2 in padded loops of their own (atan2_loops):
    one pose gives the batch row's bits, wherever the row stands (1021 rows: a remainder).
    Called in the per-point loop, about one value in eight differed in its last bits."""
    from deltagen.api.five_axis import FiveAxisMachine

    machine = FiveAxisMachine(layout, "AC", tool_length=0.1, tilt_limits=(-2.0, 2.0))
    rng = np.random.default_rng(17)
    n = 1021
    j = np.column_stack(
        [rng.uniform(-0.2, 0.2, (n, 3)), rng.uniform(-1.5, 1.5, n), rng.uniform(-3, 3, n)]
    )
    p, d = machine.fk(j)
    previous = rng.uniform(-1, 1, (n, 5))
    batch = machine.ik(p, d, previous)
    both, valid = machine.ik_all(p, d, previous)
    for i in range(0, n, 7):
        assert np.array_equal(machine.ik(p[i], d[i], previous[i]), batch[i]), i
        one, one_valid = machine.ik_all(p[i], d[i], previous[i])
        assert np.array_equal(one, both[i], equal_nan=True) and np.array_equal(one_valid, valid[i])


def test_lean_results_are_fresh_arrays(delta, puma):
    """The lean paths write into per-thread buffers and return copies: a result is not
    changed by the next call and shares no memory with it."""
    rng = np.random.default_rng(21)
    q6, q3 = rng.uniform(-1, 1, (2, 6)), rng.uniform(-0.3, 0.9, (2, 3))
    T0 = puma.fk(q6[0])
    keep = T0.copy()
    T1 = puma.fk(q6[1])
    assert np.array_equal(T0, keep) and not np.shares_memory(T0, T1)
    assert T0.flags.writeable and T0.flags.owndata
    qa, va = puma.ik_all(T0)
    qa_keep, va_keep = qa.copy(), va.copy()
    puma.ik_all(T1)
    assert np.array_equal(qa, qa_keep, equal_nan=True) and np.array_equal(va, va_keep)
    p0, pd0 = delta.fk_vel(q3[0], q3[1])
    p_keep = p0.copy()
    delta.fk_vel(q3[1], q3[0])
    assert np.array_equal(p0, p_keep) and not np.shares_memory(p0, pd0)


def test_lean_paths_from_threads_give_each_thread_its_rows(puma):
    """The buffers are per thread: concurrent one-pose calls get their own results."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(22)
    q = rng.uniform(-1, 1, (400, 6))
    T = puma.fk(q)
    J = puma.jacobian(q)

    def rows(lo):
        return all(
            np.array_equal(puma.fk(q[i]), T[i]) and np.array_equal(puma.jacobian(q[i]), J[i])
            for i in range(lo, 400, 4)
        )

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(rows, range(4)))


def test_serial_inputs_the_lean_path_leaves_to_the_general_one(puma):
    rng = np.random.default_rng(6)
    q = rng.uniform(-1, 1, (3, 6))
    T = puma.fk(q)
    wide = np.zeros((6, 2))
    wide[:, 0] = q[1]
    assert np.array_equal(puma.fk(wide[:, 0]), T[1])
    assert np.array_equal(puma.jacobian(q[2].astype(">f8")), puma.jacobian(q)[2])
    Tf = np.asfortranarray(T[0])
    assert np.array_equal(puma.ik_all(Tf)[0], puma.ik_all(T)[0][0], equal_nan=True)


def test_delta_payload_given_as_an_array_goes_the_general_way(delta):
    """A (3,) array as one pose's payload is not a scalar: the lean path leaves it to the
    general path, which refuses it (the payload broadcasts against the leading shape ());
    a scalar payload gives the batch row's torques."""
    from deltagen.inputs import InputError

    rng = np.random.default_rng(23)
    q, qd, qdd = (rng.uniform(-0.3, 0.9, 3) for _ in range(3))
    with pytest.raises(InputError, match="payload"):
        delta.inverse_dynamics(q, qd, qdd, np.array([0.1, 0.2, 0.3]))
    tau = delta.inverse_dynamics(q[None], qd, qdd, payload=0.3)[0]
    assert np.array_equal(delta.inverse_dynamics(q, qd, qdd, 0.3), tau)
