/* Model reduction: the CIRCLES explicit model fitted to a tabulated model, step by step as in Khoudari et al.
 * ("Reducing Detailed Vehicle Energy Dynamics to Physics-Like Models", section "Simplified Model with
 * Desirable Physics-like Properties"); docs/fit.md states every step, range and filter. The table is
 * evaluated with the release's semantics (wf_table_fuel, project on). Linear steps use LAPACK (wf_lsq) and
 * Lawson-Hanson NNLS (wf_nnls); the feasible-acceleration fits use GSL's nonlinear least squares.
 * Units: v m/s, a m/s^2, theta rad, fuel g/s. Also: sampling a class on the release's grid, and writing
 * fitted class files and release-format CSV tables. */
#include "wavefuel/fit.h"

#include <errno.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <gsl/gsl_vector.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/nnls.h"
#include "wavefuel/version.h"
#include "util/mem.h"

/* Grids of each step (the paper's, as the issue lists them). */
enum {
    N_CUT_V = 50, N_CUT_TH = 50,        /* 1b */
    N_V = 100, N_A = 100, N_TH = 100,   /* 2-5 and the heavy-duty lower bound */
    N_AMAX_V = 500,                     /* 6a */
    N_GRADE_V = 200, N_GRADE_TH = 150   /* 6b */
};
#define A_CUT_PROBE (-3.0)      /* m/s^2: the deceleration at which the fuel-cut speed and bounds are read */
#define BISECT_ITER 200         /* bisection stops earlier once the bracket stops shrinking */
#define IDLE_V 0.1              /* the explicit model's idle rule: v < 0.1 m/s and |a| < 0.01 m/s^2 */
#define IDLE_A 0.01

static double linspace(double lo, double hi, size_t n, size_t i)
{
    return n < 2 ? lo : (i + 1 == n ? hi : lo + (hi - lo) * (double)i / (double)(n - 1));
}

/* The table as the release's wrappers evaluate it (projection on); flag may be NULL. */
static double tab(const WfTable *t, double v, double a, double th, uint8_t *flag)
{
    return wf_table_fuel(t, v, a, th, 1, flag, NULL);
}

/* ---------------------------------------------------------------------------------------------------------
 * Which points a polynomial step may use. A table interpolates linearly across the explicit model's
 * discontinuities (fuel cut, lower bound, idle), so a value read inside a cell that touches a fuel-cut,
 * lower-bound or idle node is neither the polynomial nor the rule. A point is usable when every node of its
 * interpolation cell (the nodes with positive weight) is feasible, not at idle and above the lower bound:
 * the rule the release itself applies to the Infeasible column (any infeasible corner flags the point). */

/* Nodes of one axis with positive interpolation weight at x: [*k0, *k1] (clamped to the grid, as the
 * table's evaluation is). */
static void bracket(const WfTableAxis *ax, double x, size_t *k0, size_t *k1)
{
    size_t n = ax->n;
    if (n == 1 || !(x > ax->x[0])) {
        *k0 = *k1 = 0;
        return;
    }
    if (x >= ax->x[n - 1]) {
        *k0 = *k1 = n - 1;
        return;
    }
    size_t lo = 0, hi = n - 1; /* x[lo] <= x < x[hi] */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (ax->x[mid] <= x) lo = mid;
        else hi = mid;
    }
    *k0 = lo;
    *k1 = ax->x[lo] == x ? lo : hi;
}

typedef struct FitCtx {
    const WfTable *t;
    int            light;
    double         v_c, beta; /* light duty: the lower bound is beta below v_c, 0 from v_c on */
} FitCtx;

static int on_polynomial(const FitCtx *c, double v, double a, double th)
{
    const WfTable *t = c->t;
    size_t v0, v1, a0, a1, t0, t1;
    bracket(&t->v, v, &v0, &v1);
    bracket(&t->a, a, &a0, &a1);
    bracket(&t->theta, th, &t0, &t1);
    size_t na = t->a.n, nt = t->theta.n;
    for (size_t iv = v0; iv <= v1; iv++)
        for (size_t ia = a0; ia <= a1; ia++)
            for (size_t it = t0; it <= t1; it++) {
                size_t k = (iv * na + ia) * nt + it;
                double vn = t->v.x[iv], an = t->a.x[ia];
                if (t->infeasible[k]) return 0;
                if (vn < IDLE_V && fabs(an) < IDLE_A) return 0;
                double bound = c->light && vn < c->v_c ? c->beta : 0.0;
                if (!(t->fuel_gps[k] > bound)) return 0;
            }
    return 1;
}

static int usable(const FitCtx *c, double v, double a, double th)
{
    uint8_t flag = 0;
    tab(c->t, v, a, th, &flag);
    return flag == WF_FEASIBLE && on_polynomial(c, v, a, th);
}

/* ---------------------------------------------------------------------------------------------------------
 * Linear steps: a design matrix of the usable points, solved by wf_lsq or wf_nnls. */

typedef struct Design {
    size_t  cap, m, n;
    double *A, *b;
    double *v, *a, *th, *f; /* the points, for the residuals and the overall fuel-rate check */
} Design;

static int design_init(Design *d, size_t cap, size_t n, WfError *err)
{
    memset(d, 0, sizeof *d);
    d->cap = cap;
    d->n = n;
    d->A = malloc(cap * n * sizeof *d->A);
    d->b = malloc(cap * sizeof *d->b);
    d->v = malloc(cap * 4 * sizeof *d->v);
    if (!d->A || !d->b || !d->v) {
        WF_FREE(d->A, d->b, d->v);
        memset(d, 0, sizeof *d);
        return wf_err(err, WF_ESYS, "fit: out of memory");
    }
    d->a = d->v + cap;
    d->th = d->v + 2 * cap;
    d->f = d->v + 3 * cap;
    return 0;
}

static void design_free(Design *d)
{
    WF_FREE(d->A, d->b, d->v);
    memset(d, 0, sizeof *d);
}

/* Adds one row (capacity is the step's grid size, so it never overflows). */
static void design_row(Design *d, const double *row, double target, double v, double a, double th, double f)
{
    size_t i = d->m++;
    memcpy(d->A + i * d->n, row, d->n * sizeof *row);
    d->b[i] = target;
    d->v[i] = v;
    d->a[i] = a;
    d->th[i] = th;
    d->f[i] = f;
}

/* Residual statistics of x on the design: model - target. */
static void design_residuals(const Design *d, const double *x, WfFitStep *s)
{
    double ss = 0.0, mx = 0.0;
    for (size_t i = 0; i < d->m; i++) {
        double r = -d->b[i];
        for (size_t j = 0; j < d->n; j++) r += d->A[i * d->n + j] * x[j];
        ss += r * r;
        if (fabs(r) > mx) mx = fabs(r);
    }
    s->n_used = d->m;
    s->rms = d->m ? sqrt(ss / (double)d->m) : NAN;
    s->max_abs = mx;
    s->done = 1;
}

static int need_points(const WfFitStep *s, size_t m, size_t n, WfError *err)
{
    if (m >= n && m > 0) return 0;
    return wf_err(err, WF_EINPUT,
                  "fit step %s (%s): %zu usable points of %zu, %zu needed (feasible, not fuel-cut, not idle: "
                  "does the table cover v in [0, 35] m/s, a in [-3, 3] m/s^2, theta in [-0.03, 0.03] rad?)",
                  s->key, s->params, m, s->n_points, n);
}

/* ---------------------------------------------------------------------------------------------------------
 * Nonlinear steps (6): the feasible-acceleration bound, fitted by GSL's trust-region Levenberg-Marquardt.
 * Parameters are scaled by their starting values so the solver sees O(1) unknowns (b3 ~ 1e-4 1/m beside
 * b2 ~ 50 m^2/s^2). min() makes the model piecewise smooth; the Jacobian is that of the active branch. */

typedef struct NlData {
    size_t        n;
    const double *v, *th, *y; /* th NULL for the flat fit (b1..b3), given for the grade fit (b4..b6) */
    double        s[3];       /* parameter scales */
} NlData;

static double amax_flat(const double *b, double v) /* min(b1, b2 / max(v, 1e-12) - b3 v^2) */
{
    double g = b[1] / (v > 1e-12 ? v : 1e-12) - b[2] * v * v;
    return b[0] < g ? b[0] : g;
}

static double grade_gain(const double *b, double v) /* min(b4, b5 + b6 v) */
{
    double g = b[1] + b[2] * v;
    return b[0] < g ? b[0] : g;
}

static void unscale(const gsl_vector *x, const NlData *d, double *b)
{
    for (int j = 0; j < 3; j++) b[j] = gsl_vector_get(x, (size_t)j) * d->s[j];
}

/* The model at point i: the flat bound, or (th given) the grade term 2 g(v) theta. */
static double nl_model(const NlData *d, const double *b, size_t i)
{
    return d->th ? 2.0 * grade_gain(b, d->v[i]) * d->th[i] : amax_flat(b, d->v[i]);
}

static int nl_f(const gsl_vector *x, void *vd, gsl_vector *f)
{
    const NlData *d = vd;
    double b[3];
    unscale(x, d, b);
    for (size_t i = 0; i < d->n; i++) gsl_vector_set(f, i, nl_model(d, b, i) - d->y[i]);
    return GSL_SUCCESS;
}

static int flat_df(const gsl_vector *x, void *vd, gsl_matrix *J)
{
    const NlData *d = vd;
    double b[3];
    unscale(x, d, b);
    for (size_t i = 0; i < d->n; i++) {
        double v = d->v[i], vs = v > 1e-12 ? v : 1e-12;
        int cap = b[0] < b[1] / vs - b[2] * v * v;
        gsl_matrix_set(J, i, 0, cap ? d->s[0] : 0.0);
        gsl_matrix_set(J, i, 1, cap ? 0.0 : d->s[1] / vs);
        gsl_matrix_set(J, i, 2, cap ? 0.0 : -d->s[2] * v * v);
    }
    return GSL_SUCCESS;
}

static int grade_df(const gsl_vector *x, void *vd, gsl_matrix *J)
{
    const NlData *d = vd;
    double b[3];
    unscale(x, d, b);
    for (size_t i = 0; i < d->n; i++) {
        double v = d->v[i], tw = 2.0 * d->th[i];
        int cap = b[0] < b[1] + b[2] * v;
        gsl_matrix_set(J, i, 0, cap ? tw * d->s[0] : 0.0);
        gsl_matrix_set(J, i, 1, cap ? 0.0 : tw * d->s[1]);
        gsl_matrix_set(J, i, 2, cap ? 0.0 : tw * v * d->s[2]);
    }
    return GSL_SUCCESS;
}

static double nl_cost(const NlData *d, const double *b)
{
    double ss = 0.0;
    for (size_t i = 0; i < d->n; i++) {
        double r = nl_model(d, b, i) - d->y[i];
        ss += r * r;
    }
    return ss;
}

/* Levenberg-Marquardt from b (3 values, unscaled); on success b holds the solution. GSL's error handler
 * is switched off for the call (its default aborts) and restored after. Converged means GSL's small-step
 * or small-gradient test passed, or "no further progress" (GSL_ENOPROG: the trust region cannot shrink
 * further, an end a piecewise model on a staircase target can reach; the caller compares costs). Running
 * out of iterations is a failure (WF_ESYS). */
static int nl_fit(NlData *d, double *b, WfError *err)
{
    for (int j = 0; j < 3; j++) d->s[j] = fabs(b[j]) > 1e-300 ? fabs(b[j]) : 1.0;
    gsl_multifit_nlinear_fdf fdf = {0};
    fdf.f = nl_f;
    fdf.df = d->th ? grade_df : flat_df;
    fdf.n = d->n;
    fdf.p = 3;
    fdf.params = d;
    gsl_multifit_nlinear_parameters fp = gsl_multifit_nlinear_default_parameters();
    gsl_error_handler_t *old = gsl_set_error_handler_off();
    gsl_multifit_nlinear_workspace *w = gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &fp, d->n, 3);
    int rc = 0;
    if (!w) {
        gsl_set_error_handler(old);
        return wf_err(err, WF_ESYS, "fit: gsl_multifit_nlinear_alloc failed (%zu points)", d->n);
    }
    double x0[3] = {b[0] / d->s[0], b[1] / d->s[1], b[2] / d->s[2]};
    gsl_vector_view xv = gsl_vector_view_array(x0, 3);
    int info = 0;
    int st = gsl_multifit_nlinear_init(&xv.vector, &fdf, w);
    if (st == GSL_SUCCESS) st = gsl_multifit_nlinear_driver(500, 1e-12, 1e-12, 0.0, NULL, NULL, &info, w);
    if (st == GSL_SUCCESS || st == GSL_ENOPROG) {
        double bn[3];
        unscale(gsl_multifit_nlinear_position(w), d, bn);
        if (isfinite(bn[0]) && isfinite(bn[1]) && isfinite(bn[2])) memcpy(b, bn, sizeof bn);
        else rc = wf_err(err, WF_ESYS, "fit: the nonlinear fit of %s diverged", d->th ? "b4..b6" : "b1..b3");
    } else {
        rc = wf_err(err, WF_ESYS, "fit: the nonlinear fit of %s did not converge (gsl_multifit_nlinear_driver: %s)",
                    d->th ? "b4..b6" : "b1..b3", gsl_strerror(st));
    }
    gsl_multifit_nlinear_free(w);
    gsl_set_error_handler(old);
    return rc;
}

static void nl_residuals(const NlData *d, const double *b, WfFitStep *s)
{
    double mx = 0.0;
    for (size_t i = 0; i < d->n; i++)
        if (fabs(nl_model(d, b, i) - d->y[i]) > mx) mx = fabs(nl_model(d, b, i) - d->y[i]);
    s->n_used = d->n;
    s->rms = d->n ? sqrt(nl_cost(d, b) / (double)d->n) : NAN;
    s->max_abs = mx;
    s->done = 1;
}

/* 6a. b1..b3 from the table's largest feasible acceleration on flat road over its speed range. Start:
 * b1 = the low-speed plateau (the largest value), b2 and b3 by linear least squares of y on (1/v, -v^2)
 * over the points below the plateau (power-limited). */
static int fit_amax_flat(const WfTable *t, WfCirclesParams *p, WfFitStep *s, WfError *err)
{
    double v[N_AMAX_V], y[N_AMAX_V], rows[N_AMAX_V * 2], rhs[N_AMAX_V];
    double top = -INFINITY;
    for (size_t i = 0; i < N_AMAX_V; i++) {
        v[i] = linspace(t->v.lo, t->v.hi, N_AMAX_V, i);
        y[i] = wf_table_a_max(t, v[i], 0.0);
        if (y[i] > top) top = y[i];
    }
    s->n_points = N_AMAX_V;
    size_t m = 0;
    for (size_t i = 0; i < N_AMAX_V; i++)
        if (v[i] > 0 && y[i] < top - 1e-9) {
            rows[2 * m] = 1.0 / v[i];
            rows[2 * m + 1] = -v[i] * v[i];
            rhs[m++] = y[i];
        }
    if (m < 3)
        return wf_err(err, WF_EINPUT,
                      "fit step a_max_flat: the table's largest feasible acceleration on flat road never drops "
                      "below its low-speed value %.6g m/s^2 over [%.6g, %.6g] m/s: no power limit to fit b2, b3",
                      top, t->v.lo, t->v.hi);
    double b23[2];
    int rc = wf_lsq(m, 2, rows, rhs, b23, err);
    if (rc) return rc;
    double b[3] = {top, b23[0], b23[1]};
    NlData d = {.n = N_AMAX_V, .v = v, .th = NULL, .y = y};
    if ((rc = nl_fit(&d, b, err))) return rc;
    p->b1 = b[0];
    p->b2 = b[1];
    p->b3 = b[2];
    nl_residuals(&d, b, s);
    return 0;
}

/* 6b. b4..b6 from a_max(v, -theta) - a_max(v, theta) = 2 min(b4, b5 + b6 v) theta. The cap b4 may bind
 * anywhere in [0, 35] m/s or nowhere, and the Jacobian of an inactive branch is zero, so several starts
 * are tried: the uncapped linear fit (b4 at the line's largest value over the range: never active, the
 * same model there) and caps at the line's value at 5, 10, 20 and 30 m/s. The lowest cost wins (ties: the
 * first), so the result does not depend on anything but the table. */
static int fit_amax_grade(const WfTable *t, WfCirclesParams *p, WfFitStep *s, WfError *err)
{
    const size_t n = (size_t)N_GRADE_V * N_GRADE_TH;
    double *buf = malloc(n * 5 * sizeof *buf);
    if (!buf) return wf_err(err, WF_ESYS, "fit: out of memory");
    double *v = buf, *th = buf + n, *y = buf + 2 * n, *rows = buf + 3 * n; /* rows: 2 per point */
    size_t m = 0;
    for (size_t i = 0; i < N_GRADE_V; i++)
        for (size_t j = 0; j < N_GRADE_TH; j++) {
            double vi = linspace(0.0, WF_FIT_V_MAX, N_GRADE_V, i), tj = linspace(-0.03, 0.03, N_GRADE_TH, j);
            if (tj == 0.0) continue; /* no information at theta = 0 */
            v[m] = vi;
            th[m] = tj;
            y[m] = wf_table_a_max(t, vi, -tj) - wf_table_a_max(t, vi, tj);
            rows[2 * m] = 2.0 * tj;
            rows[2 * m + 1] = 2.0 * tj * vi;
            m++;
        }
    s->n_points = n;
    double line[2];
    int rc = wf_lsq(m, 2, rows, y, line, err);
    NlData d = {.n = m, .v = v, .th = th, .y = y};
    double best[3], best_cost = INFINITY;
    if (!rc) {
        double hi = line[0] + line[1] * WF_FIT_V_MAX;
        best[0] = hi > line[0] ? hi : line[0];
        best[1] = line[0];
        best[2] = line[1];
        best_cost = nl_cost(&d, best);
        static const double cap_v[] = {5.0, 10.0, 20.0, 30.0};
        for (size_t k = 0; k < sizeof cap_v / sizeof cap_v[0]; k++) {
            double b[3] = {line[0] + line[1] * cap_v[k], line[0], line[1]};
            /* A start that does not converge is dropped: the uncapped candidate always exists. */
            if (nl_fit(&d, b, err)) continue;
            double cost = nl_cost(&d, b);
            if (cost < best_cost) {
                best_cost = cost;
                memcpy(best, b, sizeof b);
            }
        }
    }
    if (!rc) {
        /* A cap above the line's largest value over the range never binds: write it as that value. */
        double top = best[1] + best[2] * WF_FIT_V_MAX;
        if (top < best[1]) top = best[1];
        if (best[0] > top) best[0] = top;
        p->b4 = best[0];
        p->b5 = best[1];
        p->b6 = best[2];
        nl_residuals(&d, best, s);
    }
    free(buf);
    return rc;
}

/* ---------------------------------------------------------------------------------------------------------
 * The pipeline */

static void step_init(WfFitResult *r)
{
    static const struct {
        const char *key, *params, *target, *unit;
    } info[WF_FIT_N_STEPS] = {
        [WF_FIT_STEP_CUT_SPEED] = {"fuel_cut_speed", "v_c beta",
                                   "v_c: bisection for f(v, -3, 0) = 0 over [0, 35] m/s; beta = f(0, -3, 0)", "m/s"},
        [WF_FIT_STEP_CUT_ACCEL] = {"fuel_cut_accel", "a0 a1 a2 a3 a4",
                                   "least squares on the accelerations where f reaches 0 (bisection in a), "
                                   "50 x 50 points, v in [v_c + 1, 35], theta in [-0.03, 0]",
                                   "m/s^2"},
        [WF_FIT_STEP_C] = {"C", "c0 c1 c2 c3", "NNLS of C(v) to f(v, 0, 0), 100 points on [0, 35]", "g/s"},
        [WF_FIT_STEP_P] = {"P", "p0 p1 p2",
                           "NNLS of P(v) a to f(v, a, 0) - C(v), 100 x 100 points (a in [-0.3, 0.3]: only points "
                           "whose mirror -a is usable too; heavy duty a in [0, 0.3])",
                           "g/s"},
        [WF_FIT_STEP_Q] = {"Q", "q0 q1",
                           "NNLS of Q(v) a^2 to f(v, a, 0) - C(v) - P(v) a, 100 x 100 points, a in [0, 3]", "g/s"},
        [WF_FIT_STEP_Z] = {"Z", "z0 z1 z2", "NNLS of Z(v) theta to f(v, 0, theta) - f_p(v, 0, 0), 100 x 100 points",
                           "g/s"},
        [WF_FIT_STEP_AMAX_FLAT] = {"a_max_flat", "b1 b2 b3",
                                   "min(b1, b2/v - b3 v^2) to the table's a_max(v, 0), 500 points, nonlinear",
                                   "m/s^2"},
        [WF_FIT_STEP_AMAX_GRADE] = {"a_max_grade", "b4 b5 b6",
                                    "2 min(b4, b5 + b6 v) theta to a_max(v, -theta) - a_max(v, theta), 200 x 150 "
                                    "points, nonlinear",
                                    "m/s^2"},
        [WF_FIT_STEP_IDLE] = {"idle", "f_idle", "f(0, 0, 0)", "g/s"},
        [WF_FIT_STEP_LOWER_BOUND] = {"lower_bound", "h0 h1", "NNLS of h0 + h1 v to f(v, -3, 0), 100 points on [0, 35]",
                                     "g/s"},
    };
    for (int k = 0; k < WF_FIT_N_STEPS; k++) {
        WfFitStep *s = &r->step[k];
        memset(s, 0, sizeof *s);
        s->key = info[k].key;
        s->params = info[k].params;
        s->target = info[k].target;
        s->unit = info[k].unit;
        s->rms = NAN;
        s->max_abs = NAN;
    }
}

/* 1a. The fuel-cut speed: bisection on f(v, -3, 0) > 0 over [0, 35]. Returns the speed where the fuel rate
 * reaches zero (the upper end of the final bracket, where f = 0 holds), or WF_FIT_V_MAX when f(35, -3, 0)
 * is still positive: no fuel cut in range. */
static double fuel_cut_speed(const WfTable *t, size_t *n_eval)
{
    double lo = 0.0, hi = WF_FIT_V_MAX;
    *n_eval = 2;
    if (tab(t, hi, A_CUT_PROBE, 0.0, NULL) > 0.0) return WF_FIT_V_MAX;
    if (!(tab(t, lo, A_CUT_PROBE, 0.0, NULL) > 0.0)) return 0.0;
    for (int k = 0; k < BISECT_ITER; k++) {
        double mid = 0.5 * (lo + hi);
        if (!(mid > lo && mid < hi)) break; /* the bracket is two adjacent doubles */
        ++*n_eval;
        if (tab(t, mid, A_CUT_PROBE, 0.0, NULL) > 0.0) lo = mid;
        else hi = mid;
    }
    return hi;
}

/* 1b. a0..a4 on the zero-fuel accelerations. For each (v, theta) the bracket is [lowest grid
 * acceleration, a_max(v, theta)]: f must be 0 at the bottom and positive at the top, else the point has
 * no fuel cut in range and is not used. */
static int fit_cut_accel(const FitCtx *c, WfCirclesParams *p, WfFitStep *s, WfError *err)
{
    const WfTable *t = c->t;
    Design d;
    int rc = design_init(&d, (size_t)N_CUT_V * N_CUT_TH, 5, err);
    if (rc) return rc;
    s->n_points = (size_t)N_CUT_V * N_CUT_TH;
    double v_lo = c->v_c + 1.0;
    for (size_t i = 0; v_lo <= WF_FIT_V_MAX && i < N_CUT_V; i++)
        for (size_t j = 0; j < N_CUT_TH; j++) {
            double v = linspace(v_lo, WF_FIT_V_MAX, N_CUT_V, i), th = linspace(-0.03, 0.0, N_CUT_TH, j);
            double lo = t->a.lo, hi = wf_table_a_max(t, v, th);
            if (!(hi > lo)) continue;
            if (!(tab(t, v, lo, th, NULL) <= 0.0) || !(tab(t, v, hi, th, NULL) > 0.0)) continue;
            for (int k = 0; k < BISECT_ITER; k++) {
                double mid = 0.5 * (lo + hi);
                if (!(mid > lo && mid < hi)) break;
                if (tab(t, v, mid, th, NULL) <= 0.0) lo = mid;
                else hi = mid;
            }
            double row[5] = {1.0, v, th, v * v, v * th};
            design_row(&d, row, lo, v, lo, th, 0.0);
        }
    if (!(rc = need_points(s, d.m, 5, err))) {
        double x[5];
        if (!(rc = wf_lsq(d.m, 5, d.A, d.b, x, err))) {
            p->a0 = x[0];
            p->a1 = x[1];
            p->a2 = x[2];
            p->a3 = x[3];
            p->a4 = x[4];
            design_residuals(&d, x, s);
        }
    }
    design_free(&d);
    return rc;
}

static double C_of(const WfCirclesParams *p, double v) { return p->c0 + p->c1 * v + p->c2 * v * v + p->c3 * v * v * v; }
static double P_of(const WfCirclesParams *p, double v) { return p->p0 + p->p1 * v + p->p2 * v * v; }

/* Keeps the points of steps 2-5 for the overall fuel-rate check. */
typedef struct Keep {
    size_t  n, cap;
    double *v, *a, *th, *f;
} Keep;

static void keep_design(Keep *k, const Design *d)
{
    for (size_t i = 0; i < d->m && k->n < k->cap; i++) {
        k->v[k->n] = d->v[i];
        k->a[k->n] = d->a[i];
        k->th[k->n] = d->th[i];
        k->f[k->n] = d->f[i];
        k->n++;
    }
}

/* One NNLS step on a (v, second coordinate) grid. kind: 'C' (f(v,0,0), basis 1 v v^2 v^3), 'P' (f(v,a,0) -
 * C, basis a, a v, a v^2), 'Q' (f(v,a,0) - C - P a, basis a^2, a^2 v), 'J' (P and Q jointly: f(v,a,0) - C,
 * basis a, a v, a v^2, a^2, a^2 v), 'Z' (f(v,0,th) - C, basis th, th v, th v^2). */
static int nnls_step(const FitCtx *c, int kind, double lo2, double hi2, WfCirclesParams *p, WfFitStep *s, Keep *keep,
                     WfError *err)
{
    size_t n1 = N_V, n2 = kind == 'C' ? 1 : (kind == 'Z' ? N_TH : N_A);
    /* The joint step reads the table at its own acceleration nodes in [lo2, hi2]: there the table holds the
     * model's values in a, not a linear interpolation of a^2 between nodes (whose error, up to Q h_a^2 / 4, a
     * basis without a constant term cannot absorb: it moved the class 4 truck's q1 by 0.6 %). */
    size_t a_first = 0;
    if (kind == 'J') {
        const WfTableAxis *ax = &c->t->a;
        while (a_first < ax->n && ax->x[a_first] < lo2) a_first++;
        for (n2 = 0; a_first + n2 < ax->n && ax->x[a_first + n2] <= hi2;) n2++;
    }
    size_t n = kind == 'C' ? 4 : kind == 'Q' ? 2 : kind == 'J' ? 5 : 3;
    /* Step 3's model, C + P a, leaves out Q a^2. Over an a-range symmetric about 0, a^2 is orthogonal to
     * a, a v, a v^2 only if the points used are symmetric too; the filter removes fuel-cut and lower-bound
     * points at negative a alone, which would bias P by a share of Q (up to 2x on p1 for the midsize
     * sedan). So a point is used only when its mirror (v, -a) is usable as well. */
    int symmetric = kind == 'P' && lo2 == -hi2;
    Design d;
    int rc = design_init(&d, n1 * n2, n, err);
    if (rc) return rc;
    s->n_points = n1 * n2;
    for (size_t i = 0; i < n1; i++)
        for (size_t j = 0; j < n2; j++) {
            double v = linspace(0.0, WF_FIT_V_MAX, n1, i);
            double x2 = kind == 'C' ? 0.0 : kind == 'J' ? c->t->a.x[a_first + j] : linspace(lo2, hi2, n2, j);
            double a = kind == 'P' || kind == 'Q' || kind == 'J' ? x2 : 0.0, th = kind == 'Z' ? x2 : 0.0;
            uint8_t flag = 0;
            double f = tab(c->t, v, a, th, &flag);
            if (flag != WF_FEASIBLE || !on_polynomial(c, v, a, th)) continue;
            if (symmetric && !usable(c, v, -a, th)) continue;
            double row[5], y;
            switch (kind) {
            case 'C':
                row[0] = 1.0, row[1] = v, row[2] = v * v, row[3] = v * v * v;
                y = f;
                break;
            case 'P':
                row[0] = a, row[1] = a * v, row[2] = a * v * v;
                y = f - C_of(p, v);
                break;
            case 'Q':
                /* a >= 0 and P, Q >= 0 give a+ = max(a, -P/(2Q)) = a: the step is linear in q0, q1. */
                row[0] = a * a, row[1] = a * a * v;
                y = f - C_of(p, v) - P_of(p, v) * a;
                break;
            case 'J': /* a >= 0 again: a+ = a, linear in all five */
                row[0] = a, row[1] = a * v, row[2] = a * v * v, row[3] = a * a, row[4] = a * a * v;
                y = f - C_of(p, v);
                break;
            default:
                row[0] = th, row[1] = th * v, row[2] = th * v * v;
                y = f - C_of(p, v);
                break;
            }
            design_row(&d, row, y, v, a, th, f);
        }
    double x[5] = {0};
    if (!(rc = need_points(s, d.m, n, err)) && !(rc = wf_nnls(d.m, n, d.A, d.b, x, NULL, err))) {
        design_residuals(&d, x, s);
        keep_design(keep, &d);
        switch (kind) {
        case 'C': p->c0 = x[0], p->c1 = x[1], p->c2 = x[2], p->c3 = x[3]; break;
        case 'P': p->p0 = x[0], p->p1 = x[1], p->p2 = x[2]; break;
        case 'Q': p->q0 = x[0], p->q1 = x[1]; break;
        case 'J': p->p0 = x[0], p->p1 = x[1], p->p2 = x[2], p->q0 = x[3], p->q1 = x[4]; break;
        default: p->z0 = x[0], p->z1 = x[1], p->z2 = x[2]; break;
        }
    }
    if (rc) wf_err_prefix(err, "fit step %s: ", s->key);
    design_free(&d);
    return rc;
}

/* Heavy duty: h0 + h1 v >= 0 to f(v, -3, 0) on 100 speeds. */
static int fit_lower_bound(const FitCtx *c, WfCirclesParams *p, WfFitStep *s, WfError *err)
{
    Design d;
    int rc = design_init(&d, N_V, 2, err);
    if (rc) return rc;
    s->n_points = N_V;
    for (size_t i = 0; i < N_V; i++) {
        double v = linspace(0.0, WF_FIT_V_MAX, N_V, i);
        uint8_t flag = 0;
        double f = tab(c->t, v, A_CUT_PROBE, 0.0, &flag);
        if (flag != WF_FEASIBLE) continue;
        double row[2] = {1.0, v};
        design_row(&d, row, f, v, A_CUT_PROBE, 0.0, f);
    }
    double x[2] = {0};
    if (!(rc = need_points(s, d.m, 2, err)) && !(rc = wf_nnls(d.m, 2, d.A, d.b, x, NULL, err))) {
        p->h0 = x[0];
        p->h1 = x[1];
        design_residuals(&d, x, s);
    }
    design_free(&d);
    return rc;
}

/* The steps read the table over v in [0, 35] m/s, a in [-3, 3] m/s^2 and theta in [-0.03, 0.03] rad; a table that
 * does not span them would be read at its clamped edge, which no step can fit. */
static int check_grid(const WfTable *t, WfError *err)
{
    const double eps = 1e-9;
    if (t->v.lo <= eps && t->v.hi >= WF_FIT_V_MAX - eps && t->a.lo <= -3.0 + eps && t->a.hi >= 3.0 - eps &&
        t->theta.lo <= -0.03 + eps && t->theta.hi >= 0.03 - eps)
        return 0;
    return wf_err(err, WF_EINPUT,
                  "fit: the table's grid (v [%.6g, %.6g] m/s, a [%.6g, %.6g] m/s^2, theta [%.6g, %.6g] rad) "
                  "must span "
                  "v [0, 35] m/s, a [-3, 3] m/s^2 and theta [-0.03, 0.03] rad, the ranges the fit reads (the "
                  "release's tables span v [0, 35], a [-4, 4], theta [-0.03, 0.03])",
                  t->v.lo, t->v.hi, t->a.lo, t->a.hi, t->theta.lo, t->theta.hi);
}

/* Overall: the fitted model, as the simulator evaluates it, against the table at the points of steps 2-5. */
static void overall_error(const WfCirclesParams *p, const Keep *keep, WfFitResult *r)
{
    double ss = 0.0, mx = 0.0;
    for (size_t i = 0; i < keep->n; i++) {
        double e = wf_circles_fuel(p, keep->v[i], keep->a[i], keep->th[i], 0, NULL) - keep->f[i];
        ss += e * e;
        if (fabs(e) > mx) mx = fabs(e);
    }
    r->fuel_n = keep->n;
    r->fuel_rms_gps = keep->n ? sqrt(ss / (double)keep->n) : NAN;
    r->fuel_max_gps = mx;
}

/* 3-4. P and Q: the paper's two steps, or one joint step (WfFitPQ). */
static int fit_pq(const FitCtx *c, WfFitPQ pq, WfCirclesParams *p, WfFitResult *r, Keep *keep, WfError *err)
{
    WfFitStep *sp = &r->step[WF_FIT_STEP_P];
    if (pq == WF_FIT_PQ_JOINT) {
        sp->key = "PQ";
        sp->params = "p0 p1 p2 q0 q1";
        sp->target = "NNLS of P(v) a + Q(v) a^2 to f(v, a, 0) - C(v), 100 speeds x the table's acceleration nodes "
                     "in [0, 3] (--pq joint)";
        return nnls_step(c, 'J', 0.0, 3.0, p, sp, keep, err);
    }
    /* Heavy duty: a in [0, 0.3] for P (the paper's heavy-duty range). */
    int rc = nnls_step(c, 'P', c->light ? -0.3 : 0.0, 0.3, p, sp, keep, err);
    return rc ? rc : nnls_step(c, 'Q', 0.0, 3.0, p, &r->step[WF_FIT_STEP_Q], keep, err);
}

int wf_fit_table(const WfTable *t, const WfFitOptions *opt, WfFitResult *out, WfError *err)
{
    WfFitDuty duty = opt ? opt->duty : WF_FIT_DUTY_AUTO;
    WfFitResult *r = calloc(1, sizeof *r);
    Keep keep = {0};
    if (!r) return wf_err(err, WF_ESYS, "fit: out of memory");
    step_init(r);
    WfCirclesParams *p = &r->params;
    wf_param_defaults(wf_energy_circles.spec, wf_energy_circles.n_spec, p); /* NaN everywhere */
    snprintf(r->table_source, sizeof r->table_source, "%s", t->source);
    r->table_checksum = t->data_fnv1a64;
    r->pq = opt ? opt->pq : WF_FIT_PQ_PAPER;
    int rc = 0;
    FitCtx c = {.t = t, .light = 0, .v_c = INFINITY, .beta = 0.0};
    if ((rc = check_grid(t, err))) goto done;
    double th_hi_z = 0.02;

    /* 1a. Fuel-cut speed and duty. */
    size_t n_eval = 0;
    double v_c = fuel_cut_speed(t, &n_eval);
    int no_cut = v_c >= WF_FIT_V_MAX;
    WfFitStep *s = &r->step[WF_FIT_STEP_CUT_SPEED];
    s->n_points = n_eval;
    s->n_used = 1;
    s->done = 1;
    if (duty == WF_FIT_DUTY_LIGHT && no_cut) {
        rc = wf_err(err, WF_EINPUT,
                    "fit: light duty was asked for, but the table's fuel rate at a = -3 m/s^2 on flat road is still "
                    "%.6g g/s at %.6g m/s: no fuel cut to fit (use --duty heavy or auto)",
                    tab(t, WF_FIT_V_MAX, A_CUT_PROBE, 0.0, NULL), WF_FIT_V_MAX);
        goto done;
    }
    r->duty = duty == WF_FIT_DUTY_HEAVY || (duty == WF_FIT_DUTY_AUTO && no_cut) ? WF_DUTY_HEAVY : WF_DUTY_LIGHT;
    r->duty_detected = duty == WF_FIT_DUTY_AUTO;
    c.light = r->duty == WF_DUTY_LIGHT;
    if (c.light) {
        p->v_c = c.v_c = v_c;
        p->beta = c.beta = tab(t, 0.0, A_CUT_PROBE, 0.0, NULL);
        if ((rc = fit_cut_accel(&c, p, &r->step[WF_FIT_STEP_CUT_ACCEL], err))) goto done;
    }

    /* 2-5. The polynomial, each step with the previous ones fixed. */
    keep.cap = 4 * (size_t)N_V * N_A;
    keep.v = malloc(4 * keep.cap * sizeof *keep.v);
    if (!keep.v) {
        rc = wf_err(err, WF_ESYS, "fit: out of memory");
        goto done;
    }
    keep.a = keep.v + keep.cap;
    keep.th = keep.v + 2 * keep.cap;
    keep.f = keep.v + 3 * keep.cap;
    /* Heavy duty: theta in [0, 0.02] for Z (the paper's heavy-duty range). */
    th_hi_z = c.light ? 0.03 : 0.02;
    if ((rc = nnls_step(&c, 'C', 0, 0, p, &r->step[WF_FIT_STEP_C], &keep, err)) ||
        (rc = fit_pq(&c, r->pq, p, r, &keep, err)) ||
        (rc = nnls_step(&c, 'Z', 0.0, th_hi_z, p, &r->step[WF_FIT_STEP_Z], &keep, err)))
        goto done;

    /* 6. Feasible region. */
    if ((rc = fit_amax_flat(t, p, &r->step[WF_FIT_STEP_AMAX_FLAT], err)) ||
        (rc = fit_amax_grade(t, p, &r->step[WF_FIT_STEP_AMAX_GRADE], err)))
        goto done;

    /* 7. Idle. */
    p->f_idle = tab(t, 0.0, 0.0, 0.0, NULL);
    s = &r->step[WF_FIT_STEP_IDLE];
    s->n_points = s->n_used = 1;
    s->done = 1;

    if (!c.light && (rc = fit_lower_bound(&c, p, &r->step[WF_FIT_STEP_LOWER_BOUND], err))) goto done;

    /* The parameters must form a valid class model (this also fills the kernel's derived fields). */
    if ((rc = wf_energy_circles.check(p, err))) {
        wf_err_prefix(err, "fit: the fitted parameters are not a valid model: ");
        goto done;
    }
    overall_error(p, &keep, r);
    *out = *r;
done:
    free(keep.v);
    free(r);
    return rc;
}

/* ---------------------------------------------------------------------------------------------------------
 * Files */

/* fopen(PATH.partial) with the no-overwrite rule; the caller writes, then finish_partial(). */
static int open_partial(const char *path, int force, char *partial, size_t len, FILE **out, WfError *err)
{
    *out = NULL;
    int w = snprintf(partial, len, "%s.partial", path);
    if (w < 0 || (size_t)w >= len) return wf_err(err, WF_EINPUT, "%s: path too long", path);
    if (!force && access(path, F_OK) == 0)
        return wf_err(err, WF_EINPUT, "%s exists; not overwriting it (use --force)", path);
    FILE *f = fopen(partial, "w");
    if (!f) return wf_err(err, WF_ESYS, "%s: cannot create: %s", partial, strerror(errno));
    *out = f;
    return 0;
}

static int finish_partial(FILE *f, const char *partial, const char *path, int write_failed, WfError *err)
{
    int bad = write_failed | ferror(f);
    if (fclose(f) != 0) bad = 1;
    if (!bad && rename(partial, path) == 0) return 0;
    int e = errno; /* of the failed write, close or rename */
    remove(partial);
    return bad ? wf_err(err, WF_ESYS, "%s: write failed: %s", partial, strerror(e))
               : wf_err(err, WF_ESYS, "cannot rename %s to %s: %s", partial, path, strerror(e));
}

/* A YAML double-quoted scalar (escapes quotes, backslashes and control characters). */
static void yaml_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (const unsigned char *c = (const unsigned char *)(s ? s : ""); *c; c++) {
        if (*c == '"' || *c == '\\') fprintf(f, "\\%c", *c);
        else if (*c < 0x20) fprintf(f, "\\x%02x", *c);
        else fputc(*c, f);
    }
    fputc('"', f);
}

static void yaml_num(FILE *f, double x)
{
    if (isnan(x)) fputs("null", f);
    else fprintf(f, "%.6g", x);
}

int wf_fit_write_class(const WfFitResult *r, const WfFitClassInfo *info, const char *path, int force, WfError *err)
{
    if (!(info->mass_kg >= 100 && info->mass_kg <= 100000) || !(info->length_m >= 1 && info->length_m <= 30) ||
        !(info->kw_per_gps >= 1 && info->kw_per_gps <= 100))
        return wf_err(err, WF_EINPUT,
                      "%s: class metadata out of range: mass_kg %.6g (100..100000), length_m %.6g (1..30), "
                      "kw_per_gps %.6g (1..100)",
                      path, info->mass_kg, info->length_m, info->kw_per_gps);
    char partial[4200];
    FILE *f = NULL;
    int rc = open_partial(path, force, partial, sizeof partial, &f, err);
    if (rc) return rc;
    fputs("# CIRCLES simplified (physics-like) energy model, fitted by `wavefuel fit` from a tabulated model\n"
          "# (docs/fit.md). Units of every parameter are in the trailing comment; fuel rates in g/s, speed m/s,\n"
          "# accel m/s^2, grade rad. The fit's residuals per step are under source.fit.\n",
          f);
    fputs("name: ", f);
    yaml_str(f, info->label);
    fprintf(f, "\nduty: %s\nfuel: %s\n", wf_duty_name(r->duty), wf_fuel_name(info->fuel));
    fprintf(f, "mass_kg: %.10g\nlength_m: %.10g\nkw_per_gps: %.10g        # equivalent power per fuel rate, kW/(g/s)\n",
            info->mass_kg, info->length_m, info->kw_per_gps);
    if (!isnan(info->fuel_density_g_per_l)) fprintf(f, "fuel_density_g_per_l: %.10g\n", info->fuel_density_g_per_l);
    fputs("energy_model: circles_polynomial\nsource:\n  method: ", f);
    yaml_str(f, "wavefuel fit: the model reduction of Khoudari et al., Reducing Detailed Vehicle Energy Dynamics "
                "to Physics-Like Models (arXiv:2310.06297), section Simplified Model with Desirable Physics-like "
                "Properties; steps in docs/fit.md");
    fputs("\n  table: ", f);
    yaml_str(f, info->table_path ? info->table_path : "");
    fputs("\n  table_source: ", f);
    yaml_str(f, r->table_source);
    fprintf(f, "\n  table_checksum: \"%016llx\"\n  fitted_by: ", (unsigned long long)r->table_checksum);
    char by[128];
    snprintf(by, sizeof by, "wavefuel %s (%s)", WF_VERSION, wf_git_hash());
    yaml_str(f, by);
    if (info->command) {
        fputs("\n  command: ", f);
        yaml_str(f, info->command);
    }
    fprintf(f, "\n  duty: \"%s (%s)\"\n", wf_duty_name(r->duty),
            r->duty_detected ? (r->duty == WF_DUTY_HEAVY ? "detected: no fuel cut below 35 m/s"
                                                         : "detected: fuel cut below 35 m/s")
                             : "forced by --duty");
    fprintf(f, "  fuel_rate_rms_gps: %.6g    # fitted model - table over the points of steps C, P, Q, Z\n",
            r->fuel_rms_gps);
    fprintf(f, "  fuel_rate_max_gps: %.6g\n  fuel_rate_points: %zu\n  fit:\n", r->fuel_max_gps, r->fuel_n);
    for (int k = 0; k < WF_FIT_N_STEPS; k++) {
        const WfFitStep *s = &r->step[k];
        if (!s->done) continue;
        fprintf(f, "    %s: {params: \"%s\", rms: ", s->key, s->params);
        yaml_num(f, s->rms);
        fputs(", max_abs: ", f);
        yaml_num(f, s->max_abs);
        fprintf(f, ", unit: \"%s\", points_used: %zu, points: %zu, target: ", s->unit, s->n_used, s->n_points);
        yaml_str(f, s->target);
        fputs("}\n", f);
    }
    fputs("energy:\n", f);
    for (size_t k = 0; k < wf_energy_circles.n_spec; k++) {
        const WfParamSpec *sp = &wf_energy_circles.spec[k];
        double x = wf_param_get(&r->params, sp);
        /* The other duty's keys are not written (check() filled them with values that stand for "absent"). */
        int heavy_key = !strcmp(sp->key, "h0") || !strcmp(sp->key, "h1");
        int light_key =
            !strcmp(sp->key, "v_c") || !strcmp(sp->key, "beta") || (sp->key[0] == 'a' && sp->key[2] == '\0');
        if ((r->duty == WF_DUTY_LIGHT && heavy_key) || (r->duty == WF_DUTY_HEAVY && light_key)) continue;
        char num[40];
        snprintf(num, sizeof num, "%.17g", x);
        fprintf(f, "  %s: %-24s # %s\n", sp->key, num, sp->unit);
    }
    return finish_partial(f, partial, path, 0, err);
}

/* ---------------------------------------------------------------------------------------------------------
 * Sampling and CSV */

void wf_fit_release_grid(WfFitGrid *g)
{
    /* Integer numerators divided by a power of ten: each node is the double nearest its decimal value. */
    g->nv = 101;
    for (size_t i = 0; i < g->nv; i++) g->v_mps[i] = (double)(35 * (long)i) / 100.0;
    g->na = 101;
    for (size_t j = 0; j < g->na; j++) g->a_mps2[j] = (double)(8 * (long)j - 400) / 100.0;
    g->nt = 21;
    for (size_t k = 0; k < g->nt; k++) g->theta_rad[k] = (double)(3 * (long)k - 30) / 1000.0;
}

int wf_fit_sample_class(const WfVehicleClass *vc, const WfFitGrid *g, const char *source, WfTable **out, WfError *err)
{
    *out = NULL;
    size_t n = g->nv * g->na * g->nt;
    if (n == 0 || g->nv > 256 || g->na > 256 || g->nt > 64)
        return wf_err(err, WF_EINPUT, "sample: grid of %zu x %zu x %zu nodes (each axis 1..256, grades 1..64)", g->nv,
                      g->na, g->nt);
    double *buf = malloc(n * 4 * sizeof *buf);
    uint8_t *flag = malloc(n);
    int rc = 0;
    if (!buf || !flag) rc = wf_err(err, WF_ESYS, "sample: out of memory (%zu nodes)", n);
    if (!rc) {
        double *v = buf, *a = buf + n, *th = buf + 2 * n, *f = buf + 3 * n;
        for (size_t iv = 0; iv < g->nv; iv++)
            for (size_t ia = 0; ia < g->na; ia++)
                for (size_t it = 0; it < g->nt; it++) {
                    size_t k = (iv * g->na + ia) * g->nt + it;
                    v[k] = g->v_mps[iv];
                    a[k] = g->a_mps2[ia];
                    th[k] = g->theta_rad[it];
                }
        wf_vehicle_fuel(vc, n, v, a, th, 1, f, flag);
        for (size_t k = 0; k < n; k++) flag[k] = flag[k] == WF_INFEASIBLE_ACCEL;
        rc = wf_table_from_grid(g->nv, g->v_mps, g->na, g->a_mps2, g->nt, g->theta_rad, f, flag, source, out, err);
    }
    free(buf);
    free(flag);
    return rc;
}

int wf_fit_write_table_csv(const WfTable *t, const char *path, int force, WfError *err)
{
    char partial[4200];
    FILE *f = NULL;
    int rc = open_partial(path, force, partial, sizeof partial, &f, err);
    if (rc) return rc;
    size_t na = t->a.n, nt = t->theta.n;
    int bad = fputs("Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n", f) < 0;
    for (size_t iv = 0; iv < t->v.n && !bad; iv++)
        for (size_t ia = na; ia-- > 0 && !bad;)
            for (size_t it = 0; it < nt && !bad; it++) {
                size_t k = (iv * na + ia) * nt + it;
                /* + 0.0 turns -0 into 0, as the release prints it. */
                bad = fprintf(f, "%.15g,%.15g,%.15g,%.15g,%d\n", t->v.x[iv] + 0.0, t->a.x[ia] + 0.0,
                              t->theta.x[it] + 0.0, t->fuel_gps[k] + 0.0, t->infeasible[k] ? 1 : 0) < 0;
            }
    return finish_partial(f, partial, path, bad, err);
}
