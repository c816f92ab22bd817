"""The README's Python examples run verbatim.

Every ```python block is executed, in the order of the README, in one namespace: a reader
who types them in one session gets what the README shows. A block that fails names its
first line in the README.
"""

from __future__ import annotations

import re

import pytest
from helpers import REPO

README = REPO / "README.md"
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)


def _blocks():
    text = README.read_text()
    for match in _BLOCK.finditer(text):
        yield text.count("\n", 0, match.start()) + 2, match.group(1)


def test_the_readme_has_python_examples():
    assert len(list(_blocks())) >= 3


def test_readme_python_blocks_run_verbatim(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    namespace: dict = {"__name__": "__readme__"}
    for line, code in _blocks():
        try:
            exec(compile(code, f"README.md:{line}", "exec"), namespace)
        except Exception as exc:  # noqa: BLE001 - reported with the block's line
            pytest.fail(f"README.md block at line {line} failed: {type(exc).__name__}: {exc}")


def test_the_check_catches_a_block_that_fails(tmp_path):
    """A block using an undefined name fails the way the README test reports it."""
    with pytest.raises(NameError):
        exec(compile("q = arm.ik(many_T)\n", "README.md:1", "exec"), {})
