"""The bundled serial arms (robots/*.toml with a convention, robots/*.urdf): their names
and the description SerialRobot.load(name) builds."""

from __future__ import annotations

from pathlib import Path

from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription
from deltagen.paths import robots_dir


def _is_arm_file(path: Path) -> bool:
    """A robot file of a serial arm (serial files state a convention; delta files do not)."""
    return path.is_file() and "convention" in path.read_text()


def bundled_robots() -> list[str]:
    """Names of the bundled serial arms (robots/*.toml with a convention)."""
    return [path.stem for path in sorted(robots_dir().glob("*.toml")) if _is_arm_file(path)]


def bundled_urdfs() -> list[str]:
    """Names of the bundled URDF arms (robots/*.urdf: SerialRobot.load(name) reads the chain
    from the root link to the single leaf, under the file's name)."""
    return [path.stem for path in sorted(robots_dir().glob("*.urdf"))]


def bundled_arm(name: str) -> SerialDescription:
    """The description of the bundled arm ``name``: robots/<name>.toml, else
    robots/<name>.urdf (the chain from the root link to the single leaf)."""
    if (
        isinstance(name, str)
        and name.isidentifier()
        and not (robots_dir() / f"{name}.toml").exists()
        and (robots_dir() / f"{name}.urdf").is_file()
    ):
        from deltagen.model.urdf import description_from_urdf

        desc = description_from_urdf(robots_dir() / f"{name}.urdf", name=name)
        return desc
    if (
        not isinstance(name, str)
        or not name.isidentifier()
        or not _is_arm_file(robots_dir() / f"{name}.toml")
    ):
        raise InputError(
            f"no bundled serial robot {name!r}; bundled: "
            f"{', '.join(bundled_robots() + bundled_urdfs())}"
        )
    return SerialDescription.from_toml(robots_dir() / f"{name}.toml")
