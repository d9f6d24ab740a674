/* The road: a single-lane ring of length L with a periodic, piecewise-linear grade profile theta(x) and a
 * speed limit. Positions along the ring are unwrapped (they keep growing); theta is read at x mod L. */
#ifndef WAVEFUEL_ROAD_H
#define WAVEFUEL_ROAD_H

#include <stddef.h>
#include <math.h>
#include <stdint.h>
#include "wavefuel/err.h"

typedef struct WfRoad {
    double  length_m;
    double  speed_limit_mps;  /* +inf: none */
    size_t  n_grade;          /* 0: flat road */
    double *grade_x_m;        /* owned; strictly increasing in [0, L) */
    double *grade_rad;        /* owned; grade angle at each point, linear in between, periodic */
} WfRoad;

/* Build a ring's grade profile from points (copied). Checks: x strictly increasing inside [0, L), angles
 * within +-0.2 rad, and that the profile closes (net elevation change over one lap, the integral of theta,
 * at most 0.01 m + 1e-6 L in magnitude). `where` prefixes messages. */
int wf_road_set_grade(WfRoad *r, size_t n, const double *x_m, const double *theta_rad, const char *where,
                      WfError *err);
void wf_road_free(WfRoad *r);

/* theta at unwrapped position x. *seg is a per-vehicle cache of the profile segment (start it at 0): vehicles
 * move forward, so the search is amortised O(1); any value is corrected. */
static inline double wf_road_grade(const WfRoad *r, double x_m, uint32_t *seg)
{
    if (r->n_grade == 0) return 0.0;
    double L = r->length_m;
    double xm = x_m - L * floor(x_m / L);
    if (xm >= L) xm = 0.0; /* floor rounding at the lap boundary */
    size_t n = r->n_grade, s = *seg < n ? *seg : 0;
    /* segment s spans [x_s, x_{s+1}) with x_n = x_0 + L closing the loop; before x_0 is the last segment */
    const double *px = r->grade_x_m;
    if (xm < px[0]) {
        s = n - 1;
    } else {
        if (px[s] > xm) s = 0;
        while (s + 1 < n && px[s + 1] <= xm) s++;
    }
    *seg = (uint32_t)s;
    double x0 = px[s], x1 = s + 1 < n ? px[s + 1] : px[0] + L;
    double t0 = r->grade_rad[s], t1 = r->grade_rad[s + 1 < n ? s + 1 : 0];
    if (xm < x0) xm += L; /* wrapped segment seen from before x_0 */
    double w = (x1 > x0) ? (xm - x0) / (x1 - x0) : 0.0;
    return t0 + (t1 - t0) * w;
}

#endif
