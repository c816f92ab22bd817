"""Closed-form IK of the Stanford arm (R R P + central wrist; model.structure.StanfordArm,
derive.serial.ik_recipes.stanford, run by solve.analytic) on roboticstoolbox's Stanford DH
model: our rows reproduce rtb's fkine, the original q is among the 8 branches for random in-limit poses, every valid
branch reproduces T with the reference fk (DH matrices)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.model.structure import StanfordArm, detect
from deltagen.solve.analytic import analytic_solver

rtb = pytest.importorskip("roboticstoolbox", reason="roboticstoolbox (test extra) is missing")


def _stanford():
    model = rtb.models.DH.Stanford()
    rows = []
    for link in model.links:
        row = dict(a=float(link.a), alpha=float(link.alpha), offset=float(link.offset))
        row["qlim"] = [float(x) for x in link.qlim]
        if link.isprismatic:
            row.update(type="prismatic", theta=float(link.theta))
        else:
            row["d"] = float(link.d)
        rows.append(row)
    return model, SerialRobot.from_dh(rows, "standard", name="stanford", backend="reference")


def _diff(Q, q, revolute):
    d = Q - q[:, None]
    wrapped = np.abs((d + np.pi) % (2 * np.pi) - np.pi)
    return np.where(revolute, wrapped, np.abs(d)).max(-1)


def test_stanford_closed_form():
    model, arm = _stanford()
    rng = np.random.default_rng(12)
    lim = arm.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (1500, 6))
    T = arm.fk(q)
    np.testing.assert_allclose(T[:20], [model.fkine(x).A for x in q[:20]], atol=1e-12)
    solver = analytic_solver(arm.description)
    assert isinstance(solver.detected, StanfordArm) and len(solver.configs) == 8
    Q, valid = solver.solve(T)  # within limits
    revolute = np.array([True, True, False, True, True, True])
    found = np.where(valid, _diff(Q, q, revolute), np.inf).min(-1) < 1e-7
    assert found.all()
    Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[valid].max() < 1e-10
    # without limits every pose of the arm has 8 real branches (q3 of either sign)
    Q8, v8 = solver.solve(T, limits=False)
    assert v8.all()
    q1 = arm.ik(T[:50], q0=q[:50])
    np.testing.assert_allclose(arm.fk(q1), T[:50], atol=1e-10)


def test_stanford_detection_needs_meeting_axes():
    _, arm = _stanford()
    joints = list(arm.description.joints)
    joints[4] = dataclasses.replace(joints[4], a=0.02)  # axes 5 and 6 no longer meet W
    assert detect(dataclasses.replace(arm.description, joints=tuple(joints))) is None


@pytest.fixture(scope="module")
def stanford_c():
    """The Stanford arm with the compiled backend: its ik_all is generated C
    (derive/serial/ik_recipes.py, stanford, run by ik_closed_form.py)."""
    model, arm = _stanford()
    return arm.with_backend("compiled")


def test_stanford_c_equals_numpy_closed_form_and_fk(stanford_c):
    """The C ik_all against the numpy solver (written on the same structure object but
    vectorised over branches in numpy): same valid flags, same joint values; every valid
    branch reproduces T through the forward kinematics (DH matrices); the original q is
    among the valid branches; the single-pose path equals the batch."""
    arm = stanford_c
    assert arm._core.has_ik_all
    rng = np.random.default_rng(5)
    lim = arm.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (2000, 6))
    T = arm.fk(q)
    Qc, Vc = arm.ik_all(T)
    Qn, Vn = analytic_solver(arm.description).solve(T)
    assert Vc.any(axis=1).all()
    assert np.array_equal(Vc, Vn)
    assert np.abs(np.where(Vc[..., None], Qc - Qn, 0.0)).max() < 1e-10
    assert np.isnan(Qc[~Vc & np.isnan(Qn).any(-1)]).all()
    Tq = arm.fk(np.where(Vc[..., None], Qc, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[Vc].max() < 1e-12
    revolute = np.array([True, True, False, True, True, True])
    found = np.where(Vc, _diff(Qc, q, revolute), np.inf).min(-1) < 1e-7
    assert found.all()
    for i in range(5):  # the single-pose path: the same C function, one row
        q1, v1 = arm.ik_all(T[i])
        np.testing.assert_array_equal(v1, Vc[i])
        np.testing.assert_array_equal(q1[v1], Qc[i][Vc[i]])


def test_stanford_c_statuses(stanford_c):
    """Out of reach (q3 beyond its limits): no valid branch; a non-finite pose: all NaN."""
    arm = stanford_c
    T = arm.fk(arm.qlim.mean(axis=1))
    far = T.copy()
    far[:3, 3] *= 100.0
    bad = T.copy()
    bad[0, 3] = np.nan
    Q, V = arm.ik_all(np.stack([T, far, bad]))
    assert V[0].any() and not V[1].any() and not V[2].any()
    assert np.isnan(Q[2]).all()
