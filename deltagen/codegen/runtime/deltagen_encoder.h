/* deltagen_encoder.h: encoder readings <-> the geometric crank angles of a delta robot with
 * encoder offsets (a calibrated robot as built). Hand-written C, part of deltagen.
 *
 * The delta kernels take geometric crank angles. A robot file's q_offset (model/delta.py)
 * says crank angle = reading + q_offset; the Python API applies it around the kernels
 * (native/delta.py, CompiledDelta._to_crank and _from_crank), and so do the wrappers of a
 * `deltagen export` of such a robot (templates/robot.c.j2), with these functions: operation
 * for operation as the Python API (numpy's floating-point remainder for np.mod), so in double
 * the wrappers give the API's numbers.
 *
 * C99, header only (static inline), no globals; link with libm. The *f versions are the
 * float ones for --float32 exports.
 */
#ifndef DELTAGEN_ENCODER_H
#define DELTAGEN_ENCODER_H

#include <math.h>

/* Crank angles [rad] of encoder readings q [rad]: crank = q + q_offset. */
static inline void deltagen_encoder_to_crank(const double q_offset[3], const double q[3],
                                             double crank[3])
{
    for (int i = 0; i < 3; ++i) {
        crank[i] = q[i] + q_offset[i];
    }
}

/* Encoder readings of crank angles, in place: q - q_offset wrapped to (-pi, pi] as
 * pi - mod(pi - (q - q_offset), 2 pi), mod with the sign of the divisor (numpy's); left
 * as they are when every offset is 0 (the API wraps only then). */
static inline void deltagen_encoder_from_crank(const double q_offset[3], double q[3])
{
    const double pi = 3.141592653589793;
    const double two_pi = 2.0 * 3.141592653589793;
    if (q_offset[0] == 0.0 && q_offset[1] == 0.0 && q_offset[2] == 0.0) {
        return;
    }
    for (int i = 0; i < 3; ++i) {
        double r = fmod(pi - (q[i] - q_offset[i]), two_pi);
        if (r != 0.0) {
            r = r < 0.0 ? r + two_pi : r;
        } else {
            r = 0.0; /* numpy: copysign(0, 2 pi) */
        }
        q[i] = pi - r;
    }
}

/* The same in float (exports with --float32). */
static inline void deltagen_encoder_to_crankf(const float q_offset[3], const float q[3],
                                              float crank[3])
{
    for (int i = 0; i < 3; ++i) {
        crank[i] = q[i] + q_offset[i];
    }
}

static inline void deltagen_encoder_from_crankf(const float q_offset[3], float q[3])
{
    const float pi = 3.141592653589793f;
    const float two_pi = 2.0f * 3.141592653589793f;
    if (q_offset[0] == 0.0f && q_offset[1] == 0.0f && q_offset[2] == 0.0f) {
        return;
    }
    for (int i = 0; i < 3; ++i) {
        float r = fmodf(pi - (q[i] - q_offset[i]), two_pi);
        if (r != 0.0f) {
            r = r < 0.0f ? r + two_pi : r;
        } else {
            r = 0.0f;
        }
        q[i] = pi - r;
    }
}

#endif /* DELTAGEN_ENCODER_H */
