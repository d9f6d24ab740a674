/* Not-a-knot cubic spline interpolation of samples (x[i], y[i]) with x strictly increasing: the interpolant of
 * MATLAB's `spline` and SciPy's `CubicSpline(bc_type='not-a-knot')`, which the CIRCLES release used to resample
 * its drive cycles to 10 Hz (docs/cycles.md). Two samples give the line through them, three the parabola. Units are
 * the caller's (x in s, y in m/s for a drive cycle; the derivative is then in m/s^2). */
#ifndef WAVEFUEL_SPLINE_H
#define WAVEFUEL_SPLINE_H

#include <stddef.h>
#include "wavefuel/err.h"

typedef struct WfSpline {
    size_t        n;      /* knots, >= 2 */
    const double *x, *y;  /* borrowed: the caller's knots, which must outlive the spline */
    double       *slope;  /* owned; dy/dx at each knot */
} WfSpline;

/* Fit: the knot slopes solve the not-a-knot tridiagonal system (LAPACK dgtsv, partial pivoting). *s is the
 * caller's; its slopes are owned by it until wf_spline_free(). Errors: n < 2, x not strictly increasing, values not
 * finite (WF_EINPUT, naming the index and value), out of memory or a singular system (WF_ESYS). */
int wf_spline_fit(size_t n, const double *x, const double *y, WfSpline *s, WfError *err);
void wf_spline_free(WfSpline *s);

/* Index i of the interval [x[i], x[i+1]] holding t, searched upward from `hint` (pass the previous answer when t
 * increases; 0 otherwise). t below x[0] gives 0, above x[n-1] gives n-2 (the end cubics are extended). */
size_t wf_spline_interval(const WfSpline *s, double t, size_t hint);
/* Value and derivative at t on interval i (from wf_spline_interval); dy may be NULL. */
double wf_spline_eval(const WfSpline *s, size_t i, double t, double *dy);

#endif
