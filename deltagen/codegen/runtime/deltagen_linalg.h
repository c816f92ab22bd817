/* deltagen_linalg.h: small dense linear algebra for the deltagen runtime (hand-written,
 * part of deltagen; compiled beside each generated module that needs it).
 *
 * C99, reentrant, no heap, no globals; link with libm only. Matrices are row-major; every
 * size is a run-time argument, and scratch memory is the caller's.
 */
#ifndef DELTAGEN_LINALG_H
#define DELTAGEN_LINALG_H

#include <stddef.h>

/* The storage of a runtime body that its callers take with a size fixed at compile time
 * (the 6 x 6 systems of a 6-joint arm, deltagen_linalg.c; the damped Newton of a 6-joint
 * arm, deltagen_ik_newton.c): always inlined, so the compiler unrolls its loops over that
 * size -- the same operations in the same order (no reassociation, no contraction: IEEE
 * C99), the same bits, without the loop overhead of sizes known only at run time. */
#if defined(__GNUC__)
#define DELTAGEN_SIZED_BODY static inline __attribute__((always_inline))
#else
#define DELTAGEN_SIZED_BODY static inline
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* Rotation vector (matrix logarithm) of the row-major rotation R: theta * axis, with
 * theta = atan2(|v|, (tr R - 1) / 2), v = vee(R - R^T) / 2; for theta > pi/2 the axis comes
 * from the symmetric part (accurate up to theta = pi), signed like v. */
void deltagen_rotation_log(const double R[9], double w[3]);

/* In-place Cholesky factor (lower) of the s x s matrix A, and the reciprocals of its
 * diagonal in inv (s values; the solves multiply by them: a division per step would make
 * the dependent chain of a triangular solve several times longer); 0, or -1 if A is not
 * positive definite. */
int deltagen_cholesky(double *A, size_t s, double *inv);

/* deltagen_cholesky with a relative test of definiteness: -1 also when a pivot L_jj^2 is
 * not above rtol times the largest diagonal entry of A (a matrix positive definite only by
 * rounding, e.g. the mass matrix of an arm with a massless link and no armature). */
int deltagen_cholesky_relative(double *A, size_t s, double *inv, double rtol);

/* Solve L L^T x = b (L, inv from deltagen_cholesky); b and x may be the same array. */
void deltagen_cholesky_solve(const double *L, const double *inv, size_t s, const double *b,
                             double *x);

/* LU factorisation with partial pivoting (GVL Alg. 3.4.1) of the s x s A in place: U on and
 * above the diagonal, the multipliers of L below it; piv[j] (s values, or NULL) the row
 * swapped into row j. When b is not NULL the same row operations are applied to it (the
 * forward half of Gauss elimination). 0, or -1 at a zero (or NaN) pivot. */
int deltagen_lu(double *A, size_t s, int *piv, double *b);

/* Solve A x = b in place for b (s values) from deltagen_lu's LU and piv (b NULL there). */
void deltagen_lu_solve(const double *LU, const int *piv, size_t s, double *b);

/* Gauss elimination with partial pivoting: A x = b for the s x s A (destroyed), x in b
 * (deltagen_lu with b, then back substitution); 0, or -1 if a pivot is zero. */
int deltagen_gauss(double *A, size_t s, double *b);

/* The Gram matrix of the k x N matrix A: A^T A (N x N) if N <= k, else A A^T (k x k),
 * written to G (s x s, s <= N: room for N * N values); returns s. Columns with
 * fixed[i] != 0 are left out (their A^T A row and column are those of the identity). */
size_t deltagen_gram(const double *A, size_t k, size_t N, const int *fixed, double *G);

/* Estimate of the smallest singular value of a matrix from its s x s Gram matrix G0 (not
 * changed): three steps of inverse iteration from a fixed start, through a Cholesky factor
 * of G0 shifted by a few ulps of its trace. The ratio |x| / |G^-1 x| is never below the
 * smallest eigenvalue, so the estimate errs high; it is accurate when the smallest
 * eigenvalue is well separated (near a singularity). work: s * s + 2 s doubles. */
double deltagen_sigma_min_of(const double *G0, size_t s, double *work);

#ifdef __cplusplus
}
#endif

#endif /* DELTAGEN_LINALG_H */
