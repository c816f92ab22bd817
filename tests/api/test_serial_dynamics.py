"""api/serial_dynamics.py: the six dynamics quantities of a SerialRobot share one general path
(_dynamics_rows: the inertia check, the errors mode, the broadcast of the joint states, the
core call, _finish_dynamics). Evidence: deltagen.reference.serial (the Jacobian-form numpy
dynamics, written from the model, not from the RNEA derivation) on the same rows, through
the batch path, the broadcast path and the one-state path."""

from __future__ import annotations

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.inputs import InputError
from deltagen.reference import serial as reference

STATES = {
    "mass_matrix": ("q",),
    "gravity_torque": ("q",),
    "coriolis": ("q", "qd"),
    "nonlinear_effects": ("q", "qd"),
    "inverse_dynamics": ("q", "qd", "qdd"),
    "forward_dynamics": ("q", "qd", "tau"),
}


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560", threads=1)


def _states(arm, n, rng):
    q = rng.uniform(-2.0, 2.0, (n, arm.n))
    return {
        "q": q,
        "qd": rng.uniform(-1.0, 1.0, (n, arm.n)),
        "qdd": rng.uniform(-1.0, 1.0, (n, arm.n)),
        "tau": rng.uniform(-5.0, 5.0, (n, arm.n)),
    }


@pytest.mark.parametrize("name", list(STATES))
def test_each_quantity_matches_the_reference_on_every_path(puma, name):
    data = _states(puma, 12, np.random.default_rng(31))
    args = [data[k] for k in STATES[name]]
    want, status = getattr(reference, name)(puma.description, *args)
    assert (status == 0).all()
    tol = dict(rtol=1e-9, atol=1e-9)
    method = getattr(puma, name)
    np.testing.assert_allclose(method(*args), want, **tol)  # the batch
    got, valid = method(*args, errors="nan")
    np.testing.assert_allclose(got, want, **tol)
    assert valid.all()
    np.testing.assert_allclose(method(*(a[0] for a in args)), want[0], **tol)  # one state
    if len(args) > 1:  # the joint state q broadcast against (3, 1, n) rates
        rates = [a[:3, None] for a in args[1:]]
        got = method(args[0][:4], *rates)
        want_b, _ = getattr(reference, name)(
            puma.description,
            *(
                np.broadcast_to(a, (3, 4, puma.n)).reshape(-1, puma.n)
                for a in [args[0][:4], *rates]
            ),
        )
        np.testing.assert_allclose(got.reshape(want_b.shape), want_b, **tol)


@pytest.mark.parametrize("name", list(STATES))
def test_each_quantity_refuses_an_arm_without_inertia(name):
    arm = SerialRobot.load("lecture_scara", "reference")
    args = [np.zeros(arm.n)] * len(STATES[name])
    with pytest.raises(InputError, match="no inertial parameters"):
        getattr(arm, name)(*args)
