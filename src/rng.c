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
 * the key and the first three counter words. */
typedef struct PhiloxStream {
    philox4x32_key_t key;
    philox4x32_ctr_t ctr;
    philox4x32_ctr_t out;
    unsigned used; /* words of out already handed out (4: refill) */
} PhiloxStream;

static unsigned long stream_get(void *vs)
{
    PhiloxStream *s = vs;
    if (s->used == 4) {
        s->out = philox4x32(s->ctr, s->key);
        s->ctr.v[3]++;
        s->used = 0;
    }
    return s->out.v[s->used++];
}

static double stream_get_double(void *vs) { return (double)stream_get(vs) * 0x1p-32; }

/* set is never called: wf_rng_normal_block fills the state itself. */
static void stream_set(void *vs, unsigned long seed)
{
    (void)seed;
    ((PhiloxStream *)vs)->used = 4;
}

static const gsl_rng_type philox_stream_type = {
    "wavefuel-philox4x32-10-stream", 0xFFFFFFFFUL, 0, sizeof(PhiloxStream),
    stream_set, stream_get, stream_get_double,
};

void wf_rng_normal_block(uint64_t seed, uint32_t stream, uint64_t block, uint64_t step, size_t n, double *out)
{
    PhiloxStream st = {
        .key = {{(uint32_t)seed, (uint32_t)(seed >> 32)}},
        /* Word 3 counts the refills; the high halves of block and step are folded into word 2 as in draw(). */
        .ctr = {{(uint32_t)block, (uint32_t)step,
                 stream ^ (uint32_t)(block >> 32) * 0x9E3779B9u ^ (uint32_t)(step >> 32) * 0x85EBCA6Bu, 0}},
        .used = 4,
    };
    gsl_rng r = {&philox_stream_type, &st};
    for (size_t k = 0; k < n; k++) out[k] = gsl_ran_gaussian_ziggurat(&r, 1.0);
}
