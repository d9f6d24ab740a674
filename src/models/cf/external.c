/* External controllers: driver groups whose command is set from outside the engine once per step, for the whole
 * group (wf_sim_set_actions, engine.h; the Python package's Simulation.set_actions), such as a learned policy.
 *   external        the command is the acceleration (m/s^2)
 *   external_speed  the command is a set speed (m/s), followed by the linear ACC law of `acc` (acc.c) with that
 *                   set speed: a = min(k_gap (gap - s0 - T v) + k_dv (v_lead - v), k_v (v_set - v))
 * The engine treats the command as any model's acceleration: the group's noise, limits and feasible-acceleration
 * rule apply to it. Until a vehicle's first command, and wherever a command is NaN, the vehicle drives as `acc`
 * with the group's parameters (the same keys as `acc`); initial conditions use that law too. The command is the
 * vehicle's state (8 bytes), held until the next one and saved by checkpoints. */
#include <math.h>
#include <stddef.h>

#include "models/cf/acc.h"

typedef struct ExternalState {
    double command; /* m/s^2 (external) or m/s (external_speed); NaN: none */
} ExternalState;

static double command_of(const void *state) { return state ? ((const ExternalState *)state)->command : NAN; }

static double external_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const AccParams *p = params;
    double u = command_of(state);
    return isnan(u) ? wf_acc_law(p, p->v0_mps, gap_m, v_mps, v_lead_mps) : u;
}

static double external_speed_accel(const void *params, const void *state, double gap_m, double v_mps,
                                   double v_lead_mps)
{
    const AccParams *p = params;
    double u = command_of(state);
    return wf_acc_law(p, isnan(u) ? p->v0_mps : u, gap_m, v_mps, v_lead_mps);
}

static void external_init(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps)
{
    (void)params, (void)gap_m, (void)v_mps, (void)v_lead_mps;
    ((ExternalState *)state)->command = NAN;
}

const WfCfModel wf_cf_external = {
    .name = "external",
    .doc = "acceleration commanded from outside once per step (wf_sim_set_actions; Python); acc until the first",
    .param_size = sizeof(AccParams),
    .spec = wf_cf_acc_spec,
    .n_spec = WF_ACC_N_SPEC,
    .accel = external_accel,
    .state_size = sizeof(ExternalState),
    .init_state = external_init,
    .update_state = NULL, /* the command holds until the next one is set */
    .external = 1,
};

const WfCfModel wf_cf_external_speed = {
    .name = "external_speed",
    .doc = "set speed commanded from outside once per step, followed by the acc law; acc's v0 until the first",
    .param_size = sizeof(AccParams),
    .spec = wf_cf_acc_spec,
    .n_spec = WF_ACC_N_SPEC,
    .accel = external_speed_accel,
    .state_size = sizeof(ExternalState),
    .init_state = external_init,
    .update_state = NULL, /* the command holds until the next one is set */
    .external = 1,
};
