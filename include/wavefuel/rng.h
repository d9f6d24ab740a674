/* Counter-based random numbers (Random123 Philox4x32-10): every draw is a pure function of (seed, stream,
 * a, b), e.g. (seed, WF_RNG_NOISE, vehicle, step), so results do not depend on thread count or order. */
#ifndef WAVEFUEL_RNG_H
#define WAVEFUEL_RNG_H

#include <stdint.h>

/* Streams keep unrelated uses of one seed independent. */
enum { WF_RNG_NOISE = 1, WF_RNG_PLACEMENT = 2, WF_RNG_HETERO = 3, WF_RNG_JITTER = 4, WF_RNG_USER = 16 };

/* Two independent standard normal deviates (Box-Muller on two open-interval uniforms). */
void wf_rng_normal2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2]);
/* Two independent uniforms in (0, 1). */
void wf_rng_uniform2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2]);

#endif
