/* deltagen_limits.h: a revolute joint's value fitted into its limits, for the closed-form
 * inverse kinematics (the generated deltagen_<arm>_ik_all). Hand-written C, part of
 * deltagen: geometry/limits.py's fit_limits for one revolute joint, with its constants
 * (LIMIT_TOL = 1e-10 is folded into lo_tol and hi_tol by the generator; SHIFTS = +1, -1,
 * +2, -2 turns), operation for operation as the SymPy statements it replaces printed
 * (derive/serial/ik_closed_form.py, IKKernelBuilder._fit_limits): the same doubles.
 *
 * C99, header only (static inline), no globals; link with libm. deltagen_fit_anglef is the
 * float version for --float32 exports.
 */
#ifndef DELTAGEN_LIMITS_H
#define DELTAGEN_LIMITS_H

#include <math.h>

/* The angle a [rad] wrapped into [-pi, pi), then shifted by the first of +2 pi, -2 pi,
 * +4 pi, -4 pi that lands it in [lo_tol, hi_tol] unless it is there already; a value that
 * fits is clipped onto [lo, hi]; one that does not is returned wrapped (the caller's check
 * lo_tol <= value <= hi_tol then fails, as it does for NaN).
 * lo, hi [rad]: the joint's limits (-INFINITY / INFINITY where it has none);
 * lo_tol = lo - LIMIT_TOL, hi_tol = hi + LIMIT_TOL. */
static inline double deltagen_fit_angle(double a, double lo, double hi, double lo_tol,
                                        double hi_tol)
{
    const double two_pi = 2 * 3.141592653589793;
    const double inv_two_pi = (1.0 / 2.0) / 3.141592653589793;
    const double shifts[4] = {two_pi, -two_pi, 4 * 3.141592653589793, -(4 * 3.141592653589793)};
    const double x0 = a - two_pi * floor(inv_two_pi * (a + 3.141592653589793));
    /* Limits that hold the whole circle with room to spare (lo <= -3.2, hi >= 3.2, as the
     * UR arms' +-2 pi): for |a| <= 2^20 the wrapped x0 is within 1e-9 of [-pi, pi], so it
     * fits, no shift is tried and the clip leaves it as it is; the steps below would return
     * x0 itself. With the constant limits of the generated calls the compiler keeps only
     * the |a| test (callgrind, UR5 ik_all: 54 -> ~10 instructions per call). NaN and huge
     * angles take the general path. */
    if ((lo <= -3.2) & (hi >= 3.2) & (fabs(a) <= 1048576.0)) {
        return x0;
    }
    int fits = (x0 >= lo_tol) & (x0 <= hi_tol);
    double x = x0;
    for (int k = 0; k < 4; ++k) {
        const double y = x0 + shifts[k];
        const int fy = (y >= lo_tol) & (y <= hi_tol) & !fits;
        x = fy ? y : x;
        fits = fits | fy;
    }
    return fits ? fmin(hi, fmax(lo, x)) : x;
}

/* The same in float (exports with --float32): the same operations in binary32. */
static inline float deltagen_fit_anglef(float a, float lo, float hi, float lo_tol, float hi_tol)
{
    const float two_pi = 2 * 3.141592653589793f;
    const float inv_two_pi = (1.0f / 2.0f) / 3.141592653589793f;
    const float shifts[4] = {two_pi, -two_pi, 4 * 3.141592653589793f, -(4 * 3.141592653589793f)};
    const float x0 = a - two_pi * floorf(inv_two_pi * (a + 3.141592653589793f));
    int fits = (x0 >= lo_tol) & (x0 <= hi_tol);
    float x = x0;
    for (int k = 0; k < 4; ++k) {
        const float y = x0 + shifts[k];
        const int fy = (y >= lo_tol) & (y <= hi_tol) & !fits;
        x = fy ? y : x;
        fits = fits | fy;
    }
    return fits ? fminf(hi, fmaxf(lo, x)) : x;
}

#endif /* DELTAGEN_LIMITS_H */
