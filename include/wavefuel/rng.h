/* Counter-based random numbers (Random123 Philox4x32-10): every draw is a pure function of (seed, stream,
 * a, b), e.g. (seed, WF_RNG_NOISE, vehicle, step), so results do not depend on thread count or order. */
#ifndef WAVEFUEL_RNG_H
#define WAVEFUEL_RNG_H

#include <stddef.h>
#include <stdint.h>

/* Streams keep unrelated uses of one seed independent. */
enum { WF_RNG_NOISE = 1, WF_RNG_PLACEMENT = 2, WF_RNG_HETERO = 3, WF_RNG_JITTER = 4, WF_RNG_NOISE_BLOCK = 5,
       WF_RNG_USER = 16 };

/* Two independent standard normal deviates (Box-Muller on two open-interval uniforms). */
void wf_rng_normal2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2]);
/* Two independent uniforms in (0, 1). */
void wf_rng_uniform2(uint64_t seed, uint32_t stream, uint64_t a, uint64_t b, double out[2]);
/* n standard normal deviates for the items of one block at one step: Box-Muller on 53-bit uniforms, item pair p
 * from the Philox4x32-10 output at counter (block, step, stream, p), evaluated four lanes wide with SLEEF's
 * consistent (no-FMA) log and sincospi (3.5 ulp), which give the same bits on every x86-64 vector extension. A pure function
 * of (seed, stream, block, step, n); a block's first k deviates do not depend on n. */
void wf_rng_normal_block(uint64_t seed, uint32_t stream, uint64_t block, uint64_t step, size_t n, double *out);

#endif
