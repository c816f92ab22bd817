"""The public DeltaRobot API: shapes, both backends, errors="raise" / errors="nan",
UnreachableError / SingularityError, and the inverse rates ik_vel / ik_acc."""

from __future__ import annotations

import math

import numpy as np
import pytest
from delta_oracles import (
    DEFAULT,
    GEOMETRIES,
    IRREGULAR,
    elbow_terms,
    max_rel_err,
    random_p,
    random_q,
    rod_condition,
    singular_band_pose,
    stretched_chain_pose,
    well_conditioned,
    with_tol,
)
from helpers import BACKENDS, DELTA_METHODS, args_for, as_tuple, call
from hypothesis import assume, given, settings
from hypothesis import strategies as hs

from deltagen import DeltaRobot, InputError, SingularityError, UnreachableError
from deltagen.api.delta import DeltaRobot as DeltaRobotFromModule
from deltagen.errors import GeometryError
from deltagen.model.delta import DeltaGeometry

RTOL = 1e-12


@pytest.fixture(scope="module", params=BACKENDS)
def any_robot(request):
    return DeltaRobot.default(backend=request.param)


# ------------------------------------------------------------------------------ shapes


@pytest.mark.parametrize("method", list(DELTA_METHODS))
@pytest.mark.parametrize(
    "lead,width",
    [
        ((), 3),
        ((), 4),
        ((7,), 3),
        ((7,), 4),
        ((0,), 3),
        ((0,), 4),
        ((2, 5), 3),
        ((2, 5), 4),
        ((1,), 3),
        ((3, 1, 2), 4),
    ],
    ids=lambda v: str(v),
)
def test_output_shapes(any_robot, method, lead, width):
    args = args_for(method, lead, width)
    n_out = DELTA_METHODS[method][2]
    out = as_tuple(call(any_robot, method, args))
    assert len(out) == n_out
    trailing = (3, 3) if method == "jacobian" else (width,)
    for o in out:
        assert isinstance(o, np.ndarray) and o.dtype == np.float64
        assert o.shape == tuple(lead) + trailing
    nan_mode = call(any_robot, method, args, errors="nan")
    assert len(nan_mode) == n_out + 1
    valid = nan_mode[-1]
    assert valid.dtype == np.bool_ and valid.shape == tuple(lead) and valid.all()
    for a, b in zip(out, nan_mode[:-1]):
        np.testing.assert_array_equal(a, b)


def test_single_pose_values(any_robot):
    """(3,) in, (3,) out; equal to the same row of a batch."""
    q = np.array([0.1, 0.2, 0.3])
    p = any_robot.fk(q)
    batch = any_robot.fk(np.stack([q, q + 0.1]))
    assert p.shape == (3,)
    np.testing.assert_allclose(p, batch[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(any_robot.ik(p), q, rtol=0, atol=1e-13)
    assert any_robot.jacobian(q).shape == (3, 3)


def test_default_matches_constructor_and_bundled_file(repo_root):
    g = DeltaGeometry.default()
    built = DeltaRobot(r_a=0.2, r_b=0.045, l_a=0.35, l_b=0.8)  # default theta 0/120/240
    from_file = DeltaRobot.from_toml(repo_root / "robots" / "default_delta.toml")
    q = random_q(np.random.default_rng(3), 100)
    expected = DeltaRobot.default().fk(q)
    for robot in (built, from_file):
        np.testing.assert_allclose(robot.geometry.theta, g.theta, rtol=0, atol=1e-15)
        np.testing.assert_allclose(robot.fk(q), expected, rtol=0, atol=1e-15)
    assert from_file.geometry.name == "default"
    assert DeltaRobotFromModule is DeltaRobot


def test_backends_and_repr():
    robot = DeltaRobot.default()
    assert robot.backend == "compiled"
    other = robot.with_backend("reference")
    assert other.backend == "reference" and other.geometry == robot.geometry
    text = repr(robot)
    for piece in ("r_a=0.2", "r_b=0.045", "l_a=0.35", "l_b=0.8", "0, 120, 240", "compiled"):
        assert piece in text


# -------------------------------------------------- both backends agree, errors="nan"


def test_api_backends_agree_in_nan_mode(geometry, rng):
    """10^5 arbitrary crank angles and positions through the public API with
    errors="nan": identical validity masks, NaN exactly where invalid, and values equal to
    1e-12 (relative to size / magnitudes; relaxed only by the condition number)."""
    compiled = DeltaRobot.from_geometry(geometry)
    reference = compiled.with_backend("reference")
    n = 100_000
    q = rng.uniform(-math.pi, math.pi, size=(n, 3))
    qd, qdd = rng.normal(size=(2, n, 3))
    q[::997] = np.nan  # a sprinkle of invalid rows

    got = compiled.fk_acc(q, qd, qdd, errors="nan")
    want = reference.fk_acc(q, qd, qdd, errors="nan")
    np.testing.assert_array_equal(got[-1], want[-1])
    valid = want[-1]
    assert 0 < valid.sum() < n
    for g, w in zip(got[:-1], want[:-1]):
        np.testing.assert_array_equal(np.isnan(g), ~valid[:, None] & np.ones(3, bool))
        np.testing.assert_array_equal(np.isnan(w), np.isnan(g))
    kappa = rod_condition(geometry, q[valid], want[0][valid])
    factor = np.maximum(1.0, kappa / 10.0)
    J = reference.jacobian(q, errors="nan")[0][valid]
    nJ = np.linalg.norm(J, axis=(1, 2))
    quad = reference.fk_acc(q[valid], qd[valid], np.zeros_like(qd[valid]))[2]
    scales = (
        np.full(valid.sum(), geometry.size),
        nJ * np.linalg.norm(qd[valid], axis=1),
        nJ * np.linalg.norm(qdd[valid], axis=1) + np.linalg.norm(quad, axis=1),
    )
    for name, g, w, scale in zip(("p", "pd", "pdd"), got[:-1], want[:-1], scales):
        e = np.linalg.norm(g[valid] - w[valid], axis=1) / scale / factor
        assert e.max() <= RTOL, f"{name}: {e.max():.3g}"

    p_got, v_got = compiled.fk(q, errors="nan")
    p_want, v_want = reference.fk(q, errors="nan")
    np.testing.assert_array_equal(v_got, v_want)  # includes singular poses with a position
    assert v_got.sum() >= valid.sum()

    J_got, vj_got = compiled.jacobian(q, errors="nan")
    J_want, vj_want = reference.jacobian(q, errors="nan")
    np.testing.assert_array_equal(vj_got, vj_want)
    np.testing.assert_array_equal(vj_got, valid)
    assert np.all(np.isnan(J_got[~vj_got]))

    p = random_p(rng, geometry, n)
    p[5::1013] = np.inf
    q_got, vi_got = compiled.ik(p, errors="nan")
    q_want, vi_want = reference.ik(p, errors="nan")
    np.testing.assert_array_equal(vi_got, vi_want)
    np.testing.assert_array_equal(np.isnan(q_got).any(axis=1), ~vi_got)
    ok = vi_got & np.all(elbow_terms(geometry, q_want, np.nan_to_num(p)) > 1e-2, axis=1)
    np.testing.assert_allclose(q_got[ok], q_want[ok], rtol=0, atol=RTOL)


# ---------------------------------------------------------- unreachable and singular


def _unreachable_q(n_rows):
    """Crank angles the numpy reference calls unreachable (the spheres do not meet)."""
    from deltagen.reference import delta as ref

    q = np.random.default_rng(11).uniform(-math.pi, math.pi, size=(4000, 3))
    _, status = ref.fk(DEFAULT, q)
    return q[status == 1][:n_rows]


def test_fk_unreachable_rows_raise_and_are_named(any_robot):
    q = random_q(np.random.default_rng(1), 8)
    bad_rows = [2, 5]
    q[bad_rows] = _unreachable_q(2)
    for method, args in (
        ("fk", (q,)),
        ("fk_vel", (q, np.ones_like(q))),
        ("fk_acc", (q, np.ones_like(q), np.ones_like(q))),
        ("jacobian", (q,)),
    ):
        with pytest.raises(UnreachableError) as info:
            call(any_robot, method, args)
        assert isinstance(info.value, ValueError)
        np.testing.assert_array_equal(info.value.rows, bad_rows)
        assert "[2, 5]" in str(info.value) and "unreachable" in str(info.value)
        out = call(any_robot, method, args, errors="nan")
        valid = out[-1]
        np.testing.assert_array_equal(np.flatnonzero(~valid), bad_rows)
        for o in out[:-1]:
            assert np.all(np.isnan(o[bad_rows])) and np.all(np.isfinite(o[valid]))
        good = call(any_robot, method, [a[valid] for a in args])
        for o, g in zip(out[:-1], as_tuple(good)):
            np.testing.assert_allclose(o[valid], g, rtol=0, atol=1e-14)


def test_ik_unreachable_rows_raise_and_are_named(any_robot):
    p = np.tile([0.05, -0.02, -0.7], (12, 1))
    p[3] = [0.0, 0.0, -5.0]  # further from every drive axis than l_a + l_b
    p[11] = [3.0, 0.0, -0.5]
    for method, args in (
        ("ik", (p,)),
        ("ik_vel", (p, np.ones_like(p))),
        ("ik_acc", (p, np.ones_like(p), np.zeros_like(p))),
    ):
        with pytest.raises(UnreachableError) as info:
            call(any_robot, method, args)
        np.testing.assert_array_equal(info.value.rows, [3, 11])
        assert "[3, 11]" in str(info.value)
        out = call(any_robot, method, args, errors="nan")
        np.testing.assert_array_equal(np.flatnonzero(~out[-1]), [3, 11])
        for o in out[:-1]:
            assert np.all(np.isnan(o[[3, 11]])) and np.all(np.isfinite(np.delete(o, [3, 11], 0)))


def test_error_message_with_many_rows_is_bounded(default_robot):
    q = np.tile(_unreachable_q(1), (25, 1))
    with pytest.raises(UnreachableError) as info:
        default_robot.fk(q)
    assert len(info.value.rows) == 25
    message = str(info.value)
    assert "25" in message and len(message) < 300


def test_unreachable_rows_in_leading_dims_are_flat_indices(default_robot):
    q = random_q(np.random.default_rng(2), 6).reshape(2, 3, 3)
    q[1, 2] = _unreachable_q(1)[0]
    with pytest.raises(UnreachableError) as info:
        default_robot.fk(q)
    np.testing.assert_array_equal(info.value.rows, [5])  # row-major flat index of (1, 2)
    p, valid = default_robot.fk(q, errors="nan")
    assert valid.shape == (2, 3) and not valid[1, 2] and valid.sum() == 5


@pytest.mark.parametrize("backend", BACKENDS)
def test_collinear_centres_raise_singularity_error(backend):
    robot = DeltaRobot.default(backend=backend)
    a = math.acos(-DEFAULT.r / DEFAULT.l_a)  # every sphere centre on the base axis
    q = np.array([[0.1, 0.2, 0.3], [a, -a, a]])
    for method, args in (("fk", (q,)), ("jacobian", (q,)), ("fk_vel", (q, q))):
        with pytest.raises(SingularityError) as info:
            call(robot, method, args)
        assert isinstance(info.value, ValueError)
        np.testing.assert_array_equal(info.value.rows, [1])
        assert "singular" in str(info.value) and "[1]" in str(info.value)


@pytest.mark.parametrize("backend", BACKENDS)
def test_det_singular_pose_position_given_rates_refused(backend):
    """In the band |det D| / l_b^3 < singular_tol (here 1e-6) the position exists: fk
    returns it (valid); fk_vel / fk_acc / jacobian raise SingularityError."""
    geom = with_tol(DEFAULT, 1e-6)
    robot = DeltaRobot.from_geometry(geom, backend=backend)
    q_sing = singular_band_pose(geom)
    q = np.vstack([[0.2, 0.3, 0.4], q_sing, [0.5, 0.1, 0.0]])
    p = robot.fk(q)
    assert np.all(np.isfinite(p))
    p_nan, valid = robot.fk(q, errors="nan")
    assert valid.all()
    for method, args in (
        ("jacobian", (q,)),
        ("fk_vel", (q, np.ones_like(q))),
        ("fk_acc", (q, np.ones_like(q), np.ones_like(q))),
    ):
        with pytest.raises(SingularityError) as info:
            call(robot, method, args)
        np.testing.assert_array_equal(info.value.rows, [1])
        out = call(robot, method, args, errors="nan")
        np.testing.assert_array_equal(out[-1], [True, False, True])
        for o in out[:-1]:
            assert np.all(np.isnan(o[1]))


@pytest.mark.parametrize("backend", BACKENDS)
def test_ik_singular_pose_angles_given_rates_refused(backend):
    """Crank and rod of chain 1 in line: ik still returns q; ik_vel / ik_acc would need
    J^-1 and raise SingularityError naming the row."""
    geom = with_tol(DEFAULT, 1e-3)
    robot = DeltaRobot.from_geometry(geom, backend=backend)
    p = np.vstack([[0.0, 0.0, -0.7], stretched_chain_pose(geom, 2.0)])
    q = robot.ik(p)
    assert np.all(np.isfinite(q)) and abs(elbow_terms(geom, q, p)[1, 0]) < geom.singular_tol
    q_nan, valid = robot.ik(p, errors="nan")
    np.testing.assert_array_equal(valid, [True, True])
    for method, args in (
        ("ik_vel", (p, np.ones_like(p))),
        ("ik_acc", (p, np.ones_like(p), np.ones_like(p))),
    ):
        with pytest.raises(SingularityError) as info:
            call(robot, method, args)
        np.testing.assert_array_equal(info.value.rows, [1])
        out = call(robot, method, args, errors="nan")
        np.testing.assert_array_equal(out[-1], [True, False])
        for o in out[:-1]:
            assert np.all(np.isnan(o[1])) and np.all(np.isfinite(o[0]))


# ------------------------------------------------------------- inverse rates


@pytest.mark.parametrize("backend", BACKENDS)
def test_ik_vel_and_ik_acc_invert_fk_vel_and_fk_acc(geometry, backend, rng):
    robot = DeltaRobot.from_geometry(geometry, backend=backend)
    q = random_q(rng, 20_000)
    qd = rng.normal(scale=2.0, size=q.shape)
    qdd = rng.normal(scale=10.0, size=q.shape)
    p, pd, pdd = robot.fk_acc(q, qd, qdd)
    keep = well_conditioned(geometry, q, p)
    assert keep.mean() > 0.5
    q, qd, qdd, p, pd, pdd = (a[keep] for a in (q, qd, qdd, p, pd, pdd))

    q1, qd1 = robot.ik_vel(p, pd)
    q2, qd2, qdd2 = robot.ik_acc(p, pd, pdd)
    n = len(q)
    err, row = max_rel_err(q1, q, np.ones(n))
    assert err <= RTOL
    np.testing.assert_array_equal(q1, q2)
    np.testing.assert_array_equal(qd1, qd2)
    err, row = max_rel_err(qd1, qd, np.linalg.norm(qd, axis=1))
    assert err <= 1e-11, f"qd: {err:.3g}"
    scale = np.linalg.norm(qdd, axis=1) + np.linalg.norm(qd, axis=1) ** 2
    err, row = max_rel_err(qdd2, qdd, scale)
    assert err <= 1e-11, f"qdd: {err:.3g}"
    # and forwards again: J(q) qd = pd
    J = robot.jacobian(q1)
    err, _ = max_rel_err(
        np.einsum("nij,nj->ni", J, qd1),
        pd,
        np.linalg.norm(J, axis=(1, 2)) * np.linalg.norm(qd1, axis=1),
    )
    assert err <= RTOL


_ROBOTS = {
    (name, backend): DeltaRobot.from_geometry(g, backend=backend)
    for name, g in GEOMETRIES.items()
    for backend in BACKENDS
}
_angle = hs.floats(-0.6, 1.3, allow_nan=False)
_rate = hs.floats(-20.0, 20.0, allow_nan=False)
_triple = lambda s: hs.tuples(s, s, s)  # noqa: E731


@settings(max_examples=100, deadline=None)
@given(
    hs.sampled_from(sorted(_ROBOTS)),
    _triple(_angle),
    _triple(_rate),
    _triple(_rate),
    hs.floats(-1e6, 1e6),
)
def test_property_inverse_rates_round_trip(key, q, qd, qdd, phi):
    """fk_acc then ik_acc returns (q, qd, qdd); the fourth axis rides along unchanged."""
    robot = _ROBOTS[key]
    q4, qd4, qdd4 = np.array([*q, phi]), np.array([*qd, -phi]), np.array([*qdd, 2.0])
    p, pd, pdd = robot.fk_acc(q4, qd4, qdd4)
    assume(well_conditioned(robot.geometry, q4[None], p[None])[0])
    q2, qd2, qdd2 = robot.ik_acc(p, pd, pdd)
    np.testing.assert_allclose(q2, q4, rtol=0, atol=RTOL)
    scale = 1.0 + np.linalg.norm(qd) + np.linalg.norm(qdd)
    np.testing.assert_allclose(qd2, qd4, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(qdd2, qdd4, rtol=0, atol=1e-11 * scale**2)
    assert (q2[3], qd2[3], qdd2[3]) == (phi, -phi, 2.0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_inverse_rates_fourth_axis_and_broadcasting(backend):
    robot = DeltaRobot.default(backend=backend)
    q = np.array([[0.1, 0.2, 0.3, 1.5], [0.4, 0.0, -0.2, -2.0]])
    qd = np.array([0.5, -0.5, 0.25, 3.0])  # broadcast against the batch
    qdd = np.array([[1.0, 2.0, 3.0, -7.0]])
    p, pd, pdd = robot.fk_acc(q, qd, qdd)
    q2, qd2, qdd2 = robot.ik_acc(p, pd, pdd)
    assert q2.shape == qd2.shape == qdd2.shape == (2, 4)
    np.testing.assert_array_equal(q2[:, 3], q[:, 3])
    np.testing.assert_array_equal(qd2[:, 3], [3.0, 3.0])
    np.testing.assert_array_equal(qdd2[:, 3], [-7.0, -7.0])
    np.testing.assert_allclose(qd2[:, :3], np.broadcast_to(qd[:3], (2, 3)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(qdd2[:, :3], np.broadcast_to(qdd[0, :3], (2, 3)), rtol=0, atol=1e-11)
    q1, qd1 = robot.ik_vel(p[0], pd[0])  # single pose
    assert q1.shape == qd1.shape == (4,)
    np.testing.assert_allclose(qd1, qd, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_inverse_rates_non_finite_rates_are_invalid_rows(backend):
    robot = DeltaRobot.default(backend=backend)
    p = np.tile([0.02, 0.01, -0.7], (4, 1))
    pd = np.ones((4, 3))
    pdd = np.zeros((4, 3))
    pd[1, 2] = np.nan
    pdd[3, 0] = np.inf
    with pytest.raises(InputError) as info:
        robot.ik_acc(p, pd, pdd)
    assert "[1, 3]" in str(info.value)
    q, qd, qdd, valid = robot.ik_acc(p, pd, pdd, errors="nan")
    np.testing.assert_array_equal(valid, [True, False, True, False])
    for o in (q, qd, qdd):
        assert np.all(np.isnan(o[[1, 3]])) and np.all(np.isfinite(o[[0, 2]]))
    with pytest.raises(InputError):
        robot.ik_vel(p, pd)


def test_results_do_not_alias_or_modify_inputs(any_robot):
    q = random_q(np.random.default_rng(4), 10)
    q[3] = np.nan
    keep = q.copy()
    p, valid = any_robot.fk(q, errors="nan")
    np.testing.assert_array_equal(q, keep)
    p[:] = 0.0
    np.testing.assert_array_equal(q, keep)
    target = any_robot.fk(keep[valid])
    target_copy = target.copy()
    any_robot.ik_acc(target, target, target, errors="nan")
    np.testing.assert_array_equal(target, target_copy)


def test_geometry_is_validated_by_the_robot():
    with pytest.raises(GeometryError):
        DeltaRobot(r_a=0.2, r_b=0.045, l_a=-0.35, l_b=0.8)
    with pytest.raises(GeometryError):
        DeltaRobot(r_a=0.2, r_b=0.045, l_a=0.35, l_b=0.8, theta=(0, 0, 2))


def test_singular_tol_is_a_constructor_keyword():
    robot = DeltaRobot(
        r_a=IRREGULAR.r_a,
        r_b=IRREGULAR.r_b,
        l_a=IRREGULAR.l_a,
        l_b=IRREGULAR.l_b,
        theta=IRREGULAR.theta,
        singular_tol=1e-6,
    )
    assert robot.geometry.singular_tol == 1e-6
