/* The CIRCLES simplified energy model v3.1 (Khoudari et al., "Reducing Detailed Vehicle Energy Dynamics to
 * Physics-Like Models"): fuel rate f(v, a, theta) in g/s, polynomial with a fuel cut, a lower bound and an
 * idle rule, plus the feasible-acceleration bound a_max(v, theta). Evaluation order and arithmetic follow
 * the authors' release; powers are written as products and this file is built with -ffp-contract=off.
 * The kernel evaluates two points per step with GNU C vector types; results are those of the scalar formula. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

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

/* min and max as x86-64 minsd/maxsd: on a tie (+0 against -0 included) the second operand, and the second
 * operand when either is NaN. That is glibc's fmin/fmax, which the kernel used to call (a library call
 * unless -ffinite-math-only), whenever the second operand is not NaN. For finite inputs that holds at every
 * use but two, where *_nan() keep fmax/fmin's rule (a NaN operand is ignored): a+ = max(a, -P/(2Q)) meets
 * 0/0 when degenerate parameters give P = Q = 0, and the projection min(a, a_max) meets inf - inf in a_max
 * at absurd speeds and grades (|v| ~ 1e308 m/s). So results are fmin/fmax's bits for every finite input,
 * and the plain selects compile to minsd/maxsd with no branch. */
static inline double min1(double x, double y) { return x < y ? x : y; }
static inline double max1(double x, double y) { return x > y ? x : y; }
static inline double min_nan(double x, double y) { return y != y ? x : min1(x, y); }
static inline double max_nan(double x, double y) { return y != y ? x : max1(x, y); }

double wf_circles_a_max(const WfCirclesParams *p, double v, double theta)
{
    /* max(v, 1e-12) keeps b2/v finite at rest and for negative v, as the release does. */
    double vs = max1(v, 1e-12);
    return min1(p->b1, p->b2 / vs - p->b3 * v * v) - min1(p->b4, p->b5 + p->b6 * v) * theta;
}

/* The kernel works on two points at a time with GNU C vector types (SSE2 on x86-64, NEON on AArch64, plain
 * scalar code where there is no SIMD). GCC 12 does not vectorize the scalar loop at the project's -O2:
 * the very-cheap cost model refuses unknown trip counts, and with the default -ftrapping-math it will not
 * if-convert the selects (bench/README.md). Vector arithmetic is lane-wise IEEE, the same operations in the
 * same order as the scalar formula, so every lane's result is bitwise the scalar result. */
typedef double  WfVec2 __attribute__((vector_size(16)));
typedef int64_t WfMask2 __attribute__((vector_size(16))); /* lanes all-ones (true) or zero */

static inline WfVec2 vsplat(double x) { return (WfVec2){x, x}; }
static inline WfVec2 vselect(WfMask2 m, WfVec2 x, WfVec2 y) { return (WfVec2)((m & (WfMask2)x) | (~m & (WfMask2)y)); }
static inline WfVec2 vmin(WfVec2 x, WfVec2 y) { return vselect(x < y, x, y); }                  /* min1 per lane */
static inline WfVec2 vmax(WfVec2 x, WfVec2 y) { return vselect(x > y, x, y); }                  /* max1 per lane */
static inline WfVec2 vmin_nan(WfVec2 x, WfVec2 y) { return vselect((x < y) | (y != y), x, y); } /* min_nan */
static inline WfVec2 vmax_nan(WfVec2 x, WfVec2 y) { return vselect((x > y) | (y != y), x, y); } /* max_nan */

/* n evaluations of the array form; flag may be NULL. circles_eval1() below is the same formula for
 * one point: the two must change together (tests/test_energy.c checks them bitwise against each other). */
static void circles_kernel(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                           const double *restrict a_in, const double *restrict th_in, int project,
                           double *restrict fuel, uint8_t *restrict flag)
{
    const WfVec2 b1 = vsplat(p->b1), b2 = vsplat(p->b2), b3 = vsplat(p->b3), b4 = vsplat(p->b4), b5 = vsplat(p->b5),
                 b6 = vsplat(p->b6);
    const WfVec2 c0 = vsplat(p->c0), c1 = vsplat(p->c1), c2 = vsplat(p->c2), c3 = vsplat(p->c3);
    const WfVec2 p0 = vsplat(p->p0), p1 = vsplat(p->p1), p2 = vsplat(p->p2), q0 = vsplat(p->q0), q1 = vsplat(p->q1);
    const WfVec2 z0 = vsplat(p->z0), z1 = vsplat(p->z1), z2 = vsplat(p->z2), f_idle = vsplat(p->f_idle);
    const WfVec2 a0 = vsplat(p->a0), a1 = vsplat(p->a1), a2 = vsplat(p->a2), a3 = vsplat(p->a3), a4 = vsplat(p->a4);
    const WfVec2 cut_v = vsplat(p->cut_v), lb_beta = vsplat(p->lb_beta), lb_h0 = vsplat(p->lb_h0),
                 lb_h1 = vsplat(p->lb_h1);
    const WfVec2 zero = vsplat(0.0), v_floor = vsplat(1e-12), two = vsplat(2.0);
    const WfVec2 idle_v = vsplat(0.1), idle_a = vsplat(0.01);
    const WfMask2 proj = (WfMask2){0, 0} - (project != 0), abs_bits = (WfMask2){INT64_MAX, INT64_MAX};
    for (size_t i = 0; i < n; i += 2) {
        int pair = i + 1 < n;
        WfVec2 v, a, th;
        if (pair) {
            memcpy(&v, v_in + i, sizeof v);
            memcpy(&a, a_in + i, sizeof a);
            memcpy(&th, th_in + i, sizeof th);
        } else { /* odd n: the last point fills both lanes; the second is not stored */
            v = vsplat(v_in[i]);
            a = vsplat(a_in[i]);
            th = vsplat(th_in[i]);
        }
        /* 1-2. a_max from the raw v; flag from the original a: 2 if v < 0, else 1 if a > a_max. */
        WfVec2 amax = vmin(b1, b2 / vmax(v, v_floor) - b3 * v * v) - vmin(b4, b5 + b6 * v) * th;
        WfMask2 negative = v < zero, above = a > amax;
        WfMask2 fl = (negative & WF_NEGATIVE_SPEED) | (above & ~negative & WF_INFEASIBLE_ACCEL);
        /* 3-5. Projection, v >= 0, a+ (v floored at 1e-12 inside Q keeps Q off 0 at rest when q0 = 0). */
        a = vselect(proj, vmin_nan(a, amax), a);
        v = vmax(v, zero);
        WfVec2 P = p0 + p1 * v + p2 * v * v;
        WfVec2 Q = q0 + q1 * vmax(v, v_floor);
        WfVec2 ap = vmax_nan(a, -P / (two * Q));
        /* 6. Only the two squared terms use a+. */
        WfVec2 f = c0 + c1 * v + c2 * v * v + c3 * v * v * v + p0 * a + p1 * a * v + p2 * a * v * v + q0 * ap * ap +
                   q1 * ap * ap * v + z0 * th + z1 * th * v + z2 * th * v * v;
        /* 7. Light duty: beta below v_c, 0 above (lb_h0 = lb_h1 = 0 add exact zeros).
         *    Heavy duty: h0 + h1 v (lb_beta = 0, cut_v = inf). */
        WfVec2 lb = vselect(v <= cut_v, lb_beta, zero) + lb_h0 + lb_h1 * v;
        f = vmax(f, lb);
        /* 8. Fuel cut (never for heavy duty: v > inf is false). */
        WfVec2 a_cut = a0 + a1 * v + a2 * th + a3 * v * v + a4 * v * th;
        f = vselect((v > cut_v) & (a <= a_cut), zero, f);
        /* 9. Idle, with the v of step 4 and the a of step 3. */
        WfVec2 abs_a = (WfVec2)((WfMask2)a & abs_bits);
        f = vselect((v < idle_v) & (abs_a < idle_a), f_idle, f);
        fuel[i] = f[0];
        if (flag) flag[i] = (uint8_t)fl[0];
        if (pair) {
            fuel[i + 1] = f[1];
            if (flag) flag[i + 1] = (uint8_t)fl[1];
        }
    }
}

/* One point, the same operations in the same order as a lane of circles_kernel(). A separate scalar body
 * because the kernel called with n = 1 costs twice as much (it broadcasts ~30 parameters per call). */
static double circles_eval1(const WfCirclesParams *p, double v, double a, double th, int project, uint8_t *flag)
{
    double amax = min1(p->b1, p->b2 / max1(v, 1e-12) - p->b3 * v * v) - min1(p->b4, p->b5 + p->b6 * v) * th;
    if (flag) *flag = (uint8_t)(v < 0.0 ? WF_NEGATIVE_SPEED : a > amax ? WF_INFEASIBLE_ACCEL : WF_FEASIBLE);
    if (project) a = min_nan(a, amax);
    v = max1(v, 0.0);
    double P = p->p0 + p->p1 * v + p->p2 * v * v;
    double Q = p->q0 + p->q1 * max1(v, 1e-12);
    double ap = max_nan(a, -P / (2.0 * Q));
    double f = p->c0 + p->c1 * v + p->c2 * v * v + p->c3 * v * v * v + p->p0 * a + p->p1 * a * v + p->p2 * a * v * v +
               p->q0 * ap * ap + p->q1 * ap * ap * v + p->z0 * th + p->z1 * th * v + p->z2 * th * v * v;
    double lb = (v <= p->cut_v ? p->lb_beta : 0.0) + p->lb_h0 + p->lb_h1 * v;
    f = max1(f, lb);
    double a_cut = p->a0 + p->a1 * v + p->a2 * th + p->a3 * v * v + p->a4 * v * th;
    if (v > p->cut_v && a <= a_cut) f = 0.0;
    if (v < 0.1 && fabs(a) < 0.01) f = p->f_idle;
    return f;
}

double wf_circles_fuel(const WfCirclesParams *p, double v, double a, double theta, int project, uint8_t *flag)
{
    return circles_eval1(p, v, a, theta, project, flag);
}

static void circles_eval(const void *params, size_t n, const double *restrict v, const double *restrict a,
                         const double *restrict th, int project, double *restrict fuel, uint8_t *restrict flag)
{
    circles_kernel(params, n, v, a, th, project, fuel, flag);
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
