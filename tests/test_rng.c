/* The noise generator (wf_rng_normal_block): its deviates against the standard normal distribution computed
 * independently (moments, Kolmogorov-Smirnov against 0.5 erfc(-x / sqrt 2), tail frequencies), and the
 * properties the engine relies on (a pure function of its key; a block's prefix does not depend on its size). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <Random123/philox.h>

#include "core/noise.h"
#include "core/simd.h"
#include "wavefuel/rng.h"
#include "wf_test.h"

#define NBLK 4000
#define BLK  256
#define NTOT ((size_t)NBLK * BLK)

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double *draw_all(uint64_t seed)
{
    double *z = malloc(NTOT * sizeof *z);
    /* blocks at several steps, as the engine draws them */
    for (size_t b = 0; b < NBLK; b++) wf_rng_normal_block(seed, WF_RNG_NOISE_BLOCK, b % 97, b / 97, BLK, z + b * BLK);
    return z;
}

static void test_moments_and_tails(void)
{
    double *z = draw_all(42);
    double s1 = 0, s2 = 0, s3 = 0, s4 = 0, lag = 0;
    size_t t2 = 0, t3 = 0;
    for (size_t i = 0; i < NTOT; i++) {
        double x = z[i];
        s1 += x, s2 += x * x, s3 += x * x * x, s4 += x * x * x * x;
        if (i + 1 < NTOT) lag += x * z[i + 1];
        t2 += fabs(x) > 2.0;
        t3 += fabs(x) > 3.0;
    }
    double n = (double)NTOT, se = 1.0 / sqrt(n);
    /* standard errors of the sample moments of N(0,1): mean 1, var sqrt 2, skew sqrt 6, kurtosis sqrt 24 (/sqrt n) */
    CHECK_ABS(s1 / n, 0.0, 5 * se);
    CHECK_ABS(s2 / n, 1.0, 5 * sqrt(2.0) * se);
    CHECK_ABS(s3 / n, 0.0, 5 * sqrt(15.0) * se);
    CHECK_ABS(s4 / n, 3.0, 5 * sqrt(96.0) * se);
    CHECK_ABS(lag / n, 0.0, 5 * se);
    double p2 = erfc(2.0 / sqrt(2.0)), p3 = erfc(3.0 / sqrt(2.0));
    CHECK_ABS((double)t2 / n, p2, 5 * sqrt(p2 * (1 - p2) / n));
    CHECK_ABS((double)t3 / n, p3, 5 * sqrt(p3 * (1 - p3) / n));
    free(z);
}

static void test_kolmogorov_smirnov(void)
{
    double *z = draw_all(7);
    qsort(z, NTOT, sizeof *z, cmp_double);
    double d = 0.0, n = (double)NTOT;
    for (size_t i = 0; i < NTOT; i++) {
        double F = 0.5 * erfc(-z[i] / sqrt(2.0));
        double dp = (double)(i + 1) / n - F, dm = F - (double)i / n;
        d = fmax(d, fmax(dp, dm));
    }
    /* sqrt(n) D > 1.95 has probability 0.001 for a correct generator */
    CHECK(sqrt(n) * d < 1.95, "KS statistic sqrt(n) D = %.3f over %zu deviates", sqrt(n) * d, NTOT);
    free(z);
}

static void test_pure_function(void)
{
    double a[BLK], b[BLK], c[100];
    wf_rng_normal_block(1, WF_RNG_NOISE_BLOCK, 12, 345, BLK, a);
    wf_rng_normal_block(1, WF_RNG_NOISE_BLOCK, 12, 345, BLK, b);
    CHECK(memcmp(a, b, sizeof a) == 0, "same key, different deviates");
    wf_rng_normal_block(1, WF_RNG_NOISE_BLOCK, 12, 345, 100, c);
    CHECK(memcmp(a, c, sizeof c) == 0, "a block's first 100 deviates depend on the block size");
    /* a long block takes its words in several batches: its start is still the short block's */
    static double longb[5000];
    wf_rng_normal_block(1, WF_RNG_NOISE_BLOCK, 12, 345, 5000, longb);
    CHECK(memcmp(a, longb, sizeof a) == 0, "a 5000-deviate block does not start with the 256-deviate block");
    double m1 = 0, m2 = 0;
    for (size_t i = 0; i < 5000; i++) m1 += longb[i], m2 += longb[i] * longb[i];
    CHECK(fabs(m1 / 5000) < 5 / sqrt(5000.0) && fabs(m2 / 5000 - 1) < 5 * sqrt(2.0 / 5000),
          "long block: mean %g, second moment %g", m1 / 5000, m2 / 5000);
    /* another block, step, seed or stream: a different sequence */
    const uint64_t keys[4][4] = {{1, WF_RNG_NOISE_BLOCK, 13, 345}, {1, WF_RNG_NOISE_BLOCK, 12, 346},
                                 {2, WF_RNG_NOISE_BLOCK, 12, 345}, {1, WF_RNG_NOISE, 12, 345}};
    for (int k = 0; k < 4; k++) {
        wf_rng_normal_block(keys[k][0], (uint32_t)keys[k][1], keys[k][2], keys[k][3], BLK, b);
        size_t same = 0;
        for (size_t i = 0; i < BLK; i++) same += a[i] == b[i];
        CHECK(same == 0, "key %d: %zu of %d deviates equal to the reference block", k, same, BLK);
    }
    /* indices above 2^32 are folded, not truncated */
    wf_rng_normal_block(1, WF_RNG_NOISE_BLOCK, 12 + (1ull << 32), 345, BLK, b);
    CHECK(memcmp(a, b, sizeof a) != 0, "block 12 and 12 + 2^32 share their deviates");
}

/* The vector Philox at each width the CPU has (src/core/philox_kernel.h: 8 lanes with AVX2, 16 with AVX-512) against
 * Random123's scalar philox4x32 and the uniform formula of wf_rng_uniform2, bit for bit: random keys and counters
 * (high words included), and every length up to 41 (the kernel does whole vectors and leaves the rest). */
static void test_vector_philox(void)
{
#if defined(__x86_64__)
    const struct {
        const char *name;
        WfSimdLevel level;
        size_t lanes;
        void (*fn)(uint32_t, uint32_t, uint32_t, uint32_t, uint32_t, uint32_t, size_t, double *, double *);
    } widths[] = {{"AVX2", WF_SIMD_AVX2, 8, wf_philox_uniforms_avx2},
                  {"AVX-512", WF_SIMD_AVX512, 16, wf_philox_uniforms_avx512}};
    for (size_t wi = 0; wi < sizeof widths / sizeof widths[0]; wi++) {
        if (wf_simd_level() < widths[wi].level) {
            printf("SKIP vector_philox %s: not on this CPU (or capped by WAVEFUEL_SIMD)\n", widths[wi].name);
            continue;
        }
        uint64_t s = 0x9E3779B97F4A7C15ull;
        size_t bad = 0, total = 0;
        for (int trial = 0; trial < 200; trial++) {
            uint32_t w[6];
            for (int k = 0; k < 6; k++)
                s = s * 6364136223846793005ull + 1442695040888963407ull, w[k] = (uint32_t)(s >> 32);
            size_t calls = (size_t)trial % 42;
            double u1[48], u2[48];
            for (size_t j = 0; j < 48; j++) u1[j] = u2[j] = -1.0;
            widths[wi].fn(w[0], w[1], w[2], w[3], w[4], w[5], calls, u1, u2);
            for (size_t j = 0; j < calls; j++) {
                philox4x32_ctr_t c = {{w[2], w[3], w[4], w[5] + (uint32_t)j}};
                philox4x32_key_t k = {{w[0], w[1]}};
                philox4x32_ctr_t r = philox4x32(c, k);
                uint64_t x = ((uint64_t)r.v[0] << 32) | r.v[1], y = ((uint64_t)r.v[2] << 32) | r.v[3];
                double e1 = ((double)(x >> 11) + 0.5) * 0x1p-53, e2 = ((double)(y >> 11) + 0.5) * 0x1p-53;
                int whole = j < (calls & ~(widths[wi].lanes - 1));
                /* past the last whole vector the kernel writes nothing */
                bad += whole ? (u1[j] != e1 || u2[j] != e2) : (u1[j] != -1.0 || u2[j] != -1.0);
                total++;
            }
        }
        CHECK(bad == 0, "%s: %zu of %zu calls differ from Random123's philox4x32 (or were written past the whole "
              "vectors)", widths[wi].name, bad, total);
    }
#endif
}

/* Box-Muller at each width the CPU has against the 2-lane kernel, bit for bit, on uniforms from every part of
 * (0, 1) (the ends too); and each element in the right place: the 2-lane kernel's pairs against libm's formula to
 * a few ulp (another implementation of the same deviates). */
static void test_box_muller_widths(void)
{
#if defined(__x86_64__)
    enum { PAIRS = 4096 };
    static double u1[PAIRS], u2[PAIRS], ref[2 * PAIRS], got[2 * PAIRS];
    uint64_t s = 0x2545F4914F6CDD1Dull;
    for (size_t p = 0; p < PAIRS; p++) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        u1[p] = ((double)(s >> 11) + 0.5) * 0x1p-53;
        u2[p] = ((double)((s * 0x9E3779B97F4A7C15ull) >> 11)) * 0x1p-53;
    }
    u1[0] = 0x1p-54, u1[1] = 1.0 - 0x1p-54, u2[2] = 0.0, u2[3] = 0.5, u2[4] = 0.25;
    wf_noise_sse2(PAIRS, u1, u2, ref);
    size_t far = 0;
    for (size_t p = 0; p < PAIRS; p++) {
        double r = sqrt(-2.0 * log(u1[p])), c = r * cos(6.283185307179586476925 * u2[p]),
               sn = r * sin(6.283185307179586476925 * u2[p]);
        far += fabs(ref[2 * p] - c) > 1e-13 * (1.0 + r) || fabs(ref[2 * p + 1] - sn) > 1e-13 * (1.0 + r);
    }
    CHECK(far == 0, "%zu of %d pairs of the 2-lane kernel far from libm's Box-Muller", far, PAIRS);
    const struct {
        const char *name;
        WfSimdLevel level;
        void (*fn)(size_t, const double *, const double *, double *);
    } widths[] = {{"AVX", WF_SIMD_AVX, wf_noise_avx}, {"AVX-512", WF_SIMD_AVX512, wf_noise_avx512}};
    for (size_t wi = 0; wi < sizeof widths / sizeof widths[0]; wi++) {
        if (wf_simd_level() < widths[wi].level) {
            printf("SKIP box_muller %s: not on this CPU (or capped by WAVEFUEL_SIMD)\n", widths[wi].name);
            continue;
        }
        memset(got, 0, sizeof got);
        widths[wi].fn(PAIRS, u1, u2, got);
        size_t bad = 0;
        for (size_t i = 0; i < 2 * PAIRS; i++) bad += memcmp(&got[i], &ref[i], sizeof got[i]) != 0;
        CHECK(bad == 0, "%s: %zu of %d deviates differ from the 2-lane kernel's", widths[wi].name, bad, 2 * PAIRS);
    }
#endif
}

/* Rings drawn together (wf_rng_normal_rings, a gang block's noise) against each ring's own wf_rng_normal_block, bit
 * for bit: random seeds (high words included), steps past 2^32, odd and even counts, up to the most pairs a block
 * can ask for. */
static void test_normal_rings(void)
{
    uint64_t s = 0xD1B54A32D192ED03ull, seed[64], step[64];
    size_t n[64], bad = 0, total = 0;
    double got[600], want[600];
    for (int trial = 0; trial < 300; trial++) {
        size_t nr = 0, pairs = 0, sum = 0;
        for (; nr < 64; nr++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            size_t m = 1 + (size_t)(s >> 59) + (trial % 3 == 0 ? 20 : 0);
            if (pairs + (m + 1) / 2 > WF_RNG_RINGS_PAIRS || (size_t)trial % 40 < nr) break;
            seed[nr] = s ^ (s << 17), step[nr] = (s >> 20) + (nr % 3 == 0 ? (1ull << 32) : 0), n[nr] = m;
            pairs += (m + 1) / 2, sum += m;
        }
        uint64_t block = trial % 2 ? 0 : 7;
        wf_rng_normal_rings(nr, seed, WF_RNG_NOISE_BLOCK, block, step, n, got);
        for (size_t r = 0, o = 0; r < nr; o += n[r++])
            wf_rng_normal_block(seed[r], WF_RNG_NOISE_BLOCK, block, step[r], n[r], want + o);
        for (size_t i = 0; i < sum; i++) bad += memcmp(&got[i], &want[i], sizeof got[i]) != 0;
        total += sum;
    }
    CHECK(bad == 0 && total > 10000, "%zu of %zu deviates differ from the rings' own blocks", bad, total);
}

int main(void)
{
    RUN(test_vector_philox);
    RUN(test_box_muller_widths);
    RUN(test_normal_rings);
    RUN(test_moments_and_tails);
    RUN(test_kolmogorov_smirnov);
    RUN(test_pure_function);
    TEST_EXIT();
}
