/* Benchmark of the tabulated energy model (issue 10): 1e7 random points (v in [0, 35] m/s, a in [-3, 3] m/s^2,
 * theta in [-0.03, 0.03] rad) evaluated through the array form (chunks of 16384 over OpenMP threads) and the
 * scalar form, with projection and flags (the tabulated defaults), on two tables sampled from the midsize SUV's
 * explicit model: one of the release's size (81 x 101 x 21 nodes, 1.4 MB per array) and a fine uneven one
 * (373 x 375 x 7, 7.8 MB per array). The explicit model on the same points is the reference speed. Best of 3;
 * 1 and 2 threads. Usage: bench_tabulated [N_POINTS] (default 1e7). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/err.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/vehicle.h"

enum { CHUNK = 16384, REPEATS = 3 };

/* splitmix64: benchmark inputs only (fixed seed, so every run evaluates the same points). */
static uint64_t mix_next(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double mix_uniform(uint64_t *s, double lo, double hi)
{
    return lo + (hi - lo) * ((double)(mix_next(s) >> 11) * 0x1p-53);
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static size_t fill(double *x, size_t n, double lo, double hi, double step)
{
    for (long i = 0;; i++) {
        double v = lo + (double)i * step;
        if (v > hi + 1e-9) break;
        x[n++] = v;
    }
    return n;
}

/* Samples the class's explicit model (projected, so infeasible nodes hold the saturated value, as in the
 * release) on the given axes. */
static int make_table(const WfVehicleClass *vc, size_t nv, const double *v, size_t na, const double *a, size_t nt,
                      const double *th, WfTable **out, WfError *err)
{
    size_t n = nv * na * nt;
    double *fuel = malloc(n * sizeof *fuel);
    uint8_t *inf = malloc(n);
    int rc = (!fuel || !inf) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t i = 0; i < nv && !rc; i++)
        for (size_t j = 0; j < na; j++)
            for (size_t k = 0; k < nt; k++) {
                uint8_t fl;
                size_t idx = (i * na + j) * nt + k;
                fuel[idx] = wf_circles_fuel(vc->params, v[i], a[j], th[k], 1, &fl);
                inf[idx] = fl == WF_INFEASIBLE_ACCEL;
            }
    if (!rc) rc = wf_table_from_grid(nv, v, na, a, nt, th, fuel, inf, "bench", out, err);
    free(fuel);
    free(inf);
    return rc;
}

typedef struct Kernel {
    const char          *name;
    const WfEnergyModel *model;
    const void          *params;
    int                  project, flags, scalar;
} Kernel;

static void run(const Kernel *k, const WfTable *t, size_t n, const double *v, const double *a, const double *th,
                double *fuel, uint8_t *flag)
{
    if (k->scalar) {
        /* Per point: each iteration writes only its own index. */
#pragma omp parallel for default(none) shared(t, n, v, a, th, fuel, flag, k) schedule(static)
        for (size_t i = 0; i < n; i++) fuel[i] = wf_table_fuel(t, v[i], a[i], th[i], k->project, &flag[i], NULL);
        return;
    }
    size_t n_chunks = (n + CHUNK - 1) / CHUNK;
    /* Chunks are disjoint ranges: each thread writes only its own. */
#pragma omp parallel for default(none) shared(k, n, n_chunks, v, a, th, fuel, flag) schedule(static)
    for (size_t c = 0; c < n_chunks; c++) {
        size_t s = c * CHUNK, len = n - s < CHUNK ? n - s : CHUNK;
        k->model->eval(k->params, len, v + s, a + s, th + s, k->project, fuel + s, k->flags ? flag + s : NULL);
    }
}

int main(int argc, char **argv)
{
    size_t n = 10000000;
    WfError path_err = {0};
    /* The library has no class search path of its own: the repository's classes, by its source path. */
    if (wf_vehicle_search_path_set(WF_REPO_DIR "/vehicles", &path_err)) return 1;
    if (argc > 1) {
        long k;
        if (wf_parse_long(argv[1], 1, 1000000000L, &k)) {
            fprintf(stderr, "usage: bench_tabulated [N_POINTS >= 1]\n");
            return 2;
        }
        n = (size_t)k;
    }
    WfError err = {0};
    WfVehicleClass vc;
    if (wf_vehicle_find("midsize_suv", &vc, &err)) {
        fprintf(stderr, "bench_tabulated: %s\n", err.msg);
        return 2;
    }
    static double rv[400], ra[400], rt[32], fv[400], fa[400], ft[8];
    size_t nrv = fill(rv, 0, 0, 40, 0.5), nra = fill(ra, 0, -4, 4, 0.08), nrt = fill(rt, 0, -0.03, 0.03, 0.003);
    size_t nfv = fill(fv, 0, 0, 37.2, 0.1), nfa = fill(fa, 0, -3.2, -1.25, 0.05);
    nfa = fill(fa, nfa, -1.2, 0.095, 0.005);
    nfa = fill(fa, nfa, 0.1, 3.8, 0.05);
    size_t nft = fill(ft, 0, -0.03, 0.03, 0.01);
    WfTable *tables[2] = {NULL, NULL};
    WfTabulatedParams tp[2];
    int rc = 1;
    double *v = malloc(n * sizeof *v), *a = malloc(n * sizeof *a), *th = malloc(n * sizeof *th);
    double *fuel = malloc(n * sizeof *fuel);
    uint8_t *flag = malloc(n);
    if (!v || !a || !th || !fuel || !flag) {
        fprintf(stderr, "bench_tabulated: out of memory for %zu points\n", n);
        goto done;
    }
    if (make_table(&vc, nrv, rv, nra, ra, nrt, rt, &tables[0], &err) ||
        make_table(&vc, nfv, fv, nfa, fa, nft, ft, &tables[1], &err)) {
        fprintf(stderr, "bench_tabulated: %s\n", err.msg);
        goto done;
    }
    tp[0].table = tables[0];
    tp[1].table = tables[1];
    uint64_t seed = 0x5EEDC1C1E5ull;
    for (size_t i = 0; i < n; i++) {
        v[i] = mix_uniform(&seed, 0, 35);
        a[i] = mix_uniform(&seed, -3, 3);
        th[i] = mix_uniform(&seed, -0.03, 0.03);
    }
    const Kernel kernels[] = {
        {"explicit_array", &wf_energy_circles, vc.params, 1, 1, 0},
        {"release_array", &wf_energy_tabulated, &tp[0], 1, 1, 0},
        {"release_array_noflag", &wf_energy_tabulated, &tp[0], 1, 0, 0},
        {"release_scalar", &wf_energy_tabulated, &tp[0], 1, 1, 1},
        {"fine_array", &wf_energy_tabulated, &tp[1], 1, 1, 0},
    };
    printf("# bench_tabulated: %zu points; release-sized table %zu x %zu x %zu, fine table %zu x %zu x %zu; "
           "best of %d\n",
           n, nrv, nra, nrt, nfv, nfa, nft, REPEATS);
    printf("# %-22s %7s %10s %14s %22s\n", "kernel", "threads", "best_s", "evals_per_s", "checksum");
    int threads[] = {1, 2};
    for (size_t t = 0; t < 2; t++) {
#ifdef _OPENMP
        omp_set_num_threads(threads[t]);
#else
        if (threads[t] > 1) continue; /* built without OpenMP: one thread only */
#endif
        for (size_t k = 0; k < sizeof kernels / sizeof kernels[0]; k++) {
            const Kernel *K = &kernels[k];
            const WfTable *tab =
                K->model == &wf_energy_tabulated ? ((const WfTabulatedParams *)K->params)->table : NULL;
            double best = 1e300;
            for (int r = 0; r < REPEATS; r++) {
                double t0 = now_s();
                run(K, tab, n, v, a, th, fuel, flag);
                double dt = now_s() - t0;
                if (dt < best) best = dt;
            }
            double sum = 0; /* fixed order: the same for any thread count */
            for (size_t i = 0; i < n; i++) sum += fuel[i] + (K->flags ? (double)flag[i] : 0.0);
            printf("  %-22s %7d %10.4f %14.4g %22.17g\n", K->name, threads[t], best, (double)n / best, sum);
            printf("BENCH tabulated kernel=%s threads=%d n=%zu repeats=%d best_s=%.6f evals_per_s=%.6g "
                   "checksum=%.17g\n",
                   K->name, threads[t], n, REPEATS, best, (double)n / best, sum);
            fflush(stdout);
        }
    }
    rc = 0;
done:
    wf_table_destroy(&tables[0]);
    wf_table_destroy(&tables[1]);
    free(v);
    free(a);
    free(th);
    free(fuel);
    free(flag);
    wf_vehicle_free(&vc);
    return rc;
}
