/* FollowerStopper (Stern et al. 2018, Transp. Res. C 89, 205, Sec. 3.1): a commanded speed from the gap and
 * the closing speed, tracked by a first-order law a = k (v_cmd - v). With dv_ = min(v_lead - v, 0),
 *   dx_k = dx_k^0 + dv_^2 / (2 d_k),  k = 1, 2, 3;   w = min(max(v_lead, 0), U)
 *   v_cmd = 0 (gap <= dx_1);  w (gap - dx_1)/(dx_2 - dx_1) on (dx_1, dx_2];
 *           w + (U - w)(gap - dx_2)/(dx_3 - dx_2) on (dx_2, dx_3];  U beyond.
 * Gaps (bumper to bumper) and dx in m, speeds in m/s, d_k in m/s^2, k in 1/s. Memoryless. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/cf.h"
#include "util/numfmt.h"

typedef struct FsParams {
    double U_mps;   /* desired speed */
    double k_per_s; /* speed-tracking gain */
    double dx1_m, dx2_m, dx3_m;       /* boundaries at zero closing speed */
    double d1_mps2, d2_mps2, d3_mps2; /* decelerations that widen them when closing in */
} FsParams;

static const WfParamSpec fs_spec[] = {
    {"U_mps", offsetof(FsParams, U_mps), 7.5, 0.0, 70.0, "m/s", 0,
     "desired speed (the field experiment's runs used 6.5 to 8 m/s)"},
    /* 1/s: a speed error of 1 m/s asks for 1 m/s^2, i.e. the command is tracked with a 1 s time constant.
     * k = 1/dt reproduces the one-step tracking of Flow's implementation. */
    {"k_per_s", offsetof(FsParams, k_per_s), 1.0, 0.01, 100.0, "1/s", 0,
     "speed-tracking gain: a = k (v_cmd - v)"},
    {"dx1_m", offsetof(FsParams, dx1_m), 4.5, 0.0, 100.0, "m", 0, "stop boundary at zero closing speed"},
    {"dx2_m", offsetof(FsParams, dx2_m), 5.25, 0.0, 100.0, "m", 0, "follow boundary at zero closing speed"},
    {"dx3_m", offsetof(FsParams, dx3_m), 6.0, 0.0, 100.0, "m", 0, "free boundary at zero closing speed"},
    {"d1_mps2", offsetof(FsParams, d1_mps2), 1.5, 0.01, 20.0, "m/s^2", 0, "deceleration of the stop boundary"},
    {"d2_mps2", offsetof(FsParams, d2_mps2), 1.0, 0.01, 20.0, "m/s^2", 0, "deceleration of the follow boundary"},
    {"d3_mps2", offsetof(FsParams, d3_mps2), 0.5, 0.01, 20.0, "m/s^2", 0, "deceleration of the free boundary"},
};

/* The commanded speed (m/s). check() guarantees dx_1 < dx_2 < dx_3 for every closing speed, so both
 * divisions are by at least dx_2^0 - dx_1^0 > 0 (resp. dx_3^0 - dx_2^0 > 0). */
static double fs_command(const FsParams *p, double gap_m, double v_mps, double v_lead_mps)
{
    double dv = fmin(v_lead_mps - v_mps, 0.0), dv2 = dv * dv;
    double dx1 = p->dx1_m + dv2 / (2.0 * p->d1_mps2);
    double dx2 = p->dx2_m + dv2 / (2.0 * p->d2_mps2);
    double dx3 = p->dx3_m + dv2 / (2.0 * p->d3_mps2);
    double w = fmin(fmax(v_lead_mps, 0.0), p->U_mps);
    if (gap_m <= dx1) return 0.0;
    if (gap_m <= dx2) return w * (gap_m - dx1) / (dx2 - dx1);
    if (gap_m <= dx3) return w + (p->U_mps - w) * (gap_m - dx2) / (dx3 - dx2);
    return p->U_mps;
}

static double fs_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const FsParams *p = params;
    (void)state;
    return p->k_per_s * (fs_command(p, gap_m, v_mps, v_lead_mps) - v_mps);
}

/* The three regions must stay ordered at every closing speed: dx_1 < dx_2 < dx_3 at dv = 0, and the widening
 * dv^2 / (2 d_k) must not shrink from one boundary to the next, i.e. d_1 >= d_2 >= d_3. */
static int fs_check(const void *params, WfError *err)
{
    const FsParams *p = params;
    if (!(p->dx1_m < p->dx2_m && p->dx2_m < p->dx3_m))
        return wf_err(err, WF_EINPUT, "follower_stopper: need dx1_m < dx2_m < dx3_m (got %s, %s, %s)",
                      WF_NUM(p->dx1_m), WF_NUM(p->dx2_m), WF_NUM(p->dx3_m));
    if (!(p->d1_mps2 >= p->d2_mps2 && p->d2_mps2 >= p->d3_mps2))
        return wf_err(err, WF_EINPUT,
                      "follower_stopper: need d1_mps2 >= d2_mps2 >= d3_mps2 so the regions stay ordered when closing "
                      "in (got %s, %s, %s)",
                      WF_NUM(p->d1_mps2), WF_NUM(p->d2_mps2), WF_NUM(p->d3_mps2));
    return 0;
}

const WfCfModel wf_cf_follower_stopper = {
    .name = "follower_stopper",
    .doc = "FollowerStopper automated-vehicle controller (Stern et al. 2018)",
    .param_size = sizeof(FsParams),
    .spec = fs_spec,
    .n_spec = sizeof fs_spec / sizeof fs_spec[0],
    .check = fs_check,
    .accel = fs_accel,
};
