"""Every command that loads a robot x every kind of robot, through ``deltagen.cli.main``
in-process: the exit status is the documented one (0 served, 1 served but not valid, 2
refused or bad input), a refusal names the command and the robot's kind, and nothing ends
in an exception. The kinds: the default delta TOML, a Klipper printer.cfg, a bundled arm by
name (puma560), a URDF (robots/ur5.urdf), a URDF with a <mimic> joint (a CoupledArm), a
URDF whose tree ends in a two-finger gripper (two leaves: --tip chooses the chain), the
bundled linear delta and tripod TOMLs, a Klipper linear-delta printer.cfg, the hexapod TOML
and 5-axis NC machines (a bundled one by name, and a machine TOML file).
sweep, bench and demo load no robot and are not in the matrix."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import KLIPPER_LINEAR_CFG, KLIPPER_ROTARY_CFG

from deltagen.cli import main


def _link(name, mass=1.0):
    return (
        f'<link name="{name}"><inertial><origin xyz="0.02 0.01 0.05" rpy="0 0 0"/>'
        f'<mass value="{mass}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" '
        'izz="0.015"/></inertial></link>'
    )


def _joint(name, kind, parent, child, xyz, axis, extra=""):
    limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>{limit}{extra}</joint>'
    )


# j3 mimics j2: the chain's independent variables are (q1, q2, q4)
MIMIC = (
    '<?xml version="1.0"?>\n<robot name="mimic_arm">\n<link name="base"/>'
    + "".join(_link(f"l{i}") for i in range(1, 5))
    + _joint("j1", "revolute", "base", "l1", "0 0 0.2", "0 0 1")
    + _joint("j2", "revolute", "l1", "l2", "0 0 0.1", "0 1 0")
    + _joint("j3", "revolute", "l2", "l3", "0.3 0 0", "0 1 0", '<mimic joint="j2"/>')
    + _joint("j4", "revolute", "l3", "l4", "0.2 0 0", "1 0 0")
    + "\n</robot>\n"
)

# an arm ending in a hand with two fingers: leaves finger_l and finger_r
GRIPPER = (
    '<?xml version="1.0"?>\n<robot name="gripper_arm">\n<link name="base"/>'
    + "".join(_link(n) for n in ("l1", "l2", "l3"))
    + _link("finger_l", 0.1)
    + _link("finger_r", 0.1)
    + _joint("j1", "revolute", "base", "l1", "0 0 0.2", "0 0 1")
    + _joint("j2", "revolute", "l1", "l2", "0 0 0.1", "0 1 0")
    + _joint("j3", "revolute", "l2", "l3", "0.3 0 0", "0 1 0")
    + _joint("finger_l_joint", "prismatic", "l3", "finger_l", "0.1 0.02 0", "0 1 0")
    + _joint("finger_r_joint", "prismatic", "l3", "finger_r", "0.1 -0.02 0", "0 -1 0")
    + "\n</robot>\n"
)

DELTA, SERIAL, COUPLED, HEXAPOD, MACHINE = "delta", "serial", "coupled", "hexapod", "machine"
LINEAR, TRIPOD = "linear_delta", "tripod"


@pytest.fixture(scope="module")
def robots(tmp_path_factory, repo_root):
    """kind name -> (robot arguments, kind, joint count)."""
    folder = tmp_path_factory.mktemp("kinds")
    (folder / "printer.cfg").write_text(KLIPPER_ROTARY_CFG)
    (folder / "linear_delta.cfg").write_text(KLIPPER_LINEAR_CFG)
    (folder / "mimic.urdf").write_text(MIMIC)
    (folder / "gripper.urdf").write_text(GRIPPER)
    return {
        "delta_toml": ([str(repo_root / "robots" / "default_delta.toml")], DELTA, 3),
        "klipper_cfg": ([str(folder / "printer.cfg")], DELTA, 3),
        "bundled_arm": (["puma560"], SERIAL, 6),
        "urdf": ([str(repo_root / "robots" / "ur5.urdf")], SERIAL, 6),
        "mimic_urdf": ([str(folder / "mimic.urdf")], COUPLED, 3),
        "gripper_urdf_tip": (
            [str(folder / "gripper.urdf"), "--tip", "finger_l", "--locked", "finger_r_joint=0.01"],
            SERIAL,
            4,
        ),
        "linear_delta_toml": ([str(repo_root / "robots" / "linear_delta.toml")], LINEAR, 3),
        "linear_delta_cfg": ([str(folder / "linear_delta.cfg")], LINEAR, 3),
        "tripod_toml": ([str(repo_root / "robots" / "tripod.toml")], TRIPOD, 3),
        "hexapod_toml": ([str(repo_root / "robots" / "hexapod_genhex.toml")], HEXAPOD, 6),
        "bundled_machine": (["xyzac_trt"], MACHINE, 5),
        "machine_toml": ([str(repo_root / "robots" / "bridge_bc_head.toml")], MACHINE, 5),
    }


KIND_WORDS = {
    DELTA: "a delta robot",
    SERIAL: "a serial arm",
    COUPLED: "a serial arm with coupled",
    LINEAR: "a linear delta",
    TRIPOD: "a tripod",
    HEXAPOD: "a hexapod",
    MACHINE: "a 5-axis NC machine",
}

ROBOTS = (
    "delta_toml",
    "klipper_cfg",
    "bundled_arm",
    "urdf",
    "mimic_urdf",
    "gripper_urdf_tip",
    "linear_delta_toml",
    "linear_delta_cfg",
    "tripod_toml",
    "hexapod_toml",
    "bundled_machine",
    "machine_toml",
)

#: command -> the kinds it serves (the others are refused with exit status 2)
SERVES = {
    "fk": (DELTA, SERIAL, COUPLED, LINEAR, TRIPOD, HEXAPOD, MACHINE),
    "ik": (DELTA, SERIAL, COUPLED, LINEAR, TRIPOD, HEXAPOD, MACHINE),
    "dynamics": (DELTA, SERIAL, COUPLED),
    "workspace": (DELTA, SERIAL, LINEAR, TRIPOD, HEXAPOD),
    "export": (DELTA, SERIAL, LINEAR, TRIPOD, HEXAPOD, MACHINE),
    "calibrate": (DELTA,),
    "validate": (DELTA,),
    "generate": (SERIAL, COUPLED),
}


def _q(kind, n):
    if kind == LINEAR:  # carriage heights [m] of a Kossel-sized printer
        return np.array([0.40, 0.42, 0.41])
    if kind == TRIPOD:  # strut lengths [m] of robots/tripod.toml
        return np.array([1.0, 1.0, 1.0])
    return np.array([0.3, 0.5, 0.7]) if kind == DELTA else np.linspace(0.1, 0.4, n)


def _reference(args):
    """The robot of ``args`` read through the API (not the CLI's loader)."""
    from deltagen import DeltaRobot, FiveAxisMachine, LinearDelta, SerialRobot, Tripod
    from deltagen.api.five_axis import bundled_machines

    spec = args[0]
    if spec in bundled_machines():
        return FiveAxisMachine.load(spec, backend="reference")
    if spec.endswith(".toml") and "[machine]" in open(spec).read():
        return FiveAxisMachine.from_toml(spec, backend="reference")
    if spec.endswith("linear_delta.toml"):
        return LinearDelta.from_toml(spec, backend="reference")
    if spec.endswith("tripod.toml"):
        return Tripod.from_toml(spec, backend="reference")
    if spec.endswith("linear_delta.cfg"):
        return LinearDelta.from_klipper(spec, backend="reference")
    if spec.endswith(".toml"):
        return DeltaRobot.from_toml(spec, backend="reference")
    if spec.endswith(".cfg"):
        return DeltaRobot.from_klipper(spec, backend="reference")
    if spec.endswith(".urdf"):
        tip = args[args.index("--tip") + 1] if "--tip" in args else None
        locked = {"finger_r_joint": 0.01} if "--locked" in args else None
        return SerialRobot.from_urdf(spec, tip=tip, locked=locked, backend="reference")
    return SerialRobot.load(spec, backend="reference")


def _command(command, robot_args, kind, n, tmp_path):
    """The argument list of ``command`` on the robot, with tiny inputs."""
    spec, urdf = robot_args[0], robot_args[1:]
    q = _q(kind, n)
    if kind == HEXAPOD and command in ("fk", "ik"):  # leg lengths [m]; a pose x y z r p y
        values = [0.76] * 6 if command == "fk" else [0.01, -0.02, 0.5, 0.05, 0.02, -0.1]
        return [command, spec, *map(str, values), "--backend", "reference"]
    if command == "fk":
        return ["fk", spec, *map(str, q), "--backend", "reference", *urdf]
    if command == "ik":
        from deltagen.api.serial import euler_zyx

        robot = _reference(robot_args)
        if kind == MACHINE:  # the tool tip and the tool axis
            pose = np.concatenate(robot.fk(q))
            return ["ik", spec, *(f"{v:.17g}" for v in pose), "--backend", "reference"]
        if kind in (DELTA, LINEAR, TRIPOD):
            pose = robot.fk(q)
        else:
            T = robot.fk(q)
            pose = np.concatenate([T[:3, 3], euler_zyx(T[:3, :3])])
        values = [f"{v:.17g}" for v in pose]
        extra = (
            [] if kind in (DELTA, LINEAR, TRIPOD) else ["--q0=" + ",".join(f"{v:.17g}" for v in q)]
        )
        return ["ik", spec, *values, "--backend", "reference", *extra, *urdf]
    if command == "dynamics":
        t = np.linspace(0.0, 0.04, 5)
        qs = q + 0.1 * np.outer(t, np.ones(q.size))
        path = tmp_path / "trajectory.csv"
        header = ",".join(["t"] + [f"q{i + 1}" for i in range(q.size)])
        np.savetxt(path, np.column_stack([t, qs]), delimiter=",", header=header, comments="")
        out = tmp_path / "torques.csv"
        return ["dynamics", spec, "--input", str(path), "--output", str(out), "--backend", "reference", *urdf]  # fmt: skip
    if command == "workspace":
        step = {DELTA: "0.1", LINEAR: "0.05", TRIPOD: "0.2"}.get(kind, "0.3")
        out = str(tmp_path / "ws")
        return ["workspace", spec, "--out", out, "--step", step, "--quiet", "--backend", "reference", *urdf]  # fmt: skip
    if command == "export":
        return ["export", spec, "--out", str(tmp_path / "export"), "--no-batch", *urdf]
    if command == "calibrate":
        data = tmp_path / "measured.csv"
        if kind == DELTA:
            robot = _reference(robot_args)
            qs = np.array([[0.3, 0.5, 0.7], [0.1, 0.2, 0.3], [0.6, 0.2, 0.4], [0.0, 0.4, 0.1]])
            qs = np.concatenate([qs, qs[:, ::-1] + 0.05, qs[:, [1, 2, 0]] - 0.05])
            np.savetxt(data, np.column_stack([qs, robot.fk(qs)]), delimiter=",")
        else:
            data.write_text("0,0,0,0,0,0\n")
        return ["calibrate", str(data), "--robot", spec, "--params", "l_a", *urdf]
    if command == "validate":
        out = str(tmp_path / "validation")
        return ["validate", "--robot", spec, "--rate", "20", "--duration", "0.2", "--no-plot", "--quiet", "--out", out, *urdf]  # fmt: skip
    assert command == "generate"
    return ["generate", spec, *urdf]


#: (command, robot) cells whose exit status may be 1: served, the result not valid (the
#: validation trajectory of the report's robot on a Klipper geometry; a calibration)
MAY_BE_INVALID = {("validate", "klipper_cfg"), ("calibrate", "klipper_cfg")}

#: (command, robot) cells refused although the kind is served: what the message says
INPUT_ERRORS = {("dynamics", "klipper_cfg"): "no inertial parameters"}  # a cfg has no masses

#: cells that compile C (export builds and runs its example; generate builds a module) or
#: sample a 6-joint arm's workspace: only those that exercise a kind the others do not
SLOW_SKIPPED = {
    ("workspace", "bundled_arm"),
    ("workspace", "urdf"),
    ("export", "bundled_arm"),
    ("export", "urdf"),
    ("export", "klipper_cfg"),
    ("generate", "bundled_arm"),
    ("generate", "urdf"),
    ("export", "linear_delta_cfg"),
    ("export", "machine_toml"),
}


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("command", list(SERVES))
def test_every_command_serves_or_refuses_every_kind(command, robot, robots, tmp_path, capsys):
    if (command, robot) in SLOW_SKIPPED:
        pytest.skip("compiles C; the same kind is covered by a faster cell")
    robot_args, kind, n = robots[robot]
    argv = _command(command, robot_args, kind, n, tmp_path)
    code = main(argv)  # an exception here is the traceback the command line must not show
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if kind != DELTA:
        assert "the delta robot" not in out + err
        if command == "fk" and kind == MACHINE:  # the tool tip and axis, not a frame
            assert "p = [" in out and "d = [" in out and "T =" not in out, out
        elif command == "fk" and kind in (SERIAL, COUPLED):  # an arm's tool frame, not a point
            assert "T =" in out and "p = [" not in out, out
        if command == "fk" and kind in (LINEAR, TRIPOD) and code == 0:  # the point, in m
            assert "p = [" in out and "T =" not in out, out
    if (command, robot) in INPUT_ERRORS:
        assert code == 2 and INPUT_ERRORS[command, robot] in err, (argv, out, err)
    elif kind in SERVES[command]:
        allowed = (0, 1) if (command, robot) in MAY_BE_INVALID else (0,)
        assert code in allowed, (argv, out, err)
    else:
        assert code == 2, (argv, out, err)
        assert f"deltagen {command}" in err, err
        assert KIND_WORDS[kind] in err, err


def test_a_tree_with_two_leaves_names_the_tip_option(robots, capsys):
    path = robots["gripper_urdf_tip"][0][0]
    assert main(["fk", path, "0", "0", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert "--tip" in err and "finger_l" in err and "finger_r" in err
    assert "tip=" not in err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["fk", "default", "0.3", "0.5", "0.7", "--tip", "x"], "--tip chooses the chain of a URDF"),
        (["fk", "puma560", "--config", "qz", "--base", "x"], "--base chooses the chain"),
        (["fk", "GRIPPER", "0", "0", "0", "0", "--tip", "finger_l", "--locked", "x"], "NAME=VALUE"),
        (["fk", "GRIPPER", "0", "0", "0", "0", "--tip", "nowhere"], "nowhere"),
    ],
)
def test_urdf_options_on_the_wrong_robot_or_malformed_are_usage_errors(
    argv, message, robots, capsys
):
    path = robots["gripper_urdf_tip"][0][0]
    argv = [path if a == "GRIPPER" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_a_file_is_read_as_what_it_holds_whatever_its_extension(robots, tmp_path, capsys):
    """A URDF saved as .xml is a URDF (the old dispatch read every non-TOML as a delta)."""
    xml = tmp_path / "mimic.xml"
    xml.write_text(MIMIC)
    assert main(["fk", str(xml), "0", "0", "0", "--backend", "reference"]) == 0
    assert "mimic_arm" in capsys.readouterr().out


def test_a_refused_kind_in_a_real_process_has_no_traceback(robots, tmp_path, repo_root):
    """The process's stderr (what a user sees): the refusal, not an AttributeError."""
    import subprocess
    import sys

    path = robots["mimic_urdf"][0][0]
    argv = ["workspace", path, "--out", str(tmp_path / "ws"), "--quiet"]
    done = subprocess.run(
        [sys.executable, "-m", "deltagen", *argv],
        capture_output=True,
        text=True,
        cwd=repo_root,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert "deltagen workspace" in done.stderr and "coupled" in done.stderr
