"""The command table of deltagen/cli.py: every command is served by an object with
``add_parser(subparsers)`` and ``run(args)``, its add_parser adds exactly the table's
subcommands (no command without an entry, no entry without a subcommand), and the robot
kinds a command's job table serves are the ones it refuses the others by (apps/robots.py);
a hexapod workspace grid beyond the memory budget is refused before any allocation."""

from __future__ import annotations

import argparse
import inspect
import subprocess
import sys

import pytest

from deltagen import cli, paths
from deltagen.apps import dynamics, kinematics, robots, workspace


@pytest.mark.parametrize("command", list(cli.COMMANDS))
def test_every_command_has_add_parser_and_run(command):
    served = cli.app(command)
    assert callable(served.add_parser) and callable(served.run)
    assert list(inspect.signature(served.add_parser).parameters) == ["subparsers"]
    assert list(inspect.signature(served.run).parameters) == ["args"]


def test_the_parser_holds_exactly_the_table():
    parser, commands = cli.build_parser()
    assert list(commands) == list(cli.COMMANDS)
    for command, sub in commands.items():
        assert isinstance(sub, argparse.ArgumentParser)
        assert sub.prog == f"{parser.prog} {command}"
    assert set(cli.INTERMIXED) <= set(cli.COMMANDS)


def test_fk_and_ik_know_their_command_without_the_top_parser():
    """The intermixed parse (cli._parse) goes straight to the subcommand's parser: the
    command's name comes from its own defaults, not from the caller."""
    for name in ("fk", "ik"):
        args = cli._parse([name, "default", "0.1", "--degrees", "-0.2", "0.3"])
        assert args.command == name and args.degrees
        assert args.values == [0.1, -0.2, 0.3]


def test_a_command_line_imports_only_its_own_app():
    """A known command builds its own subcommand (cli._parse), so only its app module is
    imported; --help and an unknown command still build (and list) every command. Run in a
    fresh interpreter: this process has imported every app already."""
    code = (
        "import sys\n"
        "from deltagen import cli\n"
        "args = cli._parse(['generate', '--check'])\n"
        "assert args.command == 'generate' and args.check\n"
        "apps = sorted(m for m in sys.modules if m.startswith('deltagen.apps.'))\n"
        "print('APPS', ' '.join(apps))\n"
        "try:\n"
        "    cli._parse(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print('APPS', ' '.join(sorted(m for m in sys.modules if m.startswith('deltagen.apps.'))))\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    first, after_help = [line for line in run.stdout.splitlines() if line.startswith("APPS")]
    others = set(cli.COMMANDS.values()) - {cli.COMMANDS["generate"]}
    assert cli.COMMANDS["generate"] in first.split() and not others & set(first.split())
    assert {cli.COMMANDS[c] for c in cli.COMMANDS} <= set(after_help.split())
    assert sorted(cli.build_parser(("fk",))[1]) == ["fk", "ik"]  # kinematics adds both


def test_import_deltagen_loads_no_robot_family_until_asked():
    """deltagen/__init__.py resolves its public names on first use: ``import deltagen``
    loads no api module, each name of __all__ is the defining module's object, and
    `deltagen fk default` loads the delta's modules, not the serial arms' or the other
    families'. In a fresh interpreter (this one has loaded everything)."""
    code = (
        "import sys\n"
        "import deltagen\n"
        "print('API', sorted(m for m in sys.modules if m.startswith('deltagen.api')))\n"
        "import importlib\n"
        "for name in deltagen.__all__:\n"
        "    value = getattr(deltagen, name)\n"
        "    assert value is getattr(importlib.import_module(deltagen._MODULES[name]), name)\n"
        "assert set(deltagen.__all__) <= set(dir(deltagen))\n"
        "try:\n"
        "    deltagen.NoSuchRobot\n"
        "except AttributeError as exc:\n"
        "    print('MISSING', exc)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert "API []" in run.stdout.splitlines()
    assert "MISSING module 'deltagen' has no attribute 'NoSuchRobot'" in run.stdout
    fk = (
        "import sys\n"
        "from deltagen.cli import main\n"
        "assert main(['fk', 'default', '0.1', '0.2', '0.3', '--backend', 'reference']) == 0\n"
        "print('LOADED', ' '.join(sorted(sys.modules)))\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", fk], capture_output=True, text=True, timeout=120, check=True
    )
    loaded = next(line for line in run.stdout.splitlines() if line.startswith("LOADED"))
    assert "deltagen.api.delta" in loaded.split()
    for other in ("deltagen.api.serial", "deltagen.api.hexapod", "deltagen.api.sweep"):
        assert other not in loaded.split()


@pytest.mark.parametrize("table", [kinematics.JOBS, dynamics.JOBS, workspace.JOBS])
def test_job_tables_name_known_kinds_in_message_order(table):
    """Each job table's keys are robot kinds, in the order of robots.KIND_NAMES (the order
    a refusal names the kinds served in)."""
    order = list(robots.KIND_NAMES)
    assert set(table) <= set(order)
    assert list(table) == sorted(table, key=order.index)


def test_hexapod_workspace_beyond_the_memory_budget_is_refused(capsys, tmp_path):
    robot_file = str(paths.robots_dir() / "hexapod_genhex.toml")
    out = tmp_path / "ws"
    assert cli.main(["workspace", robot_file, "--step", "1e-5", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "deltagen workspace: error: the hexapod's position grid at --step = 1e-05 m" in err
    assert "choose a larger --step" in err and "DELTAGEN_MAX_MEMORY" in err
    assert not out.exists()


def test_machine_float32_export_measures_its_accuracy(capsys, tmp_path):
    """`deltagen export MACHINE --float32` measures the float build against the double one
    on the machine's own functions (<config>_fk), not the delta's ik/fk (a traceback
    before)."""
    from deltagen.apps.export import compiler

    if compiler() is None:
        pytest.skip("no C compiler")
    out = tmp_path / "machine"
    assert cli.main(["export", "xyzac_trt", "--out", str(out), "--float32"]) == 0
    printed = capsys.readouterr().out
    tip = [line for line in printed.splitlines() if line.startswith("float32 fk tool tip")]
    assert len(tip) == 1
    # float near 0.1 m: a few units of 2^-24 * 0.1 m = 6e-3 um; far below 5 um
    assert 0 < float(tip[0].split("max ")[1].split(",")[0]) < 5
