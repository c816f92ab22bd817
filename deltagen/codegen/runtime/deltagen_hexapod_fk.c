/* deltagen_hexapod_fk.c: forward kinematics of a hexapod by damped Newton iteration (see
 * the header). Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm
 * only.
 *
 * The method is LinuxCNC genhexkins' (Newton on the leg lengths with the inverse Jacobian
 * rows (u_i, (R b_i) x u_i)), with three changes: the rotation is updated on the group,
 * R <- exp([w]) R, instead of adding to roll-pitch-yaw angles (no gimbal lock); the step
 * is damped (Levenberg-Marquardt with Marquardt's diagonal scaling, the damping
 * proportional to the squared residual, so it vanishes near the solution and the
 * convergence stays quadratic) and limited; and a converged iterate still takes its
 * Newton step, which costs no evaluation and brings the pose from within tol to within
 * about tol^2 / scale (to rounding).
 */
#include "deltagen_hexapod_fk.h"

#include <math.h>

#include "deltagen_linalg.h"

#define LEGS 6

static int all_finite(const double *x, size_t count)
{
    for (size_t k = 0; k < count; ++k) {
        if (!isfinite(x[k])) {
            return 0;
        }
    }
    return 1;
}

/* R <- exp([w]) R (Rodrigues), R row-major 3x3 inside the 4x4 T */
static void rotate_pose(double T[16], const double w[3])
{
    const double theta = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    double E[9] = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
    if (theta > 0.0) {
        /* sin(t)/t and (1 - cos t)/t^2, by their series below 1e-4 (no cancellation) */
        const double t2 = theta * theta;
        const double s = theta < 1e-4 ? 1.0 - t2 / 6.0 : sin(theta) / theta;
        const double c = theta < 1e-4 ? 0.5 - t2 / 24.0 : (1.0 - cos(theta)) / t2;
        const double K[9] = {0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                double KK = 0.0;
                for (int k = 0; k < 3; ++k) {
                    KK += K[3 * i + k] * K[3 * k + j];
                }
                E[3 * i + j] += s * K[3 * i + j] + c * KK;
            }
        }
    }
    double R[9];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            R[3 * i + j] = T[4 * i + j];
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            T[4 * i + j] = E[3 * i] * R[j] + E[3 * i + 1] * R[3 + j] + E[3 * i + 2] * R[6 + j];
        }
    }
}

/* The damped step dx (6) from J (6x6) and r (6); returns 1 if J^T J is singular by the
 * relative test (the step is then that of J^T J + singular_tol * trace / 6 * I, or zero if
 * even that fails). */
static int damped_step(const double *J, const double *r, double mu, double singular_tol,
                       double dx[6])
{
    double G[36], g[6], inv[6];
    for (int i = 0; i < 6; ++i) {
        g[i] = 0.0;
        for (int k = 0; k < LEGS; ++k) {
            g[i] += J[6 * k + i] * r[k];
        }
        for (int j = 0; j < 6; ++j) {
            double s = 0.0;
            for (int k = 0; k < LEGS; ++k) {
                s += J[6 * k + i] * J[6 * k + j];
            }
            G[6 * i + j] = s;
        }
    }
    double trace = 0.0;
    for (int i = 0; i < 6; ++i) {
        trace += G[7 * i];
        G[7 * i] *= 1.0 + mu;
    }
    double A[36];
    for (int k = 0; k < 36; ++k) {
        A[k] = G[k];
    }
    int singular = 0;
    if (deltagen_cholesky_relative(A, 6, inv, singular_tol) != 0) {
        singular = 1;
        for (int k = 0; k < 36; ++k) {
            A[k] = G[k];
        }
        for (int i = 0; i < 6; ++i) {
            A[7 * i] += singular_tol * trace / 6.0;
        }
        if (deltagen_cholesky(A, 6, inv) != 0) {
            for (int i = 0; i < 6; ++i) {
                dx[i] = 0.0;
            }
            return 1;
        }
    }
    deltagen_cholesky_solve(A, inv, 6, g, dx);
    for (int i = 0; i < 6; ++i) {
        dx[i] = -dx[i];
    }
    return singular;
}

static void fail(double *T, double *res, int8_t *st, int8_t code)
{
    for (int k = 0; k < 16; ++k) {
        T[k] = NAN;
    }
    if (code == DELTAGEN_INVALID) {
        *res = NAN;
    }
    *st = code;
}

int deltagen_hexapod_fk_newton(deltagen_hexapod_legs_fn legs, const void *geometry,
                               double scale, double singular_tol, size_t n,
                               const deltagen_hexapod_fk_options *options,
                               const double *lengths, const double *guess, double *pose,
                               double *residual, int32_t *iterations, int8_t *status)
{
    if (n == 0) {
        return 0;
    }
    if (legs == NULL || geometry == NULL || options == NULL || lengths == NULL ||
        guess == NULL || pose == NULL || residual == NULL || iterations == NULL ||
        status == NULL) {
        return -1;
    }
    if (!(options->tol > 0.0) || !(options->damping >= 0.0) || !(options->max_step > 0.0) ||
        options->max_iter < 1 || !(scale > 0.0) || !isfinite(scale) ||
        !(singular_tol > 0.0 && singular_tol < 1.0) ||
        (options->warm_start != 0 && options->warm_start != 1)) {
        return -1;
    }
    int previous_ok = 0;
    for (size_t p = 0; p < n; ++p) {
        const double *l = lengths + LEGS * p;
        double *T = pose + 16 * p;
        const double *start = guess + 16 * p;
        iterations[p] = 0;
        const double used[12] = {start[0], start[1], start[2], start[3], start[4], start[5],
                                 start[6], start[7], start[8], start[9], start[10], start[11]};
        if (!all_finite(l, LEGS) || !all_finite(used, 12)) {
            fail(T, residual + p, status + p, DELTAGEN_INVALID);
            previous_ok = 0;
            continue;
        }
        if (options->warm_start && previous_ok) {
            const double *prev = T - 16;
            for (int k = 0; k < 12; ++k) {
                T[k] = prev[k];
            }
        } else {
            for (int k = 0; k < 12; ++k) {
                T[k] = start[k];
            }
        }
        T[12] = 0.0;
        T[13] = 0.0;
        T[14] = 0.0;
        T[15] = 1.0;
        int8_t code = DELTAGEN_UNREACHABLE;
        double err = INFINITY;
        for (int32_t it = 0; it <= options->max_iter; ++it) {
            double lf[LEGS], J[36], r[LEGS], dx[6];
            int8_t leg_status;
            legs(geometry, 1, T, lf, J, &leg_status);
            if (leg_status == DELTAGEN_INVALID) {
                break; /* the iterate diverged to non-finite values */
            }
            err = 0.0;
            for (int i = 0; i < LEGS; ++i) {
                r[i] = lf[i] - l[i];
                err = fabs(r[i]) > err ? fabs(r[i]) : err;
            }
            const int converged = err <= options->tol;
            if ((it == options->max_iter && !converged) || leg_status == DELTAGEN_SINGULAR) {
                code = leg_status == DELTAGEN_SINGULAR ? DELTAGEN_SINGULAR : code;
                break;
            }
            const double rel = err / scale;
            const double mu = converged ? 0.0 : options->damping * rel * rel;
            const int singular = damped_step(J, r, mu, singular_tol, dx);
            if (singular && !converged) {
                code = DELTAGEN_SINGULAR;
            } else {
                code = DELTAGEN_UNREACHABLE;
            }
            const double dv = sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
            const double dw = sqrt(dx[3] * dx[3] + dx[4] * dx[4] + dx[5] * dx[5]);
            double shrink = 1.0;
            if (dw > options->max_step) {
                shrink = options->max_step / dw;
            }
            if (dv * shrink > options->max_step * scale) {
                shrink = options->max_step * scale / dv;
            }
            for (int i = 0; i < 3; ++i) {
                T[4 * i + 3] += shrink * dx[i];
            }
            const double w[3] = {shrink * dx[3], shrink * dx[4], shrink * dx[5]};
            rotate_pose(T, w);
            iterations[p] = it + 1;
            if (converged) {
                code = DELTAGEN_OK;
                break;
            }
        }
        residual[p] = err;
        if (code == DELTAGEN_OK && !all_finite(T, 16)) {
            code = DELTAGEN_INVALID; /* the finite-output rule */
        }
        if (code != DELTAGEN_OK) {
            fail(T, residual + p, status + p, code);
            previous_ok = 0;
        } else {
            status[p] = DELTAGEN_OK;
            previous_ok = 1;
        }
    }
    return 0;
}
