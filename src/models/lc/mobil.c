/* MOBIL, "minimizing overall braking induced by lane changes" (Kesting, Treiber & Helbing 2007, Transp. Res. Rec.
 * 1999, 86-94), with the accelerations of each driver's own car-following model (wavefuel/lanechange.h: WfLcCase;
 * a tilde is the value after the change, c the changer, n the new follower, o the old follower):
 *   safety:     ã_c >= -b_safe and ã_n >= -b_safe (b_mandatory for a mandatory change)
 *   mandatory:  (within merge_range of the end of its lane) any safe gap: advantage b_mandatory + ã_c
 *   symmetric:  ã_c - a_c + p [(ã_n - a_n) + (ã_o - a_o)] > Δa_th
 *   keep right: to the left:  ã_c - a_c + p (ã_n - a_n) > Δa_th + Δa_bias
 *               to the right: ã_c - a_c + p (ã_o - a_o) > Δa_th - Δa_bias
 * The advantage returned is the left side minus the right side. The paper's "no passing on the right" correction
 * of the accelerations (a_c^eur) is not applied. Cooperation (coop_decel, merge_range: src/core/lanes.c) lets a
 * driver yield to a vehicle that must leave the lane beside it. Units: m/s^2, s, m. Docs: docs/lanes.md. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/lanechange.h"

typedef struct Mobil {
    double politeness;     /* p */
    double threshold_mps2; /* Δa_th */
    double bias_mps2;      /* Δa_bias: keep_right only */
    double b_safe_mps2;    /* b_safe (magnitude) */
    double min_interval_s; /* least time between two changes of a vehicle */
    double b_mandatory_mps2; /* b_safe of a mandatory change */
    double coop_decel_mps2;  /* the hardest braking accepted to let a merging vehicle in (0: never) */
    double merge_range_m;    /* how far before its lane's end leaving it is mandatory */
} Mobil;

static const WfParamSpec mobil_spec[] = {
    {"politeness", offsetof(Mobil, politeness), 0.2, -1.0, 2.0, "1", 0,
     "p: weight of the followers' acceleration changes (0 selfish, 1 altruistic; the paper's realistic range is "
     "0-0.5)"},
    {"threshold_mps2", offsetof(Mobil, threshold_mps2), 0.1, 0.0, 5.0, "m/s^2", 0,
     "Δa_th: the least net advantage that makes a driver change"},
    {"bias_mps2", offsetof(Mobil, bias_mps2), 0.3, 0.0, 5.0, "m/s^2", 0,
     "Δa_bias: with `road.lane_rule: keep_right`, added to the threshold to the left and taken from it to the right"},
    {"b_safe_mps2", offsetof(Mobil, b_safe_mps2), 4.0, 0.1, 20.0, "m/s^2", 0,
     "b_safe: the hardest braking a change may impose on the new follower or the changer (magnitude)"},
    {"min_interval_s", offsetof(Mobil, min_interval_s), 1.0, 0.0, 3600.0, "s", 0,
     "least time between two changes of a vehicle"},
    {"b_mandatory_mps2", offsetof(Mobil, b_mandatory_mps2), 8.0, 0.1, 20.0, "m/s^2", 0,
     "b_safe of a mandatory change (out of a merge lane or a lane that ends): merging drivers accept harder braking "
     "behind them; the incentive is the symmetric rule's"},
    {"coop_decel_mps2", offsetof(Mobil, coop_decel_mps2), 1.5, 0.0, 20.0, "m/s^2", 0,
     "cooperation: the hardest braking this driver accepts to let in, ahead of it, a vehicle that must leave the "
     "lane beside it (it follows that vehicle as a leader while the braking this needs stays within the bound); 0: "
     "never yields"},
    {"merge_range_m", offsetof(Mobil, merge_range_m), 300.0, 0.0, 1e5, "m", 0,
     "within this distance of the end of its lane (a merge lane or a dropped lane) leaving the lane is mandatory for "
     "this driver (any gap safe under b_mandatory_mps2) and it asks the drivers beside it to cooperate; farther back "
     "it changes by the road's rule"},
};

static double mobil_advantage(const void *params, int dir, int rule, const WfLcCase *c)
{
    const Mobil *p = params;
    double b = rule == WF_LANE_RULE_MANDATORY ? p->b_mandatory_mps2 : p->b_safe_mps2;
    if (c->own_new < -b || (c->has_new && c->new_new < -b)) return -INFINITY;
    if (rule == WF_LANE_RULE_MANDATORY) return b + c->own_new; /* any safe gap; the side that lets it go faster */
    double own = c->own_new - c->own_now;
    double dn = c->has_new ? c->new_new - c->new_now : 0.0, d_o = c->has_old ? c->old_new - c->old_now : 0.0;
    if (rule != WF_LANE_RULE_KEEP_RIGHT) return own + p->politeness * (dn + d_o) - p->threshold_mps2;
    if (dir == WF_LANE_LEFT) return own + p->politeness * dn - (p->threshold_mps2 + p->bias_mps2);
    return own + p->politeness * d_o - (p->threshold_mps2 - p->bias_mps2);
}

static double mobil_min_interval(const void *params) { return ((const Mobil *)params)->min_interval_s; }

static void mobil_cooperation(const void *params, double *yield_decel_mps2, double *request_range_m)
{
    const Mobil *p = params;
    *yield_decel_mps2 = p->coop_decel_mps2, *request_range_m = p->merge_range_m;
}

const WfLaneChangeModel wf_lc_mobil = {
    .name = "mobil",
    .doc = "MOBIL (Kesting, Treiber & Helbing 2007): change when the own gain plus p times the followers' exceeds "
           "a threshold, unless someone must brake harder than b_safe",
    .param_size = sizeof(Mobil),
    .spec = mobil_spec,
    .n_spec = sizeof mobil_spec / sizeof mobil_spec[0],
    .advantage = mobil_advantage,
    .min_interval_s = mobil_min_interval,
    .cooperation = mobil_cooperation,
};
