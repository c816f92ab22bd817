/* deltagen_ik_newton.h: numerical inverse kinematics of a serial arm by damped Newton
 * (Levenberg-Marquardt), for any number of joints. Hand-written C, part of deltagen; each
 * generated arm module wraps it as deltagen_<arm>_ik_newton, passing its own fk_jacobian.
 *
 * C99, reentrant, no heap, no globals; link with libm only. The caller provides the
 * scratch memory (see DELTAGEN_IK_NEWTON_WORK_DOUBLES), so the stack use is known at
 * compile time.
 */
#ifndef DELTAGEN_IK_NEWTON_H
#define DELTAGEN_IK_NEWTON_H

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
/* Options of the numerical inverse kinematics (deltagen_ik_newton and the generated
 * deltagen_<arm>_ik_newton wrappers). */
typedef struct deltagen_ik_options {
    double tol_p;            /* position tolerance [m], >= 0 */
    double tol_r;            /* rotation tolerance [rad], >= 0 */
    double step_limit;       /* max |dq_i| per step [rad or m], > 0 (INFINITY: unlimited) */
    double damping;          /* K >= 0: weight of the singularity term of the damping */
    double base_damping;     /* c0 >= 0: damping always present, times |dx|^2 */
    int32_t max_iter;        /* Newton steps per target, >= 0 */
    int32_t stall_window;    /* stop an attempt when |dx| did not halve over this many steps
                                (0: never); with restarts: only attempts with a restart
                                left stop so, the one from q0 after 3x as many steps */
    int32_t respect_limits;  /* 1: the result stays within qlim; 0: qlim is ignored */
    int32_t free_first;      /* 1: iterate without clamping first (see the source) */
    int32_t mask[6];         /* pose components to match, vx vy vz wx wy wz: 0 or 1 */
    int32_t restarts;        /* >= 0: further attempts for a target the attempt from q0 did
                                not solve, from start points spread over the limits (see
                                deltagen_ik_newton.c, "restarts"); 0: one attempt */
    uint32_t seed;           /* which part of the restart sequence is used (deterministic) */
} deltagen_ik_options;
/* cffi: end */

/* A generated arm's fused kinematics: for n points q (n x joints), the tool pose T (n x 16,
 * 4x4 row-major), the geometric Jacobian J (n x 6 x joints, rows vx vy vz wx wy wz) and a
 * status per point (DELTAGEN_OK when the outputs are finite). */
typedef int (*deltagen_fk_jacobian_fn)(size_t n, const double *q, double *T, double *J,
                                       int8_t *status);

/* The arm the solver works on. */
typedef struct deltagen_ik_arm {
    size_t joints;                       /* number of joints, >= 1 */
    const uint8_t *revolute;             /* joints flags: 1 revolute (2 pi wrapping), 0 not */
    deltagen_fk_jacobian_fn fk_jacobian; /* the arm's fk_jacobian */
} deltagen_ik_arm;

/* Scratch memory of deltagen_ik_newton for an arm of n joints: doubles and ints. */
#define DELTAGEN_IK_NEWTON_WORK_DOUBLES(n) (3 * (n) * (n) + 39 * (n) + 56)
#define DELTAGEN_IK_NEWTON_WORK_INTS(n) (3 * (n))

/* Numerical inverse kinematics of n target poses, damped Newton attempts per target: from
 * q0, then up to options->restarts more from start points spread over the limits
 * (Levenberg-Marquardt with error-scaled damping, non-monotone acceptance, step limiting,
 * 2 pi wrapping and clamping into the joint limits; the algorithm is described in
 * deltagen/solve/numeric.py and at the top of deltagen_ik_newton.c).
 *
 * arm         in: joint count, revolute flags, fk_jacobian
 * work, iwork scratch: DELTAGEN_IK_NEWTON_WORK_DOUBLES(joints) doubles and
 *             DELTAGEN_IK_NEWTON_WORK_INTS(joints) ints, not shared with another call
 * n           number of targets
 * options     in: tolerances, damping, iteration cap, mask (see deltagen_ik_options)
 * T_target    in,  n x 16: target poses, 4x4 row-major (the rotation block and the position)
 * q0          in,  n x joints: start configurations
 * qlim        in,  joints x 2: joint limits [lower, upper] (+-INFINITY: none), or NULL
 * q           out, n x joints: the solution, or the best in-limit q seen (over all attempts)
 *             if not converged
 * err_p       out, n: |p* - p| of q [m] (matched components)
 * err_r       out, n: rotation error of q [rad] (matched components of the rotation vector)
 * iterations  out, n: Newton steps taken (all attempts)
 * status      out, n: DELTAGEN_OK (converged), DELTAGEN_UNREACHABLE (not converged within
 *             max_iter or stuck), DELTAGEN_INVALID (a non-finite value in the row's T_target
 *             or q0; q, err_p, err_r NaN, iterations 0; or, by the finite-output rule, a
 *             converged row whose q or errors are not finite: q, err_p, err_r NaN)
 * Return value: 0, or -1 if options are invalid or a pointer other than qlim is NULL while
 * n > 0 (then nothing is written).
 */
int deltagen_ik_newton(const deltagen_ik_arm *arm, double *work, int *iwork, size_t n,
                       const deltagen_ik_options *restrict options,
                       const double *restrict T_target, const double *restrict q0,
                       const double *restrict qlim, double *restrict q,
                       double *restrict err_p, double *restrict err_r,
                       int32_t *restrict iterations, int8_t *restrict status);

#ifdef __cplusplus
}
#endif

#endif /* DELTAGEN_IK_NEWTON_H */
