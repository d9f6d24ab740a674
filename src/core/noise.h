/* Box-Muller kernels over arrays of uniforms (src/noise_*.c), used by wf_rng_normal_block. pairs: a multiple
 * of 4; z receives 2 * pairs deviates. */
#ifndef WAVEFUEL_NOISE_H
#define WAVEFUEL_NOISE_H

#include <stddef.h>

void wf_noise_sse2(size_t pairs, const double *u1, const double *u2, double *z);
void wf_noise_avx(size_t pairs, const double *u1, const double *u2, double *z);

#endif
