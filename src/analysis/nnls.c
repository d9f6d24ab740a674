/* Least squares for the model-reduction fits: LAPACK's QR solver (dgels) for ordinary least squares, and
 * Lawson and Hanson's NNLS ("Solving Least Squares Problems", 1974, algorithm 23.10) whose unconstrained
 * sub-problems are solved by the same QR. Columns are scaled to unit norm first: the fits' bases span many
 * orders of magnitude (1 to v^3 = 42875 at 35 m/s), and x >= 0 is unchanged by a positive scaling. */
#include "wavefuel/nnls.h"

#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Column norms of A; checks the data are finite. */
static int column_norms(size_t m, size_t n, const double *A, const double *b, double *norm, WfError *err)
{
    for (size_t j = 0; j < n; j++) norm[j] = 0.0;
    for (size_t i = 0; i < m; i++) {
        if (!isfinite(b[i])) return wf_err(err, WF_EINPUT, "least squares: right-hand side %zu is not finite", i);
        for (size_t j = 0; j < n; j++) {
            double a = A[i * n + j];
            if (!isfinite(a))
                return wf_err(err, WF_EINPUT, "least squares: matrix entry (%zu, %zu) is not finite", i, j);
            norm[j] += a * a;
        }
    }
    for (size_t j = 0; j < n; j++) norm[j] = sqrt(norm[j]);
    return 0;
}

/* Unconstrained least squares on the columns cols[0..k-1] of the scaled matrix As (m x n): z[cols[c]] gets
 * the solution, the other entries of z are left alone. work holds m * k + m doubles. */
static int solve_columns(size_t m, size_t n, const double *As, const double *b, const size_t *cols, size_t k,
                         double *z, double *work, WfError *err)
{
    double *Ak = work, *bk = work + m * k;
    for (size_t i = 0; i < m; i++) {
        for (size_t c = 0; c < k; c++) Ak[i * k + c] = As[i * n + cols[c]];
        bk[i] = b[i];
    }
    lapack_int info = LAPACKE_dgels(LAPACK_ROW_MAJOR, 'N', (lapack_int)m, (lapack_int)k, 1, Ak, (lapack_int)k, bk, 1);
    if (info < 0) return wf_err(err, WF_ESYS, "least squares: LAPACKE_dgels argument %d is invalid", (int)-info);
    if (info > 0) /* the points do not determine the coefficients: a property of the data, not a failure */
        return wf_err(err, WF_EINPUT,
                      "least squares: the points do not determine the %zu coefficients (LAPACKE_dgels: R(%d,%d) = 0)",
                      k, (int)info, (int)info);
    /* On exit Ak holds R of A = QR. The columns have unit norm, so |R_jj| is the distance of column j from
     * the span of the ones before it: below 1e-10 the coefficients are not determined by the data (dgels
     * itself only reports an exact zero). */
    for (size_t c = 0; c < k; c++)
        if (!(fabs(Ak[c * k + c]) > 1e-10))
            return wf_err(err, WF_EINPUT,
                          "least squares: the points do not determine the %zu coefficients (column %zu is a "
                          "combination of the others: |R(%zu,%zu)| = %.3g)",
                          k, cols[c], c + 1, c + 1, fabs(Ak[c * k + c]));
    for (size_t c = 0; c < k; c++) z[cols[c]] = bk[c];
    return 0;
}

/* Shared set-up: scaled copy of A with its zero columns marked (scale 0). */
static int scaled_copy(size_t m, size_t n, const double *A, const double *b, double **As_out, double *scale,
                       WfError *err)
{
    *As_out = NULL;
    int rc = column_norms(m, n, A, b, scale, err);
    if (rc) return rc;
    double *As = malloc(m * n * sizeof *As);
    if (!As) return wf_err(err, WF_ESYS, "least squares: out of memory (%zu x %zu)", m, n);
    for (size_t i = 0; i < m; i++)
        for (size_t j = 0; j < n; j++) As[i * n + j] = scale[j] > 0 ? A[i * n + j] / scale[j] : 0.0;
    *As_out = As;
    return 0;
}

int wf_lsq(size_t m, size_t n, const double *A, const double *b, double *x, WfError *err)
{
    if (n == 0) return 0;
    if (m < n) return wf_err(err, WF_EINPUT, "least squares: %zu points for %zu unknowns", m, n);
    double scale[16];
    if (n > 16) return wf_err(err, WF_EINPUT, "least squares: at most 16 unknowns (got %zu)", n);
    double *As = NULL, *work = NULL;
    int rc = scaled_copy(m, n, A, b, &As, scale, err);
    if (rc) return rc;
    size_t cols[16], k = 0;
    for (size_t j = 0; j < n; j++) {
        x[j] = 0.0;
        if (scale[j] > 0) cols[k++] = j;
    }
    work = malloc((m * k + m) * sizeof *work);
    if (!work) rc = wf_err(err, WF_ESYS, "least squares: out of memory");
    if (!rc && k) rc = solve_columns(m, n, As, b, cols, k, x, work, err);
    if (!rc)
        for (size_t j = 0; j < n; j++) x[j] = scale[j] > 0 ? x[j] / scale[j] : 0.0;
    free(work);
    free(As);
    return rc;
}

/* w = As^T (b - As x): the negative gradient of ||As x - b||^2 / 2. */
static void gradient(size_t m, size_t n, const double *As, const double *b, const double *x, double *w, double *rnorm)
{
    double rr = 0.0;
    for (size_t j = 0; j < n; j++) w[j] = 0.0;
    for (size_t i = 0; i < m; i++) {
        double r = b[i];
        for (size_t j = 0; j < n; j++) r -= As[i * n + j] * x[j];
        rr += r * r;
        for (size_t j = 0; j < n; j++) w[j] += As[i * n + j] * r;
    }
    if (rnorm) *rnorm = sqrt(rr);
}

int wf_nnls(size_t m, size_t n, const double *A, const double *b, double *x, double *rnorm, WfError *err)
{
    if (n == 0) return 0;
    if (m < n) return wf_err(err, WF_EINPUT, "NNLS: %zu points for %zu unknowns", m, n);
    if (n > 16) return wf_err(err, WF_EINPUT, "NNLS: at most 16 unknowns (got %zu)", n);
    double scale[16], w[16], z[16];
    int passive[16];
    double *As = NULL, *work = NULL;
    int rc = scaled_copy(m, n, A, b, &As, scale, err);
    if (rc) return rc;
    work = malloc((m * n + m) * sizeof *work);
    if (!work) {
        free(As);
        return wf_err(err, WF_ESYS, "NNLS: out of memory");
    }
    for (size_t j = 0; j < n; j++) x[j] = 0.0, passive[j] = 0;
    /* Columns have unit norm, so |w_j| <= ||b||; tol separates a real descent direction from rounding. */
    double bnorm = 0.0;
    for (size_t i = 0; i < m; i++) bnorm += b[i] * b[i];
    const double tol = 10.0 * DBL_EPSILON * (double)(m > n ? m : n) * (sqrt(bnorm) + DBL_MIN);
    size_t outer = 0;
    int converged = 0;
    while (!rc && outer++ < 3 * n) {
        gradient(m, n, As, b, x, w, NULL);
        /* Step 2-5: stop when no column outside the passive set can reduce the residual. */
        size_t t = n;
        double best = tol;
        for (size_t j = 0; j < n; j++)
            if (!passive[j] && scale[j] > 0 && w[j] > best) best = w[j], t = j;
        if (t == n) {
            converged = 1;
            break;
        }
        passive[t] = 1;
        /* Steps 6-11: solve on the passive set; while the solution leaves the feasible region, move back
         * along the segment from x to z and drop the columns that reach zero. */
        for (size_t inner = 0; inner <= n && !rc; inner++) {
            size_t cols[16], k = 0;
            for (size_t j = 0; j < n; j++)
                if (passive[j]) cols[k++] = j;
            for (size_t j = 0; j < n; j++) z[j] = 0.0;
            if (k == 0) break;
            if ((rc = solve_columns(m, n, As, b, cols, k, z, work, err))) break;
            double alpha = 2.0;
            for (size_t c = 0; c < k; c++) {
                size_t j = cols[c];
                if (z[j] <= 0.0) {
                    double d = x[j] - z[j];
                    double al = d > 0 ? x[j] / d : 0.0;
                    if (al < alpha) alpha = al;
                }
            }
            if (alpha > 1.0) { /* every passive z_j > 0: accept */
                for (size_t j = 0; j < n; j++) x[j] = z[j];
                break;
            }
            for (size_t j = 0; j < n; j++) {
                x[j] += alpha * (z[j] - x[j]);
                /* The column that defined alpha lands on 0 up to rounding: drop it exactly. */
                if (passive[j] && x[j] <= tol * fabs(z[j]) + DBL_MIN) {
                    x[j] = 0.0;
                    passive[j] = 0;
                }
            }
        }
    }
    if (!rc && !converged) {
        /* The last outer step may have been the one that converged: check once more. */
        gradient(m, n, As, b, x, w, NULL);
        converged = 1;
        for (size_t j = 0; j < n; j++)
            if (!passive[j] && scale[j] > 0 && w[j] > tol) converged = 0;
        if (!converged) rc = wf_err(err, WF_ESYS, "NNLS did not converge in %zu iterations (%zu points, %zu unknowns)",
                                    3 * n, m, n);
    }
    if (!rc) {
        gradient(m, n, As, b, x, w, rnorm);
        for (size_t j = 0; j < n; j++) x[j] = scale[j] > 0 && x[j] > 0 ? x[j] / scale[j] : 0.0;
    }
    free(work);
    free(As);
    return rc;
}
