/* Box-Muller, 8 lanes (AVX-512; this file is compiled with -mavx512f and called only where the CPU has x86-64-v4's
 * AVX-512): see noise_kernel.h. */
#if defined(__x86_64__) && defined(__AVX512F__)
#include <immintrin.h>
#include <stdint.h>
#include <sleef.h>

#include "core/noise.h"

#define NK_NAME       wf_noise_box_muller_avx512
#define NK_LANES      8
#define NK_VEC        __m512d
#define NK_SC         Sleef___m512d_2
#define NK_SPLAT      _mm512_set1_pd
#define NK_MUL        _mm512_mul_pd
#define NK_SQRT       _mm512_sqrt_pd
#define NK_LOG        Sleef_cinz_logd8_u35avx512fnofma
#define NK_SINCOSPI   Sleef_cinz_sincospid8_u35avx512fnofma
/* lanes 0-3 of c and s alternating, then lanes 4-7 (indices 8-15 name s's lanes) */
#define NK_STORE2(z, c, s)                                                                                     \
    (_mm512_storeu_pd(z, _mm512_permutex2var_pd(c, _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11), s)),          \
     _mm512_storeu_pd((z) + 8, _mm512_permutex2var_pd(c, _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15), s)))
#include "core/noise_kernel.h"

void wf_noise_avx512(size_t pairs, const double *u1, const double *u2, double *z)
{
    NK_NAME(pairs, u1, u2, z);
}
#endif
