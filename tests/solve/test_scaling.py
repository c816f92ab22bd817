"""Time scalings (deltagen.plan.scaling): the quintic and the trapezoid against their closed
forms typed in here and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.plan import scaling

# ------------------------------------------------------------------ time scaling


def test_quintic_boundary_conditions_and_shape():
    s, sd, sdd = scaling.Quintic()(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(s, [0.0, 0.5, 1.0], atol=1e-15)
    np.testing.assert_allclose(sd[[0, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(sdd, 0.0, atol=1e-14)  # also 0 at tau = 1/2 (inflection)
    assert sd[1] == pytest.approx(15.0 / 8.0)
    tau = np.linspace(0, 1, 2001)
    s, sd, sdd = scaling.Quintic()(tau)
    assert np.all(np.diff(s) >= 0) and sd.max() == pytest.approx(15 / 8)
    assert np.abs(sdd).max() == pytest.approx(10 / math.sqrt(3), rel=1e-5)
    # the polynomial typed in: 10 t^3 - 15 t^4 + 6 t^5
    np.testing.assert_allclose(s, 10 * tau**3 - 15 * tau**4 + 6 * tau**5, atol=1e-15)


@pytest.mark.parametrize(
    "profile",
    [scaling.Quintic(), scaling.Trapezoid(0.25), scaling.Trapezoid(0.5), scaling.Trapezoid(0.1)],
    ids=repr,
)
def test_scaling_derivatives_match_finite_differences(profile):
    h = 1e-6
    tau = np.linspace(0.013, 0.987, 301)
    s, sd, sdd = profile(tau)
    sp, sdp, _ = profile(tau + h)
    sm, sdm, _ = profile(tau - h)
    if isinstance(profile, scaling.Trapezoid):  # sdd jumps at the blend corners: skip those
        b = profile.blend
        keep = (np.abs(tau - b) > 2 * h) & (np.abs(tau - (1 - b)) > 2 * h)
    else:
        keep = np.ones_like(tau, dtype=bool)
    np.testing.assert_allclose(sd[keep], ((sp - sm) / (2 * h))[keep], atol=1e-7)
    np.testing.assert_allclose(sdd[keep], ((sdp - sdm) / (2 * h))[keep], atol=1e-6)


@pytest.mark.parametrize("blend", [0.1, 0.25, 0.4, 0.5])
def test_trapezoid_boundary_conditions_and_plateau(blend):
    prof = scaling.Trapezoid(blend)
    s, sd, sdd = prof(np.array([0.0, 1.0]))
    np.testing.assert_allclose(s, [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(sd, [0.0, 0.0], atol=1e-15)
    assert prof(0.5)[0] == pytest.approx(0.5)
    vmax = 1.0 / (1.0 - blend)
    assert prof(0.5)[1] == pytest.approx(vmax)
    # continuity of s and s' at the blend corners
    for corner in (blend, 1 - blend):
        lo, hi = prof(corner - 1e-12), prof(corner + 1e-12)
        assert lo[0] == pytest.approx(hi[0], abs=1e-10)
        assert lo[1] == pytest.approx(hi[1], abs=1e-9)
    # accelerations +a, 0, -a
    assert prof(blend / 2)[2] == pytest.approx(vmax / blend)
    assert prof(1 - blend / 2)[2] == pytest.approx(-vmax / blend)
    if blend < 0.5:
        assert prof(0.5)[2] == 0.0


@pytest.mark.parametrize("blend", [0.0, -0.1, 0.6, float("nan")])
def test_trapezoid_rejects_bad_blend(blend):
    with pytest.raises(ValueError):
        scaling.Trapezoid(blend)
