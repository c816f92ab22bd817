"""Independent pure-numpy reference kinematics of serial arms.

This module shares nothing with the SymPy derivation or the generated C core. Its link
transforms are the model's numeric definition (:func:`deltagen.model.serial.link_transform`,
one copy, which structure detection uses too): a plain product of elementary 4x4 matrices
(batched over N poses with numpy), multiplied along the chain:

* ``standard`` DH (lecture slides 80-84, EASY-ROB paper eq. (2)):
  ``A_i = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)``;
* ``modified`` DH (Craig): ``A_i = Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i)
  Trans_z(d_i)``, a row's ``a`` / ``alpha`` being those of the link before the joint;
* ``universal`` coordinates (EASY-ROB paper eq. (3)):
  ``D_i = Rot_i(q_i) Trans_x(tx) Trans_y(ty) Trans_z(tz) Rot_x(rx) Rot_y(ry) Rot_z(rz)``
  with ``Rot_i`` the joint's rotation about (revolute) or translation along (prismatic)
  its ``axis``.

The joint variable enters as ``sign_i q_i + offset_i`` (sign -1 for a reversed joint, whose
motion axis is then minus the frame's column; revolute: theta / the axis rotation;
prismatic: d / the translation along the axis) and ``T = base A_1 ... A_n tool``.

Velocities use the geometric construction: every joint axis (unit direction ``w_i`` and,
for a revolute joint, a point ``o_i`` on it) is fixed in the link before the joint (see
:func:`joint_axes`), so the tool-point Jacobian
column is ``[w_i x (p_e - o_i); w_i]`` (revolute) or ``[w_i; 0]`` (prismatic). Its time
derivative follows from differentiating these column formulas with the angular velocity
``Omega_{i-1}`` of the link that carries axis i and the velocity of the point ``o_i``:

* ``dw_i/dt = Omega_{i-1} x w_i`` with ``Omega_{i-1} = sum_{j<i, revolute} w_j qd_j``;
* ``do_i/dt = sum_{j<i} (revolute: w_j x (o_i - o_j), prismatic: w_j) qd_j``;
* ``dp_e/dt = J_v qd``.

In the tool frame, ``J_tool = R^T J`` (both halves) and, with ``omega_e`` the tool's
angular velocity, ``dJ_tool/dt = R^T (dJ/dt - omega_e x J)`` (both halves).

Status (int8, :mod:`deltagen.status`): INVALID for rows with any non-finite input value,
and for rows whose outputs are not all finite (finite but huge inputs that overflow, e.g. a
prismatic q of 1e300 with rates of 1e200; the finite-output rule of the generated C); their
outputs are NaN. OK otherwise.
"""

from __future__ import annotations

import functools

import numpy as np

from deltagen.geometry.rotations import euler_zyx, rpy  # noqa: F401 (public here)
from deltagen.inputs import InputError, as_float_array
from deltagen.model.serial import frames as model_frames
from deltagen.model.serial import link_transform
from deltagen.status import INVALID, MASS_MATRIX_TOL, OK, SINGULAR

__all__ = [
    "link_transforms",
    "frames",
    "fk",
    "joint_axes",
    "jacobian",
    "jacobian_dot",
    "euler_zyx",
    "rpy",
    "mass_matrix",
    "gravity_torque",
    "coriolis",
    "nonlinear_effects",
    "inverse_dynamics",
    "forward_dynamics",
]

_AXIS = {"x": 0, "y": 1, "z": 2}


# ------------------------------------------------------------------------ input helpers


def _check_q(desc, q, name="q") -> np.ndarray:
    arr = as_float_array(q, name)
    if arr.ndim != 2 or arr.shape[1] != desc.n:
        raise InputError(f"{name} must have shape (N, {desc.n}) for this arm, got {arr.shape}")
    return arr


def _split_invalid(*arrays):
    """(bad rows mask, sanitised copies with bad rows zeroed)."""
    N = arrays[0].shape[0]
    bad = np.zeros(N, dtype=bool)
    for a in arrays:
        bad |= ~np.all(np.isfinite(a), axis=1)
    clean = []
    for a in arrays:
        c = np.array(a, dtype=np.float64, copy=True)
        c[bad] = 0.0
        clean.append(c)
    return bad, clean


def _status(bad: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """INVALID for the ``bad`` rows and (the finite-output rule) for rows of ``out`` that are
    not all finite, whose values are then NaN; OK elsewhere."""
    if out is not None:
        over = ~np.all(np.isfinite(out.reshape(out.shape[0], int(np.prod(out.shape[1:])))), axis=1)
        out[over] = np.nan
        bad = bad | over
    st = np.full(bad.shape[0], OK, dtype=np.int8)
    st[bad] = INVALID
    return st


# ------------------------------------------------------------------------- transforms


def link_transforms(desc, q) -> list:
    """A_i(q_i) per the description's convention: a list of n arrays (N, 4, 4).

    Rows with non-finite joint values give NaN matrices.
    """
    q = _check_q(desc, q)
    bad, (qc,) = _split_invalid(q)
    out = []
    for i in range(desc.n):
        A = link_transform(desc, i, qc[:, i])
        A[bad] = np.nan
        out.append(A)
    return out


def frames(desc, q):
    """(F (N, n+2, 4, 4), status): F[:, 0] = base, F[:, i] = base A_1 ... A_i,
    F[:, n+1] = F[:, n] tool."""
    q = _check_q(desc, q)
    bad, (qc,) = _split_invalid(q)
    with np.errstate(all="ignore"):
        F = model_frames(desc, qc)
    F[bad] = np.nan
    return F, _status(bad, F)


def fk(desc, q):
    """(T (N, 4, 4), status): the tool pose base A_1 ... A_n tool."""
    F, status = frames(desc, q)
    return np.ascontiguousarray(F[:, -1]), status


def _axes_from_frames(desc, F: np.ndarray, qc: np.ndarray):
    """Joint-axis points and unit directions (N, n, 3) in the base frame."""
    N, n = qc.shape
    origins = np.empty((N, n, 3))
    axes = np.empty((N, n, 3))
    for i, j in enumerate(desc.joints):
        if desc.convention == "standard":
            M = F[:, i]  # frame i-1: joint i moves about / along z_{i-1}
            c = 2
        elif desc.convention == "modified":
            # frame i = frame i-1 Rot_x(alpha) Trans_x(a) Rot_z(theta_i) Trans_z(d_i): z_i and
            # the origin of frame i lie on joint i's axis (for a revolute joint that origin is
            # fixed in link i-1, since d_i is constant).
            M = F[:, i + 1]
            c = 2
        else:  # universal: the axis of the frame in which Rot_i acts (base D_1 ... D_{i-1})
            M = F[:, i]
            c = _AXIS[j.axis]
        origins[:, i] = M[:, :3, 3]
        axes[:, i] = j.sign * M[:, :3, c]  # a reversed joint moves about minus the column
    return origins, axes


def joint_axes(desc, q):
    """(origins (N, n, 3), axes (N, n, 3)) of the joint motion axes in the base frame.

    standard DH: origin and z of frame i-1; modified DH: origin and z of frame i;
    universal: origin and ``axis`` of base D_1 ... D_{i-1}. Non-finite rows are NaN.
    """
    q = _check_q(desc, q)
    bad, (qc,) = _split_invalid(q)
    F = model_frames(desc, qc)
    origins, axes = _axes_from_frames(desc, F, qc)
    origins[bad] = np.nan
    axes[bad] = np.nan
    return origins, axes


# ------------------------------------------------------------------------- velocities


def _check_frame(frame: str) -> str:
    if frame not in ("base", "tool"):
        raise InputError(f'frame must be "base" or "tool", got {frame!r}')
    return frame


def _revolute_mask(desc) -> np.ndarray:
    return np.array([j.revolute for j in desc.joints], dtype=bool)


def _jacobian_parts(desc, qc: np.ndarray):
    """Base-frame J (N, 6, n) plus the pieces jacobian_dot needs."""
    F = model_frames(desc, qc)
    o, w = _axes_from_frames(desc, F, qc)
    T = F[:, -1]
    p = T[:, :3, 3]
    rev = _revolute_mask(desc)
    N, n = qc.shape
    J = np.zeros((N, 6, n))
    lin_rev = np.cross(w, p[:, None, :] - o)  # (N, n, 3)
    J[:, :3, :] = np.where(rev[None, :, None], lin_rev, w).transpose(0, 2, 1)
    J[:, 3:, :] = np.where(rev[None, :, None], w, 0.0).transpose(0, 2, 1)
    return J, T, o, w, p, rev


def jacobian(desc, q, frame: str = "base"):
    """(J (N, 6, n), status): geometric Jacobian of the tool point, rows vx vy vz wx wy wz.

    ``frame="tool"`` expresses the same twist in the tool frame (R^T on both halves).
    """
    _check_frame(frame)
    q = _check_q(desc, q)
    bad, (qc,) = _split_invalid(q)
    with np.errstate(all="ignore"):
        J, T, *_ = _jacobian_parts(desc, qc)
        if frame == "tool":
            J = _to_tool(J, T[:, :3, :3])
    J[bad] = np.nan
    return J, _status(bad, J)


def _to_tool(X: np.ndarray, R: np.ndarray) -> np.ndarray:
    """R^T applied to both 3-row halves of (N, 6, n)."""
    out = np.empty_like(X)
    out[:, :3] = np.einsum("nji,njk->nik", R, X[:, :3])
    out[:, 3:] = np.einsum("nji,njk->nik", R, X[:, 3:])
    return out


def jacobian_dot(desc, q, qd, frame: str = "base"):
    """(Jd (N, 6, n), status): time derivative of :func:`jacobian` along qd.

    Analytic differentiation of the column formulas (see the module docstring).
    """
    _check_frame(frame)
    q = _check_q(desc, q)
    qd = _check_q(desc, qd, "qd")
    if q.shape != qd.shape:
        raise InputError(f"q and qd must have the same shape, got {q.shape} and {qd.shape}")
    bad, (qc, qdc) = _split_invalid(q, qd)
    with np.errstate(all="ignore"):  # overflow of huge inputs: the status says so
        J, T, o, w, p, rev = _jacobian_parts(desc, qc)
        N, n = qc.shape

        # Angular velocity of link i-1 (the link carrying axis i): revolute j < i.
        wq = w * (qdc * rev[None, :])[:, :, None]  # (N, n, 3): w_j qd_j for revolute j
        Omega = np.cumsum(wq, axis=1) - wq  # exclusive prefix sum: sum over j < i
        lower = np.tril(np.ones((n, n), dtype=bool), k=-1)  # [i, j] = j < i

        # Velocity of point o_i (fixed in link i-1): contributions of every joint j < i.
        diff = o[:, :, None, :] - o[:, None, :, :]  # (N, i, j, 3) = o_i - o_j
        w_j = np.broadcast_to(w[:, None, :, :], diff.shape)
        contrib = np.where(rev[None, None, :, None], np.cross(w_j, diff), w_j)
        contrib = contrib * (qdc[:, None, :, None] * lower[None, :, :, None])
        o_dot = contrib.sum(axis=2)  # (N, n, 3)

        p_dot = np.einsum("nkj,nj->nk", J[:, :3], qdc)  # (N, 3)
        w_dot = np.cross(Omega, w)  # (N, n, 3)

        top_rev = np.cross(w_dot, p[:, None, :] - o) + np.cross(w, p_dot[:, None, :] - o_dot)
        Jd = np.zeros((N, 6, n))
        Jd[:, :3] = np.where(rev[None, :, None], top_rev, w_dot).transpose(0, 2, 1)
        Jd[:, 3:] = np.where(rev[None, :, None], w_dot, 0.0).transpose(0, 2, 1)

        if frame == "tool":
            omega_e = wq.sum(axis=1)  # (N, 3)
            corr = np.empty_like(J)
            corr[:, :3] = np.cross(omega_e[:, None, :], J[:, :3].transpose(0, 2, 1)).transpose(
                0, 2, 1
            )
            corr[:, 3:] = np.cross(omega_e[:, None, :], J[:, 3:].transpose(0, 2, 1)).transpose(
                0, 2, 1
            )
            Jd = _to_tool(Jd - corr, T[:, :3, :3])
    Jd[bad] = np.nan
    return Jd, _status(bad, Jd)


# --------------------------------------------------------------------------- dynamics
#
# Written from the Lagrangian (Jacobian) form, not from the Newton-Euler recursion of the
# derivation (derive/serial/dynamics.py). For link i with mass m_i, centre of mass c_i and
# world-frame inertia I_i = R_i I_i' R_i^T (I_i' about the COM in link frame i, the frame
# after A_i), the COM Jacobian Jv_i and the angular Jacobian Jw_i have the columns of the
# joints j <= i (revolute: w_j x (c_i - o_j) and w_j; prismatic: w_j and 0), and
# Jdot_i follows from the column formulas as in jacobian_dot (the axis turns with
# Omega_{j-1} = sum_{k<j, revolute} w_k qd_k, its point o_j moves with link j-1):
#
#   M      = sum_i m_i Jv_i^T Jv_i + Jw_i^T I_i Jw_i + diag(armature)
#   g(q)   = - sum_i m_i Jv_i^T g                         (the torque that holds the arm)
#   C      = sum_i m_i Jv_i^T Jvdot_i + Jw_i^T (I_i Jwdot_i + B_i Jw_i),
#            B_i = 1/2 ([omega_i]x I_i - I_i [omega_i]x - [I_i omega_i]x)
#   tau    = M qdd + C qd + g + viscous qd + Coulomb(sign qd)
#
# C is the Christoffel matrix: C(x) y is symmetric in (x, y) (Jv_i is the gradient of c_i,
# and the [I omega]x term symmetrises the rotational part), and C(qd) qd holds the
# Coriolis and centrifugal terms m Jv^T Jvdot qd + Jw^T (I Jwdot qd + omega x I omega),
# so C_kj = sum_i c_ijk qd_i; Mdot - 2C = (skew) + Jw^T [I omega]x Jw is skew-symmetric.


def _link_jacobians(desc, qc, qdc):
    """Per link i: (Jv, Jw, Jvd, Jwd) each (N, n, 3, n) [link, row, joint], the link's
    angular velocity omega (N, n, 3), world inertia Iw (N, n, 3, 3)."""
    F = model_frames(desc, qc)
    o, w = _axes_from_frames(desc, F, qc)
    rev = _revolute_mask(desc)
    N, n = qc.shape
    Jv = np.zeros((N, n, 3, n))
    Jw = np.zeros((N, n, 3, n))
    Jvd = np.zeros((N, n, 3, n))
    Jwd = np.zeros((N, n, 3, n))
    wq = w * (qdc * rev[None, :])[:, :, None]
    Omega_before = np.cumsum(wq, axis=1) - wq  # angular velocity of link j-1
    omega = np.cumsum(wq, axis=1)  # angular velocity of link i
    # velocity of the axis point o_j (fixed in link j-1)
    o_dot = np.zeros((N, n, 3))
    for j in range(n):
        for k in range(j):
            step = np.cross(w[:, k], o[:, j] - o[:, k]) if rev[k] else w[:, k]
            o_dot[:, j] += step * qdc[:, k, None]
    w_dot = np.cross(Omega_before, w)
    Iw = np.zeros((N, n, 3, 3))
    for i, joint in enumerate(desc.joints):
        inertial = joint.inertial
        R = F[:, i + 1, :3, :3]
        c = F[:, i + 1, :3, :3] @ np.asarray(inertial.com) + F[:, i + 1, :3, 3]
        Iw[:, i] = R @ inertial.inertia_matrix @ np.swapaxes(R, -1, -2)
        for j in range(i + 1):
            if rev[j]:
                Jv[:, i, :, j] = np.cross(w[:, j], c - o[:, j])
                Jw[:, i, :, j] = w[:, j]
            else:
                Jv[:, i, :, j] = w[:, j]
        c_dot = np.einsum("nrj,nj->nr", Jv[:, i], qdc)
        for j in range(i + 1):
            if rev[j]:
                Jvd[:, i, :, j] = np.cross(w_dot[:, j], c - o[:, j]) + np.cross(
                    w[:, j], c_dot - o_dot[:, j]
                )
                Jwd[:, i, :, j] = w_dot[:, j]
            else:
                Jvd[:, i, :, j] = w_dot[:, j]
    return Jv, Jw, Jvd, Jwd, omega, Iw


def _skew(v):
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _masses(desc):
    return np.array([j.inertial.mass for j in desc.joints])


def _friction(desc, qdc):
    viscous = np.array([j.inertial.viscous for j in desc.joints])
    plus = np.array([j.inertial.coulomb[0] for j in desc.joints])
    minus = np.array([j.inertial.coulomb[1] for j in desc.joints])
    return viscous * qdc + np.where(qdc > 0, plus, np.where(qdc < 0, minus, 0.0))


def _armature(desc):
    return np.array([j.inertial.armature for j in desc.joints])


def _dyn_inputs(desc, *arrays):
    desc.require_inertia()
    names = ("q", "qd", "qdd", "tau")[: len(arrays)]
    checked = [_check_q(desc, a, nm) for a, nm in zip(arrays, names)]
    for a, nm in zip(checked[1:], names[1:]):
        if a.shape != checked[0].shape:
            raise InputError(f"{nm} must have the shape of q {checked[0].shape}, got {a.shape}")
    return _split_invalid(*checked)


def _finish(out, bad):
    """NaN and INVALID for bad input rows and for rows whose result is not finite."""
    out[bad] = np.nan
    return out, _status(bad, out)  # _status applies the finite-output rule


def _quiet(function):
    """Huge finite inputs overflow inside the sums: such rows come out non-finite and are
    INVALID by the finite-output rule (_finish), so numpy's warnings would only be noise."""

    @functools.wraps(function)
    def wrapped(*args, **kwargs):
        with np.errstate(all="ignore"):
            return function(*args, **kwargs)

    return wrapped


@_quiet
def mass_matrix(desc, q):
    """(M (N, n, n), status): joint-space inertia matrix, armature on the diagonal."""
    bad, (qc,) = _dyn_inputs(desc, q)
    Jv, Jw, _, _, _, Iw = _link_jacobians(desc, qc, np.zeros_like(qc))
    m = _masses(desc)
    M = np.einsum("i,nirj,nirk->njk", m, Jv, Jv)
    M += np.einsum("nirj,nirs,nisk->njk", Jw, Iw, Jw)
    M += np.diag(_armature(desc))
    return _finish(M, bad)


@_quiet
def gravity_torque(desc, q):
    """(g (N, n), status): the joint torques that hold the arm against gravity."""
    bad, (qc,) = _dyn_inputs(desc, q)
    Jv, *_ = _link_jacobians(desc, qc, np.zeros_like(qc))
    g = np.asarray(desc.gravity)
    tau = -np.einsum("i,nirj,r->nj", _masses(desc), Jv, g)
    return _finish(tau, bad)


def _coriolis(desc, qc, qdc):
    Jv, Jw, Jvd, Jwd, omega, Iw = _link_jacobians(desc, qc, qdc)
    m = _masses(desc)
    Iomega = np.einsum("nirs,nis->nir", Iw, omega)
    B = 0.5 * (_skew(omega) @ Iw - Iw @ _skew(omega) - _skew(Iomega))
    C = np.einsum("i,nirj,nirk->njk", m, Jv, Jvd)
    C += np.einsum("nirj,nirs,nisk->njk", Jw, Iw, Jwd)
    C += np.einsum("nirj,nirs,nisk->njk", Jw, B, Jw)
    return C


@_quiet
def coriolis(desc, q, qd):
    """(C (N, n, n), status): the Christoffel-form Coriolis matrix (C qd: Coriolis and
    centrifugal torques; Mdot - 2C skew-symmetric)."""
    bad, (qc, qdc) = _dyn_inputs(desc, q, qd)
    return _finish(_coriolis(desc, qc, qdc), bad)


@_quiet
def nonlinear_effects(desc, q, qd):
    """(h (N, n), status): C qd + g + friction, the torque at qdd = 0."""
    bad, (qc, qdc) = _dyn_inputs(desc, q, qd)
    h = np.einsum("njk,nk->nj", _coriolis(desc, qc, qdc), qdc)
    h += gravity_torque(desc, qc)[0] + _friction(desc, qdc)
    return _finish(h, bad)


@_quiet
def inverse_dynamics(desc, q, qd, qdd):
    """(tau (N, n), status): M qdd + C qd + g + friction."""
    bad, (qc, qdc, qddc) = _dyn_inputs(desc, q, qd, qdd)
    tau = np.einsum("njk,nk->nj", mass_matrix(desc, qc)[0], qddc)
    tau += nonlinear_effects(desc, qc, qdc)[0]
    return _finish(tau, bad)


@_quiet
def forward_dynamics(desc, q, qd, tau):
    """(qdd (N, n), status): M^-1 (tau - h); SINGULAR where M is not positive definite
    (an eigenvalue not above MASS_MATRIX_TOL times the largest diagonal entry)."""
    bad, (qc, qdc, tauc) = _dyn_inputs(desc, q, qd, tau)
    M = mass_matrix(desc, qc)[0]
    rhs = tauc - nonlinear_effects(desc, qc, qdc)[0]
    qdd = np.full_like(rhs, np.nan)
    eig = np.linalg.eigvalsh(M)
    largest = np.max(np.diagonal(M, axis1=1, axis2=2), axis=1)
    spd = eig[:, 0] > MASS_MATRIX_TOL * largest
    qdd[spd] = np.linalg.solve(M[spd], rhs[spd][..., None])[..., 0]
    qdd, status = _finish(qdd, bad)
    status[~spd & ~bad] = SINGULAR
    qdd[~spd] = np.nan
    return qdd, status
