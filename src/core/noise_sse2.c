/* Box-Muller, 2 lanes (SSE2, every x86-64): see noise_kernel.h. */
#if defined(__x86_64__)
#include <emmintrin.h>
#include <stdint.h>
#include <sleef.h>

#include "core/noise.h"

#define NK_NAME       wf_noise_box_muller_sse2
#define NK_LANES      2
#define NK_VEC        __m128d
#define NK_SC         Sleef___m128d_2
#define NK_SPLAT      _mm_set1_pd
#define NK_MUL        _mm_mul_pd
#define NK_SQRT       _mm_sqrt_pd
#define NK_LOG        Sleef_cinz_logd2_u35sse2
#define NK_SINCOSPI   Sleef_cinz_sincospid2_u35sse2
#include "core/noise_kernel.h"

void wf_noise_sse2(size_t pairs, const double *u1, const double *u2, double *z)
{
    NK_NAME(pairs, u1, u2, z);
}
#endif
