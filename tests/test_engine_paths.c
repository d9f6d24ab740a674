/* The engine's execution paths give the same bits: the fused one-pass step and the multi-pass step, on 1 and 2
 * threads, final state and every time-series record, with noise, heterogeneous drivers (per-vehicle parameters)
 * beside homogeneous ones (one shared parameter set, IDM's block kernel), three classes, a controller with memory
 * (PI with saturation) and a graded ring, also with safety filters; and a corridor of more than 4096 vehicles (the kernel's parallel path on
 * the open boundary, a slot range wrapping around the buffer's end, zones) on 1 and 2 threads. Any difference in
 * arithmetic or ordering between the paths, or a race in the in-place update of the fused step, shows up as a bit
 * difference. */
#include <math.h>
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
#include "wf_test.h"

/* The graded ring of 5000 vehicles and three classes, up to its driver groups. */
#define RING_HEAD                                                                                               \
    "seed: 42\n"                                                                                                \
    "road:\n  length_m: 100000\n  grade: {points: [[0, 0.0], [20000, 0.02], [50000, 0.0], [70000, -0.02]]}\n"    \
    "time: {duration_s: 20, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 5}\n"                                  \
    "fleet:\n  vehicles: 5000\n  placement: random\n"                                                            \
    "  classes:\n    - {class: midsize_sedan, fraction: 0.5}\n    - {class: midsize_suv, fraction: 0.3}\n"         \
    "    - {class: class8_tractor, fraction: 0.2}\n"                                                             \
    "  drivers:\n"

static const char *yaml =
    RING_HEAD
    "    - {model: idm, fraction: 0.6, noise_mps2: 0.3, feasible_accel: clip,\n"
    "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
    "    - {model: idm, fraction: 0.3, noise_mps2: 0.2}\n"
    "    - {model: pi_saturation, fraction: 0.1}\n"
    "initial: {state: equilibrium, jitter_m: 0.5}\n";

typedef struct Out {
    size_t n;
    double *x, *v, *fuel;
    WfTsRow rows[32]; /* the time series: 21 records */
    size_t  n_rows;
    /* the complete state a checkpoint saves (accumulators, modes, controller memory), concatenated */
    unsigned char *state;
    size_t state_size;
    int64_t safety; /* the safety filters' interventions (summary) */
} Out;

static int64_t last_safety; /* the reference run's, of the last compare_paths */

static int keep_row(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    (void)err;
    Out *o = ctx;
    if (o->n_rows < sizeof o->rows / sizeof o->rows[0]) {
        WfTsRow *row = &o->rows[o->n_rows++];
        WF_TEST_KEEP_RECORD(row, rec, wf_sim_scenario(sim)->n_classes);
    }
    return 0;
}

/* mode: "time.fused_step=..." or, with trajectories (every 2 s: fused and multi-pass steps alternate),
 * "traj". */
static int run(const char *path, const char *mode, int threads, Out *o)
{
    const char *traj[] = {"time.fused_step=true", "output.trajectories=true", "output.trajectory_interval_s=2"};
    const char *plain[] = {mode};
    int with_traj = strcmp(mode, "traj") == 0;
    const char *const *set = with_traj ? traj : plain;
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    int rc = wf_scenario_load(path, set, with_traj ? 3 : 1, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    WfOutput out = {.record = keep_row, .ctx = o};
    if (!rc) rc = wf_sim_run(sim, &out, NULL, NULL, NULL, &err);
    if (rc) printf("  %s\n", err.msg);
    if (!rc) {
        const WfFleet *f = wf_sim_fleet(sim);
        o->n = f->n;
        o->x = malloc(f->n * sizeof(double));
        o->v = malloc(f->n * sizeof(double));
        o->fuel = malloc(f->n * sizeof(double));
        memcpy(o->x, f->x_m, f->n * sizeof(double));
        memcpy(o->v, f->v_mps, f->n * sizeof(double));
        memcpy(o->fuel, f->fuel_g, f->n * sizeof(double));
        o->safety = wf_sim_summary(sim)->safety_interventions;
        o->state = wf_test_state_copy(sim, &o->state_size);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

/* A scenario text into dir/s.yaml (path), dir a new temporary folder; 0 on success. */
static int write_temp(const char *text, char dir[static 28], char path[static 128])
{
    strcpy(dir, "/tmp/wf_test_paths.XXXXXX");
    if (!mkdtemp(dir)) return -1;
    snprintf(path, 128, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

/* run() of a scenario text (written to a temporary file). */
static int run_text(const char *text, const char *mode, int threads, Out *o)
{
    char dir[28], path[128];
    int rc = write_temp(text, dir, path) ? -1 : run(path, mode, threads, o);
    unlink(path);
    rmdir(dir);
    return rc;
}

/* Both paths over one scenario text; returns the reference's overlap count (final record). */
static double compare_paths(const char *text)
{
    double overlaps = -1;
    Out ref = {0}, o = {0};
    CHECK(run_text(text, "time.fused_step=false", 1, &ref) == 0, "multi-pass run failed");
    const char *modes[] = {"time.fused_step=true", "time.fused_step=true", "time.fused_step=false", "traj"};
    int threads[] = {1, 2, 2, 2};
    for (int k = 0; k < 4 && ref.x; k++) {
        memset(&o, 0, sizeof o);
        CHECK(run_text(text, modes[k], threads[k], &o) == 0, "run failed");
        if (!o.x) continue;
        CHECK(memcmp(o.x, ref.x, o.n * sizeof(double)) == 0, "%s, %d threads: positions differ", modes[k], threads[k]);
        CHECK(memcmp(o.v, ref.v, o.n * sizeof(double)) == 0, "%s, %d threads: speeds differ", modes[k], threads[k]);
        CHECK(memcmp(o.fuel, ref.fuel, o.n * sizeof(double)) == 0, "%s, %d threads: fuel differs", modes[k],
              threads[k]);
        CHECK(o.n_rows == 21 && o.n_rows == ref.n_rows, "%s, %d threads: %zu records, reference %zu", modes[k],
              threads[k], o.n_rows, ref.n_rows);
        for (size_t r = 0; r < o.n_rows && r < ref.n_rows; r++)
            CHECK(memcmp(&o.rows[r], &ref.rows[r], sizeof o.rows[r]) == 0, "%s, %d threads: record %zu (t = %g s) differs",
                  modes[k], threads[k], r, o.rows[r].v[WF_TS_T]);
        CHECK(o.state && ref.state && o.state_size == ref.state_size &&
                  memcmp(o.state, ref.state, o.state_size) == 0,
              "%s, %d threads: the checkpoint state (accumulators, modes, controller memory) differs", modes[k],
              threads[k]);
        CHECK(o.safety == ref.safety, "%s, %d threads: %lld safety interventions, reference %lld", modes[k], threads[k],
              (long long)o.safety, (long long)ref.safety);
        free(o.state);
        free(o.x), free(o.v), free(o.fuel);
    }
    if (ref.x) {
        double spread = 0;
        for (size_t i = 0; i < ref.n; i++) spread += fabs(ref.v[i] - ref.v[0]);
        CHECK(spread > 1.0, "speeds do not vary: the scenario would not exercise the paths");
    }
    if (ref.n_rows) overlaps = ref.rows[ref.n_rows - 1].v[WF_TS_OVERLAPS];
    last_safety = ref.safety;
    free(ref.x), free(ref.v), free(ref.fuel), free(ref.state);
    return overlaps;
}

static void test_paths_bitwise_equal(void) { CHECK(compare_paths(yaml) >= 0, "runs failed"); }

/* The same ring with safety filters (docs/controllers.md#safety-filters) on the controller with memory and on a
 * noisy IDM group: the filters and their counts (integers summed over chunks, saved in the checkpoint state) are the
 * same on every path and thread count. */
static void test_paths_with_safety(void)
{
    const char *text =
        RING_HEAD
        "    - {model: idm, fraction: 0.6, noise_mps2: 0.3, feasible_accel: clip, safety: {kind: ttc, ttc_s: 4},\n"
        "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
        "    - {model: idm, fraction: 0.3, noise_mps2: 0.2}\n"
        "    - {model: pi_saturation, fraction: 0.1, safety: {kind: gipps, gap_min_m: 6}}\n"
        "initial: {state: equilibrium, jitter_m: 0.5}\n";
    CHECK(compare_paths(text) >= 0, "runs failed");
    printf("  ring of 5000 vehicles with safety filters: %lld interventions, the same on every path\n",
           (long long)last_safety);
    CHECK(last_safety > 100, "only %lld interventions: the test would not exercise the filters", (long long)last_safety);
}

/* Noise far beyond what the brakes absorb (as in test_ring_physics's overlap test) on a fleet of many blocks:
 * the fused step must find overlaps inside blocks, at block edges and at chunk edges, and repair them exactly as
 * the multi-pass step does. */
static void test_paths_equal_with_overlaps(void)
{
    const char *text =
        "seed: 7\n"
        "road: {length_m: 60000}\n"
        "time: {duration_s: 20, dt_s: 0.1, output_interval_s: 1.0}\n"
        "fleet:\n  vehicles: 5000\n"
        "  classes: [{class: midsize_sedan, fraction: 1}]\n"
        "  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]\n"
        "initial: {state: equilibrium}\n";
    double overlaps = compare_paths(text);
    printf("  noisy ring of 5000 vehicles: %.0f overlap events, the same on every path\n", overlaps);
    CHECK(overlaps > 100, "only %.0f overlap events: the test would not exercise the repair", overlaps);

    /* Overlaps only at block edges: the reckless drivers are the last vehicle of every block of 256, whose leader
     * starts the next block (or, for the last, is vehicle 0 one lap ahead); the others drive without noise. */
    char edge[2048];
    int len = snprintf(edge, sizeof edge,
                       "seed: 7\nroad: {length_m: 60000}\n"
                       "time: {duration_s: 20, dt_s: 0.1, output_interval_s: 1.0}\n"
                       "fleet:\n  vehicles: 5120\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
                       "  drivers:\n    - {model: idm, count: 5100}\n"
                       "    - {model: idm, noise_mps2: 10, decel_max_mps2: 0.1, placement: explicit, indices: [");
    for (int b = 0; b < 20; b++) len += snprintf(edge + len, sizeof edge - (size_t)len, "%s%d", b ? ", " : "", 256 * b + 255);
    snprintf(edge + len, sizeof edge - (size_t)len, "]}\ninitial: {state: equilibrium}\n");
    double edge_overlaps = compare_paths(edge);
    printf("  overlaps at block edges only: %.0f events, the same on every path\n", edge_overlaps);
    CHECK(edge_overlaps > 10, "only %.0f overlap events at block edges", edge_overlaps);
}

/* ------------------------------------------------------------------------------------------ corridor */

static const char *corridor_yaml =
    "seed: 3\n"
    "road:\n  type: corridor\n  length_m: 90000\n  speed_limit_mps: 32\n"
    "  zones:\n    - {type: headway, from_m: 80000, to_m: 85000, factor: 1.3}\n"
    "    - {type: speed_limit, from_m: 86000, to_m: 88000, speed_limit_mps: 25}\n"
    "time: {duration_s: 3000, dt_s: 0.25, output_interval_s: 5.0, warmup_s: 100}\n"
    "fleet:\n  placement: random\n"
    "  classes:\n    - {class: midsize_sedan, fraction: 0.8, length_m: 3}\n"
    "    - {class: class8_tractor, fraction: 0.2, length_m: 3}\n"
    "  drivers:\n"
    "    - {model: idm, fraction: 0.6, noise_mps2: 0.05, feasible_accel: clip,\n"
    "       params: {v0_mps: 30, T_s: 0.3, s0_m: 1.0}, heterogeneity: {spread: {T_s: 0.1, v0_mps: 0.05}}}\n"
    "    - {model: idm, fraction: 0.35, params: {v0_mps: 30, T_s: 0.3, s0_m: 1.0}}\n"
    "    - {model: pi_saturation, fraction: 0.05, safety: {kind: gipps}}\n"
    "corridor:\n  inflow: {flow_vph: 20000, arrivals: deterministic}\n"
    "  edie: {dx_m: 500, dt_s: 60}\n  detectors: {x_m: [5000, 82000], interval_s: 60}\n";

typedef struct COut {
    WfCorridorRow rows[640]; /* 601 records */
    size_t n_rows;
    WfTrip *trips;
    size_t n_trips;
    unsigned char *state; /* the state blocks a checkpoint saves, at the end, concatenated */
    size_t state_size;
    double max_on_road;
    int64_t safety; /* the safety filter's interventions */
    long probes, switches; /* the thread governor's */
} COut;

static int c_row(void *ctx, const WfSim *c, const WfRecord *rec, WfError *err)
{
    (void)err;
    COut *o = ctx;
    if (o->n_rows < sizeof o->rows / sizeof o->rows[0]) {
        WfCorridorRow *row = &o->rows[o->n_rows++];
        WF_TEST_KEEP_RECORD(row, rec, wf_sim_scenario(c)->n_classes);
    }
    if (rec->v[WF_CTS_VEHICLES] > o->max_on_road) o->max_on_road = rec->v[WF_CTS_VEHICLES];
    return 0;
}

/* Trips copied field by field (the struct's padding is not part of the result). */
static int c_trips(void *ctx, const WfSim *c, const WfTrip *t, size_t n, WfError *err)
{
    (void)c;
    COut *o = ctx;
    WfTrip *p = realloc(o->trips, (o->n_trips + n) * sizeof *p);
    if (!p) return wf_err(err, WF_ESYS, "test: out of memory");
    o->trips = p;
    for (size_t k = 0; k < n; k++) {
        WfTrip *d = &o->trips[o->n_trips++];
        memset(d, 0, sizeof *d);
        *d = (WfTrip){t[k].serial, t[k].class_id, t[k].group_id, t[k].completed, t[k].t_arrival_s, t[k].t_entry_s,
                      t[k].t_exit_s, t[k].v_entry_mps, t[k].fuel_g, t[k].dist_m, t[k].time_stopped_s, t[k].stops,
                      t[k].hard_brakes, t[k].infeasible_steps, t[k].lane, t[k].lane_changes};
    }
    return 0;
}

/* check_steps: time.thread_check_steps (1: probes as often as the governor allows; 0: all threads always). */
static int run_corridor(const char *path, int threads, long check_steps, COut *o)
{
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *c = NULL;
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    char set[64];
    const char *sets[] = {set};
    snprintf(set, sizeof set, "time.thread_check_steps=%ld", check_steps);
    int rc = wf_scenario_load(path, sets, 1, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &c, &err);
    WfOutput out = {.record = c_row, .trips = c_trips, .ctx = o};
    if (!rc) rc = wf_sim_run(c, &out, NULL, NULL, NULL, &err);
    if (rc) printf("  %s\n", err.msg);
    if (!rc) {
        o->safety = wf_sim_summary(c)->safety_interventions;
        wf_sim_thread_stats(c, &o->probes, &o->switches);
        o->state = wf_test_state_copy(c, &o->state_size);
    }
    wf_sim_destroy(&c);
    wf_scenario_destroy(&sc);
    return rc;
}

static void test_corridor_threads(void)
{
    char dir[28], path[128];
    if (write_temp(corridor_yaml, dir, path)) {
        CHECK(0, "cannot write the scenario into %s", dir);
        return;
    }
    static COut a, b, sw;
    CHECK(run_corridor(path, 1, 1024, &a) == 0 && run_corridor(path, 2, 0, &b) == 0, "corridor runs failed");
    printf("  corridor: up to %.0f vehicles on the road, %zu trips, %zu records, %lld safety interventions\n",
           a.max_on_road, a.n_trips, a.n_rows, (long long)a.safety);
    CHECK(a.safety > 0 && a.safety == b.safety, "safety interventions %lld and %lld", (long long)a.safety,
          (long long)b.safety);
    CHECK(a.max_on_road > 4096, "at most %.0f vehicles: the kernel's parallel path is not exercised", a.max_on_road);
    CHECK(a.n_rows == 601 && b.n_rows == a.n_rows, "records: %zu and %zu", a.n_rows, b.n_rows);
    for (size_t r = 0; r < a.n_rows && r < b.n_rows; r++)
        CHECK(memcmp(&a.rows[r], &b.rows[r], sizeof a.rows[r]) == 0, "record %zu (t = %g s) differs", r,
              a.rows[r].v[WF_CTS_T]);
    CHECK(a.n_trips == b.n_trips && a.n_trips && !memcmp(a.trips, b.trips, a.n_trips * sizeof *a.trips),
          "trips differ (%zu and %zu)", a.n_trips, b.n_trips);
    CHECK(a.state && b.state && a.state_size == b.state_size && !memcmp(a.state, b.state, a.state_size),
          "the checkpoint state (vehicles, accumulators, Edie and detector sums) differs");
    /* the thread governor probing as often as it can (every step, then backing off to every 64): each probe and
     * each switch changes the threads between two steps; the same bits */
    CHECK(run_corridor(path, 2, 1, &sw) == 0, "corridor run with the governor switching failed");
    printf("  the governor probing as often as it can: %ld probes, %ld switches\n", sw.probes, sw.switches);
    /* the interval never exceeds 64 steps here: at least one probe per 64 steps of more than 4096 vehicles */
    CHECK(sw.probes >= 30, "only %ld probes: the threads hardly changed", sw.probes);
    CHECK(sw.n_rows == a.n_rows && !memcmp(sw.rows, a.rows, a.n_rows * sizeof *a.rows),
          "threads switched by the governor: the records differ");
    CHECK(sw.n_trips == a.n_trips && !memcmp(sw.trips, a.trips, a.n_trips * sizeof *a.trips),
          "threads switched by the governor: the trips differ");
    CHECK(sw.state && sw.state_size == a.state_size && !memcmp(sw.state, a.state, a.state_size),
          "threads switched by the governor: the checkpoint state differs");
    free(a.trips), free(b.trips), free(a.state), free(b.state), free(sw.trips), free(sw.state);
    unlink(path);
    rmdir(dir);
}

/* A block mixing driver groups gathers each group's vehicles for its rule (src/core/block.c accel_block); a block
 * of one group runs it in place. The same humans as one group and split into two identical groups (the larger
 * second, then first) must drive the same: every vehicle's final position, speed and fuel, every record, the same
 * bits, on 1 and 2 threads. */
static void test_groups_split(void)
{
    const char *one = RING_HEAD "    - {model: idm, fraction: 1.0, noise_mps2: 0.3, feasible_accel: clip}\n"
                                "initial: {state: equilibrium, jitter_m: 0.5}\n";
    const char *split[] = {
        RING_HEAD "    - {model: idm, fraction: 0.3, noise_mps2: 0.3, feasible_accel: clip}\n"
                  "    - {model: idm, fraction: 0.7, noise_mps2: 0.3, feasible_accel: clip}\n"
                  "initial: {state: equilibrium, jitter_m: 0.5}\n",
        RING_HEAD "    - {model: idm, fraction: 0.9, noise_mps2: 0.3, feasible_accel: clip}\n"
                  "    - {model: idm, fraction: 0.1, noise_mps2: 0.3, feasible_accel: clip}\n"
                  "initial: {state: equilibrium, jitter_m: 0.5}\n"};
    Out ref = {0};
    CHECK(run_text(one, "time.fused_step=true", 1, &ref) == 0 && ref.x, "one group: run failed");
    for (int k = 0; k < 2 && ref.x; k++)
        for (int threads = 1; threads <= 2; threads++) {
            Out o = {0};
            CHECK(run_text(split[k], "time.fused_step=true", threads, &o) == 0 && o.x, "split %d: run failed", k);
            if (!o.x) continue;
            CHECK(o.n == ref.n && memcmp(o.x, ref.x, o.n * sizeof(double)) == 0 &&
                      memcmp(o.v, ref.v, o.n * sizeof(double)) == 0 &&
                      memcmp(o.fuel, ref.fuel, o.n * sizeof(double)) == 0,
                  "split %d, %d threads: positions, speeds or fuel differ from one group's", k, threads);
            CHECK(o.n_rows == ref.n_rows && memcmp(o.rows, ref.rows, o.n_rows * sizeof o.rows[0]) == 0,
                  "split %d, %d threads: the records differ from one group's", k, threads);
            free(o.x), free(o.v), free(o.fuel), free(o.state);
        }
    free(ref.x), free(ref.v), free(ref.fuel), free(ref.state);
}

int main(void)
{
    RUN(test_paths_bitwise_equal);
    RUN(test_groups_split);
    RUN(test_paths_with_safety);
    RUN(test_paths_equal_with_overlaps);
    RUN(test_corridor_threads);
    TEST_EXIT();
}
