/* The engine's execution paths give the same bits: the fused one-pass step and the multi-pass step, on 1 and 2
 * threads, final state and every time-series record, with noise, heterogeneous drivers (per-vehicle parameters)
 * beside homogeneous ones (one shared parameter set, IDM's block kernel), three classes, a controller with memory
 * (PI with saturation) and a graded ring. Any difference in arithmetic or ordering between
 * the paths, or a race in the in-place update of the fused step, shows up as a bit difference. */
#include <math.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

static const char *yaml =
    "seed: 42\n"
    "road:\n  length_m: 100000\n  grade: {points: [[0, 0.0], [20000, 0.02], [50000, 0.0], [70000, -0.02]]}\n"
    "time: {duration_s: 20, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 5}\n"
    "fleet:\n  vehicles: 5000\n  placement: random\n"
    "  classes:\n    - {class: midsize_sedan, fraction: 0.5}\n    - {class: midsize_suv, fraction: 0.3}\n"
    "    - {class: class8_tractor, fraction: 0.2}\n"
    "  drivers:\n"
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
} Out;

static int keep_row(void *ctx, const WfSim *sim, const WfTsRow *row, WfError *err)
{
    (void)sim, (void)err;
    Out *o = ctx;
    if (o->n_rows < sizeof o->rows / sizeof o->rows[0]) o->rows[o->n_rows++] = *row;
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
        WfStateVar vars[64];
        size_t nv = wf_sim_state(sim, vars, 64);
        for (size_t k = 0; k < nv && k < 64; k++) o->state_size += vars[k].size;
        o->state = malloc(o->state_size);
        for (size_t k = 0, off = 0; o->state && k < nv && k < 64; k++) {
            memcpy(o->state + off, vars[k].data, vars[k].size);
            off += vars[k].size;
        }
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

/* Both paths over one scenario text; returns the reference's overlap count (final record). */
static double compare_paths(const char *text)
{
    char dir[] = "/tmp/wf_test_paths.XXXXXX", path[128];
    if (!mkdtemp(dir)) return -1;
    snprintf(path, sizeof path, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
    double overlaps = -1;
    Out ref = {0}, o = {0};
    CHECK(run(path, "time.fused_step=false", 1, &ref) == 0, "multi-pass run failed");
    const char *modes[] = {"time.fused_step=true", "time.fused_step=true", "time.fused_step=false", "traj"};
    int threads[] = {1, 2, 2, 2};
    for (int k = 0; k < 4 && ref.x; k++) {
        memset(&o, 0, sizeof o);
        CHECK(run(path, modes[k], threads[k], &o) == 0, "run failed");
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
        free(o.state);
        free(o.x), free(o.v), free(o.fuel);
    }
    if (ref.x) {
        double spread = 0;
        for (size_t i = 0; i < ref.n; i++) spread += fabs(ref.v[i] - ref.v[0]);
        CHECK(spread > 1.0, "speeds do not vary: the scenario would not exercise the paths");
    }
    if (ref.n_rows) overlaps = ref.rows[ref.n_rows - 1].v[WF_TS_OVERLAPS];
    free(ref.x), free(ref.v), free(ref.fuel), free(ref.state);
    unlink(path);
    rmdir(dir);
    return overlaps;
}

static void test_paths_bitwise_equal(void) { CHECK(compare_paths(yaml) >= 0, "runs failed"); }

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

int main(void)
{
    RUN(test_paths_bitwise_equal);
    RUN(test_paths_equal_with_overlaps);
    TEST_EXIT();
}
