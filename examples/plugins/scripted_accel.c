/* Example and test plugin: a driver that plays a prescribed acceleration sequence, whatever the traffic. Up to
 * 12 segments, segment K applies aK_mps2 for nK_steps time steps (nK_steps = 0 skips it), in order from the
 * vehicle's first step (t = 0 on a ring, its entry on a corridor); after the last segment the acceleration is 0.
 * With every nK_steps at 0 (the default) the vehicle keeps its speed: a blocker when it starts at rest, a pure
 * noise carrier when the group has `noise_mps2`. The test suite uses it to script traces whose stops, hard brakes
 * and stopped time are counted by hand (tests/t_event_counters.sh) and to place stopped vehicles at chosen ring
 * positions (tests/t_ring_recompute.sh). wavefuel still clips the result to the group's limits.
 *
 * Memory: the number of completed steps (one double). Without memory (equilibria of the initial state, the
 * corridor's insertion check) it answers as a settled follower, a = gap - 2 m - v * 1 s (the sign changes once
 * in the gap, at 2 m + v * 1 s), so initial equilibria exist. Build: as examples/plugins/follower_stopper_plugin.c. */
#include "wavefuel/cf_plugin.h"

enum { N_SEG = 12 };

/* The parameters arrive as doubles in table order: a1_mps2, n1_steps, a2_mps2, n2_steps, ... */
typedef struct ScriptParams {
    double seg[N_SEG][2];
} ScriptParams;

#define SEG(k) {"a" #k "_mps2", 0.0, -20.0, 20.0, "m/s^2", "acceleration of segment " #k}, \
               {"n" #k "_steps", 0.0, 0.0, 1e7, "1", "time steps of segment " #k}
static const WfCfPluginParam script_params[] = {SEG(1), SEG(2), SEG(3), SEG(4), SEG(5), SEG(6),
                                                SEG(7), SEG(8), SEG(9), SEG(10), SEG(11), SEG(12)};
#undef SEG

static double script_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const ScriptParams *p = params;
    (void)v_lead_mps;
    if (!state) return gap_m - 2.0 - v_mps;
    double done = *(const double *)state, end = 0.0;
    for (int k = 0; k < N_SEG; k++) {
        end += p->seg[k][1];
        if (done < end) return p->seg[k][0];
    }
    return 0.0;
}

static void script_init(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps)
{
    (void)params, (void)gap_m, (void)v_mps, (void)v_lead_mps;
    *(double *)state = 0.0;
}

static void script_update(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps,
                          double dt_s)
{
    (void)params, (void)gap_m, (void)v_mps, (void)v_lead_mps, (void)dt_s;
    *(double *)state += 1.0;
}

static const WfCfPlugin script_plugin = {
    .abi_version = WF_CF_PLUGIN_ABI_VERSION,
    .name = "scripted_accel",
    .doc = "prescribed piecewise-constant acceleration sequence (test driver)",
    .params = script_params,
    .n_params = sizeof script_params / sizeof script_params[0],
    .check = 0,
    .accel = script_accel,
    .state_size = sizeof(double),
    .init_state = script_init,
    .update_state = script_update,
};

int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **out, struct WfError *err)
{
    if (h->abi_version != WF_CF_PLUGIN_ABI_VERSION)
        return h->error(err, 2, "scripted_accel was built for ABI %u, host has %u",
                        (unsigned)WF_CF_PLUGIN_ABI_VERSION, (unsigned)h->abi_version);
    *out = &script_plugin;
    return 0;
}
