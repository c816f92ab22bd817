"""codegen.export.DiskMemo: the derivations and lowerings of `deltagen export`, kept in the
build cache so that a later process exporting the same robot unpickles them instead of
running SymPy again; a stale, corrupt or unwritable cache is a miss, never an error."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from deltagen.codegen import export, serial

#: one export's C of a small bundled arm, printed as a digest; with "forbid" any derivation
#: or lowering exits instead (so only the memo can provide them)
SCRIPT = """
import hashlib, json, sys
from deltagen.codegen import export
from deltagen.derive.serial import kernels
from deltagen.model.serial import SerialDescription
from deltagen.paths import robots_dir

if sys.argv[1] == "forbid":
    def refuse(*args, **kwargs):
        raise SystemExit("derived or lowered again")
    kernels.ArmKernels.all = refuse
    export.lower = refuse
desc = SerialDescription.from_toml(robots_dir() / "lecture_prp.toml")
unit, derived = export.arm_unit_kernels(desc)
package = export.package_sources(unit, derived, real_type=sys.argv[2])
print(hashlib.sha256(json.dumps(package.files, sort_keys=True).encode()).hexdigest())
"""


def _export(cache, how: str, real: str = "double") -> subprocess.CompletedProcess:
    env = dict(os.environ, DELTAGEN_CACHE=str(cache))
    return subprocess.run(
        [sys.executable, "-c", SCRIPT, how, real], env=env, capture_output=True, text=True
    )


def _digest(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


@pytest.mark.slow
def test_a_later_process_takes_the_derivation_and_lowering_from_the_cache(tmp_path):
    cache = tmp_path / "cache"
    first = _digest(_export(cache, "derive"))
    entries = sorted(p.name.split("-")[0] for p in (cache / "memo").glob("*.pickle"))
    assert entries == ["derivation", "lowered"]
    assert _digest(_export(cache, "forbid")) == first  # the same C, from the memo alone
    # float: the derivation is reused, the lowering is new (forbidden here, so it fails)
    refused = _export(cache, "forbid", "float")
    assert refused.returncode != 0 and "derived or lowered again" in refused.stderr
    # an empty cache must derive: the refusal is real
    empty = _export(tmp_path / "empty", "forbid")
    assert empty.returncode != 0 and "derived or lowered again" in empty.stderr


@pytest.mark.slow
def test_a_corrupt_entry_is_derived_again_and_replaced(tmp_path):
    cache = tmp_path / "cache"
    first = _digest(_export(cache, "derive"))
    for path in (cache / "memo").glob("*.pickle"):
        path.write_bytes(b"not a pickle")
    assert _digest(_export(cache, "derive")) == first
    assert _digest(_export(cache, "forbid")) == first  # rewritten whole


def test_another_generator_or_library_version_is_another_entry(tmp_path, monkeypatch):
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path))
    memo = export.DiskMemo("derivation")
    memo["k"] = ("value",)
    assert "k" in export.DiskMemo("derivation")  # read back from its file
    assert "k" not in export.DiskMemo("lowered")  # another kind
    real = serial.generator_fingerprint()
    monkeypatch.setattr(serial, "generator_fingerprint", lambda: real + "0")
    assert "k" not in export.DiskMemo("derivation")
    monkeypatch.setattr(serial, "generator_fingerprint", lambda: real)
    import sympy

    monkeypatch.setattr(sympy, "__version__", sympy.__version__ + ".post1")
    assert "k" not in export.DiskMemo("derivation")


def test_an_unwritable_cache_keeps_the_value_in_this_process(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("DELTAGEN_CACHE", str(blocker))
    memo = export.DiskMemo("derivation")
    memo["k"] = ("value",)  # cannot be written: no error
    assert "k" in memo and memo["k"] == ("value",)
    assert "k" not in export.DiskMemo("derivation")
    assert not list(tmp_path.glob("**/*.tmp"))
