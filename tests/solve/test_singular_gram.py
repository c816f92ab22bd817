"""ik's exact-singularity check for arms whose Jacobian is not square (a 7-axis arm's 6 x 7,
a SCARA's 6 x 4): the cheap Gram-determinant bound (solve/ik.py, GRAM_TOL) clears only rows
that an SVD also finds regular, and every row it does not clear gets the SVD.

Evidence: the singular values of the numpy reference's Jacobian (deltagen.reference.serial,
written from the model, not the derivation), by numpy's SVD, on random configurations, on
exact singularities (the Panda-like arm stretched upright: joint axes 1, 3, 5, 7 on one
line) and on configurations moved off them by known small angles, whose ratio
sigma_min / sigma_max lies on either side of SINGULAR_TOL.
"""

from __future__ import annotations

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.apps.bench.ik import panda_like
from deltagen.reference import serial as reference
from deltagen.solve import ik as solve_ik
from deltagen.status import SINGULAR_TOL


@pytest.fixture(scope="module")
def panda():
    return panda_like()


@pytest.fixture(scope="module")
def scara():
    return SerialRobot.load("manutec_h5", threads=1)


def _ratio(arm, q):
    J = reference.jacobian(arm.description, np.ascontiguousarray(q[None]))[0][0]
    s = np.linalg.svd(J, compute_uv=False)
    return s[-1] / s[0]


def _check(arm, q):
    ratio = _ratio(arm, q)
    planner = arm.ik_planner
    one = planner.singular_one(np.ascontiguousarray(q))
    rows = bool(planner.singular_rows(q[None])[0])
    if ratio < 0.5 * SINGULAR_TOL:
        assert one and rows, ratio
    elif ratio > 2 * SINGULAR_TOL:
        assert not one and not rows, ratio
    return ratio


def test_random_configurations_of_a_wide_jacobian(panda):
    rng = np.random.default_rng(2103)
    lim = panda.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (200, 7))
    ratios = [_check(panda, qi) for qi in q]
    assert min(ratios) > 2 * SINGULAR_TOL  # generic configurations: regular
    # the batch form on all rows at once agrees
    assert not panda.ik_planner.singular_rows(q).any()


def test_exact_and_near_singularities_of_a_wide_jacobian(panda):
    upright = np.zeros(7)  # axes 1, 3, 5 and 7 on the base z axis (frames of PANDA_DH)
    assert _check(panda, upright) < 0.5 * SINGULAR_TOL
    seen = set()
    for step in (1e-2, 1e-4, 1e-7, 1e-9, 1e-11, 1e-13):
        for joint in (1, 3, 5):
            q = upright.copy()
            q[joint] = step
            ratio = _check(panda, q)
            seen.add(ratio < 0.5 * SINGULAR_TOL)
            seen.add(ratio > 2 * SINGULAR_TOL)
    assert seen == {True, False}  # both sides of the tolerance were visited
    # the batch form on a mix of rows
    q = np.array([upright, upright + 0.3, upright])
    assert panda.ik_planner.singular_rows(q).tolist() == [True, False, True]


def test_a_tall_jacobian(scara):
    rng = np.random.default_rng(2104)
    lim = np.clip(scara.qlim, -np.pi, np.pi)
    q = rng.uniform(lim[:, 0], lim[:, 1], (100, scara.n))
    J = scara.jacobian(q[:1])[0]
    assert J.shape[0] > J.shape[1]  # 6 x 4: the Gram matrix is J^T J
    for qi in q:
        _check(scara, qi)
    # the elbow W3 stretched (q3 = 0): W2, W3 and W4 move the tool point along one line
    # and turn it about z (three columns in a plane of two components)
    stretched = q[0].copy()
    stretched[2] = 0.0
    assert _check(scara, stretched) < 0.5 * SINGULAR_TOL


def test_gram_tolerance_is_far_above_the_singular_one():
    # the bound's rounding (a few eps relative on G's eigenvalues) lifts a ratio below
    # SINGULAR_TOL to ~1e-8 at most: GRAM_TOL must stay well above that
    assert solve_ik.GRAM_TOL > 100 * SINGULAR_TOL


def test_the_c_test_of_a_square_jacobian_is_sound():
    """The Puma's cheap test in C (lean_ext regular_kernel: the generated Jacobian and the
    runtime's LU) clears a configuration only where the reference SVD finds sigma_min /
    sigma_max >= SINGULAR_TOL, and singular_one agrees with the SVD around the wrist
    singularity q5 = 0."""
    arm = SerialRobot.load("puma560", threads=1)
    regular = arm.ik_planner.regular_single
    if regular is None:
        pytest.skip("no C extension here: singular_one's numpy test serves")
    rng = np.random.default_rng(2108)
    q = rng.uniform(-np.pi, np.pi, (300, 6))
    cleared = 0
    for qi in q:
        ok = regular(qi)
        assert ok in (True, False)
        if ok:
            assert _ratio(arm, qi) >= SINGULAR_TOL
            cleared += 1
        _check(arm, qi)
    assert cleared > 250  # generic configurations are cleared without the SVD
    base = np.array([0.3, -0.6, 0.4, 0.8, 0.0, -0.2])
    assert regular(base) is False  # q5 = 0: det J = 0
    seen = set()
    for step in (1e-2, 1e-5, 1e-8, 1e-10, 1e-12):
        qs = base.copy()
        qs[4] = step
        ratio = _check(arm, qs)
        if regular(qs):
            assert ratio >= SINGULAR_TOL
        seen.add(ratio > 2 * SINGULAR_TOL)
    assert seen == {True, False}
    nan = base.copy()
    nan[0] = np.nan
    assert regular(nan) is None and regular(base[:5]) is None and regular("q") is None


@pytest.mark.parametrize("shape", [(6, 6), (6, 7), (6, 4), (3, 3)])
def test_one_bound_serves_the_stacked_and_the_one_pose_form(shape):
    """bound_clears is one function for singular_rows' (M, r, c) stack and singular_one's
    (r, c) pose: both forms give the same verdict row by row, and a row is cleared only
    where numpy's SVD finds sigma_min / sigma_max >= SINGULAR_TOL (rows scaled towards
    singular by shrinking one singular value on either side of the tolerance)."""
    rng = np.random.default_rng(2405)
    U = np.linalg.qr(rng.standard_normal((200, shape[0], shape[0])))[0]
    V = np.linalg.qr(rng.standard_normal((200, shape[1], shape[1])))[0]
    m = min(shape)
    s = rng.uniform(0.5, 3.0, (200, m))
    s[:, -1] *= 10.0 ** rng.uniform(-14, 0, 200)  # ratios across SINGULAR_TOL and GRAM_TOL
    S = np.zeros((200,) + shape)
    S[:, np.arange(m), np.arange(m)] = s
    J = U @ S @ V
    stacked = solve_ik.bound_clears(J)
    one = np.array([bool(solve_ik.bound_clears(np.ascontiguousarray(Ji))) for Ji in J])
    assert stacked.dtype == bool and stacked.shape == (200,)
    assert (stacked == one).all()
    sv = np.linalg.svd(J, compute_uv=False)
    assert (sv[stacked, -1] >= SINGULAR_TOL * sv[stacked, 0]).all()
    assert stacked.any() and not stacked.all()  # both verdicts were reached
    assert not solve_ik.bound_clears(np.zeros(shape))  # a zero J is left to the SVD
