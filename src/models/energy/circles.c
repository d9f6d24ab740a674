/* The CIRCLES simplified energy model v3.1 (Khoudari et al., "Reducing Detailed Vehicle Energy Dynamics to
 * Physics-Like Models"): fuel rate f(v, a, theta) in g/s, polynomial with a fuel cut, a lower bound and an
 * idle rule, plus the feasible-acceleration bound a_max(v, theta). Evaluation order and arithmetic follow
 * the authors' release; powers are written as products and this file is built with -ffp-contract=off.
 * The kernel evaluates two, four or eight points per step with GNU C vector types; results are those of the scalar
 * formula. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/simd.h"
#include "wavefuel/energy.h"

#define P(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, -1e6, 1e6, unit, WF_PARAM_REQUIRED, doc }
#define O(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, -1e6, 1e6, unit, WF_PARAM_OPTIONAL, doc }
/* Coefficients the paper requires to be >= 0 (its structural properties: f >= 0, convex in a and in v for
 * a, theta >= 0, a lower bound and idle rate that are fuel rates): refused below 0 when a class loads, since a
 * negative one gives negative fuel (f_idle: -5 ran at -72 L/100 km). */
#define PN(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, 0, 1e6, unit, WF_PARAM_REQUIRED, doc }
#define ON(field, unit, doc) \
    { #field, offsetof(WfCirclesParams, field), NAN, 0, 1e6, unit, WF_PARAM_OPTIONAL, doc }

static const WfParamSpec circles_spec[] = {
    PN(f_idle, "g/s", "fuel rate at idle"),
    P(b1, "m/s^2", "traction-limited acceleration"),
    P(b2, "m^2/s^2", "power-limited acceleration factor"),
    P(b3, "1/m", "drag reduction of a_max"),
    P(b4, "m/(s^2 rad)", "grade effect cap on a_max"),
    P(b5, "m/(s^2 rad)", "grade effect on a_max"),
    P(b6, "1/(s rad)", "speed-dependent grade effect on a_max"),
    PN(c0, "g/s", "C(v): constant"),
    PN(c1, "g/m", "C(v): linear"),
    PN(c2, "g s/m^2", "C(v): quadratic"),
    PN(c3, "g s^2/m^3", "C(v): cubic"),
    PN(p0, "g s/m", "P(v): constant"),
    PN(p1, "g s^2/m^2", "P(v): linear"),
    PN(p2, "g s^3/m^3", "P(v): quadratic"),
    PN(q0, "g s^3/m^2", "Q(v): constant"),
    PN(q1, "g s^4/m^3", "Q(v): linear"),
    PN(z0, "g/(s rad)", "Z(v): constant"),
    PN(z1, "g/(m rad)", "Z(v): linear"),
    PN(z2, "g s/(m^2 rad)", "Z(v): quadratic"),
    O(v_c, "m/s", "light duty: fuel-cut speed"),
    ON(beta, "g/s", "light duty: lower bound below v_c"),
    O(a0, "m/s^2", "light duty: fuel-cut acceleration, constant"),
    O(a1, "1/s", "light duty: fuel-cut acceleration, v"),
    O(a2, "m/(s^2 rad)", "light duty: fuel-cut acceleration, theta"),
    O(a3, "1/m", "light duty: fuel-cut acceleration, v^2"),
    O(a4, "1/(s rad)", "light duty: fuel-cut acceleration, v theta"),
    ON(h0, "g/s", "heavy duty: lower bound, constant"),
    ON(h1, "g/m", "heavy duty: lower bound, linear"),
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

/* The array kernel in three widths from one source (circles_kernel.h): 2 lanes (SSE2, every x86-64; NEON or
 * scalar code elsewhere) and, on x86-64, 4 lanes compiled for AVX2 and 8 for x86-64-v4 (AVX-512), chosen at run
 * time by the library's SIMD level. All give the scalar formula's bits (tests/test_energy.c checks the level's
 * width against circles_eval1; tests/t_simd.sh runs it again at each narrower level). */
#define WF_LANES  2
#define WF_KERNEL circles_kernel2
#include "models/energy/circles_kernel.h"
#undef WF_LANES
#undef WF_KERNEL

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#define WF_HAVE_WIDE_KERNELS 1
#pragma GCC push_options
#pragma GCC target("avx2")
#define WF_LANES  4
#define WF_KERNEL circles_kernel4
#include "models/energy/circles_kernel.h"
#undef WF_LANES
#undef WF_KERNEL
#pragma GCC pop_options
#pragma GCC push_options
#pragma GCC target("arch=x86-64-v4")
#define WF_LANES  8
#define WF_KERNEL circles_kernel8
#include "models/energy/circles_kernel.h"
#undef WF_LANES
#undef WF_KERNEL
#pragma GCC pop_options
#endif

typedef void CirclesFlat(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                         const double *restrict a_in, double *restrict fuel, uint8_t *restrict flag);
typedef void CirclesKernel(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                           const double *restrict a_in, const double *restrict th_in, int project,
                           double *restrict fuel, uint8_t *restrict flag);

/* The kernels by width, 2, 4 and 8 lanes, and the widest of the library's SIMD level (core/simd.h: at most 2 or 4
 * lanes when WAVEFUEL_SIMD=2 or 4; tests compare them). */
#ifdef WF_HAVE_WIDE_KERNELS
static CirclesKernel *const kernels[] = {circles_kernel2, circles_kernel4, circles_kernel8};
static CirclesFlat *const flat_kernels[] = {circles_kernel2_flat, circles_kernel4_flat, circles_kernel8_flat};
#else
static CirclesKernel *const kernels[] = {circles_kernel2};
static CirclesFlat *const flat_kernels[] = {circles_kernel2_flat};
#endif

static size_t widest(void)
{
#ifdef WF_HAVE_WIDE_KERNELS
    WfSimdLevel level = wf_simd_level();
    return level >= WF_SIMD_AVX512 ? 2 : level >= WF_SIMD_AVX2 ? 1 : 0;
#else
    return 0;
#endif
}

static void circles_kernel(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                           const double *restrict a_in, const double *restrict th_in, int project,
                           double *restrict fuel, uint8_t *restrict flag)
{
    kernels[widest()](p, n, v_in, a_in, th_in, project, fuel, flag);
}

/* The flat road's form (WfEnergyModel.eval_flat) at the same width. */
static void circles_eval_flat(const void *params, size_t n, const double *restrict v, const double *restrict a,
                              double *restrict fuel, uint8_t *restrict flag)
{
    flat_kernels[widest()](params, n, v, a, fuel, flag);
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
    .eval_flat = circles_eval_flat,
};
