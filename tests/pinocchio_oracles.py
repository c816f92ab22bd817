"""pinocchio as the oracle of URDF arms (shared by tests/model/test_urdf*.py): its own URDF
parser, rnea / crba dynamics and reduced models, compared with deltagen's arm."""

from __future__ import annotations

import math

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")


N_CONFIGS = 1000


def pin_q(model, q):
    """Pinocchio's configuration vector of deltagen's joint vector q (n,): a continuous
    joint is (cos q, sin q) there."""
    out = np.zeros(model.nq)
    for k in range(1, model.njoints):
        j = model.joints[k]
        i = j.idx_v
        if j.nq == 2:
            out[j.idx_q : j.idx_q + 2] = (math.cos(q[i]), math.sin(q[i]))
        else:
            out[j.idx_q] = q[i]
    return out


def assert_dynamics_as_pinocchio(model, data, q, qd, qdd, tau, M):
    """deltagen's tau (N, n) and M (N, n, n) at q, qd, qdd equal pinocchio's rnea (plus the
    file's damping and Coulomb friction, which rnea leaves out) and crba, to 1e-10 relative."""
    for k in range(len(q)):
        qp = pin_q(model, q[k])
        taup = pin.rnea(model, data, qp, qd[k], qdd[k])
        taup = taup + model.damping * qd[k] + model.friction * np.sign(qd[k])
        assert np.abs(tau[k] - taup).max() <= 1e-10 * np.abs(taup).max()
        Mp = pin.crba(model, data, qp)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert np.abs(M[k] - Mp).max() <= 1e-10 * np.abs(Mp).max()


def random_urdf_q(robot, rng, count=N_CONFIGS):
    lim = np.clip(robot.qlim, -np.pi, np.pi)
    return rng.uniform(lim[:, 0], lim[:, 1], (count, robot.n))


def compare_with_pinocchio(robot, path, tip):
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    assert model.nv == robot.n
    names = [model.names[k] for k in range(1, model.njoints)]
    assert names == [j.name for j in robot.description.joints]
    fid = model.getFrameId(tip)
    rng = np.random.default_rng(7)
    q = random_urdf_q(robot, rng)
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    T = robot.fk(q)
    J = robot.jacobian(q)
    tau = robot.inverse_dynamics(q, qd, qdd)
    M = robot.mass_matrix(q)
    for k in range(len(q)):
        qp = pin_q(model, q[k])
        pin.framesForwardKinematics(model, data, qp)
        np.testing.assert_allclose(T[k], data.oMf[fid].homogeneous, rtol=0, atol=1e-12)
        # deltagen's base-frame Jacobian: the tool origin's velocity and the angular
        # velocity in base axes = pinocchio's LOCAL_WORLD_ALIGNED (not WORLD, whose linear
        # part is the velocity of the point at the world origin)
        Jp = pin.computeFrameJacobian(model, data, qp, fid, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(J[k], Jp, rtol=0, atol=1e-12)
        taup = pin.rnea(model, data, qp, qd[k], qdd[k])
        assert np.abs(tau[k] - taup).max() <= 1e-10 * np.abs(taup).max()
        Mp = pin.crba(model, data, qp)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert np.abs(M[k] - Mp).max() <= 1e-10 * np.abs(Mp).max()


def pinocchio_chain(path, chain, at=None, gravity=None):
    """Pinocchio's whole-tree model of the file with world gravity (or ``gravity``), every
    joint outside ``chain`` locked at 0 or at ``at[name]``."""
    full = pin.buildModelFromUrdf(str(path))
    if gravity is not None:
        full.gravity.linear = np.asarray(gravity, dtype=float)
    q_lock = pin.neutral(full)
    for name, value in (at or {}).items():
        q_lock[full.joints[full.getJointId(name)].idx_q] = value
    lock = [k for k in range(1, full.njoints) if full.names[k] not in chain]
    model = pin.buildReducedModel(full, lock, q_lock)
    assert [model.names[k] for k in range(1, model.njoints)] == chain
    return model


def chain_pose_fk(path, chain, base, tip):
    """Pinocchio's fk of a chain of the file, as a function of q (N, n): the pose (N, 4, 4)
    of frame ``tip`` in frame ``base`` (the chain's joints free, every other joint at 0)."""
    model = pinocchio_chain(path, chain)
    data = model.createData()
    root, fid = model.getFrameId(base), model.getFrameId(tip)

    def fk(q):
        out = np.empty((len(q), 4, 4))
        for k, qk in enumerate(q):
            pin.framesForwardKinematics(model, data, qk)
            out[k] = np.linalg.solve(data.oMf[root].homogeneous, data.oMf[fid].homogeneous)
        return out

    return fk


def assert_gravity_as_pinocchio(robot, model, rng, count=50):
    data = model.createData()
    lim = np.clip(robot.qlim, -np.pi, np.pi)
    q = rng.uniform(lim[:, 0], lim[:, 1], (count, robot.n))
    qd = rng.uniform(-2, 2, q.shape)
    qdd = rng.uniform(-3, 3, q.shape)
    g = robot.gravity_torque(q)
    tau = robot.inverse_dynamics(q, qd, qdd)
    for k in range(count):
        gp = pin.computeGeneralizedGravity(model, data, q[k])
        assert np.abs(g[k] - gp).max() <= 1e-10 * np.abs(gp).max()
        taup = pin.rnea(model, data, q[k], qd[k], qdd[k])
        taup = taup + model.damping * qd[k] + model.friction * np.sign(qd[k])
        assert np.abs(tau[k] - taup).max() <= 1e-10 * np.abs(taup).max()
