/* The CIRCLES simplified energy model v3.1 (Khoudari et al., "Reducing Detailed Vehicle Energy Dynamics to
 * Physics-Like Models"): fuel rate f(v, a, theta) in g/s, polynomial with a fuel cut, a lower bound and an
 * idle rule, plus the feasible-acceleration bound a_max(v, theta). Evaluation order and arithmetic follow
 * the authors' release; powers are written as products and this file is built with -ffp-contract=off. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/energy.h"

#define P(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, -1e6, 1e6, unit, WF_PARAM_REQUIRED, doc }
#define O(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, -1e6, 1e6, unit, WF_PARAM_OPTIONAL, doc }

static const WfParamSpec circles_spec[] = {
    P(f_idle, "g/s", "fuel rate at idle"),
    P(b1, "m/s^2", "traction-limited acceleration"),
    P(b2, "m^2/s^2", "power-limited acceleration factor"),
    P(b3, "1/m", "drag reduction of a_max"),
    P(b4, "m/(s^2 rad)", "grade effect cap on a_max"),
    P(b5, "m/(s^2 rad)", "grade effect on a_max"),
    P(b6, "1/(s rad)", "speed-dependent grade effect on a_max"),
    P(c0, "g/s", "C(v): constant"),
    P(c1, "g/m", "C(v): linear"),
    P(c2, "g s/m^2", "C(v): quadratic"),
    P(c3, "g s^2/m^3", "C(v): cubic"),
    P(p0, "g s/m", "P(v): constant"),
    P(p1, "g s^2/m^2", "P(v): linear"),
    P(p2, "g s^3/m^3", "P(v): quadratic"),
    P(q0, "g s^3/m^2", "Q(v): constant"),
    P(q1, "g s^4/m^3", "Q(v): linear"),
    P(z0, "g/(s rad)", "Z(v): constant"),
    P(z1, "g/(m rad)", "Z(v): linear"),
    P(z2, "g s/(m^2 rad)", "Z(v): quadratic"),
    O(v_c, "m/s", "light duty: fuel-cut speed"),
    O(beta, "g/s", "light duty: lower bound below v_c"),
    O(a0, "m/s^2", "light duty: fuel-cut acceleration, constant"),
    O(a1, "1/s", "light duty: fuel-cut acceleration, v"),
    O(a2, "m/(s^2 rad)", "light duty: fuel-cut acceleration, theta"),
    O(a3, "1/m", "light duty: fuel-cut acceleration, v^2"),
    O(a4, "1/(s rad)", "light duty: fuel-cut acceleration, v theta"),
    O(h0, "g/s", "heavy duty: lower bound, constant"),
    O(h1, "g/m", "heavy duty: lower bound, linear"),
};

static int circles_check(void *params, WfError *err)
{
    WfCirclesParams *p = params;
    int light = !isnan(p->v_c) || !isnan(p->beta) || !isnan(p->a0) || !isnan(p->a1) || !isnan(p->a2) ||
                !isnan(p->a3) || !isnan(p->a4);
    int heavy = !isnan(p->h0) || !isnan(p->h1);
    if (light && heavy)
        return wf_err(err, WF_EINPUT,
                      "energy: give either the light-duty keys (v_c, beta, a0..a4) or the heavy-duty keys (h0, h1), "
                      "not both");
    if (light) {
        const char *names[] = {"v_c", "beta", "a0", "a1", "a2", "a3", "a4"};
        double vals[] = {p->v_c, p->beta, p->a0, p->a1, p->a2, p->a3, p->a4};
        for (int i = 0; i < 7; i++)
            if (isnan(vals[i]))
                return wf_err(err, WF_EINPUT, "energy: light-duty model needs '%s' (v_c, beta, a0..a4 all given)",
                              names[i]);
        if (p->v_c < 0) return wf_err(err, WF_EINPUT, "energy: v_c must be >= 0 m/s (got %.17g)", p->v_c);
        p->cut_v = p->v_c;
        p->lb_beta = p->beta;
        p->lb_h0 = 0.0;
        p->lb_h1 = 0.0;
    } else if (heavy) {
        if (isnan(p->h0) || isnan(p->h1))
            return wf_err(err, WF_EINPUT, "energy: heavy-duty model needs both 'h0' and 'h1'");
        /* No fuel cut: v > +inf never holds, and (v <= inf) selects lb_beta = 0. */
        p->cut_v = INFINITY;
        p->lb_beta = 0.0;
        p->lb_h0 = p->h0;
        p->lb_h1 = p->h1;
        p->a0 = p->a1 = p->a2 = p->a3 = p->a4 = 0.0;
        p->v_c = INFINITY;
    } else {
        return wf_err(err, WF_EINPUT,
                      "energy: missing the lower-bound keys: light duty needs v_c, beta, a0..a4; heavy duty h0, h1");
    }
    return 0;
}

double wf_circles_a_max(const WfCirclesParams *p, double v, double theta)
{
    /* max(v, 1e-12) keeps b2/v finite at rest and for negative v, as the release does. */
    double vs = fmax(v, 1e-12);
    return fmin(p->b1, p->b2 / vs - p->b3 * v * v) - fmin(p->b4, p->b5 + p->b6 * v) * theta;
}

/* One evaluation; `static inline` so the array loop below is a single vectorizable body. */
static inline double circles_eval1(const WfCirclesParams *p, double v, double a, double th, int project,
                                   uint8_t *flag_out)
{
    double amax = fmin(p->b1, p->b2 / fmax(v, 1e-12) - p->b3 * v * v) - fmin(p->b4, p->b5 + p->b6 * v) * th;
    *flag_out = (uint8_t)(v < 0.0 ? WF_NEGATIVE_SPEED : (a > amax ? WF_INFEASIBLE_ACCEL : WF_FEASIBLE));
    if (project) a = fmin(a, amax);
    v = fmax(v, 0.0);
    double P = p->p0 + p->p1 * v + p->p2 * v * v;
    double Q = p->q0 + p->q1 * fmax(v, 1e-12);
    double ap = fmax(a, -P / (2.0 * Q));
    double f = p->c0 + p->c1 * v + p->c2 * v * v + p->c3 * v * v * v + p->p0 * a + p->p1 * a * v + p->p2 * a * v * v +
               p->q0 * ap * ap + p->q1 * ap * ap * v + p->z0 * th + p->z1 * th * v + p->z2 * th * v * v;
    /* Light duty: beta below v_c, 0 above (lb_h0 = lb_h1 = 0 add exact zeros).
     * Heavy duty: h0 + h1 v (lb_beta = 0, cut_v = inf). */
    double lb = (v <= p->cut_v ? p->lb_beta : 0.0) + p->lb_h0 + p->lb_h1 * v;
    f = fmax(f, lb);
    double a_cut = p->a0 + p->a1 * v + p->a2 * th + p->a3 * v * v + p->a4 * v * th;
    f = (v > p->cut_v && a <= a_cut) ? 0.0 : f;
    f = (v < 0.1 && fabs(a) < 0.01) ? p->f_idle : f;
    return f;
}

double wf_circles_fuel(const WfCirclesParams *p, double v, double a, double theta, int project, uint8_t *flag)
{
    uint8_t fl;
    double f = circles_eval1(p, v, a, theta, project, &fl);
    if (flag) *flag = fl;
    return f;
}

static void circles_eval(const void *params, size_t n, const double *restrict v, const double *restrict a,
                         const double *restrict th, int project, double *restrict fuel, uint8_t *restrict flag)
{
    const WfCirclesParams *p = params;
    if (flag) {
        for (size_t i = 0; i < n; i++) fuel[i] = circles_eval1(p, v[i], a[i], th[i], project, &flag[i]);
    } else {
        for (size_t i = 0; i < n; i++) {
            uint8_t fl;
            fuel[i] = circles_eval1(p, v[i], a[i], th[i], project, &fl);
        }
    }
}

static double circles_a_max(const void *params, double v, double theta)
{
    return wf_circles_a_max(params, v, theta);
}

const WfEnergyModel wf_energy_circles = {
    .name = "circles_polynomial",
    .param_size = sizeof(WfCirclesParams),
    .spec = circles_spec,
    .n_spec = sizeof circles_spec / sizeof circles_spec[0],
    .check = circles_check,
    .eval = circles_eval,
    .a_max = circles_a_max,
};
