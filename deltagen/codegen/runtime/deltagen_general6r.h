/* deltagen_general6r.h: the eigen step of the general 6R inverse kinematics
 * (deltagen/solve/general6r.py), batched over poses (hand-written, part of deltagen; one
 * arm-independent module, compiled once: deltagen/native/general6r.py).
 *
 * Per pose, the 12 x 12 quadratic matrix polynomial M(x) = M0 + M1 x + M2 x^2 of the
 * Raghavan-Roth elimination (Raghavan & Roth 1993; Manocha & Canny 1994, the companion
 * linearisation): its real eigenvalues x (x = tan(phi3 / 2)) and null vectors v of M(x),
 * where M2 is well conditioned; a status code where it is not (the caller solves that pose
 * by QZ on the pencil). C99, reentrant, no heap, no globals, libm only.
 */
#ifndef DELTAGEN_GENERAL6R_H
#define DELTAGEN_GENERAL6R_H

#include "deltagen_eigen.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi: begin (deltagen/native/build.py hands this part to cffi's cdef) */

/* Real eigenvalues of the companion form, per pose.
 *   M        (count, 3, 12, 12) row-major: M0, M1, M2 of each pose (dimensionless)
 *   cond_limit  the largest 1-norm condition number of M2 solved here (the companion
 *            matrix [[0, I], [-M2^-1 M0, -M2^-1 M1]] is formed with M2^-1)
 *   imag_tol an eigenvalue is real when |Im| <= imag_tol (1 + |Re|)
 *   start    (12,) the start vector of the inverse iteration for the null vectors
 * Outputs, per pose n:
 *   status   (count,): 0 solved; 1 M2 singular or its condition above cond_limit;
 *            2 the QR iteration failed or a non-finite entry; 3 a null vector failed
 *            (for status != 0 nreal is 0: solve the pose another way)
 *   nreal    (count,): number of real eigenvalues, r <= 24
 *   x        (count, 24): the real eigenvalues in slots 0..r-1 (NaN after)
 *   V        (count, 24, 12): unit null vectors of M(x) (one step of inverse iteration on
 *            M(x) + 1e-13 max|M(x)| I from `start`) in the same slots (NaN after) */
void deltagen_general6r_eigen(const double *M, int count, double cond_limit, double imag_tol,
                              const double *start, int *status, int *nreal, double *x,
                              double *V);

/* The per-arm data of one arrangement of the loop (general6r.General6R): the arm's joint
 * axes, the arrangement, the cached left side and the fixed interpolation matrices. */
typedef struct {
    double T0inv[16];        /* inverse of the tool pose at q = 0 (4 x 4) */
    double w[18], o[18];     /* joint axes: unit directions, points (6 x 3, base frame, m) */
    int order[6];            /* arranged joint j is the arm's joint order[j] */
    int shift, reverse;      /* the arrangement (General6R.shift, .reverse) */
    int left_mode;           /* 0 left side fixed, 1 carried by G^-1, 2 interpolated per pose */
    double left_fixed[378];  /* (27, 14) left coefficients of the fixed axes (modes 0, 1) */
    double delta[3];         /* the fixed shifts of theta 3, 4, 5 (rad) */
    double B2inv[81], B3inv[729], half3[729]; /* interpolation and half-angle maps */
} deltagen_general6r_arm;

#define DELTAGEN_GENERAL6R_SLOTS 16

/* Candidates of every pose (General6R.starts, the standard eigen path, batched in C).
 *   T        (count, 4, 4) tool poses (m)
 *   q        (count, 16, 6) out: candidates in the arm's joint order (rad), NaN in unused
 *            slots (not yet polished: Newton follows)
 *   margin   (count,) out: Q's rank margin (min / max |diag R| of its QR)
 *   status   (count,) out: 0 done; 1-3 the eigen step's status (deltagen_general6r_eigen);
 *            4 Q nearly rank deficient (margin <= 1e-8); 5 a non-finite T. For status != 0
 *            q is NaN: the caller solves the pose by the numpy path (SVD, QZ). */
void deltagen_general6r_starts(const double *T, int count, const deltagen_general6r_arm *arm,
                               double cond_limit, double imag_tol, const double *start, double *q,
                               double *margin, int *status);

/* The distinct solutions of every pose (general6r.solve after Newton): each converged
 * candidate fitted into the limits (geometry/limits.py fit_limits, deltagen_limits.h);
 * one within 1e-7 rad (every joint, wrapped) of an earlier converged candidate is dropped;
 * the rest fill the first of the 16 slots in candidate order.
 *   qs       (count, S, 6) Newton's results (rad); conv (count, S): 1 where converged
 *   qlim     (6, 2) joint limits (rad; +-INFINITY where none); limits: 0 ignores them
 *   fitted   (count, S, 6) out: every candidate fitted into the limits (scratch)
 *   q        (count, 16, 6) out: the solutions, NaN in unused slots
 *   valid    (count, 16) out: 1 where a solution is within the limits (or limits == 0)
 *   found    (count,) out: the number of distinct solutions */
void deltagen_general6r_finish(const double *qs, const unsigned char *conv, int count, int S,
                               const double *qlim, int limits, double *fitted, double *q,
                               unsigned char *valid, int *found);

/* An arm's damped Newton kernel (the generated deltagen_<arm>_ik_newton: its header documents
 * every argument; the options struct is the runtime's deltagen_ik_newton.h, opaque here).
 * The general 6R module is arm-independent: the arm's kernel comes in as a pointer. */
struct deltagen_ik_options;
typedef int (*deltagen_general6r_newton_fn)(size_t n, const struct deltagen_ik_options *options,
                                            const double *T_target, const double *q0,
                                            const double *qlim, double *q, double *err_p,
                                            double *err_r, int32_t *iterations,
                                            int8_t *status);

/* Every solution of every pose in one call (general6r.solve on the C path): per pose the
 * candidates (deltagen_general6r_starts), each polished by the arm's Newton kernel (one
 * call per pose on its finite candidates; converged: status DELTAGEN_OK and q, err_p, err_r
 * finite), then the limits fit and the duplicates (deltagen_general6r_finish, S = 16).
 * Every pose is independent of the others: a batch gives each pose the bits it gets alone.
 *   T        (count, 4, 4) tool poses (m)
 *   arm, cond_limit, imag_tol, start: as deltagen_general6r_starts
 *   newton, newton_options: the arm's Newton kernel and its options (restarts 0)
 *   newton_qlim (6, 2) the limits handed to the Newton kernel (rad), or NULL
 *   qlim, limits: as deltagen_general6r_finish
 *   q        (count, 16, 6) out: the solutions (rad), NaN in unused slots
 *   valid    (count, 16) out: 1 where a solution is valid (deltagen_general6r_finish)
 *   found    (count,) out: the number of distinct solutions
 *   status   (count,) out: 0 done; 1-5 deltagen_general6r_starts' status; 6 the Newton
 *            kernel rejected its arguments. For status != 0 q is NaN, valid 0, found 0: the
 *            caller solves the pose another way (the numpy path). */
void deltagen_general6r_solve(const double *T, int count, const deltagen_general6r_arm *arm,
                              double cond_limit, double imag_tol, const double *start,
                              deltagen_general6r_newton_fn newton,
                              const struct deltagen_ik_options *newton_options,
                              const double *newton_qlim, const double *qlim, int limits,
                              double *q, unsigned char *valid, int *found, int *status);

/* cffi: end */

#ifdef __cplusplus
}
#endif

#endif /* DELTAGEN_GENERAL6R_H */
