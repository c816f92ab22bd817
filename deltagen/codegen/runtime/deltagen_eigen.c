/* deltagen_eigen.c: eigenvalues of a small dense real matrix (see the header).
 * Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm only.
 * Written from the algorithms' descriptions in Golub & Van Loan, "Matrix Computations",
 * 4th ed.: sec. 7.5.7 (balancing), Alg. 7.4.2 (Householder Hessenberg reduction),
 * Alg. 7.5.1 (Francis QR step) and Alg. 7.5.2 (the QR iteration with deflation). */
#include "deltagen_eigen.h"

#include <float.h>
#include <math.h>

#ifdef __FAST_MATH__
#error "deltagen's C needs IEEE arithmetic (NaN outputs, isfinite, per-point status): compile without -ffast-math"
#endif

#define AT(M, n, i, j) ((M)[(size_t)(i) * (size_t)(n) + (size_t)(j)])

void deltagen_balance(double *A, int n)
{
    /* GVL sec. 7.5.7: D^-1 A D with D diagonal, powers of 2 (no rounding), so that each
     * row and its column have comparable off-diagonal 1-norms; repeated until no scaling
     * lowers a row + column sum by 5 % (the Parlett-Reinsch rule). */
    int converged = 0;
    int sweeps = 0;
    while (!converged && sweeps++ < 100) {
        converged = 1;
        for (int i = 0; i < n; ++i) {
            double c = 0.0, r = 0.0;
            for (int j = 0; j < n; ++j) {
                if (j != i) {
                    c += fabs(AT(A, n, j, i));
                    r += fabs(AT(A, n, i, j));
                }
            }
            if (c == 0.0 || r == 0.0) {
                continue;
            }
            const double s = c + r;
            double f = 1.0;
            double g = r / 2.0;
            while (c < g) {
                f *= 2.0;
                c *= 4.0;
            }
            g = r * 2.0;
            while (c > g) {
                f /= 2.0;
                c /= 4.0;
            }
            if ((c + r) / f < 0.95 * s) {
                converged = 0;
                const double h = 1.0 / f;
                for (int j = 0; j < n; ++j) {
                    AT(A, n, i, j) *= h; /* row i times 1/f */
                }
                for (int j = 0; j < n; ++j) {
                    AT(A, n, j, i) *= f; /* column i times f */
                }
            }
        }
    }
}

void deltagen_hessenberg(double *A, int n)
{
    /* GVL Alg. 7.4.2: for column k a Householder reflection P = I - tau u u^T (u_0 = 1)
     * zeroes A[k+2:, k]; A <- P A P. */
    for (int k = 0; k < n - 2; ++k) {
        double scale = 0.0;
        for (int i = k + 1; i < n; ++i) {
            scale += fabs(AT(A, n, i, k));
        }
        if (scale == 0.0) {
            continue;
        }
        double u[64]; /* n <= 64 (deltagen_eigvals checks) */
        double sigma = 0.0;
        for (int i = k + 1; i < n; ++i) {
            u[i] = AT(A, n, i, k) / scale;
            sigma += u[i] * u[i];
        }
        const double x0 = u[k + 1];
        const double nu = copysign(sqrt(sigma), x0);
        /* P x = -nu scale e_1 with u = (x + nu e_1) / (x_0 + nu), tau = (x_0 + nu) / nu */
        const double p = x0 + nu;
        const double tau = p / nu;
        u[k + 1] = 1.0;
        for (int i = k + 2; i < n; ++i) {
            u[i] /= p;
        }
        /* left: rows k+1..n-1, columns k..n-1; s = tau u^T A accumulated row by row (the
         * inner loops run along rows: contiguous) */
        double srow[64];
        for (int j = k; j < n; ++j) {
            srow[j] = 0.0;
        }
        for (int i = k + 1; i < n; ++i) {
            const double ui = u[i];
            for (int j = k; j < n; ++j) {
                srow[j] += ui * AT(A, n, i, j);
            }
        }
        for (int i = k + 1; i < n; ++i) {
            const double ui = tau * u[i];
            for (int j = k; j < n; ++j) {
                AT(A, n, i, j) -= ui * srow[j];
            }
        }
        /* right: columns k+1..n-1, every row */
        for (int i = 0; i < n; ++i) {
            double s = 0.0;
            for (int j = k + 1; j < n; ++j) {
                s += AT(A, n, i, j) * u[j];
            }
            s *= tau;
            for (int j = k + 1; j < n; ++j) {
                AT(A, n, i, j) -= s * u[j];
            }
        }
        AT(A, n, k + 1, k) = -nu * scale;
        for (int i = k + 2; i < n; ++i) {
            AT(A, n, i, k) = 0.0;
        }
    }
}

/* The eigenvalues of the 2 x 2 block [[a, b], [c, d]]: mid +- sqrt(q), q = p^2 + b c,
 * p = (a - d) / 2; the real pair without cancellation (the larger-magnitude root first,
 * the other from the product). */
static void block2(double a, double b, double c, double d, double *wr, double *wi)
{
    const double p = 0.5 * (a - d);
    const double bc = b * c;
    const double q = p * p + bc;
    if (q >= 0.0) {
        const double z = p + copysign(sqrt(q), p);
        wr[0] = d + z;
        wr[1] = z != 0.0 ? d - bc / z : d + z;
        wi[0] = wi[1] = 0.0;
    } else {
        wr[0] = wr[1] = d + p;
        wi[0] = sqrt(-q);
        wi[1] = -wi[0];
    }
}

/* Apply the reflection I - tau u u^T, u = (1, q, r) (r used when three), to rows k..k+2
 * (columns j0..j1) from the left and to columns k..k+2 (rows i0..i1) from the right. */
static void reflect(double *H, int n, int k, int three, double tau, double q, double r, int j0,
                    int j1, int i0, int i1)
{
    for (int j = j0; j <= j1; ++j) {
        double s = AT(H, n, k, j) + q * AT(H, n, k + 1, j);
        if (three) {
            s += r * AT(H, n, k + 2, j);
        }
        s *= tau;
        AT(H, n, k, j) -= s;
        AT(H, n, k + 1, j) -= s * q;
        if (three) {
            AT(H, n, k + 2, j) -= s * r;
        }
    }
    for (int i = i0; i <= i1; ++i) {
        double s = AT(H, n, i, k) + q * AT(H, n, i, k + 1);
        if (three) {
            s += r * AT(H, n, i, k + 2);
        }
        s *= tau;
        AT(H, n, i, k) -= s;
        AT(H, n, i, k + 1) -= s * q;
        if (three) {
            AT(H, n, i, k + 2) -= s * r;
        }
    }
}

int deltagen_hessenberg_eigvals(double *H, int n, double *wr, double *wi)
{
    /* GVL Alg. 7.5.2 on the active window l..hi: deflate where a subdiagonal entry is
     * negligible beside its diagonal neighbours; a 1 x 1 or 2 x 2 window gives its
     * eigenvalues; otherwise a Francis double-shift step (Alg. 7.5.1), its shifts the
     * eigenvalues of the window's trailing 2 x 2 (exceptional shifts after 10 and 20
     * steps without deflation, as EISPACK's hqr does). Eigenvalues only: the updates stay
     * inside the window. */
    int hi = n - 1;
    int iter = 0;
    int total = 0;
    const int max_total = 40 * n;
    double norm = 0.0;
    for (int i = 0; i < n; ++i) {
        for (int j = (i > 0 ? i - 1 : 0); j < n; ++j) {
            norm += fabs(AT(H, n, i, j));
        }
    }
    while (hi >= 0) {
        int l;
        for (l = hi; l > 0; --l) {
            double s = fabs(AT(H, n, l - 1, l - 1)) + fabs(AT(H, n, l, l));
            if (s == 0.0) {
                s = norm;
            }
            if (fabs(AT(H, n, l, l - 1)) <= DBL_EPSILON * s) {
                AT(H, n, l, l - 1) = 0.0;
                break;
            }
        }
        if (l == hi) {
            wr[hi] = AT(H, n, hi, hi);
            wi[hi] = 0.0;
            hi -= 1;
            iter = 0;
            continue;
        }
        if (l == hi - 1) {
            block2(AT(H, n, hi - 1, hi - 1), AT(H, n, hi - 1, hi), AT(H, n, hi, hi - 1),
                   AT(H, n, hi, hi), wr + hi - 1, wi + hi - 1);
            hi -= 2;
            iter = 0;
            continue;
        }
        if (++total > max_total) {
            return -1;
        }
        ++iter;
        /* the shift polynomial z^2 - s z + t */
        double s, t;
        if (iter == 10 || iter == 20) {
            const double e = fabs(AT(H, n, hi, hi - 1)) + fabs(AT(H, n, hi - 1, hi - 2));
            s = 1.5 * e;
            t = e * e;
        } else {
            const double a = AT(H, n, hi - 1, hi - 1), b = AT(H, n, hi - 1, hi);
            const double c = AT(H, n, hi, hi - 1), d = AT(H, n, hi, hi);
            s = a + d;
            t = a * d - b * c;
        }
        /* first column of (H - z1)(H - z2), GVL eq. (7.5.6) */
        const double h00 = AT(H, n, l, l), h01 = AT(H, n, l, l + 1);
        const double h10 = AT(H, n, l + 1, l), h11 = AT(H, n, l + 1, l + 1);
        double x = h00 * h00 + h01 * h10 - s * h00 + t;
        double y = h10 * (h00 + h11 - s);
        double z = h10 * AT(H, n, l + 2, l + 1);
        for (int k = l; k <= hi - 2; ++k) {
            const double nrm = fabs(x) + fabs(y) + fabs(z);
            if (nrm != 0.0) {
                const double xs = x / nrm, ys = y / nrm, zs = z / nrm;
                const double nu = copysign(sqrt(xs * xs + ys * ys + zs * zs), xs);
                const double p = xs + nu;
                const int j0 = k > l ? k - 1 : l;
                const int i1 = k + 3 < hi ? k + 3 : hi;
                reflect(H, n, k, 1, p / nu, ys / p, zs / p, j0, hi, l, i1);
                if (k > l) { /* the bulge's column: exactly -nu e_1 */
                    AT(H, n, k, k - 1) = -nu * nrm;
                    AT(H, n, k + 1, k - 1) = 0.0;
                    AT(H, n, k + 2, k - 1) = 0.0;
                }
            }
            x = AT(H, n, k + 1, k);
            y = AT(H, n, k + 2, k);
            z = k + 3 <= hi ? AT(H, n, k + 3, k) : 0.0;
        }
        /* the last reflection, of two rows */
        const double nrm = fabs(x) + fabs(y);
        if (nrm != 0.0) {
            const double xs = x / nrm, ys = y / nrm;
            const double nu = copysign(sqrt(xs * xs + ys * ys), xs);
            const double p = xs + nu;
            const int k = hi - 1;
            reflect(H, n, k, 0, p / nu, ys / p, 0.0, k - 1 > l ? k - 1 : l, hi, l, hi);
            if (k - 1 >= l) {
                AT(H, n, k, k - 1) = -nu * nrm;
                AT(H, n, k + 1, k - 1) = 0.0;
            }
        }
    }
    return 0;
}

int deltagen_eigvals(double *A, int n, double *wr, double *wi)
{
    int status = 0;
    for (size_t i = 0; i < (size_t)n * (size_t)n; ++i) {
        if (!isfinite(A[i])) {
            status = -2;
        }
    }
    if (status == 0 && n > 64) {
        status = -3;
    }
    if (status == 0) {
        deltagen_balance(A, n);
        deltagen_hessenberg(A, n);
        status = deltagen_hessenberg_eigvals(A, n, wr, wi);
    }
    if (status != 0) {
        for (int k = 0; k < n; ++k) {
            wr[k] = wi[k] = NAN;
        }
    }
    return status;
}

void deltagen_eigvals_batch(double *A, int count, int n, double *wr, double *wi, int *status)
{
    for (int m = 0; m < count; ++m) {
        const size_t off = (size_t)m * (size_t)n;
        status[m] = deltagen_eigvals(A + off * (size_t)n, n, wr + off, wi + off);
    }
}
