"""The compiled eigen step of the general 6R solver (codegen/runtime/deltagen_eigen.c: a
hand-written Hessenberg + Francis double-shift QR; deltagen_general6r.c: the companion
matrix, its real eigenvalues and null vectors) against independent evidence: LAPACK's
geev through numpy on random matrices, matrices built with known eigenvalues (real,
complex pairs, clustered, a zero one), and the numpy twin of the whole eigen step
(General6R._eigen, engine="numpy") on real arms, down to the solver's solution sets."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import jaco_arm, random_6r_arm
from scipy.optimize import linear_sum_assignment

from deltagen import SerialRobot
from deltagen.solve import general6r

native_g6r = pytest.importorskip("deltagen.native.general6r")
if not native_g6r.available():  # pragma: no cover - a machine without a C compiler
    pytest.skip("the general 6R C module does not build (no C compiler)", allow_module_level=True)


def _match(a, b):
    """Largest distance between the multisets a and b of complex numbers, optimally paired."""
    D = np.abs(a[:, None] - b[None])
    r, c = linear_sum_assignment(D)
    return D[r, c].max()


def _similar(eigenvalues, rng, cond=10.0):
    """A real matrix with the given spectrum (real values, complex pairs given once as
    a + bi with b > 0): a block diagonal of 1 x 1 and 2 x 2 [[a, b], [-b, a]] blocks turned by
    a random similarity of modest condition number."""
    blocks = []
    for lam in eigenvalues:
        if np.imag(lam) == 0:
            blocks.append(np.array([[np.real(lam)]]))
        else:
            a, b = np.real(lam), np.imag(lam)
            blocks.append(np.array([[a, b], [-b, a]]))
    n = sum(b.shape[0] for b in blocks)
    D = np.zeros((n, n))
    k = 0
    for b in blocks:
        D[k : k + b.shape[0], k : k + b.shape[0]] = b
        k += b.shape[0]
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    S = U @ np.diag(np.geomspace(1.0, cond, n)) @ V
    return S @ D @ np.linalg.inv(S)


def _spectrum(eigenvalues):
    out = []
    for lam in eigenvalues:
        out += [lam] if np.imag(lam) == 0 else [lam, np.conj(lam)]
    return np.array(out, dtype=complex)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 12, 24, 33])
def test_eigvals_random_matrices_match_lapack(n):
    rng = np.random.default_rng(n)
    A = rng.standard_normal((60, n, n)) * rng.uniform(0.01, 100.0, (60, 1, 1))
    lam, status = native_g6r.eigvals(A)
    assert (status == 0).all()
    ref = np.linalg.eigvals(A)
    for i in range(A.shape[0]):
        scale = np.abs(ref[i]).max()
        assert _match(lam[i], ref[i]) < 1e-12 * n * scale, i
        # complex pairs adjacent, positive imaginary part first
        im = lam[i].imag
        k = 0
        while k < n:
            if im[k] != 0:
                assert im[k] > 0 and lam[i][k + 1] == np.conj(lam[i][k])
                k += 2
            else:
                k += 1


def test_eigvals_known_spectra():
    rng = np.random.default_rng(7)
    cases = [
        [3.0, -1.0, 0.5, 2.0 + 1.0j, -0.1 + 4.0j],  # real and complex pairs
        [1.0, 1.0 + 1e-7, 1.0 - 1e-7, 1.0 + 2e-7, -2.0],  # a tight real cluster
        [0.5 + 1.0j, 0.5 + 1.0j + 1e-6, 0.5 + 1.0j - 1e-6j, 3.0],  # clustered complex pairs
        [0.0, 1e-9, 1.0, -1.0, 5.0 + 0.1j],  # a zero eigenvalue: singular matrix
        [1e3, 1e-3, -1e2 + 1e2j, 7.0],  # widely spread magnitudes
        [1j, 1j, 1j, 1j, 2.0, -3.0],  # +-i, 4-fold (like the general 6R companion's)
    ]
    for spec in cases:
        A = _similar(spec, rng)
        want = _spectrum(spec)
        lam, status = native_g6r.eigvals(A[None])
        assert status[0] == 0
        ref = np.linalg.eigvals(A)
        # as close to the truth as LAPACK is (clusters are ill conditioned for both), and
        # close in absolute terms for the well-separated ones
        err, err_ref = _match(lam[0], want), _match(ref, want)
        assert err <= max(10 * err_ref, 1e-12 * np.abs(want).max()), (spec, err, err_ref)


def test_eigvals_special_matrices():
    n = 9
    # diagonal, upper triangular, zero, the companion of a polynomial with known roots
    roots = np.array([-3.0, -1.0, 0.0, 0.25, 0.5, 2.0, 1.0 + 2.0j, 1.0 - 2.0j, 4.0])
    c = np.poly(roots).real
    comp = np.zeros((n, n))
    comp[0] = -c[1:]
    comp[np.arange(1, n), np.arange(n - 1)] = 1.0
    tri = np.triu(np.random.default_rng(3).standard_normal((n, n)))
    mats = [np.diag(np.arange(n, dtype=float)), tri, np.zeros((n, n)), comp]
    truths = [np.arange(n), np.diag(tri), np.zeros(n), roots]
    lam, status = native_g6r.eigvals(np.stack(mats))
    assert (status == 0).all()
    for i, want in enumerate(truths):
        assert _match(lam[i], want.astype(complex)) < 1e-10, i


def test_eigvals_bad_input_status():
    A = np.random.default_rng(0).standard_normal((3, 5, 5))
    A[1, 2, 3] = np.nan
    A[2, 0, 0] = np.inf
    lam, status = native_g6r.eigvals(A)
    assert list(status) == [0, -2, -2]
    assert np.isnan(lam[1:]).all() and np.isfinite(lam[0]).all()
    lam, status = native_g6r.eigvals(np.eye(65)[None])
    assert status[0] == -3 and np.isnan(lam).all()


# ------------------------------------------------------------- the eigen step on real arms


def _arm(name):
    if name == "ur5":
        return SerialRobot.load("ur5", backend="reference")
    if name == "jaco":
        return jaco_arm("jaco_c")
    return random_6r_arm(11, "random6r_c")


def _pencils(arm, n, seed):
    (g,), _ = arm._general()
    q = np.random.default_rng(seed).uniform(-np.pi, np.pi, (n, 6))
    w, o, G = g._arranged(arm.fk(q))
    M, _ = g._pencil(w, o, G, g._left_batch(w, o, G))
    return g, M


@pytest.mark.parametrize("name", ["ur5", "jaco", "random"])
def test_eigen_step_c_equals_numpy(name, monkeypatch):
    """Per pose the same real eigenvalues x3 (to 1e-9 relative) and the same null vectors
    (up to sign) from the C step and its numpy twin; with a condition threshold that sends
    some poses to QZ, the same again (C statuses -> the same QZ)."""
    g, M = _pencils(_arm(name), 80, 5)
    for limit in (general6r.COND_STANDARD, None):
        if limit is None:  # a threshold in the middle of this batch's conditions
            cond = np.linalg.cond(M[:, 2], 1)
            limit = float(np.median(cond))
            monkeypatch.setattr(general6r, "COND_STANDARD", limit)
        ia, xa, Va = g._eigen(M, "numpy")
        ib, xb, Vb = g._eigen(M, "c")
        for n in range(M.shape[0]):
            a, b = xa[ia == n], xb[ib == n]
            assert a.shape == b.shape, (n, a, b)
            oa, ob = np.argsort(a), np.argsort(b)
            # both are rounded roots of a pencil whose roots are conditioned ~1e-8 (the
            # UR5's); Newton polishes them. Close to each other, and as accurate: the
            # residual of (x, v) in M(x) v = 0 is as small for C as for LAPACK
            assert np.allclose(a[oa], b[ob], rtol=1e-6, atol=1e-9), n
            va, vb = Va[ia == n][oa], Vb[ib == n][ob]
            sign = np.sign(np.sum(va * vb, axis=1))[:, None]
            assert np.abs(va - sign * vb).max() < 1e-4, n

            def residual(x, v, n=n):
                Mx = M[n, 0] + M[n, 1] * x[:, None, None] + M[n, 2] * (x * x)[:, None, None]
                r = np.linalg.norm(np.einsum("rij,rj->ri", Mx, v), axis=1)
                return r / np.linalg.norm(Mx, axis=(1, 2))

            assert (residual(b[ob], vb) <= 10 * residual(a[oa], va) + 1e-11).all(), n


def test_eigen_step_status_on_singular_m2():
    """An exactly singular M2 (and a NaN pose) get a status, no roots: QZ solves them."""
    g, M = _pencils(_arm("random"), 3, 6)
    M = M.copy()
    M[1, 2, 4] = 0.0  # a zero row of M2
    M[2, 0, 0, 0] = np.nan
    status, nreal, x, V = native_g6r.eigen(M, general6r.COND_STANDARD, 1e-6, general6r._START)
    assert status[0] == 0 and nreal[0] > 0
    assert status[1] == 1 and status[2] != 0
    assert (nreal[1:] == 0).all() and np.isnan(x[1:]).all() and np.isnan(V[1:]).all()
    assert np.isnan(x[0, nreal[0] :]).all()
    # and the solver still answers every pose through QZ where the C step declined
    idx, _, _ = g._eigen(M[:2], "c")
    assert set(np.unique(idx)) == {0, 1}


@pytest.mark.parametrize("name", ["ur5", "jaco", "random"])
def test_solver_c_engine_same_solutions(name):
    """ik_all through the C eigen step and through numpy: the same number of valid
    solutions per pose and the same sets (after matching: 1e-7, the solver's own identity
    of two solutions, most to 1e-9), each reproducing T to 1e-10."""
    arm = _arm(name)
    elim, _ = arm._general()
    q = np.random.default_rng(12).uniform(-np.pi, np.pi, (150, 6))
    T = arm.fk(q)
    Qa, Va = general6r.solve(arm, T, elim, engine="numpy")
    Qb, Vb = general6r.solve(arm, T, elim, engine="c")
    assert np.array_equal(Va.sum(1), Vb.sum(1))
    gaps = []
    for i in range(T.shape[0]):
        A, B = Qa[i][Va[i]], Qb[i][Vb[i]]
        if A.size:
            d = np.abs((A[:, None] - B[None] + np.pi) % (2 * np.pi) - np.pi).max(-1)
            # Newton stops at fk = T to 1e-10 from slightly different starts: the same
            # solution to ~cond(J) 1e-10 in q (up to ~1e-8 seen near singular poses);
            # 1e-7 is the solver's own test of two solutions being one (solve's dedupe)
            assert d.min(0).max() < 1e-7 and d.min(1).max() < 1e-7, i
            gaps.append(d.min(0))
    assert np.median(np.concatenate(gaps)) < 1e-9
    Tq = arm.fk(np.where(Vb[..., None], Qb, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[Vb].max() < 1e-10


def test_engine_choice():
    ref = _arm("random")
    assert general6r.eigen_engine(ref) == "numpy"  # reference backend: pure numpy
    assert general6r.eigen_engine(ref, "c") == "c"
    with pytest.raises(general6r.InputError, match="engine must be"):
        general6r.eigen_engine(ref, "lapack")


@pytest.mark.parametrize("name,count", [("jaco", 300), ("ur5", 300), ("random", 300)])
def test_complete_through_the_c_engine(name, count, monkeypatch):
    """test_ik_general6r's completeness evidence with the C eigen step: the original q among
    the valid solutions on every non-singular in-limit pose, each valid one reproducing T
    to 1e-10 in the arm's reference (DH-matrix) fk."""
    monkeypatch.setattr(general6r, "eigen_engine", lambda arm, engine="auto": "c")
    arm = _arm(name)
    rng = np.random.default_rng(2000 + count + len(name))
    lim = arm.qlim
    q = rng.uniform(np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi), (count, 6))
    q = q[np.linalg.svd(arm.jacobian(q), compute_uv=False)[:, -1] > 1e-3]
    T = arm.fk(q)
    Q, valid = arm.ik_all(T, method="complete")
    err = np.abs((Q - q[:, None] + np.pi) % (2 * np.pi) - np.pi).max(-1)
    found = np.where(valid, err, np.inf).min(-1) < 1e-6
    assert found.all(), np.flatnonzero(~found)
    Tq = arm.fk(np.where(valid[..., None], Q, 0.0))
    assert np.abs(Tq - T[:, None]).max(axis=(-1, -2))[valid].max() < 1e-10
    assert np.isnan(Q[~np.isfinite(Q).all(-1)]).all()


def test_compiled_arm_uses_the_c_engine():
    arm = SerialRobot.load("ur5", backend="compiled")
    assert general6r.eigen_engine(arm) == "c"
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (20, 6))
    Q, valid = arm.ik_all(arm.fk(q), method="complete")
    ref = SerialRobot.load("ur5", backend="reference")
    Qr, Vr = ref.ik_all(ref.fk(q), method="complete")
    assert np.array_equal(valid.sum(1), Vr.sum(1))


@pytest.mark.parametrize("name", ["ur5", "jaco", "random"])
def test_starts_c_equals_numpy(name):
    """The per-pose algebra in C (deltagen_general6r_starts: arranged axes, both sides'
    coefficients, Q's QR, the pencil, the eigen step, theta 1..6) against its numpy twin
    (General6R.starts, engine="numpy"): per pose the same number of candidates, each C
    candidate close to a numpy one (before Newton: the roots' own conditioning), the same
    rank margin of Q; the poses the C path declines (status) carry the numpy answer."""
    arm = _arm(name)
    (g,), _ = arm._general()
    q = np.random.default_rng(14).uniform(-np.pi, np.pi, (300, 6))
    T = arm.fk(q)
    qa, ma = g.starts(T, "numpy")
    qb, mb = g.starts(T, "c")
    assert np.allclose(ma, mb, rtol=1e-9)
    ha, hb = np.isfinite(qa).all(-1), np.isfinite(qb).all(-1)
    assert np.array_equal(ha.sum(1), hb.sum(1))
    gaps = []
    for n in range(T.shape[0]):
        A, B = qa[n][ha[n]], qb[n][hb[n]]
        if A.size:
            d = np.abs((A[:, None] - B[None] + np.pi) % (2 * np.pi) - np.pi).max(-1)
            gaps.append(d.min(1))
            assert d.min(1).max() < 1e-3, n
    assert np.median(np.concatenate(gaps)) < 1e-9
    _, _, status = g._native().starts(T, general6r.COND_STANDARD, g.imag_tol, general6r._START)
    declined = np.flatnonzero(status != 0)
    assert np.array_equal(np.isnan(qb[declined]), np.isnan(qa[declined]))
    # a non-finite pose: status 5 and NaN from C; the numpy path answers it with nothing
    Tbad = T[:2].copy()
    Tbad[1, 0, 0] = np.nan
    qc, _, st = g._native().starts(Tbad, general6r.COND_STANDARD, g.imag_tol, general6r._START)
    assert st[1] == 5 and np.isnan(qc[1]).all()


def test_finish_c_equals_numpy():
    """deltagen_general6r_finish against general6r.distinct on constructed Newton results:
    exact and near duplicates (also across +-pi), a chain of near ones, unconverged and
    NaN slots, values outside the limits and more than 16 distinct ones."""
    rng = np.random.default_rng(15)
    N, S = 200, 40
    qs = rng.uniform(-np.pi, np.pi, (N, S, 6))
    src = rng.integers(0, S, (N, S))
    dup = rng.random((N, S)) < 0.4
    qs[dup] = qs[np.nonzero(dup)[0], src[dup]]  # copies of other slots
    qs += np.where(rng.random((N, S, 1)) < 0.3, rng.normal(0, 3e-8, (N, S, 6)), 0.0)
    qs[:, :3] += np.array([0.0, 2 * np.pi, -2 * np.pi])[None, :, None] * (
        rng.random((N, 1, 1)) < 0.3
    )
    qs[rng.random((N, S)) < 0.05] = np.nan
    conv = (rng.random((N, S)) < rng.uniform(0.05, 0.9, (N, 1))) & np.isfinite(qs).all(-1)
    qlim = np.array([[-2.5, 2.5], [-np.inf, np.inf], [-3.0, 1.0]] + [[-np.pi, np.pi]] * 3)
    for limits in (True, False):
        qa, va, fa = general6r.distinct(qs, conv, qlim, np.ones(6, bool), limits)
        qb, vb, fb = native_g6r.finish(qs, conv, qlim, limits)
        assert np.array_equal(fa, fb) and np.array_equal(va, vb)
        assert np.array_equal(np.isnan(qa), np.isnan(qb))
        assert np.nanmax(np.abs(qa - qb)) < 1e-12
    assert (fa == 16).any() and (fa < 16).any() and not vb.all()


def test_polisher_is_numeric_solve():
    """numeric.polisher (the general solver's lean Newton call) gives the bits of
    numeric.solve with the same options on the compiled engine."""
    from deltagen.solve import numeric as ik_numeric

    arm = SerialRobot.load("ur5", backend="compiled")
    rng = np.random.default_rng(16)
    q = rng.uniform(-np.pi, np.pi, (64, 6))
    T = arm.fk(q)
    q0 = q + rng.normal(0, 0.05, q.shape)
    q0[::7] = rng.uniform(-np.pi, np.pi, (len(q0[::7]), 6))  # some that do not converge
    res = ik_numeric.solve(arm, T, q0, tol=1e-10, max_iter=30, restarts=0, respect_limits=False)
    qp, conv = ik_numeric.polisher(arm, 1e-10, 30)(T, q0)
    assert np.array_equal(conv, res.converged)
    assert np.array_equal(qp[conv], res.q[conv])
    assert ik_numeric.polisher(SerialRobot.load("ur5", backend="reference")) is None


def test_without_the_c_module_the_numpy_engine_serves(monkeypatch):
    """No C compiler (the module does not build): a compiled arm's complete ik_all runs
    the numpy engine and still answers."""
    arm = SerialRobot.load("ur5", backend="compiled")
    monkeypatch.setattr(native_g6r, "available", lambda: False)
    assert general6r.eigen_engine(arm) == "numpy"
    q = np.random.default_rng(19).uniform(-np.pi, np.pi, (5, 6))
    Q, valid = arm.ik_all(arm.fk(q), method="complete")
    err = np.abs((Q - q[:, None] + np.pi) % (2 * np.pi) - np.pi).max(-1)
    assert (np.where(valid, err, np.inf).min(-1) < 1e-6).all()


def _compiled(name):
    if name == "ur5":
        return SerialRobot.load("ur5", backend="compiled", threads=1)
    ref = _arm(name)
    return SerialRobot(ref.description, backend="compiled", threads=1)


@pytest.mark.parametrize(
    "name",
    [
        "ur5",
        pytest.param("jaco", marks=pytest.mark.slow),
        pytest.param("random", marks=pytest.mark.slow),
    ],
)
def test_one_call_equals_the_staged_c_path(name, monkeypatch):
    """deltagen_general6r_solve (starts, Newton through the arm's kernel pointer, finish in
    one C call) against the staged C path (three C calls with Python between, written
    apart): the same bits for every pose; one pose at a time (general6r.solve and
    ik_all's single-pose path) the same bits as the batch; poses the one call declines
    (here all of them: a condition limit of 1) get the staged path's answer."""
    arm = _compiled(name)
    elim, complete = arm._general()
    assert complete and general6r.eigen_engine(arm) == "c"
    q = np.random.default_rng(21).uniform(-np.pi, np.pi, (120, 6))
    T = np.ascontiguousarray(arm.fk(q))
    staged = general6r._solve_staged(arm, T, elim, None, 1e-10, 30, True, False, "c")
    one = general6r.solve(arm, T, elim)
    api = arm.ik_all(T, method="complete")
    for a, b in ((staged, one), (one, api)):
        assert np.array_equal(a[0], b[0], equal_nan=True) and np.array_equal(a[1], b[1])
    assert one[1].sum() > 2 * T.shape[0]  # solutions were found at all
    for i in range(0, T.shape[0], 5):
        Qi, Vi = arm.ik_all(T[i], method="complete")
        assert Qi.shape == (16, 6) and Vi.dtype == bool
        assert np.array_equal(Qi, one[0][i], equal_nan=True) and np.array_equal(Vi, one[1][i])
        Qs, Vs = general6r.solve(arm, T[i], elim)
        assert np.array_equal(Qs[0], one[0][i], equal_nan=True)
    # a non-contiguous pose: the same bits; a non-rigid or NaN one: NaN, nothing valid
    Qf, Vf = arm.ik_all(np.asfortranarray(T[3]), method="complete")
    assert np.array_equal(Qf, one[0][3], equal_nan=True) and np.array_equal(Vf, one[1][3])
    for bad in (T[3] * 1.5, np.where(np.eye(4, dtype=bool), np.nan, T[3])):
        Qb, Vb = arm.ik_all(bad, method="complete")
        assert Qb.shape == (16, 6) and np.isnan(Qb).all() and not Vb.any()
    # every pose declined by the one call: the staged path answers, the same bits
    monkeypatch.setattr(general6r, "COND_STANDARD", 1.0)
    fresh = _compiled(name) if name != "ur5" else SerialRobot.load("ur5", backend="compiled")
    (g,), _ = fresh._general()
    status = general6r._one_call(fresh, g, 1e-10, 30, True)(T[:10])[2]
    assert (status != 0).all()
    a = general6r._solve_staged(fresh, T[:10], [g], None, 1e-10, 30, True, False, "c")
    b = general6r.solve(fresh, T[:10], [g])
    assert np.array_equal(a[0], b[0], equal_nan=True) and np.array_equal(a[1], b[1])
