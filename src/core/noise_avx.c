/* Box-Muller, 4 lanes (AVX; this file is compiled with -mavx and called only where the CPU has AVX): see
 * noise_kernel.h. */
#if defined(__x86_64__) && defined(__AVX__)
#include <immintrin.h>
#include <stdint.h>
#include <sleef.h>

#include "core/noise.h"

#define NK_NAME       wf_noise_box_muller_avx
#define NK_LANES      4
#define NK_VEC        __m256d
#define NK_SC         Sleef___m256d_2
#define NK_SPLAT      _mm256_set1_pd
#define NK_MUL        _mm256_mul_pd
#define NK_SQRT       _mm256_sqrt_pd
#define NK_LOG        Sleef_cinz_logd4_u35avx
#define NK_SINCOSPI   Sleef_cinz_sincospid4_u35avx
/* c0 s0 c2 s2 and c1 s1 c3 s3, then their low and high halves */
#define NK_STORE2(z, c, s)                                                                                     \
    (_mm256_storeu_pd(z, _mm256_permute2f128_pd(_mm256_unpacklo_pd(c, s), _mm256_unpackhi_pd(c, s), 0x20)),    \
     _mm256_storeu_pd((z) + 4, _mm256_permute2f128_pd(_mm256_unpacklo_pd(c, s), _mm256_unpackhi_pd(c, s), 0x31)))
#include "core/noise_kernel.h"

void wf_noise_avx(size_t pairs, const double *u1, const double *u2, double *z)
{
    NK_NAME(pairs, u1, u2, z);
}
#endif
