"""apps/bench/sections.py's direct calls into the generated C (the "kernel" column of the
throughput tables): the delta's and the serial arm's both go through one _c_call, and each
writes the numbers the public API returns for the same inputs (evidence: DeltaRobot.fk /
.jacobian and SerialRobot.fk / .jacobian, whose own tests hold them to the numpy reference)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot
from deltagen.apps.bench.sections import _kernel_callable, _serial_kernel_callable


def _outputs(call):
    inputs, outs, status = inspect.getclosurevars(call).nonlocals["keep"]
    return outs, status


@pytest.mark.parametrize("name", ["fk", "jacobian"])
def test_the_delta_kernel_call_gives_the_api_numbers(name):
    robot = DeltaRobot.default(threads=1)
    q = np.ascontiguousarray(np.random.default_rng(7).uniform(-0.3, 0.6, (50, 3)))
    call = _kernel_callable(robot._core, name, [q])
    assert call is not None and call() == 0
    outs, status = _outputs(call)
    want = getattr(robot, name)(q)
    assert (status == 0).all()
    np.testing.assert_allclose(outs[0].reshape(want.shape), want, rtol=0, atol=0)


@pytest.mark.parametrize("name", ["fk", "jacobian"])
def test_the_serial_kernel_call_gives_the_api_numbers(name):
    arm = SerialRobot.load("puma560", threads=1)
    q = np.ascontiguousarray(np.random.default_rng(8).uniform(-2, 2, (40, 6)))
    call = _serial_kernel_callable(arm._core, name, [q])
    assert call is not None and call() == 0
    (out,), status = _outputs(call)
    want = getattr(arm, name)(q)
    assert (status == 0).all()
    np.testing.assert_allclose(out.reshape(want.shape), want, rtol=0, atol=0)
