/* Automated-vehicle controllers (src/models/cf/follower_stopper.c, pi_saturation.c, acc.c), per-group placement
 * (src/core/fleet.c) and plug-in controllers (src/models/cf/plugin.c) against references worked out here: commanded
 * speeds at hand-computed points of every region and boundary (the check: at dv = -3 m/s the
 * FollowerStopper boundaries are 7.5, 9.75 and 15 m), PI-with-saturation steps with the arithmetic written
 * out, the ACC's string-stability claim by evaluating its transfer function, the wave damping of one
 * FollowerStopper AV on the Sugiyama ring, and the example plugin against the built-in controller, bit for
 * bit. Parameters go through the spec tables only, so the tests do not depend on the models' structs. */
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/cf.h"
#include "wavefuel/cf_plugin.h"
#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

typedef struct Params {
    double v[WF_MAX_MODEL_PARAMS];
} Params;

static const WfCfModel *model(const char *name)
{
    const WfCfModel *m = NULL;
    WfError err = {0};
    CHECK(wf_cf_model_find(name, &m, &err) == 0, "%s", err.msg);
    return m;
}

static Params defaults(const WfCfModel *m)
{
    Params p;
    memset(&p, 0, sizeof p);
    wf_param_defaults(m->spec, m->n_spec, &p);
    return p;
}

static void set(const WfCfModel *m, Params *p, const char *key, double value)
{
    const WfParamSpec *s = wf_param_find(m->spec, m->n_spec, key);
    CHECK(s != NULL, "%s has no key '%s'", m->name, key);
    if (s) *wf_param_ptr(p, s) = value;
}

/* ------------------------------------------------------------------------------------ registry, tables */

static void test_tables(void)
{
    static const char *const names[] = {"follower_stopper", "pi_saturation", "acc"};
    for (size_t i = 0; i < 3; i++) {
        const WfCfModel *m = model(names[i]);
        if (!m) continue;
        CHECK(m->param_size == m->n_spec * sizeof(double) && m->param_size <= sizeof(Params), "%s: %zu bytes",
              m->name, m->param_size);
        for (size_t k = 0; k < m->n_spec; k++) {
            const WfParamSpec *s = &m->spec[k];
            CHECK(s->offset == k * sizeof(double), "%s.%s: offset %zu", m->name, s->key, s->offset);
            CHECK(s->min <= s->def && s->def <= s->max && s->unit && s->doc, "%s.%s", m->name, s->key);
        }
        Params p = defaults(m);
        WfError err = {0};
        CHECK(!m->check || m->check(&p, &err) == 0, "%s: defaults rejected: %s", m->name, err.msg);
        /* Only PI with saturation has memory. */
        int stateful = strcmp(names[i], "pi_saturation") == 0;
        CHECK(!!m->state_size == stateful && !!m->init_state == stateful && !!m->update_state == stateful,
              "%s: state functions", m->name);
    }
    /* The defaults named by the issue. */
    const WfCfModel *fs = model("follower_stopper");
    Params p = defaults(fs);
    static const char *const keys[] = {"dx1_m", "dx2_m", "dx3_m", "d1_mps2", "d2_mps2", "d3_mps2"};
    static const double want[] = {4.5, 5.25, 6.0, 1.5, 1.0, 0.5};
    for (size_t k = 0; k < 6; k++)
        CHECK(wf_param_get(&p, wf_param_find(fs->spec, fs->n_spec, keys[k])) == want[k], "%s", keys[k]);
}

/* ------------------------------------------------------------------------------------ FollowerStopper */

/* The command recovered from a = k (v_cmd - v) with k = 1: v_cmd = a + v (exact for these values). */
static double fs_cmd(const WfCfModel *m, const Params *p, double gap, double v, double vl)
{
    return m->accel(p, NULL, gap, v, vl) + v;
}

static void test_follower_stopper_points(void)
{
    const WfCfModel *m = model("follower_stopper");
    if (!m) return;
    Params p = defaults(m);
    set(m, &p, "U_mps", 7.5);
    set(m, &p, "k_per_s", 1.0);

    /* dv = 0 (v = v_lead = 5): boundaries 4.5, 5.25, 6 m; w = min(5, 7.5) = 5. */
    static const double g0[][2] = {
        {0.0, 0.0}, {4.0, 0.0}, {4.5, 0.0},  /* region 1 and its boundary (<= dx1 gives 0) */
        {4.875, 2.5},                        /* 5 * (4.875 - 4.5)/0.75 */
        {5.25, 5.0},                         /* end of region 2: w */
        {5.625, 6.25},                       /* 5 + 2.5 * (5.625 - 5.25)/0.75 */
        {6.0, 7.5}, {6.5, 7.5}, {100.0, 7.5} /* end of region 3: U, and beyond */
    };
    for (size_t i = 0; i < sizeof g0 / sizeof g0[0]; i++)
        CHECK_REL(fs_cmd(m, &p, g0[i][0], 5.0, 5.0), g0[i][1], 1e-14);

    /* dv = -3 (v = 8, v_lead = 5): dx1 = 4.5 + 9/3 = 7.5, dx2 = 5.25 + 9/2 = 9.75, dx3 = 6 + 9/1 = 15 m. */
    static const double g3[][2] = {
        {7.4, 0.0}, {7.5, 0.0},      /* stop region and its boundary */
        {7.5 + 1e-9, 5.0 * 1e-9 / 2.25}, /* just past it: w (gap - 7.5)/2.25 */
        {8.625, 2.5},                /* middle of region 2: 5 * 1.125/2.25 */
        {9.75, 5.0},                 /* dx2: w */
        {12.375, 6.25},              /* middle of region 3: 5 + 2.5 * 2.625/5.25 */
        {15.0, 7.5}, {15.001, 7.5},  /* dx3: U, and beyond */
    };
    for (size_t i = 0; i < sizeof g3 / sizeof g3[0]; i++) {
        double a = m->accel(&p, NULL, g3[i][0], 8.0, 5.0);
        CHECK_ABS(a, g3[i][1] - 8.0, 1e-13);
    }

    /* Leader faster than the AV (dv_ = 0, boundaries unshifted); w = min(v_lead, U). */
    CHECK_REL(fs_cmd(m, &p, 5.0, 3.0, 6.0), 6.0 * 0.5 / 0.75, 1e-14); /* w = 6 */
    CHECK_REL(fs_cmd(m, &p, 5.0, 5.0, 9.0), 7.5 * 0.5 / 0.75, 1e-14); /* w = U = 7.5 */
    CHECK_REL(fs_cmd(m, &p, 5.5, 5.0, 9.0), 7.5, 1e-14);              /* region 3 with w = U: U */

    /* The gain scales the acceleration: a = k (v_cmd - v). */
    set(m, &p, "k_per_s", 2.5);
    CHECK_REL(m->accel(&p, NULL, 8.625, 8.0, 5.0), 2.5 * (2.5 - 8.0), 1e-14);

    /* Continuity at the boundaries (the law is continuous in the gap at every closing speed). */
    set(m, &p, "k_per_s", 1.0);
    for (double dv = 0.0; dv <= 6.0; dv += 0.5) {
        double v = 3.0 + dv, vl = 3.0;
        double dx[3] = {4.5 + dv * dv / 3.0, 5.25 + dv * dv / 2.0, 6.0 + dv * dv / 1.0};
        for (int k = 0; k < 3; k++) {
            double lo = m->accel(&p, NULL, dx[k] * (1 - 1e-12), v, vl), hi = m->accel(&p, NULL, dx[k] * (1 + 1e-12), v, vl);
            CHECK(fabs(lo - hi) < 1e-9, "jump at dx%d = %g (dv %g): %g vs %g", k + 1, dx[k], dv, lo, hi);
        }
    }

    /* check(): ordering of the boundaries and of the decelerations. */
    WfError err = {0};
    Params q = p;
    set(m, &q, "dx2_m", 4.5);
    CHECK(m->check(&q, &err) == WF_EINPUT, "dx1 = dx2 accepted");
    q = p;
    set(m, &q, "d3_mps2", 1.2);
    CHECK(m->check(&q, &err) == WF_EINPUT && strstr(err.msg, "d1_mps2"), "d3 > d2 accepted: %s", err.msg);
}

/* ------------------------------------------------------------------------------------ PI with saturation */

typedef struct Pi {
    const WfCfModel *m;
    Params p;
    unsigned char *state;
} Pi;

static Pi pi_new(double window_s, double v0)
{
    Pi pi = {model("pi_saturation"), {{0}}, NULL};
    pi.p = defaults(pi.m);
    set(pi.m, &pi.p, "window_s", window_s);
    pi.state = calloc(1, pi.m->state_size);
    pi.m->init_state(&pi.p, pi.state, 20.0, v0, v0);
    return pi;
}

/* One step as the engine does it: accel from the old memory, then update with the same inputs. accel must
 * leave the memory untouched. Returns the acceleration. */
static double pi_step(Pi *pi, double gap, double v, double vl, double dt)
{
    size_t sz = pi->m->state_size;
    unsigned char *copy = malloc(sz);
    memcpy(copy, pi->state, sz);
    double a = pi->m->accel(&pi->p, pi->state, gap, v, vl);
    CHECK(memcmp(copy, pi->state, sz) == 0, "accel changed the state");
    free(copy);
    pi->m->update_state(&pi->p, pi->state, gap, v, vl, dt);
    return a;
}

static void test_pi_saturation_steps(void)
{
    /* Defaults: window 38 s, v_catch 1, g_l 7, g_u 30, gamma 2, safe gap max(2 dv, 4), k = 1. Start at 10 m/s:
     * the command starts at the current speed. */
    Pi pi = pi_new(38.0, 10.0);
    /* Step 1: gap 18.5, v = v_lead = 10. U = 10 (only the current speed); v_target = 10 + clip(11.5/23) = 10.5;
     * dx_s = 4; alpha = clip(14.5/2) = 1; beta = 0.5; v_cmd = 0.5 * 10.5 + 0.5 * 10 = 10.25; a = 0.25. */
    CHECK_REL(pi_step(&pi, 18.5, 10.0, 10.0, 0.1), 0.25, 1e-14);
    /* Step 2: gap 5, v = 10, v_lead = 9. U = (10 + 10)/2 = 10; v_target = 10 (gap < g_l); dx_s = max(-2, 4) = 4;
     * alpha = 0.5; beta = 0.75; v_cmd = 0.75 (0.5 * 10 + 0.5 * 9) + 0.25 * 10.25 = 9.6875; a = -0.3125. */
    CHECK_REL(pi_step(&pi, 5.0, 10.0, 9.0, 0.1), -0.3125, 1e-14);
    /* Step 3: gap 3, v = 9, v_lead = 12: dx_s = max(6, 4) = 6, alpha = 0, beta = 1: v_cmd = v_lead = 12;
     * a = 3 whatever the memory. */
    CHECK_REL(pi_step(&pi, 3.0, 9.0, 12.0, 0.1), 3.0, 1e-14);
    /* Step 4: gap 40 (alpha = 1, beta = 0.5, catch-up saturated: +1), v = 6, v_lead = 6.
     * U = (10 + 10 + 9 + 6)/4 = 8.75; v_cmd = 0.5 * 9.75 + 0.5 * 12 = 10.875; a = 4.875. */
    CHECK_REL(pi_step(&pi, 40.0, 6.0, 6.0, 0.1), 4.875, 1e-14);
    free(pi.state);

    /* The window: 0.3 s = 3 samples, the current one included. Samples 10, 10, 9, 6 stored; next step at
     * v = 3 averages (9 + 6 + 3)/3 = 6; gap 40: v_cmd = 0.5 (6 + 1) + 0.5 v_cmd_prev. */
    pi = pi_new(0.3, 10.0);
    pi_step(&pi, 40.0, 10.0, 10.0, 0.1); /* v_cmd = 0.5 * 11 + 0.5 * 10 = 10.5 */
    pi_step(&pi, 40.0, 10.0, 10.0, 0.1); /* U = 10: v_cmd = 0.5 * 11 + 0.5 * 10.5 = 10.75 */
    pi_step(&pi, 40.0, 9.0, 10.0, 0.1);  /* U = (10 + 10 + 9)/3 = 29/3: v_cmd = 0.5 (32/3) + 5.375 */
    double c3 = 0.5 * (29.0 / 3.0 + 1.0) + 0.5 * 10.75;
    pi_step(&pi, 40.0, 6.0, 10.0, 0.1); /* U = (10 + 9 + 6)/3 = 25/3 */
    double c4 = 0.5 * (25.0 / 3.0 + 1.0) + 0.5 * c3;
    CHECK_REL(pi_step(&pi, 40.0, 3.0, 3.0, 0.1), 0.5 * (6.0 + 1.0) + 0.5 * c4 - 3.0, 1e-14);
    free(pi.state);

    /* The 0.1 s sampling clock is independent of dt. dt = 0.2: each step stores two samples; after steps at
     * v = 1 and 2 the history is 1, 1, 2, 2; with window 0.4 s (4 samples) the next average at v = 5 is
     * (1 + 2 + 2 + 5)/4 = 2.5. dt = 0.05: the samples at t = 0 and 0.1 fall in the steps at v = 1 and v = 3
     * (of steps at 1, 2, 3, 4); the average at v = 5 is (1 + 3 + 5)/3 = 3. Every step runs at gap 3 m, inside
     * the safe gap (alpha = 0, beta = 1: v_cmd = v_lead), so both end with v_cmd = 7 and the averages show in
     * the next command at gap 40 m: v_cmd = 0.5 (U + 1) + 0.5 * 7. */
    Pi a = pi_new(0.4, 1.0), b = pi_new(0.4, 1.0);
    pi_step(&a, 3.0, 1.0, 1.0, 0.2);
    pi_step(&a, 3.0, 2.0, 7.0, 0.2);
    pi_step(&b, 3.0, 1.0, 1.0, 0.05);
    pi_step(&b, 3.0, 2.0, 1.0, 0.05);
    pi_step(&b, 3.0, 3.0, 1.0, 0.05);
    pi_step(&b, 3.0, 4.0, 7.0, 0.05);
    CHECK_REL(a.m->accel(&a.p, a.state, 40.0, 5.0, 5.0), 0.5 * (2.5 + 1.0) + 0.5 * 7.0 - 5.0, 1e-14);
    CHECK_REL(b.m->accel(&b.p, b.state, 40.0, 5.0, 5.0), 0.5 * (3.0 + 1.0) + 0.5 * 7.0 - 5.0, 1e-14);
    free(a.state);
    free(b.state);

    /* Without memory (the uniform-flow solvers): the sign of (gap - g_l) at v_lead = v, so initial
     * conditions put the AV at g_l = 7 m. */
    const WfCfModel *m = model("pi_saturation");
    Params p = defaults(m);
    CHECK(m->accel(&p, NULL, 6.9, 5.0, 5.0) < 0.0 && m->accel(&p, NULL, 7.0, 5.0, 5.0) == 0.0 &&
              m->accel(&p, NULL, 7.1, 5.0, 5.0) > 0.0,
          "stand-in sign");
    /* 0.5 m/s of catch-up at the middle of [g_l, g_u], k = 1. */
    CHECK_REL(m->accel(&p, NULL, 18.5, 5.0, 5.0), 0.5, 1e-14);
    WfError err = {0};
    set(m, &p, "g_u_m", 7.0);
    CHECK(m->check(&p, &err) == WF_EINPUT, "g_u = g_l accepted");
}

/* ------------------------------------------------------------------------------------ ACC */

static void test_acc(void)
{
    const WfCfModel *m = model("acc");
    if (!m) return;
    Params p = defaults(m);
    /* a = 0.4 (gap - 2 - 1.1 v) + 0.8 (v_lead - v), capped by 0.4 (30 - v). */
    CHECK_REL(m->accel(&p, NULL, 13.0, 10.0, 10.0), 0.0, 1e-14);           /* equilibrium gap s0 + T v */
    CHECK_REL(m->accel(&p, NULL, 20.0, 10.0, 8.0), 0.4 * 7.0 - 1.6, 1e-14); /* 2.8 - 1.6 = 1.2 */
    CHECK_REL(m->accel(&p, NULL, 500.0, 10.0, 10.0), 0.4 * 20.0, 1e-14);    /* speed mode: 8 */
    CHECK_REL(m->accel(&p, NULL, 0.0, 0.0, 0.0), -0.8, 1e-14);

    /* The comment's claim, checked on the transfer function G(jw) = (k_dv jw + k_gap) / (-w^2 + (k_dv + k_gap
     * T) jw + k_gap): the defaults keep |G| <= 1 at every frequency, Milanés & Shladover's gains exceed 1. */
    double T = 1.1, kg[2] = {0.4, 0.23}, kd[2] = {0.8, 0.07}, peak[2] = {0.0, 0.0};
    for (int c = 0; c < 2; c++)
        for (double w = 1e-3; w < 10.0; w *= 1.01) {
            double complex jw = I * w;
            double g = cabs((kd[c] * jw + kg[c]) / (jw * jw + (kd[c] + kg[c] * T) * jw + kg[c]));
            peak[c] = fmax(peak[c], g);
        }
    CHECK(peak[0] <= 1.0 + 1e-12, "defaults amplify: peak |G| = %.6g", peak[0]);
    CHECK(peak[1] > 1.1, "production gains should amplify: peak |G| = %.6g", peak[1]);
}

/* ------------------------------------------------------------------------------------ scenarios */

static char tmp_dir[64];

static WfScenario *load(const char *path, const char *const *set_, size_t n_set, WfError *err)
{
    WfScenario *sc = NULL;
    if (wf_scenario_load(path, set_, n_set, &sc, err)) return NULL;
    return sc;
}

/* Write `text` to tmp_dir/name; returns the path in a static buffer (valid until the next call). */
static const char *write_tmp(const char *name, const char *text)
{
    static char path[256];
    snprintf(path, sizeof path, "%s/%s", tmp_dir, name);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL, "cannot write %s", path);
    if (fp) {
        fputs(text, fp);
        fclose(fp);
    }
    return path;
}

/* Run a scenario to the end; returns the simulation (caller destroys) or NULL after a failed CHECK. */
static WfSim *run(const WfScenario *sc)
{
    WfSim *sim = NULL;
    WfError err = {0};
    int rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_run(sim, NULL, NULL, NULL, NULL, &err);
    CHECK(rc == 0, "run: %s", err.msg);
    if (rc) wf_sim_destroy(&sim);
    return sim;
}

static int same_fleet(const WfFleet *a, const WfFleet *b)
{
    if (a->n != b->n) return 0;
    size_t sz = a->n * sizeof(double);
    return memcmp(a->x_m, b->x_m, sz) == 0 && memcmp(a->v_mps, b->v_mps, sz) == 0 &&
           memcmp(a->fuel_g, b->fuel_g, sz) == 0 && memcmp(a->x_start_m, b->x_start_m, sz) == 0;
}

static const char *ring_yaml =
    "seed: 5\n"
    "road: {type: ring, length_m: 2000}\n"
    "time: {duration_s: 1, dt_s: 0.1}\n"
    "fleet:\n"
    "  vehicles: 100\n"
    "  placement: random\n"
    "  classes:\n"
    "    - {class: compact_sedan, count: 70}\n"
    "    - {class: midsize_suv, count: 30}\n"
    "  drivers:\n"
    "    - {name: human, model: idm, count: 93}\n"
    "    - {name: av, model: acc, count: 7, placement: interleaved, class: midsize_suv}\n";

/* Per-group placement: evenly spaced vehicles floor(j n / k), random without repeats and by seed, explicit
 * lists; a group's class; classes' counts kept; and the errors. */
static void test_group_placement(void)
{
    WfError err = {0};
    char path[256];
    snprintf(path, sizeof path, "%s", write_tmp("ring.yaml", ring_yaml));
    WfScenario *sc = load(path, NULL, 0, &err);
    CHECK(sc != NULL, "%s", err.msg);
    if (!sc) return;
    WfSim *sim = NULL;
    CHECK(wf_sim_create(sc, &sim, &err) == 0, "%s", err.msg);
    if (sim) {
        const WfFleet *f = wf_sim_fleet(sim);
        long n_av = 0, n_suv = 0;
        unsigned char want[100] = {0};
        for (size_t j = 0; j < 7; j++) want[j * 100 / 7] = 1; /* 0, 14, 28, 42, 57, 71, 85 */
        for (size_t i = 0; i < f->n; i++) {
            int av = want[i];
            CHECK(f->group_id[i] == (av ? 1 : 0), "vehicle %zu: group %u", i, f->group_id[i]);
            if (av) CHECK(f->class_id[i] == 1, "AV %zu has class %u", i, f->class_id[i]);
            n_av += f->group_id[i] == 1;
            n_suv += f->class_id[i] == 1;
        }
        CHECK(n_av == 7 && n_suv == 30, "counts %ld AVs, %ld SUVs", n_av, n_suv);
        wf_sim_destroy(&sim);
    }
    wf_scenario_destroy(&sc);

    /* Random: 7 distinct vehicles, the same for the same seed, different for another. */
    const char *rnd[] = {"fleet.drivers[1].placement=random"};
    const char *rnd2[] = {"fleet.drivers[1].placement=random", "seed=6"};
    unsigned char pick[3][100];
    for (int r = 0; r < 3; r++) {
        sc = load(path, r == 2 ? rnd2 : rnd, r == 2 ? 2 : 1, &err);
        CHECK(sc != NULL, "%s", err.msg);
        if (!sc || wf_sim_create(sc, &sim, &err)) {
            wf_scenario_destroy(&sc);
            return;
        }
        const WfFleet *f = wf_sim_fleet(sim);
        int cnt = 0;
        for (size_t i = 0; i < 100; i++) pick[r][i] = f->group_id[i] == 1, cnt += pick[r][i];
        CHECK(cnt == 7, "random placement gave %d AVs", cnt);
        wf_sim_destroy(&sim);
        wf_scenario_destroy(&sc);
    }
    CHECK(memcmp(pick[0], pick[1], 100) == 0, "same seed, different placement");
    CHECK(memcmp(pick[0], pick[2], 100) != 0, "seed did not change the placement");

    /* Explicit indices of one group, the others by fleet.placement (--set cannot create list items: the
     * variant is written out). */
    char text[2048];
    snprintf(text, sizeof text, "%s", ring_yaml);
    char *av = strstr(text, "    - {name: av");
    snprintf(av, sizeof text - (size_t)(av - text),
             "    - {name: av, model: acc, placement: explicit, indices: [3, 50, 99], class: midsize_suv}\n");
    char *h = strstr(text, "count: 93");
    memcpy(h, "count: 97", 9);
    sc = load(write_tmp("explicit.yaml", text), NULL, 0, &err);
    CHECK(sc != NULL, "%s", err.msg);
    if (sc && wf_sim_create(sc, &sim, &err) == 0) {
        const WfFleet *f = wf_sim_fleet(sim);
        for (size_t i = 0; i < 100; i++)
            CHECK(f->group_id[i] == (i == 3 || i == 50 || i == 99), "vehicle %zu: group %u", i, f->group_id[i]);
        wf_sim_destroy(&sim);
    }
    wf_scenario_destroy(&sc);

    /* Errors: more AVs than SUVs; an unknown class; a group placement under fleet-wide explicit placement. */
    const char *too_many[] = {"fleet.drivers[0].count=60", "fleet.drivers[1].count=40"};
    sc = load(path, too_many, 2, &err);
    CHECK(!sc && strstr(err.msg, "midsize_suv") && strstr(err.msg, "40"), "class overflow: %s", err.msg);
    wf_scenario_destroy(&sc);
    const char *bad_class[] = {"fleet.drivers[1].class=class8_tractor"};
    sc = load(path, bad_class, 1, &err);
    CHECK(!sc && strstr(err.msg, "class8_tractor") && strstr(err.msg, "compact_sedan"), "unknown class: %s",
          err.msg);
    wf_scenario_destroy(&sc);
    /* Two explicit groups claiming the same vehicle. */
    const char *twice = "road: {type: ring, length_m: 200}\ntime: {duration_s: 1}\nfleet:\n  vehicles: 4\n"
                        "  classes: [{class: compact_sedan, count: 4}]\n  drivers:\n"
                        "    - {model: idm, count: 2}\n"
                        "    - {model: acc, placement: explicit, indices: [1]}\n"
                        "    - {model: acc, placement: explicit, indices: [1]}\n";
    sc = load(write_tmp("twice.yaml", twice), NULL, 0, &err);
    CHECK(!sc && strstr(err.msg, "vehicle 1 is listed twice"), "claimed twice: %s", err.msg);
    wf_scenario_destroy(&sc);
    /* A group's own placement when fleet.placement is explicit already lists everyone. */
    const char *fleet_explicit = "road: {type: ring, length_m: 200}\ntime: {duration_s: 1}\nfleet:\n"
                                 "  vehicles: 2\n  placement: explicit\n"
                                 "  classes: [{class: compact_sedan, indices: [0, 1]}]\n  drivers:\n"
                                 "    - {model: idm, indices: [0]}\n"
                                 "    - {model: acc, indices: [1], placement: random}\n";
    sc = load(write_tmp("fleet_explicit.yaml", fleet_explicit), NULL, 0, &err);
    CHECK(!sc && strstr(err.msg, "fleet.placement is explicit"), "group placement under explicit: %s", err.msg);
    wf_scenario_destroy(&sc);
}

#define SUGIYAMA_FS "scenarios/sugiyama_followerstopper.yaml"

/* One FollowerStopper AV (U = 2.5 m/s, below the 2.88 m/s mean speed of the humans' wave) against the same
 * seed without it. Measured at seed 2008: time-averaged spatial speed s.d. 2.818 -> 0.141 m/s (-95.0 %), fleet
 * fuel 15.675 -> 14.077 L/100km (-10.2 %). Over seeds 1..10 the s.d. falls by 94.7-95.5 % every time, the fuel by
 * 10.0-13.7 %. The assertions (s.d. at least -80 %, fuel at least -5 %) keep half of the measured effect at this
 * seed. The control that they can fail: the same slot driven by an ACC with Milanés & Shladover's string-unstable
 * production gains leaves the wave in place (measured over seeds 1-4: +4.5 % s.d., +5.2 % fuel). */
static int summary_of(const char *path, const char *const *set_, size_t n_set, WfSummary *out)
{
    WfError err = {0};
    WfScenario *sc = load(path, set_, n_set, &err);
    CHECK(sc != NULL, "%s: %s", path, err.msg);
    WfSim *sim = sc ? run(sc) : NULL;
    int ok = sim != NULL;
    if (ok) *out = *wf_sim_summary(sim);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return ok;
}

static void test_sugiyama_one_av(void)
{
    WfError err = {0};
    const char *none[] = {"fleet.drivers[0].count=22", "fleet.drivers[1].count=0"};
    WfScenario *with = load(SUGIYAMA_FS, NULL, 0, &err), *without = load(SUGIYAMA_FS, none, 2, &err);
    WfScenario *plain = load("scenarios/sugiyama.yaml", NULL, 0, &err);
    CHECK(with && without && plain, "%s", err.msg);
    WfSim *a = with ? run(with) : NULL, *b = without ? run(without) : NULL, *c = plain ? run(plain) : NULL;
    int have_b = b != NULL;
    if (a && b && c) {
        const WfSummary *sa = wf_sim_summary(a);
        WfSummary sb = *wf_sim_summary(b);
        double dsd = sa->sd_speed_time_avg_mps / sb.sd_speed_time_avg_mps - 1.0;
        double dfuel = sa->l_per_100km / sb.l_per_100km - 1.0;
        printf("  one FollowerStopper AV: speed s.d. %.4f -> %.4f m/s (%+.1f %%), fuel %.4f -> %.4f L/100km "
               "(%+.1f %%)\n",
               sb.sd_speed_time_avg_mps, sa->sd_speed_time_avg_mps, 100 * dsd, sb.l_per_100km, sa->l_per_100km,
               100 * dfuel);
        CHECK(dsd < -0.80, "speed s.d. changed by %+.1f %%, expected at most -80 %%", 100 * dsd);
        CHECK(dfuel < -0.05, "fuel changed by %+.1f %%, expected at most -5 %%", 100 * dfuel);
        CHECK(sa->overlaps == 0, "%lld overlaps", (long long)sa->overlaps);
        /* An AV group of 0 vehicles changes nothing: the same bits as scenarios/sugiyama.yaml. */
        CHECK(same_fleet(wf_sim_fleet(b), wf_sim_fleet(c)), "0 AVs differ from sugiyama.yaml");
    }
    wf_sim_destroy(&a);
    wf_sim_destroy(&b);
    wf_sim_destroy(&c);
    wf_scenario_destroy(&plain);
    wf_scenario_destroy(&with);
    wf_scenario_destroy(&without);

    /* The control: the AV slot with the production-gain ACC (the scenario text with its model and params
     * lines replaced). */
    char text[4096];
    FILE *fp = fopen(SUGIYAMA_FS, "r");
    size_t len = fp ? fread(text, 1, sizeof text - 1, fp) : 0;
    if (fp) fclose(fp);
    text[len] = '\0';
    char *model_line = strstr(text, "model: follower_stopper");
    char *params_line = strstr(text, "params: {U_mps");
    CHECK(model_line && params_line, "scenario layout changed");
    if (!have_b || !model_line || !params_line) return;
    memcpy(model_line, "model: acc             ", 23);
    char *eol = strchr(params_line, '\n');
    const char *acc = "params: {k_gap_per_s2: 0.23, k_dv_per_s: 0.07}";
    CHECK(eol && (size_t)(eol - params_line) <= strlen(acc) + 40, "params line");
    if (!eol) return;
    char rest[4096];
    snprintf(rest, sizeof rest, "%s", eol);
    snprintf(params_line, sizeof text - (size_t)(params_line - text), "%s%s", acc, rest);
    /* Averaged over seeds: on one realisation of the noise the ACC's effect on the wave ranges from -23 % to
     * +9 % (seeds 1-8 and 2008), far from the FollowerStopper's -90 % and more. */
    const char *acc_path = write_tmp("acc_slot.yaml", text);
    double dsd = 0.0, dfuel = 0.0;
    int runs = 0;
    for (int seed = 1; seed <= 4; seed++) {
        char seed_set[32];
        snprintf(seed_set, sizeof seed_set, "seed=%d", seed);
        const char *base_set[] = {"fleet.drivers[0].count=22", "fleet.drivers[1].count=0", seed_set};
        WfSummary sh = {0}, s0 = {0};
        if (!summary_of(acc_path, base_set + 2, 1, &sh) || !summary_of(SUGIYAMA_FS, base_set, 3, &s0)) continue;
        dsd += sh.sd_speed_time_avg_mps / s0.sd_speed_time_avg_mps - 1.0;
        dfuel += sh.l_per_100km / s0.l_per_100km - 1.0;
        runs++;
    }
    CHECK(runs == 4, "%d of 4 seeds ran", runs);
    if (runs) {
        dsd /= runs, dfuel /= runs;
        printf("  one production-gain ACC (mean of seeds 1-4): speed s.d. %+.1f %%, fuel %+.1f %%\n", 100 * dsd,
               100 * dfuel);
        CHECK(dsd > -0.2 && dfuel > -0.05, "ACC slot: s.d. %+.1f %%, fuel %+.1f %%", 100 * dsd, 100 * dfuel);
    }
}

/* Initial equilibrium with a FollowerStopper AV. Its uniform-flow gap jumps with the speed: 5.25 m below U,
 * any gap >= 5.25 m at U (it cruises at U behind whatever gap it has), none above. When U is below the humans'
 * ring equilibrium (3.95 m/s here) the fleet starts at a speed <= U with the AV at >= 5.25 m and every gap
 * >= 0: the ring solver must settle on the feasible side of that jump, for every U. */
static void test_fs_initial_equilibrium(void)
{
    long bad = 0;
    for (int j = 0; j <= 200; j++) {
        double U = 1.9 + 0.01 * j;
        char set_u[64];
        snprintf(set_u, sizeof set_u, "fleet.drivers[1].params.U_mps=%.2f", U);
        const char *sets[] = {set_u, "initial.jitter_m=0"};
        WfError err = {0};
        WfScenario *sc = load(SUGIYAMA_FS, sets, 2, &err);
        WfSim *sim = NULL;
        int rc = sc ? wf_sim_create(sc, &sim, &err) : -1;
        if (rc == 0) {
            const WfFleet *f = wf_sim_fleet(sim);
            double gap0 = f->x_m[1] - wf_fleet_length(f, 1) - f->x_m[0]; /* the AV is vehicle 0 */
            if (!(f->v_init_mps <= U && gap0 >= 5.25 - 1e-9)) rc = -2;
        }
        if (rc && bad++ < 3)
            printf("  U = %.2f m/s: %s\n", U, rc == -2 ? "AV gap below 5.25 m or speed above U" : err.msg);
        wf_sim_destroy(&sim);
        wf_scenario_destroy(&sc);
    }
    CHECK(bad == 0, "%ld of 201 values of U fail to start", bad);
}

/* ------------------------------------------------------------------------------------ plugins */

static void plugin_path(char *buf, size_t len)
{
    const char *build = getenv("BUILD");
    snprintf(buf, len, "%s/plugins/follower_stopper_plugin.so", build && build[0] ? build : "build");
}

/* The example plugin and the built-in controller: the same parameter table, the same accelerations over a
 * sweep (bit for bit), and the same run of scenarios/sugiyama_followerstopper.yaml (every position, speed
 * and fuel total equal). */
static void test_plugin_matches_builtin(void)
{
    char so[512], set_path[1100];
    plugin_path(so, sizeof so);
    if (access(so, R_OK) != 0) {
        CHECK(0, "%s missing: build it with `make tests`", so);
        return;
    }
    WfError err = {0};
    WfCfPluginLib *lib = NULL;
    CHECK(wf_cf_plugin_load(so, &lib, &err) == 0, "%s", err.msg);
    if (!lib) return;
    const WfCfModel *pm = wf_cf_plugin_model(lib), *bm = model("follower_stopper");
    CHECK(strcmp(pm->name, "follower_stopper_plugin") == 0, "name %s", pm->name);
    CHECK(pm->n_spec == bm->n_spec, "%zu vs %zu parameters", pm->n_spec, bm->n_spec);
    for (size_t k = 0; k < pm->n_spec && k < bm->n_spec; k++)
        CHECK(strcmp(pm->spec[k].key, bm->spec[k].key) == 0 && pm->spec[k].offset == bm->spec[k].offset &&
                  pm->spec[k].def == bm->spec[k].def && pm->spec[k].min == bm->spec[k].min &&
                  pm->spec[k].max == bm->spec[k].max && strcmp(pm->spec[k].unit, bm->spec[k].unit) == 0,
              "parameter %zu differs", k);
    Params p = defaults(bm);
    set(bm, &p, "U_mps", 6.0);
    long differ = 0;
    for (double gap = 0.0; gap <= 40.0; gap += 0.37)
        for (double v = 0.0; v <= 12.0; v += 0.7)
            for (double vl = 0.0; vl <= 12.0; vl += 0.9) {
                double x = pm->accel(&p, NULL, gap, v, vl), y = bm->accel(&p, NULL, gap, v, vl);
                differ += memcmp(&x, &y, sizeof x) != 0;
            }
    CHECK(differ == 0, "%ld accelerations differ", differ);
    /* The plugin's check() reports through wavefuel's error record. */
    set(bm, &p, "d3_mps2", 2.0);
    memset(&err, 0, sizeof err);
    CHECK(pm->check(&p, &err) == WF_EINPUT && strstr(err.msg, "d1_mps2"), "plugin check: %s", err.msg);
    wf_cf_plugin_close(&lib);
    CHECK(lib == NULL, "close must clear the pointer");

    char abs_so[1024];
    CHECK(realpath(so, abs_so) != NULL, "realpath %s", so);
    snprintf(set_path, sizeof set_path, "fleet.drivers[1].path=%s", abs_so);
    const char *as_plugin[] = {"fleet.drivers[1].model=plugin", set_path};
    WfScenario *s1 = load(SUGIYAMA_FS, NULL, 0, &err), *s2 = load(SUGIYAMA_FS, as_plugin, 2, &err);
    CHECK(s1 && s2, "%s", err.msg);
    WfSim *a = s1 ? run(s1) : NULL, *b = s2 ? run(s2) : NULL;
    if (a && b) {
        CHECK(same_fleet(wf_sim_fleet(a), wf_sim_fleet(b)), "plugin run differs from the built-in run");
        CHECK(wf_sim_summary(a)->sd_speed_time_avg_mps == wf_sim_summary(b)->sd_speed_time_avg_mps, "s.d.");
        CHECK(strcmp(wf_sim_scenario(b)->groups[1].model->name, "follower_stopper_plugin") == 0, "model name");
    }
    wf_sim_destroy(&a);
    wf_sim_destroy(&b);
    wf_scenario_destroy(&s1);
    wf_scenario_destroy(&s2);
}

int main(void)
{
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/wf_ctrl_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
        perror("mkdtemp");
        return 1;
    }
    RUN(test_tables);
    RUN(test_follower_stopper_points);
    RUN(test_pi_saturation_steps);
    RUN(test_acc);
    RUN(test_group_placement);
    RUN(test_sugiyama_one_av);
    RUN(test_fs_initial_equilibrium);
    RUN(test_plugin_matches_builtin);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp_dir);
    if (system(cmd) != 0) printf("  could not remove %s\n", tmp_dir);
    TEST_EXIT();
}
