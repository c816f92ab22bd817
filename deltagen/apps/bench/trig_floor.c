/* trig_floor.c: the arithmetic floor of a batched serial-arm kernel, measured by
 * `deltagen bench --bars` (deltagen/apps/bench/bars.py, "Puma fk <= 2.0x the floor").
 *
 * Two loops, compiled by native/toolchain.py with the generated modules' own flags
 * (compile_flags: -std=c99 -O3 -fno-math-errno -march=native, and -fopenmp-simd with
 * DELTAGEN_FLOOR_VECTOR_MATH where glibc's libmvec is present):
 *
 * deltagen_floor_trig  the trigonometry a kernel of `angles` joint angles cannot avoid: per
 *                      point and angle one sine and one cosine, in the generated kernels' own
 *                      shape -- blocks of DELTAGEN_FLOOR_BLOCK points gathered from the
 *                      row-major (n, angles) input into columns, the columns padded to whole
 *                      vectors of DELTAGEN_FLOOR_TRIG_LANES, a sine loop and a cosine loop
 *                      per angle that the compiler turns into libmvec's vector sin and cos (8 lanes with
 *                      AVX-512: _ZGVeN8v_sin / _ZGVeN8v_cos) or scalar libm calls without it.
 *                      The results are summed per angle (a simd reduction) so that nothing
 *                      is optimised away and a test can check them against numpy.
 * deltagen_floor_fma   the machine's vector fused multiply-add throughput as this compiler
 *                      emits it: DELTAGEN_FLOOR_CHAINS independent accumulators (enough
 *                      chains to cover the FMA latency on every pipe) updated by
 *                      acc = fma(acc, a, b) `iterations` times; 2 floating-point operations
 *                      per update.
 */
#include <math.h>
#include <stddef.h>

#ifdef __FAST_MATH__
#error "the floor must be built as the kernels are: without -ffast-math"
#endif

#if defined(DELTAGEN_FLOOR_VECTOR_MATH) && defined(__GNUC__) && defined(__x86_64__)
/* as in the generated modules: glibc declares its vector sin/cos (libmvec) only under
 * -ffast-math; declaring them here lets gcc -fopenmp-simd call them with IEEE kept */
#pragma omp declare simd notinbranch
extern double cos(double);
#pragma omp declare simd notinbranch
extern double sin(double);
#define DELTAGEN_FLOOR_TRIG_LANES 8
#endif
#ifndef DELTAGEN_FLOOR_TRIG_LANES
#define DELTAGEN_FLOOR_TRIG_LANES 1 /* scalar libm: no padding */
#endif

#define DELTAGEN_FLOOR_BLOCK 64
#define DELTAGEN_FLOOR_MAX_ANGLES 16
#define DELTAGEN_FLOOR_CHAINS 64

/* The trig floor: n points of `angles` angles (q, n x angles, row-major, rad) -> sums
 * (2 x angles): sums[a] = sum over the points of sin(q[., a]), sums[angles + a] = the sum of
 * cos(q[., a]). Returns 0, or -1 for a NULL pointer or more than DELTAGEN_FLOOR_MAX_ANGLES
 * angles. */
int deltagen_floor_trig(size_t n, size_t angles, const double *restrict q, double *restrict sums)
{
    if (q == NULL || sums == NULL || angles == 0 || angles > DELTAGEN_FLOOR_MAX_ANGLES) {
        return -1;
    }
    double sin_sum[DELTAGEN_FLOOR_MAX_ANGLES];
    double cos_sum[DELTAGEN_FLOOR_MAX_ANGLES];
    for (size_t a = 0; a < angles; ++a) {
        sin_sum[a] = 0.0;
        cos_sum[a] = 0.0;
    }
    double x_b[DELTAGEN_FLOOR_MAX_ANGLES][DELTAGEN_FLOOR_BLOCK];
    double s_b[DELTAGEN_FLOOR_BLOCK];
    double c_b[DELTAGEN_FLOOR_BLOCK];
    for (size_t start = 0; start < n; start += DELTAGEN_FLOOR_BLOCK) {
        const size_t m = (n - start < DELTAGEN_FLOOR_BLOCK) ? n - start : DELTAGEN_FLOOR_BLOCK;
        /* gather: the block's angles into contiguous columns (as the kernels do) */
        for (size_t k = 0; k < m; ++k) {
            for (size_t a = 0; a < angles; ++a) {
                x_b[a][k] = q[(start + k) * angles + a];
            }
        }
        const size_t padded = (m + DELTAGEN_FLOOR_TRIG_LANES - 1)
                              & ~(size_t)(DELTAGEN_FLOOR_TRIG_LANES - 1);
        const size_t m_v = padded <= DELTAGEN_FLOOR_BLOCK ? padded : m;
        for (size_t a = 0; a < angles; ++a) {
            for (size_t k = m; k < m_v; ++k) {
                x_b[a][k] = x_b[a][0];
            }
            /* sin and cos in loops of their own, as the kernels have them: in one loop gcc
             * fuses the pair into a scalar sincos call and the loop no longer vectorises */
            const double *restrict x = x_b[a];
            for (size_t k = 0; k < m_v; ++k) {
                s_b[k] = sin(x[k]);
            }
            for (size_t k = 0; k < m_v; ++k) {
                c_b[k] = cos(x[k]);
            }
            double s = 0.0;
            double c = 0.0;
#pragma omp simd reduction(+ : s, c)
            for (size_t k = 0; k < m; ++k) {
                s += s_b[k];
                c += c_b[k];
            }
            sin_sum[a] += s;
            cos_sum[a] += c;
        }
    }
    for (size_t a = 0; a < angles; ++a) {
        sums[a] = sin_sum[a];
        sums[angles + a] = cos_sum[a];
    }
    return 0;
}

/* The FMA rate: DELTAGEN_FLOOR_CHAINS accumulators acc_i = i / CHAINS, each updated
 * `iterations` times by acc_i = fma(acc_i, a, b); out (DELTAGEN_FLOOR_CHAINS) gets them.
 * 2 * DELTAGEN_FLOOR_CHAINS * iterations floating-point operations. Returns 0, or -1 for a
 * NULL out. */
int deltagen_floor_fma(size_t iterations, double a, double b, double *restrict out)
{
    if (out == NULL) {
        return -1;
    }
    double acc[DELTAGEN_FLOOR_CHAINS];
    for (size_t i = 0; i < DELTAGEN_FLOOR_CHAINS; ++i) {
        acc[i] = (double)i / DELTAGEN_FLOOR_CHAINS;
    }
    for (size_t it = 0; it < iterations; ++it) {
#pragma omp simd
        for (size_t i = 0; i < DELTAGEN_FLOOR_CHAINS; ++i) {
            acc[i] = fma(acc[i], a, b);
        }
    }
    for (size_t i = 0; i < DELTAGEN_FLOOR_CHAINS; ++i) {
        out[i] = acc[i];
    }
    return 0;
}
