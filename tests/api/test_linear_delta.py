"""The linear delta and the tripod (deltagen.LinearDelta, deltagen.Tripod): the compiled
cores against the independent numpy reference, round trips, finite differences, and the
published formulas of Klipper (klippy/kinematics/delta.py, klippy/mathutil.py) and of
LinuxCNC (src/emc/kinematics/tripodkins.c), rewritten here from their descriptions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import KLIPPER_LINEAR_CFG

from deltagen import GeometryError, InputError, LinearDelta, Tripod, UnreachableError
from deltagen.model.klipper import klipper_delta_from_text
from deltagen.status import INVALID, OK, SINGULAR, UNREACHABLE

# an asymmetric linear delta: every tower its own radius, angle and arm
ASYM = dict(
    radius=(0.1, 0.105, 0.097),
    arm_length=(0.25, 0.252, 0.247),
    angle=tuple(math.radians(a) for a in (211.0, 329.0, 90.5)),
)


@pytest.fixture(scope="module")
def machines():
    return {
        "linear": LinearDelta.default(),
        "asym": LinearDelta(**ASYM),  # type: ignore[arg-type]
        "tripod": Tripod.default(),
        "tripod_below": Tripod(1.2, -0.3, 0.9, side="below"),
    }


def workspace_points(name, n=400, seed=1):
    """Points inside each machine's working volume (reachable, away from singularities)."""
    rng = np.random.default_rng(seed)
    if name in ("linear", "asym"):
        r = 0.07 * np.sqrt(rng.uniform(0, 1, n))
        t = rng.uniform(0, 2 * np.pi, n)
        return np.c_[r * np.cos(t), r * np.sin(t), rng.uniform(0.0, 0.2, n)]
    sign = -1.0 if name == "tripod_below" else 1.0
    return np.c_[rng.uniform(-0.3, 1.2, (n, 2)), sign * rng.uniform(0.1, 1.2, n)]


NAMES = ("linear", "asym", "tripod", "tripod_below")


@pytest.mark.parametrize("name", NAMES)
def test_round_trips(machines, name):
    """ik(fk) and fk(ik) to 1e-12 over the working volume."""
    robot = machines[name]
    p = workspace_points(name)
    q = robot.ik(p)
    assert np.max(np.abs(robot.fk(q) - p)) < 1e-12
    assert np.max(np.abs(robot.ik(robot.fk(q)) - q)) < 1e-12


@pytest.mark.parametrize("name", NAMES)
def test_compiled_matches_reference(machines, name):
    robot = machines[name]
    ref = robot.with_backend("reference")
    p = workspace_points(name, seed=2)
    rng = np.random.default_rng(3)
    q = robot.ik(p)
    np.testing.assert_allclose(q, ref.ik(p), rtol=0, atol=1e-13)
    np.testing.assert_allclose(robot.fk(q), ref.fk(q), rtol=0, atol=1e-13)
    np.testing.assert_allclose(robot.jacobian(q), ref.jacobian(q), rtol=1e-10, atol=1e-12)
    qd, qdd = rng.normal(size=(2,) + q.shape)
    for a, b in zip(robot.fk_acc(q, qd, qdd), ref.fk_acc(q, qd, qdd)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-11)
    for a, b in zip(robot.fk_vel(q, qd), ref.fk_vel(q, qd)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-11)


@pytest.mark.parametrize("name", NAMES)
def test_jacobian_and_rates_by_finite_differences(machines, name):
    """J against central differences of fk; fk_vel = J qdot; fk_acc against the
    difference of fk_vel along q(t) = q0 + qd t + qdd t^2 / 2."""
    robot = machines[name]
    q = robot.ik(workspace_points(name, n=20, seed=4))
    eps = 1e-6
    J = robot.jacobian(q)
    for j in range(3):
        step = np.zeros(3)
        step[j] = eps
        fd = (robot.fk(q + step) - robot.fk(q - step)) / (2 * eps)
        np.testing.assert_allclose(J[:, :, j], fd, rtol=1e-6, atol=1e-7)
    rng = np.random.default_rng(5)
    qd, qdd = rng.normal(size=(2,) + q.shape) * 0.1
    p, pd = robot.fk_vel(q, qd)
    np.testing.assert_allclose(pd, np.einsum("nij,nj->ni", J, qd), rtol=1e-12, atol=1e-13)
    _, pd_plus = robot.fk_vel(q + qd * eps + qdd * eps**2 / 2, qd + qdd * eps)
    _, pd_minus = robot.fk_vel(q - qd * eps + qdd * eps**2 / 2, qd - qdd * eps)
    _, _, pdd = robot.fk_acc(q, qd, qdd)
    np.testing.assert_allclose(pdd, (pd_plus - pd_minus) / (2 * eps), rtol=1e-5, atol=1e-7)


# -- Klipper -----------------------------------------------------------------------------


def klipper_towers(radius, angles_deg):
    """Klipper's tower positions: (cos(angle) radius, sin(angle) radius) for the angles of
    stepper_a, _b, _c (default 210, 330, 90 deg; klippy/kinematics/delta.py)."""
    return [
        (math.cos(math.radians(a)) * radius, math.sin(math.radians(a)) * radius) for a in angles_deg
    ]


def klipper_stepper_heights(towers, arms, xyz):
    """Klipper's carriage height of a toolhead position: sqrt(arm^2 - dx^2 - dy^2) + z
    (klippy/kinematics/delta.py, DeltaCalibration.calc_stable_position)."""
    x, y, z = xyz
    return [math.sqrt(a**2 - (t[0] - x) ** 2 - (t[1] - y) ** 2) + z for t, a in zip(towers, arms)]


def klipper_trilateration(centres, radius2):
    """Klipper's trilateration (klippy/mathutil.py): a frame with ex along S_2 - S_1, ey
    in the centres' plane, ez = ex x ey; the point at (x, y, -sqrt(r1^2 - x^2 - y^2))."""
    c1, c2, c3 = (np.array(c, dtype=float) for c in centres)
    s21, s31 = c2 - c1, c3 - c1
    d = np.linalg.norm(s21)
    ex = s21 / d
    i = ex @ s31
    ey = s31 - i * ex
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    j = ey @ s31
    x = (radius2[0] - radius2[1] + d**2) / (2 * d)
    y = (radius2[0] - radius2[2] - x**2 + (x - i) ** 2 + j**2) / (2 * j)
    z = -math.sqrt(radius2[0] - x**2 - y**2)
    return c1 + x * ex + y * ey + z * ez


@pytest.fixture(scope="module")
def klipper(tmp_path_factory):
    path = tmp_path_factory.mktemp("klipper") / "printer.cfg"
    path.write_text(KLIPPER_LINEAR_CFG)
    return LinearDelta.from_klipper(path), klipper_delta_from_text(KLIPPER_LINEAR_CFG)


def test_klipper_mapping(klipper):
    robot, parsed = klipper
    g = robot.geometry
    towers = klipper_towers(174.75, (210.0, 330.0, 91.0))
    np.testing.assert_allclose(np.c_[g.tower_x, g.tower_y] * 1e3, towers, atol=1e-9)
    assert g.arm_length == pytest.approx((0.333, 0.333, 0.3345))
    # Klipper's abs_endstops: position_endstop + sqrt(arm^2 - radius^2)
    abs_endstops = [297.05 + math.sqrt(a**2 - 174.75**2) for a in (333.0, 333.0, 334.5)]
    np.testing.assert_allclose(np.array(parsed.endstop_carriage) * 1e3, abs_endstops, atol=1e-9)
    assert parsed.max_z == pytest.approx(0.29705)


def test_klipper_formulas(klipper):
    """ik against Klipper's carriage height formula, fk against Klipper's trilateration,
    on toolhead positions over the bed (mm in Klipper, m in deltagen)."""
    robot, _ = klipper
    towers = klipper_towers(174.75, (210.0, 330.0, 91.0))
    arms = (333.0, 333.0, 334.5)
    rng = np.random.default_rng(7)
    r = 140.0 * np.sqrt(rng.uniform(0, 1, 50))
    t = rng.uniform(0, 2 * np.pi, 50)
    xyz = np.c_[r * np.cos(t), r * np.sin(t), rng.uniform(0.0, 250.0, 50)]
    h = robot.ik(xyz * 1e-3)
    expected = np.array([klipper_stepper_heights(towers, arms, p) for p in xyz])
    np.testing.assert_allclose(h * 1e3, expected, rtol=0, atol=1e-9)
    back = np.array(
        [
            klipper_trilateration(
                [(tx, ty, hz) for (tx, ty), hz in zip(towers, row)], [a**2 for a in arms]
            )
            for row in expected
        ]
    )
    np.testing.assert_allclose(robot.fk(h) * 1e3, back, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back, xyz, atol=1e-8)


def test_klipper_errors(tmp_path):
    with pytest.raises(GeometryError, match="kinematics is 'rotary_delta'"):
        klipper_delta_from_text(
            KLIPPER_LINEAR_CFG.replace("kinematics: delta", "kinematics: rotary_delta")
        )
    with pytest.raises(GeometryError, match="delta_radius"):
        klipper_delta_from_text(KLIPPER_LINEAR_CFG.replace("delta_radius: 174.75", ""))
    with pytest.raises(GeometryError, match="exceed delta_radius"):
        klipper_delta_from_text(KLIPPER_LINEAR_CFG.replace("arm_length: 333.0", "arm_length: 100"))


# -- LinuxCNC tripodkins -----------------------------------------------------------------


def tripodkins_forward(lengths, bx, cx, cy, fflags):
    """LinuxCNC's tripodkins forward kinematics (src/emc/kinematics/tripodkins.c):
    P = AD^2, Q = BD^2 - Bx^2, R = CD^2 - Cx^2 - Cy^2, s = -2 Bx, t = -2 Cx, u = -2 Cy;
    x = (Q - P) / s, y = (R - Q - (t - s) x) / u, z = +-sqrt(P - x^2 - y^2) (fflags != 0:
    the negative root)."""
    ad, bd, cd = lengths
    P, Q, R = ad**2, bd**2 - bx**2, cd**2 - cx**2 - cy**2
    s, t, u = -2 * bx, -2 * cx, -2 * cy
    x = (Q - P) / s
    y = (R - Q - (t - s) * x) / u
    z = math.sqrt(P - x**2 - y**2)
    return np.array([x, y, -z if fflags else z])


def tripodkins_inverse(p, bx, cx, cy):
    """tripodkins' inverse: the distances from A = 0, B = (Bx, 0, 0), C = (Cx, Cy, 0)."""
    x, y, z = p
    return np.array(
        [
            math.sqrt(x**2 + y**2 + z**2),
            math.sqrt((x - bx) ** 2 + y**2 + z**2),
            math.sqrt((x - cx) ** 2 + (y - cy) ** 2 + z**2),
        ]
    )


@pytest.mark.parametrize("name", ("tripod", "tripod_below"))
def test_tripodkins_formulas(machines, name):
    robot = machines[name]
    g = robot.geometry
    p = workspace_points(name, n=50, seed=8)
    lengths = robot.ik(p)
    expected = np.array([tripodkins_inverse(row, g.b_x, g.c_x, g.c_y) for row in p])
    np.testing.assert_allclose(lengths, expected, rtol=0, atol=1e-13)
    fwd = np.array(
        [tripodkins_forward(row, g.b_x, g.c_x, g.c_y, g.side == "below") for row in lengths]
    )
    np.testing.assert_allclose(robot.fk(lengths), fwd, rtol=0, atol=1e-12)
    # tripodkins' Jacobian: row i is the unit vector from base point i to D (d l / d p),
    # the inverse of deltagen's J = d p / d l
    base = np.array(g.base_points)
    rows = (p[:, None, :] - base) / lengths[:, :, None]
    np.testing.assert_allclose(
        np.einsum("nij,njk->nik", rows, robot.jacobian(lengths)),
        np.broadcast_to(np.eye(3), rows.shape),
        atol=1e-11,
    )


def test_tripod_mirror_solutions(machines):
    """The two solutions of the same strut lengths are mirror images in the base plane;
    a point on the other side is unreachable for the chosen side."""
    robot = machines["tripod"]
    p = workspace_points("tripod", n=30, seed=9)
    lengths = robot.ik(p)
    mirrored = robot.mirror().fk(lengths)
    np.testing.assert_allclose(mirrored, p * [1, 1, -1], atol=1e-12)
    with pytest.raises(UnreachableError, match="other side"):
        robot.ik(p * [1, 1, -1])
    q, ok = robot.ik(p * [1, 1, -1], errors="nan")
    assert not ok.any() and np.isnan(q).all()


# -- status and errors ----------------------------------------------------------------


def test_statuses_and_modes(machines):
    robot = machines["linear"]
    ref = robot.with_backend("reference")
    good = np.array([0.01, -0.02, 0.1])
    h = robot.ik(good)
    rows_p = np.array([good, [1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    rows_h = np.array([h, [0.0, 0.0, 5.0], [np.inf, 0.0, 0.0]])
    for backend in (robot, ref):
        q, ok = backend.ik(rows_p, errors="nan")
        assert ok.tolist() == [True, False, False] and np.isnan(q[1:]).all()
        p, ok = backend.fk(rows_h, errors="nan")
        assert ok.tolist() == [True, False, False] and np.isnan(p[1:]).all()
        with pytest.raises(UnreachableError, match=r"rows \[1\]"):
            backend.ik(rows_p[:2])
        with pytest.raises(InputError, match="NaN or infinite"):
            backend.fk(rows_h[[0, 2]])
    # the raw statuses agree between the C core and the reference
    _, s_c = robot._core.ik(np.ascontiguousarray(rows_p))
    _, s_r = ref._core.ik(rows_p)
    assert s_c.tolist() == s_r.tolist() == [OK, UNREACHABLE, INVALID]
    _, s_c = robot._core.fk(np.ascontiguousarray(rows_h))
    _, s_r = ref._core.fk(rows_h)
    assert s_c.tolist() == s_r.tolist() == [OK, UNREACHABLE, INVALID]


@pytest.mark.parametrize("name", NAMES)
def test_statuses_agree_on_a_wide_cloud(machines, name):
    """The C core's and the reference's statuses agree row by row on points and joint
    values far beyond the working volume (reachable, unreachable, other side)."""
    robot = machines[name]
    ref = robot.with_backend("reference")
    rng = np.random.default_rng(11)
    p = rng.uniform(-1.5, 1.5, (3000, 3))
    _, s_c = robot._core.ik(p)
    _, s_r = ref._core.ik(p)
    assert np.array_equal(s_c, s_r)
    assert {OK, UNREACHABLE} <= set(s_c.tolist())
    q = rng.uniform(-0.5, 1.5, (3000, 3))
    _, s_c = robot._core.fk(q)
    _, s_r = ref._core.fk(q)
    assert np.array_equal(s_c, s_r)


def test_tripod_singular_in_the_base_plane():
    """A tripod point within singular_tol of the base plane (tripodkins: "Dz = 0 is the
    singularity"): ik and fk give it (SINGULAR but finite), the Jacobian does not exist.
    (Much closer to the plane than sqrt(eps) L the spheres barely touch and rounding may
    leave them apart: UNREACHABLE, as for the rotary delta.)"""
    tripod = Tripod(1.0, 0.5, 0.8, singular_tol=1e-4)  # the band |z| < ~1.2e-4 m
    flat = np.array([[0.4, 0.3, 1e-5]])
    lengths = tripod.ik(flat)
    np.testing.assert_allclose(tripod.fk(lengths), flat, atol=1e-9)
    _, status = tripod._core.ik(flat)
    assert status.tolist() == [SINGULAR]
    _, status = tripod._core.jacobian(np.ascontiguousarray(lengths))
    assert status.tolist() == [SINGULAR]
    with pytest.raises(Exception, match="singular"):
        tripod.jacobian(lengths)


def test_bad_geometry():
    with pytest.raises(GeometryError, match="one line"):
        LinearDelta(0.1, 0.25, angle=(0.0, math.pi, 0.0))
    with pytest.raises(GeometryError, match="arm lengths must be positive"):
        LinearDelta(0.1, (0.25, -1.0, 0.25))
    with pytest.raises(GeometryError, match="b_x must not be 0"):
        Tripod(0.0, 0.5, 0.8)
    with pytest.raises(GeometryError, match="collinear"):
        Tripod(1.0, 0.5, 0.0)
    with pytest.raises(GeometryError, match="side"):
        Tripod(1.0, 0.5, 0.8, side="up")
    with pytest.raises(InputError, match="errors must be"):
        LinearDelta.default().fk([0.1, 0.1, 0.1], errors="ignore")  # type: ignore[arg-type]


def test_batches_and_single_points(machines):
    """Leading dimensions are kept; one point through the lean path gives the batch's bits."""
    robot = machines["asym"]
    p = workspace_points("asym", n=24, seed=10).reshape(2, 3, 4, 3)
    q = robot.ik(p)
    assert q.shape == (2, 3, 4, 3)
    flat = q.reshape(-1, 3)
    assert all(np.array_equal(robot.fk(row), robot.fk(flat)[k]) for k, row in enumerate(flat))
    J = robot.jacobian(q)
    assert J.shape == (2, 3, 4, 3, 3)


def test_threads_give_the_same_bits():
    """A batch split across threads (native.parallel) gives the single-threaded bits."""
    one, two = LinearDelta(**ASYM, threads=1), LinearDelta(**ASYM, threads=2)  # type: ignore[arg-type]
    p = workspace_points("asym", n=50_000, seed=12)
    h = one.ik(p)
    assert np.array_equal(h, two.ik(p))
    assert np.array_equal(
        one.fk_acc(h, h, h, errors="nan")[2], two.fk_acc(h, h, h, errors="nan")[2]
    )
    tripods = Tripod.default(threads=1), Tripod.default(threads=2)
    lengths = tripods[0].ik(workspace_points("tripod", n=50_000, seed=13))
    assert np.array_equal(tripods[0].jacobian(lengths), tripods[1].jacobian(lengths))


@pytest.mark.parametrize("name", NAMES)
def test_inverse_rates(machines, name):
    """ik_vel and ik_acc invert fk_vel and fk_acc (round trips), and agree with the
    reference."""
    robot = machines[name]
    ref = robot.with_backend("reference")
    p = workspace_points(name, n=200, seed=14)
    rng = np.random.default_rng(15)
    pd, pdd = rng.normal(size=(2,) + p.shape)
    q, qd, qdd = robot.ik_acc(p, pd, pdd)
    for a, b in zip((q, qd, qdd), ref.ik_acc(p, pd, pdd)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(robot.ik_vel(p, pd)[1], qd)
    p2, pd2, pdd2 = robot.fk_acc(q, qd, qdd)
    np.testing.assert_allclose(p2, p, atol=1e-12)
    np.testing.assert_allclose(pd2, pd, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(pdd2, pdd, rtol=1e-8, atol=1e-9)


def test_inverse_rates_at_a_horizontal_arm():
    """A linear delta's arm lying horizontal: the carriage height exists (SINGULAR, given),
    its rate does not (NaN, not valid; SingularityError when raising)."""
    robot = LinearDelta(0.1, 0.25)
    tower = np.array([robot.geometry.tower_x[2], robot.geometry.tower_y[2]])
    p = np.array([[*(tower * (1 - 0.25 / 0.1)), 0.1]])  # 0.25 m from tower 3, through the axis
    h, ok = robot.ik(p, errors="nan")
    assert ok.all() and np.isclose(h[0, 2], 0.1)
    h, hd, ok = robot.ik_vel(p, [[0.0, 0.1, 0.0]], errors="nan")
    assert not ok.any() and np.isnan(hd).all()
    with pytest.raises(Exception, match="singular"):
        robot.ik_vel(p, [[0.0, 0.1, 0.0]])
