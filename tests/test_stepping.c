/* A run taken a piece at a time (wf_sim_begin, wf_sim_step, wf_sim_finish: the interface external controllers and
 * the Python package step through) gives the bits of wf_sim_run, whatever the pieces: every record, every trip,
 * the summary and the complete state (the blocks a checkpoint saves), on a ring with a controller with memory and
 * noise, and on a corridor with queues, trips and Edie fields. And the rules around it: the end comes once, with
 * the final instant's record; no step after it; a run ended early by the caller says so (WF_EINTR) and keeps its
 * state. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

/* Everything a run hands its output, as bytes in call order. */
typedef struct Log {
    unsigned char *b;
    size_t         n, cap;
    long           records, trips, ends;
} Log;

static int put(Log *l, const void *p, size_t n, WfError *err)
{
    if (l->n + n > l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 1 << 16;
        while (cap < l->n + n) cap *= 2;
        unsigned char *q = realloc(l->b, cap);
        if (!q) return wf_err(err, WF_ESYS, "test: out of memory");
        l->b = q, l->cap = cap;
    }
    memcpy(l->b + l->n, p, n);
    l->n += n;
    return 0;
}

static int log_record(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    Log *l = ctx;
    l->records++;
    return put(l, rec->v, rec->n * sizeof *rec->v, err) ||
           put(l, rec->class_fuel_rate_gps, wf_sim_scenario(sim)->n_classes * sizeof(double), err);
}

/* Field by field: the struct's padding is not part of a result. */
static int log_trips(void *ctx, const WfSim *sim, const WfTrip *t, size_t n, WfError *err)
{
    (void)sim;
    Log *l = ctx;
    int rc = 0;
    for (size_t k = 0; !rc && k < n; k++) {
        double d[] = {(double)t[k].serial, t[k].class_id, t[k].group_id, t[k].completed, t[k].t_arrival_s,
                      t[k].t_entry_s, t[k].t_exit_s, t[k].v_entry_mps, t[k].fuel_g, t[k].dist_m, t[k].time_stopped_s,
                      t[k].stops, t[k].hard_brakes, t[k].infeasible_steps};
        rc = put(l, d, sizeof d, err);
        l->trips++;
    }
    return rc;
}

static int log_end(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    (void)sim, (void)reason;
    Log *l = ctx;
    l->ends++;
    return put(l, &completed, sizeof completed, err);
}

/* The state blocks and the summary, appended to the log. */
static void log_state(Log *l, WfSim *sim)
{
    WfStateVar vars[WF_MAX_STATE_VARS];
    WfError err = {0};
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS);
    for (size_t k = 0; k < nv; k++) put(l, vars[k].data, vars[k].size, &err);
    put(l, wf_sim_summary(sim), sizeof(WfSummary), &err);
}

/* The run of `path` (with sets) in pieces of `piece` steps (0: wf_sim_run), logged. Returns the status. */
static int run(const char *path, const char *const *sets, size_t n_set, long piece, Log *l)
{
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfError err = {0};
    WfOutput out = {.record = log_record, .trips = log_trips, .end = log_end, .ctx = l};
    int rc = wf_scenario_load(path, sets, n_set, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc && !piece) rc = wf_sim_run(sim, &out, NULL, NULL, NULL, &err);
    if (!rc && piece) {
        rc = wf_sim_begin(sim, &out, &err);
        while (!rc && !wf_sim_done(sim)) rc = wf_sim_step(sim, piece, &err);
    }
    if (rc) printf("  %s (pieces of %ld): %s\n", path, piece, err.msg);
    if (!rc) {
        CHECK(wf_sim_time_s(sim) == sc->duration_s, "%s: ended at t = %g s", path, wf_sim_time_s(sim));
        CHECK(wf_sim_step(sim, 1, &err) == WF_EINPUT && strstr(err.msg, "no step is left"),
              "a step after the end: %s", err.msg);
        log_state(l, sim);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

static void same_in_pieces(const char *path, const char *const *sets, size_t n_set)
{
    Log ref = {0};
    CHECK(run(path, sets, n_set, 0, &ref) == 0, "%s: wf_sim_run failed", path);
    const long pieces[] = {1, 7, 1000, 1L << 40};
    for (size_t k = 0; k < sizeof pieces / sizeof pieces[0]; k++) {
        Log l = {0};
        CHECK(run(path, sets, n_set, pieces[k], &l) == 0, "%s: stepping failed", path);
        CHECK(l.ends == 1 && ref.ends == 1, "%s: %ld ends", path, l.ends);
        CHECK(l.records == ref.records && l.trips == ref.trips && l.n == ref.n && !memcmp(l.b, ref.b, l.n),
              "%s, pieces of %ld steps: %ld records, %ld trips, %zu bytes differ from wf_sim_run's %ld, %ld, %zu",
              path, pieces[k], l.records, l.trips, l.n, ref.records, ref.trips, ref.n);
        free(l.b);
    }
    printf("  %s: %ld records, %ld trips, %zu bytes: the same in pieces of 1, 7, 1000 steps and in one\n", path,
           ref.records, ref.trips, ref.n);
    free(ref.b);
}

static void test_ring_in_pieces(void)
{
    /* PI with saturation keeps per-vehicle memory; the fleet has noise. */
    const char *sets[] = {"fleet.drivers[0].model=pi_saturation", "road.length_m=400", "time.duration_s=60"};
    same_in_pieces("tests/data/tiny_ring.yaml", sets, 3);
}

static void test_corridor_in_pieces(void)
{
    const char *sets[] = {"time.duration_s=700"};
    same_in_pieces("tests/data/corridor_resume.yaml", sets, 1);
}

/* Ended by the caller: WF_EINTR with the reason, the output ended as incomplete, nothing more to step. */
static void test_finish_early(void)
{
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfError err = {0};
    Log l = {0};
    WfOutput out = {.record = log_record, .end = log_end, .ctx = &l};
    int rc = wf_scenario_load("tests/data/tiny_ring.yaml", NULL, 0, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_begin(sim, &out, &err);
    if (!rc) rc = wf_sim_step(sim, 25, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        CHECK(wf_sim_time_s(sim) == 25 * sc->dt_s && !wf_sim_done(sim), "t = %g s", wf_sim_time_s(sim));
        CHECK(wf_sim_begin(sim, &out, &err) == WF_EINPUT, "a second begin was accepted");
        rc = wf_sim_finish(sim, &err);
        int completed = -1;
        if (l.n >= sizeof completed) memcpy(&completed, l.b + l.n - sizeof completed, sizeof completed);
        CHECK(rc == WF_EINTR && strstr(err.msg, "stopped by the caller") && wf_sim_done(sim) && l.ends == 1 &&
                  completed == 0,
              "finish: rc %d, '%s', %ld ends, completed %d", rc, err.msg, l.ends, completed);
        CHECK(wf_sim_finish(sim, &err) == 0 && l.ends == 1, "a second finish ended the output again");
        CHECK(wf_sim_step(sim, 1, &err) == WF_EINPUT, "a step after finish was accepted");
    }
    free(l.b);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
}

int main(void)
{
    RUN(test_ring_in_pieces);
    RUN(test_corridor_in_pieces);
    RUN(test_finish_early);
    TEST_EXIT();
}
