/* Test plugin for tests/t_run_cli.sh: an IDM-like controller that returns NaN once the vehicle is faster than
 * 5 m/s, to check that wavefuel stops with a numerical-fault error naming the vehicle and keeps partial results. */
#include <math.h>
#include "wavefuel/cf_plugin.h"

static const WfCfPluginParam params[] = {{"dummy", 1.0, 0.0, 2.0, "1", "unused"}};

static double accel(const void *p, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    (void)p, (void)state, (void)v_lead_mps;
    if (v_mps > 5.0) return NAN;
    return gap_m > 10.0 ? 1.0 : -1.0;
}

static const WfCfPlugin plugin = {.abi_version = WF_CF_PLUGIN_ABI_VERSION, .name = "nan_after_5mps",
                                  .doc = "returns NaN above 5 m/s (test)", .params = params, .n_params = 1,
                                  .accel = accel};

int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err)
{
    (void)h, (void)err;
    *out = &plugin;
    return 0;
}
