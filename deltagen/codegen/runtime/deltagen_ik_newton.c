/* deltagen_ik_newton.c: numerical inverse kinematics, damped Newton-Raphson
 * (Levenberg-Marquardt), one attempt per target, for an arm of any number of joints.
 * Hand-written C, part of deltagen; C99, reentrant, no heap, no globals, libm only.
 *
 * The same iteration as deltagen/solve/numeric.py (its docstring is the full description;
 * its numpy engine draws its restarts from numpy's generator instead of the sequence here):
 *
 *   error    dx = [p* - p; w], w the rotation vector of R* R^T (axis * angle, exact up to
 *            pi), components outside the mask set to 0; |dx| = hypot(|dp|, |w|);
 *   damping  lambda^2 = (mu + c0 + K (1 - (s / S_WELL)^2)_+) |dx|^2, mu the row's LM
 *            parameter, s an estimate of the smallest singular value of the matched rows
 *            of J: three steps of inverse iteration on the Gram matrix (J^T J or J J^T)
 *            through its Cholesky factor. The estimate is an upper bound of sigma_min
 *            that is accurate when sigma_min is small, i.e. where the term matters.
 *            (The numpy solver takes sigma_min from an SVD.)
 *   step     k = number of matched components. n == k with negligible damping
 *            (lambda <= 1e-3 s, s >= S_WELL): Gauss elimination with partial pivoting
 *            on J dq = dx. Otherwise the damped normal equations by Cholesky:
 *            (J^T J + lambda^2 I) dq = J^T dx for n <= k, dq = J^T y with
 *            (J J^T + lambda^2 I) y = dx for n > k (minimum norm for redundant arms);
 *            then dq is scaled so that max |dq_i| <= step_limit;
 *   limits   a revolute joint outside its (finite) range is shifted by 2 pi k where
 *            that brings it inside; with free_first the attempt first iterates with only
 *            these shifts, and once |dp|, |w| <= max(tol, 1e-9) at a q outside the limits
 *            it starts again from its start point, clamped, with the limits enforced:
 *            every step is clamped, and joints the step would push through a limit are
 *            set onto it while the others solve for the rest of dx (one active-set pass,
 *            same lambda, normal equations);
 *   accept   non-monotone (Zhang-Hager, eta = 0.95): a step is taken if the new |dx| is
 *            below the running average C of the accepted errors; mu -> mu / 10 (below
 *            1e-2: 0) on acceptance, max(10 mu, 1e-2) on rejection;
 *   stop     converged when |dp| <= tol_p and |w| <= tol_r within the limits; an attempt
 *            is given up after max_iter steps, when mu > 1e12, or (window > 0) when |dx|
 *            did not halve over window steps;
 *   restarts a target the attempt from q0 did not solve gets up to ``restarts`` more
 *            attempts, from the points of an additive-recurrence (Kronecker) sequence in
 *            the joint box (ikn_sequence_point): deterministic and spread evenly over the
 *            limits. Stall windows while a restart is left: 3 stall_window for the attempt
 *            from q0 (usually an informed start: a slow but converging start near a
 *            singularity is not given up early), stall_window for the others; the last
 *            attempt runs to max_iter. (Without restarts the one attempt uses stall_window.)
 *            Unconverged targets return the best in-limit q seen over all attempts (the
 *            starts clamped into the limits included).
 *
 * Every array sized by the joint count N lives in the caller's work/iwork (see the header
 * for their sizes); the frames of these functions hold only scalars and 3x3 blocks.
 */
#include "deltagen_ik_newton.h"

#include <math.h>

#ifdef __FAST_MATH__
#error "deltagen's C needs IEEE arithmetic (NaN outputs, isfinite, per-point status): compile without -ffast-math"
#endif

#include "deltagen_linalg.h"

#if defined(__GNUC__) && !defined(__clang__)
/* The copy and fill loops over the joints stay loops: gcc would otherwise turn them into
 * memmove/memset calls (the joint count is a run-time value), and the runtime needs
 * nothing but libm. */
#pragma GCC optimize("no-tree-loop-distribute-patterns")
#endif

/* The per-target state of the iteration: q with its pose, Jacobian and error. */
typedef struct ikn_point {
    double *q;  /* N */
    double *T;  /* 16 */
    double *J;  /* 6 N */
    double *e;  /* 6 */
    double ep, er, err;
} ikn_point;

/* fk and J at qv, the masked error e = [p* - p; w] and its norms; 0, or -1 if not finite. */
static int ikn_eval(const deltagen_ik_arm *arm, const double *qv, const double *Tt,
                    const int32_t *mask, double *T, double *J, double e[6], double *ep,
                    double *er)
{
    int8_t st;
    (void)arm->fk_jacobian(1, qv, T, J, &st);
    double M[9];  /* R* R^T */
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            M[3 * i + j] = Tt[4 * i] * T[4 * j] + Tt[4 * i + 1] * T[4 * j + 1] + Tt[4 * i + 2] * T[4 * j + 2];
        }
    }
    for (int i = 0; i < 3; ++i) {
        e[i] = Tt[4 * i + 3] - T[4 * i + 3];
    }
    deltagen_rotation_log(M, e + 3);
    for (int i = 0; i < 6; ++i) {
        e[i] = mask[i] ? e[i] : 0.0;
    }
    *ep = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    *er = sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]);
    return (st == DELTAGEN_OK && isfinite(*ep) && isfinite(*er)) ? 0 : -1;
}

/* deltagen_sigma_min_of for the matched rows A (k x N) themselves; scratch: 2 N^2 + 2 N. */
static double ikn_sigma_min(const double *A, size_t k, size_t N, const int *zeros,
                            double *scratch)
{
    const size_t s = deltagen_gram(A, k, N, zeros, scratch);
    return deltagen_sigma_min_of(scratch, s, scratch + N * N);
}

/* The step dq (N) for the k x N matched rows A and residual r (k): Gauss elimination if
 * ``gauss`` (square, nothing fixed), else the damped normal equations with lambda^2 = lam2;
 * fixed joints get dq_i = 0. 0, or -1 if the system is numerically singular (dq = 0).
 * G0 (s0 x s0): the Gram matrix of A if the caller has it (nothing fixed), else NULL.
 * scratch: N^2 + 2 N. */
static int ikn_solve(const double *A, size_t k, size_t N, const double *r, const int *fixed,
                     double lam2, int gauss, const double *G0, size_t s0, double *dq,
                     double *scratch)
{
    double *G = scratch, *b = scratch + N * N, *inv = b + N;
    if (gauss) {
        /* "+ 0.0" (not an identity in IEEE arithmetic, so not folded): keeps these loops
         * from becoming memcpy calls, the module needs nothing but libm */
        for (size_t i = 0; i < N * N; ++i) {
            G[i] = A[i] + 0.0;
        }
        for (size_t i = 0; i < N; ++i) {
            b[i] = r[i] + 0.0;
        }
        if (deltagen_gauss(G, N, b) == 0) {
            for (size_t i = 0; i < N; ++i) {
                dq[i] = b[i];
            }
            return 0;
        }
    }
    size_t s = s0;
    if (G0 != NULL) {  /* the caller's Gram matrix (nothing fixed) */
        for (size_t i = 0; i < s * s; ++i) {
            G[i] = G0[i] + 0.0;
        }
    } else {
        s = deltagen_gram(A, k, N, fixed, G);
    }
    double trace = 0.0;
    for (size_t i = 0; i < s; ++i) {
        trace += G[i * s + i];
        G[i * s + i] += lam2;
    }
    int rc = deltagen_cholesky(G, s, inv);
    if (rc != 0) {  /* rank deficient and undamped: a shift of a few ulps of the trace */
        s = deltagen_gram(A, k, N, fixed, G);
        for (size_t i = 0; i < s; ++i) {
            G[i * s + i] += lam2 + 1e-14 * trace + 1e-300;
        }
        rc = deltagen_cholesky(G, s, inv);
    }
    if (rc != 0) {
        for (size_t i = 0; i < N; ++i) {
            dq[i] = 0.0;
        }
        return -1;
    }
    if (s == N && N <= k) {  /* (A^T A + lambda^2 I) dq = A^T r */
        for (size_t i = 0; i < N; ++i) {
            double x = 0.0;
            for (size_t row = 0; row < k; ++row) {
                x += A[row * N + i] * r[row];
            }
            b[i] = fixed[i] ? 0.0 : x;
        }
        deltagen_cholesky_solve(G, inv, s, b, dq);
    } else {  /* dq = A^T y, (A A^T + lambda^2 I) y = r */
        deltagen_cholesky_solve(G, inv, s, r, b);
        for (size_t i = 0; i < N; ++i) {
            double x = 0.0;
            for (size_t row = 0; row < k; ++row) {
                x += A[row * N + i] * b[row];
            }
            dq[i] = fixed[i] ? 0.0 : x;
        }
    }
    return 0;
}

/* q_i shifted by a multiple of 2 pi into [lo, hi] where that is possible (revolute joints
 * with finite limits), else unchanged. */
static double ikn_wrap(double qi, double lo, double hi, int wraps)
{
    const double two_pi = 6.283185307179586;
    if (!wraps || (qi >= lo && qi <= hi)) {
        return qi;
    }
    const double k = qi < lo ? ceil((lo - qi) / two_pi) : -ceil((qi - hi) / two_pi);
    const double q2 = qi + two_pi * k;
    return (q2 >= lo && q2 <= hi) ? q2 : qi;
}

/* The limits applied to q (N): 2 pi shifts only (free), or shifts then clamping. */
static void ikn_limit(double *qv, size_t N, const double *lo, const double *hi,
                      const int *wraps, int clamp)
{
    for (size_t i = 0; i < N; ++i) {
        double x = ikn_wrap(qv[i], lo[i], hi[i], wraps[i]);
        if (clamp) {
            x = x < lo[i] ? lo[i] : (x > hi[i] ? hi[i] : x);
        }
        qv[i] = x;
    }
}

static int ikn_inside(const double *qv, size_t N, const double *lo, const double *hi)
{
    for (size_t i = 0; i < N; ++i) {
        if (!(qv[i] >= lo[i] && qv[i] <= hi[i])) {
            return 0;
        }
    }
    return 1;
}

static void ikn_limit_step(double *dq, size_t N, double step_limit)
{
    double big = 0.0;
    for (size_t i = 0; i < N; ++i) {
        big = fabs(dq[i]) > big ? fabs(dq[i]) : big;
    }
    if (big > step_limit) {
        const double f = step_limit / big;
        for (size_t i = 0; i < N; ++i) {
            dq[i] *= f;
        }
    }
}

static int ikn_set(const deltagen_ik_arm *arm, size_t N, const double *qv, const double *Tt,
                   const int32_t *mask, ikn_point *pt)
{
    for (size_t i = 0; i < N; ++i) {
        pt->q[i] = qv[i];
    }
    const int rc = ikn_eval(arm, pt->q, Tt, mask, pt->T, pt->J, pt->e, &pt->ep, &pt->er);
    pt->err = hypot(pt->ep, pt->er);
    return rc;
}

/* The box restarts are drawn from (numeric.py's _sample_box): the joint limits where finite
 * (and respected); an unlimited revolute joint [-pi, pi] (or a 2 pi wide range beside its
 * one finite limit), an unlimited prismatic one [-1, 1] m (or 2 m beside its finite limit). */
static void ikn_restart_box(const deltagen_ik_arm *arm, const double *lo, const double *hi,
                            int respect, double *box_lo, double *box_hi)
{
    for (size_t i = 0; i < arm->joints; ++i) {
        const double width = arm->revolute[i] ? 6.283185307179586 : 2.0;
        const double l = respect ? lo[i] : -INFINITY, h = respect ? hi[i] : INFINITY;
        const int lf = isfinite(l) != 0, hf = isfinite(h) != 0;
        box_lo[i] = lf ? l : (hf ? h - width : -0.5 * width);
        box_hi[i] = hf ? h : box_lo[i] + width;
    }
}

/* The steps alpha_i = 1 / phi^(i+1), i = 0 .. N-1, of the additive recurrence (Kronecker)
 * sequence u_k = frac(u_0 + k alpha) in N dimensions, phi the real root > 1 of
 * x^(N+1) = x + 1 (Roberts' R_N sequence, the "generalised golden ratio": N = 1 gives the
 * golden ratio). Its points cover the unit cube evenly for every prefix length, so the
 * first restarts are already spread over the whole joint box (no clustering as with
 * random draws). */
static void ikn_sequence_steps(size_t N, double *alpha)
{
    double phi = 2.0;
    for (int i = 0; i < 60; ++i) {  /* fixed-point iteration phi = (1 + phi)^(1/(N+1)) */
        phi = pow(1.0 + phi, 1.0 / (double)(N + 1));
    }
    double a = 1.0;
    for (size_t i = 0; i < N; ++i) {
        a /= phi;
        alpha[i] = a;
    }
}

/* Restart k (k >= 1) of the sequence for ``seed``: q_i = lo_i + (hi_i - lo_i) u_i with
 * u = frac(1/2 + (seed * 7919 + k) alpha) (the seed selects a later stretch of the same
 * sequence; the 7919 keeps two seeds' stretches of a few thousand restarts apart). */
static void ikn_sequence_point(size_t N, const double *alpha, uint32_t seed, int32_t k,
                               const double *box_lo, const double *box_hi, double *qv)
{
    const double index = (double)seed * 7919.0 + (double)k;
    for (size_t i = 0; i < N; ++i) {
        double u = 0.5 + index * alpha[i];
        u -= floor(u);
        qv[i] = box_lo[i] + (box_hi[i] - box_lo[i]) * u;
    }
}

/* The body of deltagen_ik_newton for N = arm->joints joints (read there; the checks below
 * make sure arm is there before N is used). A 6-joint arm takes it with N a constant
 * (DELTAGEN_SIZED_BODY, deltagen_linalg.h). */
DELTAGEN_SIZED_BODY int ikn_newton(const deltagen_ik_arm *arm, const size_t N, double *work, int *iwork, size_t n,
               const deltagen_ik_options *restrict options, const double *restrict T_target,
               const double *restrict q0, const double *restrict qlim, double *restrict q,
               double *restrict err_p, double *restrict err_r, int32_t *restrict iterations,
               int8_t *restrict status)
{
    const double S_WELL = 1e-2;       /* sigma_min below this: the damping grows */
    const double GAUSS_REL = 1e-3;    /* Gauss elimination when lambda <= this * sigma_min */
    const double MU_START = 1e-2, MU_MAX = 1e12, ETA = 0.95, FREE_CHECK = 1e-9;
    if (n == 0) {
        return 0;
    }
    if (arm == NULL || arm->joints == 0 || arm->revolute == NULL || arm->fk_jacobian == NULL
        || work == NULL || iwork == NULL || options == NULL || T_target == NULL || q0 == NULL
        || q == NULL || err_p == NULL || err_r == NULL || iterations == NULL || status == NULL) {
        return -1;
    }
    const deltagen_ik_options o = *options;
    int k = 0;
    for (int i = 0; i < 6; ++i) {
        if (o.mask[i] != 0 && o.mask[i] != 1) {
            return -1;
        }
        k += o.mask[i];
    }
    if (k == 0 || !(o.tol_p >= 0.0) || !(o.tol_r >= 0.0) || !(o.step_limit > 0.0)
        || !(o.damping >= 0.0) || !isfinite(o.damping) || !(o.base_damping >= 0.0)
        || !isfinite(o.base_damping) || o.max_iter < 0 || o.stall_window < 0
        || o.restarts < 0) {
        return -1;
    }
    /* the scratch memory, DELTAGEN_IK_NEWTON_WORK_DOUBLES(N) and _INTS(N) */
    double *lo = work, *hi = lo + N, *start = hi + N, *best_q = start + N, *dq = best_q + N;
    double *target = dq + N, *moved = target + N, *dq2 = moved + N;    /* 8 N */
    double *A = dq2 + N, *Af = A + 6 * N;                               /* 12 N */
    double *r = Af + 6 * N, *rf = r + 6;                                /* 12 */
    double *G0 = rf + 6;                                                /* N^2 */
    ikn_point points[2];                                                /* 2 (7 N + 22) */
    double *next = G0 + N * N;
    for (int i = 0; i < 2; ++i) {
        points[i].q = next;
        points[i].T = points[i].q + N;
        points[i].J = points[i].T + 16;
        points[i].e = points[i].J + 6 * N;
        next = points[i].e + 6;
    }
    double *scratch = next;                                             /* 2 N^2 + 2 N */
    double *box_lo = scratch + 2 * N * N + 2 * N, *box_hi = box_lo + N;
    double *alpha = box_hi + N;                                         /* 3 N */
    int *wraps = iwork, *fixed = iwork + N, *zeros = iwork + 2 * N;     /* 3 N */

    const int respect = o.respect_limits != 0 && qlim != NULL;
    for (size_t i = 0; i < N; ++i) {
        lo[i] = respect ? qlim[2 * i] : -INFINITY;
        hi[i] = respect ? qlim[2 * i + 1] : INFINITY;
        wraps[i] = arm->revolute[i] && isfinite(lo[i]) && isfinite(hi[i]);
        zeros[i] = 0;
    }
    const double check_p = o.tol_p > FREE_CHECK ? o.tol_p : FREE_CHECK;
    const double check_r = o.tol_r > FREE_CHECK ? o.tol_r : FREE_CHECK;
    int have_sequence = 0;  /* the box and the steps, made at the first restart of a call */

    for (size_t row = 0; row < n; ++row) {
        const double *Tt = T_target + 16 * row;
        double *q_out = q + N * row;
        int finite = 1;
        for (size_t i = 0; i < 16; ++i) {
            finite &= isfinite(Tt[i]);
        }
        for (size_t i = 0; i < N; ++i) {
            finite &= isfinite(q0[N * row + i]);
        }
        if (!finite) {
            for (size_t i = 0; i < N; ++i) {
                q_out[i] = NAN;
            }
            err_p[row] = err_r[row] = NAN;
            iterations[row] = 0;
            status[row] = DELTAGEN_INVALID;
            continue;
        }
        ikn_point *cur = &points[0], *trial = &points[1];
        double best_ep = INFINITY, best_er = INFINITY, best_err = INFINITY;
        int32_t it = 0;
        int converged = 0;
        for (int32_t attempt = 0; attempt <= o.restarts && !converged; ++attempt) {
            /* the attempt's start: q0, then the restart sequence; its stall window */
            if (attempt == 0) {
                for (size_t i = 0; i < N; ++i) {
                    start[i] = q0[N * row + i];
                }
            } else {
                if (!have_sequence) {  /* most targets converge from q0: no pow calls then */
                    ikn_restart_box(arm, lo, hi, respect, box_lo, box_hi);
                    ikn_sequence_steps(N, alpha);
                    have_sequence = 1;
                }
                ikn_sequence_point(N, alpha, o.seed, attempt, box_lo, box_hi, start);
            }
            int32_t window = o.stall_window;
            if (o.restarts > 0) {
                window = attempt == o.restarts ? 0 : (attempt == 0 ? 3 * window : window);
            }
            int free_phase = respect && o.free_first;
            ikn_limit(start, N, lo, hi, wraps, !free_phase);
            int stuck = ikn_set(arm, N, start, Tt, o.mask, cur) != 0;
            /* the best in-limit q seen: the start clamped into the limits counts */
            for (size_t i = 0; i < N; ++i) {
                moved[i] = start[i];
            }
            ikn_limit(moved, N, lo, hi, wraps, 1);
            const ikn_point *clamped = cur;
            if (!ikn_inside(start, N, lo, hi)) {
                stuck |= ikn_set(arm, N, moved, Tt, o.mask, trial) != 0;
                clamped = trial;
            }
            if (attempt == 0 || clamped->err < best_err) {
                for (size_t i = 0; i < N; ++i) {
                    best_q[i] = moved[i];
                }
                best_ep = clamped->ep;
                best_er = clamped->er;
                best_err = clamped->err;
            }
            double mu = 0.0, cref = cur->err, qz = 1.0, chk = cur->err, s_prev = 0.0;
            double trace_prev = 0.0;
            int s_pending = 0;
            int32_t it_att = 0;
            for (;;) {
                const int inside = ikn_inside(cur->q, N, lo, hi);
                if (cur->ep <= o.tol_p && cur->er <= o.tol_r && inside) {
                    converged = 1;
                    break;
                }
                if (free_phase && !inside && cur->ep <= check_p && cur->er <= check_r) {
                    /* a solution outside the limits: again from the start, limits enforced */
                    free_phase = 0;
                    ikn_limit(start, N, lo, hi, wraps, 1);
                    stuck = ikn_set(arm, N, start, Tt, o.mask, cur) != 0;
                    mu = 0.0;
                    cref = chk = cur->err;
                    qz = 1.0;
                    s_prev = 0.0;
                    s_pending = 0;
                    continue;
                }
                if (it_att >= o.max_iter || stuck) {
                    break;
                }
                /* the matched rows of J and dx */
                size_t kk = 0;
                for (size_t c = 0; c < 6; ++c) {
                    if (o.mask[c]) {
                        for (size_t i = 0; i < N; ++i) {
                            A[kk * N + i] = cur->J[c * N + i];
                        }
                        r[kk++] = cur->e[c];
                    }
                }
                const double err2 = cur->err * cur->err;
                /* damping; a square, well-conditioned row whose damping is negligible keeps
                 * the previous sigma_min estimate (x2 safety) and goes straight to Gauss */
                double s = s_prev, lam2 = 0.0;
                if (s_pending) {
                    /* the previous step skipped its estimate (below): made now from its Gram
                     * matrix (still in G0) where the test below can use it; where it cannot
                     * (lam2 above GAUSS_REL^2 trace >= (GAUSS_REL s_prev)^2) no value of
                     * s_prev would take the shortcut */
                    s_pending = 0;
                    s = (size_t)k == N
                                && (mu + o.base_damping) * err2
                                       <= GAUSS_REL * GAUSS_REL * trace_prev
                            ? deltagen_sigma_min_of(G0, N, scratch)
                            : 0.0;
                }
                size_t s0 = 0;
                int gauss = 0, have_gram = 0;
                if ((size_t)k == N && s >= 2.0 * S_WELL) {
                    lam2 = (mu + o.base_damping) * err2;
                    gauss = lam2 <= (GAUSS_REL * s) * (GAUSS_REL * s);
                }
                if (!gauss) {  /* one Gram matrix serves the estimate and the damped step */
                    s0 = deltagen_gram(A, (size_t)k, N, zeros, G0);
                    have_gram = 1;
                    /* The estimate s is needed for the Nakamura-Hanafusa term (nonzero only
                     * for s < S_WELL) and for the Gauss test (lam2 <= (GAUSS_REL s)^2, s^2 at
                     * most the trace of G). When G - S_WELL^2 I has a Cholesky factor,
                     * sigma_min > S_WELL (so s > S_WELL too: the term is 0), and when
                     * moreover lam2 > GAUSS_REL^2 trace the Gauss test fails whatever s is:
                     * then the step is the one the estimate would give, without it (one
                     * factorisation instead of one and three solves; the error is still
                     * large, so these are most steps). The next step makes the estimate
                     * if its shortcut can use it (s_pending): the steps are those of the
                     * estimate made every time, bit for bit. */
                    const double lam2_regular = (mu + o.base_damping) * err2;
                    double trace = 0.0;
                    for (size_t i = 0; i < s0; ++i) {
                        trace += G0[i * s0 + i];
                    }
                    int regular = 0;
                    if (!((size_t)k == N && lam2_regular <= GAUSS_REL * GAUSS_REL * trace)) {
                        double *Gs = scratch, *inv = scratch + s0 * s0;
                        for (size_t i = 0; i < s0 * s0; ++i) {
                            Gs[i] = G0[i] + 0.0;
                        }
                        for (size_t i = 0; i < s0; ++i) {
                            Gs[i * s0 + i] -= S_WELL * S_WELL;
                        }
                        regular = deltagen_cholesky(Gs, s0, inv) == 0;
                    }
                    if (regular) {
                        s = 0.0;
                        s_pending = 1;
                        trace_prev = trace;
                        lam2 = lam2_regular;
                        gauss = 0;
                    } else {
                        s = deltagen_sigma_min_of(G0, s0, scratch);
                        double nh = 1.0 - (s / S_WELL) * (s / S_WELL);
                        nh = nh > 0.0 ? nh : 0.0;
                        lam2 = (mu + o.base_damping + o.damping * nh) * err2;
                        gauss = (size_t)k == N && lam2 <= (GAUSS_REL * s) * (GAUSS_REL * s)
                                && s >= S_WELL;
                    }
                }
                s_prev = s;
                for (size_t i = 0; i < N; ++i) {
                    fixed[i] = 0;
                }
                ikn_solve(A, (size_t)k, N, r, fixed, lam2, gauss, have_gram ? G0 : NULL, s0,
                          dq, scratch);
                ikn_limit_step(dq, N, o.step_limit);
                for (size_t i = 0; i < N; ++i) {
                    target[i] = cur->q[i] + dq[i];
                }
                if (respect && !free_phase) {
                    /* active set: joints pushed beyond a limit go onto it, the others solve
                     * for the rest of dx */
                    int any = 0;
                    for (size_t i = 0; i < N; ++i) {
                        const double w = ikn_wrap(target[i], lo[i], hi[i], wraps[i]);
                        const double c = w < lo[i] ? lo[i] : (w > hi[i] ? hi[i] : w);
                        fixed[i] = c != w;
                        moved[i] = fixed[i] ? c - cur->q[i] : 0.0;
                        any |= fixed[i];
                    }
                    if (any) {
                        for (size_t c = 0; c < (size_t)k; ++c) {
                            rf[c] = r[c];
                            for (size_t i = 0; i < N; ++i) {
                                rf[c] -= A[c * N + i] * moved[i];
                                Af[c * N + i] = fixed[i] ? 0.0 : A[c * N + i];
                            }
                        }
                        const double sf = ikn_sigma_min(Af, (size_t)k, N, zeros, scratch);
                        double nh = 1.0 - (sf / S_WELL) * (sf / S_WELL);
                        nh = nh > 0.0 ? nh : 0.0;
                        const double lam2f = (mu + o.base_damping + o.damping * nh) * err2;
                        ikn_solve(Af, (size_t)k, N, rf, fixed, lam2f, 0, NULL, 0, dq2, scratch);
                        ikn_limit_step(dq2, N, o.step_limit);
                        for (size_t i = 0; i < N; ++i) {
                            target[i] = cur->q[i] + (fixed[i] ? moved[i] : dq2[i]);
                        }
                    }
                }
                ikn_limit(target, N, lo, hi, wraps, !free_phase);
                const int good = ikn_set(arm, N, target, Tt, o.mask, trial) == 0;
                ++it;
                ++it_att;
                if (good && trial->err < cref) {  /* non-monotone acceptance (Zhang-Hager) */
                    const double qz_new = ETA * qz + 1.0;
                    cref = (ETA * qz * cref + trial->err) / qz_new;
                    qz = qz_new;
                    ikn_point *t = cur;
                    cur = trial;
                    trial = t;
                    mu = mu / 10.0 < MU_START ? 0.0 : mu / 10.0;
                    if (cur->err < best_err && ikn_inside(cur->q, N, lo, hi)) {
                        for (size_t i = 0; i < N; ++i) {
                            best_q[i] = cur->q[i];
                        }
                        best_ep = cur->ep;
                        best_er = cur->er;
                        best_err = cur->err;
                    }
                } else {
                    mu = mu * 10.0 > MU_START ? mu * 10.0 : MU_START;
                }
                stuck = mu > MU_MAX;
                if (window > 0 && it_att % window == 0) {
                    stuck |= cur->err > 0.5 * chk;
                    chk = cur->err;
                }
            }
        }
        const double *q_res = converged ? cur->q : best_q;
        int finite_out = 1;
        for (size_t i = 0; i < N; ++i) {
            q_out[i] = q_res[i];
            finite_out &= isfinite(q_res[i]) != 0;
        }
        err_p[row] = converged ? cur->ep : best_ep;
        err_r[row] = converged ? cur->er : best_er;
        iterations[row] = it;
        status[row] = converged ? DELTAGEN_OK : DELTAGEN_UNREACHABLE;
        finite_out &= (isfinite(err_p[row]) != 0) & (isfinite(err_r[row]) != 0);
        if (converged && !finite_out) {  /* the finite-output rule (deltagen/status.py) */
            for (size_t i = 0; i < N; ++i) {
                q_out[i] = NAN;
            }
            err_p[row] = err_r[row] = NAN;
            status[row] = DELTAGEN_INVALID;
        }
    }
    return 0;
}

int deltagen_ik_newton(const deltagen_ik_arm *arm, double *work, int *iwork, size_t n,
                       const deltagen_ik_options *restrict options,
                       const double *restrict T_target, const double *restrict q0,
                       const double *restrict qlim, double *restrict q,
                       double *restrict err_p, double *restrict err_r,
                       int32_t *restrict iterations, int8_t *restrict status)
{
    if (arm != NULL && arm->joints == 6) {
        return ikn_newton(arm, 6, work, iwork, n, options, T_target, q0, qlim, q, err_p,
                          err_r, iterations, status);
    }
    return ikn_newton(arm, arm == NULL ? 0 : arm->joints, work, iwork, n, options, T_target,
                      q0, qlim, q, err_p, err_r, iterations, status);
}
