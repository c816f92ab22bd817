"""The damped least-squares step (deltagen/solve/least_squares.py) against the Tikhonov
normal equations written out here, (J^T J + lambda^2 I) dx = J^T r (Nocedal & Wright,
Numerical Optimization, sec. 10.3: the Levenberg-Marquardt step), for a single fit and a
batch, and the truncation: a direction below rcond gets no step (minimum norm); ``solve``
(the step from J itself, with the loops' damping scales) against the right-sided normal
equations J^T (J J^T + lambda^2 I)^-1 r the path follower used to solve, numpy's LU and
numpy's minimum-norm lstsq."""

from __future__ import annotations

import numpy as np
import pytest

from deltagen.solve.least_squares import damped_step, kept, lambda2, solve


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


@pytest.mark.parametrize("shape", [(6, 6), (3, 7), (9, 4)])
@pytest.mark.parametrize("scale", ["absolute", "largest", "mean"])
def test_solve_is_the_damped_step_of_each_scale(shape, scale):
    """lambda^2 = damping (absolute), damping |J|_2^2 (largest) or damping trace(J J^T) / m
    (mean, the path follower's schedule), checked against the other side's normal
    equations J^T (J J^T + lambda^2 I)^-1 r (the same step by the push-through identity)."""
    rng = np.random.default_rng(len(scale) + sum(shape))
    m, n = shape
    J = rng.standard_normal((4, m, n))
    r = rng.standard_normal((4, m))
    damping = 0.3
    factor = {
        "absolute": np.ones(4),
        "largest": np.linalg.norm(J, 2, axis=(1, 2)) ** 2,
        "mean": np.trace(J @ np.swapaxes(J, 1, 2), axis1=1, axis2=2) / m,
    }[scale]
    batched = solve(J, r, damping, scale=scale)
    for k in range(4):
        lam2 = damping * factor[k]
        expected = J[k].T @ np.linalg.solve(J[k] @ J[k].T + lam2 * np.eye(m), r[k])
        np.testing.assert_allclose(solve(J[k], r[k], damping, scale=scale), expected, rtol=1e-9)
        np.testing.assert_allclose(batched[k], expected, rtol=1e-9)
    s = np.linalg.svd(J, compute_uv=False)
    np.testing.assert_allclose(lambda2(s, damping, scale, m), damping * factor, rtol=1e-12)
    with pytest.raises(ValueError, match="scale"):
        lambda2(s, damping, "median", m)  # type: ignore[arg-type]


def test_undamped_solve_is_newtons_step_or_the_minimum_norm_one():
    """Undamped: numpy's LU for a regular square J, bit for bit; a batch with an exactly
    singular row, or a J that is not square, gets numpy lstsq's minimum-norm solution."""
    rng = np.random.default_rng(11)
    J = rng.standard_normal((3, 6, 6))
    r = rng.standard_normal((3, 6))
    assert np.array_equal(solve(J, r), np.linalg.solve(J, r[..., None])[..., 0])
    assert np.array_equal(solve(J[0], r[0]), np.linalg.solve(J[0], r[0]))
    J[1, :, 5] = J[1, :, 0]  # exactly singular: LU refuses the batch
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(J, r[..., None])
    for k, dx in enumerate(solve(J, r)):
        np.testing.assert_allclose(dx, np.linalg.lstsq(J[k], r[k], rcond=None)[0], atol=1e-10)
    wide = rng.standard_normal((3, 7))
    rhs = rng.standard_normal(3)
    np.testing.assert_allclose(solve(wide, rhs), np.linalg.lstsq(wide, rhs, rcond=None)[0])
    np.testing.assert_allclose(wide @ solve(wide, rhs), rhs, atol=1e-12)
