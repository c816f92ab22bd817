/* deltagen_linalg.c: small dense linear algebra for the deltagen runtime (see the header).
 * Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm only. */
#include "deltagen_linalg.h"

#include <math.h>

#ifdef __FAST_MATH__
#error "deltagen's C needs IEEE arithmetic (NaN outputs, isfinite, per-point status): compile without -ffast-math"
#endif

/* The 6 x 6 systems of a 6-joint arm (the numerical IK's Gram matrices, the mass matrix)
 * take the same bodies with the size a constant (DELTAGEN_SIZED_BODY, the header). */

void deltagen_rotation_log(const double R[9], double w[3])
{
    const double v[3] = {0.5 * (R[7] - R[5]), 0.5 * (R[2] - R[6]), 0.5 * (R[3] - R[1])};
    double c = 0.5 * (R[0] + R[4] + R[8] - 1.0);
    c = c < -1.0 ? -1.0 : (c > 1.0 ? 1.0 : c);
    const double s = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const double theta = atan2(s, c);
    const double factor = s < 1e-300 ? 1.0 : theta / s;
    for (int i = 0; i < 3; ++i) {
        w[i] = v[i] * factor;
    }
    if (c < 0.0) {
        /* (R + R^T)/2 = c I + (1 - c) a a^T: the column of the largest diagonal entry */
        double S[9];
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                S[3 * i + j] = (0.5 * (R[3 * i + j] + R[3 * j + i]) - (i == j ? c : 0.0)) / (1.0 - c);
            }
        }
        int k = 0;
        if (S[4] > S[0]) {
            k = 1;
        }
        if (S[8] > S[4 * k]) {
            k = 2;
        }
        double a[3] = {S[k], S[3 + k], S[6 + k]};
        const double norm = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        const double dot = a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
        const double scale = (dot < 0.0 ? -theta : theta) / norm;
        for (int i = 0; i < 3; ++i) {
            w[i] = a[i] * scale;
        }
    }
}

DELTAGEN_SIZED_BODY int cholesky_body(double *A, size_t s, double *inv)
{
    for (size_t j = 0; j < s; ++j) {
        double d = A[j * s + j];
        for (size_t k = 0; k < j; ++k) {
            d -= A[j * s + k] * A[j * s + k];
        }
        if (!(d > 0.0)) {
            return -1;
        }
        d = sqrt(d);
        A[j * s + j] = d;
        inv[j] = 1.0 / d;
        for (size_t i = j + 1; i < s; ++i) {
            double x = A[i * s + j];
            for (size_t k = 0; k < j; ++k) {
                x -= A[i * s + k] * A[j * s + k];
            }
            A[i * s + j] = x * inv[j];
        }
    }
    return 0;
}

int deltagen_cholesky(double *A, size_t s, double *inv)
{
    return s == 6 ? cholesky_body(A, 6, inv) : cholesky_body(A, s, inv);
}

int deltagen_cholesky_relative(double *A, size_t s, double *inv, double rtol)
{
    double largest = 0.0;
    for (size_t j = 0; j < s; ++j) {
        largest = A[j * s + j] > largest ? A[j * s + j] : largest;
    }
    if (deltagen_cholesky(A, s, inv) != 0) {
        return -1;
    }
    for (size_t j = 0; j < s; ++j) {
        if (!(A[j * s + j] * A[j * s + j] > rtol * largest)) {
            return -1;
        }
    }
    return 0;
}

DELTAGEN_SIZED_BODY void cholesky_solve_body(const double *L, const double *inv, size_t s,
                                     const double *b, double *x)
{
    for (size_t i = 0; i < s; ++i) {
        double y = b[i];
        for (size_t k = 0; k < i; ++k) {
            y -= L[i * s + k] * x[k];
        }
        x[i] = y * inv[i];
    }
    for (size_t i = s; i-- > 0;) {
        double y = x[i];
        for (size_t k = i + 1; k < s; ++k) {
            y -= L[k * s + i] * x[k];
        }
        x[i] = y * inv[i];
    }
}

void deltagen_cholesky_solve(const double *L, const double *inv, size_t s, const double *b,
                             double *x)
{
    if (s == 6) {
        cholesky_solve_body(L, inv, 6, b, x);
    } else {
        cholesky_solve_body(L, inv, s, b, x);
    }
}

int deltagen_lu(double *A, size_t s, int *piv, double *b)
{
    for (size_t j = 0; j < s; ++j) {
        size_t p = j;
        for (size_t i = j + 1; i < s; ++i) {
            if (fabs(A[i * s + j]) > fabs(A[p * s + j])) {
                p = i;
            }
        }
        if (piv != NULL) {
            piv[j] = (int)p;
        }
        if (!(A[p * s + j] != 0.0)) {
            return -1;
        }
        if (p != j) {
            for (size_t k = 0; k < s; ++k) {
                const double t = A[j * s + k];
                A[j * s + k] = A[p * s + k];
                A[p * s + k] = t;
            }
            if (b != NULL) {
                const double t = b[j];
                b[j] = b[p];
                b[p] = t;
            }
        }
        const double pivot_inv = 1.0 / A[j * s + j];
        for (size_t i = j + 1; i < s; ++i) {
            const double f = A[i * s + j] * pivot_inv;
            A[i * s + j] = f;
            for (size_t k = j + 1; k < s; ++k) {
                A[i * s + k] -= f * A[j * s + k];
            }
            if (b != NULL) {
                b[i] -= f * b[j];
            }
        }
    }
    return 0;
}

/* Back substitution U x = b in place (U: the upper triangle of LU, s x s). */
static void lu_back(const double *LU, size_t s, double *b)
{
    for (size_t i = s; i-- > 0;) {
        double x = b[i];
        for (size_t k = i + 1; k < s; ++k) {
            x -= LU[i * s + k] * b[k];
        }
        b[i] = x / LU[i * s + i];
    }
}

void deltagen_lu_solve(const double *LU, const int *piv, size_t s, double *b)
{
    for (size_t k = 0; k < s; ++k) {
        const double t = b[k];
        b[k] = b[piv[k]];
        b[piv[k]] = t;
    }
    for (size_t i = 1; i < s; ++i) {
        double x = b[i];
        for (size_t j = 0; j < i; ++j) {
            x -= LU[i * s + j] * b[j];
        }
        b[i] = x;
    }
    lu_back(LU, s, b);
}

int deltagen_gauss(double *A, size_t s, double *b)
{
    if (deltagen_lu(A, s, NULL, b) != 0) {
        return -1;
    }
    lu_back(A, s, b);
    return 0;
}

DELTAGEN_SIZED_BODY size_t gram_body(const double *A, size_t k, size_t N, const int *fixed, double *G)
{
    int any_fixed = 0;
    for (size_t i = 0; i < N; ++i) {
        any_fixed |= fixed[i];
    }
    if (N <= k && !any_fixed) {  /* the usual case, without the tests per entry */
        for (size_t i = 0; i < N; ++i) {
            for (size_t j = 0; j <= i; ++j) {
                double x = 0.0;
                for (size_t r = 0; r < k; ++r) {
                    x += A[r * N + i] * A[r * N + j];
                }
                G[i * N + j] = x;
                G[j * N + i] = x;
            }
        }
        return N;
    }
    if (N <= k) {
        for (size_t i = 0; i < N; ++i) {
            for (size_t j = 0; j <= i; ++j) {
                double x = 0.0;
                if (!fixed[i] && !fixed[j]) {
                    for (size_t r = 0; r < k; ++r) {
                        x += A[r * N + i] * A[r * N + j];
                    }
                } else if (i == j) {
                    x = 1.0;
                }
                G[i * N + j] = x;
                G[j * N + i] = x;
            }
        }
        return N;
    }
    for (size_t i = 0; i < k; ++i) {
        for (size_t j = 0; j <= i; ++j) {
            double x = 0.0;
            for (size_t c = 0; c < N; ++c) {
                x += fixed[c] ? 0.0 : A[i * N + c] * A[j * N + c];
            }
            G[i * k + j] = x;
            G[j * k + i] = x;
        }
    }
    return k;
}

size_t deltagen_gram(const double *A, size_t k, size_t N, const int *fixed, double *G)
{
    return k == 6 && N == 6 ? gram_body(A, 6, 6, fixed, G) : gram_body(A, k, N, fixed, G);
}

DELTAGEN_SIZED_BODY double sigma_min_body(const double *G0, size_t s, double *work)
{
    double *G = work, *inv = work + s * s, *x = inv + s;
    for (size_t i = 0; i < s * s; ++i) {
        G[i] = G0[i] + 0.0;  /* "+ 0.0": a loop, not a memcpy call (libm only) */
    }
    double trace = 0.0;
    for (size_t i = 0; i < s; ++i) {
        trace += G[i * s + i];
    }
    /* a shift of a few ulps of the trace keeps the factorisation defined at an exact
     * singularity; it is taken off again at the end */
    const double shift = 1e-15 * trace + 1e-300;
    for (size_t i = 0; i < s; ++i) {
        G[i * s + i] += shift;
    }
    if (cholesky_body(G, s, inv) != 0) {
        return 0.0;
    }
    for (size_t i = 0; i < s; ++i) {
        x[i] = 1.0 / (double)(i + 1) * ((i & 1) ? -1.0 : 1.0);
    }
    double lambda = trace;
    for (int it = 0; it < 3; ++it) {
        double before = 0.0, after = 0.0;
        for (size_t i = 0; i < s; ++i) {
            before += x[i] * x[i];
        }
        cholesky_solve_body(G, inv, s, x, x);
        for (size_t i = 0; i < s; ++i) {
            after += x[i] * x[i];
        }
        after = sqrt(after);
        lambda = sqrt(before) / after;
        const double scale = 1.0 / after;
        for (size_t i = 0; i < s; ++i) {
            x[i] *= scale;
        }
    }
    lambda -= shift;
    return lambda > 0.0 ? sqrt(lambda) : 0.0;
}

double deltagen_sigma_min_of(const double *G0, size_t s, double *work)
{
    return s == 6 ? sigma_min_body(G0, 6, work) : sigma_min_body(G0, s, work);
}
