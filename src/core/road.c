/* Ring road geometry: grade profile validation (strictly increasing, bounded, closing over a lap). */
#include "wavefuel/road.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void wf_road_free(WfRoad *r)
{
    if (!r) return;
    free(r->grade_x_m);
    free(r->grade_rad);
    r->grade_x_m = r->grade_rad = NULL;
    r->n_grade = 0;
}

int wf_road_set_grade(WfRoad *r, size_t n, const double *x, const double *th, const char *where, WfError *err)
{
    wf_road_free(r);
    if (n == 0) return 0;
    double L = r->length_m;
    for (size_t i = 0; i < n; i++) {
        if (!(x[i] >= 0.0 && x[i] < L))
            return wf_err(err, WF_EINPUT, "%s: grade point %zu: x_m must be in [0, %.17g) m, the ring (got %.17g)",
                          where, i, L, x[i]);
        if (i && !(x[i] > x[i - 1]))
            return wf_err(err, WF_EINPUT, "%s: grade point %zu: x_m must increase (got %.17g after %.17g)", where,
                          i, x[i], x[i - 1]);
        if (!(fabs(th[i]) <= 0.2))
            return wf_err(err, WF_EINPUT, "%s: grade point %zu: grade_rad must be in [-0.2, 0.2] rad (got %.17g)",
                          where, i, th[i]);
    }
    /* Net climb over one lap (trapezoid of the piecewise-linear theta, which is exact for it). */
    double climb = 0.0;
    for (size_t i = 0; i < n; i++) {
        double x1 = i + 1 < n ? x[i + 1] : x[0] + L, t1 = th[i + 1 < n ? i + 1 : 0];
        climb += 0.5 * (th[i] + t1) * (x1 - x[i]);
    }
    if (fabs(climb) > 0.01 + 1e-6 * L)
        return wf_err(err, WF_EINPUT,
                      "%s: the grade profile does not close on the ring: one lap climbs %.6g m (integral of theta dx); "
                      "a ring must return to its start height",
                      where, climb);
    r->grade_x_m = malloc(n * sizeof *x);
    r->grade_rad = malloc(n * sizeof *th);
    if (!r->grade_x_m || !r->grade_rad) {
        wf_road_free(r);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    memcpy(r->grade_x_m, x, n * sizeof *x);
    memcpy(r->grade_rad, th, n * sizeof *th);
    r->n_grade = n;
    return 0;
}
