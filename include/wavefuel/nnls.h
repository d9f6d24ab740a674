/* Linear least squares for the model-reduction fits (wavefuel fit): ordinary least squares through LAPACK's
 * QR solver (LAPACKE_dgels), and non-negative least squares by Lawson and Hanson's active-set algorithm
 * ("Solving Least Squares Problems", 1974, ch. 23) on top of it. Matrices are row-major, m rows (points)
 * by n columns (basis functions); small n (the fits use n <= 5) and any m >= 1. */
#ifndef WAVEFUEL_NNLS_H
#define WAVEFUEL_NNLS_H

#include <stddef.h>

#include "wavefuel/err.h"

/* min ||A x - b||_2 over x (n values). A (m x n, row-major) and b (m) are not modified. Columns are scaled
 * to unit norm before the QR factorisation, so bases of very different magnitudes (1, v, v^2, v^3 with v up
 * to 35 m/s) do not lose precision; a zero column gets x = 0. Needs m >= n. Returns 0, or WF_EINPUT for
 * m < n or non-finite data, WF_ESYS for an allocation or LAPACK failure (the message names the routine). */
int wf_lsq(size_t m, size_t n, const double *A, const double *b, double *x, WfError *err);

/* min ||A x - b||_2 subject to x >= 0 (Lawson-Hanson NNLS). Same arguments and failures as wf_lsq. On
 * return every x[j] >= 0 (exact zeros for the constrained ones); *rnorm (may be NULL) = ||A x - b||.
 * Stops after 3 n outer iterations at most, as Lawson and Hanson recommend: an error if it has not
 * converged by then (WF_ESYS, "NNLS did not converge"). */
int wf_nnls(size_t m, size_t n, const double *A, const double *b, double *x, double *rnorm, WfError *err);

#endif
