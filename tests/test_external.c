/* External controllers (src/models/cf/external.c, wf_sim_observe / wf_sim_set_actions): a controller computed
 * outside the engine from the observations and set every step must drive exactly as the same law inside the engine.
 * On a ring, a group commanded with IDM's acceleration (wf_cf_idm.accel on the observed speed, leader speed and
 * gap) gives the bits of the same group driving IDM: every record and the final state, with noise. On a corridor,
 * an external_speed group commanded with acc's set speed gives the bits of the acc group, entries and trips
 * included. RL batches of small rings stepped side by side give the bits of each ring alone. And the refusals: a
 * group that is not external, a wrong count, an infinite command. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wavefuel/rl.h"
#include "wf_test.h"

typedef struct Bytes {
    unsigned char *b;
    size_t         n;
} Bytes;

static void add(Bytes *o, const void *p, size_t n)
{
    unsigned char *q = realloc(o->b, o->n + n);
    if (!q) return;
    memcpy(q + o->n, p, n);
    o->b = q, o->n += n;
}

static int keep(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    (void)err;
    add(ctx, rec->v, rec->n * sizeof *rec->v);
    add(ctx, rec->class_fuel_rate_gps, wf_sim_scenario(sim)->n_classes * sizeof(double));
    return 0;
}

static int keep_trips(void *ctx, const WfSim *sim, const WfTrip *t, size_t n, WfError *err)
{
    (void)sim, (void)err;
    for (size_t k = 0; k < n; k++) {
        double d[] = {(double)t[k].serial, t[k].t_entry_s, t[k].t_exit_s, t[k].fuel_g, t[k].dist_m, t[k].stops};
        add(ctx, d, sizeof d);
    }
    return 0;
}

/* The law a step's commands come from: IDM's acceleration (ring) or acc's set speed (corridor). */
typedef enum { LAW_IDM, LAW_SET_SPEED } Law;

/* The run of text with sets; when `law` commands group 1, every step is preceded by its observation and
 * commands. The final positions and speeds are appended to the log. */
static int run(const char *text, const char *const *sets, size_t n_set, int commanded, Law law, Bytes *log,
               long *commands)
{
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfError err = {0};
    WfOutput out = {.record = keep, .trips = keep_trips, .ctx = log};
    int rc = wf_scenario_load_text("external.yaml", text, sets, n_set, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_begin(sim, &out, &err);
    double idm[WF_MAX_MODEL_PARAMS];
    for (size_t k = 0; k < wf_cf_idm.n_spec; k++) *wf_param_ptr(idm, &wf_cf_idm.spec[k]) = wf_cf_idm.spec[k].def;
    double *obs = NULL, *u = NULL;
    while (!rc && !wf_sim_done(sim)) {
        if (commanded) {
            size_t n = wf_sim_group_size(sim, 1);
            obs = realloc(obs, (3 * n + 1) * sizeof *obs), u = realloc(u, (n + 1) * sizeof *u);
            rc = wf_sim_observe(sim, 1, obs, n, &err);
            for (size_t k = 0; !rc && k < n; k++)
                u[k] = law == LAW_IDM ? wf_cf_idm.accel(idm, NULL, obs[3 * k + 2], obs[3 * k], obs[3 * k + 1]) : 24.0;
            if (!rc) rc = wf_sim_set_actions(sim, 1, u, n, &err);
            *commands += (long)n;
        }
        if (!rc) rc = wf_sim_step(sim, 1, &err);
    }
    if (rc) printf("  %s\n", err.msg);
    if (!rc && wf_sim_fleet(sim)) {
        add(log, wf_sim_fleet(sim)->x_m, wf_sim_fleet(sim)->n * sizeof(double));
        add(log, wf_sim_fleet(sim)->v_mps, wf_sim_fleet(sim)->n * sizeof(double));
    }
    free(obs), free(u);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

static const char *ring =
    "seed: 11\nroad: {length_m: 600}\ntime: {duration_s: 120, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 10}\n"
    "fleet:\n  vehicles: 30\n  placement: interleaved\n  classes:\n    - {class: midsize_sedan, fraction: 1.0}\n"
    "  drivers:\n    - {model: idm, fraction: 0.8, noise_mps2: 0.3}\n    - {model: idm, fraction: 0.2, noise_mps2: 0.3}\n"
    "initial: {state: rest, jitter_m: 0.5}\n";

static void test_ring_idm_commands(void)
{
    const char *ext[] = {"fleet.drivers[1].model=external"};
    Bytes a = {0}, b = {0};
    long na = 0, nb = 0;
    CHECK(run(ring, NULL, 0, 0, LAW_IDM, &a, &na) == 0, "IDM run failed");
    CHECK(run(ring, ext, 1, 1, LAW_IDM, &b, &nb) == 0, "commanded run failed");
    CHECK(a.n > 0 && a.n == b.n && !memcmp(a.b, b.b, a.n), "commanded IDM differs from IDM (%zu vs %zu bytes)", b.n,
          a.n);
    CHECK(nb == 6 * 1201, "%ld commands, expected 6 vehicles x (1200 steps + the final record)", nb);
    printf("  ring: %ld commands; %zu bytes of records and final state identical to IDM's\n", nb, a.n);
    free(a.b), free(b.b);
}

static const char *corridor =
    "seed: 5\nroad: {type: corridor, length_m: 3000}\n"
    "time: {duration_s: 400, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 20}\n"
    "fleet:\n  placement: interleaved\n  classes:\n    - {class: midsize_suv, fraction: 1.0}\n"
    "  drivers:\n    - {model: idm, fraction: 0.7, noise_mps2: 0.2}\n"
    "    - {model: acc, fraction: 0.3, params: {v0_mps: 24}}\n"
    "corridor:\n  inflow: {flow_vph: 1800, arrivals: poisson}\n  outflow: {type: speed, speed_mps: 15}\n";

static void test_corridor_set_speed(void)
{
    const char *ext[] = {"fleet.drivers[1].model=external_speed"};
    Bytes a = {0}, b = {0};
    long na = 0, nb = 0;
    CHECK(run(corridor, NULL, 0, 0, LAW_SET_SPEED, &a, &na) == 0, "acc run failed");
    CHECK(run(corridor, ext, 1, 1, LAW_SET_SPEED, &b, &nb) == 0, "commanded run failed");
    CHECK(a.n > 0 && a.n == b.n && !memcmp(a.b, b.b, a.n), "commanded set speed differs from acc (%zu vs %zu bytes)",
          b.n, a.n);
    CHECK(nb > 1000, "only %ld commands", nb);
    printf("  corridor: %ld commands; %zu bytes of records and trips identical to acc's\n", nb, a.n);
    free(a.b), free(b.b);
}

static void test_refusals(void)
{
    const char *ext[] = {"fleet.drivers[1].model=external"};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfError err = {0};
    int rc = wf_scenario_load_text("external.yaml", ring, ext, 1, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        double u[6] = {0, 0, 0, 0, 0, 0}, obs[18];
        CHECK(wf_sim_group_size(sim, 1) == 6 && wf_sim_group_size(sim, 0) == 24 && wf_sim_group_size(sim, 7) == 0,
              "group sizes %zu %zu", wf_sim_group_size(sim, 0), wf_sim_group_size(sim, 1));
        CHECK(wf_sim_set_actions(sim, 0, u, 6, &err) == WF_EINPUT && strstr(err.msg, "takes no commands"),
              "a human group took commands: %s", err.msg);
        CHECK(wf_sim_set_actions(sim, 1, u, 5, &err) == WF_EINPUT && strstr(err.msg, "6 vehicles"), "count: %s",
              err.msg);
        CHECK(wf_sim_observe(sim, 2, obs, 6, &err) == WF_EINPUT && strstr(err.msg, "no driver group 2"), "group: %s",
              err.msg);
        u[3] = INFINITY;
        CHECK(wf_sim_set_actions(sim, 1, u, 6, &err) == WF_EINPUT && strstr(err.msg, "command 3 is inf"), "inf: %s",
              err.msg);
        /* Observations: at rest, every gap is the ring's spacing minus a length (jitter aside). */
        CHECK(wf_sim_observe(sim, 1, obs, 6, &err) == 0, "%s", err.msg);
        for (size_t k = 0; k < 6; k++)
            CHECK(obs[3 * k] == 0.0 && obs[3 * k + 1] == 0.0 && fabs(obs[3 * k + 2] - (20.0 - 4.9)) < 1.01,
                  "vehicle %zu: v %g, v_lead %g, gap %g", k, obs[3 * k], obs[3 * k + 1], obs[3 * k + 2]);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
}

/* The group's rows are its vehicles in ring order, each with its own inputs (from the fleet's arrays here), and
 * command k goes to row k's vehicle: after distinct commands and one step, each speed changed by its command. */
static void test_ring_rows_in_order(void)
{
    /* the commanded vehicles without noise (the humans keep theirs): a command is then the step's acceleration */
    const char *ext[] = {"fleet.drivers[1].model=external", "fleet.drivers[1].noise_mps2=0"};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfError err = {0};
    int rc = wf_scenario_load_text("external.yaml", ring, ext, 2, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_begin(sim, NULL, &err);
    double u[6], obs[18], v0[6];
    for (int s = 0; !rc && s < 400; s++) { /* noise and distinct commands: every vehicle's state its own */
        for (size_t k = 0; k < 6; k++) u[k] = 0.2 + 0.05 * (double)k - (s > 200 ? 0.3 : 0.0);
        rc = wf_sim_set_actions(sim, 1, u, 6, &err);
        if (!rc) rc = wf_sim_step(sim, 1, &err);
    }
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        const WfFleet *f = wf_sim_fleet(sim);
        size_t member[6], m = 0, bad = 0;
        for (size_t i = 0; i < f->n && m < 6; i++)
            if (f->group_id[i] == 1) member[m++] = i;
        CHECK(m == 6, "%zu members", m);
        rc = wf_sim_observe(sim, 1, obs, 6, &err);
        for (size_t k = 0; !rc && k < m; k++) {
            size_t i = member[k], l = (i + 1) % f->n;
            double gap = f->x_m[l] + (l < i ? 600.0 : 0.0) - sc->classes[0].length_m - f->x_m[i];
            bad += obs[3 * k] != f->v_mps[i] || obs[3 * k + 1] != f->v_mps[l] || fabs(obs[3 * k + 2] - gap) > 1e-9;
            v0[k] = f->v_mps[i];
            u[k] = 0.1 * (double)k - 0.2;
        }
        CHECK(bad == 0, "%zu of 6 rows are not their vehicle's inputs in ring order", bad);
        if (!rc) rc = wf_sim_set_actions(sim, 1, u, 6, &err);
        if (!rc) rc = wf_sim_step(sim, 1, &err);
        for (size_t k = 0; !rc && k < m; k++)
            CHECK(fabs(f->v_mps[member[k]] - v0[k] - u[k] * 0.1) < 1e-12, "row %zu: speed %.17g -> %.17g, command %g",
                  k, v0[k], f->v_mps[member[k]], u[k]);
        CHECK(rc == 0, "%s", err.msg);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
}

/* An RL batch over two such rings: its steps are not added to the runs' wall times, and it may be destroyed after
 * its runs (include/wavefuel/rl.h; VectorEnv replaces its environments' runs before rebuilding its batch): under
 * make sanitize, a destroy that touched the runs fails here. */
static void test_rl_batch_lifetime(void)
{
    const char *ext[] = {"fleet.drivers[1].model=external"};
    WfScenario *sc = NULL;
    WfSim *sims[2] = {NULL, NULL};
    WfRlBatch *b = NULL;
    WfError err = {0}, errs[2] = {{0}, {0}};
    int rc = wf_scenario_load_text("external.yaml", ring, ext, 1, &sc, &err);
    for (int k = 0; !rc && k < 2; k++) {
        rc = wf_sim_create(sc, &sims[k], &err);
        if (!rc) rc = wf_sim_begin(sims[k], NULL, &err);
        if (!rc) rc = wf_sim_step(sims[k], 10, &err);
    }
    const size_t group[2] = {1, 1};
    const WfRlReward rw = {.scope_all = 1, .w_fuel = 1.0, .gap_min_m = 5.0, .gap_max_m = 60.0, .w_gap = 1.0};
    if (!rc) rc = wf_rl_batch_create(sims, 2, group, &rw, 1, 0.1, &b, &err);
    double wall0 = rc ? 0.0 : wf_sim_wall_s(sims[0]), u[12] = {0}, obs[36], reward[2], info[2 * WF_RL_N_INFO];
    for (int a = 0; !rc && a < 50; a++) rc = wf_rl_batch_step(b, u, 1, obs, reward, info, errs);
    CHECK(rc == 0, "%s %s %s", err.msg, errs[0].msg, errs[1].msg);
    if (!rc) CHECK(wf_sim_wall_s(sims[0]) == wall0, "the batch's steps were timed: %g -> %g s", wall0,
                   wf_sim_wall_s(sims[0]));
    for (int k = 0; k < 2; k++) wf_sim_destroy(&sims[k]);
    wf_rl_batch_destroy(&b); /* after its runs */
    CHECK(b == NULL, "batch not released");
    wf_scenario_destroy(&sc);
}

/* The commands' bounds (wf_rl_batch_set_bounds): refused when low > high or NaN (the bounds kept), an infinite
 * command clipped to them and stepped where without bounds it is refused, and NULL removing them. */
static void test_rl_batch_bounds(void)
{
    const char *ext[] = {"fleet.drivers[1].model=external"};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfRlBatch *b = NULL;
    WfError err = {0}, e1 = {0}, e2 = {0}, errs[1] = {{0}};
    int rc = wf_scenario_load_text("external.yaml", ring, ext, 1, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_begin(sim, NULL, &err);
    const size_t group[1] = {1};
    const WfRlReward rw = {.scope_all = 1, .w_fuel = 1.0, .gap_min_m = 5.0, .gap_max_m = 60.0, .w_gap = 1.0};
    if (!rc) rc = wf_rl_batch_create(&sim, 1, group, &rw, 1, 0.1, &b, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (rc) return;
    size_t m = wf_rl_batch_rows(b);
    double low[64], high[64], u[64], obs[192], reward[1], info[WF_RL_N_INFO];
    for (size_t j = 0; j < m && j < 64; j++) low[j] = -1.0, high[j] = 0.5, u[j] = INFINITY;
    high[m - 1] = -2.0;
    int bad_order = wf_rl_batch_set_bounds(b, low, high, &e1);
    high[m - 1] = 0.5, low[0] = NAN;
    int bad_nan = wf_rl_batch_set_bounds(b, low, high, &e2);
    int unbounded = wf_rl_batch_step(b, u, 1, obs, reward, info, errs); /* both refused: still no bounds */
    low[0] = -1.0;
    int ok = wf_rl_batch_set_bounds(b, low, high, &err) || wf_rl_batch_step(b, u, 1, obs, reward, info, errs);
    int removed = wf_rl_batch_set_bounds(b, NULL, NULL, &err);
    if (!removed) removed = wf_rl_batch_step(b, u, 1, obs, reward, info, errs);
    CHECK(bad_order == WF_EINPUT && strstr(e1.msg, "bounds [-1, -2]") && bad_nan == WF_EINPUT &&
          strstr(e2.msg, "command 0's bounds [nan, 0.5]") && unbounded == WF_EINPUT && ok == 0 &&
          removed == WF_EINPUT && strstr(errs[0].msg, "is inf"),
          "order %d (%s), NaN %d (%s), unbounded %d, bounded %d, removed %d (%s)", bad_order, e1.msg, bad_nan, e2.msg,
          unbounded, ok, removed, errs[0].msg);
    wf_rl_batch_destroy(&b);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
}

/* Runs side by side in one batch (b) and their twins, each alone in a batch of its own (one[k]): the same scenario
 * sc[k] for both. Owned; twins_free releases them. */
enum { TWINS_MAX = 8 };
typedef struct Twins {
    int         n;
    WfScenario *sc[TWINS_MAX];
    WfSim      *sims[TWINS_MAX], *alone[TWINS_MAX];
    WfRlBatch  *b, *one[TWINS_MAX];
} Twins;

/* Run k and its twin: the scenario `ring` with overrides sets[0 .. n_sets), begun and stepped `steps` steps. */
static int twin_runs(Twins *t, int k, const char *const *sets, size_t n_sets, long steps, WfError *err)
{
    int rc = wf_scenario_load_text("external.yaml", ring, sets, n_sets, &t->sc[k], err);
    for (int copy = 0; copy < 2 && !rc; copy++) {
        WfSim **s = copy ? &t->alone[k] : &t->sims[k];
        rc = wf_sim_create(t->sc[k], s, err);
        if (!rc) rc = wf_sim_begin(*s, NULL, err);
        if (!rc) rc = wf_sim_step(*s, steps, err);
    }
    return rc;
}

/* The batch of every run's group 1 and each twin's own, an action of one step of 0.1 s. */
static int twin_batches(Twins *t, const WfRlReward *rw, WfError *err)
{
    size_t group[TWINS_MAX] = {1, 1, 1, 1, 1, 1, 1, 1};
    int rc = wf_rl_batch_create(t->sims, (size_t)t->n, group, rw, 1, 0.1, &t->b, err);
    for (int k = 0; !rc && k < t->n; k++) rc = wf_rl_batch_create(&t->alone[k], 1, group, rw, 1, 0.1, &t->one[k], err);
    return rc;
}

static void twins_free(Twins *t)
{
    wf_rl_batch_destroy(&t->b);
    for (int k = 0; k < t->n; k++) {
        wf_rl_batch_destroy(&t->one[k]);
        wf_sim_destroy(&t->sims[k]);
        wf_sim_destroy(&t->alone[k]);
        wf_scenario_destroy(&t->sc[k]);
    }
}

/* The blocks of two runs' state (as a checkpoint saves them) that differ, 1 more when their lists do. */
static size_t state_differs(WfSim *a, WfSim *b)
{
    WfStateVar va[WF_MAX_STATE_VARS], vb[WF_MAX_STATE_VARS];
    size_t na = wf_sim_state(a, va, WF_MAX_STATE_VARS), nb = wf_sim_state(b, vb, WF_MAX_STATE_VARS), bad = na != nb;
    for (size_t j = 0; j < na && j < nb; j++)
        bad += va[j].size != vb[j].size || memcmp(va[j].data, vb[j].data, va[j].size);
    return bad;
}

/* Rings side by side across their statistics windows' opening: four rings of PI-with-saturation drivers (memory the
 * steps advance) and automated vehicles, whose windows open at steps 600, 600, 600 and 150 (time.warmup_s), stepped
 * in one batch on two threads from step 5 to 1005 against each alone: side by side while every window is closed
 * (RingEnv's runs: their windows open after the episode), one by one while they differ and at each opening, side by
 * side again once all are open; every observation, reward and info, then every block of the runs' state and their
 * summaries, the same bits. */
static void test_rl_batch_side_by_side_windows(void)
{
    enum { R = 4, M = 6, ACTS = 1000 };
    Twins t = {.n = R};
    WfError err = {0}, errs[R];
    const WfRlReward rw = {.w_fuel = 1.0, .gap_min_m = 5.0, .gap_max_m = 60.0, .w_gap = 1.0, .w_accel = 0.1};
    int rc = 0;
    for (int k = 0; !rc && k < R; k++) {
        char seed[64], warm[64];
        snprintf(seed, sizeof seed, "seed=%d", 60 + k);
        snprintf(warm, sizeof warm, "time.warmup_s=%d", k < 3 ? 60 : 15);
        /* PI with saturation keeps memory that each step advances: the gang gives it back after every call */
        const char *sets[] = {"fleet.drivers[1].model=external", "fleet.drivers[0].model=pi_saturation", seed, warm};
        rc = twin_runs(&t, k, sets, 4, 5, &err);
    }
    if (!rc) rc = twin_batches(&t, &rw, &err);
    double u[R * M], obs[R * M * 3], reward[R], info[R * WF_RL_N_INFO], o1[M * 3], r1, i1[WF_RL_N_INFO];
    size_t bad = 0;
    long gang[3] = {0, 0, 0}; /* side by side: windows all closed, some open, all open */
    for (int a = 0; !rc && a < ACTS; a++) {
        for (int j = 0; j < R * M; j++) u[j] = 1.5 * sin(0.11 * a + j);
        long before = wf_rl_batch_gang_calls(t.b);
        rc = wf_rl_batch_step(t.b, u, 2, obs, reward, info, errs);
        long step = wf_sim_steps_done(t.sims[0]);
        gang[step <= 150 ? 0 : step <= 600 ? 1 : 2] += wf_rl_batch_gang_calls(t.b) - before;
        for (int k = 0; !rc && k < R; k++) {
            rc = wf_rl_batch_step(t.one[k], u + k * M, 1, o1, &r1, i1, &err);
            bad += memcmp(o1, obs + k * M * 3, sizeof o1) || memcmp(&r1, reward + k, sizeof r1) ||
                   memcmp(i1, info + k * WF_RL_N_INFO, sizeof i1);
        }
    }
    CHECK(rc == 0, "%s %s", err.msg, errs[0].msg);
    for (int k = 0; !rc && k < R; k++) {
        bad += state_differs(t.sims[k], t.alone[k]);
        WfError fin = {0};
        wf_sim_finish(t.sims[k], &fin), wf_sim_finish(t.alone[k], &fin);
        bad += memcmp(wf_sim_summary(t.sims[k]), wf_sim_summary(t.alone[k]), sizeof(WfSummary)) != 0;
    }
    CHECK(!rc && bad == 0 && gang[0] > 100 && gang[1] == 0 && gang[2] > 300,
          "%zu differences; side by side %ld / %ld / %ld actions (windows closed / mixed / open)", bad, gang[0],
          gang[1], gang[2]);
    printf("  %d rings, %d actions: side by side %ld with the windows closed, %ld mixed, %ld open\n", R, ACTS, gang[0],
           gang[1], gang[2]);
    twins_free(&t);
}

/* Rings stepped side by side (src/core/gang.c): five such rings of different seeds and lengths in one batch on two
 * threads against each alone in a batch of its own (stepped by the engine one run at a time): every observation,
 * reward and info, every block of the final state and the summaries, bit for bit; the actions cross records (the batch
 * then steps them one by one) and drive one ring's automated vehicles into their leaders (overlap repairs in the
 * shared blocks); one command refused inside the shared blocks. Under make tsan, the shared blocks' parallel region. */
static void test_rl_batch_side_by_side(void)
{
    enum { R = 5, M = 6, ACTS = 400 };
    Twins t = {.n = R};
    WfSim **sims = t.sims, **alone = t.alone;
    WfError err = {0}, errs[R];
    const WfRlReward rw = {.w_fuel = 1.0, .gap_min_m = 5.0, .gap_max_m = 60.0, .w_gap = 1.0, .w_accel = 0.1};
    int rc = 0;
    for (int k = 0; !rc && k < R; k++) {
        char seed[64], len[64];
        snprintf(seed, sizeof seed, "seed=%d", 40 + k);
        snprintf(len, sizeof len, "road.length_m=%d", 560 + 17 * k);
        const char *sets[] = {"fleet.drivers[1].model=external", seed, len};
        rc = twin_runs(&t, k, sets, 3, 105, &err); /* past the warm-up: the statistics window is open */
    }
    if (!rc) rc = twin_batches(&t, &rw, &err);
    double u[R * M], obs[R * M * 3], reward[R], info[R * WF_RL_N_INFO], o1[M * 3], r1, i1[WF_RL_N_INFO];
    size_t bad = 0;
    /* At action REFUSE (side by side, as the one before it) ring 2's first command is infinite: refused, that ring
     * not stepped (its twin neither), the others stepped; the call fails and returns no observation. */
    enum { REFUSE = 211 };
    long gang_before = 0;
    int refused = 0;
    for (int a = 0; !rc && a < ACTS; a++) {
        for (int j = 0; j < R * M; j++) u[j] = j < M ? 3.0 : sin(0.37 * a + j);
        if (a == REFUSE - 1) gang_before = wf_rl_batch_gang_calls(t.b);
        if (a == REFUSE) u[2 * M] = INFINITY;
        rc = wf_rl_batch_step(t.b, u, 2, obs, reward, info, errs);
        if (a == REFUSE) refused = rc == WF_EINPUT && errs[2].code && !errs[1].code, rc = 0;
        for (int k = 0; !rc && k < R; k++) {
            rc = wf_rl_batch_step(t.one[k], u + k * M, 1, o1, &r1, i1, &err);
            if (a == REFUSE) {
                refused &= (rc != 0) == (k == 2), rc = 0;
                continue;
            }
            bad += memcmp(o1, obs + k * M * 3, sizeof o1) || memcmp(&r1, reward + k, sizeof r1) ||
                   memcmp(i1, info + k * WF_RL_N_INFO, sizeof i1);
        }
    }
    CHECK(rc == 0, "%s %s", err.msg, errs[0].msg);
    CHECK(refused && wf_rl_batch_gang_calls(t.b) > gang_before + 1,
          "action %d: ring 2's infinite command not refused alone, or actions %d and %d not side by side", REFUSE,
          REFUSE - 1, REFUSE);
    /* Every block of the runs' state, as a checkpoint saves it (the stop modes and statistics sums the gang holds
     * until asked included), then each run's summary once ended by the caller (its statistics), the first ring's
     * with the batch still alive, the others' after it is gone */
    for (int k = 0; !rc && k < R; k++)
        bad += state_differs(sims[k], alone[k]) + (wf_sim_steps_done(sims[k]) != 105 + ACTS - (k == 2)) +
               (wf_sim_steps_done(sims[k]) != wf_sim_steps_done(alone[k]));
    long gang = rc ? 0 : wf_rl_batch_gang_calls(t.b), repaired = 0;
    for (int k = 0; !rc && k < R; k++) repaired += wf_rl_batch_gang_calls(t.one[k]);
    /* every automated vehicle brakes to a stop (the stopped time counts every step), the last action side by side:
     * what the gang holds is again newer than the rings' arrays */
    for (int j = 0; j < R * M; j++) u[j] = -3.0;
    for (long a = 0, before = 0; !rc && (a < 60 || wf_rl_batch_gang_calls(t.b) == before); a++) {
        before = wf_rl_batch_gang_calls(t.b);
        rc = wf_rl_batch_step(t.b, u, 2, obs, reward, info, errs);
        for (int k = 0; !rc && k < R; k++) rc = wf_rl_batch_step(t.one[k], u + k * M, 1, o1, &r1, i1, &err);
    }
    WfSummary sum[R], twin[R];
    for (int k = 0; !rc && k < R; k++) { /* ended by the caller: WF_EINTR, the summary written */
        WfError fin = {0};
        if (k == 1) wf_rl_batch_destroy(&t.b);
        wf_sim_finish(sims[k], &fin), wf_sim_finish(alone[k], &fin);
        sum[k] = *wf_sim_summary(sims[k]), twin[k] = *wf_sim_summary(alone[k]);
        bad += memcmp(&sum[k], &twin[k], sizeof sum[k]) != 0 || !(sum[k].time_stopped_share > 0.0);
    }
    CHECK(!rc && bad == 0 && gang > ACTS / 2 && gang < ACTS && repaired == 0 && sum[0].overlaps > 0,
          "%zu differences; %ld of %d actions side by side (%ld by batches of one); ring 0 repaired %lld overlaps",
          bad, gang, ACTS, repaired, rc ? 0LL : (long long)sum[0].overlaps);
    printf("  %d rings, %d actions: %ld side by side, the others at records; ring 0: %lld overlaps repaired\n", R, ACTS,
           gang, rc ? 0LL : (long long)sum[0].overlaps);
    twins_free(&t);
}

int main(void)
{
    RUN(test_ring_idm_commands);
    RUN(test_rl_batch_lifetime);
    RUN(test_rl_batch_bounds);
    RUN(test_rl_batch_side_by_side);
    RUN(test_rl_batch_side_by_side_windows);
    RUN(test_ring_rows_in_order);
    RUN(test_corridor_set_speed);
    RUN(test_refusals);
    TEST_EXIT();
}
