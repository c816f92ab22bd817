"""`deltagen generate`: (re)write generated/ deterministically, or check it is current."""

from __future__ import annotations

import difflib
from pathlib import Path

from .paths import generated_dir


def generated_files() -> dict[str, str]:
    """Every checked-in generated file, by name."""
    from .delta.emit import delta_sources

    return dict(delta_sources())


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


def check(directory: Path | None = None) -> list[str]:
    """Return a unified diff per stale or missing file (empty when generated/ is current)."""
    directory = Path(directory) if directory else generated_dir()
    problems = []
    for name, text in generated_files().items():
        path = directory / name
        current = path.read_text() if path.exists() else ""
        if current != text:
            diff = difflib.unified_diff(
                current.splitlines(keepends=True),
                text.splitlines(keepends=True),
                fromfile=f"{path} (checked in)",
                tofile=f"{path} (regenerated)",
                n=1,
            )
            problems.append(f"{name} is {'stale' if path.exists() else 'missing'}:\n" + "".join(list(diff)[:60]))
    return problems
