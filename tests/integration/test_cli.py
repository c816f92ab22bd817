"""The command line: `deltagen fk | ik ROBOT ...` on single poses and CSV/NPY batches, and
clean failures (exit code 2 and a message, never a traceback)."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from delta_oracles import DEFAULT, symmetric_fk
from numpy.lib.recfunctions import structured_to_unstructured

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
    np.testing.assert_allclose(
        _bracket(out), symmetric_fk(DEFAULT, math.radians(20)), rtol=0, atol=1e-11
    )
    code, out, _ = run(
        capsys, "fk", "default", "0.1", "0.1", "0.1", "0.75", "--backend", "reference"
    )
    assert code == 0
    np.testing.assert_allclose(_bracket(out), symmetric_fk(DEFAULT, 0.1), rtol=0, atol=1e-11)
    assert re.search(r"phi = 0\.75\b", out)


def test_options_before_values(capsys):
    code, out, _ = run(capsys, "fk", "default", "--degrees", "20", "20", "20")
    assert code == 0
    np.testing.assert_allclose(
        _bracket(out), symmetric_fk(DEFAULT, math.radians(20)), rtol=0, atol=1e-11
    )


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
    q = np.array(
        [[0.0, 0.0, 0.0], [0.1, 0.2, 0.3], [np.nan, 0.0, 0.0], [-0.3, 0.9, 0.4], [0.5, 0.5, 0.5]]
    )
    return q


def test_fk_csv_to_csv(capsys, tmp_path):
    q = _q_batch()
    src = tmp_path / "q.csv"
    np.savetxt(src, q, delimiter=",", header="q1,q2,q3")
    dst = tmp_path / "p.csv"
    code, out, err = run(capsys, "fk", "default", "--input", str(src), "--output", str(dst))
    assert code == 1 and out == ""  # exit 1: a row without a valid result
    assert "1 of 5 rows failed" in err and "rows 2 " in err
    assert dst.read_text().splitlines()[0] == "x,y,z,valid"
    table = np.loadtxt(dst, delimiter=",", ndmin=2, skiprows=1)
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
    assert code == 1
    lines = out.splitlines()
    assert lines[0] == "x,y,z,phi,valid"  # phi: the platform's turn, delta report eq. (43)
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
    assert code == 1 and "1 of 5 rows failed" in err
    table = np.load(dst)
    assert table.shape == (5,) and table.dtype.names == ("q1", "q2", "q3", "valid")
    np.testing.assert_array_equal(table["valid"], [True, True, True, True, False])
    q_out = structured_to_unstructured(table[["q1", "q2", "q3"]])
    np.testing.assert_allclose(q_out[:4], q, rtol=0, atol=1e-12)


def test_ik_csv_in_degrees(capsys, tmp_path):
    z = symmetric_fk(DEFAULT, math.radians(12))[2]
    src, dst = tmp_path / "p.csv", tmp_path / "q.csv"
    np.savetxt(src, [[0.0, 0.0, z]], delimiter=",")
    code, _, _ = run(
        capsys, "ik", "default", "--degrees", "--input", str(src), "--output", str(dst)
    )
    assert code == 0
    np.testing.assert_allclose(
        np.loadtxt(dst, delimiter=",", ndmin=2, skiprows=1)[0, :3], [12.0] * 3, rtol=0, atol=1e-9
    )


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


@pytest.mark.parametrize(
    "argv,words",
    [
        (["fk", "/nonexistent/robot.toml", "0", "0", "0"], "cannot read robot file"),
        (["fk", "default", "1", "2"], "give 3 joint angles"),
        (["fk", "default", "1", "2", "3", "4", "5"], "got 5 values"),
        (["ik", "default", "0", "0", "nan"], "finite"),
        (["fk", "default", "--input", "/nonexistent/q.csv"], "/nonexistent/q.csv"),
    ],
)
def test_bad_invocations_exit_2(capsys, argv, words):
    code, out, err = run(capsys, *argv)
    assert code == 2 and words in err, err
    assert "Traceback" not in err + out


def test_bad_batch_files_exit_2(capsys, tmp_path):
    narrow = tmp_path / "narrow.csv"
    np.savetxt(narrow, np.zeros((3, 2)), delimiter=",")
    code, _, err = run(capsys, "fk", "default", "--input", str(narrow))
    assert code == 2 and "2 columns without names" in err and "q1,q2,q3[,q4]" in err
    text = tmp_path / "text.csv"
    text.write_text("a,b,c\n1,2,3\n")
    code, _, err = run(capsys, "fk", "default", "--input", str(text))
    assert code == 2 and "error" in err and "Traceback" not in err


def test_real_process_reports_errors_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[delta]\nr_a = 0.2\n")
    cmd = [sys.executable, "-m", "deltagen.cli"]
    ok = subprocess.run(
        cmd + ["fk", "default", "0", "0", "0"], capture_output=True, text=True, timeout=120
    )
    assert ok.returncode == 0 and "p = [" in ok.stdout
    failed = subprocess.run(
        cmd + ["fk", str(bad), "0", "0", "0"], capture_output=True, text=True, timeout=120
    )
    assert failed.returncode == 2
    assert "missing keys" in failed.stderr and "Traceback" not in failed.stderr
    assert _numbers(ok.stdout)[-1] == pytest.approx(Z0, abs=1e-11)


# ----------------------------------------------------------- the CLI's files: CSV and NPY


def _read(path):
    """A table written by the CLI as {name: column}, from CSV or NPY."""
    path = Path(path)
    if path.read_bytes().startswith(b"\x93NUMPY"):
        table = np.load(path)
        return {name: np.asarray(table[name], dtype=float) for name in table.dtype.names}
    table = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(table[name], dtype=float).reshape(-1) for name in table.dtype.names}


def _columns(table, names):
    return np.column_stack([table[n] for n in names])


def _write_q(path, q, names=None):
    names = names or [f"q{i + 1}" for i in range(q.shape[1])]
    if str(path).lower().endswith(".npy"):
        arr = np.empty(len(q), dtype=[(n, float) for n in names])
        for k, n in enumerate(names):
            arr[n] = q[:, k]
        np.save(path, arr)
    else:
        np.savetxt(path, q, delimiter=",", header=",".join(names), comments="")


@pytest.mark.parametrize("ext", ["csv", "npy"])
def test_round_trip_delta_fk_ik_fk(capsys, tmp_path, ext):
    """fk output -> ik input -> fk again reproduces the poses (with the fourth axis)."""
    rng = np.random.default_rng(3)
    q = np.column_stack([rng.uniform(-0.4, 0.9, (20, 3)), rng.uniform(-2, 2, 20)])
    src, p1, q2, p2 = (tmp_path / f"{n}.{ext}" for n in ("q", "p1", "q2", "p2"))
    _write_q(src, q)
    assert run(capsys, "fk", "default", "--input", str(src), "--output", str(p1))[0] == 0
    assert run(capsys, "ik", "default", "--input", str(p1), "--output", str(q2))[0] == 0
    assert run(capsys, "fk", "default", "--input", str(q2), "--output", str(p2))[0] == 0
    first, back, second = _read(p1), _read(q2), _read(p2)
    assert list(first) == ["x", "y", "z", "phi", "valid"]
    assert list(back) == ["q1", "q2", "q3", "q4", "valid"]
    names = ["x", "y", "z", "phi"]
    np.testing.assert_allclose(_columns(second, names), _columns(first, names), rtol=0, atol=1e-12)
    np.testing.assert_allclose(_columns(back, ["q1", "q2", "q3", "q4"]), q, rtol=0, atol=1e-9)


@pytest.mark.parametrize("ext", ["csv", "npy"])
def test_round_trip_puma_fk_ik_fk(capsys, tmp_path, ext):
    from deltagen import SerialRobot

    arm = SerialRobot.load("puma560")
    rng = np.random.default_rng(4)
    lim = arm.qlim
    q = rng.uniform(lim[:, 0] * 0.8, lim[:, 1] * 0.8, (15, 6))
    src, p1, q2, p2 = (tmp_path / f"{n}.{ext}" for n in ("q", "p1", "q2", "p2"))
    _write_q(src, q)
    assert run(capsys, "fk", "puma560", "--input", str(src), "--output", str(p1))[0] == 0
    code, _, err = run(
        capsys,
        "ik",
        "puma560",
        "--input",
        str(p1),
        "--output",
        str(q2),
        "--q0=" + ",".join(str(float(v)) for v in q[0]),
    )
    assert code == 0, err
    assert run(capsys, "fk", "puma560", "--input", str(q2), "--output", str(p2))[0] == 0
    first, second = _read(p1), _read(p2)
    T = [f"T{r}{c}" for r in range(1, 5) for c in range(1, 5)]
    np.testing.assert_allclose(_columns(second, T), _columns(first, T), rtol=0, atol=1e-12)
    pose = ["x", "y", "z", "psi", "theta", "phi"]
    np.testing.assert_allclose(_columns(second, pose), _columns(first, pose), rtol=0, atol=1e-9)


def test_serial_ik_from_euler_columns_single_pose_and_options(capsys, tmp_path):
    """Serial ik: poses as x,y,z,psi,theta,phi (no T columns), --config, --method numeric
    with --q0 (numbers or a configuration name), and one pose from the command line."""
    from deltagen import SerialRobot

    arm = SerialRobot.load("puma560")
    q = np.array([0.2, -0.6, 0.3, 0.4, 0.7, -0.2])
    pose = arm.pose(q)
    src = tmp_path / "pose.csv"
    np.savetxt(src, pose[None], delimiter=",", header="x,y,z,psi,theta,phi", comments="")
    code, out, err = run(capsys, "ik", "puma560", "--input", str(src))
    assert code == 0, err
    got = np.loadtxt(out.splitlines()[1:], delimiter=",", ndmin=2)
    assert out.splitlines()[0] == "q1,q2,q3,q4,q5,q6,valid"
    np.testing.assert_allclose(arm.fk(got[0, :6]), arm.fk(q), rtol=0, atol=1e-12)

    values = [str(float(v)) for v in pose]
    for extra in (
        [],
        ["--config", "front_up_noflip"],
        ["--method", "numeric", "--q0", "qn"],
        ["--method", "numeric", "--q0=" + ",".join(map(str, q + 0.05))],
    ):
        code, out, err = run(capsys, "ik", "puma560", *values, *extra)
        assert code in (0, 1), err
        if code == 0:
            np.testing.assert_allclose(arm.fk(_bracket(out)), arm.fk(q), rtol=0, atol=1e-9)
        else:
            assert "no valid result" in err
    code, out, _ = run(
        capsys,
        "ik",
        "puma560",
        *values,
        "--method",
        "numeric",
        "--q0=" + ",".join(map(str, q + 0.05)),
    )
    assert code == 0
    np.testing.assert_allclose(_bracket(out), q, rtol=0, atol=1e-9)
    code, _, err = run(capsys, "ik", "puma560", *values, "--config", "upside_down")
    assert code == 2 and "front_up_noflip" in err
    code, _, err = run(capsys, "ik", "default", "0", "0", "-0.7", "--config", "qn")
    assert code == 2 and "serial arms" in err


def test_degrees_convert_revolute_joints_only(capsys, tmp_path):
    """lecture_prp is P-R-P: with --degrees the strokes stay in m (0.5 m, not 0.0087 m)."""
    code, out, _ = run(capsys, "fk", "lecture_prp", "0.5", "30", "0.4", "--degrees")
    assert code == 0
    position = _bracket(out.splitlines()[-2][out.splitlines()[-2].index("=") :])
    np.testing.assert_allclose(
        position,
        [0.4 * math.cos(math.radians(30)), 0.4 * math.sin(math.radians(30)), 0.5],
        atol=1e-12,
    )
    # batch in, batch out; bosch_sr800 is R-R-P-R: ik prints q3 in m, the others in deg
    from deltagen import SerialRobot

    arm = SerialRobot.load("bosch_sr800")
    q_deg = np.array([[20.0, -30.0, 0.1, 40.0], [-10.0, 50.0, 0.25, -60.0]])
    q_rad = q_deg.copy()
    q_rad[:, [0, 1, 3]] = np.radians(q_rad[:, [0, 1, 3]])
    src, p, back = tmp_path / "q.csv", tmp_path / "p.csv", tmp_path / "back.csv"
    _write_q(src, q_deg)
    assert (
        run(capsys, "fk", "bosch_sr800", "--degrees", "--input", str(src), "--output", str(p))[0]
        == 0
    )
    T = [f"T{r}{c}" for r in range(1, 5) for c in range(1, 5)]
    np.testing.assert_allclose(_columns(_read(p), T).reshape(-1, 4, 4), arm.fk(q_rad), atol=1e-12)
    code, _, err = run(
        capsys,
        "ik",
        "bosch_sr800",
        "--degrees",
        "--q0=20,-30,0.1,40",
        "--input",
        str(p),
        "--output",
        str(back),
    )
    assert code == 0, err
    np.testing.assert_allclose(_columns(_read(back), ["q1", "q2", "q3", "q4"]), q_deg, atol=1e-9)
    code, out, _ = run(
        capsys,
        "ik",
        "bosch_sr800",
        "--degrees",
        "--q0=20,-30,0.1,40",
        *(str(float(v)) for v in arm.pose(q_rad[0])),
    )
    assert code == 0 and out.rstrip().endswith("(deg, deg, m, deg)")
    np.testing.assert_allclose(_bracket(out), q_deg[0], atol=1e-9)


def test_ik_reads_fk_output_by_name(capsys, tmp_path):
    """The `valid` column of fk's output is not the fourth axis: ik gives 3 joints back."""
    q = _q_batch()[[0, 1, 3]]
    src, p, back = tmp_path / "q.csv", tmp_path / "p.csv", tmp_path / "back.csv"
    _write_q(src, q)
    run(capsys, "fk", "default", "--input", str(src), "--output", str(p))
    assert run(capsys, "ik", "default", "--input", str(p), "--output", str(back))[0] == 0
    table = _read(back)
    assert list(table) == ["q1", "q2", "q3", "valid"]
    np.testing.assert_allclose(_columns(table, ["q1", "q2", "q3"]), q, atol=1e-12)


@pytest.mark.parametrize(
    "text",
    [
        "q1,q2,q3\n0.1,0.2,0.3\n",  # plain CSV header
        "# q1,q2,q3\n0.1,0.2,0.3\n",  # numpy's savetxt header
        "Q3, q1 ,q2,valid\n0.3,0.1,0.2,1\n",  # by name, any order and case, extra columns
        "# made by hand\n0.1,0.2,0.3\n",  # a comment, then positional columns
        "0.1 0.2 0.3\n",  # whitespace-separated, positional
        "\ufeffq1,q2,q3\r\n0.1,0.2,0.3\r\n",  # BOM and CRLF
    ],
)
def test_csv_inputs_by_name_or_position(capsys, tmp_path, text):
    src = tmp_path / "q.csv"
    src.write_text(text, encoding="utf-8")
    code, out, err = run(capsys, "fk", "default", "--input", str(src))
    assert code == 0, err
    np.testing.assert_allclose(
        np.loadtxt(out.splitlines()[1:], delimiter=",")[:3],
        DeltaRobot.default().fk([0.1, 0.2, 0.3]),
        atol=1e-15,
    )


def test_single_pose_with_output_writes_the_row(capsys, tmp_path):
    dst = tmp_path / "p.csv"
    code, out, _ = run(capsys, "fk", "default", "0.1", "0.2", "0.3", "--output", str(dst))
    assert code == 0 and out == ""
    table = _read(dst)
    np.testing.assert_allclose(
        _columns(table, ["x", "y", "z"])[0], DeltaRobot.default().fk([0.1, 0.2, 0.3]), atol=1e-15
    )
    np.testing.assert_array_equal(table["valid"], [1.0])
    # an unreachable single pose: written as NaN, valid 0, exit 1
    code, _, err = run(capsys, "ik", "default", "0", "0", "-5", "--output", str(dst))
    assert code == 1 and "unreachable" in err
    assert _read(dst)["valid"].tolist() == [0.0] and np.isnan(_read(dst)["q1"][0])


def test_output_extension_is_case_insensitive(capsys, tmp_path):
    dst = tmp_path / "p.NPY"
    assert run(capsys, "fk", "default", "0.1", "0.2", "0.3", "--output", str(dst))[0] == 0
    assert dst.read_bytes().startswith(b"\x93NUMPY") and not (tmp_path / "p.NPY.npy").exists()
    code, _, err = run(
        capsys, "fk", "default", "0.1", "0.2", "0.3", "--output", str(tmp_path / "p.dat")
    )
    assert code == 2 and ".npy" in err
    # input: NPY is recognised by its content, whatever the name
    src = tmp_path / "q.bin"
    np.save(open(src, "wb"), np.array([[0.1, 0.2, 0.3]]))
    assert run(capsys, "fk", "default", "--input", str(src))[0] == 0


@pytest.mark.parametrize("shape", [(3,), (2, 3, 3), ()])
def test_npy_of_wrong_dimension_is_a_clear_error(capsys, tmp_path, shape):
    src = tmp_path / "q.npy"
    np.save(src, np.zeros(shape))
    code, out, err = run(capsys, "fk", "default", "--input", str(src))
    assert code == 2 and "must be 2-D" in err and str(shape) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err + out


def test_values_with_input_is_a_usage_error(capsys, tmp_path):
    src = tmp_path / "q.csv"
    _write_q(src, np.zeros((2, 3)))
    code, out, err = run(capsys, "fk", "default", "0.1", "0.2", "0.3", "--input", str(src))
    assert code == 2 and "not both" in err and out == ""


def test_generate_of_a_delta_file_says_what_generate_accepts(capsys, repo_root):
    code, _, err = run(capsys, "generate", str(repo_root / "robots" / "default_delta.toml"))
    assert code == 2
    assert "delta robot" in err and "serial-arm file" in err
    assert "unknown top-level keys" not in err


@pytest.mark.parametrize("command", ["fk", "ik"])
def test_help_fits_serial_arms_and_documents_exit_codes(capsys, command):
    code, out, _ = run(capsys, command, "--help")
    assert code == 0
    assert "serial arm" in out and "delta" in out
    assert "exit status" in out and "computed, but some rows" in out
    for status in ("0  success", "1  computed", "2  usage or input error"):
        assert status in out
    code, out, _ = run(capsys, "--help")
    assert code == 0 and "exit status" in out


def test_exit_codes(capsys, tmp_path):
    assert run(capsys, "fk", "default", "0", "0", "0")[0] == 0
    assert run(capsys, "ik", "default", "0", "0", "-5")[0] == 1  # computed, no solution
    assert run(capsys, "ik", "default", "0", "0", "inf")[0] == 2  # not a usable input
    assert run(capsys, "fk", "default", "--no-such-option")[0] == 2  # argparse: returned
    assert run(capsys, "fk", "default", "--q0", "1")[0] == 2  # an ik option
    src = tmp_path / "q.csv"
    _write_q(src, np.array([[0.0, 0.0, 0.0], [np.inf, 0.0, 0.0]]))
    assert run(capsys, "fk", "default", "--input", str(src))[0] == 1


def test_readme_documents_the_exit_codes(repo_root):
    text = (repo_root / "README.md").read_text()
    assert "Exit status" in text and "2: usage or input error" in text


# ----------------------------------------------------------------------------- fuzzing


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as hs  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

FUZZ = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
FLOATS = hs.one_of(
    hs.floats(allow_nan=True, allow_infinity=True),
    hs.sampled_from([0.0, -0.0, 0.3, -0.7, 1e-310, 1e155, -1e300, 5e-324]),
)


def _check_outcome(code, out, err, output=None):
    """Exit 2 with one line naming the problem, or 0/1 with finite values in valid rows."""
    assert "Traceback" not in out + err
    assert code in (0, 1, 2), (code, err)
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("deltagen ") and ": error: " in lines[0], err
        return
    table = _read(output) if output else None
    if table is None:
        rows = np.genfromtxt(out.splitlines(), delimiter=",", names=True, ndmin=1)
        table = {n: np.asarray(rows[n], dtype=float).reshape(-1) for n in rows.dtype.names}
    valid = table.pop("valid").astype(bool)
    values = np.column_stack(list(table.values()))
    assert np.all(np.isfinite(values[valid]))
    assert np.all(np.isnan(values[~valid]))
    assert (code == 0) == bool(np.all(valid)), err


@FUZZ
@given(
    arr=hnp.arrays(
        dtype=hs.sampled_from(
            [np.float64, np.float32, np.int64, np.bool_, np.complex128, np.uint8]
        ),
        shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5),
        elements=None,
    ),
    command=hs.sampled_from(["fk", "ik"]),
)
def test_fuzz_npy_inputs(capsys, tmp_path_factory, arr, command):
    if arr.dtype.kind == "f":
        arr = np.where(np.isfinite(arr), arr, np.nan) if arr.size % 2 else arr
    src = tmp_path_factory.mktemp("fuzz") / "in.npy"
    np.save(src, arr)
    code, out, err = run(capsys, command, "default", "--input", str(src))
    _check_outcome(code, out, err)


@FUZZ
@given(
    rows=hs.lists(hs.lists(FLOATS, min_size=3, max_size=4), min_size=1, max_size=6),
    header=hs.sampled_from(["", "q1,q2,q3\n", "# x,y,z\n", "x,y,z,phi\n", "a,b\n"]),
    command=hs.sampled_from(["fk", "ik"]),
    ext=hs.sampled_from(["csv", "npy"]),
)
def test_fuzz_values_nan_inf_huge(capsys, tmp_path_factory, rows, header, command, ext):
    width = len(rows[0])
    rows = [(r + r)[:width] for r in rows]
    folder = tmp_path_factory.mktemp("fuzz")
    src, dst = folder / "in.csv", folder / f"out.{ext}"
    src.write_text(header + "".join(",".join(repr(v) for v in r) + "\n" for r in rows))
    code, out, err = run(capsys, command, "default", "--input", str(src), "--output", str(dst))
    _check_outcome(code, out, err, output=dst if code != 2 else None)


@FUZZ
@given(
    text=hs.text(alphabet=hs.sampled_from(list("0123456789.,-+eE #\n\tnaifxyzq\x00;")), max_size=60)
)
def test_fuzz_malformed_csv(capsys, tmp_path_factory, text):
    src = tmp_path_factory.mktemp("fuzz") / "in.csv"
    src.write_text(text)
    code, out, err = run(capsys, "fk", "default", "--input", str(src))
    _check_outcome(code, out, err)


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(values=hs.lists(FLOATS, min_size=0, max_size=7), command=hs.sampled_from(["fk", "ik"]))
def test_fuzz_serial_single_pose(capsys, values, command):
    code, out, err = run(capsys, command, "puma560", *(str(float(v)) for v in values))
    assert "Traceback" not in out + err and code in (0, 1, 2)
    if code == 2:
        assert len(err.strip().splitlines()) == 1
    elif code == 0:
        assert all(math.isfinite(v) for v in _numbers(out.split("=", 1)[1]))
    else:
        assert "no valid result" in err


def test_end_to_end_round_trip_in_a_process(tmp_path):
    """The installed entry point: fk writes NPY, ik reads it and exits 0."""
    cmd = [sys.executable, "-m", "deltagen.cli"]
    src = tmp_path / "q.csv"
    _write_q(src, np.array([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]]))
    p = tmp_path / "p.npy"
    first = subprocess.run(
        cmd + ["fk", "default", "--input", str(src), "--output", str(p)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert first.returncode == 0, first.stderr
    second = subprocess.run(
        cmd + ["ik", "default", "--input", str(p)], capture_output=True, text=True, timeout=120
    )
    assert second.returncode == 0 and second.stdout.startswith("q1,q2,q3,valid\n")
    bad = subprocess.run(
        cmd + ["ik", "default", "1", "2", "3", "--input", str(p)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr


# -- `deltagen dynamics ARM --input traj.csv` ---------------------------------------------------


def _puma_sine(t):
    """An analytic joint trajectory with its exact rates: q = q0 + a sin(w t + phi)."""
    a = np.array([0.6, 0.4, 0.5, 0.8, 0.7, 0.9])
    w = np.array([1.3, 2.1, 1.7, 2.9, 3.3, 2.5])
    phi = np.array([0.0, 0.4, 1.1, 2.0, 0.3, 1.5])
    q0 = np.array([0.1, -0.5, 0.4, 0.0, 0.6, -0.2])
    arg = np.outer(t, w) + phi
    return q0 + a * np.sin(arg), a * w * np.cos(arg), -a * w**2 * np.sin(arg)


def _report_rows(text):
    rows = {}
    for key, label in (("peak", "peak |tau|"), ("rms", "RMS tau"), ("power", "peak power")):
        line = next(line for line in text.splitlines() if line.strip().startswith(label))
        rows[key] = np.array([float(v) for v in line.split()[len(label.split()) :][:6]])
    return rows


def test_dynamics_serial_arm_torques_and_report(tmp_path, capsys):
    from deltagen import SerialRobot

    arm = SerialRobot.load("puma560")
    t = np.linspace(0.0, 2.0, 401)
    q, qd, qdd = _puma_sine(t)
    names = ["t"] + [f"{p}{i + 1}" for p in ("q", "qd", "qdd") for i in range(6)]
    given = tmp_path / "puma.csv"
    np.savetxt(
        given,
        np.column_stack((t, q, qd, qdd)),
        delimiter=",",
        header=",".join(names),
        comments="",
    )
    out = tmp_path / "tau.csv"
    plot = tmp_path / "tau.png"
    args = ["dynamics", "puma560", "--input", str(given), "--output", str(out)]
    assert cli.main([*args, "--plot", str(plot)]) == 0
    text = capsys.readouterr().out
    assert plot.stat().st_size > 10_000
    table = np.genfromtxt(out, delimiter=",", names=True)
    tau = np.column_stack([table[f"tau{i}"] for i in range(1, 7)])
    # independent path: the API on the analytic rates, one state at a time
    want = np.array([arm.inverse_dynamics(q[k], qd[k], qdd[k]) for k in range(len(t))])
    np.testing.assert_allclose(tau, want, rtol=1e-12, atol=1e-12)
    assert table["valid"].all()
    # the printed report, recomputed from the CSV by hand (4 significant digits printed)
    rows = _report_rows(text)
    qd_csv = np.column_stack([table[f"qd{i}"] for i in range(1, 7)])
    np.testing.assert_allclose(rows["peak"], np.abs(tau).max(axis=0), rtol=1e-3)
    np.testing.assert_allclose(rows["rms"], np.sqrt((tau**2).mean(axis=0)), rtol=1e-3)
    np.testing.assert_allclose(rows["power"], np.abs(tau * qd_csv).max(axis=0), rtol=1e-3)

    # angles only: rates by second-order differences, close to the analytic torques inside
    angles = tmp_path / "q.csv"
    np.savetxt(angles, np.column_stack((t, q)), delimiter=",")  # no header: positional
    assert cli.main(["dynamics", "puma560", "--input", str(angles), "--output", str(out)]) == 0
    capsys.readouterr()
    table = np.genfromtxt(out, delimiter=",", names=True)
    tau_fd = np.column_stack([table[f"tau{i}"] for i in range(1, 7)])
    inner = slice(3, -3)
    err = np.abs(tau_fd[inner] - want[inner]).max(axis=0)
    assert (err < 2e-3 * np.abs(want).max(axis=0)).all(), err

    # delta-only options and a NaN row
    assert cli.main([*args, "--payload", "0.5"]) == 2
    assert "--payload is for delta robots" in capsys.readouterr().err
    assert cli.main([*args, "--model", "simplified"]) == 2
    q_bad = q.copy()
    q_bad[7, 2] = np.nan
    np.savetxt(angles, np.column_stack((t, q_bad)), delimiter=",")
    assert cli.main(["dynamics", "puma560", "--input", str(angles), "--output", str(out)]) == 1
    assert "rows" in capsys.readouterr().err
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert not table["valid"][7] and table["valid"][0]
