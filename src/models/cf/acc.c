/* Linear constant-time-gap adaptive cruise control (the form Milanés & Shladover 2014, Transp. Res. C 48, 285,
 * identified for production ACC), with a speed-control mode for large gaps:
 *   a_gap   = k_gap (gap - s0 - T v) + k_dv (v_lead - v)
 *   a_speed = k_v (v0 - v)
 *   a       = min(a_gap, a_speed)
 * Gap in m, speeds in m/s, k_gap in 1/s^2, k_dv and k_v in 1/s, T in s. Memoryless. */
#include "models/cf/acc.h"

#include <stddef.h>

const WfParamSpec wf_cf_acc_spec[WF_ACC_N_SPEC] = {
    /* Default gains: string stable with margin and about critically damped at T = 1.1 s. The law's
     * leader-to-follower speed transfer is G = (k_dv s + k_gap)/(s^2 + (k_dv + k_gap T) s + k_gap), and
     * |G(jw)| <= 1 at every w exactly when k_gap T^2 + 2 k_dv T >= 2: here 2.24. Damping ratio
     * (k_dv + k_gap T) / (2 sqrt(k_gap)) = 0.98. Milanés & Shladover's production gains (0.23 1/s^2, 0.07 1/s)
     * give 0.43, string unstable like the systems they measured (docs/controllers.md). */
    /* k_gap > 0: with k_gap = 0 the gap never enters and no uniform flow exists. */
    {"k_gap_per_s2", offsetof(AccParams, k_gap_per_s2), 0.4, 0.001, 10.0, "1/s^2", 0, "gain on the gap error"},
    {"k_dv_per_s", offsetof(AccParams, k_dv_per_s), 0.8, 0.0, 10.0, "1/s", 0,
     "gain on the speed difference v_lead - v"},
    {"T_s", offsetof(AccParams, T_s), 1.1, 0.1, 5.0, "s", 0, "time gap"},
    {"s0_m", offsetof(AccParams, s0_m), 2.0, 0.0, 20.0, "m", 0, "gap kept at standstill"},
    {"v0_mps", offsetof(AccParams, v0_mps), 30.0, 0.0, 70.0, "m/s", 0, "set speed"},
    {"k_v_per_s", offsetof(AccParams, k_v_per_s), 0.4, 0.01, 10.0, "1/s", 0, "gain of the speed-control mode"},
};

static double acc_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const AccParams *p = params;
    (void)state;
    return wf_acc_law(p, p->v0_mps, gap_m, v_mps, v_lead_mps);
}

const WfCfModel wf_cf_acc = {
    .name = "acc",
    .doc = "Linear constant-time-gap adaptive cruise control (Milanés & Shladover 2014)",
    .param_size = sizeof(AccParams),
    .spec = wf_cf_acc_spec,
    .n_spec = WF_ACC_N_SPEC,
    /* Every in-range set is well posed: accel(s, v, v) = min(k_gap (s - s0 - T v), k_v (v0 - v)) is
     * strictly decreasing in v (k_gap T >= 1e-4, k_v >= 0.01 by the ranges): one uniform-flow speed per gap. */
    .check = NULL,
    .accel = acc_accel,
};
