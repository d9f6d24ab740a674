/* Philox4x32-10 over 16 counters at once with AVX-512 (this file is compiled with -mavx512f and called only where
 * the CPU has x86-64-v4's AVX-512): see philox_kernel.h. Twice the counters of the AVX2 form a vector instruction:
 * perf gave the AVX2 form 13.6 % of the 10^6-vehicle scaling ring's step on two threads (Xeon, AVX-512). */
#if defined(__x86_64__) && defined(__AVX512F__)
#include <immintrin.h>

#include "core/noise.h"

#define PK_LANES          16
#define PK_V              __m512i
#define PK_D              __m512d
#define PK_MUL            _mm512_mul_epu32
#define PK_SRL64          _mm512_srli_epi64
#define PK_SLL64          _mm512_slli_epi64
#define PK_SRL32          _mm512_srli_epi32
#define PK_ODD(a, b)      _mm512_mask_blend_epi32((__mmask16)0xAAAA, a, b)
#define PK_XOR            _mm512_xor_si512
#define PK_ADD32          _mm512_add_epi32
#define PK_SET1_32        _mm512_set1_epi32
#define PK_SET1_64        _mm512_set1_epi64
#define PK_LOAD(p)        _mm512_loadu_si512((const void *)(p))
#define PK_IOTA           _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)
#define PK_HALF_PD(v, h)  _mm512_cvtepi32_pd((h) ? _mm512_extracti64x4_epi64(v, 1) : _mm512_castsi512_si256(v))
#define PK_DADD           _mm512_add_pd
#define PK_DMUL           _mm512_mul_pd
#define PK_DSET1          _mm512_set1_pd
#define PK_DSTORE         _mm512_storeu_pd
#define PK_UNIFORMS       wf_philox_uniforms_avx512
#define PK_UNIFORMS_LANES wf_philox_uniforms_lanes_avx512
#include "core/philox_kernel.h"
#endif
