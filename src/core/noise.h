/* Box-Muller kernels over arrays of uniforms (src/core/noise_*.c; pairs: a multiple of the kernel's lanes, 2, 4 or
 * 8; z receives 2 * pairs deviates) and the vector Philox (src/core/philox_kernel.h, 8 and 16 lanes), used by
 * wf_rng_normal_block. Each is called only where the CPU has its instructions (core/simd.h); all give the same
 * bits. */
#ifndef WAVEFUEL_NOISE_H
#define WAVEFUEL_NOISE_H

#include <stddef.h>
#include <stdint.h>

void wf_noise_sse2(size_t pairs, const double *u1, const double *u2, double *z);
void wf_noise_avx(size_t pairs, const double *u1, const double *u2, double *z);
void wf_noise_avx512(size_t pairs, const double *u1, const double *u2, double *z);

/* The uniforms of Philox4x32-10 calls with key (k0, k1) and counters (c0, c1, c2, first + j) for j < calls rounded
 * down to a multiple of the lanes (8: AVX2; 16: AVX-512): u1[j] from words 0 and 1, u2[j] from words 2 and 3, each
 * ((w_a:w_b >> 11) + 0.5) 2^-53. */
void wf_philox_uniforms_avx2(uint32_t k0, uint32_t k1, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first,
                             size_t calls, double *u1, double *u2);
void wf_philox_uniforms_avx512(uint32_t k0, uint32_t k1, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first,
                               size_t calls, double *u1, double *u2);

/* The same for calls j < calls (rounded down likewise) each with its own key (k[0][j], k[1][j]) and counter
 * (c[0][j], c[1][j], c[2][j], c[3][j]). */
void wf_philox_uniforms_lanes_avx2(const uint32_t *const k[2], const uint32_t *const c[4], size_t calls, double *u1,
                                   double *u2);
void wf_philox_uniforms_lanes_avx512(const uint32_t *const k[2], const uint32_t *const c[4], size_t calls,
                                     double *u1, double *u2);

/* The deviates of wf_rng_normal_block(seed[r], stream, block, step[r], n[r], .) for r < nr, ring after ring in out
 * (sum of n[r] values), drawn together: the Philox calls of all in whole vectors and one Box-Muller pass (the rings
 * of a gang block, src/core/gang.c). At most WF_RNG_RINGS_PAIRS pairs in all (sum of (n[r] + 1) / 2). */
enum { WF_RNG_RINGS_PAIRS = 256 };
void wf_rng_normal_rings(size_t nr, const uint64_t *seed, uint32_t stream, uint64_t block, const uint64_t *step,
                         const size_t *n, double *out);

#endif
