"""The command line: `deltagen fk | ik ROBOT ...` on single poses and CSV/NPY batches, and
clean failures (exit code 2 and a message, never a traceback)."""

from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pytest
from delta_oracles import DEFAULT, symmetric_fk

from deltagen import DeltaRobot, cli

Z0 = -math.sqrt(DEFAULT.l_b**2 - (DEFAULT.r_a - DEFAULT.r_b + DEFAULT.l_a) ** 2)

GOOD_TOML = """\
name = "cli_bot"
[delta]
r_a = 0.15
r_b = 0.04
l_a = 0.25
l_b = 0.6
theta_deg = [30, 150, 270]
"""


def _numbers(text):
    return [float(v) for v in re.findall(r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?", text)]


def _bracket(text):
    inside = re.search(r"\[(.*?)\]", text).group(1)
    return np.array([float(v) for v in inside.split(",")])


def run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------------- single pose


def test_fk_default_at_home(capsys):
    code, out, err = run(capsys, "fk", "default", "0", "0", "0")
    assert code == 0 and err == ""
    assert out.startswith("p = [") and out.rstrip().endswith("m")
    np.testing.assert_allclose(_bracket(out), [0.0, 0.0, Z0], rtol=0, atol=1e-11)


def test_fk_with_degrees_fourth_axis_and_reference_backend(capsys):
    code, out, _ = run(capsys, "fk", "default", "20", "20", "20", "--degrees")
    assert code == 0
    np.testing.assert_allclose(_bracket(out), symmetric_fk(DEFAULT, math.radians(20)),
                               rtol=0, atol=1e-11)
    code, out, _ = run(capsys, "fk", "default", "0.1", "0.1", "0.1", "0.75", "--backend", "reference")
    assert code == 0
    np.testing.assert_allclose(_bracket(out), symmetric_fk(DEFAULT, 0.1), rtol=0, atol=1e-11)
    assert re.search(r"phi = 0\.75\b", out)


def test_options_before_values(capsys):
    code, out, _ = run(capsys, "fk", "default", "--degrees", "20", "20", "20")
    assert code == 0
    np.testing.assert_allclose(_bracket(out), symmetric_fk(DEFAULT, math.radians(20)),
                               rtol=0, atol=1e-11)


def test_ik_single_pose(capsys):
    code, out, _ = run(capsys, "ik", "default", "0", "0", repr(Z0))
    assert code == 0 and out.startswith("q = [") and "rad" in out
    np.testing.assert_allclose(_bracket(out), [0.0, 0.0, 0.0], rtol=0, atol=1e-11)
    z = symmetric_fk(DEFAULT, math.radians(15))[2]
    code, out, _ = run(capsys, "ik", "default", "0", "0", repr(float(z)), "--degrees")
    assert code == 0 and "deg" in out
    np.testing.assert_allclose(_bracket(out), [15.0, 15.0, 15.0], rtol=0, atol=1e-9)


def test_robot_file_argument(capsys, tmp_path):
    path = tmp_path / "bot.toml"
    path.write_text(GOOD_TOML)
    code, out, _ = run(capsys, "fk", str(path), "0.2", "0.3", "0.4")
    assert code == 0
    expected = DeltaRobot.from_toml(path).fk([0.2, 0.3, 0.4])
    np.testing.assert_allclose(_bracket(out), expected, rtol=0, atol=1e-11)


# ----------------------------------------------------------------------------- batches


def _q_batch():
    q = np.array([[0.0, 0.0, 0.0], [0.1, 0.2, 0.3], [np.nan, 0.0, 0.0], [-0.3, 0.9, 0.4],
                  [0.5, 0.5, 0.5]])
    return q


def test_fk_csv_to_csv(capsys, tmp_path):
    q = _q_batch()
    src = tmp_path / "q.csv"
    np.savetxt(src, q, delimiter=",", header="q1,q2,q3")
    dst = tmp_path / "p.csv"
    code, out, err = run(capsys, "fk", "default", "--input", str(src), "--output", str(dst))
    assert code == 0 and out == ""
    assert "1 of 5 rows failed" in err
    assert dst.read_text().splitlines()[0] == "# x,y,z,valid"
    table = np.loadtxt(dst, delimiter=",", ndmin=2)
    assert table.shape == (5, 4)
    np.testing.assert_array_equal(table[:, 3], [1, 1, 0, 1, 1])
    p, valid = DeltaRobot.default(backend="reference").fk(q, errors="nan")
    np.testing.assert_allclose(table[valid, :3], p[valid], rtol=0, atol=1e-12)
    assert np.all(np.isnan(table[2, :3]))
    np.testing.assert_allclose(table[0, :3], [0.0, 0.0, Z0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(table[4, :3], symmetric_fk(DEFAULT, 0.5), rtol=0, atol=1e-15)


def test_fk_csv_to_stdout_with_fourth_axis(capsys, tmp_path):
    q = np.column_stack([_q_batch(), [0.5, -1.0, 2.0, 3.0, 4.0]])
    src = tmp_path / "q.csv"
    np.savetxt(src, q, delimiter=",")
    code, out, _ = run(capsys, "fk", "default", "--input", str(src))
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == "# x,y,z,q4,valid"
    table = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    assert table.shape == (5, 5)
    np.testing.assert_array_equal(table[[0, 1, 3, 4], 3], q[[0, 1, 3, 4], 3])


def test_ik_npy_round_trip(capsys, tmp_path):
    q = _q_batch()[[0, 1, 3, 4]]
    p = DeltaRobot.default().fk(q)
    p = np.vstack([p, [0.0, 0.0, -5.0]])  # unreachable
    src, dst = tmp_path / "p.npy", tmp_path / "q.npy"
    np.save(src, p)
    code, _, err = run(capsys, "ik", "default", "--input", str(src), "--output", str(dst))
    assert code == 0 and "1 of 5 rows failed" in err
    table = np.load(dst)
    assert table.shape == (5, 4)
    np.testing.assert_array_equal(table[:, 3], [1, 1, 1, 1, 0])
    np.testing.assert_allclose(table[:4, :3], q, rtol=0, atol=1e-12)


def test_ik_csv_in_degrees(capsys, tmp_path):
    z = symmetric_fk(DEFAULT, math.radians(12))[2]
    src, dst = tmp_path / "p.csv", tmp_path / "q.csv"
    np.savetxt(src, [[0.0, 0.0, z]], delimiter=",")
    code, _, _ = run(capsys, "ik", "default", "--degrees", "--input", str(src), "--output", str(dst))
    assert code == 0
    np.testing.assert_allclose(np.loadtxt(dst, delimiter=",", ndmin=2)[0, :3], [12.0] * 3,
                               rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- failures


BAD_ROBOTS = {
    "malformed": ("[delta\nr_a = 0.2\n", "malformed TOML"),
    "missing key": (GOOD_TOML.replace("l_b = 0.6\n", ""), "missing keys"),
    "unknown key": (GOOD_TOML + "l_c = 1.0\n", "unknown keys"),
    "bad type": (GOOD_TOML.replace("r_a = 0.15", 'r_a = "wide"'), "r_a must be a real number"),
    "both thetas": (GOOD_TOML + "theta = [0.0, 2.0, 4.0]\n", "not both"),
    "bad name": (GOOD_TOML.replace('"cli_bot"', '"my robot"'), "invalid robot name"),
    "too short": (GOOD_TOML.replace("r_a = 0.15", "r_a = 3.0"), "rods too short"),
}


@pytest.mark.parametrize("command", ["fk", "ik"])
@pytest.mark.parametrize("case", list(BAD_ROBOTS))
def test_bad_robot_file_exits_2_with_message(capsys, tmp_path, command, case):
    text, words = BAD_ROBOTS[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, out, err = run(capsys, command, str(path), "0", "0", "-0.5")
    assert code == 2
    assert f"deltagen {command}: error:" in err and words in err, err
    assert "Traceback" not in err + out


@pytest.mark.parametrize("argv,words", [
    (["fk", "/nonexistent/robot.toml", "0", "0", "0"], "cannot read robot file"),
    (["fk", "default", "1", "2"], "give 3 values"),
    (["fk", "default", "1", "2", "3", "4", "5"], "give 3 values"),
    (["ik", "default", "0", "0", "-5"], "unreachable"),
    (["ik", "default", "0", "0", "nan"], "NaN"),
    (["fk", "default", "--input", "/nonexistent/q.csv"], "/nonexistent/q.csv"),
])
def test_bad_invocations_exit_2(capsys, argv, words):
    code, out, err = run(capsys, *argv)
    assert code == 2 and words in err, err
    assert "Traceback" not in err + out


def test_bad_batch_files_exit_2(capsys, tmp_path):
    narrow = tmp_path / "narrow.csv"
    np.savetxt(narrow, np.zeros((3, 2)), delimiter=",")
    code, _, err = run(capsys, "fk", "default", "--input", str(narrow))
    assert code == 2 and "(3, 2)" in err
    text = tmp_path / "text.csv"
    text.write_text("a,b,c\n1,2,3\n")
    code, _, err = run(capsys, "fk", "default", "--input", str(text))
    assert code == 2 and "error" in err and "Traceback" not in err


def test_real_process_reports_errors_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[delta]\nr_a = 0.2\n")
    cmd = [sys.executable, "-m", "deltagen.cli"]
    ok = subprocess.run(cmd + ["fk", "default", "0", "0", "0"], capture_output=True, text=True,
                        timeout=120)
    assert ok.returncode == 0 and "p = [" in ok.stdout
    failed = subprocess.run(cmd + ["fk", str(bad), "0", "0", "0"], capture_output=True, text=True,
                            timeout=120)
    assert failed.returncode == 2
    assert "missing keys" in failed.stderr and "Traceback" not in failed.stderr
    assert _numbers(ok.stdout)[-1] == pytest.approx(Z0, abs=1e-11)
