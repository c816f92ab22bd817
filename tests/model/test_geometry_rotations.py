"""deltagen.geometry.rotations against independent formulas typed in here: the matrix
exponential by its power series, rotations of vectors by quaternion (Hamilton) products,
Euler matrices as products of the lecture's elementary rotations, the rotation axis as the
eigenvector of eigenvalue 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from deltagen.geometry import rotations as rot
from deltagen.inputs import InputError

PI = math.pi


# ------------------------------------------------------------ independent formulas


def _series_exp(v):
    """exp([v]x) by its power series (|v| <= pi: 60 terms are far past convergence)."""
    W = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    out, term = np.eye(3), np.eye(3)
    for k in range(1, 60):
        term = term @ W / k
        out = out + term
    return out


def _hamilton(p, q):
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def _quat_rotate(q, v):
    """v turned by the unit quaternion q: the vector part of q (0, v) q*."""
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return _hamilton(_hamilton(q, np.r_[0.0, v]), conj)[1:]


def _axis_angle_quat(k, theta):
    return np.r_[math.cos(theta / 2), math.sin(theta / 2) * np.asarray(k)]


def _Rz(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def _Ry(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _Rx(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _random_rotations(rng, n):
    return rot.matrix_from_quat(rng.normal(size=(n, 4)))


def _angle_between(Ra, Rb):
    return np.linalg.norm(rot.rot_log(Ra @ np.swapaxes(Rb, -1, -2)), axis=-1)


# ------------------------------------------------------------------ strategies

_unit_axis = (
    hs.tuples(*[hs.floats(-1, 1)] * 3)
    .map(np.array)
    .filter(lambda a: np.linalg.norm(a) > 0.1)
    .map(lambda a: a / np.linalg.norm(a))
)
# generic angles, angles near 0 and angles near pi (down to 1e-12 from either end)
_angle = hs.one_of(
    hs.floats(0.0, PI),
    hs.floats(-12.0, -1.0).map(lambda e: 10.0**e),
    hs.floats(-12.0, -1.0).map(lambda e: PI - 10.0**e),
    hs.just(0.0),
    hs.just(PI),
)


# --------------------------------------------------------------- skew, vee, axes


def test_skew_is_the_cross_product_and_vee_its_inverse(rng):
    w, v = rng.normal(size=(2, 50, 3))
    W = rot.skew(w)
    np.testing.assert_allclose((W @ v[..., None])[..., 0], np.cross(w, v), atol=1e-15)
    np.testing.assert_array_equal(rot.vee(W), w)  # exact on a skew matrix
    np.testing.assert_array_equal(W, -np.swapaxes(W, -1, -2))
    assert rot.skew(w.reshape(5, 10, 3)).shape == (5, 10, 3, 3)
    # vee of a rotation is sin(theta) k
    k = w / np.linalg.norm(w, axis=-1, keepdims=True)
    th = rng.uniform(0, PI, 50)
    np.testing.assert_allclose(
        rot.vee(rot.rot_exp(k * th[:, None])), k * np.sin(th)[:, None], atol=1e-15
    )


def test_elementary_rotations_are_the_lecture_matrices():
    for a in (-2.0, 0.3, PI):
        np.testing.assert_allclose(rot.rot_axis("x", a), _Rx(a), atol=0)
        np.testing.assert_allclose(rot.rot_axis("y", a), _Ry(a), atol=0)
        np.testing.assert_allclose(rot.rot_axis(2, a), _Rz(a), atol=0)
    assert rot.rot_axis("z", np.zeros((4, 5))).shape == (4, 5, 3, 3)
    with pytest.raises(InputError):
        rot.rot_axis("w", 0.1)


def test_rotate_vectors_rodrigues(rng):
    k = rng.normal(size=(30, 3))
    k /= np.linalg.norm(k, axis=-1, keepdims=True)
    th = rng.uniform(-4, 4, 30)
    v = rng.normal(size=(30, 3))
    expect = np.array([_quat_rotate(_axis_angle_quat(k[i], th[i]), v[i]) for i in range(30)])
    np.testing.assert_allclose(rot.rotate(k, th, v), expect, atol=1e-14)  # batched axes
    for i in range(3):  # one axis, a batch of angles and vectors
        np.testing.assert_allclose(
            rot.rotate(k[i], th, v),
            (rot.rot_exp(k[i] * th[:, None]) @ v[..., None])[..., 0],
            atol=1e-14,
        )
    # plane: 90 deg turns x into y
    np.testing.assert_allclose(rot.rotate2d(PI / 2, np.array([1.0, 0.0])), [0.0, 1.0], atol=1e-16)
    a = rng.uniform(-4, 4, 20)
    p = rng.normal(size=(20, 2))
    expect = np.stack([(_Rz(a[i]) @ np.r_[p[i], 0.0])[:2] for i in range(20)])
    np.testing.assert_allclose(rot.rotate2d(a, p), expect, atol=1e-15)


# ---------------------------------------------------------------------- exp, log


@settings(max_examples=300)
@given(_unit_axis, _angle)
def test_exp_log_round_trip(k, theta):
    v = k * theta
    R = rot.rot_exp(v)
    np.testing.assert_allclose(R, _series_exp(v), atol=4e-15)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    w = rot.rot_log(R)
    assert np.linalg.norm(w) <= PI + 4e-15  # |w| = theta, rounded
    # exp(log(R)) = R everywhere (at pi both signs of the axis are right) ...
    np.testing.assert_allclose(rot.rot_exp(w), R, atol=4e-15)
    # ... and log(exp(v)) = v up to pi: the axis' sign is lost only within ~eps of pi
    assert abs(np.linalg.norm(w) - theta) < 4e-15
    if theta < PI - 1e-7:
        np.testing.assert_allclose(w, v, rtol=1e-13, atol=1e-15)


def test_log_axis_is_the_eigenvector_of_eigenvalue_one(rng):
    R = _random_rotations(rng, 200)
    w = rot.rot_log(R)
    for Ri, wi in zip(R, w):
        vals, vecs = np.linalg.eig(Ri)
        axis = np.real(vecs[:, np.argmin(np.abs(vals - 1.0))])
        cos_t = (np.trace(Ri) - 1.0) / 2.0
        assert abs(abs(axis @ wi) - np.linalg.norm(wi)) < 1e-12
        assert abs(math.cos(np.linalg.norm(wi)) - cos_t) < 1e-13


def test_log_of_exact_half_turns_and_identity():
    for k in np.r_[np.eye(3), [[0.6, 0.8, 0.0], [0.0, -0.6, 0.8]]]:
        w = rot.rot_log(2.0 * np.outer(k, k) - np.eye(3))  # a half turn about k
        np.testing.assert_allclose(np.abs(w), PI * np.abs(k), atol=1e-15)
    np.testing.assert_array_equal(rot.rot_log(np.eye(3)), np.zeros(3))


def test_exp_log_broadcast_and_the_single_matrix_agrees_with_the_batch(rng):
    v = rng.normal(size=(4, 5, 3)) * np.geomspace(1e-9, 1.0, 5)[:, None]  # small and large
    R = rot.rot_exp(v)
    assert R.shape == (4, 5, 3, 3)
    w = rot.rot_log(R)
    assert w.shape == (4, 5, 3)
    for idx in np.ndindex(4, 5):  # one matrix (its own fast path below pi/2): the same
        # formula, within a few ulp: math.atan2 is the C library's, np.arctan2 may be
        # numpy's own SIMD routine (AVX-512 CPUs: 1 ulp apart), so no bit-for-bit claim
        np.testing.assert_array_max_ulp(rot.rot_log(R[idx]), w[idx], maxulp=4)
        np.testing.assert_array_equal(rot.skew(v[idx]), rot.skew(v)[idx])
    with pytest.raises(InputError):
        rot.rot_log(np.eye(4))


# ------------------------------------------------------------------- Euler, rpy


def test_euler_zyx_round_trip_and_definition(rng):
    ang = np.column_stack(
        [rng.uniform(-PI, PI, 300), rng.uniform(-1.55, 1.55, 300), rng.uniform(-PI, PI, 300)]
    )
    R = rot.matrix_from_euler_zyx(ang)
    expect = np.array([_Rz(p) @ _Ry(t) @ _Rx(f) for p, t, f in ang])
    np.testing.assert_allclose(R, expect, atol=1e-15)
    np.testing.assert_allclose(rot.euler_zyx(R), ang, atol=1e-13)
    np.testing.assert_allclose(rot.rpy(R), ang[:, ::-1], atol=1e-13)
    np.testing.assert_array_equal(rot.matrix_from_rpy(ang[:, ::-1]), R)
    # the lecture's worked example (slide 95): a 60 deg turn about z
    c = math.sqrt(3) / 2  # the slide prints 0.866
    T2 = np.array([[0.5, -c, 0], [c, 0.5, 0], [0, 0, 1.0]])
    np.testing.assert_allclose(np.degrees(rot.euler_zyx(T2)), [60.0, 0.0, 0.0], atol=1e-12)
    # rpy reads as turns about the fixed axes: roll about x first
    np.testing.assert_allclose(rot.matrix_from_rpy([0.4, 0, 0]), _Rx(0.4), atol=0)
    np.testing.assert_allclose(rot.matrix_from_rpy([0.4, 0.2, 0]), _Ry(0.2) @ _Rx(0.4), atol=1e-16)
    assert rot.euler_zyx(R.reshape(10, 30, 3, 3)).shape == (10, 30, 3)
    with pytest.raises(InputError):
        rot.euler_zyx(np.eye(4))


@settings(max_examples=200)
@given(
    hs.floats(-PI, PI),
    hs.sampled_from([-1.0, 1.0]),
    hs.floats(-PI, PI),
    hs.one_of(hs.just(0.0), hs.floats(-16.0, -5.0).map(lambda e: 10.0**e)),
)
def test_euler_zyx_at_and_near_gimbal_lock_gives_the_rotation_back(psi, sign, phi, gap):
    """theta = +-pi/2 (or within 1e-5 of it): psi and phi are not separately defined, but
    the angles returned give the matrix back, and theta is right."""
    theta = sign * (PI / 2 - gap)
    R = _Rz(psi) @ _Ry(theta) @ _Rx(phi)
    ang = rot.euler_zyx(R)
    assert abs(ang[1] - theta) < 1e-7 + 1e-3 * gap  # theta from atan2(-a31, ~0): ok
    np.testing.assert_allclose(rot.matrix_from_euler_zyx(ang), R, atol=4e-15)


def test_euler_zyx_exact_gimbal_lock_convention():
    # a11 = a21 = 0 exactly: psi = atan2(0, 0) = 0 and phi carries the whole turn
    for theta in (PI / 2, -PI / 2):
        for turn in (-2.0, 0.0, 0.7, 3.0):
            R = np.round(_Ry(theta), 15) @ _Rx(turn)
            R[np.abs(R) < 1e-15] = 0.0
            psi, th, phi = rot.euler_zyx(R)
            assert psi == 0.0 and th == theta
            assert abs(math.remainder(phi - turn, 2 * PI)) < 1e-15


# ---------------------------------------------------------------------- quaternions


def test_quaternion_sign_convention_and_round_trips(rng):
    R = _random_rotations(rng, 500)
    q = rot.quat_from_matrix(R)
    assert np.all(q[:, 0] >= 0.0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rot.matrix_from_quat(q), R, atol=1e-15)
    # q and -q are one rotation; from_matrix picks w >= 0
    q2 = rng.normal(size=(500, 4))
    q2 /= np.linalg.norm(q2, axis=-1, keepdims=True)
    canon = np.where(q2[:, :1] < 0, -q2, q2)
    np.testing.assert_allclose(rot.quat_from_matrix(rot.matrix_from_quat(-q2)), canon, atol=1e-15)
    # independent: the quaternion turns vectors as the matrix does (Hamilton products)
    v = rng.normal(size=(500, 3))
    turned = np.array([_quat_rotate(qi, vi) for qi, vi in zip(q, v)])
    np.testing.assert_allclose(turned, (R @ v[..., None])[..., 0], atol=1e-14)
    # composition: q(R1 R2) = q1 q2 up to sign
    prod = np.array([_hamilton(a, b) for a, b in zip(q[:-1], q[1:])])
    prod = np.where(prod[:, :1] < 0, -prod, prod)
    np.testing.assert_allclose(rot.quat_from_matrix(R[:-1] @ R[1:]), prod, atol=1e-15)


@settings(max_examples=200)
@given(_unit_axis, _angle)
def test_quaternion_of_axis_angle_incl_near_half_turn(k, theta):
    q = rot.quat_from_matrix(rot.rot_exp(k * theta))
    expect = _axis_angle_quat(k, theta)
    if theta > PI - 1e-7:  # w ~ 0: the sign of the vector part is the log's
        expect = expect * np.sign(q[1:] @ expect[1:])
    np.testing.assert_allclose(q, expect, atol=2e-15)
    assert q[0] >= 0.0


# ------------------------------------------------------------------------ slerp


def test_slerp_endpoints_constant_rate_and_shorter_arc(rng):
    R0, R1 = _random_rotations(rng, 2)
    s = np.linspace(0.0, 1.0, 21)
    Rs = rot.slerp(R0, R1, s)
    np.testing.assert_allclose(Rs[0], R0, atol=1e-15)
    np.testing.assert_allclose(Rs[-1], R1, atol=1e-14)
    total = _angle_between(R1, R0)
    assert total <= PI
    np.testing.assert_allclose(_angle_between(Rs[1:], Rs[:-1]), total / 20, atol=1e-14)
    np.testing.assert_allclose(_angle_between(Rs, R0), s * total, atol=1e-14)
    # the quaternion form agrees, whichever sign the ends are given in
    q0, q1 = rot.quat_from_matrix(R0), rot.quat_from_matrix(R1)
    for a, b in ((q0, q1), (q0, -q1), (-q0, q1)):
        qs = rot.quat_slerp(a, b, s)
        np.testing.assert_allclose(rot.matrix_from_quat(qs), Rs, atol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(qs, axis=-1), 1.0, atol=1e-15)
        np.testing.assert_allclose(qs[0], a / np.linalg.norm(a), atol=1e-15)
    # shorter arc: a 350 deg turn about z is a -10 deg turn
    Rz = rot.slerp(np.eye(3), _Rz(np.radians(350)), np.array([0.5]))[0]
    np.testing.assert_allclose(Rz, _Rz(np.radians(-5)), atol=1e-15)


def test_slerp_batched_and_nearly_equal_ends(rng):
    R0, R1 = _random_rotations(rng, 20), _random_rotations(rng, 20)
    s = rng.uniform(0, 1, 20)
    batch = rot.slerp(R0, R1, s)
    for i in range(20):
        np.testing.assert_allclose(batch[i], rot.slerp(R0[i], R1[i], s[i]), atol=1e-15)
    q = rot.quat_slerp(rot.quat_from_matrix(R0), rot.quat_from_matrix(R1), s)
    np.testing.assert_allclose(rot.matrix_from_quat(q), batch, atol=1e-14)
    # ends 1e-9 rad apart: finite, unit, on the way
    Rn = R0[0] @ rot.rot_exp([1e-9, 0, 0])
    q = rot.quat_slerp(rot.quat_from_matrix(R0[0]), rot.quat_from_matrix(Rn), [0.0, 0.5, 1.0])
    assert np.all(np.isfinite(q))
    np.testing.assert_allclose(
        _angle_between(rot.matrix_from_quat(q), R0[0]), [0.0, 5e-10, 1e-9], atol=1e-15
    )
    with pytest.raises(InputError):
        rot.slerp(np.eye(3), 2 * np.eye(3), 0.5)
    with pytest.raises(InputError):
        rot.slerp(np.diag([1.0, 1.0, -1.0]), np.eye(3), 0.5)


def test_public_names_elsewhere_are_the_geometry_ones():
    from deltagen.api import serial as api_serial
    from deltagen.plan import trajectory
    from deltagen.reference import serial as reference
    from deltagen.solve import numeric

    assert api_serial.euler_zyx is rot.euler_zyx
    assert reference.euler_zyx is rot.euler_zyx and reference.rpy is rot.rpy
    assert numeric.rotation_vector is rot.rot_log
    for name in (
        "skew",
        "rot_exp",
        "rot_log",
        "quat_from_matrix",
        "matrix_from_quat",
        "quat_slerp",
        "slerp",
    ):
        assert getattr(trajectory, name) is getattr(rot, name)


# ------------------------------------------------------------------ exp / log, quaternions, slerp


def _rand_rot(rng):
    return rot.rot_exp(rng.normal(size=3))


def test_rot_exp_log_roundtrip_including_small_and_near_pi(rng):
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.r_[
        np.geomspace(1e-12, 1e-3, 10),
        rng.uniform(0, math.pi, 20),
        math.pi - np.geomspace(1e-3, 1e-9, 10),
    ]
    v = axes * angles[:, None]
    R = rot.rot_exp(v)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14
    )
    np.testing.assert_allclose(rot.rot_log(R), v, atol=2e-8)  # near pi: sqrt(eps)-limited sign
    np.testing.assert_allclose(rot.rot_log(R[:30]), v[:30], atol=1e-13)
    for k in range(40):  # the single-matrix path agrees with the batch path
        np.testing.assert_allclose(rot.rot_log(R[k]), rot.rot_log(R[k : k + 1])[0], atol=1e-12)
    # Rodrigues typed in for one case: 90 deg about z
    np.testing.assert_allclose(
        rot.rot_exp([0, 0, math.pi / 2]), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15
    )


def test_quaternion_roundtrip(rng):
    R = np.stack([_rand_rot(rng) for _ in range(50)])
    q = rot.quat_from_matrix(R)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(rot.matrix_from_quat(q), R, atol=1e-14)
    # 180 deg about x: (w, x, y, z) = (0, 1, 0, 0)
    np.testing.assert_allclose(
        np.abs(rot.quat_from_matrix(np.diag([1.0, -1, -1]))), [0, 1, 0, 0], atol=1e-15
    )


def test_slerp_endpoints_agrees_with_quaternion_slerp_and_constant_rate(rng):
    for _ in range(10):
        R0, R1 = _rand_rot(rng), _rand_rot(rng)
        s = np.linspace(0, 1, 11)
        Rs = rot.slerp(R0, R1, s)
        np.testing.assert_allclose(Rs[0], R0, atol=1e-14)
        np.testing.assert_allclose(Rs[-1], R1, atol=1e-12)
        qs = rot.quat_slerp(rot.quat_from_matrix(R0), rot.quat_from_matrix(R1), s)
        np.testing.assert_allclose(rot.matrix_from_quat(qs), Rs, atol=1e-12)
        # equal angles between consecutive samples (constant angular velocity)
        steps = np.linalg.norm(rot.rot_log(Rs[1:] @ np.swapaxes(Rs[:-1], 1, 2)), axis=1)
        total = np.linalg.norm(rot.rot_log(R1 @ R0.T))
        np.testing.assert_allclose(steps, total / 10, atol=1e-12)
