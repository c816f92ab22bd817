"""Asymmetric delta geometry (per-chain r_a, r_b, l_a, l_b, theta, encoder offsets) and the
calibration of a built robot (deltagen.solve.calibration, DeltaRobot.calibrate, the CLI)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from deltagen import DeltaRobot
from deltagen.errors import GeometryError
from deltagen.inputs import InputError
from deltagen.model.delta import DeltaGeometry
from deltagen.native.delta import CompiledDelta
from deltagen.solve.calibration import _values, parameter_names

NOMINAL = DeltaGeometry.default()
ALL = ("r_a", "l_a", "l_b", "theta", "q_offset")


def perturbed(seed=1, size=1e-3):
    rng = np.random.default_rng(seed)
    n = np.array
    return NOMINAL.with_chains(
        r_a=n(NOMINAL.chain("r_a")) + rng.normal(0, size, 3),
        r_b=n(NOMINAL.chain("r_b")) + rng.normal(0, size, 3),
        l_a=n(NOMINAL.chain("l_a")) + rng.normal(0, size, 3),
        l_b=n(NOMINAL.chain("l_b")) + rng.normal(0, size, 3),
        theta=n(NOMINAL.theta) + rng.normal(0, 3 * size, 3),
        q_offset=rng.normal(0, 5 * size, 3),
    )


ASYM = perturbed()


def _q(rng, n):
    return rng.uniform(-0.3, 1.0, (n, 3))


# ------------------------------------------------------------ the asymmetric robot


def test_compiled_matches_reference_on_an_asymmetric_robot():
    rng = np.random.default_rng(2)
    q = _q(rng, 3000)
    c, r = DeltaRobot.from_geometry(ASYM), DeltaRobot.from_geometry(ASYM, "reference")
    pc, vc = c.fk(q, errors="nan")
    pr, vr = r.fk(q, errors="nan")
    np.testing.assert_array_equal(vc, vr)
    assert vc.mean() > 0.9
    np.testing.assert_allclose(pc[vc], pr[vr], rtol=0, atol=1e-12 * ASYM.size)
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape)
    for a, b in zip(c.fk_acc(q[vc], qd[vc], qdd[vc]), r.fk_acc(q[vc], qd[vc], qdd[vc])):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(c.ik(pc[vc]), r.ik(pr[vr]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_asymmetric_round_trips_and_rod_lengths(backend):
    """fk(ik(p)) = p, ik(fk(q)) = q, and each chain's rod has its own length: the
    distance from the crank tip to the platform joint, computed here from the geometry."""
    robot = DeltaRobot.from_geometry(ASYM, backend)
    rng = np.random.default_rng(3)
    q = _q(rng, 500)
    p, valid = robot.fk(q, errors="nan")
    q, p = q[valid], p[valid]
    np.testing.assert_allclose(robot.ik(p), q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(robot.fk(robot.ik(p)), p, rtol=0, atol=1e-12)
    for i in range(3):
        crank = q[:, i] + ASYM.q_offset[i]
        th = ASYM.theta[i]
        radial = np.array([np.cos(th), np.sin(th), 0.0])
        tip = (ASYM.chain("r_a")[i] + ASYM.chain("l_a")[i] * np.cos(crank))[:, None] * radial
        tip[:, 2] = -ASYM.chain("l_a")[i] * np.sin(crank)
        joint = p + ASYM.chain("r_b")[i] * radial
        np.testing.assert_allclose(
            np.linalg.norm(joint - tip, axis=1), ASYM.chain("l_b")[i], rtol=0, atol=1e-12
        )


def test_asymmetric_jacobian_and_rates_against_finite_differences():
    robot = DeltaRobot.from_geometry(ASYM)
    q = _q(np.random.default_rng(4), 50)
    p, valid = robot.fk(q, errors="nan")
    q = q[valid]
    h = 1e-6
    J_fd = np.stack(
        [(robot.fk(q + h * e) - robot.fk(q - h * e)) / (2 * h) for e in np.eye(3)], axis=-1
    )
    np.testing.assert_allclose(robot.jacobian(q), J_fd, rtol=0, atol=1e-8)
    qd = np.ones_like(q)
    q2, qd2, qdd2 = robot.ik_acc(*robot.fk_acc(q, qd, -qd))
    np.testing.assert_allclose(qd2, qd, rtol=0, atol=1e-10)
    np.testing.assert_allclose(qdd2, -qd, rtol=0, atol=1e-9)


def test_parameter_jacobian_against_finite_differences():
    """The generated dp/dpi (implicit derivative of eq. (1)) against central differences of
    fk over perturbed geometries, for every parameter family and chain."""
    q = _q(np.random.default_rng(5), 20)
    spec = parameter_names(("r_a", "r_b", "l_a", "l_b", "theta", "q_offset"))
    _, G, status = CompiledDelta(ASYM).fk_param_jacobian(q)
    assert (status == 0).all()
    x0 = _values(ASYM, spec)
    from deltagen.solve.calibration import _apply

    h = 1e-7
    for j, (name, _, col, sign) in enumerate(spec):
        step = np.zeros(len(spec))
        step[j] = h
        hi = DeltaRobot.from_geometry(_apply(ASYM, spec, x0 + step)).fk(q)
        lo = DeltaRobot.from_geometry(_apply(ASYM, spec, x0 - step)).fk(q)
        np.testing.assert_allclose(
            sign * G[:, :, col], (hi - lo) / (2 * h), rtol=0, atol=1e-7, err_msg=name
        )


def test_symmetric_robot_is_unchanged_and_asymmetric_dynamics_refused():
    assert NOMINAL.symmetric and not ASYM.symmetric
    assert NOMINAL.chain("l_a") == (0.35, 0.35, 0.35)
    with pytest.raises(GeometryError, match="symmetric"):
        DeltaRobot.from_geometry(ASYM.with_chains(q_offset=(0.0, 0.0, 0.0))).inverse_dynamics(
            [0.1, 0.2, 0.3], [0.0] * 3, [0.0] * 3
        )
    with pytest.raises(GeometryError, match="chain_l_a"):
        NOMINAL.with_chains(l_a=(0.35, -0.1, 0.35))


def test_robot_file_with_per_chain_values(tmp_path):
    path = tmp_path / "built.toml"
    path.write_text(
        "[delta]\nr_a = 0.2\nr_b = 0.045\nl_a = 0.35\nl_b = 0.8\ntheta_deg = [0, 120, 240]\n"
        "chain_l_a = [0.35, 0.351, 0.349]\nq_offset_deg = [0.0, 0.5, -0.25]\n"
    )
    g = DeltaGeometry.from_toml(path)
    assert g.chain("l_a") == (0.35, 0.351, 0.349)
    assert np.degrees(g.q_offset) == pytest.approx([0.0, 0.5, -0.25])


# --------------------------------------------------------------------- calibration


def _measure(truth, q, noise, rng):
    p, valid = DeltaRobot.from_geometry(truth).fk(q, errors="nan")
    return q[valid], p[valid] + rng.normal(0.0, noise, p[valid].shape)


def test_recovers_known_perturbations_within_the_predicted_uncertainty():
    rng = np.random.default_rng(6)
    truth = perturbed(seed=7).with_chains(r_b=NOMINAL.chain("r_b"))  # r_b is not separable
    noise = 20e-6  # 20 um per coordinate
    q, p = _measure(truth, _q(rng, 80), noise, rng)
    result = DeltaRobot.default().calibrate(q, p, params=ALL)
    assert result.identifiable and result.converged
    x_true = _values(truth, parameter_names(ALL))
    z = (result.values - x_true) / result.uncertainty
    assert np.all(np.abs(z) < 4.0), dict(zip(result.names, np.round(z, 2)))
    # the residual drops to the noise (3 coordinates per point)
    assert result.rms_before > 50 * noise
    assert result.rms_after < 1.5 * noise * np.sqrt(3)
    # the calibrated robot predicts fresh measurements to the noise level
    q2, p2 = _measure(truth, _q(rng, 40), 0.0, rng)
    err = np.linalg.norm(result.robot.fk(q2) - p2, axis=1)
    assert err.max() < 10 * noise
    assert "identifiable" in result.report()


def test_a_redundant_pair_is_reported_unidentifiable():
    rng = np.random.default_rng(8)
    q, p = _measure(perturbed(seed=9), _q(rng, 40), 10e-6, rng)
    result = DeltaRobot.default().calibrate(q, p, params=("r_a", "r_b", "l_b"))
    assert not result.identifiable
    assert set(result.unidentifiable) == {(f"r_a[{i}]", f"r_b[{i}]") for i in range(3)}
    assert np.all(np.isinf(result.uncertainty[:6])) and np.all(np.isfinite(result.uncertainty[6:]))
    assert "NOT identifiable" in result.report()


def test_a_chain_that_never_moves_cannot_separate_its_crank():
    """With q_1 fixed in every measurement, chain 1's crank tip is one point: r_a,1, l_a,1
    and its encoder offset cannot be told apart."""
    rng = np.random.default_rng(10)
    q = _q(rng, 60)
    q[:, 0] = 0.3
    q, p = _measure(perturbed(seed=11), q, 10e-6, rng)
    result = DeltaRobot.default().calibrate(q, p, params=ALL)
    assert result.unidentifiable == (("r_a[0]", "l_a[0]", "q_offset[0]"),)


def test_bad_calibration_input_is_a_clear_error():
    robot = DeltaRobot.default()
    q = np.zeros((10, 3))
    with pytest.raises(InputError, match="unknown calibration parameter"):
        robot.calibrate(q, q, params=("l_c",))
    with pytest.raises(InputError, match=r"rows \[2\]"):
        p = robot.fk(q)
        p[2, 1] = np.nan
        robot.calibrate(q, p)
    with pytest.raises(InputError, match="N, 3"):
        robot.calibrate(q, q[:, :2])


def test_cli_calibrate(tmp_path, repo_root):
    rng = np.random.default_rng(12)
    truth = perturbed(seed=13).with_chains(r_b=NOMINAL.chain("r_b"))
    q, p = _measure(truth, _q(rng, 50), 10e-6, rng)
    data = tmp_path / "measured.csv"
    np.savetxt(data, np.column_stack([q, p]), delimiter=",", header="q1,q2,q3,x,y,z", comments="")
    out_toml = tmp_path / "built.toml"
    run = subprocess.run(
        [sys.executable, "-m", "deltagen", "calibrate", str(data), "--out", str(out_toml)],
        capture_output=True,
        text=True,
        cwd=repo_root,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert "residual RMS" in run.stdout and "l_b[2]" in run.stdout
    built = DeltaRobot.from_toml(out_toml)
    np.testing.assert_allclose(built.fk(q), p, rtol=0, atol=1e-4)
