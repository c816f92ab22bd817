"""Rotations: the one copy of each piece of rotation math in deltagen.

Conventions (every function, unless it says otherwise):

* Angles in radians. Rotation matrices act on column vectors (``v' = R v``); a matrix
  argument is (..., 3, 3) and every leading dimension broadcasts, so one rotation is
  (3, 3) and a batch (N, 3, 3) or (A, B, 3, 3). Vectors are (..., 3).
* ``skew(w)`` is the cross-product matrix, ``skew(w) @ v == cross(w, v)``; ``vee`` is its
  inverse (of the antisymmetric part of any matrix).
* A rotation vector ``v = theta k`` is the unit axis k times the angle theta about it,
  right-handed; ``rot_exp(v)`` is R (Rodrigues), ``rot_log(R)`` returns theta in [0, pi].
* Euler angles after Vukobratovic (lecture slide 89), ``euler_zyx``: (psi, theta, phi) with
  ``R = Rot_z(psi) Rot_y(theta) Rot_x(phi)`` -- turn about z by psi, then about the new y by
  theta, then about the newest x by phi. psi, phi in (-pi, pi], theta in [-pi/2, pi/2].
* rpy, ``rpy``: (roll, pitch, yaw) of the same matrix read as turns about the fixed base
  axes -- roll about x, then pitch about y, then yaw about z: ``R = Rot_z(yaw) Rot_y(pitch)
  Rot_x(roll)``; so (roll, pitch, yaw) = (phi, theta, psi), ``euler_zyx`` reversed. This is
  also the ``rpy`` of URDF and of the robot files (``[base] rpy``).
* Quaternions are (..., 4) = (w, x, y, z), scalar first, unit, ``q = (cos(theta/2),
  sin(theta/2) k)``; ``quat_from_matrix`` returns the sign with w >= 0.
* ``quat_slerp`` / ``slerp`` go along the shorter arc at constant angular rate in s.

Plain numpy: scipy.spatial.transform would do most of this, but not to the same last bit
(the log, Euler angles and quaternions here are the ones the rest of deltagen and the C
runtime were written and tested against), and deltagen does not otherwise need scipy.
"""

from __future__ import annotations

import math

import numpy as np

from deltagen.inputs import InputError

__all__ = [
    "skew",
    "vee",
    "rot_axis",
    "rotate",
    "rotate2d",
    "rot_exp",
    "rot_log",
    "euler_zyx",
    "matrix_from_euler_zyx",
    "rpy",
    "matrix_from_rpy",
    "quat_from_matrix",
    "matrix_from_quat",
    "quat_slerp",
    "slerp",
    "as_rotation",
    "GIMBAL_TOL",
]

# euler_zyx: below this cos(theta) the lecture's phi = atan2(a32, a33) loses its digits (its
# error grows like eps / cos(theta)); phi then comes from psi so that the angles give R back
GIMBAL_TOL = 1e-6
_EXP_SERIES = 1e-4  # rot_exp: below this angle the series (error ~ theta^4 / 120 < 1e-18)


# ------------------------------------------------------------------- skew, vee, axes


def skew(w) -> np.ndarray:
    """[w]x (..., 3, 3) of vectors w (..., 3): ``skew(w) @ v == cross(w, v)``."""
    w = np.asarray(w, dtype=float)
    if w.shape == (3,):  # one vector (Rodrigues about one axis): a literal is faster
        x, y, z = w.tolist()
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    W = np.zeros(w.shape[:-1] + (3, 3))
    W[..., 0, 1], W[..., 0, 2] = -w[..., 2], w[..., 1]
    W[..., 1, 0], W[..., 1, 2] = w[..., 2], -w[..., 0]
    W[..., 2, 0], W[..., 2, 1] = -w[..., 1], w[..., 0]
    return W


def vee(W) -> np.ndarray:
    """(..., 3) vector of the antisymmetric part (W - W^T) / 2 of matrices W (..., 3, 3);
    the inverse of :func:`skew` (exact on a skew matrix). Of a rotation matrix it is
    sin(theta) k; of dR/dt R^T, the angular velocity."""
    W = np.asarray(W, dtype=float)
    return 0.5 * np.stack(
        [W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]],
        axis=-1,
    )


_AXES = {"x": 0, "y": 1, "z": 2, 0: 0, 1: 1, 2: 2}


def rot_axis(axis, angle) -> np.ndarray:
    """Elementary rotations (..., 3, 3) by ``angle`` (...) about the coordinate axis ``axis``
    ("x", "y", "z" or 0, 1, 2): Rot_x, Rot_y, Rot_z of the lecture (slide 76)."""
    if axis not in _AXES:
        raise InputError(f"axis must be one of 'x', 'y', 'z' (or 0, 1, 2), got {axis!r}")
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    j, k = [(1, 2), (2, 0), (0, 1)][_AXES[axis]]  # right-handed cyclic pair
    M = np.zeros(angle.shape + (3, 3))
    M[..., _AXES[axis], _AXES[axis]] = 1.0
    M[..., j, j] = c
    M[..., j, k] = -s
    M[..., k, j] = s
    M[..., k, k] = c
    return M


def rotate(axis, angle, v) -> np.ndarray:
    """Vectors v (..., 3) turned by ``angle`` (...) about the unit ``axis`` (3,) or (..., 3)
    through the origin (Rodrigues): v c + (k x v) s + k (k . v)(1 - c)."""
    w = np.asarray(axis, dtype=float)
    v = np.asarray(v, dtype=float)
    th = np.asarray(angle, dtype=float)[..., None]
    c, s = np.cos(th), np.sin(th)
    if w.ndim == 1:  # one axis: two small matrix products (the closed-form IK's hot path)
        return v * c + (v @ skew(w).T) * s + np.multiply.outer(v @ w, w) * (1.0 - c)
    return v * c + np.cross(w, v) * s + w * (np.sum(w * v, axis=-1)[..., None] * (1.0 - c))


def rotate2d(angle, v) -> np.ndarray:
    """Plane vectors v (..., 2) turned by ``angle`` (...) (counter-clockwise)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


# ------------------------------------------------------------------------- exp, log


def rot_exp(v) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors v (..., 3) (Rodrigues):
    R = I + (sin t / t) [v]x + ((1 - cos t) / t^2) [v]x^2, t = |v| (series below 1e-4 rad)."""
    v = np.asarray(v, dtype=float)
    th2 = np.sum(v * v, axis=-1)
    th = np.sqrt(th2)
    small = th < _EXP_SERIES
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    W = skew(v)
    return np.eye(3) + a[..., None, None] * W + b[..., None, None] * (W @ W)


def rot_log(R) -> np.ndarray:
    """Rotation vectors (..., 3) theta k, theta in [0, pi], of rotation matrices (..., 3, 3)
    (the matrix logarithm; accurate to a few eps up to and at pi).

    theta = atan2(|v|, (tr R - 1) / 2) with v = vee(R) = sin(theta) k. For theta <= pi/2 the
    vector is v theta / |v| (v itself when |v| is tiny: exact to first order); for
    theta > pi/2 the axis comes from the symmetric part, (R + R^T)/2 = c I + (1 - c) k k^T,
    column of the largest diagonal entry, with the sign of v. At exactly pi both signs are
    right; which one comes out is then decided by rounding. The numeric-IK C runtime
    computes its pose error the same way.
    """
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise InputError(f"R must have shape (..., 3, 3), got {R.shape}")
    if R.ndim == 2:  # one matrix (an IK error in a loop): the same steps on Python floats
        v = _rot_log_one(R)
        if v is not None:
            return v
    v = vee(R)
    c = np.clip(0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0), -1.0, 1.0)
    s = np.linalg.norm(v, axis=-1)
    theta = np.arctan2(s, c)
    small = s < 1e-300
    factor = np.where(small, 1.0, theta / np.where(small, 1.0, s))
    out = v * factor[..., None]
    big = c < 0.0
    if np.any(big):
        Rb, cb, vb, tb = R[big], c[big], v[big], theta[big]
        S = 0.5 * (Rb + np.swapaxes(Rb, 1, 2)) - cb[:, None, None] * np.eye(3)
        S = S / (1.0 - cb)[:, None, None]  # = k k^T
        i = np.argmax(np.stack([S[:, 0, 0], S[:, 1, 1], S[:, 2, 2]], axis=-1), axis=-1)
        a = S[np.arange(len(i)), :, i]
        a = a / np.linalg.norm(a, axis=-1, keepdims=True)
        sign = np.where(np.einsum("ij,ij->i", a, vb) < 0.0, -1.0, 1.0)
        out[big] = a * (sign * tb)[:, None]
    return out


def _rot_log_one(R):
    """rot_log of one matrix with theta <= pi/2 by the same operations on Python floats
    (a tenth of the time of the array path); None where theta > pi/2. Not bit for bit the
    array path's: math.atan2 is the C library's and np.arctan2 may be numpy's own SIMD
    routine (on AVX-512 CPUs the two differ by an ulp), so the results agree to a few ulp."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
    c = min(max(0.5 * (r00 + r11 + r22 - 1.0), -1.0), 1.0)
    if not c >= 0.0:  # also NaN: the array path
        return None
    v0, v1, v2 = 0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)
    s = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    factor = 1.0 if s < 1e-300 else math.atan2(s, c) / s
    return np.array([v0 * factor, v1 * factor, v2 * factor])


# ---------------------------------------------------------------- Euler angles, rpy


def euler_zyx(R) -> np.ndarray:
    """(..., 3, 3) -> (..., 3) angles (psi, theta, phi) after Vukobratovic (lecture
    slide 89), R = Rot_z(psi) Rot_y(theta) Rot_x(phi)::

        psi   = atan2(a21, a11)
        theta = atan2(-a31, a11 cos psi + a21 sin psi)
        phi   = atan2(a32, a33)

    Gimbal lock (theta = +-pi/2, a11 = a21 = 0): only psi - phi (theta = pi/2) or psi + phi
    (theta = -pi/2) is defined, and a32 = a33 = 0 too, so the printed phi is noise. Where
    cos(theta) < GIMBAL_TOL, phi = atan2(a13 sin psi - a23 cos psi, a22 cos psi - a12 sin
    psi) instead (Paul; equal to the printed phi wherever both are defined): the angles
    then give R back, with psi what atan2(a21, a11) makes of the rounding (0 when both are
    exactly 0).
    """
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise InputError(f"R must have shape (..., 3, 3), got {R.shape}")
    a11, a21, a31 = R[..., 0, 0], R[..., 1, 0], R[..., 2, 0]
    a32, a33 = R[..., 2, 1], R[..., 2, 2]
    psi = np.arctan2(a21, a11)
    cp, sp = np.cos(psi), np.sin(psi)
    ct = a11 * cp + a21 * sp  # = cos(theta) >= 0
    theta = np.arctan2(-a31, ct)
    phi = np.arctan2(a32, a33)
    lock = ct < GIMBAL_TOL
    if np.any(lock):
        phi_lock = np.arctan2(
            R[..., 0, 2] * sp - R[..., 1, 2] * cp, R[..., 1, 1] * cp - R[..., 0, 1] * sp
        )
        phi = np.where(lock, phi_lock, phi)
    return np.stack([psi, theta, phi], axis=-1)


def matrix_from_euler_zyx(angles) -> np.ndarray:
    """(..., 3) angles (psi, theta, phi) -> (..., 3, 3) Rot_z(psi) Rot_y(theta) Rot_x(phi)."""
    angles = np.asarray(angles, dtype=float)
    return matrix_from_rpy(angles[..., ::-1])


def xyz_angles(R) -> tuple[float, float, float]:
    """(rx, ry, rz) with R = Rot_x(rx) Rot_y(ry) Rot_z(rz) for one rotation matrix (the
    fixed part of a universal-coordinate joint, model/serial.py); at cos ry = 0 the angle rz
    is set to 0."""
    ry = math.atan2(R[0, 2], math.hypot(R[0, 0], R[0, 1]))
    if math.hypot(R[0, 0], R[0, 1]) < 1e-12:  # cos ry = 0: rz = 0, rx from the rest
        return math.atan2(R[2, 1], R[1, 1]), ry, 0.0
    return math.atan2(-R[1, 2], R[2, 2]), ry, math.atan2(-R[0, 1], R[0, 0])


def rpy(R) -> np.ndarray:
    """(..., 3, 3) -> (..., 3) (roll, pitch, yaw) with R = Rot_z(yaw) Rot_y(pitch) Rot_x(roll),
    i.e. :func:`euler_zyx` reversed."""
    return euler_zyx(R)[..., ::-1].copy()


def matrix_from_rpy(rpy_angles) -> np.ndarray:
    """(..., 3) (roll, pitch, yaw) -> (..., 3, 3) Rot_z(yaw) Rot_y(pitch) Rot_x(roll)."""
    a = np.asarray(rpy_angles, dtype=float)
    if a.shape[-1:] != (3,):
        raise InputError(f"rpy must have shape (..., 3), got {a.shape}")
    roll, pitch, yaw = a[..., 0], a[..., 1], a[..., 2]
    cr, sr, cp, sp_, cy, sy = (
        np.cos(roll),
        np.sin(roll),
        np.cos(pitch),
        np.sin(pitch),
        np.cos(yaw),
        np.sin(yaw),
    )
    R = np.empty(a.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp_ * sr - sy * cr
    R[..., 0, 2] = cy * sp_ * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp_ * sr + cy * cr
    R[..., 1, 2] = sy * sp_ * cr - cy * sr
    R[..., 2, 0] = -sp_
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


# ---------------------------------------------------------------------- quaternions


def quat_from_matrix(R) -> np.ndarray:
    """Unit quaternions (..., 4) = (w, x, y, z) with w >= 0 of rotation matrices (..., 3, 3)
    (Shepperd's method: the largest of the four candidates is computed from the trace or a
    diagonal element, the others from off-diagonal sums, so no cancellation near 180 deg)."""
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    r21, r12 = R[..., 2, 1], R[..., 1, 2]
    r02, r20 = R[..., 0, 2], R[..., 2, 0]
    r10, r01 = R[..., 1, 0], R[..., 0, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        # k = 0: w largest
        s0 = 2.0 * np.sqrt(np.maximum(1.0 + tr, 0.0))
        q0 = np.stack([s0 / 4, (r21 - r12) / s0, (r02 - r20) / s0, (r10 - r01) / s0], axis=-1)
        s1 = 2.0 * np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 0.0))
        q1 = np.stack([(r21 - r12) / s1, s1 / 4, (r01 + r10) / s1, (r02 + r20) / s1], axis=-1)
        s2 = 2.0 * np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 0.0))
        q2 = np.stack([(r02 - r20) / s2, (r01 + r10) / s2, s2 / 4, (r12 + r21) / s2], axis=-1)
        s3 = 2.0 * np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 0.0))
        q3 = np.stack([(r10 - r01) / s3, (r02 + r20) / s3, (r12 + r21) / s3, s3 / 4], axis=-1)
    for idx, cand_q in enumerate((q0, q1, q2, q3)):
        sel = k == idx
        q[sel] = cand_q[sel]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def matrix_from_quat(q) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) = (w, x, y, z) (normalised first)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


# --------------------------------------------------------------------------- slerp


def quat_slerp(q0, q1, s) -> np.ndarray:
    """Spherical linear interpolation of quaternions (..., 4) (normalised first) along the
    shorter arc (q1 or -q1, whichever is nearer q0): q(0) = q0, q(1) = +-q1, constant
    angular rate in s. q0, q1 (..., 4) and s (...) broadcast; -> (..., 4). Nearly equal
    ends (cos of the half-angle above 1 - 1e-12) are interpolated linearly and normalised."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    q0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    d = np.sum(q0 * q1, axis=-1)[..., None]
    q1 = np.where(d < 0.0, -q1, q1)
    d = np.abs(d)
    s = np.asarray(s, dtype=float)[..., None]
    near = d > 1.0 - 1e-12
    lin = q0 + s * (q1 - q0)
    lin = lin / np.linalg.norm(lin, axis=-1, keepdims=True)
    om = np.arccos(np.minimum(d, 1.0))
    sin_om = np.sin(np.where(near, 1.0, om))
    arc = (np.sin((1.0 - s) * om) * q0 + np.sin(s * om) * q1) / sin_om
    return np.where(near, lin, arc)


def slerp(R0, R1, s) -> np.ndarray:
    """R(s) = R0 exp(s log(R0^T R1)): the shortest rotation from R0 to R1 at constant angular
    velocity about a fixed axis. R0, R1 rotation matrices (..., 3, 3) (or poses (..., 4, 4):
    their rotation blocks), s (...), all broadcast; -> (..., 3, 3). Raises InputError for a
    matrix that is not a rotation."""
    R0, R1 = as_rotation(R0, "R0"), as_rotation(R1, "R1")
    k = rot_log(np.swapaxes(R0, -1, -2) @ R1)
    s = np.asarray(s, dtype=float)
    return R0 @ rot_exp(s[..., None] * k)


def as_rotation(R, name="R") -> np.ndarray:
    """R (..., 3, 3), or the rotation block of poses (..., 4, 4), as float, checked: finite,
    R R^T = I to 1e-8 and det R > 0; InputError naming ``name`` otherwise."""
    R = np.asarray(R, dtype=float)
    if R.ndim >= 2 and R.shape[-2:] == (4, 4):
        R = R[..., :3, :3]
    if R.ndim < 2 or R.shape[-2:] != (3, 3) or not np.all(np.isfinite(R)):
        raise InputError(f"{name} must be a 3x3 rotation matrix (or a 4x4 pose)")
    if not np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-8) or np.any(
        np.linalg.det(R) < 0
    ):
        raise InputError(f"{name} is not a rotation matrix (R R^T != I or det R < 0)")
    return R
