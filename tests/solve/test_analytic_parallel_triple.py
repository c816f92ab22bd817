"""Closed-form IK of 6R arms with three consecutive parallel axes (model.structure
ParallelTriple6R, solve.analytic._ParallelTripleSolver): the UR family.

Evidence: roboticstoolbox's UR3/UR5/UR10 DH models (their numbers, our rows) and the bundled
UR5 URDF (universal coordinates); poses from the reference fk of random q; every valid
branch checked with the reference fk (a product of DH matrices, not the solver's product of
exponentials); the solution count against a numeric multi-start (damped Newton from many
random seeds, deltagen.solve.numeric): no converged numeric solution is missing from the
closed form's set.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import rtb_dh_rows

from deltagen import SerialRobot
from deltagen.model.serial import SerialDescription
from deltagen.model.structure import ParallelTriple6R, detect
from deltagen.paths import robots_dir
from deltagen.solve import numeric as ik_numeric
from deltagen.solve.analytic import analytic_solver

rtb = pytest.importorskip("roboticstoolbox", reason="roboticstoolbox (test extra) is missing")


def _arm(name):
    if name == "ur5_urdf":
        return SerialRobot.load("ur5", backend="reference")
    rows = rtb_dh_rows(getattr(rtb.models.DH, name)())
    return SerialRobot.from_dh(rows, "standard", name=name.lower(), backend="reference")


def _wrapped(a):
    return np.abs((a + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("name", ["UR5", "UR3", "UR10", "ur5_urdf"])
def test_every_branch_reaches_the_pose_and_the_original_is_among_them(name):
    arm = _arm(name)
    solver = analytic_solver(arm.description)
    assert solver is not None and solver.structure == "parallel_triple_6r"
    assert len(solver.configs) == 8
    rng = np.random.default_rng(42)
    lim = np.clip(arm.qlim, -np.pi, np.pi)
    q = rng.uniform(lim[:, 0], lim[:, 1], (1500, 6))
    T = arm.fk(q)
    Q, valid = solver.solve(T, limits=False)
    found = np.where(valid, _wrapped(Q - q[:, None]).max(-1), np.inf).min(-1) < 1e-7
    assert found.all(), f"original q missed on {np.flatnonzero(~found)[:10]}"
    # every valid branch reproduces T (reference fk, DH matrices) to 1e-10
    Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
    err = np.abs(Tq - T[:, None]).max(axis=(-1, -2))
    assert err[valid].max() < 1e-10
    # invalid branches are NaN (no real solution) and never silently wrong
    assert np.isnan(Q[~valid]).all()
    # 8 solutions for most poses of a UR (2 per reachable shoulder / wrist / elbow pair)
    assert np.mean(valid.sum(-1) == 8) > 0.5


def test_api_ik_all_and_ik_use_the_closed_form():
    arm = _arm("ur5_urdf")
    assert len(arm.analytic_configs()) == 8
    rng = np.random.default_rng(1)
    q = rng.uniform(-3, 3, (50, 6))
    T = arm.fk(q)
    Q, valid = arm.ik_all(T)
    assert Q.shape == (50, 8, 6) and valid.any(-1).all()
    q1 = arm.ik(T, q0=q)  # the branch nearest q0
    np.testing.assert_allclose(arm.fk(q1), T, atol=1e-10)


def test_no_solution_is_missed_by_the_closed_form():
    """Numeric multi-start: 48 random seeds per pose, Newton without limits; every converged
    solution must be one of the closed form's valid branches."""
    arm = _arm("UR5")
    solver = analytic_solver(arm.description)
    rng = np.random.default_rng(9)
    poses, seeds = 12, 48
    T = arm.fk(rng.uniform(-np.pi, np.pi, (poses, 6)))
    Q, valid = solver.solve(T, limits=False)
    starts = rng.uniform(-np.pi, np.pi, (poses, seeds, 6))
    res = ik_numeric.solve(
        arm,
        np.repeat(T, seeds, axis=0),
        starts.reshape(-1, 6),
        tol=1e-11,
        max_iter=200,
        respect_limits=False,
    )
    conv = res.converged.reshape(poses, seeds)
    qn = res.q.reshape(poses, seeds, 6)
    assert conv.mean() > 0.5
    for p in range(poses):
        for s in np.flatnonzero(conv[p]):
            d = _wrapped(Q[p][valid[p]] - qn[p, s]).max(-1)
            assert d.min() < 1e-6, f"pose {p}: numeric solution {qn[p, s]} not in the closed form"
        distinct = {tuple(np.round(_wrapped(x), 5)) for x in qn[p][conv[p]]}
        assert len(distinct) <= valid[p].sum()


def test_detection_from_geometry_not_names():
    ur5 = _arm("UR5").description
    assert isinstance(detect(ur5), ParallelTriple6R)
    # renamed, flipped joint 3 (the axes' signs change, the structure does not)
    joints = list(ur5.joints)
    joints[2] = dataclasses.replace(joints[2], sign=-1.0)
    flipped = dataclasses.replace(ur5, name="cobot", joints=tuple(joints))
    solver = analytic_solver(flipped)
    assert solver is not None and solver.structure == "parallel_triple_6r"
    arm = SerialRobot(flipped, backend="reference")
    q = np.random.default_rng(3).uniform(-3, 3, (200, 6))
    Q, valid = solver.solve(arm.fk(q), limits=False)
    assert (np.where(valid, _wrapped(Q - q[:, None]).max(-1), np.inf).min(-1) < 1e-7).all()
    # axes 5 and 6 no longer meet (a5 != 0): not this structure
    joints = list(ur5.joints)
    joints[4] = dataclasses.replace(joints[4], a=0.03)
    assert detect(dataclasses.replace(ur5, joints=tuple(joints))) is None
    # axis 4 not parallel to axis 3 (alpha3 != 0): not this structure
    joints = list(ur5.joints)
    joints[2] = dataclasses.replace(joints[2], alpha=0.3)
    assert detect(dataclasses.replace(ur5, joints=tuple(joints))) is None
    assert not isinstance(
        detect(SerialDescription.from_toml(robots_dir() / "puma560.toml")), ParallelTriple6R
    )


@pytest.mark.slow
def test_compiled_kernel_matches_the_numpy_solver():
    """The generated C ik_all of a UR5 (derive/serial/ik_closed_form.py, the same steps as
    the numpy solver) against the numpy solver: the same valid flags and joint values, the
    original q among the branches, with limits (+-6.2 rad) checked in C."""
    rows = rtb_dh_rows(rtb.models.DH.UR5())
    for row in rows:
        row["qlim"] = [-6.2, 6.2]
    arm = SerialRobot.from_dh(rows, "standard", name="ur5_dh_c")
    assert arm._core.has_ik_all
    q = np.random.default_rng(0).uniform(-3, 3, (3000, 6))
    T = arm.fk(q)
    Qc, Vc = arm.ik_all(T)
    Qn, Vn = analytic_solver(arm.description).solve(T)
    assert np.array_equal(Vc, Vn)
    assert np.abs(np.where(Vc[..., None], Qc - Qn, 0.0)).max() < 1e-10
    assert (np.where(Vc, _wrapped(Qc - q[:, None]).max(-1), np.inf).min(-1) < 1e-7).all()
    q1, v1 = arm.ik_all(T[0])  # the single-pose fast path
    np.testing.assert_array_equal(v1, Vc[0])
