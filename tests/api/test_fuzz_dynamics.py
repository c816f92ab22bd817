"""Extreme inputs for the dynamics methods (tests/api/test_fuzz_kinematics.py's property): on
both backends a result is either finite and valid, or NaN and not valid, the raise mode names
the rows, and the compiled core agrees with the independent reference where both are valid.
Deterministic: a fixed grid of special magnitudes placed in every input column."""

from __future__ import annotations

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot
from deltagen.errors import DeltagenError

SPECIAL = (
    0.0,
    -0.0,
    5e-324,
    -2.2e-308,
    1e-300,
    0.3,
    -1.7,
    1e100,
    -1e200,
    1.7e308,
    np.nan,
    np.inf,
    -np.inf,
)


def _batches(width, count, seed):
    """(count*len(SPECIAL)*width, ...) rows: moderate random values with one special entry."""
    rng = np.random.default_rng(seed)
    rows = []
    for value in SPECIAL:
        for column in range(width):
            base = rng.uniform(-1.0, 1.0, (count, width))
            base[:, column] = value
            rows.append(base)
    return np.concatenate(rows)


def _check(name, compiled, reference, args, n_rows):
    out_c, ok_c = compiled(*args, errors="nan")
    out_r, ok_r = reference(*args, errors="nan")
    flat_c = np.asarray(out_c).reshape(n_rows, -1)
    flat_r = np.asarray(out_r).reshape(n_rows, -1)
    ok_c, ok_r = np.asarray(ok_c).reshape(-1), np.asarray(ok_r).reshape(-1)
    for flat, ok in ((flat_c, ok_c), (flat_r, ok_r)):
        assert np.all(np.isfinite(flat[ok])), f"{name}: a non-finite value marked valid"
        assert np.all(np.isnan(flat[~ok])), f"{name}: an invalid row that is not NaN"
    # rows with moderate inputs: both backends valid and equal (relative to the row's size).
    # Huge rates are not compared: terms in qd^2 that cancel exactly in the derived C (an
    # inertia symmetric about the joint axis) leave eps * qd^2 in the reference's world-frame
    # sums, legitimately far apart from each other.
    moderate = np.ones(n_rows, dtype=bool)
    for a in args:
        moderate &= np.all(np.abs(np.asarray(a).reshape(n_rows, -1)) < 1e6, axis=1)
    both = ok_c & ok_r & moderate
    scale = np.maximum(np.max(np.abs(flat_r[both]), axis=1, initial=0.0), 1.0)
    err = np.max(np.abs(flat_c[both] - flat_r[both]), axis=1, initial=0.0) / scale
    assert np.all(err < 1e-9), f"{name}: backends differ by {err.max():.3g}"
    if not ok_c.all():
        with pytest.raises(DeltagenError) as info:
            compiled(*args)
        assert set(info.value.rows) <= set(np.flatnonzero(~ok_c)), name
        assert info.value.rows.size > 0


@pytest.mark.parametrize("model", ["exact", "simplified"])
def test_delta_inverse_dynamics_extreme_inputs(model):
    compiled, reference = DeltaRobot.default(), DeltaRobot.default(backend="reference")
    n = _batches(3, 2, seed=1).shape[0]
    q = np.tile([0.3, 0.4, 0.5], (n, 1))  # a regular pose in every row
    for slot in range(3):  # the special values in q, then qd, then qdd
        args = [q.copy(), np.tile([1.0, -2.0, 0.5], (n, 1)), np.tile([20.0, 0.0, -10.0], (n, 1))]
        args[slot] = _batches(3, 2, seed=slot) + (args[slot] if slot == 0 else 0.0)
        _check(
            f"delta inverse_dynamics[{model}] slot {slot}",
            lambda *a, **k: compiled.inverse_dynamics(*a, model=model, **k),
            lambda *a, **k: reference.inverse_dynamics(*a, model=model, **k),
            args,
            n,
        )


@pytest.mark.parametrize(
    "method, slots",
    [
        ("inverse_dynamics", 3),
        ("mass_matrix", 1),
        ("gravity_torque", 1),
        ("coriolis", 2),
        ("forward_dynamics", 3),
    ],
)
def test_serial_dynamics_extreme_inputs(method, slots):
    compiled, reference = SerialRobot.load("puma560"), SerialRobot.load("puma560", "reference")
    rows = _batches(6, 1, seed=7)
    n = rows.shape[0]
    regular = np.random.default_rng(3).uniform(-1.0, 1.0, (slots, n, 6))
    for slot in range(slots):
        args = [regular[k].copy() for k in range(slots)]
        args[slot] = rows
        _check(
            f"puma560 {method} slot {slot}",
            getattr(compiled, method),
            getattr(reference, method),
            args,
            n,
        )
