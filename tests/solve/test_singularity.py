"""Singularity report (deltagen.solve.singularity); lecture slides 112-114.

Independent evidence: the singular poses are derived here from the Puma 560 DH table
(closed-form planar geometry of joints 2 and 3), and every flagged pose is also checked to
make numpy's SVD of the Jacobian lose rank; the condition number is compared with
numpy.linalg.cond.
"""

import math

import numpy as np
import pytest

from deltagen.api.serial import SerialRobot
from deltagen.solve.singularity import describe, report, row_of

# Puma 560 DH table (robots/puma560.toml, standard DH)
A2, A3, D3, D4 = 0.4318, 0.0203, 0.15005, 0.4318


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560", backend="reference")


@pytest.fixture(scope="module")
def scara():
    return SerialRobot.load("lecture_scara", backend="reference")


def _svd_ratio(robot, q):
    s = np.linalg.svd(robot.jacobian(q), compute_uv=False)
    return s[-1] / s[0]


def _wrist_centre(robot, q):
    # standard DH Puma: the origin of frame 4 (d4 along z3 from frame 3) is the wrist centre
    return robot.frames(q)[4, :3, 3]


def test_wrist_singularity_q5_zero(puma):
    q = np.array([0.3, 0.5, -1.0, 0.4, 0.0, 0.2])
    rep = report(puma, q)
    assert rep["structure"] == "spherical_wrist_6r"
    assert rep["wrist"] and rep["singular"]
    assert not rep["shoulder"] and not rep["elbow"]
    assert (4, 6) in rep["aligned_axes"]
    assert _svd_ratio(puma, q) < 1e-12
    text = describe(rep)
    assert text.startswith("wrist singularity: axes 4 and 6 aligned; condition number")


def _elbow_angles():
    # Forearm in frame 2 (after Rot_z(q3), alpha3 = -90 deg so z3 = (-s3, c3)): the wrist
    # centre sits at a3 (c3, s3) + d4 (-s3, c3) from axis 3; axis 2 -> axis 3 runs along x2.
    # Collinear when a3 s3 + d4 c3 = 0: q3 = atan2(a3, d4) - pi/2 (stretched) or + pi/2
    # (folded back).
    stretched = math.atan2(A3, D4) - math.pi / 2
    folded = math.atan2(A3, D4) + math.pi / 2
    return stretched, folded


@pytest.mark.parametrize("which", [0, 1])
def test_elbow_singularity(puma, which):
    q3 = _elbow_angles()[which]
    q = np.array([0.3, 0.5, q3, 0.4, 0.7, 0.2])
    # independent check of the derivation: axis-2 point, axis-3 point and W collinear
    F = puma.frames(q)
    p2, p3, W = F[1, :3, 3], F[2, :3, 3], _wrist_centre(puma, q)
    z2 = F[1, :3, 2]
    # project onto the plane normal to the (parallel) axes 2, 3 and test collinearity there
    u = (p3 - p2) - ((p3 - p2) @ z2) * z2
    v = (W - p2) - ((W - p2) @ z2) * z2
    assert np.linalg.norm(np.cross(u, v)) < 1e-12
    assert (u @ v > 0) == (which == 0)  # stretched: W beyond axis 3
    rep = report(puma, q)
    assert rep["elbow"] and rep["singular"]
    assert not rep["wrist"] and not rep["shoulder"]
    assert _svd_ratio(puma, q) < 1e-12
    assert "elbow singularity" in describe(rep)


def _shoulder_q2(q3):
    # W in shoulder frame 1: x1 = a2 c2 + a3 c23 - d4 s23 (the d3 offset is along z1, i.e.
    # along axis 2). The shoulder singularity is x1 = 0: W in the plane of axis 1 and the
    # direction of axis 2, at the offset distance |d3| from axis 1 (it cannot reach axis 1).
    def f(q2):
        return A2 * math.cos(q2) + A3 * math.cos(q2 + q3) - D4 * math.sin(q2 + q3)

    lo, hi = 0.0, 2.5
    assert f(lo) * f(hi) < 0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(lo) * f(mid) <= 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def test_shoulder_singularity_with_offset(puma):
    q3 = -0.6
    q2 = _shoulder_q2(q3)
    q = np.array([0.3, q2, q3, 0.4, 0.7, 0.2])
    F = puma.frames(q)
    W1 = np.linalg.solve(F[1], np.append(_wrist_centre(puma, q), 1.0))[:3]
    assert abs(W1[0]) < 1e-12  # the closed form above agrees with the frames
    # W is at distance |d3| from axis 1 (the base z axis through the base origin)
    W = _wrist_centre(puma, q)
    assert np.hypot(W[0], W[1]) == pytest.approx(D3, abs=1e-12)
    rep = report(puma, q)
    assert rep["shoulder"] and rep["singular"]
    assert not rep["wrist"] and not rep["elbow"]
    assert _svd_ratio(puma, q) < 1e-12
    assert "shoulder singularity" in describe(rep)
    # one step away it is gone
    q_off = q + np.array([0, 1e-2, 0, 0, 0, 0])
    assert not report(puma, q_off)["shoulder"]


def test_shoulder_singularity_on_axis_without_offset():
    # the same arm with d3 = 0: now W reaches axis 1 itself
    rows = [
        dict(a=0.0, alpha_deg=90, d=0.67183),
        dict(a=A2, alpha=0.0, d=0.0),
        dict(a=A3, alpha_deg=-90, d=0.0),
        dict(a=0.0, alpha_deg=90, d=D4),
        dict(a=0.0, alpha_deg=-90, d=0.0),
        dict(a=0.0, alpha=0.0, d=0.0),
    ]
    arm = SerialRobot.from_dh(rows, "standard", name="puma_no_offset", backend="reference")
    q3 = -0.6
    q = np.array([0.3, _shoulder_q2(q3), q3, 0.4, 0.7, 0.2])
    W = arm.frames(q)[4, :3, 3]
    assert np.hypot(W[0], W[1]) < 1e-12
    rep = report(arm, q)
    assert rep["shoulder"] and rep["singular"] and not rep["elbow"] and not rep["wrist"]


def test_generic_poses_and_condition_number(puma):
    rng = np.random.default_rng(7)
    lim = puma.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], size=(50, 6))
    # keep clear of the three singular sets (derived above), so "nothing flagged" is expected
    q[:, 4] = np.where(np.abs(q[:, 4]) < 0.2, 0.5, q[:, 4])
    rep = report(puma, q)
    assert rep["condition"].shape == (50,)
    J = puma.jacobian(q)
    cond = np.linalg.cond(J)
    ok = (rep["elbow_distance"] > 0.02) & (rep["shoulder_distance"] > 0.02)
    assert ok.sum() > 30
    assert not rep["wrist"][ok].any()
    assert not rep["shoulder"][ok].any() and not rep["elbow"][ok].any()
    assert not rep["singular"][ok].any()
    assert np.all(np.isfinite(rep["condition"][ok]))
    np.testing.assert_allclose(rep["condition"], cond, rtol=1e-8)
    np.testing.assert_allclose(
        rep["manipulability"], np.abs(np.linalg.det(J)), rtol=1e-8, atol=1e-14
    )
    assert all(a == [] for a in rep["aligned_axes"][ok])
    r0 = row_of(rep, int(np.flatnonzero(ok)[0]))
    assert describe(r0).startswith("not singular; condition number")


def test_batched_shape_and_invalid_rows(puma):
    q = np.zeros((2, 3, 6))
    q[0, 1, 4] = 0.7
    q[1, 2, 0] = np.nan
    rep = report(puma, q)
    assert rep["singular"].shape == (2, 3) and rep["aligned_axes"].shape == (2, 3)
    assert rep["wrist"][0, 0] and not rep["wrist"][1, 2]
    assert np.isnan(rep["condition"][1, 2]) and rep["aligned_axes"][1, 2] == []
    assert "non-finite" in describe(row_of(rep, (1, 2)))


def test_lecture_scara(scara):
    rep = report(scara, [[0.4, 0.0], [0.4, 1.0], [0.4, math.pi]])
    assert rep["structure"] == "general"
    assert rep["singular"].tolist() == [True, False, True]  # stretched, bent, folded
    assert not rep["wrist"].any() and not rep["shoulder"].any() and not rep["elbow"].any()
    # position Jacobian of the planar 2R: det = L1 L2 sin(q2) = 12 sin(q2)
    assert rep["manipulability"][1] == pytest.approx(12 * math.sin(1.0), rel=1e-12)
    assert rep["aligned_axes"][0] == []  # parallel axes, not the same line
    assert describe(row_of(rep, 0)).startswith("singular configuration")


def test_aligned_axes_general_arm():
    # a 3R arm whose axes 1 and 3 can line up: a1 = 1, a2 = 1 (planar) ... use a spatial arm
    rows = [
        dict(a=0.0, alpha_deg=90, d=0.0),
        dict(a=0.0, alpha_deg=-90, d=0.0),
        dict(a=0.0, alpha=0.0, d=0.5),
    ]
    arm = SerialRobot.from_dh(rows, "standard", name="rrr", backend="reference")
    rep = report(arm, [[0.1, 0.0, 0.3], [0.1, 0.8, 0.3]])
    # axes 1 (z0) and 3 (z2) both pass through the origin; collinear when q2 = 0
    assert rep["aligned_axes"][0] == [(1, 3)]
    assert rep["aligned_axes"][1] == []
    assert "collinear axes 1 and 3" in describe(row_of(rep, 0))


@pytest.mark.parametrize("tol", [0, 0.0, -1e-6, float("nan"), float("inf"), True, "1e-6", None])
def test_report_and_the_closed_form_refuse_the_same_tolerances(puma, tol):
    """report's and AnalyticSolver.solve's tol are one check (deltagen.inputs.check_real,
    > 0 and finite): each bad value is refused by both with the same message."""
    from deltagen.inputs import InputError

    q = np.zeros((1, 6))
    with pytest.raises(InputError, match="^tol must be") as by_report:
        report(puma, q, tol=tol)
    solver = puma.ik_planner.analytic
    with pytest.raises(InputError, match="^tol must be") as by_solver:
        solver.solve(np.eye(4), tol=tol)
    assert str(by_report.value) == str(by_solver.value)
    assert report(puma, q, tol=np.float32(1e-6))["condition"].shape == (1,)
