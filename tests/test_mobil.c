/* The MOBIL lane-change rule (src/models/lc/mobil.c) through its registry entry and advantage(), against values
 * computed by hand from the rule of Kesting, Treiber & Helbing (2007) as include/wavefuel/lanechange.h and
 * docs/scenarios.md state it: incentive against the threshold, the safety criterion, politeness, the keep-right
 * bias and its one-sided follower terms, missing followers; and one case with IDM's accelerations (its default
 * parameters), every acceleration worked out in the comments. Units: m/s^2, m, m/s. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wavefuel/lanechange.h"
#include "wf_test.h"

typedef struct Params {
    double v[16];
} Params;

static const WfLaneChangeModel *mobil(void)
{
    const WfLaneChangeModel *m = NULL;
    WfError err = {0};
    if (wf_lc_model_find("mobil", &m, &err)) return NULL;
    return m;
}

static Params lc_defaults(const WfLaneChangeModel *m)
{
    Params p;
    memset(&p, 0, sizeof p);
    wf_param_defaults(m->spec, m->n_spec, &p);
    return p;
}

static void lc_set(const WfLaneChangeModel *m, Params *p, const char *key, double value)
{
    const WfParamSpec *s = wf_param_find(m->spec, m->n_spec, key);
    CHECK(s != NULL, "mobil has no key '%s'", key);
    if (s) *wf_param_ptr(p, s) = value;
}

/* A case from the three drivers' accelerations (now, after the change): changer, new follower, old follower. */
static WfLcCase lc_case(double own_now, double own_new, double new_now, double new_new, double old_now,
                        double old_new)
{
    return (WfLcCase){own_now, own_new, new_now, new_new, old_now, old_new, 1, 1};
}

static double adv(const WfLaneChangeModel *m, const Params *p, int dir, int rule, WfLcCase c)
{
    return m->advantage(p, dir, rule, &c);
}

/* ---------------------------------------------------------------- registry and parameters */

static void test_registry_and_defaults(void)
{
    const WfLaneChangeModel *m = mobil();
    CHECK(m != NULL && strcmp(m->name, "mobil") == 0, "mobil not found");
    if (!m) return;
    const WfLaneChangeModel *u = NULL;
    WfError err = {0};
    int rc = wf_lc_model_find("lmrs", &u, &err);
    CHECK(rc == WF_EINPUT && u == NULL, "unknown model gave rc %d", rc);
    CHECK(strstr(err.msg, "lmrs") != NULL, "message does not name the unknown model: %s", err.msg);
    for (size_t i = 0; wf_lc_models[i]; i++)
        CHECK(strstr(err.msg, wf_lc_models[i]->name) != NULL, "message does not list %s: %s", wf_lc_models[i]->name,
              err.msg);
    CHECK(m->param_size <= WF_MAX_LC_PARAMS * sizeof(double) && m->param_size <= sizeof(Params), "param_size %zu",
          m->param_size);
    /* The defaults docs/lanes.md states: p 0.2, Δa_th 0.1, Δa_bias 0.3, b_safe 4, 1 s between changes, and
     * b_safe 8 for mandatory changes, cooperation up to 1.5 m/s^2 within 300 m of a lane's end. */
    static const struct { const char *key; double def; } want[] = {
        {"politeness", 0.2}, {"threshold_mps2", 0.1}, {"bias_mps2", 0.3}, {"b_safe_mps2", 4.0},
        {"min_interval_s", 1.0}, {"b_mandatory_mps2", 8.0}, {"coop_decel_mps2", 1.5}, {"merge_range_m", 300.0}};
    CHECK(m->n_spec == sizeof want / sizeof want[0], "%zu keys", m->n_spec);
    Params p = lc_defaults(m);
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        const WfParamSpec *s = wf_param_find(m->spec, m->n_spec, want[k].key);
        CHECK(s != NULL, "no key %s", want[k].key);
        if (s) CHECK(s->def == want[k].def && wf_param_get(&p, s) == want[k].def, "%s default %g", want[k].key, s->def);
    }
    CHECK(m->min_interval_s(&p) == 1.0, "min_interval_s %g", m->min_interval_s(&p));
    lc_set(m, &p, "min_interval_s", 2.5);
    CHECK(m->min_interval_s(&p) == 2.5, "min_interval_s %g", m->min_interval_s(&p));
}

/* ---------------------------------------------------------------- incentive */

/* Symmetric rule, defaults (p = 0.2, Δa_th = 0.1):
 *   own gain ã_c - a_c = 0.3 - (-0.5) = 0.8; new follower ã_n - a_n = 0.0 - 0.2 = -0.2; old follower
 *   ã_o - a_o = 0.1 - (-0.3) = 0.4; advantage = 0.8 + 0.2 (-0.2 + 0.4) - 0.1 = 0.74 > 0: change. Both directions
 *   give the same value under the symmetric rule. */
static void test_incentive_above_threshold(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    WfLcCase c = lc_case(-0.5, 0.3, 0.2, 0.0, -0.3, 0.1);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c), 0.74, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_SYMMETRIC, c), 0.74, 1e-12);
}

/* Own gain 0.05 < Δa_th = 0.1 with followers unaffected: 0.05 - 0.1 = -0.05, no change. With Δa_th = 0.125 and a
 * gain of exactly 0.125 (dyadic numbers: no rounding) the advantage is exactly 0, which is not a reason to change
 * (the engine changes when it is > 0). */
static void test_incentive_below_threshold(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    WfLcCase c = lc_case(1.0, 1.05, -0.7, -0.7, 0.25, 0.25);
    double a = adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c);
    CHECK_ABS(a, -0.05, 1e-12);
    CHECK(a < 0.0, "advantage %g", a);
    lc_set(m, &p, "threshold_mps2", 0.125);
    c = lc_case(-0.25, -0.125, 0.5, 0.5, -1.0, -1.0);
    a = adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_SYMMETRIC, c);
    CHECK(a == 0.0 && !(a > 0.0), "at the threshold: %.17g, want exactly 0", a);
}

/* ---------------------------------------------------------------- safety */

/* b_safe = 4: the change is unsafe (-INFINITY) when ã_c < -4 or, with a new follower, ã_n < -4, whatever the gain;
 * exactly -4 is still safe (the rule is ã >= -b_safe). The old follower's braking is no safety matter in MOBIL:
 * ã_o = -8 gives a finite advantage: gain 1.0 - 0.0 = 1.0, p (0 + (-8 - 0)) = -1.6, minus 0.1: -0.7. */
static void test_safety(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    for (int rule = 0; rule < 2; rule++)
        for (int dir = -1; dir <= 1; dir += 2) {
            double a = adv(m, &p, dir, rule, lc_case(-6.0, -4.0000001, 0.0, 0.0, 0.0, 0.0));
            CHECK(a == -INFINITY, "own braking beyond b_safe, dir %d rule %d: %g", dir, rule, a);
            a = adv(m, &p, dir, rule, lc_case(-6.0, 2.0, 0.0, -4.5, 0.0, 0.0));
            CHECK(a == -INFINITY, "new follower beyond b_safe, dir %d rule %d: %g", dir, rule, a);
            a = adv(m, &p, dir, rule, lc_case(-6.0, -4.0, 0.0, -4.0, 0.0, 0.0));
            CHECK(isfinite(a) && a > 0.0, "exactly -b_safe is safe, dir %d rule %d: %g", dir, rule, a);
        }
    double a = adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, lc_case(0.0, 1.0, 0.0, 0.0, 0.0, -8.0));
    CHECK_ABS(a, -0.7, 1e-12);
    /* A larger b_safe admits the same change: ã_n = -4.5 >= -5; advantage 8 + 0.2 (-4.5) - 0.1 = 7.0. */
    lc_set(m, &p, "b_safe_mps2", 5.0);
    WfLcCase c = lc_case(-6.0, 2.0, 0.0, -4.5, 0.0, 0.0);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c), 7.0, 1e-12);
}

/* A mandatory change (out of a lane that ends, within the merge range) takes any gap that is safe under
 * b_mandatory (default 8); the advantage is b_mandatory + ã_c, so that between two sides the one letting the changer
 * go faster wins. The new follower braking at 6 blocks an ordinary change (b_safe 4) but not a mandatory one, whose
 * advantage is then 8 + 2 = 10 to either side, whatever the politeness; with ã_c = -7.5 still 8 - 7.5 = 0.5 > 0;
 * beyond -8 (the follower's or the changer's) it is unsafe. */
static void test_mandatory(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    WfLcCase c = lc_case(-6.0, 2.0, 0.0, -6.0, 0.0, 0.0);
    CHECK(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c) == -INFINITY, "ordinary change admitted");
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_MANDATORY, c), 10.0, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_MANDATORY, c), 10.0, 1e-12);
    lc_set(m, &p, "politeness", 1.0);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_MANDATORY, c), 10.0, 1e-12);
    c = lc_case(0.0, -7.5, 0.0, -1.0, 0.0, 0.0);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_MANDATORY, c), 0.5, 1e-12);
    c = lc_case(-6.0, 2.0, 0.0, -8.5, 0.0, 0.0);
    CHECK(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_MANDATORY, c) == -INFINITY, "beyond b_mandatory admitted");
    c = lc_case(-6.0, -8.5, 0.0, 0.0, 0.0, 0.0);
    CHECK(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_MANDATORY, c) == -INFINITY, "changer beyond b_mandatory admitted");
}

/* Cooperation: the keys reach the model's answer (defaults 1.5 m/s^2 and 300 m; 0 turns yielding off). */
static void test_cooperation_keys(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    double yield = -1.0, range = -1.0;
    m->cooperation(&p, &yield, &range);
    CHECK_ABS(yield, 1.5, 0.0);
    CHECK_ABS(range, 300.0, 0.0);
    lc_set(m, &p, "coop_decel_mps2", 0.0);
    lc_set(m, &p, "merge_range_m", 120.0);
    m->cooperation(&p, &yield, &range);
    CHECK_ABS(yield, 0.0, 0.0);
    CHECK_ABS(range, 120.0, 0.0);
}

/* ---------------------------------------------------------------- politeness */

/* The changer gains 1.0 (from -0.5 to 0.5); the new follower goes from 0 to -1.5 (safe); the old follower is
 * unaffected. Selfish p = 0: 1.0 - 0.1 = 0.9 > 0, change. Altruistic p = 1: 1.0 - 1.5 - 0.1 = -0.6 < 0, stay.
 * The break-even politeness is (1.0 - 0.1) / 1.5 = 0.6: p = 0.5 changes (1.0 - 0.75 - 0.1 = 0.15), p = 0.75
 * stays (1.0 - 1.125 - 0.1 = -0.225). */
static void test_politeness_flips(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    WfLcCase c = lc_case(-0.5, 0.5, 0.0, -1.5, 0.3, 0.3);
    static const double pol[] = {0.0, 0.5, 0.75, 1.0}, want[] = {0.9, 0.15, -0.225, -0.6};
    for (size_t k = 0; k < 4; k++) {
        lc_set(m, &p, "politeness", pol[k]);
        double a = adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c);
        CHECK_ABS(a, want[k], 1e-12);
        CHECK((a > 0.0) == (pol[k] < 0.6), "p = %g: advantage %g", pol[k], a);
    }
}

/* ---------------------------------------------------------------- keep right */

/* p = 0.5, Δa_th = 0.1, Δa_bias = 0.3; own gain 0.2, new follower -0.5, old follower +1.0:
 *   symmetric, either side:  0.2 + 0.5 (-0.5 + 1.0) - 0.1           =  0.35
 *   keep_right, to the left: 0.2 + 0.5 (-0.5)       - (0.1 + 0.3)   = -0.45  (old follower ignored)
 *   keep_right, to the right: 0.2 + 0.5 (1.0)       - (0.1 - 0.3)   =  0.9   (new follower ignored)
 * Changing the ignored term leaves the value unchanged; changing the counted one moves it by p times the change. */
static void test_keep_right_bias(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    lc_set(m, &p, "politeness", 0.5);
    WfLcCase c = lc_case(0.0, 0.2, 0.5, 0.0, -1.0, 0.0);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c), 0.35, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_SYMMETRIC, c), 0.35, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c), -0.45, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c), 0.9, 1e-12);
    /* old follower changed by -2 (from +1.0 to -1.0): the left value keeps -0.45, the right one drops by 1.0 */
    WfLcCase c2 = c;
    c2.old_new = -2.0;
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c2), -0.45, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c2), -0.1, 1e-12);
    /* new follower changed by -3 (from -0.5 to -3.5, still safe): the right value keeps 0.9, the left drops 1.5 */
    WfLcCase c3 = c;
    c3.new_new = -3.0;
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c3), 0.9, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c3), -1.95, 1e-12);
    /* ...but its safety still counts on a change to the right: ã_n = -4.5 < -4 */
    c3.new_new = -4.5;
    CHECK(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c3) == -INFINITY, "unsafe right change allowed");
    /* Nothing to gain, nobody affected: keep_right moves right (0 - (0.1 - 0.3) = 0.2 > 0) and not left
     * (0 - 0.4 = -0.4); symmetric moves neither way (-0.1). The bias 0: keep_right equals the one-sided sums. */
    WfLcCase z = lc_case(0.5, 0.5, 0.1, 0.1, 0.1, 0.1);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, z), 0.2, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, z), -0.4, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_SYMMETRIC, z), -0.1, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, z), -0.1, 1e-12);
    lc_set(m, &p, "bias_mps2", 0.0);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, z), -0.1, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c), 0.2 - 0.25 - 0.1, 1e-12);
}

/* ---------------------------------------------------------------- missing followers */

/* has_new = 0 / has_old = 0: that follower's terms are 0 and its values (here absurd: NaN and -100) are not read,
 * nor is the missing new follower's safety checked. Defaults: gain 0.6 - 0.1 = 0.5 plus p times what is left. */
static void test_missing_followers(void)
{
    const WfLaneChangeModel *m = mobil();
    if (!m) return;
    Params p = lc_defaults(m);
    WfLcCase c = {.own_now = -0.1, .own_new = 0.5, .new_now = NAN, .new_new = -100.0, .old_now = 0.0,
                  .old_new = 1.0, .has_new = 0, .has_old = 1};
    /* symmetric: 0.6 + 0.2 (1.0) - 0.1 = 0.7; keep_right left: 0.6 - 0.4 = 0.2; right: 0.6 + 0.2 + 0.2 = 1.0 */
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c), 0.7, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c), 0.2, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c), 1.0, 1e-12);
    c = (WfLcCase){.own_now = -0.1, .own_new = 0.5, .new_now = 0.0, .new_new = -1.0, .old_now = NAN,
                   .old_new = -100.0, .has_new = 1, .has_old = 0};
    /* symmetric: 0.6 + 0.2 (-1.0) - 0.1 = 0.3; keep_right right: 0.6 + 0.2 = 0.8; left: 0.6 - 0.2 - 0.4 = 0.0 */
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_SYMMETRIC, c), 0.3, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_RIGHT, WF_LANE_RULE_KEEP_RIGHT, c), 0.8, 1e-12);
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, c), 0.0, 1e-12);
    c.has_new = 0;
    c.has_old = 0;
    /* nobody else: the own gain alone, 0.6 - 0.1 = 0.5 */
    CHECK_ABS(adv(m, &p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, c), 0.5, 1e-12);
}

/* ---------------------------------------------------------------- with IDM's accelerations */

/* IDM with its defaults: v0 = 30 m/s, T = 1 s, s0 = 2 m, a = 1 m/s^2, b = 1.5 m/s^2, delta = 4;
 *   a_IDM(s, v, v_l) = a [1 - (v/v0)^4 - (s_star/s)^2],
 *   s_star = s0 + max(0, v T + v (v - v_l) / (2 sqrt(a b))),
 *   2 sqrt(a b) = 2 sqrt(1.5) = 2.449489743.
 * The changer c drives 25 m/s in the right lane, 40 m behind a truck at 22 m/s; an old follower o drives 25 m/s
 * 30 m behind c. In the left lane, a leader at 28 m/s would be 60 m ahead of c, and the new follower n drives
 * 27 m/s 40 m behind c; c is 5 m long, so n's gap to its leader now is 40 + 5 + 60 = 105 m, and o's gap to the
 * truck after the change 30 + 5 + 40 = 75 m. (25/30)^4 = 0.4822530864, (27/30)^4 = 0.6561.
 *   a_c now: s_star = 2 + 25 + 25*3/2.449489743 = 57.61862178, (s_star/40)^2 = 2.074941985;  a = -1.5571940717
 *   ã_c:     v T + v dv/(..) = 25 - 30.6186 < 0, s_star = 2, (2/60)^2 = 0.001111111;      a =  0.5166358025
 *   a_n now: s_star = 2 + 27 - 27/2.449489743 = 17.97729616, (s_star/105)^2 = 0.02931367;  a =  0.3145863331
 *   ã_n:     s_star = 2 + 27 + 54/2.449489743 = 51.04540769, (s_star/40)^2 = 1.628521029;  a = -1.2846210286
 *   a_o now: s_star = 2 + 25 + 0 = 27, (27/30)^2 = 0.81;                                   a = -0.2922530864
 *   ã_o:     s_star = 57.61862178 (as a_c now), (s_star/75)^2 = 0.590205436;              a = -0.0724585222
 * Gains: own 2.0738298741, new follower -1.5992073617, old follower 0.2197945642.
 *   symmetric, p = 0.2:       2.0738298741 + 0.2 (-1.3794127975) - 0.1 = 1.6979473146  (change to the left)
 *   symmetric, p = 1:         2.0738298741 - 1.3794127975 - 0.1        = 0.5944170766
 *   keep_right (left), p=0.2: 2.0738298741 + 0.2 (-1.5992073617) - 0.4 = 1.3539884018
 * With n only 10 m behind c: s_star = 51.04540769, (s_star/10)^2 = 26.05633653, ã_n = -25.7124364573 < -4: unsafe. */
static void test_idm_pipeline(void)
{
    const WfLaneChangeModel *m = mobil();
    const WfCfModel *idm = NULL;
    WfError err = {0};
    CHECK(wf_cf_model_find("idm", &idm, &err) == 0, "idm: %s", err.msg);
    if (!m || !idm) return;
    Params ip;
    memset(&ip, 0, sizeof ip);
    wf_param_defaults(idm->spec, idm->n_spec, &ip);
    static const struct { const char *key; double v; } idm_def[] = {
        {"v0_mps", 30.0}, {"T_s", 1.0}, {"s0_m", 2.0}, {"a_mps2", 1.0}, {"b_mps2", 1.5}, {"delta", 4.0}};
    for (size_t k = 0; k < sizeof idm_def / sizeof idm_def[0]; k++) {
        const WfParamSpec *s = wf_param_find(idm->spec, idm->n_spec, idm_def[k].key);
        CHECK(s && wf_param_get(&ip, s) == idm_def[k].v, "IDM default %s is not %g: the hand values below assume it",
              idm_def[k].key, idm_def[k].v);
    }
    WfLcCase c = {
        .own_now = idm->accel(&ip, NULL, 40.0, 25.0, 22.0),
        .own_new = idm->accel(&ip, NULL, 60.0, 25.0, 28.0),
        .new_now = idm->accel(&ip, NULL, 105.0, 27.0, 28.0),
        .new_new = idm->accel(&ip, NULL, 40.0, 27.0, 25.0),
        .old_now = idm->accel(&ip, NULL, 30.0, 25.0, 25.0),
        .old_new = idm->accel(&ip, NULL, 75.0, 25.0, 22.0),
        .has_new = 1,
        .has_old = 1,
    };
    CHECK_ABS(c.own_now, -1.5571940717, 1e-9);
    CHECK_ABS(c.own_new, 0.5166358025, 1e-9);
    CHECK_ABS(c.new_now, 0.3145863331, 1e-9);
    CHECK_ABS(c.new_new, -1.2846210286, 1e-9);
    CHECK_ABS(c.old_now, -0.2922530864, 1e-9);
    CHECK_ABS(c.old_new, -0.0724585222, 1e-9);
    Params p = lc_defaults(m);
    CHECK_ABS(m->advantage(&p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, &c), 1.6979473146, 1e-9);
    CHECK_ABS(m->advantage(&p, WF_LANE_LEFT, WF_LANE_RULE_KEEP_RIGHT, &c), 1.3539884018, 1e-9);
    lc_set(m, &p, "politeness", 1.0);
    CHECK_ABS(m->advantage(&p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, &c), 0.5944170766, 1e-9);
    c.new_new = idm->accel(&ip, NULL, 10.0, 27.0, 25.0);
    CHECK_ABS(c.new_new, -25.7124364573, 1e-9);
    CHECK(m->advantage(&p, WF_LANE_LEFT, WF_LANE_RULE_SYMMETRIC, &c) == -INFINITY, "unsafe change allowed");
}

int main(void)
{
    RUN(test_registry_and_defaults);
    RUN(test_incentive_above_threshold);
    RUN(test_incentive_below_threshold);
    RUN(test_safety);
    RUN(test_mandatory);
    RUN(test_cooperation_keys);
    RUN(test_politeness_flips);
    RUN(test_keep_right_bias);
    RUN(test_missing_followers);
    RUN(test_idm_pipeline);
    TEST_EXIT();
}
