/* deltagen_eigen.h: eigenvalues of a small dense real matrix (hand-written, part of
 * deltagen; compiled beside the modules that include it).
 *
 * The textbook algorithm, written from its description in Golub & Van Loan, "Matrix
 * Computations", 4th ed. (2013): balancing by powers of 2 (sec. 7.5.7, after Parlett &
 * Reinsch 1969), Householder reduction to upper Hessenberg form (Alg. 7.4.2) and the
 * Francis implicit double-shift QR iteration with deflation (Alg. 7.5.1, 7.5.2), computing
 * eigenvalues only (every update restricted to the active window, no Schur vectors).
 *
 * C99, reentrant, no heap, no globals, libm only. Matrices are row-major n x n.
 */
#ifndef DELTAGEN_EIGEN_H
#define DELTAGEN_EIGEN_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi: begin (deltagen/native/build.py hands this part to cffi's cdef) */

/* Eigenvalues wr[k] + i wi[k] (k < n) of the row-major n x n matrix A (destroyed: it ends
 * as the deflated quasi-triangular iterate). Complex pairs are adjacent, positive imaginary
 * part first. Returns 0, or -1 when the QR iteration did not converge in 40 n double steps
 * (every wr, wi then NaN), or -2 when A holds a non-finite entry (NaN results). */
int deltagen_eigvals(double *A, int n, double *wr, double *wi);

/* deltagen_eigvals for `count` matrices stored one after the other (A: count * n * n),
 * results in wr, wi (count * n) and status (count): one call for a batch. */
void deltagen_eigvals_batch(double *A, int count, int n, double *wr, double *wi, int *status);

/* cffi: end */

/* The steps, for callers that want them separately: balance A by a diagonal similarity
 * of powers of 2 (rows and columns of comparable 1-norm); reduce A to upper Hessenberg
 * form in place (entries below the subdiagonal set to 0); the eigenvalues of an upper
 * Hessenberg H (destroyed), 0 or -1 (no convergence). */
void deltagen_balance(double *A, int n);
void deltagen_hessenberg(double *A, int n);
int deltagen_hessenberg_eigvals(double *H, int n, double *wr, double *wi);


#ifdef __cplusplus
}
#endif

#endif /* DELTAGEN_EIGEN_H */
