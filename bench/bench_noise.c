/* Benchmark of the noise generator's kernels (src/core/rng.c, noise.h): each width of Box-Muller (2, 4, 8 lanes)
 * and of the vector Philox (8, 16 counters) this CPU runs, on chunks of 128 pairs as wf_rng_normal_block calls them,
 * in nanoseconds per pair (Box-Muller: two deviates) or per Philox call (two uniforms); and wf_rng_normal_block
 * itself (with the widths the process chose on its first draw) per deviate. One thread; each kernel warmed up for
 * 20 ms, then the best of 5 runs of ~20 ms. Checks that every width gives the bits of the narrowest. Usage:
 * bench_noise (no arguments). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "core/noise.h"
#include "core/simd.h"
#include "util/clock.h"
#include "wavefuel/rng.h"

enum { PAIRS = 128, REPEATS = 5 };

static double u1[PAIRS], u2[PAIRS], z[2 * PAIRS], ref[2 * PAIRS];

typedef void (*Run)(int k);
static void (*const BM[])(size_t, const double *, const double *, double *) = {wf_noise_sse2, wf_noise_avx,
                                                                                  wf_noise_avx512};
static void (*const PH[])(uint32_t, uint32_t, uint32_t, uint32_t, uint32_t, uint32_t, size_t, double *,
                          double *) = {wf_philox_uniforms_avx2, wf_philox_uniforms_avx512};
static uint32_t counter;

static void run_bm(int k) { BM[k](PAIRS, u1, u2, z); }
static void run_ph(int k) { PH[k](1u, 2u, 3u, 4u, 5u, counter += PAIRS, PAIRS, u1, u2); }
static void run_block(int k)
{
    (void)k;
    wf_rng_normal_block(42, WF_RNG_NOISE_BLOCK, counter++, 7, 2 * PAIRS, z);
}

/* Nanoseconds per item (PAIRS items a call) of the best of REPEATS runs of ~20 ms, after 20 ms of warm-up. */
static double time_ns(Run run, int k)
{
    for (double end = wf_wall_now() + 0.02; wf_wall_now() < end;) run(k);
    double best = 1e300;
    for (int r = 0; r < REPEATS; r++) {
        long calls = 0;
        double t0 = wf_wall_now(), t1;
        do {
            for (int c = 0; c < 64; c++) run(k);
            calls += 64;
        } while ((t1 = wf_wall_now()) - t0 < 0.02);
        double ns = (t1 - t0) / ((double)calls * PAIRS) * 1e9;
        if (ns < best) best = ns;
    }
    return best;
}

int main(void)
{
    for (size_t p = 0; p < PAIRS; p++) u1[p] = ((double)p + 0.5) / PAIRS, u2[p] = (double)p / PAIRS;
    WfSimdLevel level = wf_simd_level();
    static const char *bm_name[] = {"Box-Muller, 2 lanes (SSE2)", "Box-Muller, 4 lanes (AVX)",
                                    "Box-Muller, 8 lanes (AVX-512)"};
    static const WfSimdLevel bm_need[] = {WF_SIMD_BASE, WF_SIMD_AVX, WF_SIMD_AVX512};
    static const char *ph_name[] = {"Philox, 8 counters (AVX2)", "Philox, 16 counters (AVX-512)"};
    static const WfSimdLevel ph_need[] = {WF_SIMD_AVX2, WF_SIMD_AVX512};
    int bad = 0;
    printf("| kernel | ns per pair or call |\n|---|---|\n");
    BM[0](PAIRS, u1, u2, ref);
    for (int k = 0; k < 3; k++) {
        if (level < bm_need[k]) continue;
        BM[k](PAIRS, u1, u2, z);
        bad |= memcmp(z, ref, sizeof z) != 0;
        printf("| %s | %.2f |\n", bm_name[k], time_ns(run_bm, k));
    }
    for (int k = 0; k < 2; k++)
        if (level >= ph_need[k]) printf("| %s | %.2f |\n", ph_name[k], time_ns(run_ph, k));
    printf("| wf_rng_normal_block, per deviate (the process's choice) | %.2f |\n", time_ns(run_block, 0) / 2.0);
    if (bad) fprintf(stderr, "bench_noise: a Box-Muller width gave other bits than the 2-lane kernel\n");
    return bad;
}
