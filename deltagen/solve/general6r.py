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

Degenerate arms. The pencil is *singular* (det M(x3) = 0 for every x3) for many industrial
arms: consecutive axes that meet (a_i = 0) or are parallel make the 14 equations dependent.
Then the eigenvalues include arbitrary ones and the true ones need not appear; the reversed
chain (G^-1 = e6^-1 ... e1^-1, the same method on joints 6..1) is sometimes regular when the
forward one is not. :func:`eliminations` picks a regular elimination when there is one
(``complete`` True) and otherwise runs both as a best effort (``complete`` False: measured
on rtb's Jaco and Puma 560 the original q was among the solutions for only ~72-74% of random
poses). Arms with a closed form (model.structure) use it; the combined method
(solve/combined.py) stays the better choice for nearly-central-wrist arms with a singular
pencil. ``General6R.regular`` / ``pencil_margin`` report the check.
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


def _rot(w, th):
    """(..., 3, 3) rotations about the unit axis w (3,) by th (...) (Rodrigues)."""
    Kw = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    c, s = np.cos(th)[..., None, None], np.sin(th)[..., None, None]
    return np.eye(3) + s * Kw + (1.0 - c) * (Kw @ Kw)


def _trig(th):
    """(..., 3): (1, cos, sin) of th (...)."""
    return np.stack([np.ones_like(th), np.cos(th), np.sin(th)], axis=-1)


def _fourteen(p, line):
    """(..., 14): p, l, p.p, p.l, p x l, (p.p) l - 2 (p.l) p (Raghavan-Roth), l = line."""
    pp = np.sum(p * p, axis=-1, keepdims=True)
    pl = np.sum(p * line, axis=-1, keepdims=True)
    return np.concatenate([p, line, pp, pl, np.cross(p, line), pp * line - 2.0 * pl * p], axis=-1)


class General6R:
    """The elimination of one 6R arm (module docstring): ``solve(arm, T)``."""

    def __init__(self, desc, reverse=False):
        if desc.n != 6 or not all(j.revolute for j in desc.joints):
            raise InputError(f"{desc.name}: the general 6R solver needs 6 revolute joints")
        self.ax = ax = joint_axes(desc)
        self.w, self.o = ax.directions, ax.points
        self.reverse = reverse
        self.slots = K
        self.imag_tol = 1e-6
        if reverse:  # G^-1 = e6^-1 ... e1^-1: the axes in reverse order, turning backwards
            self.w, self.o = -self.w[::-1].copy(), self.o[::-1].copy()
        self.delta = np.random.default_rng(_SHIFT_SEED).uniform(-np.pi, np.pi, 3)
        # left coefficients C[a3, a4, a5, k] on the grid of phi = theta - delta
        g = np.stack(np.meshgrid(_GRID, _GRID, _GRID, indexing="ij"), axis=-1).reshape(-1, 3)
        values = self._left(g + self.delta)  # (27, 14)
        basis = self._basis3(g)  # (27, 27)
        self.C = np.linalg.solve(basis, values).reshape(3, 3, 3, 14)
        g2 = np.stack(np.meshgrid(_GRID, _GRID, indexing="ij"), axis=-1).reshape(-1, 2)
        self._grid2 = g2
        self._basis2_inv = np.linalg.inv(
            np.einsum("na,nb->nab", _trig(g2[:, 0]), _trig(g2[:, 1])).reshape(9, 9)
        )
        rng = np.random.default_rng(1)
        t = rng.uniform(-np.pi, np.pi, (64, 3))
        fit = np.einsum("nk,km->nm", self._basis3(t - self.delta), self.C.reshape(27, 14))
        self.fit_residual = float(np.max(np.abs(fit - self._left(t))))
        # is the 12 x 12 pencil regular? (singular for every pose of many industrial arms:
        # consecutive axes that meet or are parallel) -- its smallest relative singular value
        # at a random x3 for 4 poses from random joint values
        qr = rng.uniform(-np.pi, np.pi, (4, 6))
        R, p = ax.fk(qr)
        Tr = np.broadcast_to(np.eye(4), (4, 4, 4)).copy()
        Tr[:, :3, :3], Tr[:, :3, 3] = R, p
        G = Tr @ np.linalg.inv(ax.T0)
        if reverse:
            G = np.linalg.inv(G)
        M, _ = self._pencil(G)
        x = 0.3719
        sv = np.linalg.svd(M[:, 0] + M[:, 1] * x + M[:, 2] * x * x, compute_uv=False)
        self.pencil_margin = float(np.min(sv[:, -1] / sv[:, 0]))
        self.regular = self.pencil_margin > 1e-10

    @staticmethod
    def _basis3(phi):
        t3, t4, t5 = _trig(phi[:, 0]), _trig(phi[:, 1]), _trig(phi[:, 2])
        return np.einsum("na,nb,nc->nabc", t3, t4, t5).reshape(phi.shape[0], 27)

    def _left(self, th):
        """(M, 14) of theta 3, 4, 5 (M, 3)."""
        w, o = self.w, self.o
        R3, R4, R5 = _rot(w[2], th[:, 0]), _rot(w[3], th[:, 1]), _rot(w[4], th[:, 2])
        q5 = R5 @ (o[5] - o[4]) + o[4]
        q4 = np.einsum("nij,nj->ni", R4, q5 - o[3]) + o[3]
        p = np.einsum("nij,nj->ni", R3, q4 - o[2])
        l_ = np.einsum("nij,nj->ni", R3 @ R4 @ R5, np.broadcast_to(w[5], p.shape))
        return _fourteen(p, l_)

    def _right(self, G, th12):
        """(N, M, 14) for poses G (N, 4, 4) and theta 1, 2 (M, 2)."""
        w, o = self.w, self.o
        R1t = np.swapaxes(_rot(w[0], th12[:, 0]), -1, -2)  # (M, 3, 3)
        R2t = np.swapaxes(_rot(w[1], th12[:, 1]), -1, -2)
        y = G[:, :3, :3] @ o[5] + G[:, :3, 3]  # (N, 3)
        v = G[:, :3, :3] @ w[5]
        z = np.einsum("mij,nj->nmi", R1t, y - o[0]) + o[0]
        z2 = np.einsum("mij,nmj->nmi", R2t, z - o[1]) + o[1]
        p = z2 - o[2]
        l_ = np.einsum("mij,nj->nmi", R2t @ R1t, v)
        return _fourteen(p, l_)

    def _pencil(self, G):
        """(M (N, 3, 12, 12): M0, M1, M2 of the matrix polynomial, (C, Q, rank margin of Q))
        for poses G (N, 4, 4) (module docstring)."""
        N = G.shape[0]
        D = self._right(G, self._grid2)  # (N, 9, 14)
        D = np.einsum("ab,nbk->nak", self._basis2_inv, D).reshape(N, 3, 3, 14)
        C = np.broadcast_to(self.C, (N, 3, 3, 3, 14)).copy()
        C[:, 0, 0, 0] -= D[:, 0, 0]
        Q = D.reshape(N, 9, 14)[:, 1:].transpose(0, 2, 1)  # (N, 14, 8)
        U, sv, _ = np.linalg.svd(Q, full_matrices=True)
        margin = sv[:, 7] / np.maximum(sv[:, 0], 1e-300)
        Nul = U[:, :, 8:]  # (N, 14, 6)
        A = np.einsum("nabck,nkr->nrabc", C, Nul)  # (N, 6, 3, 3, 3)
        E = np.einsum("nrabc,ax,by,cz->nrxyz", A, _HALF, _HALF, _HALF)  # powers of x3, x4, x5
        M = np.zeros((N, 3, 12, 12))
        for s in range(2):  # the 6 equations, and the same times x4
            for p4 in range(3):
                for p5 in range(3):
                    col = (p4 + s) * 3 + p5
                    M[:, :, s * 6 : s * 6 + 6, col] = E[:, :, :, p4, p5].transpose(0, 2, 1)
        return M, (C, Q, margin)

    def candidates(self, G):
        """Raw candidates for poses G (N, 4, 4) (G = T T(0)^-1): q (N, 16, 6) (NaN in unused
        slots) and the rank margin of Q per pose (its 8th singular value / its 1st)."""
        N = G.shape[0]
        M, (C, Q, margin) = self._pencil(G)
        q = np.full((N, self.slots, 6), np.nan)
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
            x3 = lam[real].real
            V = Zn[:12, real].T  # (r, 12) monomials x4^i x5^j, index 3 i + j
            V = V / V[np.arange(len(real)), np.argmax(np.abs(V), axis=1)][:, None]
            V = V.real
            W = np.abs(V).reshape(-1, 4, 3)
            i4 = np.argmax(W[:, :3, :].max(axis=2), axis=1)
            j4 = np.argmax(W[np.arange(len(real)), i4], axis=1)
            x4 = V[np.arange(len(real)), (i4 + 1) * 3 + j4] / V[np.arange(len(real)), i4 * 3 + j4]
            j5 = np.argmax(W[:, :, :2].max(axis=1), axis=1)
            i5 = np.argmax(W[np.arange(len(real)), :, j5], axis=1)
            x5 = V[np.arange(len(real)), i5 * 3 + j5 + 1] / V[np.arange(len(real)), i5 * 3 + j5]
            th = 2.0 * np.arctan(np.stack([x3, x4, x5], axis=1)) + self.delta  # (r, 3)
            rhs = np.einsum("rk,kj->rj", self._basis3(th - self.delta), C[n].reshape(27, 14))
            sig2, *_ = np.linalg.lstsq(Q[n], rhs.T, rcond=None)  # (8, r)
            # Sigma2 order: (b1, b2) over {1, c, s}^2 without (1, 1)
            c1, s1, c2, s2 = sig2[2], sig2[5], sig2[0], sig2[1]
            th1, th2 = np.arctan2(s1, c1), np.arctan2(s2, c2)
            th6 = self._theta6(G[n], th1, th2, th)
            sol = np.stack([th1, th2, th[:, 0], th[:, 1], th[:, 2], th6], axis=1)
            q[n, : min(self.slots, len(sol))] = sol[: self.slots]
        return q, margin

    def _theta6(self, G, th1, th2, th345):
        w = self.w
        R = (
            _rot(w[0], th1)
            @ _rot(w[1], th2)
            @ _rot(w[2], th345[:, 0])
            @ _rot(w[3], th345[:, 1])
            @ _rot(w[4], th345[:, 2])
        )
        R6 = np.swapaxes(R, -1, -2) @ G[:3, :3]
        w6 = w[5]
        ref = np.cross(w6, [1.0, 0.0, 0.0])
        if np.linalg.norm(ref) < 0.1:
            ref = np.cross(w6, [0.0, 1.0, 0.0])
        ref = ref / np.linalg.norm(ref)
        y = R6 @ ref
        return np.arctan2(np.cross(ref, y) @ w6, y @ ref)

    def starts(self, T):
        """Candidates (N, 16, 6) in the arm's joint order for tool poses T (N, 4, 4), and the
        rank margin of Q."""
        G = T @ np.linalg.inv(self.ax.T0)
        if self.reverse:
            G = np.linalg.inv(G)
        q0, margin = self.candidates(G)
        return (q0[..., ::-1] if self.reverse else q0), margin


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
    """The eliminations of a 6R description to use, and whether they are complete: the
    forward chain and the reversed chain (G^-1 = e6^-1 ... e1^-1), those whose 12 x 12 pencil
    is regular (complete: every isolated solution is an eigenvalue); if neither is regular
    (many industrial arms: meeting or parallel neighbouring axes make it singular for every
    pose), both, as a best effort (complete False: solutions can be missed)."""
    both = [General6R(desc), General6R(desc, reverse=True)]
    regular = [g for g in both if g.regular]
    return (regular[:1], True) if regular else (both, False)
