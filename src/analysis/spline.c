/* Not-a-knot cubic spline: knot slopes from the tridiagonal system in slope form (de Boor, "A Practical Guide to
 * Splines", ch. IV; the same rows as SciPy's CubicSpline), solved by LAPACK's dgtsv; evaluation in Hermite form. */
#include "wavefuel/spline.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void wf_spline_free(WfSpline *s)
{
    if (!s) return;
    free(s->slope);
    s->slope = NULL;
    s->n = 0;
}

/* Rows of the not-a-knot system for n >= 4 knots: dl (sub-diagonal), d, du (super-diagonal), b. The first and
 * last rows say that the third derivative is continuous at x[1] and x[n-2]; the others are C2 continuity. */
static void not_a_knot_rows(size_t n, const double *x, const double *y, double *dl, double *d, double *du, double *b)
{
    double h0 = x[1] - x[0], h1 = x[2] - x[1];
    double m0 = (y[1] - y[0]) / h0, m1 = (y[2] - y[1]) / h1;
    d[0] = h1;
    du[0] = h0 + h1;
    b[0] = ((h0 + 2.0 * (h0 + h1)) * h1 * m0 + h0 * h0 * m1) / (h0 + h1);
    for (size_t i = 1; i + 1 < n; i++) {
        double hl = x[i] - x[i - 1], hr = x[i + 1] - x[i];
        double ml = (y[i] - y[i - 1]) / hl, mr = (y[i + 1] - y[i]) / hr;
        dl[i - 1] = hr;
        d[i] = 2.0 * (hl + hr);
        du[i] = hl;
        b[i] = 3.0 * (hr * ml + hl * mr);
    }
    double ha = x[n - 2] - x[n - 3], hb = x[n - 1] - x[n - 2];
    double ma = (y[n - 2] - y[n - 3]) / ha, mb = (y[n - 1] - y[n - 2]) / hb;
    dl[n - 2] = ha + hb;
    d[n - 1] = ha;
    b[n - 1] = (hb * hb * ma + (2.0 * (ha + hb) + hb) * ha * mb) / (ha + hb);
}

/* Two knots: the line; three: the parabola (the not-a-knot conditions at both ends coincide). */
static void low_order_slopes(size_t n, const double *x, const double *y, double *slope)
{
    double m0 = (y[1] - y[0]) / (x[1] - x[0]);
    if (n == 2) {
        slope[0] = slope[1] = m0;
        return;
    }
    double m1 = (y[2] - y[1]) / (x[2] - x[1]), c = (m1 - m0) / (x[2] - x[0]);
    for (size_t i = 0; i < 3; i++) slope[i] = m0 + c * (2.0 * x[i] - x[0] - x[1]);
}

int wf_spline_fit(size_t n, const double *x, const double *y, WfSpline *s, WfError *err)
{
    memset(s, 0, sizeof *s);
    if (n < 2) return wf_err(err, WF_EINPUT, "spline: needs at least 2 knots (got %zu)", n);
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(x[i]) || !isfinite(y[i]))
            return wf_err(err, WF_EINPUT, "spline: knot %zu is not finite (x %.17g, y %.17g)", i, x[i], y[i]);
        if (i > 0 && !(x[i] > x[i - 1]))
            return wf_err(err, WF_EINPUT, "spline: x must increase strictly (x[%zu] = %.17g after %.17g)", i, x[i],
                          x[i - 1]);
    }
    double *slope = malloc(n * sizeof *slope), *work = n >= 4 ? malloc(3 * n * sizeof *work) : NULL;
    if (!slope || (n >= 4 && !work)) {
        free(slope);
        free(work);
        return wf_err(err, WF_ESYS, "spline: out of memory for %zu knots", n);
    }
    if (n < 4) {
        low_order_slopes(n, x, y, slope);
    } else {
        double *dl = work, *d = work + n, *du = work + 2 * n;
        not_a_knot_rows(n, x, y, dl, d, du, slope);
        lapack_int info = LAPACKE_dgtsv(LAPACK_COL_MAJOR, (lapack_int)n, 1, dl, d, du, slope, (lapack_int)n);
        if (info != 0) {
            free(slope);
            free(work);
            return wf_err(err, WF_ESYS, "spline: LAPACKE_dgtsv failed on %zu knots (info %d)", n, (int)info);
        }
    }
    free(work);
    s->n = n;
    s->x = x;
    s->y = y;
    s->slope = slope;
    return 0;
}

size_t wf_spline_interval(const WfSpline *s, double t, size_t hint)
{
    size_t i = hint < s->n - 1 ? hint : s->n - 2;
    while (i > 0 && t < s->x[i]) i--;
    while (i + 2 < s->n && t >= s->x[i + 1]) i++;
    return i;
}

double wf_spline_eval(const WfSpline *s, size_t i, double t, double *dy)
{
    double h = s->x[i + 1] - s->x[i], u = t - s->x[i];
    double m = (s->y[i + 1] - s->y[i]) / h, s0 = s->slope[i], s1 = s->slope[i + 1];
    double c2 = (3.0 * m - 2.0 * s0 - s1) / h, c3 = (s0 + s1 - 2.0 * m) / (h * h);
    if (dy) *dy = s0 + u * (2.0 * c2 + 3.0 * u * c3);
    return s->y[i] + u * (s0 + u * (c2 + u * c3));
}
