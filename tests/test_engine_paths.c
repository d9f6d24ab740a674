/* The engine's execution paths give the same bits: the fused one-pass step (steps that record nothing) and the
 * multi-pass step (steps that record), on 1 and 2 threads, with noise, heterogeneous drivers, three classes, a
 * controller with memory (PI with saturation) and a graded ring. Any difference in arithmetic or ordering between
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
    "    - {model: idm, fraction: 0.9, noise_mps2: 0.3, feasible_accel: clip,\n"
    "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
    "    - {model: pi_saturation, fraction: 0.1}\n"
    "initial: {state: equilibrium, jitter_m: 0.5}\n";

typedef struct Out {
    size_t n;
    double *x, *v, *fuel;
} Out;

static int run(const char *path, const char *fused, int threads, Out *o)
{
    const char *set[] = {fused};
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    int rc = wf_scenario_load(path, set, 1, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    if (!rc) rc = wf_sim_run(sim, NULL, NULL, NULL, NULL, &err);
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
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return rc;
}

static void test_paths_bitwise_equal(void)
{
    char dir[] = "/tmp/wf_test_paths.XXXXXX", path[128];
    if (!mkdtemp(dir)) return;
    snprintf(path, sizeof path, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    fputs(yaml, f);
    fclose(f);
    Out ref = {0}, o = {0};
    CHECK(run(path, "time.fused_step=false", 1, &ref) == 0, "multi-pass run failed");
    const char *modes[] = {"time.fused_step=true", "time.fused_step=true", "time.fused_step=false"};
    int threads[] = {1, 2, 2};
    for (int k = 0; k < 3 && ref.x; k++) {
        memset(&o, 0, sizeof o);
        CHECK(run(path, modes[k], threads[k], &o) == 0, "run failed");
        if (!o.x) continue;
        CHECK(memcmp(o.x, ref.x, o.n * sizeof(double)) == 0, "%s, %d threads: positions differ", modes[k], threads[k]);
        CHECK(memcmp(o.v, ref.v, o.n * sizeof(double)) == 0, "%s, %d threads: speeds differ", modes[k], threads[k]);
        CHECK(memcmp(o.fuel, ref.fuel, o.n * sizeof(double)) == 0, "%s, %d threads: fuel differs", modes[k],
              threads[k]);
        free(o.x), free(o.v), free(o.fuel);
    }
    if (ref.x) {
        double spread = 0;
        for (size_t i = 0; i < ref.n; i++) spread += fabs(ref.v[i] - ref.v[0]);
        CHECK(spread > 1.0, "speeds do not vary: the scenario would not exercise the paths");
    }
    free(ref.x), free(ref.v), free(ref.fuel);
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    RUN(test_paths_bitwise_equal);
    TEST_EXIT();
}
