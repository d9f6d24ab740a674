/* Gipps' car-following model (Gipps 1981, Transp. Res. B 15, 105), its speed update over the reaction
 * time tau turned into an acceleration a = (v_new - v) / tau, with decelerations written as positive
 * magnitudes b (own most severe braking) and b_hat (assumed braking of the leader), and d = gap - s0:
 *   v_acc = v + 2.5 a tau (1 - v/V) sqrt(0.025 + v/V)
 *   v_brk = -b tau + sqrt(b^2 tau^2 + b (2 d - v tau + v_lead^2 / b_hat))   (0 if the radicand is < 0)
 *   v_new = max(0, min(v_acc, v_brk))
 * Units: m, m/s, m/s^2, s. Gipps's (x_{n-1} - s_{n-1} - x_n) is gap - s0 with s0 = s_{n-1} - L_{n-1}. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/cf.h"
#include "util/numfmt.h"

typedef struct GippsParams {
    double a_mps2;     /* maximum acceleration the driver wishes to use */
    double b_mps2;     /* most severe braking the driver wishes to use (magnitude) */
    double b_hat_mps2; /* the driver's estimate of the leader's most severe braking (magnitude) */
    double v0_mps;     /* desired speed V */
    double tau_s;      /* reaction time, also the model's update interval */
    double s0_m;       /* leader's effective size minus its length: margin kept at standstill */
} GippsParams;

static const WfParamSpec gipps_spec[] = {
    {"a_mps2", offsetof(GippsParams, a_mps2), 1.7, 0.1, 10.0, "m/s^2", 0, "maximum desired acceleration"},
    {"b_mps2", offsetof(GippsParams, b_mps2), 3.0, 0.5, 15.0, "m/s^2", 0,
     "most severe braking the driver undertakes (magnitude)"},
    {"b_hat_mps2", offsetof(GippsParams, b_hat_mps2), 3.0, 0.5, 15.0, "m/s^2", 0,
     "driver's estimate of the leader's most severe braking (magnitude)"},
    {"v0_mps", offsetof(GippsParams, v0_mps), 30.0, 1.0, 70.0, "m/s", 0, "desired speed"},
    {"tau_s", offsetof(GippsParams, tau_s), 0.66, 0.1, 5.0, "s", 0, "reaction time"},
    {"s0_m", offsetof(GippsParams, s0_m), 2.0, 0.0, 20.0, "m", 0,
     "margin: leader's effective size minus its length"},
};

/* One uniform-flow speed per gap. With v_lead = v and c = b/b_hat - 1, v_brk > v exactly when
 * Q(v) = -c v^2 + 3 b tau v - 2 b d < 0. For c <= 0 Q is increasing on v >= 0; for c > 0 it increases up
 * to its vertex v* = 3 b tau / (2c) and falls again, so a driver who assumes the leader brakes much more
 * gently than itself (b_hat << b) would, at some gaps, see the braking constraint vanish again above a
 * second root, giving several uniform-flow speeds. Since v_acc < v for v > V, requiring v* >= V, i.e.
 * b_hat >= b / (1 + 1.5 b tau / V), leaves a single sign change of accel(s, v, v) in v, which
 * wf_cf_equilibrium_speed's bisection relies on. */
static int gipps_check(const void *params, WfError *err)
{
    const GippsParams *p = params;
    double b_hat_min = p->b_mps2 / (1.0 + 1.5 * p->b_mps2 * p->tau_s / p->v0_mps);
    if (p->b_hat_mps2 < b_hat_min)
        return wf_err(err, WF_EINPUT,
                      "gipps: b_hat_mps2 must be >= b_mps2 / (1 + 1.5 b_mps2 tau_s / v0_mps) = %.6g m/s^2 with "
                      "b_mps2 = %s, tau_s = %s, v0_mps = %s (got %s); below it the uniform-flow speed "
                      "at a given gap is not unique",
                      b_hat_min, WF_NUM(p->b_mps2), WF_NUM(p->tau_s), WF_NUM(p->v0_mps), WF_NUM(p->b_hat_mps2));
    return WF_OK;
}

static double gipps_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const GippsParams *p = params;
    (void)state;
    double tau = p->tau_s, b = p->b_mps2;
    /* V >= 1 m/s by the spec range. fmax: a speed a hair below 0 (outside the contract) must not make the
     * square root's argument negative. */
    double u = v_mps / p->v0_mps;
    double v_acc = v_mps + 2.5 * p->a_mps2 * tau * (1.0 - u) * sqrt(fmax(0.025 + u, 0.0));
    /* b_hat >= 0.5 m/s^2 by the spec range. */
    double rad =
        b * b * tau * tau + b * (2.0 * (gap_m - p->s0_m) - v_mps * tau + v_lead_mps * v_lead_mps / p->b_hat_mps2);
    /* A negative radicand means no speed lets the driver stop behind a leader braking at b_hat: Gipps's
     * formula has no real value there, so brake as hard as the model allows, v_new = 0. */
    double v_brk = rad > 0.0 ? -b * tau + sqrt(rad) : 0.0;
    /* v_new >= 0: the speed update never asks for reversing (v_brk < 0 when 2d - v tau + v_lead^2/b_hat < 0). */
    double v_new = fmax(0.0, fmin(v_acc, v_brk));
    /* tau >= 0.1 s by the spec range. */
    return (v_new - v_mps) / tau;
}

const WfCfModel wf_cf_gipps = {
    .name = "gipps",
    .doc = "Gipps (1981) safe-speed model, as an acceleration over the reaction time",
    .param_size = sizeof(GippsParams),
    .spec = gipps_spec,
    .n_spec = sizeof gipps_spec / sizeof gipps_spec[0],
    .check = gipps_check,
    .accel = gipps_accel,
};
