/* Philox4x32-10 from Random123: key = seed, counter = (stream, a, b). 53-bit uniforms in (0,1), Box-Muller
 * normals, and blocks of normals from GSL's ziggurat fed by one Philox stream per block. */
#include "wavefuel/rng.h"

#include <math.h>
#include <Random123/philox.h>
#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

static void draw(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double u[2])
{
    philox4x32_key_t k = {{(uint32_t)seed, (uint32_t)(seed >> 32)}};
    /* 32 bits of a and of b: vehicle and step indices stay far below 2^32 for any feasible run; the high
     * bits are folded into the stream word so distinct (a, b) pairs still give distinct counters. */
    philox4x32_ctr_t c = {{(uint32_t)a, (uint32_t)b, stream ^ (uint32_t)(a >> 32) * 0x9E3779B9u,
                           (uint32_t)(b >> 32)}};
    philox4x32_ctr_t r = philox4x32(c, k);
    uint64_t x = ((uint64_t)r.v[0] << 32) | r.v[1], y = ((uint64_t)r.v[2] << 32) | r.v[3];
    /* (k + 0.5) / 2^53 lies strictly inside (0, 1): log() below never sees 0. */
    u[0] = ((double)(x >> 11) + 0.5) * 0x1p-53;
    u[1] = ((double)(y >> 11) + 0.5) * 0x1p-53;
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

/* A gsl_rng whose words are the successive outputs of Philox4x32-10 at counters (c0, c1, c2, 0), (c0, c1, c2, 1),
 * ...: GSL's ziggurat draws from it like from any 32-bit generator, and the whole sequence is a pure function of
 * the key and the first three counter words. The words are computed ahead in batches (one vectorised loop: the
 * Philox rounds of independent counters run side by side) and handed out one by one. */
#define STREAM_BATCH 80 /* Philox calls per batch: 320 words, a block of 256 deviates and its rejections */

typedef struct PhiloxStream {
    philox4x32_key_t key;
    uint32_t c0, c1, c2;
    uint32_t next_call; /* counter word 3 of the next batch's first call */
    unsigned used, have; /* words of buf handed out / filled */
    uint32_t buf[4 * STREAM_BATCH];
} PhiloxStream;

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
__attribute__((target_clones("avx2", "default")))
#endif
static void philox_fill(philox4x32_key_t key, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first, unsigned calls,
                        uint32_t *restrict out)
{
#pragma omp simd
    for (unsigned j = 0; j < calls; j++) {
        philox4x32_ctr_t c = {{c0, c1, c2, first + j}};
        philox4x32_ctr_t r = philox4x32(c, key);
        out[4 * j] = r.v[0], out[4 * j + 1] = r.v[1], out[4 * j + 2] = r.v[2], out[4 * j + 3] = r.v[3];
    }
}

static void stream_refill(PhiloxStream *s, unsigned calls)
{
    philox_fill(s->key, s->c0, s->c1, s->c2, s->next_call, calls, s->buf);
    s->next_call += calls;
    s->used = 0;
    s->have = 4 * calls;
}

static unsigned long stream_get(void *vs)
{
    PhiloxStream *s = vs;
    if (s->used == s->have) stream_refill(s, 16); /* past the first batch: rejections beyond the margin */
    return s->buf[s->used++];
}

static double stream_get_double(void *vs) { return (double)stream_get(vs) * 0x1p-32; }

/* set is never called: wf_rng_normal_block fills the state itself. */
static void stream_set(void *vs, unsigned long seed)
{
    (void)seed;
    ((PhiloxStream *)vs)->used = ((PhiloxStream *)vs)->have;
}

static const gsl_rng_type philox_stream_type = {
    "wavefuel-philox4x32-10-stream", 0xFFFFFFFFUL, 0, sizeof(PhiloxStream),
    stream_set, stream_get, stream_get_double,
};

void wf_rng_normal_block(uint64_t seed, uint32_t stream, uint64_t block, uint64_t step, size_t n, double *out)
{
    PhiloxStream st;
    st.key = (philox4x32_key_t){{(uint32_t)seed, (uint32_t)(seed >> 32)}};
    /* Word 3 counts the calls; the high halves of block and step are folded into word 2 as in draw(). */
    st.c0 = (uint32_t)block, st.c1 = (uint32_t)step;
    st.c2 = stream ^ (uint32_t)(block >> 32) * 0x9E3779B9u ^ (uint32_t)(step >> 32) * 0x85EBCA6Bu;
    st.next_call = 0;
    /* One word per deviate plus about 1.2 % rejections (each takes one or two more words): n + n/32 + 8 words
     * almost always suffice; the rest comes in further batches. */
    size_t words = n + n / 32 + 8, calls = (words + 3) / 4;
    stream_refill(&st, (unsigned)(calls < STREAM_BATCH ? calls : STREAM_BATCH));
    gsl_rng r = {&philox_stream_type, &st};
    for (size_t k = 0; k < n; k++) out[k] = gsl_ran_gaussian_ziggurat(&r, 1.0);
}
