"""The damped least-squares step (deltagen/solve/least_squares.py) against the Tikhonov
normal equations written out here, (J^T J + lambda^2 I) dx = J^T r (Nocedal & Wright,
Numerical Optimization, sec. 10.3: the Levenberg-Marquardt step), for a single fit and a
batch, and the truncation: a direction below rcond gets no step (minimum norm)."""

from __future__ import annotations

import numpy as np
import pytest

from deltagen.solve.least_squares import damped_step, kept


def _normal_equations(J, r, lam2):
    n = J.shape[1]
    return np.linalg.solve(J.T @ J + lam2 * np.eye(n), J.T @ r)


@pytest.mark.parametrize("shape", [(9, 4), (6, 6), (3, 7)])
def test_single_and_batched_steps_solve_the_damped_normal_equations(shape):
    rng = np.random.default_rng(sum(shape))
    J = rng.standard_normal((5, *shape))
    r = rng.standard_normal((5, shape[0]))
    lam2 = rng.uniform(1e-3, 1.0, 5)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    batched = damped_step(U, s, Vt, r, lam2, kept(s, 1e-12))
    for k in range(5):
        expected = _normal_equations(J[k], r[k], lam2[k])
        single = damped_step(U[k], s[k], Vt[k], r[k], lam2[k], kept(s[k], 1e-12))
        np.testing.assert_allclose(single, expected, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(batched[k], expected, rtol=1e-10, atol=1e-12)


def test_an_unseen_direction_gets_no_step():
    rng = np.random.default_rng(3)
    J = rng.standard_normal((8, 3))
    J[:, 2] = J[:, 0] - J[:, 1]  # rank 2: (1, -1, -1) / sqrt(3) is unseen
    r = rng.standard_normal(8)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    keep = kept(s, 1e-9)
    assert keep.tolist() == [True, True, False]
    dx = damped_step(U, s, Vt, r, 0.0, keep)
    null = np.array([1.0, -1.0, -1.0]) / np.sqrt(3.0)
    assert abs(dx @ null) < 1e-12
    # undamped, the kept directions give the least-squares fit: the residual is orthogonal
    # to the columns of J
    np.testing.assert_allclose(J.T @ (r - J @ dx), 0.0, atol=1e-12)


def test_nothing_is_kept_when_the_jacobian_is_zero():
    s = np.zeros((2, 3))
    assert not kept(s, 1e-9).any()
    U, Vt = np.zeros((2, 4, 3)), np.zeros((2, 3, 3))
    dx = damped_step(U, s, Vt, np.ones((2, 4)), np.ones(2), kept(s, 1e-9))
    assert np.all(dx == 0.0)
