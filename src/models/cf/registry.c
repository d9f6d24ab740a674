/* The list of car-following models and controllers; adding one is one line here. Also the generic
 * equilibrium solver that initial conditions use for every model. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/cf.h"

/* Automated-vehicle controllers (src/cf/follower_stopper.c, pi_saturation.c, acc.c; docs/controllers.md). */
extern const WfCfModel wf_cf_follower_stopper;
extern const WfCfModel wf_cf_pi_saturation;
extern const WfCfModel wf_cf_acc;
/* Commands set from outside the engine (src/cf/external.c; docs/controllers.md). */
extern const WfCfModel wf_cf_external, wf_cf_external_speed;

const WfCfModel *const wf_cf_models[] = {&wf_cf_idm,           &wf_cf_ovm,           &wf_cf_gipps,
                                         &wf_cf_follower_stopper, &wf_cf_pi_saturation, &wf_cf_acc,
                                         &wf_cf_external,      &wf_cf_external_speed, NULL};

WF_REGISTRY_FINDER(wf_cf_model_find, WfCfModel, wf_cf_models, "car-following model")

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
