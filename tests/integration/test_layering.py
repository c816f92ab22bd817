"""The layering rule of docs/architecture.md ("Layout") and CONTRIBUTING.md: imports go down
the stages, never back up, and no module imports a private name of another package.

The imports are read from the source (every ``import`` and ``from ... import`` anywhere in
a module, including those inside functions), so a lazy import that goes back up fails too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from helpers import REPO

PACKAGE = REPO / "deltagen"

FOUNDATION = {"errors", "status", "inputs", "paths"}
BELOW_NATIVE = {"codegen", "derive", "model", "geometry"}
# stage -> the stages it may import (the foundation modules are open to every stage)
ALLOWED = {
    "geometry": set(),
    "model": {"geometry"},
    "derive": {"model", "geometry"},
    "codegen": {"derive", "model", "geometry"},
    "native": BELOW_NATIVE,
    "reference": {"model", "geometry"},
    "solve": {"native", "reference"} | BELOW_NATIVE,
    "plan": {"solve", "native", "reference"} | BELOW_NATIVE,
    "api": {"plan", "solve", "native", "reference"} | BELOW_NATIVE,
    "apps": {"api", "plan", "solve", "native", "reference"} | BELOW_NATIVE,
    "cli": {"apps", "api", "plan", "solve", "native", "reference"} | BELOW_NATIVE,
    "__init__": {"api"},
    "__main__": {"cli"},
}
for name in FOUNDATION:
    ALLOWED[name] = set()


def _stage(module: str) -> str:
    """'deltagen.derive.delta.fk' -> 'derive'; 'deltagen.errors' -> 'errors'."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _module_name(path: Path) -> tuple[str, str]:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        name = ".".join(parts[:-1])
        return name, name
    return ".".join(parts), ".".join(parts[:-1])


def _imports(path: Path):
    """(line, imported module, imported name or None) of every deltagen import in a file."""
    module, package = _module_name(path)
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "deltagen" or target.startswith("deltagen."):
                for alias in node.names:
                    yield node.lineno, target, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("deltagen"):
                    yield node.lineno, alias.name, None


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py"))


def _violations():
    found = []
    for path in _modules():
        module, _ = _module_name(path)
        if module == "deltagen":
            stage = "__init__"
        else:
            stage = _stage(module)
        for line, target, name in _imports(path):
            where = f"{path.relative_to(PACKAGE.parent)}:{line}"
            full = f"{target}.{name}" if name else target
            # `from deltagen import status` names a module of the package
            target_stage = _stage(full) if target == "deltagen" and name else _stage(target)
            if target_stage != stage and target_stage not in FOUNDATION | {"__version__"}:
                if target_stage not in ALLOWED.get(stage, set()):
                    found.append(
                        f"{where}: {stage} imports {full} ({target_stage} is not below {stage})"
                    )
            if target_stage != stage and name and name.startswith("_") and name != "__version__":
                found.append(f"{where}: imports the private name {full}")
            private_module = [p for p in full.split(".")[1:-1] if p.startswith("_")]
            if target_stage != stage and private_module:
                found.append(f"{where}: imports from the private module {full}")
    return found


def test_every_stage_is_known():
    stages = {_stage(_module_name(p)[0]) for p in _modules() if _module_name(p)[0] != "deltagen"}
    assert stages <= set(ALLOWED), f"stages without a layering rule: {stages - set(ALLOWED)}"


def test_imports_go_down_the_stages():
    assert _violations() == []


def test_every_package_says_what_it_holds_and_may_import():
    for init in PACKAGE.rglob("__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc, f"{init.relative_to(PACKAGE.parent)} has no docstring"
        if init.parent.parent == PACKAGE:  # a stage
            assert "May import" in doc, (
                f"{init.relative_to(PACKAGE.parent)}: say what it may import"
            )


@pytest.mark.parametrize(
    "bad",
    [
        ("model", "from deltagen.api.serial import SerialRobot\n"),
        ("reference", "from deltagen.solve import numeric\n"),
        ("derive", "def f():\n    from deltagen.codegen.printer import to_c\n"),
        ("api", "from deltagen.native.serial import _Scratch\n"),
    ],
)
def test_the_check_catches_an_import_going_up(tmp_path, monkeypatch, bad):
    """The rule fails when an import goes back up (or takes a private name)."""
    stage, text = bad
    fake = PACKAGE / stage / "_layering_probe.py"
    fake.write_text(text)
    try:
        assert any("_layering_probe" in v for v in _violations())
    finally:
        fake.unlink()
