"""`deltagen generate`: (re)write generated/ deterministically, or check it is current."""

from __future__ import annotations

import difflib
from collections.abc import Callable
from pathlib import Path

from deltagen.paths import generated_dir


def generated_files() -> dict[str, str]:
    """Every checked-in generated file, by name: the delta core, the linear delta's and the
    tripod's cores, the 5-axis machine core and each bundled arm (the TOML ones and the URDF
    ones, robots/*.urdf read as SerialRobot.load reads them)."""
    files: dict[str, str] = {}
    for render in module_renderers().values():
        files.update(render())
    return files


def module_renderers() -> dict[str, Callable[[], dict[str, str]]]:
    """Each module of generated/ by its stem (its files are ``<stem>.*``), with the function
    that renders it alone: the per-module checks of tests/codegen/ render one each, in
    parallel, and their union is :func:`generated_files`. Listing them derives nothing."""
    from deltagen.api.serial import bundled_robots, bundled_urdfs
    from deltagen.codegen.delta import delta_sources
    from deltagen.codegen.five_axis import five_axis_sources
    from deltagen.codegen.hexapod import hexapod_sources
    from deltagen.codegen.linear_delta import linear_delta_sources, tripod_sources
    from deltagen.codegen.serial import arm_sources
    from deltagen.model.serial import SerialDescription
    from deltagen.model.urdf import description_from_urdf
    from deltagen.paths import robots_dir

    def toml_arm(name):
        return lambda: arm_sources(SerialDescription.from_toml(robots_dir() / f"{name}.toml"))

    def urdf_arm(name):
        return lambda: arm_sources(description_from_urdf(robots_dir() / f"{name}.urdf", name=name))

    renderers: dict[str, Callable[[], dict[str, str]]] = {
        "delta_kinematics": delta_sources,
        "linear_delta_kinematics": linear_delta_sources,
        "tripod_kinematics": tripod_sources,
        "five_axis_kinematics": five_axis_sources,
    }
    for name in bundled_robots():
        renderers[f"serial_{name}"] = toml_arm(name)
    for name in bundled_urdfs():
        renderers[f"serial_{name}"] = urdf_arm(name)
    renderers["hexapod_kinematics"] = hexapod_sources
    return renderers


def generate_robot_file(path) -> Path:
    """`deltagen generate my_arm.toml` (or `arm.urdf`: its chain from the root link to the
    single leaf, model/urdf.py): render, compile and cache a user's robot module; returns
    the folder holding its C sources."""
    from deltagen.model.serial import SerialDescription
    from deltagen.model.urdf import description_from_urdf

    if str(path).lower().endswith(".urdf"):
        return _module_folder(description_from_urdf(path))
    return _module_folder(SerialDescription.from_toml(path))


def generate_robot(robot) -> Path:
    """Render, compile and cache the module of a loaded serial arm (SerialRobot, or a
    CoupledArm: the module of its full chain, the one it evaluates); returns the folder
    holding its C sources."""
    return _module_folder(
        robot.full.description if hasattr(robot, "coupling") else robot.description
    )


def _module_folder(desc) -> Path:
    """The folder of the C sources of ``desc``'s complete module, built (or found) first."""
    from deltagen.native.serial import complete_module, source_dir

    complete_module(desc)
    folder = source_dir(desc)
    assert folder is not None
    return folder


def write(directory: Path | None = None) -> list[Path]:
    directory = Path(directory) if directory else generated_dir()
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in generated_files().items():
        path = directory / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            written.append(path)
    return written


def stray(directory: Path | None = None, names=None) -> list[str]:
    """Files in generated/ that the generator does not produce (a removed robot, a hand-made
    file): names, sorted."""
    directory = Path(directory) if directory else generated_dir()
    names = set(generated_files() if names is None else names)
    if not directory.is_dir():
        return []
    return sorted(p.name for p in directory.iterdir() if p.is_file() and p.name not in names)


def check(directory: Path | None = None) -> list[str]:
    """Return a unified diff per stale or missing file and a line per stray file (empty when
    generated/ is current)."""
    directory = Path(directory) if directory else generated_dir()
    problems = []
    files = generated_files()
    for name in stray(directory, files):
        problems.append(f"{name} is stray: the generator does not produce it (delete it)\n")
    for name, text in files.items():
        problem = stale(directory / name, text)
        if problem:
            problems.append(problem)
    return problems


def stale(path: Path, text: str) -> str | None:
    """None when ``path`` holds ``text``; else "<name> is stale|missing:" and a unified diff
    (its first 60 lines)."""
    current = path.read_text() if path.exists() else ""
    if current == text:
        return None
    diff = difflib.unified_diff(
        current.splitlines(keepends=True),
        text.splitlines(keepends=True),
        fromfile=f"{path} (checked in)",
        tofile=f"{path} (regenerated)",
        n=1,
    )
    state = "stale" if path.exists() else "missing"
    return f"{path.name} is {state}:\n" + "".join(list(diff)[:60])


# ---------------------------------------------------------------- the command


def add_parser(subparsers) -> None:
    """`deltagen generate [ROBOT_FILE] [--check]`."""
    from deltagen.apps.robots import add_urdf_options

    p = subparsers.add_parser("generate", help="regenerate generated/ (deterministic)")
    p.add_argument(
        "robot_file",
        nargs="?",
        help="a serial-arm TOML, a URDF or a bundled arm's name: generate, compile and "
        "cache its module",
    )
    add_urdf_options(p)
    p.add_argument(
        "--check", action="store_true", help="fail and show a diff if generated/ is stale"
    )


def run(args) -> int:
    """`deltagen generate`: 0 written or current; 1 (--check) stale; the robot file's module
    generated and compiled."""
    import sys

    if args.robot_file:
        return _run_robot_file(args)
    if args.check:
        problems = check()
        for text in problems:
            print(text, file=sys.stderr)
        if problems:
            print("generated/ is stale: run `deltagen generate`", file=sys.stderr)
            return 1
        print("generated/ is up to date")
        return 0
    written = write()
    for path in written:
        print(f"wrote {path}")
    if not written:
        print("generated/ already up to date")
    for name in stray():
        print(
            f"warning: generated/{name} is not produced by the generator; delete it "
            "(`deltagen generate --check` fails while it is there)",
            file=sys.stderr,
        )
    return 0


def _run_robot_file(args) -> int:
    """`deltagen generate ROBOT_FILE`: a serial arm's module; other kinds have a generic core
    whose geometry is read at run time, so they are refused with the way to use the file."""
    from deltagen.apps.robots import COUPLED, KIND_NAMES, MACHINE, SERIAL, kind_of, robot_of
    from deltagen.inputs import InputError
    from deltagen.paths import runtime_dir

    robot = robot_of(args, spec=args.robot_file, backend="reference")  # built below, once
    kind = kind_of(robot)
    if kind == MACHINE:
        raise InputError(
            f"`deltagen generate ROBOT_FILE` takes a serial arm; {args.robot_file} describes "
            "a 5-axis NC machine, whose core is generic (`deltagen generate` writes it; the "
            f"geometry is read at run time), so use the file directly: `deltagen fk "
            f"{args.robot_file} ...`"
        )
    if kind not in (SERIAL, COUPLED):
        raise InputError(
            "`deltagen generate ROBOT_FILE` takes a serial arm: a serial-arm file (a "
            "`convention` key and [[joint]] tables), a URDF or a bundled arm's name; "
            f"{args.robot_file} "
            f"describes {KIND_NAMES[kind]}, whose core is generic (`deltagen generate` writes "
            f"it; the geometry is read at run time), so use the file directly: "
            f"`deltagen fk {args.robot_file} ...`"
        )
    folder = generate_robot(robot)
    print(
        f"generated and compiled {args.robot_file}: C sources in {folder} "
        f"(compile them with the runtime C in {runtime_dir()})"
    )
    return 0
