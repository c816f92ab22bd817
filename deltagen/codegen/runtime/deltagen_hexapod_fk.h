/* deltagen_hexapod_fk.h: forward kinematics of a hexapod (Stewart-Gough platform) by damped
 * Newton iteration on the leg lengths. Hand-written C, part of deltagen; the generated
 * hexapod module wraps it as deltagen_hexapod_fk, passing its own jacobian kernel.
 *
 * C99, reentrant, no heap, no globals; link with libm only.
 */
#ifndef DELTAGEN_HEXAPOD_FK_H
#define DELTAGEN_HEXAPOD_FK_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Per-point status codes of deltagen's C (the same block, with the same guard, is in every
 * generated header; the values are deltagen/status.py's). */
#ifndef DELTAGEN_STATUS_CODES
#define DELTAGEN_STATUS_CODES
#define DELTAGEN_OK 0
#define DELTAGEN_UNREACHABLE 1
#define DELTAGEN_SINGULAR 2
#define DELTAGEN_INVALID 3
#endif

/* cffi: begin (deltagen/native/build.py hands this part to cffi's cdef) */
/* Options of the hexapod forward kinematics (deltagen_hexapod_fk_newton and the generated
 * deltagen_hexapod_fk). */
typedef struct deltagen_hexapod_fk_options {
    double tol;            /* converged when max_i |l_i(pose) - l_i| <= tol [m], > 0; the
                              Newton step of that iterate is still taken (quadratic
                              convergence: the returned pose is far closer than tol) */
    double damping;        /* >= 0: Marquardt damping mu = damping * (|r| / scale)^2 times
                              diag(J^T J) (0: Gauss-Newton, the plain Newton step of a
                              square J) */
    double max_step;       /* > 0: max rotation per step [rad]; the translation step is
                              limited to max_step * scale [m] (both scaled together) */
    int32_t max_iter;      /* Newton steps per point, >= 1 */
    int32_t warm_start;    /* 1: point k > 0 starts from point k - 1's pose when that one
                              converged (a trajectory), else from its guess; 0: every point
                              from its guess */
} deltagen_hexapod_fk_options;
/* cffi: end */

/* The hexapod's fused leg kinematics at n poses (n x 16, 4x4 row-major): the leg lengths
 * (n x 6), the leg-length Jacobian dl/d(v, w) (n x 36, row-major 6 x 6) and a status per
 * point (DELTAGEN_OK; DELTAGEN_SINGULAR: a leg of zero length, J NaN). */
typedef int (*deltagen_hexapod_legs_fn)(const void *geometry, size_t n, const double *pose,
                                        double *lengths, double *J, int8_t *status);

/* Forward kinematics of n sets of leg lengths: from a start pose, damped Newton steps
 * (v, w) on the residual r = l(pose) - l (J^T J + mu diag(J^T J)) (v, w) = -J^T r; the
 * platform origin moves by v and the rotation by exp([w]) R (w in the base frame).
 *
 * legs, geometry  the leg kinematics and its first argument
 * scale           size of the robot [m] (scales the damping and the step limit), > 0
 * singular_tol    relative threshold: J^T J whose Cholesky pivot L_jj^2 is not above
 *                 singular_tol times its largest diagonal entry is singular
 * n               number of points
 * options         in: tolerance, damping, step limit, iteration cap, warm start
 * lengths         in,  n x 6: leg lengths [m]
 * guess           in,  n x 16: start poses, 4x4 row-major (R a rotation; row 3 not read)
 * pose            out, n x 16: the pose (row 3 = 0 0 0 1), or NaN if not converged
 * residual        out, n: max_i |l_i(pose) - l_i| [m] of the last iterate evaluated
 * iterations      out, n: Newton steps taken
 * status          out, n: DELTAGEN_OK (converged); DELTAGEN_UNREACHABLE (no convergence
 *                 within max_iter: lengths the platform cannot take, or a start outside
 *                 the solution's basin; pose NaN); DELTAGEN_SINGULAR (no convergence and
 *                 J singular at the last iterate; pose NaN); DELTAGEN_INVALID (a
 *                 non-finite length or guess: pose and residual NaN, iterations 0)
 * Return value: 0, or -1 if an option is out of range or a pointer is NULL while n > 0.
 */
int deltagen_hexapod_fk_newton(deltagen_hexapod_legs_fn legs, const void *geometry,
                               double scale, double singular_tol, size_t n,
                               const deltagen_hexapod_fk_options *options,
                               const double *lengths, const double *guess, double *pose,
                               double *residual, int32_t *iterations, int8_t *status);

#ifdef __cplusplus
}
#endif

#endif /* DELTAGEN_HEXAPOD_FK_H */
