"""Instructions per point of the batched kernels (callgrind, native/instructions.py) against
the checked-in baseline tests/baselines/instructions.json: the delta core's kernels and
the Puma 560's and UR5's batched kernels.

A kernel that executes more than 5 % more instructions per point than its baseline fails,
naming the kernel and both counts; one that executes more than 5 % fewer fails too (a
snapshot: the baseline is refreshed so the next slowdown is measured from the new level).
Refresh after a deliberate change with

    DELTAGEN_UPDATE_BASELINES=1 python -m pytest tests/native/test_instructions.py
    (or: python -m pytest tests/native/test_instructions.py --update-baselines)

and commit the file. Counts are exact for a given compiler, glibc (libmvec) and valgrind;
the baseline records their versions, and where they differ the comparison is skipped with
both named (refresh the baseline when the project's toolchain moves). No timing is asserted.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from helpers import BASELINES

from deltagen.native import build, instructions
from deltagen.paths import generated_dir

BASELINE = BASELINES / "instructions.json"
TOLERANCE = 0.05
SEED = 2008
DELTA_KERNELS = (
    "fk",
    "fk_vel",
    "fk_acc",
    "jacobian",
    "ik",
    "ik_vel",
    "ik_acc",
    "fk_param_jacobian",
    "inverse_dynamics",
    "inverse_dynamics_simplified",
)
ARM_KERNELS = (
    "fk",
    "frames",
    "jacobian",
    "fk_jacobian",
    "jacobian_dot",
    "ik_all",
    "inverse_dynamics",
    "mass_matrix",
    "gravity_torque",
    "coriolis",
    "nonlinear_effects",
    "forward_dynamics",
)
#: kernels of the counted modules that are not counted, and why
NOT_COUNTED = {
    "ik_newton": "iterative: its cost is its iteration count (tests/solve/test_numeric_c.py)",
}
MODULES = {
    "delta_kinematics": DELTA_KERNELS,
    "serial_puma560": ARM_KERNELS,
    "serial_ur5": ARM_KERNELS,
}
REASON = instructions.unavailable()
pytestmark = pytest.mark.skipif(REASON is not None, reason=str(REASON))


def _update_requested(config) -> bool:
    flag = os.environ.get("DELTAGEN_UPDATE_BASELINES", "").strip().lower()
    return flag in ("1", "yes", "true", "on") or bool(config.getoption("--update-baselines"))


def _delta_inputs(points: int):
    """Inputs every delta kernel reads (all rows OK: apps.bench.sections.sample_poses), the geometry."""
    from deltagen.api.delta import DeltaRobot
    from deltagen.apps.bench.sections import sample_poses
    from deltagen.native.delta import geometry_struct

    robot = DeltaRobot.default(threads=1)
    core = robot._core
    data = sample_poses(points, [core], np.random.default_rng(SEED))
    p, pd, pdd, _ = core.fk_acc(data["q"], data["qd"], data["qdd"])
    inputs = {k: data[k] for k in ("q", "qd", "qdd", "payload")} | {"p": p, "pd": pd, "pdd": pdd}
    return inputs, ("deltagen_delta_geometry", geometry_struct(robot.geometry))


def _arm_inputs(name: str, points: int):
    """q uniform within the joint limits, qd, qdd, T = fk(q) (ik_all), tau = the inverse
    dynamics of (q, qd, qdd) (forward_dynamics)."""
    from deltagen.api.serial import SerialRobot

    arm = SerialRobot.load(name, threads=1)
    rng = np.random.default_rng(SEED)
    lim = arm.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (points, arm.n))
    qd = rng.uniform(-2.0, 2.0, (points, arm.n))
    qdd = rng.uniform(-5.0, 5.0, (points, arm.n))
    T = arm.fk(q).reshape(points, 16)
    tau = arm._core.inverse_dynamics(q, qd, qdd)[0]
    return {"q": q, "qd": qd, "qdd": qdd, "T": T, "tau": tau}, None


def measure(module: str, kernels, source: Path | None = None) -> dict[str, float]:
    """Instructions per point of ``kernels`` of generated/<module>.c (or ``source``)."""
    source = source or generated_dir() / f"{module}.c"
    cdef = (generated_dir() / f"{module}.cdef.h").read_text()
    if module == "delta_kinematics":
        prefix = "deltagen_delta"
        data, geometry = _delta_inputs(instructions.POINTS[-1])
    else:
        prefix = "deltagen_" + module.removeprefix("serial_")
        data, geometry = _arm_inputs(module.removeprefix("serial_"), instructions.POINTS[-1])
    sigs = instructions.signatures(cdef, prefix)
    widths = {k: int(np.prod(v.shape[1:])) for k, v in data.items()}
    driver = instructions.driver_source(
        source.with_suffix(".h").name, prefix, {k: sigs[k] for k in kernels}, widths, geometry
    )
    executable = instructions.build_driver(source, prefix, driver)
    counts = instructions.count(executable, data, kernels)
    return {k: round(instructions.per_point(counts[k]), 2) for k in kernels}


def _baseline() -> dict:
    return json.loads(BASELINE.read_text()) if BASELINE.is_file() else {}


def test_every_batched_kernel_is_counted():
    """A new kernel in a counted module must be counted (or listed, with a reason)."""
    for module, kernels in MODULES.items():
        cdef = (generated_dir() / f"{module}.cdef.h").read_text()
        prefix = "deltagen_delta" if module == "delta_kinematics" else "deltagen_" + module[7:]
        found = set(instructions.signatures(cdef, prefix))
        assert found - set(NOT_COUNTED) == set(kernels), (module, sorted(found))


@pytest.mark.parametrize("module", list(MODULES))
def test_instructions_per_point(module, request):
    measured = measure(module, MODULES[module])
    stored = _baseline()
    toolchain = instructions.toolchain()
    if _update_requested(request.config):
        stored.setdefault("about", __doc__.split("\n\n")[0].replace("\n", " "))
        stored["toolchain"] = toolchain
        stored["points"] = list(instructions.POINTS)
        stored.setdefault("instructions_per_point", {})[module] = measured
        BASELINE.parent.mkdir(exist_ok=True)
        BASELINE.write_text(json.dumps(stored, indent=1, sort_keys=True) + "\n")
        return
    assert stored, f"no baseline {BASELINE}: run with DELTAGEN_UPDATE_BASELINES=1"
    if stored.get("toolchain") != toolchain or stored.get("points") != list(instructions.POINTS):
        pytest.skip(
            f"the baseline was counted with {stored.get('toolchain')} at "
            f"{stored.get('points')} points, this is {toolchain}: counts are comparable only "
            "on the same toolchain (refresh with DELTAGEN_UPDATE_BASELINES=1)"
        )
    problems = instructions.compare(
        stored["instructions_per_point"].get(module, {}), measured, TOLERANCE
    )
    assert not problems, (
        f"{module}: instructions per point differ from {BASELINE.name} by more than "
        f"{100 * TOLERANCE:g} %:\n  "
        + "\n  ".join(problems)
        + "\nIf the change is intended, refresh the baseline: DELTAGEN_UPDATE_BASELINES=1 "
        "python -m pytest tests/native/test_instructions.py (or --update-baselines), and commit it"
    )


def test_compare_reports_both_directions():
    base = {"fk": 100.0, "ik": 200.0, "jacobian": 50.0}
    assert instructions.compare(base, {"fk": 104.9, "ik": 190.1, "jacobian": 50.0}) == []
    problems = instructions.compare(base, {"fk": 105.1, "ik": 189.9, "extra": 1.0})
    assert problems == [
        "extra: 1.0 instructions per point, and no baseline",
        "fk: 100.0 -> 105.1 instructions per point (+5.1 %, more than 5 %): slower",
        "ik: 200.0 -> 189.9 instructions per point (-5.0 %, more than 5 % fewer): "
        "faster, refresh the baseline",
        "jacobian: in the baseline (50.0) but not measured",
    ]


def test_a_devectorised_kernel_fails_against_the_baseline(tmp_path):
    """The regression this guard exists for, made on purpose: delta fk with the finite-output
    guard in the form gcc 12 does not vectorise (tests/native/test_vectorisation.py) executes
    several times the baseline's instructions per point, and the comparison says so."""
    stored = _baseline()
    if stored.get("toolchain") != instructions.toolchain():
        pytest.skip("the baseline is from another toolchain")
    text = (generated_dir() / "delta_kinematics.c").read_text()
    preamble, kernels = build.split_units(text)
    fk = next(lines for _, lines in kernels if lines[0].startswith("int deltagen_delta_fk("))
    guard = next(i for i, line in enumerate(fk) if "const int nonfinite_output" in line)
    old = "isfinite((((collinear) | (invalid) | (unreachable)) ? NAN : {}))"
    for var in ("x", "y", "z"):
        fk[guard] = fk[guard].replace(f"isfinite({var})", old.format(var))
    source = tmp_path / "delta_kinematics.c"
    source.write_text("\n".join(preamble + fk) + "\n")
    for ext in (".h", ".cdef.h"):
        name = f"delta_kinematics{ext}"
        (tmp_path / name).write_text((generated_dir() / name).read_text())
    measured = measure("delta_kinematics", ("fk",), source)
    baseline = {"fk": stored["instructions_per_point"]["delta_kinematics"]["fk"]}
    problems = instructions.compare(baseline, measured, TOLERANCE)
    assert len(problems) == 1 and problems[0].startswith("fk: ") and "slower" in problems[0]
    assert measured["fk"] > 1.5 * baseline["fk"], (measured, baseline)
