"""Tests of `deltagen validate` (deltagen.apps.validate): the report's trajectory of
eqs. (40)-(42), the round trip ik_acc -> fk_acc, the CSV/PNG output and the exit codes.

Expected values come from the printed equations and from finite differences, never from
what the code prints.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from deltagen import DeltaRobot
from deltagen.apps import validate as val
from deltagen.cli import main as cli_main

# ------------------------------------------------------------------ trajectory


def _eqs_40_42(t):
    """x, y, z of eqs. (40)-(42), typed in from the report, one float t at a time."""
    x = 0.25 * math.sin(0.5 * (5 - 0.1) * 2 * math.pi / 10 * t**2 + 0.1 * 2 * math.pi * t)
    y = 0.25 * math.sin(0.5 * (0.1 - 5) * 2 * math.pi / 10 * t**2 + 5 * 2 * math.pi * t)
    z = 0.1 * math.sin(5 * 2 * math.pi * t + math.pi / 2) - 0.7556
    return x, y, z


def test_trajectory_is_eqs_40_to_42():
    t = np.linspace(0.0, 10.0, 97)
    p, pd, pdd = val.trajectory(t)
    assert p.shape == pd.shape == pdd.shape == (97, 4)
    expected = np.array([_eqs_40_42(float(v)) for v in t])
    # phases reach ~160 rad: a different rounding order costs ~0.25 m * 160 * eps
    np.testing.assert_allclose(p[:, :3], expected, rtol=0, atol=1e-13)
    np.testing.assert_allclose(p[:, 3], 0.5 * np.sin(np.pi * t), rtol=0, atol=1e-15)
    # t = 0: x = y = 0, z = 0.1 - 0.7556; the initial speeds are the start frequencies
    np.testing.assert_allclose(p[0], [0.0, 0.0, 0.1 - 0.7556, 0.0], atol=1e-15)
    np.testing.assert_allclose(
        pd[0],
        [0.25 * 0.2 * math.pi, 0.25 * 10 * math.pi, 0.0, 0.5 * math.pi],
        rtol=1e-14,
        atol=1e-14,
    )


def test_trajectory_scalar_time():
    p, pd, pdd = val.trajectory(1.25)
    assert p.shape == pd.shape == pdd.shape == (4,)


@pytest.mark.parametrize("h", [1e-5])
def test_trajectory_derivatives_match_central_differences(h):
    t = np.linspace(0.0, 10.0, 1001)
    p, pd, pdd = val.trajectory(t)
    p_plus, pd_plus, _ = val.trajectory(t + h)
    p_minus, pd_minus, _ = val.trajectory(t - h)
    fd_pd = (p_plus - p_minus) / (2 * h)
    fd_pdd = (pd_plus - pd_minus) / (2 * h)
    fd2_pdd = (p_plus - 2 * p + p_minus) / h**2
    # truncation error h^2/6 |p'''| ~ 1e-10 * 8e3 m/s^3; compare relative to the peaks
    vmax = np.abs(pd).max(axis=0)
    amax = np.abs(pdd).max(axis=0)
    assert np.all(np.abs(fd_pd - pd) <= 1e-7 * vmax)
    assert np.all(np.abs(fd_pdd - pdd) <= 1e-7 * amax)
    assert np.all(np.abs(fd2_pdd - pdd) <= 1e-3 * amax)  # second difference: round-off ~eps/h^2


def test_trajectory_peaks_versus_the_report():
    """The report claims up to 8 m/s and 24 m/s^2; the chirps at 5 Hz with 0.25 m
    amplitude give 0.25 * (10 pi)^2 ~ 247 m/s^2 per axis, i.e. about 25 g."""
    t = val.sample_times(1000.0, 10.0)
    _, pd, pdd = val.trajectory(t)
    speed = np.linalg.norm(pd[:, :3], axis=1).max()
    accel = np.linalg.norm(pdd[:, :3], axis=1).max()
    assert 7.5 < speed < 8.0
    assert 200.0 < accel < 260.0


def test_sample_times():
    t = val.sample_times(1000.0, 10.0)
    assert t.size == 10001 and t[0] == 0.0 and t[-1] == pytest.approx(10.0, abs=1e-12)
    assert val.sample_times(100.0, 1.0).size == 101
    assert val.sample_times(200.0, 0.0).size == 1
    assert val.sample_times(3.0, 1.5).size == 5  # 0, 1/3, 2/3, 1, 4/3: never beyond 1.5 s
    for rate, duration in (
        (0.0, 1.0),
        (-5.0, 1.0),
        (math.nan, 1.0),
        (10.0, -1.0),
        (10.0, math.inf),
    ):
        with pytest.raises(ValueError):
            val.sample_times(rate, duration)


# ------------------------------------------------------------------ the run


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_run_default_robot_passes(backend):
    robot = DeltaRobot.default(backend=backend)
    calls = []
    result = val.run_trajectory(
        robot,
        rate=200.0,
        duration=2.0,
        chunk=150,
        progress=lambda done, total: calls.append((done, total)),
    )
    assert result.n == 401
    assert calls[-1] == (401, 401) and len(calls) == 3
    assert not result.failed.any()
    assert result.passed
    rel = result.relative_errors()
    assert set(rel) == {"position", "velocity", "acceleration", "phi", "phid", "phidd"}
    assert all(v < 1e-12 for v in rel.values()), rel
    # the fourth axis passes through unchanged, eq. (43)
    np.testing.assert_array_equal(result.q[:, 3], result.p[:, 3])
    np.testing.assert_array_equal(result.qdd[:, 3], result.pdd[:, 3])
    # joint rates really are J^-1 pd: check with the Jacobian
    J = robot.jacobian(result.q)
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", J, result.qd[:, :3]), result.pd[:, :3], rtol=0, atol=1e-12
    )
    # the default robot is far from singular on this trajectory
    assert 0.3 < np.nanmin(result.det_margin) <= 1.0
    assert 0.3 < np.nanmin(result.jq_margin) <= 1.0
    assert 1.0 <= np.nanmax(result.cond) < 10.0


def test_backends_agree():
    a = val.run_trajectory(DeltaRobot.default(backend="compiled"), rate=100.0, duration=1.0)
    b = val.run_trajectory(DeltaRobot.default(backend="reference"), rate=100.0, duration=1.0)
    for name in ("q", "qd", "qdd"):
        scale = np.abs(getattr(b, name)).max()
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-11 * scale)


def test_singularity_margins_by_hand():
    """At the home pose x = y = 0 of a symmetric robot every chain looks the same."""
    robot = DeltaRobot.default(backend="reference")
    g = robot.geometry
    p = np.array([[0.0, 0.0, -0.7, 0.0]])
    q = robot.ik(p)
    det_margin, jq_margin = val.singularity_margins(g, p, q)
    q1 = q[0, 0]
    rho = g.r + g.l_a * math.cos(q1)
    S = np.array(
        [[rho * math.cos(th), rho * math.sin(th), -g.l_a * math.sin(q1)] for th in g.theta]
    )
    D = p[0, :3] - S
    dS = np.array(
        [
            [
                -g.l_a * math.sin(q1) * math.cos(th),
                -g.l_a * math.sin(q1) * math.sin(th),
                -g.l_a * math.cos(q1),
            ]
            for th in g.theta
        ]
    )
    assert det_margin[0] == pytest.approx(abs(np.linalg.det(D)) / g.l_b**3, rel=1e-12)
    assert jq_margin[0] == pytest.approx(abs(D[0] @ dS[0]) / (g.l_a * g.l_b), rel=1e-12)


class _Perturbed:
    """A robot whose direct kinematics is off by 1 um: the validation must catch it."""

    def __init__(self, robot):
        self._robot, self.geometry, self.backend = robot, robot.geometry, robot.backend

    def __getattr__(self, name):
        return getattr(self._robot, name)

    def fk_acc(self, q, qd, qdd, errors="raise"):
        p, pd, pdd, ok = self._robot.fk_acc(q, qd, qdd, errors=errors)
        return p + np.array([1e-6, 0.0, 0.0, 0.0]), pd, pdd, ok


def test_run_detects_wrong_kinematics():
    result = val.run_trajectory(_Perturbed(DeltaRobot.default()), rate=50.0, duration=0.5)
    assert not result.failed.any()
    assert result.relative_errors()["position"] == pytest.approx(1e-6 / 1.35, rel=1e-6)
    assert not result.passed


def _short_robot(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(
        'name = "short"\n[delta]\nr_a = 0.2\nr_b = 0.045\nl_a = 0.35\n'
        "l_b = 0.5\ntheta_deg = [0, 120, 240]\n"
    )
    return path


def test_run_flags_unreachable_samples(tmp_path):
    robot = DeltaRobot.from_toml(_short_robot(tmp_path))
    result = val.run_trajectory(robot, rate=100.0, duration=2.0)
    _, reachable = robot.ik(result.p, errors="nan")
    np.testing.assert_array_equal(result.unreachable, ~reachable)
    assert result.unreachable.any() and (~result.unreachable).any()
    assert np.isnan(result.q[result.unreachable]).all()
    assert not result.passed


# ------------------------------------------------------------------ CLI


def test_cli_validate_writes_csv_and_png(tmp_path, capsys):
    out = tmp_path / "nested" / "val"
    rc = cli_main(["validate", "--rate", "100", "--duration", "1", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "PASSED" in captured.out
    assert "101 samples" in captured.out
    assert "peak acceleration" in captured.out and "cond(J)" in captured.out
    assert "101/101 samples" in captured.err  # progress on stderr
    with open(out / "validation.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert len(rows) == 1 + 101
    header = rows[0]
    assert header[:5] == ["t", "x", "y", "z", "phi"]
    for name in ("q1", "q4", "qd1", "qdd4", "err_pos", "err_vel", "err_acc", "det_margin", "cond"):
        assert name in header
    assert all(len(r) == len(header) for r in rows)
    data = np.array(rows[1:], dtype=float)
    assert data[-1, 0] == pytest.approx(1.0)
    robot = DeltaRobot.default()
    np.testing.assert_allclose(
        data[:, header.index("q1") : header.index("q4") + 1],
        robot.ik(data[:, 1:5]),
        rtol=0,
        atol=1e-15,
    )
    png = (out / "validation.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_cli_validate_quiet_no_plot(tmp_path, capsys):
    rc = cli_main(
        [
            "validate",
            "--rate",
            "50",
            "--duration",
            "0.5",
            "--out",
            str(tmp_path),
            "--no-plot",
            "--quiet",
            "--backend",
            "reference",
        ]
    )
    captured = capsys.readouterr()
    assert rc == 0
    assert captured.err == ""
    assert (tmp_path / "validation.csv").exists()
    assert not (tmp_path / "validation.png").exists()


def test_cli_validate_unreachable_robot_fails_cleanly(tmp_path, capsys):
    robot = _short_robot(tmp_path)
    rc = cli_main(
        [
            "validate",
            "--robot",
            str(robot),
            "--rate",
            "100",
            "--duration",
            "1",
            "--out",
            str(tmp_path / "out"),
            "--no-plot",
            "--quiet",
        ]
    )
    captured = capsys.readouterr()
    assert rc == 1
    assert "Traceback" not in captured.err + captured.out
    assert "unreachable" in captured.out and "t = " in captured.out
    assert "FAILED" in captured.err and "unreachable" in captured.err
    assert (tmp_path / "out" / "validation.csv").exists()  # the evidence is still written


def test_cli_validate_bad_arguments(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[delta]\nr_a = 0.2\n")
    assert cli_main(["validate", "--robot", str(bad), "--out", str(tmp_path)]) == 2
    assert "missing keys" in capsys.readouterr().err
    assert cli_main(["validate", "--rate", "0", "--out", str(tmp_path)]) == 2
    assert "rate" in capsys.readouterr().err


def test_the_speed_and_acceleration_panels(tmp_path, monkeypatch):
    """plot's two rate panels (one rate_panel each): |pd| and |pdd| of the run drawn over t
    against the report's figures, each with its own label, unit and peak."""
    from deltagen.apps import validate

    result = validate.run_trajectory(DeltaRobot.default(), rate=50, duration=0.5)
    seen = {}
    from deltagen.apps.plotting import pyplot

    plt = pyplot()
    monkeypatch.setattr(plt, "close", lambda fig: seen.setdefault("fig", fig))
    validate.plot(result, tmp_path / "v.png")
    axes = {ax.get_ylabel(): ax for ax in seen["fig"].axes}
    for label, series, report, peak in (
        ("speed [m/s]", result.speed, validate.REPORT_SPEED, result.peak_speed),
        ("acceleration [m/s²]", result.accel, validate.REPORT_ACCEL, result.peak_accel),
    ):
        ax = axes[label]
        line, limit = ax.get_lines()[:2]
        np.testing.assert_array_equal(line.get_ydata(), series)
        np.testing.assert_array_equal(line.get_xdata(), result.t)
        assert limit.get_ydata()[0] == report
        assert f"(peak {peak:.3g} " in ax.get_title()
