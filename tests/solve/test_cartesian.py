"""Cartesian paths (deltagen.plan.cartesian): line and arc geometry against circle geometry
typed in here, segments in seconds, the angular velocity of a slerped segment against finite
differences, the path builder's continuity and sampling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.geometry import rotations as rot
from deltagen.plan import cartesian

# ------------------------------------------------------------------ segments in seconds


def test_segment_time_scaling_in_seconds():
    seg = cartesian.Segment(cartesian.Line([0, 0, 0], [2, 0, 0]), 4.0)
    out = seg.evaluate(np.array([0.0, 2.0, 4.0]))
    np.testing.assert_allclose(out["p"][:, 0], [0, 1, 2], atol=1e-15)
    # peak speed of the quintic: 15/8 * length / T
    assert out["v"][1, 0] == pytest.approx(15 / 8 * 2 / 4)
    np.testing.assert_allclose(out["v"][[0, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(out["a"][[0, 2]], 0.0, atol=1e-15)


# ------------------------------------------------------------------ paths


def _circle(center, normal, radius):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    return lambda ang: np.asarray(center) + radius * (math.cos(ang) * u + math.sin(ang) * w), n


@pytest.mark.parametrize("a0, a1, a2", [(0.1, 0.9, 1.7), (0.0, 2.0, 4.0), (-0.5, 2.5, 5.5)])
def test_arc_through_three_points_geometry(a0, a1, a2):
    """Points at angles a0 < a1 < a2 on a tilted circle (including sweeps above pi)."""
    c, r = np.array([0.3, -0.2, 0.7]), 0.45
    point, n = _circle(c, [0.3, -0.5, 0.8], r)
    arc = cartesian.Arc.from_three_points(point(a0), point(a1), point(a2))
    np.testing.assert_allclose(arc.center, c, atol=1e-12)
    assert arc.radius == pytest.approx(r, abs=1e-12)
    np.testing.assert_allclose(arc.axis, n, atol=1e-12)
    assert arc.angle == pytest.approx(a2 - a0, abs=1e-12)
    assert arc.length == pytest.approx(r * (a2 - a0), abs=1e-12)
    np.testing.assert_allclose(arc.start, point(a0), atol=1e-13)
    np.testing.assert_allclose(arc.end, point(a2), atol=1e-12)
    s = np.linspace(0, 1, 401)
    p, dp, ddp = arc.evaluate(s)
    # every point on the circle: distance r from the centre, in the plane
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), r, atol=1e-12)
    np.testing.assert_allclose((p - c) @ n, 0.0, atol=1e-12)
    # the via point is passed through, at s = (a1 - a0) / (a2 - a0)
    p_via = arc.evaluate(np.array([(a1 - a0) / (a2 - a0)]))[0][0]
    np.testing.assert_allclose(p_via, point(a1), atol=1e-12)
    # constant speed r * angle along s; acceleration centripetal
    np.testing.assert_allclose(np.linalg.norm(dp, axis=1), r * arc.angle, rtol=1e-12)
    np.testing.assert_allclose(ddp, -(arc.angle**2) * (p - c), atol=1e-12)
    # derivatives vs central differences
    h = 1e-6
    pp, _, _ = arc.evaluate(s + h)
    pm, _, _ = arc.evaluate(s - h)
    np.testing.assert_allclose(dp, (pp - pm) / (2 * h), atol=1e-8)


def test_arc_by_centre_axis_angle_and_direction():
    arc = cartesian.Arc([0, 0, 0.5], [1, 0, 0.5], [0, 0, 1], math.pi / 2)
    p, dp, _ = arc.evaluate(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(
        p, [[1, 0, 0.5], [math.sqrt(0.5), math.sqrt(0.5), 0.5], [0, 1, 0.5]], atol=1e-15
    )
    assert dp[0, 1] > 0  # counter-clockwise about +z
    cw = cartesian.Arc([0, 0, 0.5], [1, 0, 0.5], [0, 0, 1], -math.pi / 2)
    np.testing.assert_allclose(cw.end, [0, -1, 0.5], atol=1e-15)


def test_arc_rejects_bad_input():
    with pytest.raises(ValueError):
        cartesian.Arc([0, 0, 0], [1, 0, 0], [1, 1, 0], 1.0)  # axis not perpendicular
    with pytest.raises(ValueError):
        cartesian.Arc([0, 0, 0], [0, 0, 0], [0, 0, 1], 1.0)  # radius 0
    with pytest.raises(ValueError):
        cartesian.Arc.from_three_points([0, 0, 0], [1, 1, 1], [2, 2, 2])  # collinear


def test_line_geometry():
    line = cartesian.Line([1, 2, 3], [4, 6, 3])
    p, dp, ddp = line.evaluate(np.array([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(p, [[1, 2, 3], [1.75, 3, 3], [4, 6, 3]])
    np.testing.assert_allclose(dp, [[3, 4, 0]] * 3)
    assert not ddp.any() and line.length == 5.0


def _rand_rot(rng):
    return rot.rot_exp(rng.normal(size=3))


def test_segment_angular_velocity_matches_finite_differences(rng):
    R0, R1 = _rand_rot(rng), _rand_rot(rng)
    seg = cartesian.Segment(cartesian.Line([0, 0, 0], [1, 0, 0]), 2.0, R0=R0, R1=R1)
    t = np.linspace(0.05, 1.95, 39)
    h = 1e-5
    out, plus, minus = seg.evaluate(t), seg.evaluate(t + h), seg.evaluate(t - h)
    # w = vee(Rdot R^T); central difference of log(R(t+h) R(t-h)^T) / 2h
    w_fd = rot.rot_log(plus["R"] @ np.swapaxes(minus["R"], 1, 2)) / (2 * h)
    np.testing.assert_allclose(out["w"], w_fd, atol=1e-8)
    np.testing.assert_allclose(out["wd"], (plus["w"] - minus["w"]) / (2 * h), atol=1e-6)


# ------------------------------------------------------------------ trajectories


def test_path_builder_continuity_and_sampling():
    b = cartesian.PathBuilder([1.0, 0, 0], joints=[0.0])
    b.line([1.0, 0, 0.5], 1.0).arc_about([0, 0, 0], [0, 0, 1], math.pi / 2, 2.0, joints=[1.0])
    b.dwell(0.5).line([0, 0, 0.5], 1.5)
    traj = b.build()
    assert traj.duration == 5.0
    np.testing.assert_allclose(traj.breaks, [1.0, 3.0, 3.5])
    t = traj.sample_times(0.01)
    assert t.size == 501 and t[-1] == 5.0
    cs = traj.evaluate(t)
    # continuous position; zero velocity at every segment joint (quintic stops)
    assert np.max(np.linalg.norm(np.diff(cs.p, axis=0), axis=1)) < 0.02
    for tb in traj.breaks:
        k = int(round(tb / 0.01))
        np.testing.assert_allclose(cs.v[k], 0.0, atol=1e-12)
        np.testing.assert_allclose(cs.a[k], 0.0, atol=1e-12)
    np.testing.assert_allclose(cs.p[-1], [0, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(cs.qj[[0, -1], 0], [0.0, 1.0])
    # the arc keeps radius 1 about the z axis at z = 0.5
    arc = cs.segment == 1
    np.testing.assert_allclose(np.hypot(cs.p[arc, 0], cs.p[arc, 1]), 1.0, atol=1e-12)
    np.testing.assert_allclose(cs.p[arc, 2], 0.5, atol=1e-12)


def test_trajectory_rejects_gaps():
    with pytest.raises(ValueError, match="continuous"):
        cartesian.CartesianTrajectory(
            [
                cartesian.Segment(cartesian.Line([0, 0, 0], [1, 0, 0]), 1.0),
                cartesian.Segment(cartesian.Line([1, 0, 0.1], [1, 1, 0]), 1.0),
            ]
        )
    with pytest.raises(ValueError):
        cartesian.Segment(cartesian.Line([0, 0, 0], [1, 0, 0]), 0.0)
