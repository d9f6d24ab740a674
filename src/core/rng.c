/* Philox4x32-10 from Random123: key = seed, counter = (stream, a, b). 53-bit uniforms in (0,1), Box-Muller
 * normals, and blocks of normals: Box-Muller over vectors with SLEEF's logarithm and sine/cosine. */
#include "wavefuel/rng.h"

#include <math.h>
#include <stdatomic.h>
#include <string.h>
#include <threads.h>
#include <Random123/philox.h>

#include "core/noise.h"
#include "core/simd.h"
#include "util/clock.h"

/* The uniform of two Philox words hi:lo: its top 53 bits, (k + 0.5) / 2^53, strictly inside (0, 1) (log never sees
 * 0). The one scalar form of the rule (src/core/philox_kernel.h forms the same value in vectors; tests/test_rng.c). */
static inline double uniform53(uint32_t hi, uint32_t lo)
{
    return ((double)((((uint64_t)hi << 32) | lo) >> 11) + 0.5) * 0x1p-53;
}

static void draw(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double u[2])
{
    philox4x32_key_t k = {{(uint32_t)seed, (uint32_t)(seed >> 32)}};
    /* 32 bits of a and of b: vehicle and step indices stay far below 2^32 for any feasible run; the high
     * bits are folded into the stream word so distinct (a, b) pairs still give distinct counters. */
    philox4x32_ctr_t c = {{(uint32_t)a, (uint32_t)b, stream ^ (uint32_t)(a >> 32) * 0x9E3779B9u,
                           (uint32_t)(b >> 32)}};
    philox4x32_ctr_t r = philox4x32(c, k);
    u[0] = uniform53(r.v[0], r.v[1]);
    u[1] = uniform53(r.v[2], r.v[3]);
}

void wf_rng_uniform2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2])
{
    draw(seed, stream, a, b, out);
}

void wf_rng_normal2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2])
{
    double u[2];
    draw(seed, stream, a, b, u);
    double r = sqrt(-2.0 * log(u[0]));
    double ang = 6.283185307179586476925 * u[1];
    out[0] = r * cos(ang);
    out[1] = r * sin(ang);
}

/* The uniforms of Philox calls (c0, c1, c2, first), (c0, c1, c2, first + 1), ...: call j's words (r0, r1, r2, r3)
 * give u1[j] and u2[j] as draw() does. Where the CPU has no AVX2 (a vector kernel otherwise: kernels()). */
WF_SIMD_CLONES
static void philox_uniforms(philox4x32_key_t key, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first,
                            size_t calls, double *restrict u1, double *restrict u2)
{
    /* A size_t index: with a 32-bit one GCC 12 does not vectorise this loop. */
#pragma omp simd
    for (size_t j = 0; j < calls; j++) {
        philox4x32_ctr_t c = {{c0, c1, c2, first + (uint32_t)j}};
        philox4x32_ctr_t r = philox4x32(c, key);
        u1[j] = uniform53(r.v[0], r.v[1]);
        u2[j] = uniform53(r.v[2], r.v[3]);
    }
}

typedef void BoxMuller(size_t pairs, const double *u1, const double *u2, double *z);

/* Word 2 of the counter of (stream, block, step): the high halves of block and step folded in, as draw() does. */
static uint32_t word2(uint32_t stream, uint64_t block, uint64_t step)
{
    return stream ^ (uint32_t)(block >> 32) * 0x9E3779B9u ^ (uint32_t)(step >> 32) * 0x85EBCA6Bu;
}

#define NB_CHUNK 128 /* pairs per chunk: the buffers below stay on the stack (4 kB) */
enum { BM_LANES = 8 }; /* the widest Box-Muller kernel's lanes: callers pad the pairs to a multiple of it */
enum { PHILOX_LANES = 16 }; /* the widest vector Philox's calls at once (the others' divide it) */
_Static_assert(NB_CHUNK % PHILOX_LANES == 0 && NB_CHUNK % BM_LANES == 0, "the vector kernels fill whole vectors");

typedef void PhiloxUniforms(uint32_t k0, uint32_t k1, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first,
                            size_t calls, double *u1, double *u2);
typedef void PhiloxLanes(const uint32_t *const k[2], const uint32_t *const c[4], size_t calls, double *u1,
                         double *u2);

/* The vector kernels, chosen once per process among the widths this CPU runs (core/simd.h). Every width gives the
 * same bits (tests/test_rng.c), but which is fastest differs between CPUs: SLEEF 3.5's 8-lane logarithm took 27 % of
 * a one-thread step against 4 % for its 4-lane one on a Zen 5 (bench/README.md, "AVX-512 (session 10)"), where on a
 * Xeon with AVX-512 the 8-lane Box-Muller takes half the 4-lane one's time. So the first draw times each width on a
 * chunk of pairs (some 3 ms in all, once per process, only where noise is drawn) and keeps the fastest: the choice
 * changes speed, never bits. */
typedef struct {
    BoxMuller      *box_muller;
    PhiloxUniforms *philox;  /* NULL: the plain loop (no AVX2) */
    PhiloxLanes    *lanes;
} NoiseKernels;

#if defined(__x86_64__)
#define SPAN_S 1.5e-4
enum { CALLS = 4 };

/* Of the candidates k < n that the CPU runs, the one with the shortest round (CALLS calls), each timed over a
 * stretch of SPAN_S seconds, widest first, twice. A core runs its first wide instructions slowly (on a Xeon the
 * 8-lane Box-Muller ran at half speed for its first 1.5 ms, and timed in short rounds among the others it stayed
 * there and lost to the 4-lane one), so the widest first runs warm_s alone. */
static int fastest(int n, const WfSimdLevel *need, void (*run)(int k, void *arg), void *arg, double warm_s)
{
    double best[4] = {INFINITY, INFINITY, INFINITY, INFINITY};
    int top = 0;
    while (top + 1 < n && wf_simd_level() >= need[top + 1]) top++;
    for (double end = wf_wall_now() + warm_s; wf_wall_now() < end;) run(top, arg);
    for (int pass = 0; pass < 2; pass++)
        for (int k = top; k >= 0; k--)
            for (double end = wf_wall_now() + SPAN_S, t0 = wf_wall_now(), t1; t0 < end; t0 = t1) {
                for (int c = 0; c < CALLS; c++) run(k, arg);
                t1 = wf_wall_now();
                if (t1 - t0 < best[k]) best[k] = t1 - t0;
            }
    int pick = 0;
    for (int k = 1; k <= top; k++)
        if (best[k] < best[pick]) pick = k;
    return pick;
}

typedef struct {
    double u1[NB_CHUNK], u2[NB_CHUNK], z[2 * NB_CHUNK];
} TimeBuf;

static BoxMuller *const BM[] = {wf_noise_sse2, wf_noise_avx, wf_noise_avx512};
static PhiloxUniforms *const PH[] = {wf_philox_uniforms_avx2, wf_philox_uniforms_avx512};
static PhiloxLanes *const PL[] = {wf_philox_uniforms_lanes_avx2, wf_philox_uniforms_lanes_avx512};

static void time_box_muller(int k, void *arg)
{
    TimeBuf *b = arg;
    BM[k](NB_CHUNK, b->u1, b->u2, b->z);
}

static void time_philox(int k, void *arg)
{
    TimeBuf *b = arg;
    PH[k](1u, 2u, 3u, 4u, 5u, 6u, NB_CHUNK, b->u1, b->u2);
}

static int choose(void)
{
    static const WfSimdLevel bm_need[] = {WF_SIMD_BASE, WF_SIMD_AVX, WF_SIMD_AVX512};
    static const WfSimdLevel ph_need[] = {WF_SIMD_AVX2, WF_SIMD_AVX512};
    TimeBuf b;
    for (size_t j = 0; j < NB_CHUNK; j++) b.u1[j] = ((double)j + 0.5) / NB_CHUNK, b.u2[j] = (double)j / NB_CHUNK;
    int bm = fastest(3, bm_need, time_box_muller, &b, 1.5e-3); /* the core is warm for the Philox kernels then */
    return bm + 4 * (wf_simd_level() >= WF_SIMD_AVX2 ? 1 + fastest(2, ph_need, time_philox, &b, 0.0) : 0);
}

static NoiseKernels kernels_of(int code)
{
    int ph = code / 4 - 1;
    return (NoiseKernels){BM[code % 4], ph >= 0 ? PH[ph] : NULL, ph >= 0 ? PL[ph] : NULL};
}
#else
/* Elsewhere: the same formula with libm (bits may differ from x86-64's SLEEF in the last place). */
static void box_muller_libm(size_t pairs, const double *u1, const double *u2, double *z)
{
    for (size_t p = 0; p < pairs; p++) {
        double r = sqrt(-2.0 * log(u1[p]));
        z[2 * p] = r * cos(6.283185307179586476925 * u2[p]);
        z[2 * p + 1] = r * sin(6.283185307179586476925 * u2[p]);
    }
}

static int choose(void) { return 0; }
static NoiseKernels kernels_of(int code) { return (void)code, (NoiseKernels){box_muller_libm, NULL, NULL}; }
#endif

/* The process's kernels, chosen on the first call by one thread while any other waits (timings taken side by side
 * would disturb each other). The choice is an atomic as well: glibc's call_once does not go through the
 * pthread_once that ThreadSanitizer watches, so it would not see the ordering call_once gives. */
static _Atomic int chosen_code;
static void choose_once(void) { atomic_store_explicit(&chosen_code, choose(), memory_order_release); }

static NoiseKernels kernels(void)
{
    static once_flag once = ONCE_FLAG_INIT;
    call_once(&once, choose_once);
    return kernels_of(atomic_load_explicit(&chosen_code, memory_order_acquire));
}

void wf_rng_normal_block(uint64_t seed, uint32_t stream, uint64_t block, uint64_t step, size_t n, double *out)
{
    philox4x32_key_t key = {{(uint32_t)seed, (uint32_t)(seed >> 32)}};
    /* Word 3 counts the pairs; the high halves of block and step are folded into word 2 as in draw(). */
    uint32_t c0 = (uint32_t)block, c1 = (uint32_t)step, c2 = word2(stream, block, step);
    NoiseKernels nk = kernels();
    BoxMuller *bm = nk.box_muller;
    PhiloxUniforms *vec = nk.philox;
    double u1[NB_CHUNK], u2[NB_CHUNK], z[2 * NB_CHUNK];
    size_t pairs = (n + 1) / 2;
    for (size_t p0 = 0; p0 < pairs; p0 += NB_CHUNK) {
        size_t cnt = pairs - p0 < NB_CHUNK ? pairs - p0 : NB_CHUNK;
        size_t padded = (cnt + BM_LANES - 1) & ~(size_t)(BM_LANES - 1);
        /* whole vectors of calls, the last vector's extra uniforms unused (each call is independent) */
        if (vec)
            vec(key.v[0], key.v[1], c0, c1, c2, (uint32_t)p0, (cnt + PHILOX_LANES - 1) & ~(size_t)(PHILOX_LANES - 1),
                u1, u2);
        else
            philox_uniforms(key, c0, c1, c2, (uint32_t)p0, cnt, u1, u2);
        for (size_t j = cnt; j < padded; j++) u1[j] = 0.5, u2[j] = 0.5;
        bm(padded, u1, u2, z);
        size_t lo = 2 * p0, m = n - lo < 2 * cnt ? n - lo : 2 * cnt;
        memcpy(out + lo, z, m * sizeof *z);
    }
}

void wf_rng_normal_rings(size_t nr, const uint64_t *seed, uint32_t stream, uint64_t block, const uint64_t *step,
                         const size_t *n, double *out)
{
    enum { P = WF_RNG_RINGS_PAIRS + PHILOX_LANES };
    /* one Philox call a pair, each with its ring's key and counter (block, step, word 2, pair); padded to a whole
     * vector of calls with copies of the last (independent calls: the padding's uniforms are not used) */
    uint32_t kw[2][P], cw[4][P];
    size_t calls = 0;
    for (size_t r = 0; r < nr; r++)
        for (size_t p = 0; p < (n[r] + 1) / 2; p++, calls++) {
            kw[0][calls] = (uint32_t)seed[r], kw[1][calls] = (uint32_t)(seed[r] >> 32);
            cw[0][calls] = (uint32_t)block, cw[1][calls] = (uint32_t)step[r];
            cw[2][calls] = word2(stream, block, step[r]), cw[3][calls] = (uint32_t)p;
        }
    double u1[P], u2[P], z[2 * P];
    size_t padded = (calls + PHILOX_LANES - 1) & ~(size_t)(PHILOX_LANES - 1);
    for (size_t j = calls; j < padded; j++) {
        for (int w = 0; w < 2; w++) kw[w][j] = kw[w][calls - 1];
        for (int w = 0; w < 4; w++) cw[w][j] = cw[w][calls - 1];
    }
    PhiloxLanes *lanes = kernels().lanes;
    if (lanes) {
        const uint32_t *const k[2] = {kw[0], kw[1]}, *const c[4] = {cw[0], cw[1], cw[2], cw[3]};
        lanes(k, c, padded, u1, u2);
    } else
        for (size_t j = 0; j < calls; j++) {
            philox4x32_key_t key = {{kw[0][j], kw[1][j]}};
            philox4x32_ctr_t ctr = {{cw[0][j], cw[1][j], cw[2][j], cw[3][j]}}, w = philox4x32(ctr, key);
            u1[j] = uniform53(w.v[0], w.v[1]), u2[j] = uniform53(w.v[2], w.v[3]);
        }
    size_t whole = (calls + BM_LANES - 1) & ~(size_t)(BM_LANES - 1);
    for (size_t j = calls; j < whole; j++) u1[j] = 0.5, u2[j] = 0.5;
    kernels().box_muller(whole, u1, u2, z);
    for (size_t r = 0, p0 = 0; r < nr; p0 += (n[r] + 1) / 2, r++) {
        memcpy(out, z + 2 * p0, n[r] * sizeof *out);
        out += n[r];
    }
}
