"""The serial arms' packed block arrays (codegen/render.py pack_block_arrays): all angles of
a block in one cos loop and one sin loop, and every row's bits independent of the batch
around it.

Why: a single pose used to cost one vector cos and one vector sin call per angle (twelve
8-lane calls for a 6R arm's fk, each padded to 8 points); with the angles end to end it
costs one of each. The layout must not change any result: a row computed alone, at any
place in a batch, in a full block or in a block's remainder, gives the same bits, status
included, also for non-finite, huge and overflowing inputs. The independent evidence is
the kernel itself called one row at a time.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.paths import generated_dir

#: the batched kernels of q alone, and those of (q, qd) and (q, qd, qdd)
KERNELS = {
    "fk": 1,
    "frames": 1,
    "jacobian": 1,
    "fk_jacobian": 1,
    "jacobian_dot": 2,
    "inverse_dynamics": 3,
}


@pytest.mark.parametrize("module", ["serial_puma560", "serial_ur5", "serial_gantry_xyz_ac"])
def test_one_cos_loop_and_one_sin_loop_per_kernel(module):
    """Every kernel of the arm that evaluates cosines and sines of joint angles does so in
    one loop each, over all its angles (a prismatic axis has none)."""
    text = (generated_dir() / f"{module}.c").read_text()
    bodies = re.findall(r"^int (deltagen_\w+)\(.*?^}", text, re.DOTALL | re.MULTILINE)
    kernels = re.split(r"^int deltagen_\w+\(", text, flags=re.MULTILINE)[1:]
    assert len(bodies) == len(kernels)
    with_trig = 0
    for name, body in zip(bodies, kernels):
        cos_loops = body.count("/* loop: cos */")
        sin_loops = body.count("/* loop: sin */")
        assert cos_loops <= 1 and sin_loops <= 1, (name, cos_loops, sin_loops)
        with_trig += cos_loops
    assert with_trig >= 5  # fk, frames, jacobian, fk_jacobian, jacobian_dot at least


def _rows(n: int, rng) -> tuple:
    q = rng.uniform(-4.0, 4.0, (n, 6))
    qd = rng.normal(size=(n, 6))
    qdd = rng.normal(size=(n, 6))
    q[3, 2] = np.nan
    q[7, 0] = np.inf
    q[11, 5] = 1e308  # finite, its cosine well defined, the libmvec fallback lane
    q[12, 1] = 1e22
    q[30, 4] = -0.0
    qd[20, 3] = 1e200  # finite rates that overflow the dynamics: INVALID, all NaN
    qd[21, 0] = -np.inf
    return q, qd, qdd


@pytest.fixture(scope="module", params=["puma560", "ur5"])
def core(request):
    return SerialRobot.load(request.param, threads=1)._core


@pytest.mark.parametrize("kernel", list(KERNELS))
def test_every_row_gets_the_bits_it_gets_alone(core, kernel):
    q, qd, qdd = _rows(150, np.random.default_rng(21))  # two blocks of 64 and a remainder
    inputs = (q, qd, qdd)[: KERNELS[kernel]]
    batch = getattr(core, kernel)(*inputs)
    statuses = batch[-1]
    assert set(np.unique(statuses)) >= {0, 3}  # OK rows and INVALID ones
    for size, start in ((1, 0), (1, 11), (1, 149), (5, 9), (13, 60), (70, 3), (64, 64)):
        part = getattr(core, kernel)(*(a[start : start + size].copy() for a in inputs))
        for whole, piece in zip(batch, part):
            np.testing.assert_array_equal(
                np.asarray(whole[start : start + size]).view(np.uint8),
                np.asarray(piece).view(np.uint8),
                err_msg=f"{kernel}: rows {start}..{start + size - 1}",
            )
