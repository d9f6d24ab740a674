/* The list of car-following models and controllers; adding one is one line here. Also the generic
 * equilibrium solver that initial conditions use for every model. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/cf.h"

/* Automated-vehicle controllers (src/cf/follower_stopper.c, pi_saturation.c, acc.c; docs/controllers.md). */
extern const WfCfModel wf_cf_follower_stopper;
extern const WfCfModel wf_cf_pi_saturation;
extern const WfCfModel wf_cf_acc;

const WfCfModel *const wf_cf_models[] = {&wf_cf_idm,           &wf_cf_ovm,           &wf_cf_gipps,
                                         &wf_cf_follower_stopper, &wf_cf_pi_saturation, &wf_cf_acc, NULL};

int wf_cf_model_find(const char *name, const WfCfModel **out, WfError *err)
{
    char known[256] = "";
    size_t used = 0;
    for (size_t i = 0; wf_cf_models[i]; i++) {
        if (strcmp(wf_cf_models[i]->name, name) == 0) {
            *out = wf_cf_models[i];
            return 0;
        }
        int w = snprintf(known + used, sizeof known - used, "%s%s", i ? ", " : "", wf_cf_models[i]->name);
        if (w > 0 && (size_t)w < sizeof known - used) used += (size_t)w;
    }
    return wf_err(err, WF_EINPUT, "unknown car-following model '%s' (known: %s)", name, known);
}

double wf_cf_equilibrium_speed(const WfCfModel *m, const void *params, double gap_m, double v_hi)
{
    double lo = 0.0, hi = v_hi;
    if (m->accel(params, NULL, gap_m, lo, lo) <= 0.0) return 0.0;
    if (m->accel(params, NULL, gap_m, hi, hi) >= 0.0) return hi;
    for (int it = 0; it < 200 && hi - lo > 0.0; it++) {
        double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (m->accel(params, NULL, gap_m, mid, mid) > 0.0) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}
