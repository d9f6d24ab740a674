/* Optimal-velocity model with a follow-the-leader term (OV-FTL), as used by Stern et al. 2018 (Transp. Res.
 * C 89, 205) and in Seibold & Pohlmann's Sugiyama-ring code:
 *   a = alpha (V(s) - v) + beta (v_lead - v) / s^2,
 *   V(s) = v_max (tanh(s/d0 - 2) + tanh(2)) / (1 + tanh(2))   (the optimal-velocity shape of Bando et al. 1995)
 * with s the bumper-to-bumper gap (m), speeds in m/s, alpha in 1/s, beta in m^2/s. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/cf.h"

typedef struct OvmParams {
    double alpha_per_s;   /* relaxation rate towards V(s) */
    double beta_m2_per_s; /* follow-the-leader strength */
    double v_max_mps;     /* V(s) as s -> infinity */
    double d0_m;          /* length scale of V(s) */
} OvmParams;

/* Smallest gap the follow-the-leader term sees: it divides by s^2, so s = 0 needs a floor. 1 mm keeps the
 * result finite (at most beta * 40 m/s / 1e-6 m^2 = 8e8 m/s^2 with the defaults, clipped by the engine's
 * acceleration bounds) and is far below any gap the model is meant for. V(s) needs no guard: it is
 * finite for every s and V(0) = 0. */
#define OVM_GAP_FLOOR_M 1e-3

static const WfParamSpec ovm_spec[] = {
    /* alpha > 0: with alpha = 0, accel(s, v, v) = 0 for every v and the uniform-flow speed is undefined. */
    {"alpha_per_s", offsetof(OvmParams, alpha_per_s), 0.5, 0.01, 10.0, "1/s", 0,
     "optimal-velocity relaxation rate"},
    {"beta_m2_per_s", offsetof(OvmParams, beta_m2_per_s), 20.0, 0.0, 1000.0, "m^2/s", 0,
     "follow-the-leader strength (0 gives Bando's OVM)"},
    /* 35 km/h, the value of the Seibold-Pohlmann code for the 230 m Sugiyama ring. */
    {"v_max_mps", offsetof(OvmParams, v_max_mps), 35.0 / 3.6, 1.0, 70.0, "m/s", 0,
     "optimal velocity at infinite gap"},
    {"d0_m", offsetof(OvmParams, d0_m), 2.23, 0.1, 50.0, "m", 0,
     "length scale of V(s); the inflection point is at s = 2 d0"},
};

static double ovm_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const OvmParams *p = params;
    (void)state;
    /* tanh(2.0) is folded to a constant by the compiler; d0 >= 0.1 m by the spec range. */
    const double t2 = tanh(2.0);
    double V = p->v_max_mps * (tanh(gap_m / p->d0_m - 2.0) + t2) / (1.0 + t2);
    double s = gap_m > OVM_GAP_FLOOR_M ? gap_m : OVM_GAP_FLOOR_M; /* not fmax(): a library call, same value */
    return p->alpha_per_s * (V - v_mps) + p->beta_m2_per_s * (v_lead_mps - v_mps) / (s * s);
}

/* check is NULL: alpha > 0 and beta >= 0 (enforced by the ranges) make accel strictly decreasing in v at
 * v_lead = v with the unique root V(s); no other combination of in-range values is inconsistent. */
const WfCfModel wf_cf_ovm = {
    .name = "ovm",
    .doc = "Optimal-velocity model with follow-the-leader term, OV-FTL (Bando et al. 1995; Stern et al. 2018)",
    .param_size = sizeof(OvmParams),
    .spec = ovm_spec,
    .n_spec = sizeof ovm_spec / sizeof ovm_spec[0],
    .accel = ovm_accel,
};
