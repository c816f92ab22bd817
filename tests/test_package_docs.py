"""Every package's ``__init__`` docstring names what it holds (docs/architecture.md,
"Layout"): each module (a ``.py`` file) and each subpackage in it, written as
```name``` in the docstring. A module added without a word in its package's docstring fails
here, so the docstrings stay a true table of contents.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "deltagen"

PACKAGES = sorted(init.parent for init in PACKAGE.rglob("__init__.py") if init.parent != PACKAGE)


def _members(package: Path) -> list[str]:
    """The modules and subpackages of a package, by the name an import would use."""
    names = [p.stem for p in package.glob("*.py") if p.name != "__init__.py"]
    names += [p.name for p in package.iterdir() if (p / "__init__.py").is_file()]
    return sorted(names)


def _unnamed(package: Path) -> list[str]:
    doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
    return [name for name in _members(package) if f"``{name}``" not in doc]


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: str(p.relative_to(PACKAGE.parent)))
def test_the_docstring_names_every_module(package):
    missing = _unnamed(package)
    assert missing == [], (
        f"{package.relative_to(PACKAGE.parent)}/__init__.py: the docstring does not name "
        f"{', '.join(missing)} (write each as ``name``)"
    )


def test_the_check_catches_an_unnamed_module(tmp_path):
    """A module or subpackage the docstring does not name is reported; one it names is not."""
    (tmp_path / "__init__.py").write_text('"""Holds ``named``."""\n')
    (tmp_path / "named.py").write_text("")
    (tmp_path / "forgotten.py").write_text("")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "__init__.py").write_text("")
    (tmp_path / "data").mkdir()  # not a package: no __init__.py
    assert _unnamed(tmp_path) == ["forgotten", "sub"]
