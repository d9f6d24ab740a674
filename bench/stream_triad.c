/* STREAM-like triad a[i] = b[i] + s c[i] (McCalpin's STREAM, "Triad" kernel) with OpenMP on 1, 2, ... threads
 * up to the number of processors: the sustainable memory bandwidth that bounds wavefuel's step loop at large N
 * (bench/README.md, "STREAM triad and roofline"). Arrays far larger than the caches, first-touched in parallel
 * with the same static schedule as the kernel, best of R repeats. Bandwidth is counted as STREAM counts it:
 * 24 bytes per element (read b and c, write a); with write-allocate the memory also reads a, i.e. 32 bytes.
 * Usage: stream_triad [N_ELEMENTS [REPEATS]]   (default 2^26 elements = 512 MiB per array, 10 repeats).
 * Output: one CSV row per thread count: threads,n,repeats,best_s,mean_s,gb_per_s,gb_per_s_write_allocate. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/err.h"

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int max_threads(void)
{
#ifdef _OPENMP
    return omp_get_num_procs();
#else
    return 1;
#endif
}

/* The kernel. restrict + a plain loop: GCC vectorizes it at -O2 (GCC 12 only for a known-simple loop like this
 * one), and a memory-bound loop runs at the same speed scalar or vector. */
static void triad(size_t n, double *restrict a, const double *restrict b, const double *restrict c, double s,
                  int nthreads)
{
    (void)nthreads; /* only used by the OpenMP clause */
#pragma omp parallel for schedule(static) num_threads(nthreads) default(none) shared(n, a, b, c, s)
    for (size_t i = 0; i < n; i++) a[i] = b[i] + s * c[i];
}

int main(int argc, char **argv)
{
    long n_arg = 1L << 26, reps = 10;
    if (argc > 3 || (argc > 1 && wf_parse_long(argv[1], 1024, 1L << 34, &n_arg)) ||
        (argc > 2 && wf_parse_long(argv[2], 1, 1000, &reps))) {
        fprintf(stderr, "usage: stream_triad [N_ELEMENTS in [1024, 2^34] [REPEATS in [1, 1000]]]\n");
        return 2;
    }
    size_t n = (size_t)n_arg;
    int tmax = max_threads();
    double *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *c = malloc(n * sizeof *c);
    if (!a || !b || !c) {
        fprintf(stderr, "stream_triad: cannot allocate 3 x %zu doubles (%.3g GB)\n", n, 3.0 * 8.0 * (double)n / 1e9);
        free(a), free(b), free(c);
        return 1;
    }
    /* First touch by every thread on its own static share, so the pages sit where the kernel's threads read
     * them (matters on NUMA machines; harmless on one node). */
    const double b0 = 2.0, c0 = 0.5, s = 3.0;
#pragma omp parallel for schedule(static) num_threads(tmax) default(none) shared(n, a, b, c, b0, c0)
    for (size_t i = 0; i < n; i++) a[i] = 0.0, b[i] = b0, c[i] = c0;

    printf("threads,n,repeats,best_s,mean_s,gb_per_s,gb_per_s_write_allocate\n");
    int status = 0;
    /* Thread counts 1, 2, 4, ... and the number of processors. */
    for (int t = 1;; t = 2 * t < tmax ? 2 * t : tmax) {
        triad(n, a, b, c, s, t); /* warm-up: page tables, thread pool */
        double best = INFINITY, sum = 0.0;
        for (long r = 0; r < reps; r++) {
            double t0 = now_s();
            triad(n, a, b, c, s, t);
            double dt = now_s() - t0;
            best = dt < best ? dt : best;
            sum += dt;
        }
        /* Verification (as STREAM does): every element must be b0 + s c0, exactly (3.5 is representable and
         * the operations are exact), which also keeps the compiler from dropping the stores. */
        size_t bad = 0;
        for (size_t i = 0; i < n; i++) bad += a[i] != b0 + s * c0;
        if (bad) {
            fprintf(stderr, "stream_triad: %zu of %zu results wrong on %d threads\n", bad, n, t);
            status = 1;
        }
        printf("%d,%zu,%ld,%.6f,%.6f,%.3f,%.3f\n", t, n, reps, best, sum / (double)reps, 24.0 * (double)n / best / 1e9,
               32.0 * (double)n / best / 1e9);
        fflush(stdout);
        if (t == tmax) break;
    }
    free(a), free(b), free(c);
    return status;
}
