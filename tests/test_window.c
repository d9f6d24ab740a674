/* Time-blocked stepping (time.block_steps, src/core/window.c) gives the bits of stepping one step at a time: final
 * positions, speeds, the complete checkpoint state (accumulators, modes, controller memory, safety counts) and every
 * time-series record, for windows of 2 to 37 steps, tiles of one block to the whole chunk, 1 and 2 threads, records
 * every step or every 3 steps (windows that start between records), a statistics window opening inside the run,
 * trajectories, a run stepped in pieces as Python steps it, and windows that must be undone and redone because a
 * vehicle overlapped inside them. Each run also reports how many windows it took, so a path that silently fell back
 * to one step at a time fails. Corridors (their windows when asked): every record, every trip and the whole
 * checkpoint state (Edie and detector sums, class totals, counters, unused slots) against one step at a time. */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "core/window.h"
#include "wf_test.h"

/* A graded ring of 5000 vehicles (20 blocks: two threads split it), three classes, a speed limit, noisy heterogeneous IDM with the feasible
 * clip, a controller with memory (PI with saturation) under a safety filter. */
static const char *ring_yaml =
    "seed: 11\n"
    "road:\n  length_m: 100000\n  speed_limit_mps: 24\n"
    "  grade: {points: [[0, 0.0], [20000, 0.02], [50000, 0.0], [70000, -0.02]]}\n"
    "time: {duration_s: 12, dt_s: 0.1, output_interval_s: 0.1, warmup_s: 3.3}\n"
    "fleet:\n  vehicles: 5000\n  placement: random\n"
    "  classes:\n    - {class: midsize_sedan, fraction: 0.5}\n    - {class: midsize_suv, fraction: 0.3}\n"
    "    - {class: class8_tractor, fraction: 0.2}\n"
    "  drivers:\n"
    "    - {model: idm, fraction: 0.6, noise_mps2: 0.3, feasible_accel: clip,\n"
    "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
    "    - {model: idm, fraction: 0.3, noise_mps2: 0.2}\n"
    "    - {model: pi_saturation, fraction: 0.1, safety: {kind: gipps, gap_min_m: 6}}\n"
    "initial: {state: equilibrium, jitter_m: 0.5}\n";

/* Noise far beyond what the brakes absorb: overlaps in many windows. */
static const char *overlap_yaml =
    "seed: 7\nroad: {length_m: 60000}\ntime: {duration_s: 20, dt_s: 0.1, output_interval_s: 0.5}\n"
    "fleet:\n  vehicles: 5000\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
    "  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]\n"
    "initial: {state: equilibrium}\n";

/* A corridor with every part of its state a window touches (wf_test.h). */
static const char *corridor_yaml = WF_TEST_CORRIDOR_YAML;

/* Noise far beyond what the brakes absorb on a corridor: overlaps, and windows redone. */
static const char *corridor_overlap_yaml =
    "seed: 5\nroad: {type: corridor, length_m: 6000}\n"
    "time: {duration_s: 600, dt_s: 0.1, output_interval_s: 2.0}\n"
    "fleet:\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
    "  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]\n"
    "corridor:\n  inflow: {flow_vph: 3000}\n"
    "  outflow: {type: speed, points: [[0, 20], [200, 20], [260, 3], [600, 3]]}\n";

typedef struct Out {
    size_t n;
    double *x, *v;
    WfTsRow rows[128];          /* a ring's first records */
    size_t n_rows;
    WfTestVals vals;            /* every record's values and class fuel rates, then (a corridor) every trip's fields */
    size_t n_trips;
    unsigned char *state;
    size_t state_size;
    long windows, redone;
    long probes, switches;      /* the thread governor's (time.thread_check_steps) */
} Out;

static int keep_row(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    (void)err;
    Out *o = ctx;
    wf_test_keep(&o->vals, rec->v, rec->n);
    wf_test_keep(&o->vals, rec->class_fuel_rate_gps, wf_sim_scenario(sim)->n_classes);
    if (rec->n == WF_TS_N_COLS && o->n_rows < sizeof o->rows / sizeof o->rows[0]) {
        WfTsRow *row = &o->rows[o->n_rows++];
        WF_TEST_KEEP_RECORD(row, rec, wf_sim_scenario(sim)->n_classes);
    }
    return 0;
}

/* A corridor's trips, field by field, in the order they come. */
static int keep_trips(void *ctx, const WfSim *sim, const WfTrip *tr, size_t n, WfError *err)
{
    (void)sim, (void)err;
    Out *o = ctx;
    for (size_t k = 0; k < n; k++, o->n_trips++) wf_test_keep_trip(&o->vals, &tr[k]);
    return 0;
}

static void out_free(Out *o)
{
    free(o->x), free(o->v), free(o->state), free(o->vals.v);
    memset(o, 0, sizeof *o);
}

/* One run with the overrides; piece > 0: stepped piece steps at a time (wf_sim_step), as Python does. */
static int run(const char *path, const char *const *set, size_t n_set, int threads, long piece, Out *o)
{
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    memset(o, 0, sizeof *o);
    int rc = wf_scenario_load(path, set, n_set, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    WfOutput out = {.record = keep_row, .trips = keep_trips, .ctx = o};
    if (!rc && piece <= 0) rc = wf_sim_run(sim, &out, NULL, NULL, NULL, &err);
    if (!rc && piece > 0) {
        rc = wf_sim_begin(sim, &out, &err);
        while (!rc && !wf_sim_done(sim)) rc = wf_sim_step(sim, piece, &err);
    }
    if (rc) printf("  %s\n", err.msg);
    if (!rc) {
        const WfFleet *f = wf_sim_fleet(sim); /* a corridor's vehicles are in its state */
        o->n = f ? f->n : 0;
        o->x = malloc(o->n * sizeof(double) + 1);
        o->v = malloc(o->n * sizeof(double) + 1);
        if (f) memcpy(o->x, f->x_m, f->n * sizeof(double)), memcpy(o->v, f->v_mps, f->n * sizeof(double));
        o->state = wf_test_state_copy(sim, &o->state_size);
        wf_sim_window_stats(sim, &o->windows, &o->redone);
        wf_sim_thread_stats(sim, &o->probes, &o->switches);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

static void compare(const Out *o, const Out *ref, const char *what)
{
    CHECK(o->x && ref->x, "%s: a run failed", what);
    if (!o->x || !ref->x) return;
    CHECK(memcmp(o->x, ref->x, o->n * sizeof(double)) == 0, "%s: positions differ", what);
    CHECK(memcmp(o->v, ref->v, o->n * sizeof(double)) == 0, "%s: speeds differ", what);
    CHECK(o->vals.n == ref->vals.n && o->vals.n > 0 && memcmp(o->vals.v, ref->vals.v, o->vals.n * sizeof(double)) == 0,
          "%s: the records or trips differ (%zu values, reference %zu)", what, o->vals.n, ref->vals.n);
    CHECK(o->n_trips == ref->n_trips, "%s: %zu trips, reference %zu", what, o->n_trips, ref->n_trips);
    for (size_t r = 0; r < o->n_rows && r < ref->n_rows; r++)
        CHECK(memcmp(&o->rows[r], &ref->rows[r], sizeof o->rows[r]) == 0, "%s: record %zu (t = %g s) differs", what, r,
              ref->rows[r].v[WF_TS_T]);
    CHECK(o->state_size == ref->state_size && memcmp(o->state, ref->state, o->state_size) == 0,
          "%s: the checkpoint state (accumulators, modes, controller memory, safety counts) differs", what);
}

typedef struct Variant {
    const char *set[4];
    size_t n_set;
    int threads;
    long piece;
} Variant;

/* Every variant against the reference (one step at a time, one thread); returns the reference's last overlap count
 * and the variants' windows and redone windows (summed), and their thread governors' probes (summed) in *probes when
 * it is not NULL. */
static double compare_variants_probes(const char *text, const Variant *vs, size_t nv, const char *const *extra,
                                      size_t n_extra, long *windows, long *redone, long *probes)
{
    char dir[] = "/tmp/wf_test_window.XXXXXX", path[128];
    if (!wf_test_write_yaml(text, dir, path, sizeof path)) return -1;
    const char *set[8] = {"time.block_steps=1"};
    for (size_t j = 0; j < n_extra; j++) set[1 + j] = extra[j];
    Out ref, o;
    CHECK(run(path, set, 1 + n_extra, 1, 0, &ref) == 0, "reference run failed");
    CHECK(ref.windows == 0, "the reference took %ld windows", ref.windows);
    *windows = *redone = 0;
    if (probes) *probes = 0;
    for (size_t k = 0; k < nv; k++) {
        const char *vset[8];
        size_t n = 0;
        for (size_t j = 0; j < vs[k].n_set; j++) vset[n++] = vs[k].set[j];
        for (size_t j = 0; j < n_extra; j++) vset[n++] = extra[j];
        char what[256];
        snprintf(what, sizeof what, "%s %s%s, %d thread(s)%s", vs[k].set[0], vs[k].n_set > 1 ? vs[k].set[1] : "",
                 n_extra ? " (+ overrides)" : "", vs[k].threads, vs[k].piece ? ", stepped in pieces" : "");
        CHECK(run(path, vset, n, vs[k].threads, vs[k].piece, &o) == 0, "%s: run failed", what);
        compare(&o, &ref, what);
        CHECK(o.windows > 0, "%s: no window was taken", what);
        *windows += o.windows, *redone += o.redone;
        if (probes) *probes += o.probes;
        out_free(&o);
    }
    double overlaps = ref.n_rows ? ref.rows[ref.n_rows - 1].v[WF_TS_OVERLAPS] : -1;
    out_free(&ref);
    wf_test_remove_yaml(dir, path);
    return overlaps;
}

static double compare_variants(const char *text, const Variant *vs, size_t nv, const char *const *extra,
                               size_t n_extra, long *windows, long *redone)
{
    return compare_variants_probes(text, vs, nv, extra, n_extra, windows, redone, NULL);
}

static const Variant variants[] = {
    {{"time.block_steps=2", "time.tile_vehicles=256"}, 2, 1, 0},
    {{"time.block_steps=16"}, 1, 1, 0},
    {{"time.block_steps=16"}, 1, 2, 0},
    {{"time.block_steps=5", "time.tile_vehicles=1000"}, 2, 2, 0},
    {{"time.block_steps=37", "time.tile_vehicles=700"}, 2, 2, 0},
    {{"time.block_steps=16"}, 1, 2, 7},
};
#define N_VARIANTS (sizeof variants / sizeof *variants)

static void test_windows_bitwise_equal(void)
{
    long windows, redone;
    compare_variants(ring_yaml, variants, N_VARIANTS, NULL, 0, &windows, &redone);
    printf("  graded ring of 5000 vehicles, records every step: %ld windows, the same bits as one step at a time\n",
           windows);
    CHECK(redone == 0, "%ld windows redone without an overlap", redone);
}

/* Records every 3 steps (windows begin between records) and trajectories every 1.3 s (steps of their own). */
static void test_windows_records_and_trajectories(void)
{
    const char *extra[] = {"time.output_interval_s=0.3", "output.trajectories=true",
                           "output.trajectory_interval_s=1.3"};
    long windows, redone;
    compare_variants(ring_yaml, variants, N_VARIANTS, extra, 3, &windows, &redone);
    printf("  records every 3 steps, trajectories every 13: %ld windows, the same bits\n", windows);
    CHECK(redone == 0, "%ld windows redone without an overlap", redone);
}

/* Overlaps: the windows they fall in are undone and redone one step at a time, repairs included. */
static void test_windows_redone_on_overlap(void)
{
    long windows, redone;
    double overlaps = compare_variants(overlap_yaml, variants, N_VARIANTS, NULL, 0, &windows, &redone);
    printf("  noisy ring of 5000 vehicles: %.0f overlap events, %ld of %ld windows redone, the same bits\n", overlaps,
           redone, windows);
    CHECK(overlaps > 50, "only %.0f overlap events: the test would not exercise the redo", overlaps);
    CHECK(redone > 0 && redone < windows, "%ld of %ld windows redone", redone, windows);
}

/* The thread governor probing as often as it can (time.thread_check_steps: 1) switches a ring's threads between
 * windows and between single steps (records every 3 steps): the same bits, and the switches happened. */
static void test_windows_governed(void)
{
    static const Variant governed[] = {
        {{"time.block_steps=16", "time.thread_check_steps=1"}, 2, 2, 0},
        {{"time.block_steps=5", "time.thread_check_steps=1"}, 2, 2, 0},
    };
    const char *extra[] = {"time.output_interval_s=0.3"};
    long windows, redone, probes;
    compare_variants_probes(ring_yaml, governed, 2, extra, 1, &windows, &redone, &probes);
    printf("  the governor probing as often as it can: %ld probes in %ld windows, the same bits\n", probes, windows);
    /* 120 steps a run: a probe after the first window, then at most 64 steps apart */
    CHECK(probes >= 4, "only %ld probes: the threads hardly changed", probes);
}

/* A ring's default window: 64 steps, or 16 records' worth when records come more often than every 4 steps (the
 * window keeps each record's block sums), as docs/scenarios.md says. */
static void test_default_steps(void)
{
    static const long out_every[] = {1, 2, 3, 4, 10, 1000};
    static const int expect[] = {16, 32, 48, 64, 64, 64};
    for (size_t j = 0; j < sizeof expect / sizeof *expect; j++)
        CHECK(wf_window_steps_default(out_every[j]) == expect[j], "records every %ld steps: windows of %d steps, "
              "expected %d", out_every[j], wf_window_steps_default(out_every[j]), expect[j]);
}

/* Corridors: the front part, the windowed interior and the entrance give the per-step path's records, trips, Edie
 * cells, detector sums and state, bit for bit; records every 3 steps (windows of 2) too. */
static void test_corridor_windows(void)
{
    long windows, redone;
    compare_variants(corridor_yaml, variants, N_VARIANTS, NULL, 0, &windows, &redone);
    printf("  corridor of 12 km: %ld windows (%ld redone), the same bits as one step at a time\n", windows, redone);
    const char *extra[] = {"time.output_interval_s=0.3"};
    compare_variants(corridor_yaml, variants, N_VARIANTS, extra, 1, &windows, &redone);
    printf("  records every 3 steps: %ld windows, the same bits\n", windows);
}

static void test_corridor_windows_redone(void)
{
    long windows, redone;
    compare_variants(corridor_overlap_yaml, variants, N_VARIANTS, NULL, 0, &windows, &redone);
    printf("  noisy corridor: %ld of %ld windows redone, the same bits\n", redone, windows);
    CHECK(redone > 0 && redone < windows, "%ld of %ld windows redone", redone, windows);
}

int main(void)
{
    RUN(test_windows_bitwise_equal);
    RUN(test_windows_records_and_trajectories);
    RUN(test_windows_redone_on_overlap);
    RUN(test_windows_governed);
    RUN(test_default_steps);
    RUN(test_corridor_windows);
    RUN(test_corridor_windows_redone);
    TEST_EXIT();
}
