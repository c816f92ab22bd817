"""Every solution of a general 6R arm (solve/general6r.py: Raghavan-Roth elimination,
Manocha-Canny eigenproblem, Newton polish) and its use by SerialRobot.ik_all.

Evidence: random 6R arms (random DH) and poses from the reference fk of random q (the
original q must be among the valid solutions); every valid solution checked with the
reference fk (DH matrices, not the solver's product of exponentials); the published arm with
16 real solutions of Manocha & Canny, "Efficient inverse kinematics for general 6R
manipulators", IEEE Trans. Robotics and Automation 10(5), 1994, Table I (DH) and Table III
(the 16 solutions, degrees) -- problem 6 of Wampler & Morgan (1991), a variation of the arm of
Manseur & Doty (1989); a numeric multi-start that finds no solution the solver missed.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import jaco_arm, random_6r_arm

from deltagen import IncompleteSolutionsWarning, SerialRobot
from deltagen.inputs import InputError
from deltagen.solve import general6r
from deltagen.solve import numeric as ik_numeric


def _wrapped(a):
    return np.abs((a + np.pi) % (2 * np.pi) - np.pi)


def _found(Q, valid, q, tol=1e-6):
    return np.where(valid, _wrapped(Q - q[:, None]).max(-1), np.inf).min(-1) < tol


@pytest.mark.parametrize("seed", [1, 2])
def test_random_arms_every_solution(seed):
    arm = random_6r_arm(seed)
    (elimination,), complete = arm._general()
    assert complete and elimination.regular
    assert elimination.fit_residual < 1e-12  # Raghavan-Roth's structure holds
    rng = np.random.default_rng(100 + seed)
    q = rng.uniform(-np.pi, np.pi, (400, 6))
    T = arm.fk(q)
    result = arm.ik_all(T)  # auto: no closed form, a regular elimination -> complete
    assert result.complete
    Q, valid = result
    assert Q.shape == (400, 16, 6)
    found = _found(Q, valid, q)
    assert found.mean() >= 0.995, f"missed rows {np.flatnonzero(~found)}"
    Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[valid].max() < 1e-10
    # real solutions come in even numbers for a generic pose (complex roots pair up)
    assert np.mean(valid.sum(-1) % 2 == 0) > 0.97
    assert np.isnan(Q[~valid]).all()


# Manocha & Canny (1994), Table I: a_i [m], d_i [m], alpha_i [deg]
MC_ROWS = [
    dict(a=0.3, d=0.0, alpha_deg=90.0),
    dict(a=1.0, d=0.0, alpha_deg=1.0),
    dict(a=0.0, d=0.2, alpha_deg=90.0),
    dict(a=1.5, d=0.0, alpha_deg=1.0),
    dict(a=0.0, d=0.0, alpha_deg=90.0),
    dict(a=0.0, d=0.0, alpha_deg=1.0),
]
# Table III: the 16 solutions theta_1..theta_6 [deg] of their end-effector pose
MC_TABLE_III = [
    [-96.28, -6.27, 179.96, 38.48, 52.55, -39.40],
    [-120.78, 172.33, -179.07, 31.33, -146.71, 142.82],
    [88.67, -176.72, -176.72, -63.24, 157.19, 140.43],
    [113.84, 5.30, -177.74, -55.92, -62.98, -43.37],
    [-178.12, 108.19, -147.73, -5.69, -164.67, 179.58],
    [168.32, -103.89, 146.60, -17.24, -171.87, 98.16],
    [-12.94, -105.09, -114.97, 3.02, 7.41, -79.42],
    [2.51, 108.07, 112.04, -10.52, 0.00, -0.10],
    [2.51, 108.07, -67.95, -169.47, 179.99, 179.89],
    [-12.94, -105.09, 65.02, 176.97, 172.58, 100.57],
    [168.32, -103.89, -33.39, -162.75, -8.12, -81.83],
    [-178.12, 108.19, 32.26, -174.30, -15.32, -0.41],
    [88.67, -176.72, 3.27, -116.75, 22.80, -39.56],
    [-96.28, -6.27, -0.03, 141.51, 127.44, 140.59],
    [-120.78, 172.33, 0.92, 148.66, -33.28, -37.17],
    [113.84, 5.30, 2.25, -124.07, -117.01, 136.62],
]


def test_manocha_canny_arm_has_16_real_solutions():
    arm = SerialRobot.from_dh(MC_ROWS, "standard", name="manocha_canny", backend="reference")
    table = np.radians(MC_TABLE_III)
    T = arm.fk(table)
    # the table's 16 solutions reach one pose (to its 2-decimal rounding)
    assert np.abs(T - T[0]).max() < 1e-3
    Q, valid = arm.ik_all(T[0])
    assert valid.sum() == 16
    ours = Q[valid]
    d = np.degrees(_wrapped(ours[:, None] - table[None]).max(-1))
    assert d.min(axis=0).max() < 0.05  # every published solution is one of ours
    assert d.min(axis=1).max() < 0.05  # and every one of ours is published
    assert np.abs(arm.fk(ours) - T[0]).max() < 1e-10


def _complete_and_multistart(arm, rng, poses, seeds=64):
    """Random poses, the complete solver's slots for them, and a numeric multi-start from
    `seeds` random starts per pose (joint limits ignored): (T, Q, valid, converged, q)."""
    T = arm.fk(rng.uniform(-np.pi, np.pi, (poses, 6)))
    Q, valid = arm.ik_all(T, method="complete")
    res = ik_numeric.solve(
        arm,
        np.repeat(T, seeds, axis=0),
        rng.uniform(-np.pi, np.pi, (poses * seeds, 6)),
        tol=1e-11,
        max_iter=200,
        respect_limits=False,
    )
    conv = res.converged.reshape(poses, seeds)
    assert conv.mean() > 0.3
    return T, Q, valid, conv, res.q.reshape(poses, seeds, 6)


def test_no_solution_is_missed_numeric_multistart():
    arm = random_6r_arm(3)
    T, Q, valid, conv, qn = _complete_and_multistart(arm, np.random.default_rng(4), 6)
    for p in range(len(T)):
        for s in np.flatnonzero(conv[p]):
            assert _wrapped(Q[p][valid[p]] - qn[p, s]).max(-1).min() < 1e-6


def test_jaco_complete_by_a_regular_arrangement():
    """rtb's Jaco (meeting / parallel neighbouring axes): the forward elimination's pencil
    is singular, a cyclic arrangement's is not; ik_all is complete by default and finds
    everything the combined method finds (and the originals the combined method misses)."""
    arm = jaco_arm()
    assert not general6r.General6R(arm.description).regular
    (elimination,), complete = arm._general()
    assert (
        complete
        and elimination.regular
        and (elimination.shift, elimination.reverse)
        != (
            0,
            False,
        )
    )
    q = np.random.default_rng(8).uniform(-np.pi, np.pi, (60, 6))
    T = arm.fk(q)
    Qa, Va = arm.ik_all(T)
    assert Qa.shape == (60, 16, 6)
    with pytest.warns(IncompleteSolutionsWarning):
        Qc, Vc = arm.ik_all(T, method="combined")
    assert Qc.shape == (60, 8, 6) and len(arm.analytic_configs()) == 8
    fa, fc = _found(Qa, Va, q), _found(Qc, Vc, q)
    assert fa.all() and np.all(fa | ~fc)
    Tq = arm.fk(np.where(Va[..., None], Qa, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[Va].max() < 1e-10


def test_best_effort_path_of_singular_eliminations():
    """With only singular eliminations (forced here: the Jaco's forward and reversed
    chains), ik_all(method="complete") is a best effort that adds the combined branches:
    nothing invalid is marked valid, and it finds whatever the combined method finds."""
    arm = jaco_arm()
    forced = [general6r.General6R(arm.description, reverse=r) for r in (False, True)]
    assert not any(g.regular for g in forced)
    arm._general_6r = (forced, False)
    q = np.random.default_rng(9).uniform(-np.pi, np.pi, (20, 6))
    T = arm.fk(q)
    with pytest.warns(IncompleteSolutionsWarning, match=r"method='complete'\) is not complete"):
        best = arm.ik_all(T, method="complete")
    Qa, Va = best
    assert best.complete is False  # an empty answer here need not mean unreachable
    with pytest.warns(IncompleteSolutionsWarning, match=r"method='combined'\) is not complete"):
        Qc, Vc = arm.ik_all(T, method="combined")
    assert np.all(_found(Qa, Va, q) | ~_found(Qc, Vc, q))
    Tq = arm.fk(np.where(Va[..., None], Qa, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[Va].max() < 1e-10


def test_ik_all_methods_are_checked():
    arm = random_6r_arm(1)
    T = arm.fk(np.zeros(6))
    with pytest.raises(InputError, match="method must be"):
        arm.ik_all(T, method="magic")
    with pytest.raises(InputError, match="no closed-form inverse"):
        arm.ik_all(T, method="closed_form")
    with pytest.raises(InputError, match="combined method does not apply"):
        arm.ik_all(T, method="combined")
    scara = SerialRobot.load("lecture_scara", backend="reference")
    with pytest.raises(InputError, match="needs a 6R arm"):
        scara.ik_all(np.eye(4), method="complete")
    q, valid = arm.ik_all(np.full((4, 4), np.nan))
    assert not valid.any() and np.isnan(q).all()
    with pytest.raises(InputError, match="6 revolute joints"):
        general6r.General6R(scara.description)


# ---------------------------------------------------------------------- batched solver


def _solution_set_equal(Qa, Va, Qb, Vb, tol=1e-9):
    """The valid solutions of two results for one pose are the same set (wrapped)."""
    A, B = Qa[Va], Qb[Vb]
    if A.shape[0] != B.shape[0]:
        return False
    if A.shape[0] == 0:
        return True
    d = _wrapped(A[:, None] - B[None]).max(-1)
    return bool(d.min(axis=0).max() < tol and d.min(axis=1).max() < tol)


@pytest.mark.parametrize("which", ["random", "jaco"])
def test_batched_equals_one_pose_per_call(which):
    """ik_all on a batch (stacked eigenproblems, vectorised extraction and dedupe) gives,
    pose by pose, the same solution set as one (4, 4) pose per call."""
    arm = random_6r_arm(5) if which == "random" else jaco_arm()
    q = np.random.default_rng(21).uniform(-np.pi, np.pi, (24, 6))
    T = arm.fk(q)
    Qb, Vb = arm.ik_all(T, method="complete")
    for i in range(T.shape[0]):
        Q1, V1 = arm.ik_all(T[i], method="complete")
        assert Q1.shape == (16, 6)
        assert _solution_set_equal(Qb[i], Vb[i], Q1, V1), f"pose {i}"


def _ur5():
    return SerialRobot.load("ur5", backend="reference")


def _puma():
    return SerialRobot.load("puma560", backend="reference")


def _nonsingular(arm, q, sigma=1e-3):
    """Rows of q whose geometric Jacobian is clearly of full rank."""
    return np.linalg.svd(arm.jacobian(q), compute_uv=False)[:, -1] > sigma


# (arm, poses): 2100 poses in total across five arms (the completeness check asks >= 2000)
COMPLETENESS = [("jaco", 500), ("ur5", 400), ("puma560", 400), ("random7", 400), ("random8", 400)]


@pytest.mark.parametrize("name,count", COMPLETENESS)
def test_complete_on_random_poses(name, count):
    """The complete solver (forced with method="complete", also for the arms that have a
    closed form; its elimination alone: no combined branches join it): the original q is among the valid solutions on every non-singular pose
    of random q, and every valid solution reproduces T to 1e-10 in the arm's own
    (reference, DH-matrix) fk."""
    arm = {
        "jaco": jaco_arm,
        "ur5": _ur5,
        "puma560": _puma,
        "random7": lambda: random_6r_arm(7),
        "random8": lambda: random_6r_arm(8),
    }[name]()
    eliminations, complete = arm._general()
    assert complete and len(eliminations) == 1 and eliminations[0].recovered == 8
    rng = np.random.default_rng(1000 + count + len(name))
    lim = arm.qlim  # in-limit q (valid means within the limits)
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (count, 6))
    q = q[_nonsingular(arm, q)]
    assert q.shape[0] > 0.9 * count
    T = arm.fk(q)
    Q, valid = arm.ik_all(T, method="complete")
    found = _found(Q, valid, q)
    assert found.all(), f"{name}: original q missed on rows {np.flatnonzero(~found)}"
    Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[valid].max() < 1e-10
    assert np.isfinite(Q[valid]).all()  # (a converged slot outside the limits keeps its q)


def test_standard_and_qz_eigen_paths_agree(monkeypatch):
    """The stacked companion-matrix path and the per-pose QZ path (forced by a condition
    threshold of 0) find the same real eigenvalues x3 of the pencil."""
    arm = jaco_arm()
    (g,), _ = arm._general()
    T = arm.fk(np.random.default_rng(22).uniform(-np.pi, np.pi, (12, 6)))
    w, o, G = g._arranged(T)
    M, _ = g._pencil(w, o, G, g._left_batch(w, o, G))
    idx_a, x_a, _ = g._eigen(M)
    monkeypatch.setattr(general6r, "COND_STANDARD", 0.0)
    idx_b, x_b, _ = g._eigen(M)
    for n in range(12):
        a, b = np.sort(x_a[idx_a == n]), np.sort(x_b[idx_b == n])
        assert a.shape == b.shape and np.allclose(a, b, rtol=1e-6, atol=1e-8), n


def test_carried_left_equals_interpolated():
    """The left side's coefficients from the cached fixed-axis ones (turned by R_G^T for
    the carried arrangements) equal the per-pose interpolation."""
    arm = jaco_arm()
    T = arm.fk(np.random.default_rng(23).uniform(-np.pi, np.pi, (5, 6)))
    for reverse in (False, True):
        for shift in (0, 4, 5):
            g = general6r.General6R(arm.description, reverse=reverse, shift=shift)
            w, o, G = g._arranged(T)
            assert np.abs(g._left_batch(w, o, G) - g._left_coefficients(w, o)).max() < 1e-12


@pytest.mark.parametrize("name", ["jaco", "ur5"])
def test_no_solution_is_missed_on_industrial_arms(name):
    """The independent count check on shifted arrangements: a numeric multi-start (64
    random seeds per pose) converges to no solution that the complete solver missed."""
    arm = jaco_arm() if name == "jaco" else _ur5()
    T, Q, valid, conv, qn = _complete_and_multistart(arm, np.random.default_rng(31), 3)
    # every converged slot (valid or outside the limits) counts: the multi-start ignores them
    have = np.isfinite(Q).all(-1)
    for p in range(len(T)):
        for s_ in np.flatnonzero(conv[p]):
            assert _wrapped(Q[p][have[p]] - qn[p, s_]).max(-1).min() < 1e-6, (p, s_)
