/* deltagen_general6r.c: the eigen step of the general 6R inverse kinematics (see the
 * header). Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm
 * only. The numpy twin is General6R._eigen (deltagen/solve/general6r.py), which
 * tests/test_general6r_c.py compares this with. */
#include "deltagen_general6r.h"

#include <math.h>
#include <string.h>

#define N12 12
#define N24 24

/* LU factorisation with partial pivoting of the 12 x 12 A in place (GVL Alg. 3.4.1);
 * piv[k] the row swapped into k; -1 at an exactly zero pivot. */
static int lu12(double *A, int *piv)
{
    for (int k = 0; k < N12; ++k) {
        int p = k;
        double best = fabs(A[k * N12 + k]);
        for (int i = k + 1; i < N12; ++i) {
            if (fabs(A[i * N12 + k]) > best) {
                best = fabs(A[i * N12 + k]);
                p = i;
            }
        }
        piv[k] = p;
        if (best == 0.0) {
            return -1;
        }
        if (p != k) {
            for (int j = 0; j < N12; ++j) {
                const double t = A[k * N12 + j];
                A[k * N12 + j] = A[p * N12 + j];
                A[p * N12 + j] = t;
            }
        }
        const double inv = 1.0 / A[k * N12 + k];
        for (int i = k + 1; i < N12; ++i) {
            const double f = A[i * N12 + k] * inv;
            A[i * N12 + k] = f;
            for (int j = k + 1; j < N12; ++j) {
                A[i * N12 + j] -= f * A[k * N12 + j];
            }
        }
    }
    return 0;
}

/* Solve (LU) x = b in place for b of 12 values (LU, piv from lu12). */
static void lu12_solve(const double *LU, const int *piv, double *b)
{
    for (int k = 0; k < N12; ++k) {
        const double t = b[k];
        b[k] = b[piv[k]];
        b[piv[k]] = t;
    }
    for (int i = 1; i < N12; ++i) {
        double s = b[i];
        for (int j = 0; j < i; ++j) {
            s -= LU[i * N12 + j] * b[j];
        }
        b[i] = s;
    }
    for (int i = N12 - 1; i >= 0; --i) {
        double s = b[i];
        for (int j = i + 1; j < N12; ++j) {
            s -= LU[i * N12 + j] * b[j];
        }
        b[i] = s / LU[i * N12 + i];
    }
}

static int solve_pose(const double *M, double cond_limit, double imag_tol, const double *start,
                      int *nreal, double *x, double *V)
{
    const double *M0 = M, *M1 = M + 144, *M2 = M + 288;
    double LU[144], inv[144], col[N12];
    int piv[N12];
    *nreal = 0;
    double n1 = 0.0; /* 1-norm: the largest column sum */
    for (int j = 0; j < N12; ++j) {
        double s = 0.0;
        for (int i = 0; i < N12; ++i) {
            s += fabs(M2[i * N12 + j]);
        }
        n1 = s > n1 ? s : n1;
    }
    memcpy(LU, M2, sizeof LU);
    if (lu12(LU, piv) != 0) {
        return 1;
    }
    double n1inv = 0.0;
    for (int j = 0; j < N12; ++j) {
        for (int i = 0; i < N12; ++i) {
            col[i] = i == j ? 1.0 : 0.0;
        }
        lu12_solve(LU, piv, col);
        double s = 0.0;
        for (int i = 0; i < N12; ++i) {
            inv[i * N12 + j] = col[i];
            s += fabs(col[i]);
        }
        n1inv = s > n1inv ? s : n1inv;
    }
    if (!(n1 * n1inv <= cond_limit)) { /* also NaN */
        return 1;
    }
    /* the companion matrix [[0, I], [-M2^-1 M0, -M2^-1 M1]] (24 x 24) */
    double C[N24 * N24];
    memset(C, 0, sizeof C);
    for (int i = 0; i < N12; ++i) {
        C[i * N24 + N12 + i] = 1.0;
        for (int j = 0; j < N12; ++j) {
            double s0 = 0.0, s1 = 0.0;
            for (int k = 0; k < N12; ++k) {
                s0 += inv[i * N12 + k] * M0[k * N12 + j];
                s1 += inv[i * N12 + k] * M1[k * N12 + j];
            }
            C[(N12 + i) * N24 + j] = -s0;
            C[(N12 + i) * N24 + N12 + j] = -s1;
        }
    }
    double wr[N24], wi[N24];
    /* 8 (a generic arm) or 16 (the UR5) of the 24 eigenvalues are +-i, from the half-angle
     * substitution. Not deflated ahead: they are 4- and 8-fold and ill conditioned (LAPACK
     * finds the UR5's to ~1e-6), and taking +-i as exact shifts first
     * (GVL sec. 7.5.5) did not lower the number of QR steps (34 per matrix for a generic
     * arm, 50 for the UR5, measured on 300 poses each, with and without): the Francis
     * shifts find them as fast. */
    if (deltagen_eigvals(C, N24, wr, wi) != 0) {
        return 2;
    }
    int r = 0;
    for (int k = 0; k < N24; ++k) {
        if (!isfinite(wr[k]) || !(fabs(wi[k]) <= imag_tol * (1.0 + fabs(wr[k])))) {
            continue;
        }
        const double xk = wr[k], xx = xk * xk;
        double Mx[144], scale = 0.0;
        for (int e = 0; e < 144; ++e) {
            Mx[e] = M0[e] + M1[e] * xk + M2[e] * xx;
            scale = fabs(Mx[e]) > scale ? fabs(Mx[e]) : scale;
        }
        /* the shift keeps an exactly singular M(x) (an accurate eigenvalue) solvable and
         * moves the null vector by rounding only (General6R._null_vectors) */
        for (int i = 0; i < N12; ++i) {
            Mx[i * N12 + i] += 1e-13 * scale;
        }
        double v[N12];
        memcpy(v, start, sizeof v);
        if (lu12(Mx, piv) != 0) {
            return 3;
        }
        lu12_solve(Mx, piv, v);
        double norm = 0.0;
        for (int i = 0; i < N12; ++i) {
            norm += v[i] * v[i];
        }
        norm = sqrt(norm);
        if (!isfinite(norm) || norm == 0.0) {
            return 3;
        }
        x[r] = xk;
        for (int i = 0; i < N12; ++i) {
            V[r * N12 + i] = v[i] / norm;
        }
        ++r;
    }
    *nreal = r;
    return 0;
}

void deltagen_general6r_eigen(const double *M, int count, double cond_limit, double imag_tol,
                              const double *start, int *status, int *nreal, double *x, double *V)
{
    for (int n = 0; n < count; ++n) {
        double *xn = x + (size_t)n * N24, *Vn = V + (size_t)n * N24 * N12;
        for (int k = 0; k < N24; ++k) {
            xn[k] = NAN;
        }
        for (int k = 0; k < N24 * N12; ++k) {
            Vn[k] = NAN;
        }
        status[n] = solve_pose(M + (size_t)n * 432, cond_limit, imag_tol, start, nreal + n, xn,
                            Vn);
        if (status[n] != 0) {
            nreal[n] = 0;
            for (int k = 0; k < N24; ++k) {
                xn[k] = NAN;
            }
            for (int k = 0; k < N24 * N12; ++k) {
                Vn[k] = NAN;
            }
        }
    }
}
