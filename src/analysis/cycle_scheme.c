/* Cycle schemes: how a 1 Hz speed trace becomes the samples the energy model is evaluated at (docs/cycles.md).
 * `spline` and `release` read the trace as the CIRCLES release's 10 Hz files do: a not-a-knot cubic spline of the
 * samples, set to 0 where it undershoots below 0 and wherever two consecutive samples are both 0 (measured on the
 * release's UDDS_drivecycle_speeds_10Hz.csv); `release` then takes the script's central differences at 10 Hz,
 * `spline` the spline's own derivative at 100 Hz. Both sum with the trapezoid rule. Units: s, m/s, m/s^2. */
#include "wavefuel/cycle.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "util/registry.h"
#include "wavefuel/spline.h"

void wf_cycle_samples_free(WfCycleSamples *s)
{
    if (!s) return;
    free(s->t_s); /* the one block holding all four arrays */
    memset(s, 0, sizeof *s);
}

static int alloc_samples(WfCycleSamples *s, size_t n, WfError *err)
{
    memset(s, 0, sizeof *s);
    double *block = malloc(4 * n * sizeof *block);
    if (!block) return wf_err(err, WF_ESYS, "out of memory for %zu cycle samples", n);
    s->n = n;
    s->t_s = block;
    s->v_mps = block + n;
    s->a_mps2 = block + 2 * n;
    s->w_s = block + 3 * n;
    return 0;
}

/* The trace's own samples, forward differences, left Riemann weights (the cycle's dt and a). */
static int sample_first_order(const WfCycle *c, double rate_hz, WfCycleSamples *s, WfError *err)
{
    (void)rate_hz;
    int rc = alloc_samples(s, c->n, err);
    if (rc) return rc;
    memcpy(s->t_s, c->t_s, c->n * sizeof *c->t_s);
    memcpy(s->v_mps, c->v_mps, c->n * sizeof *c->v_mps);
    memcpy(s->a_mps2, c->a_mps2, c->n * sizeof *c->a_mps2);
    memcpy(s->w_s, c->dt_s, c->n * sizeof *c->dt_s);
    return 0;
}

/* Times t[0] + k / rate up to the cycle's end, and the end itself when the duration is not a whole number of
 * steps (the 1e-9 absorbs the rounding of k / rate for a whole number). Trapezoid weights. */
static int resample_grid(const WfCycle *c, double rate_hz, WfCycleSamples *s, WfError *err)
{
    double t0 = c->t_s[0], dur = c->t_s[c->n - 1] - t0;
    double steps = floor(dur * rate_hz + 1e-9);
    /* 1e8 samples hold 3.2 GB (four doubles each): 11.6 days of trace at 100 Hz. */
    if (!(steps < 1e8))
        return wf_err(err, WF_EINPUT, "cycle %s: %.17g s at %g Hz is more than 1e8 samples (--scheme first-order uses "
                      "the trace's own)", c->name, dur, rate_hz);
    size_t k_max = (size_t)steps;
    int tail = (double)k_max / rate_hz < dur - 1e-9 * (dur > 1.0 ? dur : 1.0);
    size_t n = k_max + 1 + (size_t)tail;
    int rc = alloc_samples(s, n < 2 ? 2 : n, err);
    if (rc) return rc;
    n = s->n;
    for (size_t k = 0; k <= k_max; k++) s->t_s[k] = t0 + (double)k / rate_hz;
    s->t_s[n - 1] = c->t_s[c->n - 1]; /* the last sample is the cycle's end, exactly */
    s->w_s[0] = 0.5 * (s->t_s[1] - s->t_s[0]);
    for (size_t i = 1; i + 1 < n; i++) s->w_s[i] = 0.5 * (s->t_s[i + 1] - s->t_s[i - 1]);
    s->w_s[n - 1] = 0.5 * (s->t_s[n - 1] - s->t_s[n - 2]);
    return 0;
}

/* Speed (and its derivative) of the release's reading of the trace at the grid times of s. */
static int spline_trace(const WfCycle *c, WfCycleSamples *s, WfError *err)
{
    WfSpline sp;
    int rc = wf_spline_fit(c->n, c->t_s, c->v_mps, &sp, err);
    if (rc) return wf_err_prefix(err, "%s: ", c->name);
    size_t i = 0;
    for (size_t k = 0; k < s->n; k++) {
        i = wf_spline_interval(&sp, s->t_s[k], i);
        double dv, v = wf_spline_eval(&sp, i, s->t_s[k], &dv);
        /* Standing still stays still, and a speed is never negative: the spline's wiggles around stops are
         * removed as in the release's 10 Hz files (its derivative there is then 0 too). */
        if ((c->v_mps[i] == 0.0 && c->v_mps[i + 1] == 0.0) || v < 0.0) v = dv = 0.0;
        s->v_mps[k] = v;
        s->a_mps2[k] = dv;
    }
    wf_spline_free(&sp);
    return 0;
}

static int sample_spline(const WfCycle *c, double rate_hz, WfCycleSamples *s, WfError *err)
{
    int rc = resample_grid(c, rate_hz, s, err);
    if (!rc && (rc = spline_trace(c, s, err))) wf_cycle_samples_free(s);
    return rc;
}

/* The release's script: D_a = (D_v([2:end,end]) - D_v([1,1:end-1])) ./ (D_t([2:end,end]) - D_t([1,1:end-1])),
 * central differences inside and one-sided at the two ends. */
static int sample_release(const WfCycle *c, double rate_hz, WfCycleSamples *s, WfError *err)
{
    int rc = sample_spline(c, rate_hz, s, err);
    if (rc) return rc;
    size_t n = s->n;
    const double *t = s->t_s, *v = s->v_mps;
    for (size_t i = 0; i < n; i++) {
        size_t hi = i + 1 < n ? i + 1 : i, lo = i > 0 ? i - 1 : i;
        s->a_mps2[i] = (v[hi] - v[lo]) / (t[hi] - t[lo]); /* n >= 2: hi > lo */
    }
    return 0;
}

static const WfCycleScheme schemes[] = {
    {"spline", "spline trace at 100 Hz, its exact derivative, trapezoid sum; the most accurate (default)", 100.0,
     sample_spline},
    {"release", "spline trace at 10 Hz, central differences, trapezoid sum; the CIRCLES release's script", 10.0,
     sample_release},
    {"first-order", "the trace's own samples, forward differences, sum f(v[i], a[i]) dt_i; earlier wavefuel", 0.0,
     sample_first_order},
};

const WfCycleScheme *wf_cycle_schemes(size_t *n)
{
    *n = sizeof schemes / sizeof schemes[0];
    return schemes;
}

const WfCycleScheme *wf_cycle_scheme_find(const char *name, WfError *err)
{
    const char *names[sizeof schemes / sizeof schemes[0] + 1] = {NULL};
    for (size_t i = 0; i < sizeof schemes / sizeof schemes[0]; i++) names[i] = schemes[i].name;
    long i = wf_registry_find((const void *const *)names, WF_REG_STRINGS, name, "cycle scheme", err);
    return i < 0 ? NULL : &schemes[i];
}

int wf_cycle_samples(const WfCycle *c, const WfCycleScheme *scheme, WfCycleSamples *s, WfError *err)
{
    int rc = scheme->sample(c, scheme->rate_hz, s, err);
    if (!rc) s->scheme = scheme;
    return rc;
}
