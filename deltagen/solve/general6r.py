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
(SVD): A(theta3) Sigma1 = 0, 6 x 9. With x = tan(phi/2) for the shifted angles phi_i =
theta_i - delta_i (random fixed shifts keep phi = pi, x = infinity, away) and the equations
times (1 + x3^2)(1 + x4^2)(1 + x5^2), the 6 equations and the same times x4 are 12 equations
in the 12 monomials x4^i x5^j (i <= 3, j <= 2): (M0 + M1 x3 + M2 x3^2) v = 0. Its real
eigenvalues x3 (of the 24 x 24 companion matrix; numpy/LAPACK ``geev`` -- this eigen step is
the only part that is not closed-form numpy, and it is not emitted as C) give theta3, the
eigenvector v gives x4 and x5, the least-squares solution of Q Sigma2 = P Sigma1 gives
(c1, s1, c2, s2), and theta6 is the remaining rotation about axis 6. Each candidate is then
polished by damped Newton on the arm's own kinematics (deltagen.solve.numeric, restarts=0)
and is valid when Newton converges (fk = T to ``tol``), the solution is finite, within
limits, and not a duplicate of an earlier slot.

The eigen step uses LAPACK's QZ (scipy.linalg.eig(A, B), ggev), one 24 x 24 pencil per pose;
everything else is batched numpy. Nothing of this solver is emitted as C.

Degenerate arms and arrangements. The pencil is *singular* (det M(x3) = 0 for every x3)
for many industrial arms in the arrangement above: neighbouring axes that meet (a_i = 0) or
are parallel make the 14 equations dependent, or Q rank deficient. The loop can be cut
elsewhere: e_{k+1} ... e6 e'_1 ... e'_k = G with e'_i = G^-1 e_i G (shift k = 0..5; the
pose's generic link moves to another place of the loop; the left side's coefficients then
depend on the pose and are interpolated per pose), or reversed (G^-1 = e6^-1 ... e1^-1).
:func:`eliminations` takes the first arrangement whose pencil and Q are clearly regular
(checked at 4 random poses when the arm is loaded): for rtb's Jaco, Mico, Puma 560 and UR5 a
shifted one is (the original q was found on 100% of 300 random poses each). Only if no
arrangement is regular does it fall back to the forward and reversed chains as a best effort
(``complete`` False), to which SerialRobot.ik_all adds the combined method's branches.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from deltagen.geometry.limits import fit_limits
from deltagen.inputs import InputError
from deltagen.model.structure import joint_axes

__all__ = ["General6R", "K", "eliminations", "solve"]

K = 16  # solution slots
_GRID = np.array([0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0])
_SHIFT_SEED = 6016  # the fixed random shifts delta_3, delta_4, delta_5
# (1, c, s) times (1 + x^2) as polynomials in x = tan(phi / 2): rows 1, c, s; columns x^0..x^2
_HALF = np.array([[1.0, 0.0, 1.0], [1.0, 0.0, -1.0], [0.0, 2.0, 0.0]])


def _turn(w, th, v):
    """Vectors v (..., 3) turned about unit axes w (..., 3) by th (...) (Rodrigues)."""
    c, s = np.cos(th)[..., None], np.sin(th)[..., None]
    return v * c + np.cross(w, v) * s + w * (np.sum(w * v, axis=-1)[..., None] * (1.0 - c))


def _trig(th):
    """(..., 3): (1, cos, sin) of th (...)."""
    return np.stack([np.ones_like(th), np.cos(th), np.sin(th)], axis=-1)


def _fourteen(p, line):
    """(..., 14): p, l, p.p, p.l, p x l, (p.p) l - 2 (p.l) p (Raghavan-Roth), l = line."""
    pp = np.sum(p * p, axis=-1, keepdims=True)
    pl = np.sum(p * line, axis=-1, keepdims=True)
    return np.concatenate([p, line, pp, pl, np.cross(p, line), pp * line - 2.0 * pl * p], axis=-1)


def _grid(k):
    return np.stack(np.meshgrid(*([_GRID] * k), indexing="ij"), axis=-1).reshape(-1, k)


def _basis(phi):
    """(M, 3^k) products of (1, cos, sin) of the k angles phi (M, k)."""
    out = _trig(phi[:, 0])
    for i in range(1, phi.shape[1]):
        out = np.einsum("ma,mb->mab", out, _trig(phi[:, i])).reshape(phi.shape[0], -1)
    return out


_B3_INV = np.linalg.inv(_basis(_grid(3)))
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
        self.regular = self.pencil_margin > 1e-10

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

    def _pencil(self, w, o, G, C):
        """(M (N, 3, 12, 12): M0, M1, M2 of the matrix polynomial, (C with the right's
        constant moved over, Q, rank margin of Q))."""
        N = G.shape[0]
        D = np.einsum("ab,nbk->nak", _B2_INV, _right(w, o, G, _grid(2))).reshape(N, 3, 3, 14)
        C = C.copy()
        C[:, 0, 0, 0] -= D[:, 0, 0]
        Q = D.reshape(N, 9, 14)[:, 1:].transpose(0, 2, 1)  # (N, 14, 8)
        U, sv, _ = np.linalg.svd(Q, full_matrices=True)
        margin = sv[:, 7] / np.maximum(sv[:, 0], 1e-300)
        A = np.einsum("nabck,nkr->nrabc", C, U[:, :, 8:])  # (N, 6, 3, 3, 3)
        E = np.einsum("nrabc,ax,by,cz->nrxyz", A, _HALF, _HALF, _HALF)  # powers of x3, x4, x5
        M = np.zeros((N, 3, 12, 12))
        for s in range(2):  # the 6 equations, and the same times x4
            for p4 in range(3):
                for p5 in range(3):
                    col = (p4 + s) * 3 + p5
                    M[:, :, s * 6 : s * 6 + 6, col] = E[:, :, :, p4, p5].transpose(0, 2, 1)
        return M, (C, Q, margin)

    def starts(self, T):
        """Candidates (N, 16, 6) in the arm's joint order for tool poses T (N, 4, 4) (NaN in
        unused slots), and the rank margin of Q per pose."""
        w, o, G = self._arranged(T)
        C0 = self._left_coefficients(w, o)
        M, (C, Q, margin) = self._pencil(w, o, G, C0)
        N = G.shape[0]
        qa = np.full((N, self.slots, 6), np.nan)
        Z0, I12 = np.zeros((12, 12)), np.eye(12)
        B0 = np.block([[I12, Z0], [Z0, Z0]])
        for n in range(N):
            # (M0 + M1 x + M2 x^2) v = 0 as A z = x B z, z = (v, x v): QZ (LAPACK ggev),
            # which also copes with a singular M2 (eigenvalues at infinity)
            A_ = np.block([[Z0, I12], [-M[n, 0], -M[n, 1]]])
            B_ = B0.copy()
            B_[12:, 12:] = M[n, 2]
            with np.errstate(all="ignore"):
                lam, Zn = scipy.linalg.eig(A_, B_)
            ok = np.isfinite(lam) & (np.abs(lam.imag) <= self.imag_tol * (1.0 + np.abs(lam.real)))
            real = np.flatnonzero(ok)
            if real.size == 0:
                continue
            r = np.arange(real.size)
            x3 = lam[real].real
            V = Zn[:12, real].T  # (r, 12) monomials x4^i x5^j, index 3 i + j
            V = (V / V[r, np.argmax(np.abs(V), axis=1)][:, None]).real
            Wv = np.abs(V).reshape(-1, 4, 3)
            # x4, x5 as ratios of the largest neighbouring monomials (Manocha-Canny)
            i4 = np.argmax(Wv[:, :3, :].max(axis=2), axis=1)
            j4 = np.argmax(Wv[r, i4], axis=1)
            x4 = V[r, (i4 + 1) * 3 + j4] / V[r, i4 * 3 + j4]
            j5 = np.argmax(Wv[:, :, :2].max(axis=1), axis=1)
            i5 = np.argmax(Wv[r, :, j5], axis=1)
            x5 = V[r, i5 * 3 + j5 + 1] / V[r, i5 * 3 + j5]
            th = 2.0 * np.arctan(np.stack([x3, x4, x5], axis=1)) + self.delta  # (r, 3)
            rhs = np.einsum("rk,kj->rj", _basis(th - self.delta), C[n].reshape(27, 14))
            sig2, *_ = np.linalg.lstsq(Q[n], rhs.T, rcond=None)  # (8, r)
            # Sigma2 order: (b1, b2) over {1, c, s}^2 without (1, 1)
            th1 = np.arctan2(sig2[5], sig2[2])
            th2 = np.arctan2(sig2[1], sig2[0])
            th6 = self._theta6(w[n], G[n], th1, th2, th)
            sol = np.stack([th1, th2, th[:, 0], th[:, 1], th[:, 2], th6], axis=1)
            qa[n, : min(self.slots, len(sol))] = sol[: self.slots]
        q = np.empty_like(qa)
        q[..., self.order] = qa
        return q, margin

    @staticmethod
    def _theta6(w, G, th1, th2, th345):
        """The angle of the arranged joint 6: Rot(w6, th6) = (R1 ... R5)^T R_G, on a
        reference normal to w6."""
        w6 = w[5]
        ref = np.cross(w6, [1.0, 0.0, 0.0])
        if np.linalg.norm(ref) < 0.1:
            ref = np.cross(w6, [0.0, 1.0, 0.0])
        ref = ref / np.linalg.norm(ref)
        r = th1.shape[0]
        y = np.broadcast_to(G[:3, :3] @ ref, (r, 3))
        angles = [th1, th2, th345[:, 0], th345[:, 1], th345[:, 2]]
        for i in range(5):  # (R1 ... R5)^T = R5^T ... R1^T: undo joint 1 first
            y = _turn(np.broadcast_to(w[i], (r, 3)), -angles[i], y)
        return np.arctan2(np.cross(ref, y) @ w6, y @ ref)


def solve(arm, T, eliminations, *, extra=None, tol=1e-10, max_iter=30, limits=True, info=False):
    """All solutions for poses T (N, 4, 4) of ``arm`` (a SerialRobot): the candidates of
    every :class:`General6R` in ``eliminations`` (e.g. the chain forwards and reversed) and
    the optional ``extra`` starts (N, S', 6) (e.g. the combined method's branches), each
    polished by Newton; converged, distinct solutions fill the first of the 16 slots.
    Returns q (N, 16, 6), valid (N, 16) (module docstring)."""
    from deltagen.solve import numeric as ik_numeric

    T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
    N = T.shape[0]
    parts = [g.starts(T) for g in eliminations]
    q0 = np.concatenate([p[0] for p in parts] + ([] if extra is None else [extra]), axis=1)
    S = q0.shape[1]
    has = np.all(np.isfinite(q0), axis=-1)
    qs = np.full((N, S, 6), np.nan)
    conv = np.zeros((N, S), dtype=bool)
    rows = np.flatnonzero(has.reshape(-1))
    if rows.size:
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
    with np.errstate(invalid="ignore"):
        qs, inside = fit_limits(qs, ax.qlim, ax.revolute)
    # distinct solutions in order (a double root, or two candidates Newton pulled together,
    # are one): compact them into the first slots
    q = np.full((N, K, 6), np.nan)
    valid = np.zeros((N, K), dtype=bool)
    count = np.zeros(N, dtype=int)
    for a in range(S):
        d = q - qs[:, a : a + 1]
        d = np.abs((d + np.pi) % (2.0 * np.pi) - np.pi).max(axis=-1)
        dup = np.any(np.isfinite(d) & (d < 1e-7), axis=1)
        take = conv[:, a] & ~dup & (count < K)
        idx = np.flatnonzero(take)
        q[idx, count[idx]] = qs[idx, a]
        valid[idx, count[idx]] = inside[idx, a] if limits else True
        count[idx] += 1
    if info:
        margin = np.min(np.stack([p[1] for p in parts]), axis=0)
        return q, valid, {"candidates": q0, "rank_margin": margin, "found": count}
    return q, valid


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
            if g.pencil_margin > 1e-6:
                return [g], True
            tried.append(g)
    regular = [g for g in tried if g.regular]
    if regular:
        return [max(regular, key=lambda g: g.pencil_margin)], True
    return [tried[0], tried[6]], False
