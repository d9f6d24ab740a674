/* The linear constant-time-gap ACC law (src/models/cf/acc.c) and its parameters, shared with the external
 * controllers (src/models/cf/external.c), whose low-level follower it is. */
#ifndef WAVEFUEL_MODELS_CF_ACC_H
#define WAVEFUEL_MODELS_CF_ACC_H

#include <math.h>

#include "wavefuel/cf.h"

typedef struct AccParams {
    double k_gap_per_s2; /* gain on the gap error */
    double k_dv_per_s;   /* gain on the speed difference */
    double T_s;          /* time gap */
    double s0_m;         /* standstill gap */
    double v0_mps;       /* set speed */
    double k_v_per_s;    /* gain of the speed-control mode */
} AccParams;

#define WF_ACC_N_SPEC 6
extern const WfParamSpec wf_cf_acc_spec[WF_ACC_N_SPEC];

/* min(a_gap, a_speed) with the set speed v_set_mps (m/s^2). */
static inline double wf_acc_law(const AccParams *p, double v_set_mps, double gap_m, double v_mps, double v_lead_mps)
{
    double a_gap = p->k_gap_per_s2 * (gap_m - p->s0_m - p->T_s * v_mps) + p->k_dv_per_s * (v_lead_mps - v_mps);
    double a_speed = p->k_v_per_s * (v_set_mps - v_mps);
    return fmin(a_gap, a_speed);
}

#endif
