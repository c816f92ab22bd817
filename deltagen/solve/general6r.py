"""Every solution (up to 16) of the inverse kinematics of a general 6R arm: Raghavan-Roth
elimination to a 12 x 12 quadratic matrix polynomial, solved as a generalized eigenvalue
problem (Manocha-Canny), polished by Newton.

Written in the product of exponentials of model/structure.py (any convention, base and tool
included): G = T_target T(0)^-1 = e1 e2 e3 e4 e5 e6 with e_i = exp(xi_i q_i), a rotation by q_i
about the axis (w_i, o_i). Rearranged as

    e3 e4 e5 (line of axis 6) = e2^-1 e1^-1 G (line of axis 6)

(e6 leaves its own axis in place) and read through two vectors of that line: the direction
l = w6 and the point p of axis 6 relative to the point o3 of axis 3 (o3 is fixed by e3):

    left:   p = R3 (e4 e5 o6 - o3),           l = R3 R4 R5 w6
    right:  p = e2^-1 e1^-1 (G o6) - o3,      l = R2^T R1^T R_G w6

Raghavan and Roth (1993) showed that the 14 quantities p, l, p.p, p.l, p x l,
(p.p) l - 2 (p.l) p are, on the left, linear in (1, c3, s3) x (1, c4, s4) x (1, c5, s5) and,
on the right, in (1, c1, s1) x (1, c2, s2). Here their coefficients are not derived
symbolically but **interpolated exactly**: a trigonometric polynomial of degree 1 in each
angle is fixed by its values on the grid {0, 2pi/3, 4pi/3} per angle (27 points on the left,
once per arm; 9 on the right, per pose), a fixed linear solve. ``General6R.fit_residual``
checks the structure at random angles (it is ~1e-15 for every arm).

Elimination. Moving the right's constant term to the left: P(theta3) Sigma1 = Q Sigma2, with
Sigma1 the 9 products of (1, c4, s4) and (1, c5, s5) and Sigma2 the 8 non-constant ones of
angles 1 and 2; Q (14 x 8, per pose) is eliminated with the 6 left null vectors of Q
(its complete QR): A(theta3) Sigma1 = 0, 6 x 9. With x = tan(phi/2) for the shifted angles phi_i =
theta_i - delta_i (random fixed shifts keep phi = pi, x = infinity, away) and the equations
times (1 + x3^2)(1 + x4^2)(1 + x5^2), the 6 equations and the same times x4 are 12 equations
in the 12 monomials x4^i x5^j (i <= 3, j <= 2): (M0 + M1 x3 + M2 x3^2) v = 0. Its real
eigenvalues x3 (8 of the 24 are always +-i, from the (1 + x3^2) factor) give theta3, the
null vector v of M(x3) gives x4 and x5, the least-squares solution of Q Sigma2 = P Sigma1 gives
(c1, s1, c2, s2), and theta6 is the remaining rotation about axis 6. Each candidate is then
polished by damped Newton on the arm's own kinematics (deltagen.solve.numeric, restarts=0)
and is valid when Newton converges (fk = T to ``tol``), the solution is finite, within
limits, and not a duplicate of an earlier slot.

Performance split (the eigenvalue step may use LAPACK through numpy; where the time goes
is stated here). Two engines compute the same steps (``engine``, :func:`eigen_engine`):
- "c", on a compiled arm: hand-written C in one arm-independent cffi module
  (native/general6r.py; codegen/runtime/deltagen_general6r.c and deltagen_eigen.c), built
  once per machine, no compile per arm: per pose the arranged axes, both sides'
  coefficients, Q's complete QR (Householder), the pencil, the companion matrix and its
  eigenvalues by a hand-written balancing + Hessenberg reduction + Francis double-shift QR
  (Golub & Van Loan, Alg. 7.4.2, 7.5.1, 7.5.2; eigenvalues only), the null vectors by the
  same inverse iteration, theta 1..6 (``deltagen_general6r_starts``); the Newton polish by
  the arm's generated C (numeric.polisher: solve()'s call, options packed once); the
  limits fit and the duplicates (``deltagen_general6r_finish``). All of it is one C call
  (``deltagen_general6r_solve``, :func:`_one_call`; the arm's Newton kernel passed in as a
  function pointer, the module stays arm-independent) for a batch of any size, and
  :func:`single` is SerialRobot.ik_all's one-pose path around it (~5 us of Python); the
  staged form (three C calls, :func:`_solve_staged`) serves the declined poses, several
  eliminations, extra starts and ``info``. Poses the C path
  declines (Q nearly rank deficient: SVD; M2's 1-norm condition > ``COND_STANDARD``:
  QZ; a failure) go through the numpy path, pose by pose;
- "numpy", the reference (and the reference backend's): batched numpy, the eigen step by
  LAPACK through numpy (stacked ``np.linalg.eigvals`` of the 24 x 24 companion matrices,
  geev, where M2 is well conditioned; QZ per pose, ``scipy.linalg.eig(A, B)``, ggev,
  elsewhere), the null vectors by one step of batched inverse iteration. The left side's
  coefficients are cached per arm (``General6R``) when its four axes are fixed in the base
  (shift 0) or all carried by G^-1 (then they are the rigid motion of the fixed ones:
  turned by R_G^T), else interpolated per pose (both engines).
Of the 24 eigenvalues 8 (a generic arm) or 16 (the UR5) are +-i, from the half-angle
substitution; they are not deflated ahead (deltagen_general6r.c says why: 4- and 8-fold,
ill conditioned, and exact +-i shifts did not save QR steps). The eigen step is the floor:
~50 us of CPU per 24 x 24 matrix in C on the 2-core development machine (LAPACK through
numpy: ~120-150 us there); tests/native/test_general6r.py compares the engines.

Degenerate arms and arrangements. The pencil is *singular* (det M(x3) = 0 for every x3)
for many industrial arms in the arrangement above: neighbouring axes that meet (a_i = 0) or
are parallel make the 14 equations dependent, or Q rank deficient. The loop can be cut
elsewhere: e_{k+1} ... e6 e'_1 ... e'_k = G with e'_i = G^-1 e_i G (shift k = 0..5; the
pose's generic link moves to another place of the loop; the left side's coefficients then
depend on the pose and are interpolated per pose), or reversed (G^-1 = e6^-1 ... e1^-1).
:func:`eliminations` takes the first arrangement whose pencil and Q are clearly regular
(checked at 4 random poses when the arm is loaded) and whose candidates contain the q of 8
further random poses (``recovered``; the margins alone can pass on rounding noise): for
rtb's Jaco, Mico, the Puma 560 and the UR5 a shifted one is (tests/solve/test_general6r.py:
the original q found on 100% of 400-500 in-limit poses each). Only if no
arrangement is regular does it fall back to the forward and reversed chains as a best effort
(``complete`` False), to which SerialRobot.ik_all adds the combined method's branches.
"""

from __future__ import annotations

import weakref

import numpy as np
import scipy.linalg

from deltagen.geometry.limits import fit_limits
from deltagen.inputs import InputError
from deltagen.model.structure import joint_axes

__all__ = ["General6R", "K", "distinct", "eigen_engine", "eliminations", "single", "solve"]

K = 16  # solution slots
_GRID = np.array([0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0])
_SHIFT_SEED = 6016  # the fixed random shifts delta_3, delta_4, delta_5
# (1, c, s) times (1 + x^2) as polynomials in x = tan(phi / 2): rows 1, c, s; columns x^0..x^2
_HALF = np.array([[1.0, 0.0, 1.0], [1.0, 0.0, -1.0], [0.0, 2.0, 0.0]])


def _cross(a, b):
    """a x b over the last axis (3) (np.cross's axis handling costs more than the product
    on the small arrays here)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _turn(w, th, v):
    """Vectors v (..., 3) turned about unit axes w (..., 3) by th (...) (Rodrigues)."""
    c, s = np.cos(th)[..., None], np.sin(th)[..., None]
    wv = (w * v).sum(axis=-1)[..., None]
    return v * c + _cross(w, v) * s + w * (wv * (1.0 - c))


def _trig(th):
    """(..., 3): (1, cos, sin) of th (...)."""
    return np.stack([np.ones_like(th), np.cos(th), np.sin(th)], axis=-1)


def _fourteen(p, line):
    """(..., 14): p, l, p.p, p.l, p x l, (p.p) l - 2 (p.l) p (Raghavan-Roth), l = line."""
    pp = np.sum(p * p, axis=-1, keepdims=True)
    pl = np.sum(p * line, axis=-1, keepdims=True)
    return np.concatenate([p, line, pp, pl, _cross(p, line), pp * line - 2.0 * pl * p], axis=-1)


def _grid(k):
    return _GRIDS[k]


def _make_grid(k):
    return np.stack(np.meshgrid(*([_GRID] * k), indexing="ij"), axis=-1).reshape(-1, k)


_GRIDS = {2: _make_grid(2), 3: _make_grid(3)}


def _basis(phi):
    """(M, 3^k) products of (1, cos, sin) of the k angles phi (M, k)."""
    out = _trig(phi[:, 0])
    for i in range(1, phi.shape[1]):
        out = np.einsum("ma,mb->mab", out, _trig(phi[:, i])).reshape(phi.shape[0], -1)
    return out


_B3_INV = np.linalg.inv(_basis(_grid(3)))
_HALF3 = np.kron(np.kron(_HALF, _HALF), _HALF)  # (1, c, s)^3 -> powers of x3, x4, x5
#: M's layout: the 6 equations (rows r) with monomials x4^p4 x5^p5 (E's column 3 p4 + p5),
#: and the same times x4 (rows 6 + r, monomial x4^(p4 + 1) x5^p5)
_E_R, _E_K = (a.ravel() for a in np.meshgrid(np.arange(6), np.arange(9), indexing="ij"))
_M_ROWS = np.concatenate([_E_R, 6 + _E_R])
_M_COLS = np.concatenate([_E_K, _E_K + 3])
_E_R, _E_K = np.tile(_E_R, 2), np.tile(_E_K, 2)
#: the vector components of the 14 (p, l, p x l, (p.p) l - 2 (p.l) p)
_VECTORS = np.r_[0:6, 8:14]
#: the companion form is used where M2's 1-norm condition number is at most this; QZ on
#: the pencil elsewhere
COND_STANDARD = 1e7
_B2_INV = np.linalg.inv(_basis(_grid(2)))


def _left(w, o, th):
    """(N, M, 14) of theta 3, 4, 5 (M, 3) for per-pose axes w, o (N, 6, 3) (module
    docstring: p = R3 (e4 e5 o6 - o3), l = R3 R4 R5 w6)."""
    N, M = w.shape[0], th.shape[0]

    def ax(i):
        return np.broadcast_to(w[:, None, i], (N, M, 3))

    def t(i):
        return np.broadcast_to(th[None, :, i], (N, M))

    pt = [o[:, None, i] for i in range(6)]
    q5 = _turn(ax(4), t(2), np.broadcast_to(pt[5] - pt[4], (N, M, 3))) + pt[4]
    q4 = _turn(ax(3), t(1), q5 - pt[3]) + pt[3]
    p = _turn(ax(2), t(0), q4 - pt[2])
    line = _turn(ax(2), t(0), _turn(ax(3), t(1), _turn(ax(4), t(2), ax(5))))
    return _fourteen(p, line)


def _right(w, o, G, th12):
    """(N, M, 14) for poses G (N, 4, 4) and theta 1, 2 (M, 2) (module docstring:
    p = e2^-1 e1^-1 (G o6) - o3, l = R2^T R1^T R_G w6)."""
    N, M = w.shape[0], th12.shape[0]

    def ax(i):
        return np.broadcast_to(w[:, None, i], (N, M, 3))

    def t(i):
        return np.broadcast_to(th12[None, :, i], (N, M))

    y = np.einsum("nij,nj->ni", G[:, :3, :3], o[:, 5]) + G[:, :3, 3]
    v = np.einsum("nij,nj->ni", G[:, :3, :3], w[:, 5])
    z = _turn(ax(0), -t(0), np.broadcast_to((y - o[:, 0])[:, None], (N, M, 3))) + o[:, None, 0]
    z2 = _turn(ax(1), -t(1), z - o[:, None, 1]) + o[:, None, 1]
    line = _turn(ax(1), -t(1), _turn(ax(0), -t(0), np.broadcast_to(v[:, None], (N, M, 3))))
    return _fourteen(z2 - o[:, None, 2], line)


def _null_vectors(Mx):
    """Unit null vectors (r, 12) of nearly singular matrices Mx (r, 12, 12) (at an
    eigenvalue): one step of inverse iteration from a fixed start, batched, on Mx shifted
    by 1e-13 of its largest entry (a matrix that is exactly singular in floating point,
    which happens at accurate eigenvalues, would stop LAPACK's solve; a shift at the
    level of rounding changes the null vector by as little); the smallest right singular
    vector if a shifted matrix is still exactly singular."""
    b = np.broadcast_to(_START, Mx.shape[:2])[..., None]
    scale = np.abs(Mx).max(axis=(1, 2))
    shifted = Mx + (1e-13 * scale)[:, None, None] * np.eye(12)
    with np.errstate(all="ignore"):
        try:
            v = np.linalg.solve(shifted, b)[..., 0]
            return v / np.linalg.norm(v, axis=1, keepdims=True)
        except np.linalg.LinAlgError:
            return np.linalg.svd(Mx)[2][:, -1]


_START = np.random.default_rng(12).standard_normal(12)


class General6R:
    """The elimination of one 6R arm in one arrangement of its loop (module docstring).

    ``shift`` k = 0..5 and ``reverse``: the loop e1 ... e6 = G is solved as
    e_{k+1} ... e6 e'_1 ... e'_k = G with e'_i = G^-1 e_i G (joint i's axis carried by G^-1,
    the same angle), and, reversed, as the inverse chain (axes in reverse order, turning
    backwards, target G^-1). Different arrangements put the pose's generic link at different
    places of the loop; for arms whose neighbouring axes meet or are parallel some of them
    make the pencil singular and others do not (:func:`eliminations` picks a regular one).
    """

    def __init__(self, desc, reverse=False, shift=0):
        if desc.n != 6 or not all(j.revolute for j in desc.joints):
            raise InputError(f"{desc.name}: the general 6R solver needs 6 revolute joints")
        self.ax = ax = joint_axes(desc)
        self.reverse, self.shift = bool(reverse), int(shift)
        order = list(range(self.shift, 6)) + list(range(self.shift))
        self.order = order[::-1] if self.reverse else order  # arranged joint j = order[j]
        self.slots = K
        self.imag_tol = 1e-6
        self.delta = np.random.default_rng(_SHIFT_SEED).uniform(-np.pi, np.pi, 3)
        # which arranged axes are carried by G^-1 (the shifted joints), and the left's
        # coefficients for the axes fixed in the base (cached: the left is that, or its
        # rigid motion by G^-1, when its four axes are all fixed or all carried)
        carried = np.array([j < self.shift for j in order])
        self._carried = carried[::-1] if self.reverse else carried
        w_fixed, o_fixed = ax.directions[order], ax.points[order]
        if self.reverse:
            w_fixed, o_fixed = -w_fixed[::-1], o_fixed[::-1]
        self._left_fixed = self._left_coefficients(w_fixed[None], o_fixed[None])[0]
        rng = np.random.default_rng(1)
        # the structure check of the interpolation and the pencil's regularity at 4 poses
        qr = rng.uniform(-np.pi, np.pi, (4, 6))
        R, p = ax.fk(qr)
        Tr = np.broadcast_to(np.eye(4), (4, 4, 4)).copy()
        Tr[:, :3, :3], Tr[:, :3, 3] = R, p
        w, o, G = self._arranged(Tr)
        C = self._left_coefficients(w, o)
        t = rng.uniform(-np.pi, np.pi, (64, 3))
        fit = np.einsum("mk,nkj->nmj", _basis(t - self.delta), C.reshape(-1, 27, 14))
        self.fit_residual = float(np.max(np.abs(fit - _left(w, o, t))))
        M, (_, _, q_margin) = self._pencil(w, o, G, C)
        x = 0.3719
        sv = np.linalg.svd(M[:, 0] + M[:, 1] * x + M[:, 2] * x * x, compute_uv=False)
        # the 12 x 12 pencil's smallest relative singular value at a random x3, and Q's
        # rank margin (both must be clear of 0: a rank-deficient Q, e.g. two parallel axes
        # on the right side, leaves too few equations)
        self.pencil_margin = float(min(np.min(sv[:, -1] / sv[:, 0]), np.min(q_margin)))
        # the elimination's own test: the candidates (before Newton) of 8 random poses
        # contain the q they came from. A pencil can pass the margin test on rounding
        # noise and still lose solutions (every arrangement of the Puma 560's: spherical
        # wrist and parallel shoulder and elbow; margins ~1e-5, 5-19 % of the q found)
        qc = rng.uniform(-np.pi, np.pi, (8, 6))
        Rc, pc = ax.fk(qc)
        Tc = np.broadcast_to(np.eye(4), (8, 4, 4)).copy()
        Tc[:, :3, :3], Tc[:, :3, 3] = Rc, pc
        cand, _ = self.starts(Tc)
        with np.errstate(invalid="ignore"):
            d = np.abs((cand - qc[:, None] + np.pi) % (2.0 * np.pi) - np.pi).max(axis=-1)
        self.recovered = int(np.sum(np.any(d < 1e-4, axis=1)))
        self.regular = self.pencil_margin > 1e-10 and self.recovered >= 7

    def __repr__(self):
        return f"General6R({self.ax.name!r}, shift={self.shift}, reverse={self.reverse})"

    def _arranged(self, T):
        """Per-pose axes w, o (N, 6, 3) of the arrangement and its target G (N, 4, 4) for
        tool poses T (N, 4, 4)."""
        ax = self.ax
        G = T @ np.linalg.inv(ax.T0)
        N = G.shape[0]
        RGt = np.swapaxes(G[:, :3, :3], 1, 2)
        w = np.broadcast_to(ax.directions, (N, 6, 3)).copy()
        o = np.broadcast_to(ax.points, (N, 6, 3)).copy()
        k = self.shift
        if k:  # e'_i = G^-1 e_i G: the axis carried by G^-1
            w[:, :k] = np.einsum("nij,nkj->nki", RGt, w[:, :k])
            o[:, :k] = np.einsum("nij,nkj->nki", RGt, o[:, :k] - G[:, None, :3, 3])
        order = list(range(k, 6)) + list(range(k))
        w, o = w[:, order], o[:, order]
        if self.reverse:
            w, o, G = -w[:, ::-1], o[:, ::-1], np.linalg.inv(G)
        return np.ascontiguousarray(w), np.ascontiguousarray(o), G

    def _left_coefficients(self, w, o):
        """C (N, 3, 3, 3, 14) of the left side on the grid of phi = theta - delta."""
        values = _left(w, o, _grid(3) + self.delta)  # (N, 27, 14)
        return np.einsum("ab,nbk->nak", _B3_INV, values).reshape(-1, 3, 3, 3, 14)

    def _pencil(self, w, o, G, C, with_pinv=False):
        """(M (N, 3, 12, 12): M0, M1, M2 of the matrix polynomial, (C with the right's
        constant moved over, Q, rank margin of Q)[, Q's pseudo-inverse (N, 8, 14)])."""
        N = G.shape[0]
        D = np.einsum("ab,nbk->nak", _B2_INV, _right(w, o, G, _grid(2))).reshape(N, 9, 14)
        C = np.array(C, dtype=float).reshape(N, 27, 14)
        C[:, 0] -= D[:, 0]
        Q = D[:, 1:].transpose(0, 2, 1)  # (N, 14, 8)
        if with_pinv:
            # per pose (starts): Q's complete QR gives its left null space and its
            # least-squares solution (a third of the SVD's time); the SVD where R's
            # diagonal shows Q (nearly) rank deficient
            U, R = np.linalg.qr(Q, mode="complete")
            dR = np.abs(np.diagonal(R[:, :8], axis1=1, axis2=2))
            margin = dR.min(axis=1) / np.maximum(dR.max(axis=1), 1e-300)
            pinv = np.zeros((N, 8, 14))
            fine = margin > 1e-8
            if fine.any():
                pinv[fine] = np.linalg.solve(R[fine, :8], np.swapaxes(U[fine, :, :8], 1, 2))
            if not fine.all():
                U_s, sv_s, Vh_s = np.linalg.svd(Q[~fine], full_matrices=True)
                U[~fine], margin[~fine] = U_s, sv_s[:, 7] / np.maximum(sv_s[:, 0], 1e-300)
                # lstsq's cut (rcond = eps max(14, 8)) on the small singular values
                cut = sv_s > 14.0 * np.finfo(float).eps * sv_s[:, :1]
                inv_s = np.where(cut, 1.0 / np.where(cut, sv_s, 1.0), 0.0)
                pinv[~fine] = np.swapaxes(Vh_s, 1, 2) @ (
                    inv_s[:, :, None] * np.swapaxes(U_s[:, :, :8], 1, 2)
                )
        else:
            U, sv, _ = np.linalg.svd(Q, full_matrices=True)
            margin = sv[:, 7] / np.maximum(sv[:, 0], 1e-300)
        # the 6 left null vectors of Q eliminate it: A (N, 6, 27), then powers of x3, x4, x5
        E = (np.swapaxes(U[:, :, 8:], 1, 2) @ np.swapaxes(C, 1, 2)) @ _HALF3  # (N, 6, 27)
        E = E.reshape(N, 6, 3, 9).transpose(0, 2, 1, 3)  # (N, x3 power, r, 3 p4 + p5)
        M = np.zeros((N, 3, 12, 12))
        M[:, :, _M_ROWS, _M_COLS] = E[:, :, _E_R, _E_K]
        C = C.reshape(N, 3, 3, 3, 14)
        if not with_pinv:
            return M, (C, Q, margin)
        return M, (C, Q, margin), pinv

    def _carry_rotation(self, G):
        """R_G^T (N, 3, 3) of the original target, from the arranged target G."""
        RG = G[:, :3, :3]
        return RG if self.reverse else np.swapaxes(RG, 1, 2)

    def _left_batch(self, w, o, G):
        """C (N, 3, 3, 3, 14) of the left side for the arranged axes w, o (N, 6, 3).

        When the left's four axes (arranged joints 3..6) are all fixed in the base, C is
        the arm's constant (interpolated once, cached); when they are all carried by the
        same G^-1 (the shifted joints), the left chain is that rigid motion of the fixed
        one: p and l (and p x l, (p.p) l - 2 (p.l) p) turn by R_G^T, p.p and p.l stay
        (Raghavan-Roth's 14 quantities are vectors and scalars of one frame); otherwise
        it is interpolated per pose."""
        carried = self._carried[2:]
        if carried.any() and not carried.all():
            return self._left_coefficients(w, o)
        N = w.shape[0]
        if not carried.any():
            return np.broadcast_to(self._left_fixed, (N, 3, 3, 3, 14))
        Rt = self._carry_rotation(G)  # (N, 3, 3): the rotation that carried the axes
        C0 = self._left_fixed.reshape(27, 14)
        out = np.empty((N, 27, 14))
        out[:, :, 6:8] = C0[:, 6:8]
        vectors = C0[:, _VECTORS].reshape(108, 3) @ np.swapaxes(Rt, 1, 2)  # (N, 108, 3)
        out[:, :, _VECTORS] = vectors.reshape(N, 27, 12)
        return out.reshape(N, 3, 3, 3, 14)

    def starts(self, T, engine="numpy"):
        """Candidates (N, 16, 6) in the arm's joint order for tool poses T (N, 4, 4) (NaN in
        unused slots), and the rank margin of Q per pose. Batched over the poses; the
        eigen step is the standard eigenproblem of the 24 x 24 companion matrix (stacked
        ``np.linalg.eigvals``) where M2 is well conditioned, LAPACK's QZ per pose where it
        is not (module docstring); ``engine`` of the standard eigen step: "numpy" or "c"
        (:meth:`_eigen`)."""
        if engine == "c":
            return self._starts_c(T)
        w, o, G = self._arranged(T)
        C0 = self._left_batch(w, o, G)
        M, (C, Q, margin), pinv = self._pencil(w, o, G, C0, with_pinv=True)
        N = G.shape[0]
        qa = np.full((N, self.slots, 6), np.nan)
        idx, x3, V = self._eigen(M, engine)
        if idx.size:
            th = self._angles345(x3, V)
            # (c1, s1, c2, s2) from Q Sigma2 = P Sigma1, by Q's pseudo-inverse (its SVD)
            rhs = np.einsum("rk,rkj->rj", _basis(th - self.delta), C[idx].reshape(-1, 27, 14))
            sig2 = np.einsum("rij,rj->ri", pinv[idx], rhs)  # Sigma2 (r, 8)
            # Sigma2 order: (b1, b2) over {1, c, s}^2 without (1, 1)
            th1 = np.arctan2(sig2[:, 5], sig2[:, 2])
            th2 = np.arctan2(sig2[:, 1], sig2[:, 0])
            th6 = self._theta6(w[idx], G[idx], th1, th2, th)
            sol = np.stack([th1, th2, th[:, 0], th[:, 1], th[:, 2], th6], axis=1)
            # the slot of each root: its rank among its pose's real roots (first 16 kept)
            first = np.searchsorted(idx, idx, side="left")
            slot = np.arange(idx.size) - first
            keep = slot < self.slots
            qa[idx[keep], slot[keep]] = sol[keep]
        q = np.empty_like(qa)
        q[..., self.order] = qa
        return q, margin

    def _native(self):
        """The arrangement's data for the C path (native.general6r.Arm), packed once."""
        if getattr(self, "_native_arm", None) is None:
            from deltagen.native import general6r as native_g6r

            carried = self._carried[2:]
            mode = 2 if carried.any() and not carried.all() else int(carried.all())
            self._native_arm = native_g6r.Arm(
                T0inv=np.linalg.inv(self.ax.T0),
                w=self.ax.directions,
                o=self.ax.points,
                order=self.order,
                shift=self.shift,
                reverse=self.reverse,
                left_mode=mode,
                left_fixed=self._left_fixed,
                delta=self.delta,
                B2inv=_B2_INV,
                B3inv=_B3_INV,
                half3=_HALF3,
            )
        return self._native_arm

    def _starts_c(self, T):
        """:meth:`starts` in C (native/general6r.py: the arranged axes, both sides'
        coefficients, Q's QR, the pencil, the eigen step, theta 1..6, per pose in one
        call); the poses it declines (Q nearly rank deficient, M2 ill conditioned, a
        failure) by the numpy path."""
        q, margin, status = self._native().starts(T, COND_STANDARD, self.imag_tol, _START)
        redo = np.flatnonzero(status != 0)
        if redo.size:
            q[redo], margin[redo] = self.starts(T[redo], "numpy")
        return q, margin

    def _eigen(self, M, engine="numpy"):
        """The real eigenvalues x3 of (M0 + M1 x + M2 x^2) v = 0 for every pose, with their
        eigenvectors v (12 monomials): (pose index (r,), x3 (r,), v (r, 12)), sorted by
        pose. Where M2 is well conditioned (1-norm condition <= COND_STANDARD) the
        companion matrix of M2^-1 M(x) (stacked eigvals) and v by one step of inverse
        iteration on M(x3); elsewhere (and where that fails) QZ on the pencil per pose
        (LAPACK ggev), which copes with a singular M2 (eigenvalues at infinity).
        ``engine``: "numpy" (LAPACK geev through numpy, the reference) or "c" (the same
        steps in hand-written C, :meth:`_eigen_c`)."""
        if engine == "c":
            return self._eigen_c(M)
        N = M.shape[0]
        M2 = M[:, 2]
        std = np.zeros(N, dtype=bool)
        inv = np.zeros((N, 12, 12))
        with np.errstate(all="ignore"):
            n1 = np.abs(M2).sum(axis=1).max(axis=1)
            try:
                inv[:] = np.linalg.inv(M2)
                ok = np.all(np.isfinite(inv), axis=(1, 2))
            except np.linalg.LinAlgError:  # an exactly singular M2 in the batch: one by one
                ok = np.zeros(N, dtype=bool)
                for n in range(N):
                    try:
                        inv[n] = np.linalg.inv(M2[n])
                        ok[n] = np.all(np.isfinite(inv[n]))
                    except np.linalg.LinAlgError:
                        pass
            cond = n1 * np.abs(inv).sum(axis=1).max(axis=1)
        std = ok & (cond <= COND_STANDARD)
        idx_parts, x_parts, v_parts = [], [], []
        rows = np.flatnonzero(std)
        if rows.size:
            comp = np.zeros((rows.size, 24, 24))
            comp[:, :12, 12:] = np.eye(12)
            comp[:, 12:, :12] = -inv[rows] @ M[rows, 0]
            comp[:, 12:, 12:] = -inv[rows] @ M[rows, 1]
            lam = np.linalg.eigvals(comp)
            real = np.isfinite(lam) & (np.abs(lam.imag) <= self.imag_tol * (1.0 + np.abs(lam.real)))
            pr, er = np.nonzero(real)
            x = lam[pr, er].real
            Mx = (
                M[rows[pr], 0]
                + M[rows[pr], 1] * x[:, None, None]
                + M[rows[pr], 2] * (x * x)[:, None, None]
            )
            v = _null_vectors(Mx)
            good = np.all(np.isfinite(v), axis=1)
            idx_parts.append(rows[pr[good]])
            x_parts.append(x[good])
            v_parts.append(v[good])
            std[rows[pr[~good]]] = False  # inverse iteration failed: QZ for that pose
            if (~good).any():
                drop = np.isin(idx_parts[-1], rows[pr[~good]])
                idx_parts[-1], x_parts[-1], v_parts[-1] = (
                    idx_parts[-1][~drop],
                    x_parts[-1][~drop],
                    v_parts[-1][~drop],
                )
        self._eigen_qz(M, np.flatnonzero(~std), idx_parts, x_parts, v_parts)
        if not idx_parts:
            return np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, 12))
        idx = np.concatenate(idx_parts)
        order = np.argsort(idx, kind="stable")
        return idx[order], np.concatenate(x_parts)[order], np.concatenate(v_parts)[order]

    def _eigen_c(self, M):
        """_eigen by the compiled eigen step (native/general6r.py: the companion matrix,
        its eigenvalues by the hand-written Hessenberg + Francis QR of
        codegen/runtime/deltagen_eigen.c, the null vectors by the same inverse iteration),
        QZ per pose where it reports a status (M2 ill conditioned, or a failure)."""
        from deltagen.native import general6r as native_g6r

        status, nreal, x, V = native_g6r.eigen(M, COND_STANDARD, self.imag_tol, _START)
        have = np.arange(24)[None, :] < nreal[:, None]
        pr, er = np.nonzero(have)
        idx_parts, x_parts, v_parts = [pr], [x[pr, er]], [V[pr, er]]
        self._eigen_qz(M, np.flatnonzero(status != 0), idx_parts, x_parts, v_parts)
        idx = np.concatenate(idx_parts)
        order = np.argsort(idx, kind="stable")
        return idx[order], np.concatenate(x_parts)[order], np.concatenate(v_parts)[order]

    def _eigen_qz(self, M, rows, idx_parts, x_parts, v_parts):
        """QZ on the pencil (scipy.linalg.eig, LAPACK ggev) for the poses ``rows``; their
        real eigenvalues and eigenvectors appended to the parts."""
        Z0, I12 = np.zeros((12, 12)), np.eye(12)
        for n in rows:
            # (M0 + M1 x + M2 x^2) v = 0 as A z = x B z, z = (v, x v)
            A_ = np.block([[Z0, I12], [-M[n, 0], -M[n, 1]]])
            B_ = np.block([[I12, Z0], [Z0, M[n, 2]]])
            with np.errstate(all="ignore"):
                lam, Zn = scipy.linalg.eig(A_, B_)
            ok = np.isfinite(lam) & (np.abs(lam.imag) <= self.imag_tol * (1.0 + np.abs(lam.real)))
            real = np.flatnonzero(ok)
            if real.size == 0:
                continue
            V = Zn[:12, real].T
            V = V / V[np.arange(real.size), np.argmax(np.abs(V), axis=1)][:, None]
            idx_parts.append(np.full(real.size, n))
            x_parts.append(lam[real].real)
            v_parts.append(V.real)

    def _angles345(self, x3, V):
        """theta 3, 4, 5 (r, 3) from the eigenvalues x3 (r,) and eigenvectors V (r, 12) of
        monomials x4^i x5^j (index 3 i + j): x4 and x5 as ratios of the largest
        neighbouring monomials (Manocha-Canny)."""
        r = np.arange(x3.size)
        V = V / V[r, np.argmax(np.abs(V), axis=1)][:, None]
        Wv = np.abs(V).reshape(-1, 4, 3)
        i4 = np.argmax(Wv[:, :3, :].max(axis=2), axis=1)
        j4 = np.argmax(Wv[r, i4], axis=1)
        x4 = V[r, (i4 + 1) * 3 + j4] / V[r, i4 * 3 + j4]
        j5 = np.argmax(Wv[:, :, :2].max(axis=1), axis=1)
        i5 = np.argmax(Wv[r, :, j5], axis=1)
        x5 = V[r, i5 * 3 + j5 + 1] / V[r, i5 * 3 + j5]
        return 2.0 * np.arctan(np.stack([x3, x4, x5], axis=1)) + self.delta

    @staticmethod
    def _theta6(w, G, th1, th2, th345):
        """The angle of the arranged joint 6 for r candidates (per-candidate axes w (r, 6,
        3), targets G (r, 4, 4)): Rot(w6, th6) = (R1 ... R5)^T R_G, on a reference normal
        to w6."""
        w6 = w[:, 5]
        ref = _cross(w6, np.array([1.0, 0.0, 0.0]))
        alt = _cross(w6, np.array([0.0, 1.0, 0.0]))
        small = np.linalg.norm(ref, axis=1) < 0.1
        ref[small] = alt[small]
        ref /= np.linalg.norm(ref, axis=1)[:, None]
        y = np.einsum("rij,rj->ri", G[:, :3, :3], ref)
        angles = [th1, th2, th345[:, 0], th345[:, 1], th345[:, 2]]
        for i in range(5):  # (R1 ... R5)^T = R5^T ... R1^T: undo joint 1 first
            y = _turn(w[:, i], -angles[i], y)
        return np.arctan2((_cross(ref, y) * w6).sum(axis=1), (y * ref).sum(axis=1))


_POLISHERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _polisher(arm, tol, max_iter):
    """numeric.polisher(arm, tol, max_iter), cached per arm (None: the compiled Newton
    engine does not apply; solve() then calls numeric.solve)."""
    from deltagen.solve import numeric as ik_numeric

    try:
        cached = _POLISHERS.setdefault(arm, {})
    except TypeError:  # not weakly referenceable: no cache
        cached = {}
    key = (float(tol), int(max_iter))
    if key not in cached:
        cached[key] = ik_numeric.polisher(arm, tol, max_iter)
    return cached[key]


def eigen_engine(arm, engine="auto") -> str:
    """The eigen step's engine for ``arm``: "numpy" or "c" as asked; "auto": "c" on the
    compiled backend when the module builds (native/general6r.py), else "numpy" (the
    reference backend stays pure numpy, like its Newton polish)."""
    if engine not in ("auto", "c", "numpy"):
        raise InputError(f'engine must be "auto", "c" or "numpy", not {engine!r}')
    if engine != "auto":
        return engine
    if getattr(arm, "backend", None) != "compiled":
        return "numpy"
    from deltagen.native import general6r as native_g6r

    return "c" if native_g6r.available() else "numpy"


def solve(
    arm,
    T,
    eliminations,
    *,
    extra=None,
    tol=1e-10,
    max_iter=30,
    limits=True,
    info=False,
    engine="auto",
):
    """All solutions for poses T (N, 4, 4) of ``arm`` (a SerialRobot): the candidates of
    every :class:`General6R` in ``eliminations`` (e.g. the chain forwards and reversed) and
    the optional ``extra`` starts (N, S', 6) (e.g. the combined method's branches), each
    polished by Newton; converged, distinct solutions fill the first of the 16 slots.
    ``engine``: the eigen step's (:func:`eigen_engine`).
    Returns q (N, 16, 6), valid (N, 16) (module docstring)."""
    T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
    engine = eigen_engine(arm, engine)
    if engine == "c" and len(eliminations) == 1 and extra is None and not info:
        one = _one_call(arm, eliminations[0], tol, max_iter, limits)
        if one is not None:  # starts, Newton and finish in one C call
            q, valid, status = one(T if T.flags.c_contiguous else np.ascontiguousarray(T))
            redo = np.flatnonzero(status)
            if redo.size:  # declined poses: the staged path (numpy starts), pose by pose
                q[redo], valid[redo] = _solve_staged(
                    arm, T[redo], eliminations, None, tol, max_iter, limits, False, engine
                )
            return q, valid
    return _solve_staged(arm, T, eliminations, extra, tol, max_iter, limits, info, engine)


def single(arm, eliminations, *, tol=1e-10, max_iter=30, limits=True):
    """A one-pose form of :func:`solve` for SerialRobot.ik_all's single-pose path:
    ``call(T (4, 4) float64 C-contiguous, a finite rigid transform)`` -> (q (16, 6),
    valid (16,)), the bits solve() gives that pose (the same C call; a declined pose goes
    through solve()'s staged path). None where the one-call C path does not apply (not
    the compiled engine, or more than one elimination)."""
    if len(eliminations) != 1 or eigen_engine(arm) != "c":
        return None
    one = _one_call(arm, eliminations[0], tol, max_iter, limits)
    if one is None:
        return None

    def call(T):
        T1 = T.reshape(1, 4, 4)
        q, valid, status = one(T1)
        if status[0]:
            q, valid = _solve_staged(arm, T1, eliminations, None, tol, max_iter, limits, False, "c")
        return q[0], valid[0]

    return call


def _one_call(arm, g, tol, max_iter, limits):
    """The one-call C solve (native.general6r.Arm.solver: deltagen_general6r_solve) of
    elimination ``g`` with the arm's own Newton kernel (numeric.polisher's), cached per
    arm; None where the compiled Newton engine does not apply."""
    polish = _polisher(arm, tol, max_iter)
    kernel = getattr(polish, "kernel", None)
    if kernel is None:
        return None
    try:
        cached = _POLISHERS.setdefault(arm, {})
    except TypeError:
        cached = {}
    key = ("one_call", g, float(tol), int(max_iter), bool(limits))
    if key not in cached:
        cached[key] = g._native().solver(
            COND_STANDARD, g.imag_tol, _START, kernel, g.ax.qlim, limits
        )
    return cached[key]


def _solve_staged(arm, T, eliminations, extra, tol, max_iter, limits, info, engine):
    """solve() in stages: the candidates of every elimination (C or numpy), Newton on all
    of them in one call, the distinct solutions."""
    from deltagen.solve import numeric as ik_numeric

    N = T.shape[0]
    parts = [g.starts(T, engine) for g in eliminations]
    q0 = np.concatenate([p[0] for p in parts] + ([] if extra is None else [extra]), axis=1)
    has = np.all(np.isfinite(q0), axis=-1)
    used = has.any(axis=0)  # slots that hold a candidate for some pose (order kept)
    q0, has = q0[:, used], has[:, used]
    S = q0.shape[1]
    qs = np.full((N, S, 6), np.nan)
    conv = np.zeros((N, S), dtype=bool)
    rows = np.flatnonzero(has.reshape(-1))
    polish = _polisher(arm, tol, max_iter) if engine == "c" else None
    if rows.size and polish is not None:  # the same C call as ik_numeric.solve's, lean
        qs.reshape(-1, 6)[rows], conv.reshape(-1)[rows] = polish(
            T[rows // S], q0.reshape(-1, 6)[rows]
        )
    elif rows.size:
        res = ik_numeric.solve(
            arm,
            T[rows // S],
            q0.reshape(-1, 6)[rows],
            tol=tol,
            max_iter=max_iter,
            restarts=0,
            respect_limits=False,
        )
        qs.reshape(-1, 6)[rows] = res.q
        conv.reshape(-1)[rows] = res.converged & np.all(np.isfinite(res.q), axis=-1)
    ax = eliminations[0].ax
    if engine == "c":  # the same steps in C (deltagen_general6r_finish)
        from deltagen.native import general6r as native_g6r

        q, valid, count = native_g6r.finish(qs, conv, ax.qlim, limits)
    else:
        q, valid, count = distinct(qs, conv, ax.qlim, ax.revolute, limits)
    if info:
        margin = np.min(np.stack([p[1] for p in parts]), axis=0)
        return q, valid, {"candidates": q0, "rank_margin": margin, "found": count}
    return q, valid


def distinct(qs, conv, qlim, revolute, limits=True):
    """The distinct solutions among Newton's results qs (N, S, 6) (converged where conv
    (N, S)), in order: each fitted into the limits (geometry/limits.py); a double root, or
    two candidates Newton pulled together, are one (a candidate within 1e-7 rad of an
    earlier converged one is dropped); compacted into the first of K slots.
    Returns q (N, K, 6) (NaN in unused slots), valid (N, K) (within the limits, or every
    solution when ``limits`` is False), found (N,). The C twin: deltagen_general6r_finish."""
    N, S = conv.shape
    with np.errstate(invalid="ignore"):
        qs, inside = fit_limits(qs, qlim, revolute)
    d = qs[:, :, None] - qs[:, None, :]  # (N, S, S, 6)
    with np.errstate(invalid="ignore"):
        d = np.abs((d + np.pi) % (2.0 * np.pi) - np.pi).max(axis=-1)
        near = (d < 1e-7) & conv[:, None, :] & np.tri(S, S, -1, dtype=bool)
    take = conv & ~near.any(axis=2)
    rank = np.cumsum(take, axis=1) - 1
    take &= rank < K
    n_idx, s_idx = np.nonzero(take)
    q = np.full((N, K, 6), np.nan)
    valid = np.zeros((N, K), dtype=bool)
    q[n_idx, rank[n_idx, s_idx]] = qs[n_idx, s_idx]
    valid[n_idx, rank[n_idx, s_idx]] = inside[n_idx, s_idx] if limits else True
    return q, valid, take.sum(axis=1)


def eliminations(desc) -> tuple[list[General6R], bool]:
    """The elimination(s) of a 6R description to use, and whether they are complete: the
    first arrangement (shift, reverse) whose pencil is clearly regular (every isolated
    solution is then an eigenvalue), else the most regular one; if none is regular, the
    forward and reversed chains as a best effort (complete False: solutions can be
    missed)."""
    tried = []
    for reverse in (False, True):
        for shift in range(6):
            g = General6R(desc, reverse=reverse, shift=shift)
            if g.pencil_margin > 1e-6 and g.recovered == 8:
                return [g], True
            tried.append(g)
    regular = [g for g in tried if g.regular]
    if regular:
        return [max(regular, key=lambda g: (g.recovered, g.pencil_margin))], True
    return [tried[0], tried[6]], False
