/* deltagen_general6r.c: the eigen step of the general 6R inverse kinematics (see the
 * header). Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm
 * only. The numpy twin is General6R._eigen (deltagen/solve/general6r.py), which
 * tests/native/test_general6r.py compares this with. */
#include "deltagen_general6r.h"

#include "deltagen_limits.h"
#include "deltagen_linalg.h" /* deltagen_lu, deltagen_lu_solve: the 12 x 12 solves */

#include <math.h>

#ifdef __FAST_MATH__
#error "deltagen's C needs IEEE arithmetic (NaN outputs, isfinite, per-point status): compile without -ffast-math"
#endif
#include <string.h>

#define N12 12
#define N24 24

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
    if (deltagen_lu(LU, N12, piv, NULL) != 0) {
        return 1;
    }
    double n1inv = 0.0;
    for (int j = 0; j < N12; ++j) {
        for (int i = 0; i < N12; ++i) {
            col[i] = i == j ? 1.0 : 0.0;
        }
        deltagen_lu_solve(LU, piv, N12, col);
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
        if (deltagen_lu(Mx, N12, piv, NULL) != 0) {
            return 3;
        }
        deltagen_lu_solve(Mx, piv, N12, v);
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

/* ------------------------------------------------------------------ the per-pose algebra */

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* cos and sin of th. Read through a volatile: gcc would otherwise fuse the pair into GNU
 * sincos, which is not C99 (the runtime needs only C99 libm: tests/c/test_standalone.py) */
static void cos_sin(double th, double *c, double *s)
{
    volatile double angle = th;
    *c = cos(angle);
    *s = sin(angle);
}

/* out = v turned about the unit axis w by th (Rodrigues); out may be v */
static void turn(const double *w, double th, const double *v, double *out)
{
    double c, s;
    cos_sin(th, &c, &s);
    double wxv[3];
    cross3(w, v, wxv);
    const double k = dot3(w, v) * (1.0 - c);
    for (int i = 0; i < 3; ++i) {
        out[i] = v[i] * c + wxv[i] * s + w[i] * k;
    }
}

/* Raghavan & Roth's 14 quantities of a point p and a line direction l: p, l, p.p, p.l,
 * p x l, (p.p) l - 2 (p.l) p (general6r._fourteen) */
static void fourteen(const double *p, const double *l, double *f)
{
    const double pp = dot3(p, p), pl = dot3(p, l);
    double pxl[3];
    cross3(p, l, pxl);
    for (int i = 0; i < 3; ++i) {
        f[i] = p[i];
        f[3 + i] = l[i];
        f[8 + i] = pxl[i];
        f[11 + i] = pp * l[i] - 2.0 * pl * p[i];
    }
    f[6] = pp;
    f[7] = pl;
}

/* out (rows x cols) = A (rows x inner) B (inner x cols), row-major, each entry summed in
 * the order of the inner index */
static void matmul(const double *A, const double *B, int rows, int inner, int cols, double *out)
{
    for (int i = 0; i < rows; ++i) {
        for (int j = 0; j < cols; ++j) {
            double s = 0.0;
            for (int k = 0; k < inner; ++k) {
                s += A[i * inner + k] * B[k * cols + j];
            }
            out[i * cols + j] = s;
        }
    }
}

static const double GRID[3] = {0.0, 2.0943951023931957, 4.1887902047863905}; /* 0, 2pi/3, 4pi/3 */

/* Householder QR of the 14 x 8 Q (GVL Alg. 5.2.1) with U (14 x 14) accumulated: Q = U R;
 * R's upper 8 x 8 in R (row-major 8 x 8). */
static void qr14x8(const double *Q, double *U, double *R)
{
    double A[14 * 8];
    memcpy(A, Q, sizeof A);
    for (int i = 0; i < 14; ++i) {
        for (int j = 0; j < 14; ++j) {
            U[i * 14 + j] = i == j ? 1.0 : 0.0;
        }
    }
    for (int k = 0; k < 8; ++k) {
        double sigma = 0.0;
        for (int i = k; i < 14; ++i) {
            sigma += A[i * 8 + k] * A[i * 8 + k];
        }
        if (sigma == 0.0) {
            continue;
        }
        const double x0 = A[k * 8 + k];
        const double nu = copysign(sqrt(sigma), x0);
        const double p = x0 + nu, tau = p / nu;
        double u[14];
        u[k] = 1.0;
        for (int i = k + 1; i < 14; ++i) {
            u[i] = A[i * 8 + k] / p;
        }
        for (int j = k; j < 8; ++j) { /* A <- (I - tau u u^T) A */
            double t = 0.0;
            for (int i = k; i < 14; ++i) {
                t += u[i] * A[i * 8 + j];
            }
            t *= tau;
            for (int i = k; i < 14; ++i) {
                A[i * 8 + j] -= t * u[i];
            }
        }
        for (int i = 0; i < 14; ++i) { /* U <- U (I - tau u u^T) */
            double t = 0.0;
            for (int j = k; j < 14; ++j) {
                t += U[i * 14 + j] * u[j];
            }
            t *= tau;
            for (int j = k; j < 14; ++j) {
                U[i * 14 + j] -= t * u[j];
            }
        }
    }
    for (int i = 0; i < 8; ++i) {
        for (int j = 0; j < 8; ++j) {
            R[i * 8 + j] = j >= i ? A[i * 8 + j] : 0.0;
        }
    }
}

static int argmax_abs(const double *v, int n)
{
    int k = 0;
    for (int i = 1; i < n; ++i) {
        if (fabs(v[i]) > fabs(v[k])) {
            k = i;
        }
    }
    return k;
}

/* One pose: general6r.General6R.starts (_arranged, _left_batch, _pencil, _eigen,
 * _angles345, _theta6) for the standard eigen path. Returns 0, or a status (4: Q's QR
 * margin <= 1e-8, its SVD is wanted; else the eigen step's) for the numpy path. */
static int starts_pose(const double *T, const deltagen_general6r_arm *arm, double cond_limit,
                       double imag_tol, const double *start, double *q, double *margin)
{
    /* G = T T0^-1, the arranged axes (carried by G^-1 for the shifted joints) */
    double G[16];
    matmul(T, arm->T0inv, 4, 4, 4, G);
    double w0[18], o0[18], w[18], o[18];
    for (int j = 0; j < 6; ++j) {
        const double *wj = arm->w + 3 * j, *oj = arm->o + 3 * j;
        if (j < arm->shift) { /* R_G^T w, R_G^T (o - p_G) */
            for (int i = 0; i < 3; ++i) {
                w0[3 * j + i] = G[0 * 4 + i] * wj[0] + G[1 * 4 + i] * wj[1] + G[2 * 4 + i] * wj[2];
                o0[3 * j + i] = G[0 * 4 + i] * (oj[0] - G[3]) + G[1 * 4 + i] * (oj[1] - G[7]) +
                                G[2 * 4 + i] * (oj[2] - G[11]);
            }
        } else {
            memcpy(w0 + 3 * j, wj, 3 * sizeof(double));
            memcpy(o0 + 3 * j, oj, 3 * sizeof(double));
        }
    }
    for (int j = 0; j < 6; ++j) {
        const int src = (arm->shift + j) % 6;
        memcpy(w + 3 * j, w0 + 3 * src, 3 * sizeof(double));
        memcpy(o + 3 * j, o0 + 3 * src, 3 * sizeof(double));
    }
    if (arm->reverse) {
        double wr_[18], or_[18];
        for (int j = 0; j < 6; ++j) {
            for (int i = 0; i < 3; ++i) {
                wr_[3 * j + i] = -w[3 * (5 - j) + i];
                or_[3 * j + i] = o[3 * (5 - j) + i];
            }
        }
        memcpy(w, wr_, sizeof w);
        memcpy(o, or_, sizeof o);
        double Gi[16]; /* the rigid inverse [R^T, -R^T p] */
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                Gi[i * 4 + j] = G[j * 4 + i];
            }
            Gi[i * 4 + 3] = -(G[0 * 4 + i] * G[3] + G[1 * 4 + i] * G[7] + G[2 * 4 + i] * G[11]);
            Gi[12 + i] = 0.0;
        }
        Gi[15] = 1.0;
        memcpy(G, Gi, sizeof G);
    }
    /* the left side's coefficients C (27 x 14) */
    double C[27 * 14];
    if (arm->left_mode == 0) {
        memcpy(C, arm->left_fixed, sizeof C);
    } else if (arm->left_mode == 1) { /* turned by R_G^T (R_G when reversed) */
        double Rt[9];
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                Rt[i * 3 + j] = arm->reverse ? G[i * 4 + j] : G[j * 4 + i];
            }
        }
        static const int vec[4] = {0, 3, 8, 11};
        for (int m = 0; m < 27; ++m) {
            const double *c0 = arm->left_fixed + 14 * m;
            C[14 * m + 6] = c0[6];
            C[14 * m + 7] = c0[7];
            for (int v = 0; v < 4; ++v) {
                for (int i = 0; i < 3; ++i) {
                    C[14 * m + vec[v] + i] = Rt[3 * i] * c0[vec[v]] +
                                             Rt[3 * i + 1] * c0[vec[v] + 1] +
                                             Rt[3 * i + 2] * c0[vec[v] + 2];
                }
            }
        }
    } else { /* interpolated on the 27 grid points of theta 3, 4, 5 (general6r._left) */
        double values[27 * 14];
        for (int m = 0; m < 27; ++m) {
            const double t3 = GRID[m / 9] + arm->delta[0];
            const double t4 = GRID[(m / 3) % 3] + arm->delta[1];
            const double t5 = GRID[m % 3] + arm->delta[2];
            double a[3], q5[3], q4[3], p[3], l[3];
            for (int i = 0; i < 3; ++i) {
                a[i] = o[15 + i] - o[12 + i];
            }
            turn(w + 12, t5, a, q5);
            for (int i = 0; i < 3; ++i) {
                a[i] = q5[i] + o[12 + i] - o[9 + i];
            }
            turn(w + 9, t4, a, q4);
            for (int i = 0; i < 3; ++i) {
                a[i] = q4[i] + o[9 + i] - o[6 + i];
            }
            turn(w + 6, t3, a, p);
            turn(w + 12, t5, w + 15, l);
            turn(w + 9, t4, l, l);
            turn(w + 6, t3, l, l);
            fourteen(p, l, values + 14 * m);
        }
        matmul(arm->B3inv, values, 27, 27, 14, C); /* the coefficients on the grid */
    }
    /* the right side on the 9 grid points of theta 1, 2 (general6r._right) and its
     * coefficients D = B2^-1 values */
    double values2[9 * 14], D[9 * 14];
    {
        double y[3], v[3];
        for (int i = 0; i < 3; ++i) {
            y[i] = G[i * 4] * o[15] + G[i * 4 + 1] * o[16] + G[i * 4 + 2] * o[17] + G[i * 4 + 3];
            v[i] = G[i * 4] * w[15] + G[i * 4 + 1] * w[16] + G[i * 4 + 2] * w[17];
        }
        for (int m = 0; m < 9; ++m) {
            const double t1 = GRID[m / 3], t2 = GRID[m % 3];
            double a[3], z[3], z2[3], l[3];
            for (int i = 0; i < 3; ++i) {
                a[i] = y[i] - o[i];
            }
            turn(w, -t1, a, z);
            for (int i = 0; i < 3; ++i) {
                a[i] = z[i] + o[i] - o[3 + i];
            }
            turn(w + 3, -t2, a, z2);
            for (int i = 0; i < 3; ++i) {
                z2[i] += o[3 + i] - o[6 + i];
            }
            turn(w, -t1, v, l);
            turn(w + 3, -t2, l, l);
            fourteen(z2, l, values2 + 14 * m);
        }
        matmul(arm->B2inv, values2, 9, 9, 14, D);
    }
    for (int j = 0; j < 14; ++j) {
        C[j] -= D[j];
    }
    /* Q (14 x 8) = D[1:]^T; its complete QR: left null space and least squares */
    double Q[14 * 8], U[14 * 14], R[64];
    for (int i = 0; i < 14; ++i) {
        for (int j = 0; j < 8; ++j) {
            Q[i * 8 + j] = D[14 * (1 + j) + i];
        }
    }
    qr14x8(Q, U, R);
    double dmin = INFINITY, dmax = 0.0;
    for (int k = 0; k < 8; ++k) {
        const double d = fabs(R[k * 9]);
        dmin = d < dmin ? d : dmin;
        dmax = d > dmax ? d : dmax;
    }
    *margin = dmin / (dmax > 1e-300 ? dmax : 1e-300);
    if (!(*margin > 1e-8)) {
        return 4;
    }
    double pinv[8 * 14]; /* R^-1 U[:, :8]^T */
    for (int c = 0; c < 14; ++c) {
        for (int i = 7; i >= 0; --i) {
            double s = U[c * 14 + i];
            for (int j = i + 1; j < 8; ++j) {
                s -= R[i * 8 + j] * pinv[j * 14 + c];
            }
            pinv[i * 14 + c] = s / R[i * 9];
        }
    }
    /* E = (U[:, 8:]^T C^T) HALF3 (6 x 27), then M (3, 12, 12) by the fixed index maps */
    double A6[6 * 27], E[6 * 27];
    for (int r = 0; r < 6; ++r) {
        for (int m = 0; m < 27; ++m) {
            double s = 0.0;
            for (int i = 0; i < 14; ++i) {
                s += U[i * 14 + 8 + r] * C[14 * m + i];
            }
            A6[r * 27 + m] = s;
        }
    }
    matmul(A6, arm->half3, 6, 27, 27, E);
    double M[3 * 144];
    memset(M, 0, sizeof M);
    for (int p3 = 0; p3 < 3; ++p3) {
        for (int r = 0; r < 6; ++r) {
            for (int k = 0; k < 9; ++k) {
                const double e = E[r * 27 + 9 * p3 + k];
                M[144 * p3 + r * 12 + k] = e;
                M[144 * p3 + (6 + r) * 12 + k + 3] = e;
            }
        }
    }
    int nreal = 0;
    double x[N24], V[N24 * N12];
    const int status = solve_pose(M, cond_limit, imag_tol, start, &nreal, x, V);
    if (status != 0) {
        return status;
    }
    for (int k = 0; k < nreal && k < DELTAGEN_GENERAL6R_SLOTS; ++k) {
        /* theta 3, 4, 5 (general6r._angles345: x4, x5 as ratios of the largest
         * neighbouring monomials, Manocha-Canny) */
        double v[12];
        const double big = V[k * 12 + argmax_abs(V + k * 12, 12)];
        for (int i = 0; i < 12; ++i) {
            v[i] = V[k * 12 + i] / big;
        }
        int i4 = 0, j4 = 0, i5 = 0, j5 = 0;
        double best = -1.0;
        for (int i = 0; i < 3; ++i) {
            double rowmax = fmax(fmax(fabs(v[3 * i]), fabs(v[3 * i + 1])), fabs(v[3 * i + 2]));
            if (rowmax > best) {
                best = rowmax;
                i4 = i;
            }
        }
        j4 = argmax_abs(v + 3 * i4, 3);
        best = -1.0;
        for (int j = 0; j < 2; ++j) {
            double colmax = 0.0;
            for (int i = 0; i < 4; ++i) {
                colmax = fmax(colmax, fabs(v[3 * i + j]));
            }
            if (colmax > best) {
                best = colmax;
                j5 = j;
            }
        }
        for (int i = 1; i < 4; ++i) {
            if (fabs(v[3 * i + j5]) > fabs(v[3 * i5 + j5])) {
                i5 = i;
            }
        }
        const double x4 = v[(i4 + 1) * 3 + j4] / v[i4 * 3 + j4];
        const double x5 = v[i5 * 3 + j5 + 1] / v[i5 * 3 + j5];
        double th[6];
        th[2] = 2.0 * atan(x[k]) + arm->delta[0];
        th[3] = 2.0 * atan(x4) + arm->delta[1];
        th[4] = 2.0 * atan(x5) + arm->delta[2];
        /* (c1, s1, c2, s2) from Q Sigma2 = P Sigma1: Sigma2 = pinv (basis C) */
        double b[3][3], rhs[14], sig2[8];
        for (int a = 0; a < 3; ++a) {
            b[a][0] = 1.0;
            cos_sin(th[2 + a] - arm->delta[a], &b[a][1], &b[a][2]);
        }
        for (int j = 0; j < 14; ++j) {
            double s = 0.0;
            for (int m = 0; m < 27; ++m) {
                s += b[0][m / 9] * b[1][(m / 3) % 3] * b[2][m % 3] * C[14 * m + j];
            }
            rhs[j] = s;
        }
        matmul(pinv, rhs, 8, 14, 1, sig2);
        th[0] = atan2(sig2[5], sig2[2]);
        th[1] = atan2(sig2[1], sig2[0]);
        /* theta 6: Rot(w6, th6) = (R1 ... R5)^T R_G on a reference normal to w6
         * (general6r._theta6) */
        const double *w6 = w + 15;
        const double ex[3] = {1.0, 0.0, 0.0}, ey[3] = {0.0, 1.0, 0.0};
        double ref[3], y[3], c[3];
        cross3(w6, ex, ref);
        if (sqrt(dot3(ref, ref)) < 0.1) {
            cross3(w6, ey, ref);
        }
        const double rn = sqrt(dot3(ref, ref));
        for (int i = 0; i < 3; ++i) {
            ref[i] /= rn;
        }
        for (int i = 0; i < 3; ++i) {
            y[i] = G[i * 4] * ref[0] + G[i * 4 + 1] * ref[1] + G[i * 4 + 2] * ref[2];
        }
        for (int i = 0; i < 5; ++i) {
            turn(w + 3 * i, -th[i], y, y);
        }
        cross3(ref, y, c);
        th[5] = atan2(dot3(c, w6), dot3(y, ref));
        for (int j = 0; j < 6; ++j) {
            q[6 * k + arm->order[j]] = th[j];
        }
    }
    return 0;
}

void deltagen_general6r_starts(const double *T, int count, const deltagen_general6r_arm *arm,
                               double cond_limit, double imag_tol, const double *start, double *q,
                               double *margin, int *status)
{
    for (int n = 0; n < count; ++n) {
        double *qn = q + (size_t)n * DELTAGEN_GENERAL6R_SLOTS * 6;
        for (int k = 0; k < DELTAGEN_GENERAL6R_SLOTS * 6; ++k) {
            qn[k] = NAN;
        }
        margin[n] = NAN;
        int finite = 1;
        for (int k = 0; k < 16; ++k) {
            finite &= isfinite(T[16 * (size_t)n + k]) != 0;
        }
        status[n] = finite ? starts_pose(T + 16 * (size_t)n, arm, cond_limit, imag_tol, start, qn,
                                         margin + n)
                           : 5;
        if (status[n] != 0) {
            for (int k = 0; k < DELTAGEN_GENERAL6R_SLOTS * 6; ++k) {
                qn[k] = NAN;
            }
        }
    }
}

/* ------------------------------------------------------------------ distinct solutions */

void deltagen_general6r_finish(const double *qs, const unsigned char *conv, int count, int S,
                               const double *qlim, int limits, double *fitted, double *q,
                               unsigned char *valid, int *found)
{
    const double two_pi = 2 * 3.141592653589793;
    for (int n = 0; n < count; ++n) {
        double *qn = q + (size_t)n * DELTAGEN_GENERAL6R_SLOTS * 6;
        unsigned char *vn = valid + (size_t)n * DELTAGEN_GENERAL6R_SLOTS;
        double *fn = fitted + (size_t)n * (size_t)S * 6;
        const unsigned char *cn = conv + (size_t)n * (size_t)S;
        for (int k = 0; k < DELTAGEN_GENERAL6R_SLOTS * 6; ++k) {
            qn[k] = NAN;
        }
        for (int k = 0; k < DELTAGEN_GENERAL6R_SLOTS; ++k) {
            vn[k] = 0;
        }
        int taken = 0;
        for (int s = 0; s < S; ++s) {
            /* geometry/limits.py fit_limits, joint by joint (deltagen_limits.h) */
            int inside = 1;
            for (int j = 0; j < 6; ++j) {
                const double lo = qlim[2 * j], hi = qlim[2 * j + 1];
                const double x = deltagen_fit_angle(qs[((size_t)n * (size_t)S + (size_t)s) * 6 + j],
                                                    lo, hi, lo - 1e-10, hi + 1e-10);
                fn[6 * s + j] = x;
                inside &= (x >= lo - 1e-10) & (x <= hi + 1e-10);
            }
            if (!cn[s] || taken >= DELTAGEN_GENERAL6R_SLOTS) {
                continue;
            }
            /* a duplicate: within 1e-7 rad in every joint (wrapped) of an earlier converged
             * candidate (a double root, or two candidates Newton pulled together) */
            int duplicate = 0;
            for (int t = 0; t < s && !duplicate; ++t) {
                if (!cn[t]) {
                    continue;
                }
                double d = 0.0;
                for (int j = 0; j < 6; ++j) {
                    const double x = fn[6 * s + j] - fn[6 * t + j];
                    const double w = fabs(x - two_pi * floor((x + 3.141592653589793) / two_pi));
                    d = w > d ? w : d;
                }
                duplicate = d < 1e-7;
            }
            if (duplicate) {
                continue;
            }
            for (int j = 0; j < 6; ++j) {
                qn[6 * taken + j] = fn[6 * s + j];
            }
            vn[taken] = (unsigned char)(limits ? inside : 1);
            ++taken;
        }
        found[n] = taken;
    }
}

/* ------------------------------------------------------------------ the whole solve */

void deltagen_general6r_solve(const double *T, int count, const deltagen_general6r_arm *arm,
                              double cond_limit, double imag_tol, const double *start,
                              deltagen_general6r_newton_fn newton,
                              const struct deltagen_ik_options *newton_options,
                              const double *newton_qlim, const double *qlim, int limits,
                              double *q, unsigned char *valid, int *found, int *status)
{
    enum { S = DELTAGEN_GENERAL6R_SLOTS };
    for (int n = 0; n < count; ++n) {
        const double *Tn = T + 16 * (size_t)n;
        double *qn = q + (size_t)n * S * 6;
        unsigned char *vn = valid + (size_t)n * S;
        /* the candidates (deltagen_general6r_starts on one pose) */
        double cand[S * 6], margin;
        int stn = 0;
        deltagen_general6r_starts(Tn, 1, arm, cond_limit, imag_tol, start, cand, &margin, &stn);
        /* Newton on the finite candidates, in slot order (general6r.solve's rows) */
        double Tk[S * 16], q0[S * 6], qk[S * 6], err_p[S], err_r[S];
        int32_t iterations[S];
        int8_t st[S];
        int slot[S], k = 0;
        if (stn == 0) {
            for (int s = 0; s < S; ++s) {
                int finite = 1;
                for (int j = 0; j < 6; ++j) {
                    finite &= isfinite(cand[6 * s + j]) != 0;
                }
                if (finite) {
                    memcpy(Tk + 16 * k, Tn, 16 * sizeof(double));
                    memcpy(q0 + 6 * k, cand + 6 * s, 6 * sizeof(double));
                    slot[k++] = s;
                }
            }
            if (k > 0 && newton((size_t)k, newton_options, Tk, q0, newton_qlim, qk, err_p, err_r,
                                iterations, st) != 0) {
                stn = 6;
            }
        }
        status[n] = stn;
        if (stn != 0) {
            for (int i = 0; i < S * 6; ++i) {
                qn[i] = NAN;
            }
            memset(vn, 0, S);
            found[n] = 0;
            continue;
        }
        double qs[S * 6], fitted[S * 6];
        unsigned char conv[S];
        for (int i = 0; i < S * 6; ++i) {
            qs[i] = NAN;
        }
        memset(conv, 0, S);
        for (int i = 0; i < k; ++i) {
            int ok = st[i] == 0 && isfinite(err_p[i]) && isfinite(err_r[i]);
            for (int j = 0; j < 6; ++j) {
                qs[6 * slot[i] + j] = qk[6 * i + j];
                ok &= isfinite(qk[6 * i + j]) != 0;
            }
            conv[slot[i]] = (unsigned char)ok;
        }
        deltagen_general6r_finish(qs, conv, 1, S, qlim, limits, fitted, qn, vn, found + n);
    }
}
