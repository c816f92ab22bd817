"""Combined explicit + numerical IK (deltagen.solve.combined) on the Puma 560 with an
offset wrist (robots/puma560_offset_wrist.toml, a4 = 0.02 m)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from deltagen.api.serial import SerialRobot
from deltagen.inputs import InputError
from deltagen.solve import combined as ik_combined
from deltagen.solve.analytic import analytic_solver

N = 500


@pytest.fixture(scope="module")
def arm():
    return SerialRobot.load("puma560_offset_wrist", backend="reference")


@pytest.fixture(scope="module")
def samples(arm):
    rng = np.random.default_rng(20260101)
    lim = arm.qlim
    q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((N, arm.n))
    T = arm.fk(q)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        qa, valid, info = ik_combined.solve_all(arm, T, info=True)
    return q, T, qa, valid, info


def test_robot_file_loads(arm):
    d = arm.description
    assert d.name == "puma560_offset_wrist" and d.convention == "standard" and arm.n == 6
    assert d.joints[3].a == pytest.approx(0.02)
    np.testing.assert_allclose(arm.fk(np.zeros(6))[:3, 3], [0.4721, -0.15005, 1.10363], atol=1e-12)
    puma = SerialRobot.load("puma560", backend="reference").description
    assert np.allclose(arm.qlim, puma.qlim)


def test_analytic_only_for_nearest_central_wrist(arm):
    assert analytic_solver(arm.description) is None
    # SerialRobot.ik (config=) and ik_all(method="combined") use the combined method, with
    # the same branch names
    assert arm.analytic_configs() == ik_combined.branch_names(arm)
    central = ik_combined.nearest_central_wrist(arm.description)
    assert central.joints[3].a == 0.0
    solver = analytic_solver(central)
    assert solver is not None and solver.structure == "spherical_wrist_6r"
    assert ik_combined.branch_names(arm) == solver.configs and len(solver.configs) == 8
    # the central-wrist arm of the real Puma is the Puma itself
    puma = SerialRobot.load("puma560", backend="reference")
    q = np.array([0.3, 0.5, -1.0, 0.4, 0.7, -0.2])
    np.testing.assert_allclose(
        SerialRobot(central, backend="reference").fk(q), puma.fk(q), atol=1e-14
    )


def test_valid_branches_reproduce_T(arm, samples):
    q, T, qa, valid, _ = samples
    assert qa.shape == (N, 8, 6) and valid.shape == (N, 8)
    assert np.all(np.isfinite(qa[valid]))
    Tk = np.broadcast_to(T[:, None], (N, 8, 4, 4))[valid]
    assert np.max(np.abs(arm.fk(qa[valid]) - Tk)) <= 1e-10
    assert np.all(arm.within_limits(qa[valid]))


def test_original_among_valid_branches(samples):
    q, _, qa, valid, _ = samples
    d = np.abs(np.remainder(qa - q[:, None] + np.pi, 2 * np.pi) - np.pi).max(axis=-1)
    found = np.any(valid & (d < 1e-6), axis=1)
    missed = int(np.count_nonzero(~found))
    print(f"original q not among the valid branches: {missed} of {N}")
    assert missed <= 0.05 * N  # measured: 14 of 500 (near the wrist singularity or a limit)


def test_several_branches_per_pose(samples):
    _, _, _, valid, info = samples
    count = valid.sum(axis=1)
    assert np.count_nonzero(count > 1) >= 0.9 * N
    assert np.median(info["iterations"][valid]) <= 4


def test_unreachable_and_invalid_targets(arm):
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.5]
    bad = np.full((4, 4), np.nan)
    skew = np.eye(4)
    skew[0, 1] = 0.5
    T = np.stack([far, bad, skew, arm.fk(np.zeros(6))])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        qa, valid = ik_combined.solve_all(arm, T)
    assert not valid[:3].any() and np.all(np.isnan(qa[:3]))
    assert valid[3].any()


def test_compiled_backend_agrees(arm, samples):
    compiled = arm.with_backend("compiled")
    q, T, qa, valid, _ = samples
    qc, vc = ik_combined.solve_all(compiled, T[:50])
    assert np.array_equal(vc, valid[:50])
    np.testing.assert_allclose(qc[vc], qa[:50][valid[:50]], atol=1e-9)


def test_not_supported():
    scara = SerialRobot.load("manutec_h5", backend="reference")
    with pytest.raises(InputError, match="6R arm"):
        ik_combined.nearest_central_wrist(scara.description)


def test_serial_robot_ik_all_uses_the_combined_method(arm):
    rng = np.random.default_rng(77)
    lim = arm.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], size=(50, 6))
    T = arm.fk(q)
    # the combined method is an option; by default ik_all is complete (solve/general6r.py)
    q_all, valid = arm.ik_all(T, method="combined")
    assert q_all.shape == (50, 8, 6) and valid.any(axis=1).mean() > 0.9
    np.testing.assert_allclose(
        arm.fk(q_all[valid]), np.repeat(T[:, None], 8, axis=1)[valid], atol=1e-10
    )
