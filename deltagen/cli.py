"""Command line: deltagen generate | validate | fk | ik | dynamics | workspace | sweep | demo |
export | calibrate | bench."""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys

#: Every command and the app module that serves it (deltagen/apps/): each exposes
#: ``add_parser(subparsers)`` (its argparse subcommand; kinematics adds fk and ik) and
#: ``run(args) -> int`` (the exit status). Order: the order of `deltagen --help`.
COMMANDS: dict[str, str] = {
    "generate": "deltagen.apps.generate",
    "fk": "deltagen.apps.kinematics",
    "ik": "deltagen.apps.kinematics",
    "validate": "deltagen.apps.validate",
    "demo": "deltagen.apps.demos",
    "dynamics": "deltagen.apps.dynamics",
    "workspace": "deltagen.apps.workspace",
    "sweep": "deltagen.apps.sweep",
    "export": "deltagen.apps.export",
    "calibrate": "deltagen.apps.calibrate",
    "bench": "deltagen.apps.bench",
}

#: Commands whose options may come between their values (`fk default --degrees 20 20 20`):
#: argparse cannot intermix with subparsers, so they parse themselves.
INTERMIXED = ("fk", "ik")

EXIT_STATUS_ALL = """\
exit status:
  0  success
  1  ran, but the result is not valid: fk/ik rows without a valid result, a stale
     generated/ (generate --check), a tolerance missed (validate)
  2  usage or input error (bad arguments, an unreadable or malformed file, a grid or
     sweep larger than DELTAGEN_MAX_MEMORY, an input file larger than DELTAGEN_MAX_INPUT)
  130  interrupted (Ctrl-C)"""


def app(command: str):
    """The app module serving ``command`` (COMMANDS), imported."""
    return importlib.import_module(COMMANDS[command])


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error (the usage is one `--help` away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


_NEGATIVE_NUMBER = re.compile(r"-(\d|\.\d|inf|nan)", re.IGNORECASE)


def _protect_negative_numbers(argv):
    """argparse takes '-1e+16', '-inf' or '--q0 -0.1,0.2' for options (it only knows
    '-1' and '-1.5' as numbers); a leading space keeps them values (float() ignores it)."""
    return [" " + a if _NEGATIVE_NUMBER.match(a) else a for a in argv]


def build_parser(commands=None) -> tuple[argparse.ArgumentParser, dict]:
    """The `deltagen` parser and its subcommands' parsers by name, each added by its app:
    every command of COMMANDS (``--help`` lists them all), or only those named in
    ``commands`` (the one a command line asks for: its app alone is imported)."""
    parser = _Parser(
        prog="deltagen",
        description=__doc__,
        epilog=EXIT_STATUS_ALL,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True)
    added: set = set()
    for command in COMMANDS if commands is None else commands:
        if id(serving := app(command)) not in added:  # kinematics adds fk and ik at once
            added.add(id(serving))
            serving.add_parser(sub)
    return parser, dict(sub.choices)


def _parse(argv: list) -> argparse.Namespace:
    """The parsed arguments (SystemExit for --help or a usage error, argparse printed why).
    A known command builds its own subcommand only; anything else (``--help``, no command,
    an unknown one) the whole parser, so argparse lists every command."""
    known = bool(argv) and argv[0] in COMMANDS
    parser, commands = build_parser((argv[0],) if known else None)
    if known and argv[0] in INTERMIXED:
        # options may come between the values; negative numbers stay values
        return commands[argv[0]].parse_intermixed_args(_protect_negative_numbers(argv[1:]))
    return parser.parse_args(argv)


def main(argv=None) -> int:
    """`deltagen ...`: the exit status (0 success, 1 not valid, 2 usage or input error,
    130 interrupted; EXIT_STATUS_ALL)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        try:
            args = _parse(argv)
        except SystemExit as exc:  # --help (0) or a usage error (2, argparse printed why)
            return exc.code if isinstance(exc.code, int) else 2
        return _run(args)
    except KeyboardInterrupt:  # Ctrl-C: the shell's 128 + SIGINT, no traceback
        name = str((argv or [""])[0])
        command = f"deltagen {name}" if name and not name.startswith("-") else "deltagen"
        print(f"{command}: interrupted", file=sys.stderr)
        return 130


def _run(args: argparse.Namespace) -> int:
    """The command's exit status; a deltagen error, a ValueError or an OSError is a one-line
    message and exit status 2, a closed pipe (`deltagen validate | head`) exit status 0."""
    from deltagen.errors import DeltagenError

    try:
        return int(app(args.command).run(args) or 0)
    except BrokenPipeError:  # the reader left: not an error
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except (DeltagenError, ValueError, OSError) as exc:
        print(f"deltagen {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
