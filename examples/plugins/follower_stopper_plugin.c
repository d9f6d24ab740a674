/* Example wavefuel controller plugin: FollowerStopper (Stern et al. 2018, Transp. Res. C 89, 205), the same
 * law as the built-in `follower_stopper` (src/models/cf/follower_stopper.c), written against the plugin ABI alone.
 * tests/t_plugin.sh checks that both give bit-identical runs. Build (as `make tests` does):
 *
 *     cc -std=c11 -O2 -ffp-contract=off -fPIC -shared -Iinclude \
 *        examples/plugins/follower_stopper_plugin.c -o build/plugins/follower_stopper_plugin.so
 *
 * and use it from a scenario:  {name: av, model: plugin, path: ../build/plugins/follower_stopper_plugin.so,
 * count: 1, params: {U_mps: 2.5}}. Units: gaps in m, speeds in m/s, decelerations in m/s^2, gain in 1/s. */
#include <math.h>

#include "wavefuel/cf_plugin.h"

/* The parameters arrive as doubles in the order of the table below. */
typedef struct FsParams {
    double U_mps, k_per_s, dx1_m, dx2_m, dx3_m, d1_mps2, d2_mps2, d3_mps2;
} FsParams;

static const WfCfPluginParam fs_params[] = {
    {"U_mps", 7.5, 0.0, 70.0, "m/s", "desired speed"},
    {"k_per_s", 1.0, 0.01, 100.0, "1/s", "speed-tracking gain: a = k (v_cmd - v)"},
    {"dx1_m", 4.5, 0.0, 100.0, "m", "stop boundary at zero closing speed"},
    {"dx2_m", 5.25, 0.0, 100.0, "m", "follow boundary at zero closing speed"},
    {"dx3_m", 6.0, 0.0, 100.0, "m", "free boundary at zero closing speed"},
    {"d1_mps2", 1.5, 0.01, 20.0, "m/s^2", "deceleration of the stop boundary"},
    {"d2_mps2", 1.0, 0.01, 20.0, "m/s^2", "deceleration of the follow boundary"},
    {"d3_mps2", 0.5, 0.01, 20.0, "m/s^2", "deceleration of the free boundary"},
};

/* Kept from the entry point so check() can report errors through wavefuel. */
static const WfCfPluginHost *host;

static double fs_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const FsParams *p = params;
    (void)state;
    double dv = fmin(v_lead_mps - v_mps, 0.0), dv2 = dv * dv;
    double dx1 = p->dx1_m + dv2 / (2.0 * p->d1_mps2);
    double dx2 = p->dx2_m + dv2 / (2.0 * p->d2_mps2);
    double dx3 = p->dx3_m + dv2 / (2.0 * p->d3_mps2);
    double w = fmin(fmax(v_lead_mps, 0.0), p->U_mps), v_cmd;
    /* check() keeps dx1 < dx2 < dx3 at every closing speed, so the divisions are safe. */
    if (gap_m <= dx1) v_cmd = 0.0;
    else if (gap_m <= dx2) v_cmd = w * (gap_m - dx1) / (dx2 - dx1);
    else if (gap_m <= dx3) v_cmd = w + (p->U_mps - w) * (gap_m - dx2) / (dx3 - dx2);
    else v_cmd = p->U_mps;
    return p->k_per_s * (v_cmd - v_mps);
}

static int fs_check(const void *params, struct WfError *err)
{
    const FsParams *p = params;
    if (!(p->dx1_m < p->dx2_m && p->dx2_m < p->dx3_m))
        return host->error(err, 2, "follower_stopper_plugin: need dx1_m < dx2_m < dx3_m");
    if (!(p->d1_mps2 >= p->d2_mps2 && p->d2_mps2 >= p->d3_mps2))
        return host->error(err, 2, "follower_stopper_plugin: need d1_mps2 >= d2_mps2 >= d3_mps2");
    return 0;
}

static const WfCfPlugin fs_plugin = {
    .abi_version = WF_CF_PLUGIN_ABI_VERSION,
    .name = "follower_stopper_plugin",
    .doc = "FollowerStopper (Stern et al. 2018), example plugin",
    .params = fs_params,
    .n_params = sizeof fs_params / sizeof fs_params[0],
    .check = fs_check,
    .accel = fs_accel,
    .state_size = 0,
    .init_state = 0,
    .update_state = 0,
};

/* The one exported symbol. A plugin that needs a newer wavefuel refuses older hosts here. */
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err)
{
    if (h->abi_version != WF_CF_PLUGIN_ABI_VERSION)
        return h->error(err, 2, "follower_stopper_plugin was built for ABI %u, host has %u",
                        (unsigned)WF_CF_PLUGIN_ABI_VERSION, (unsigned)h->abi_version);
    host = h;
    *out = &fs_plugin;
    return 0;
}
