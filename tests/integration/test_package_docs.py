"""Every package's ``__init__`` docstring names what it holds (docs/architecture.md,
"Layout"): each module (a ``.py`` file) and each subpackage in it, in double backquotes
(``name``). A module added without a word in its package's docstring fails here, so the
docstrings stay a true table of contents. Likewise every file that docs/architecture.md
names in a code span must exist, so the map does not point at files that moved.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from helpers import REPO

PACKAGE = REPO / "deltagen"

PACKAGES = sorted(init.parent for init in PACKAGE.rglob("__init__.py") if init.parent != PACKAGE)


def _members(package: Path) -> list[str]:
    """The modules and subpackages of a package, by the name an import would use."""
    # not the private ones: test_layering writes a ``_layering_probe.py`` into a package
    # for a moment, and a worker running this file beside it must not see it
    names = [p.stem for p in package.glob("*.py") if not p.name.startswith("_")]
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


ARCHITECTURE = PACKAGE.parent / "docs" / "architecture.md"
#: a file or folder named in code spans of docs/architecture.md: ``native/build.py``,
#: ``lean_ext.c``, ``derive/delta/``
_FILE_SPAN = re.compile(r"`([A-Za-z_][\w./-]*(?:\.(?:py|c|h|j2|json|md)|/))`")


def _missing_files(text: str) -> list[str]:
    """File names of the document that exist nowhere: a path is looked up from the
    repository's root and from deltagen/, a bare file name anywhere in the repository."""
    root = PACKAGE.parent
    missing = []
    for name in sorted(set(_FILE_SPAN.findall(text))):
        path = name.rstrip("/")
        if "/" in path:
            found = (root / path).exists() or (PACKAGE / path).exists()
        else:
            found = any(root.glob(f"deltagen/**/{path}")) or any(root.glob(f"*/{path}"))
            found = found or (root / path).exists()
        if not found:
            missing.append(name)
    return missing


def test_the_architecture_document_names_real_files():
    assert _missing_files(ARCHITECTURE.read_text()) == []


def test_the_file_check_catches_a_missing_file():
    text = "`native/build.py`, `lean_ext.c`, `derive/delta/` and `native/no_such_module.py`"
    assert _missing_files(text) == ["native/no_such_module.py"]
