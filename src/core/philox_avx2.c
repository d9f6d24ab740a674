/* Philox4x32-10 over 8 counters at once with AVX2 (this file is compiled with -mavx2 and called only where the CPU
 * has AVX2): see philox_kernel.h. */
#if defined(__x86_64__) && defined(__AVX2__)
#include <immintrin.h>

#include "core/noise.h"

#define PK_LANES          8
#define PK_V              __m256i
#define PK_D              __m256d
#define PK_MUL            _mm256_mul_epu32
#define PK_SRL64          _mm256_srli_epi64
#define PK_SLL64          _mm256_slli_epi64
#define PK_SRL32          _mm256_srli_epi32
#define PK_ODD(a, b)      _mm256_blend_epi32(a, b, 0xAA)
#define PK_XOR            _mm256_xor_si256
#define PK_ADD32          _mm256_add_epi32
#define PK_SET1_32        _mm256_set1_epi32
#define PK_SET1_64        _mm256_set1_epi64x
#define PK_LOAD(p)        _mm256_loadu_si256((const __m256i *)(p))
#define PK_IOTA           _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)
#define PK_HALF_PD(v, h)  _mm256_cvtepi32_pd((h) ? _mm256_extracti128_si256(v, 1) : _mm256_castsi256_si128(v))
#define PK_DADD           _mm256_add_pd
#define PK_DMUL           _mm256_mul_pd
#define PK_DSET1          _mm256_set1_pd
#define PK_DSTORE         _mm256_storeu_pd
#define PK_UNIFORMS       wf_philox_uniforms_avx2
#define PK_UNIFORMS_LANES wf_philox_uniforms_lanes_avx2
#include "core/philox_kernel.h"
#endif
