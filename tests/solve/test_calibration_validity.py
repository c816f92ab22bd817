"""Calibration that says what it cannot know: identifiability judged against the noise,
bounded parameters, the validity of the fit in the result and the CLI's exit status, hints
at units, clear errors for data that cannot be calibrated; and the positive control: known
errors are recovered within honest uncertainties, through the CLI to a robot file whose fk
agrees with the true robot."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from deltagen import DeltaRobot
from deltagen.errors import KinematicsError
from deltagen.inputs import InputError
from deltagen.model.delta import DeltaGeometry
from deltagen.solve.calibration import _values, parameter_names

NOMINAL = DeltaGeometry.default()
# r_b is not separable from r_a (they enter only as r_a - r_b): it is not calibrated
ALL = ("r_a", "l_a", "l_b", "theta", "q_offset")
NOISE = 20e-6  # 20 um per coordinate, a laser tracker


def built(seed=13, size=1e-3):
    """A robot as built: mm-sized length errors, mrad-sized angle errors."""
    rng = np.random.default_rng(seed)
    n = np.array
    return NOMINAL.with_chains(
        r_a=n(NOMINAL.chain("r_a")) + rng.normal(0, size, 3),
        l_a=n(NOMINAL.chain("l_a")) + rng.normal(0, size, 3),
        l_b=n(NOMINAL.chain("l_b")) + rng.normal(0, size, 3),
        theta=n(NOMINAL.theta) + rng.normal(0, 3 * size, 3),
        q_offset=rng.normal(0, 5 * size, 3),
    )


TRUTH = built()


def measure(q, noise=NOISE, seed=0, truth=TRUTH):
    rng = np.random.default_rng(seed)
    p, valid = DeltaRobot.from_geometry(truth).fk(q, errors="nan")
    return q[valid], p[valid] + rng.normal(0.0, noise, p[valid].shape)


def spread_poses(n, seed=1):
    return np.random.default_rng(seed).uniform(-0.3, 1.0, (n, 3))


@pytest.fixture(scope="module")
def nominal():
    return DeltaRobot.default()


# --------------------------------------------------------------- what cannot be known


def test_three_cranks_moving_together_is_not_identifiable_nor_valid(nominal):
    """q1 = q2 = q3 in every pose: the platform only moves on the axis, and the drive angles
    theta_i are seen through a few tens of nm at best. Before: theta ~ -8.8e9 rad, 1 sigma up
    to 1e3 rad, "every parameter is identifiable"."""
    t = np.random.default_rng(2).uniform(-0.3, 1.0, 60)
    q, p = measure(np.column_stack([t, t, t]))
    result = nominal.calibrate(q, p, params=ALL)
    assert not result.valid and not result.identifiable
    unplaced = {n for group in result.unidentifiable for n in group}
    assert {"theta[0]", "theta[1]", "theta[2]"} <= unplaced
    assert "every parameter is identifiable" not in result.report()
    assert "FIT NOT VALID" in result.report()
    # bounded: no parameter leaves nominal +- its bound
    lo, hi = result.bounds.T
    assert np.all((result.values >= lo) & (result.values <= hi))
    theta = np.array([result.values[result.names.index(f"theta[{i}]")] for i in range(3)])
    assert np.all(np.abs(theta - np.array(NOMINAL.theta)) <= 0.3 + 1e-12)
    # what is reported unidentifiable has 1 sigma beyond a third of its bound
    half = (hi - lo) / 2  # lengths' lower bounds are far from 0 here: symmetric boxes
    for name in unplaced:
        j = result.names.index(name)
        assert result.uncertainty[j] > half[j] / 3


def test_positions_in_millimetres_are_an_invalid_fit_with_a_units_hint(nominal):
    q, p = measure(spread_poses(50))
    result = nominal.calibrate(q, 1000.0 * p, params=ALL)
    assert not result.valid
    assert any("does not fit" in problem for problem in result.problems)
    assert len(result.hints) == 1 and "millimetres" in result.hints[0]
    # with the noise given, the chi-square test refuses it the same way
    result = nominal.calibrate(q, 1000.0 * p, params=ALL, sigma=NOISE)
    assert not result.valid and result.p_value < 1e-3
    assert "millimetres" in result.hints[0]


def test_swapped_columns_are_an_invalid_fit_with_a_hint(nominal):
    q, p = measure(spread_poses(50))
    result = nominal.calibrate(p, q, params=ALL)
    assert not result.valid
    assert len(result.hints) == 1 and "swapped" in result.hints[0]


def test_q_in_degrees_that_the_model_cannot_reach_name_degrees(nominal):
    """Readings in degrees put some poses out of the nominal robot's reach: the error names
    the rows and the likely cause."""
    q, p = measure(spread_poses(50))
    with pytest.raises(KinematicsError, match=r"at measurements \[.*hint: q look like degrees"):
        nominal.calibrate(np.degrees(q), p, params=ALL)


def test_a_fit_that_leaves_its_bounds_is_invalid(nominal):
    """A robot 20 % longer than the nominal one: the lengths cannot reach it inside their
    10 % bound; the fit ends on the bound and says so."""
    long = DeltaGeometry(r_a=0.24, r_b=0.054, l_a=0.42, l_b=0.96, theta=NOMINAL.theta)
    q, p = measure(spread_poses(50), truth=long)
    result = nominal.calibrate(q, p, params=("l_a", "l_b"), sigma=NOISE)
    assert not result.valid and result.at_bound
    assert any("bound" in problem for problem in result.problems)


def test_a_residual_at_the_given_noise_is_valid_and_one_far_above_it_is_not(nominal):
    q, p = measure(spread_poses(60))
    assert nominal.calibrate(q, p, params=ALL, sigma=NOISE).valid
    result = nominal.calibrate(q, p, params=ALL, sigma=NOISE / 10)  # noise understated 10x
    assert not result.valid and result.reduced_chi2 > 50


@pytest.mark.parametrize(
    "case, match",
    [
        ("empty", "no measurements"),
        ("five points", "too few measurements: 5 points give 15 equations for 15 parameters"),
        ("negative sigma", "sigma .* positive finite"),
        ("nan sigma", "sigma .* positive finite"),
        ("zero sigma", "sigma .* positive finite"),
        ("inf sigma", "sigma .* positive finite"),
    ],
)
def test_data_that_cannot_be_calibrated_is_a_clear_error(nominal, case, match):
    q, p = measure(spread_poses(20))
    kwargs: dict = {}
    if case == "empty":
        q, p = q[:0], p[:0]
    elif case == "five points":
        q, p = q[:5], p[:5]
    else:
        kwargs["sigma"] = {"negative": -1e-5, "nan": np.nan, "zero": 0.0, "inf": np.inf}[
            case.split()[0]
        ]
    with pytest.raises(InputError, match=match):
        nominal.calibrate(q, p, params=ALL, **kwargs)


# ------------------------------------------------------------------ positive control


def test_known_errors_are_recovered_within_honest_uncertainties(nominal):
    """Over 8 noise seeds the errors of the 15 identified parameters divided by their
    reported 1 sigma behave like standard normal draws: mean square ~1 (a covariance 3x too
    small or too large would give ~9 or ~0.1), none beyond 4.5; every fit is valid and the
    residual passes the chi-square test with the true noise."""
    x_true = _values(TRUTH, parameter_names(ALL))
    z = []
    q_all = spread_poses(80, seed=20)
    for seed in range(8):
        q, p = measure(q_all, seed=100 + seed)
        result = nominal.calibrate(q, p, params=ALL, sigma=NOISE if seed % 2 else None)
        assert result.valid and result.identifiable and result.converged, result.problems
        assert "fit valid" in result.report()
        z.append((result.values - x_true) / result.uncertainty)
    z = np.array(z)
    assert np.all(np.abs(z) < 4.5), np.round(z, 2)
    assert 0.5 < np.mean(z**2) < 1.7, np.mean(z**2)


def test_cli_exit_status_and_the_written_robot(tmp_path, repo_root):
    """calibrate -> the written robot file -> `deltagen fk` on it agrees with the true robot
    on fresh poses to the noise; an invalid fit exits 1 and writes nothing unless --force;
    bad input exits 2 with a message, no traceback."""

    def cli(*argv):
        return subprocess.run(
            [sys.executable, "-m", "deltagen", *map(str, argv)],
            capture_output=True,
            text=True,
            cwd=repo_root,
            timeout=300,
        )

    q, p = measure(spread_poses(80))
    good = tmp_path / "measured.csv"
    np.savetxt(good, np.column_stack([q, p]), delimiter=",", header="q1,q2,q3,x,y,z", comments="")
    out = tmp_path / "built.toml"
    run = cli("calibrate", good, "--sigma", NOISE, "--out", out)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "fit valid" in run.stdout and out.exists()
    fresh = spread_poses(30, seed=99)
    p_true, ok = DeltaRobot.from_geometry(TRUTH).fk(fresh, errors="nan")
    poses = tmp_path / "fresh.csv"
    np.savetxt(poses, fresh[ok], delimiter=",", header="q1,q2,q3", comments="")
    answer = tmp_path / "answer.csv"
    run = cli("fk", out, "--input", poses, "--output", answer)
    assert run.returncode == 0, run.stderr
    p_fk = np.loadtxt(answer, delimiter=",", skiprows=1, usecols=(0, 1, 2))
    err = np.linalg.norm(p_fk - p_true[ok], axis=1)
    assert err.max() < 5 * NOISE, err.max()
    # the nominal robot is 5 mm off: the agreement is the calibration's
    p_nominal = DeltaRobot.default().fk(fresh[ok])
    assert np.linalg.norm(p_nominal - p_true[ok], axis=1).max() > 100 * NOISE

    # positions in mm: exit 1, the hint, nothing written
    mm = tmp_path / "mm.csv"
    np.savetxt(mm, np.column_stack([q, 1000 * p]), delimiter=",")
    bad_out = tmp_path / "bad.toml"
    run = cli("calibrate", mm, "--out", bad_out)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "millimetres" in run.stderr and "not written" in run.stderr
    assert not bad_out.exists() and "Traceback" not in run.stderr
    run = cli("calibrate", mm, "--out", bad_out, "--force")
    assert run.returncode == 1 and bad_out.exists()

    # three cranks together: exit 1
    t = np.random.default_rng(2).uniform(-0.3, 1.0, 60)
    q3, p3 = measure(np.column_stack([t, t, t]))
    together = tmp_path / "together.csv"
    np.savetxt(together, np.column_stack([q3, p3]), delimiter=",")
    run = cli("calibrate", together, "--out", bad_out.with_name("t.toml"))
    assert run.returncode == 1 and "theta" in run.stderr
    assert not bad_out.with_name("t.toml").exists()

    # bad input: exit 2, a message naming the problem
    five = tmp_path / "five.csv"
    np.savetxt(five, np.column_stack([q, p])[:5], delimiter=",")
    empty = tmp_path / "empty.csv"
    empty.write_text("q1,q2,q3,x,y,z\n")
    for argv, message in [
        ((five,), "too few measurements"),
        ((empty,), "no measurements"),
        ((good, "--sigma", "-1e-5"), "sigma"),
        ((good, "--sigma", "nan"), "sigma"),
    ]:
        run = cli("calibrate", *argv)
        assert run.returncode == 2, (argv, run.stdout, run.stderr)
        assert message in run.stderr and "Traceback" not in run.stderr
