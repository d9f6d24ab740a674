/* Philox4x32-10 from Random123: key = seed, counter = (stream, a, b). 53-bit uniforms in (0,1) and
 * Box-Muller normals. */
#include "wavefuel/rng.h"

#include <math.h>
#include <Random123/philox.h>

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
