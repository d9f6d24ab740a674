/* Benchmark of the CIRCLES energy model (issue 3): 1e7 points, all six vehicle classes mixed, evaluated
 * (a) per point through the scalar form wf_circles_fuel() in the points' mixed order and (b) grouped by
 * class through the array form wf_energy_circles.eval() on contiguous chunks, on 1 and 2 OpenMP threads,
 * best of 3 repeats. Reports evaluations per second and a checksum of the results (so the work cannot be
 * optimised away); both forms must agree bitwise. Usage: bench_energy [N_POINTS] (default 1e7). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/energy.h"
#include "wavefuel/err.h"
#include "wavefuel/vehicle.h"

static const char *const class_names[] = {"compact_sedan", "midsize_sedan", "midsize_suv",
                                          "midsize_pickup", "class4_pnd",    "class8_tractor"};
enum { N_CLASSES = sizeof class_names / sizeof class_names[0], CHUNK = 16384, REPEATS = 3 };

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

typedef struct Chunk {
    int    cls;
    size_t start, len;
} Chunk;

/* Per point, mixed classes: the way a caller with one vehicle at a time uses the model. */
static void run_scalar(const void *const *params, size_t n, const uint8_t *cls, const double *v, const double *a,
                       const double *th, double *fuel, uint8_t *flag)
{
    /* Each iteration writes only its own index: race-free, and the result does not depend on threads. */
#pragma omp parallel for default(none) shared(params, n, cls, v, a, th, fuel, flag) schedule(static)
    for (size_t i = 0; i < n; i++) fuel[i] = wf_circles_fuel(params[cls[i]], v[i], a[i], th[i], 0, &flag[i]);
}

/* Grouped by class, array form over contiguous chunks: the way the simulator evaluates a fleet. */
static void run_array(const void *const *params, size_t n_chunks, const Chunk *ch, const double *v, const double *a,
                      const double *th, double *fuel, uint8_t *flag)
{
    const WfEnergyModel *m = &wf_energy_circles;
    /* Chunks are disjoint ranges: each thread writes only its own. */
#pragma omp parallel for default(none) shared(m, params, n_chunks, ch, v, a, th, fuel, flag) schedule(static)
    for (size_t c = 0; c < n_chunks; c++) {
        size_t s = ch[c].start;
        m->eval(params[ch[c].cls], ch[c].len, v + s, a + s, th + s, 0, fuel + s, flag + s);
    }
}

/* Sum in a fixed order (serial), so the checksum is the same for any thread count. */
static double checksum(size_t n, const double *fuel, const uint8_t *flag)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) s += fuel[i] + (double)flag[i];
    return s;
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
            fprintf(stderr, "usage: bench_energy [N_POINTS >= 1]\n");
            return 2;
        }
        n = (size_t)k;
    }
    WfVehicleClass vc[N_CLASSES];
    const void *params[N_CLASSES];
    for (int k = 0; k < N_CLASSES; k++) {
        WfError err = {0};
        if (wf_vehicle_find(class_names[k], &vc[k], &err)) {
            fprintf(stderr, "bench_energy: %s\n", err.msg);
            for (int j = 0; j < k; j++) wf_vehicle_free(&vc[j]);
            return 2;
        }
        params[k] = vc[k].params;
    }

    int rc = 1;
    size_t n_chunks_max = n / CHUNK + N_CLASSES + 1;
    double *v = malloc(n * sizeof *v), *a = malloc(n * sizeof *a), *th = malloc(n * sizeof *th);
    double *gv = malloc(n * sizeof *gv), *ga = malloc(n * sizeof *ga), *gth = malloc(n * sizeof *gth);
    double *f_scalar = malloc(n * sizeof *f_scalar), *f_array = malloc(n * sizeof *f_array);
    uint8_t *cls = malloc(n), *fl_scalar = malloc(n), *fl_array = malloc(n);
    size_t *where = malloc(n * sizeof *where);
    Chunk *ch = malloc(n_chunks_max * sizeof *ch);
    if (!v || !a || !th || !gv || !ga || !gth || !f_scalar || !f_array || !cls || !fl_scalar || !fl_array || !where ||
        !ch) {
        fprintf(stderr, "bench_energy: out of memory for %zu points\n", n);
        goto done;
    }

    /* Inputs in mixed order, then a copy grouped by class (counting sort; where[i] = grouped index of i). */
    uint64_t seed = 0x5EEDC1C1E5ull;
    size_t count[N_CLASSES] = {0}, off[N_CLASSES];
    for (size_t i = 0; i < n; i++) {
        cls[i] = (uint8_t)(mix_next(&seed) % N_CLASSES);
        v[i] = mix_uniform(&seed, 0, 35);
        a[i] = mix_uniform(&seed, -3, 3);
        th[i] = mix_uniform(&seed, -0.03, 0.03);
        count[cls[i]]++;
    }
    size_t n_chunks = 0, pos = 0;
    for (int k = 0; k < N_CLASSES; k++) {
        off[k] = pos;
        for (size_t s = 0; s < count[k]; s += CHUNK)
            ch[n_chunks++] = (Chunk){k, pos + s, count[k] - s < CHUNK ? count[k] - s : CHUNK};
        pos += count[k];
    }
    for (size_t i = 0; i < n; i++) {
        size_t j = off[cls[i]]++;
        where[i] = j;
        gv[j] = v[i];
        ga[j] = a[i];
        gth[j] = th[i];
    }

    int threads[] = {1, 2};
    printf("# bench_energy: %zu points, %d classes mixed, %zu array chunks of <= %d, best of %d\n", n, N_CLASSES,
           n_chunks, CHUNK, REPEATS);
    printf("# %-6s %7s %12s %14s %22s\n", "form", "threads", "best_s", "evals_per_s", "checksum");
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
#ifdef _OPENMP
        omp_set_num_threads(threads[t]);
#else
        if (threads[t] > 1) continue; /* built without OpenMP: one thread only */
#endif
        for (int form = 0; form < 2; form++) {
            double best = 1e300;
            for (int r = 0; r < REPEATS; r++) {
                double t0 = now_s();
                if (form == 0)
                    run_scalar(params, n, cls, v, a, th, f_scalar, fl_scalar);
                else
                    run_array(params, n_chunks, ch, gv, ga, gth, f_array, fl_array);
                double dt = now_s() - t0;
                if (dt < best) best = dt;
            }
            double sum = form == 0 ? checksum(n, f_scalar, fl_scalar) : 0;
            if (form == 1) {
                /* Same points in the mixed order, so the checksum is comparable; and bitwise equality. */
                size_t bad = 0;
                sum = 0;
                for (size_t i = 0; i < n; i++) {
                    size_t j = where[i];
                    sum += f_array[j] + (double)fl_array[j];
                    bad += memcmp(&f_array[j], &f_scalar[i], sizeof(double)) != 0 || fl_array[j] != fl_scalar[i];
                }
                if (bad) {
                    fprintf(stderr, "bench_energy: %zu points differ between the scalar and array forms\n", bad);
                    goto done;
                }
            }
            const char *name = form == 0 ? "scalar" : "array";
            printf("  %-6s %7d %12.4f %14.4g %22.17g\n", name, threads[t], best, (double)n / best, sum);
            printf("BENCH energy form=%s threads=%d n=%zu repeats=%d best_s=%.6f evals_per_s=%.6g checksum=%.17g\n",
                   name, threads[t], n, REPEATS, best, (double)n / best, sum);
            fflush(stdout);
        }
    }
    rc = 0;
done:
    free(v);
    free(a);
    free(th);
    free(gv);
    free(ga);
    free(gth);
    free(f_scalar);
    free(f_array);
    free(cls);
    free(fl_scalar);
    free(fl_array);
    free(where);
    free(ch);
    for (int k = 0; k < N_CLASSES; k++) wf_vehicle_free(&vc[k]);
    return rc;
}
