/* Philox4x32-10 (Random123's philox4x32) over 8 counters at once with AVX2, and the uniforms wf_rng_normal_block
 * makes of each call's words (this file is compiled with -mavx2 and called only where the CPU has AVX2). The
 * compiler's vectorisation of Random123's scalar round forms 64-bit products and spends most of its time shuffling
 * them apart (perf: 13 % of the scaling ring's step); here each of the four words stays in one vector of 8 lanes,
 * and the 32 x 32 -> 64-bit products of even and odd lanes are blended back into low and high words; what the first
 * three rounds compute from the counter's words 0-2 alone, the same in every call, is computed once a call. Integer
 * arithmetic and exact conversions: the same bits as the scalar call (tests/test_rng.c compares them). The
 * constants are Random123's. */
#if defined(__x86_64__) && defined(__AVX2__)
#include <immintrin.h>
#include <stddef.h>
#include <stdint.h>
#include <Random123/philox.h>

#include "core/noise.h"

/* lo, hi: the low and high words of m x a, lane by lane. */
static inline void mulhilo8(__m256i m, __m256i a, __m256i *lo, __m256i *hi)
{
    __m256i even = _mm256_mul_epu32(a, m), odd = _mm256_mul_epu32(_mm256_srli_epi64(a, 32), m);
    *lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
    *hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
}

/* (double)(w0:w1 >> 11) for 4 lanes (half 0 or 1 of the 8): w0 * 2^21 + (w1 >> 11), each term exact. */
static inline __m256d top53(__m256i w0, __m256i w1, int half)
{
    const __m256i sign = _mm256_set1_epi32((int)0x80000000u);
    __m256i s0 = _mm256_xor_si256(w0, sign), s1 = _mm256_srli_epi32(w1, 11);
    __m128i h0 = half ? _mm256_extracti128_si256(s0, 1) : _mm256_castsi256_si128(s0);
    __m128i h1 = half ? _mm256_extracti128_si256(s1, 1) : _mm256_castsi256_si128(s1);
    __m256d hi = _mm256_add_pd(_mm256_cvtepi32_pd(h0), _mm256_set1_pd(2147483648.0));
    return _mm256_add_pd(_mm256_mul_pd(hi, _mm256_set1_pd(0x1p21)), _mm256_cvtepi32_pd(h1));
}

/* The two uniforms of each lane's words: u1 from words 0 and 1, u2 from words 2 and 3. */
static inline void store_uniforms(__m256i x0, __m256i x1, __m256i x2, __m256i x3, double *u1, double *u2)
{
    const __m256d half = _mm256_set1_pd(0.5), scale = _mm256_set1_pd(0x1p-53);
    for (int h = 0; h < 2; h++) {
        _mm256_storeu_pd(u1 + 4 * h, _mm256_mul_pd(_mm256_add_pd(top53(x0, x1, h), half), scale));
        _mm256_storeu_pd(u2 + 4 * h, _mm256_mul_pd(_mm256_add_pd(top53(x2, x3, h), half), scale));
    }
}

void wf_philox_uniforms_lanes_avx2(const uint32_t *const k[2], const uint32_t *const c[4], size_t calls, double *u1,
                                   double *u2)
{
    const __m256i m0 = _mm256_set1_epi64x(PHILOX_M4x32_0), m1 = _mm256_set1_epi64x(PHILOX_M4x32_1);
    const __m256i w0 = _mm256_set1_epi32((int)PHILOX_W32_0), w1 = _mm256_set1_epi32((int)PHILOX_W32_1);
#define LOAD(p) _mm256_loadu_si256((const __m256i *)(p + j))
    for (size_t j = 0; j + 8 <= calls; j += 8) {
        __m256i x0 = LOAD(c[0]), x1 = LOAD(c[1]), x2 = LOAD(c[2]), x3 = LOAD(c[3]), key0 = LOAD(k[0]),
                key1 = LOAD(k[1]), lo0, hi0, lo1, hi1;
#pragma GCC unroll 10
        for (int r = 0; r < 10; r++) {
            mulhilo8(m0, x0, &lo0, &hi0);
            mulhilo8(m1, x2, &lo1, &hi1);
            x0 = _mm256_xor_si256(_mm256_xor_si256(hi1, x1), key0);
            x1 = lo1;
            x2 = _mm256_xor_si256(_mm256_xor_si256(hi0, x3), key1);
            x3 = lo0;
            key0 = _mm256_add_epi32(key0, w0), key1 = _mm256_add_epi32(key1, w1);
        }
        store_uniforms(x0, x1, x2, x3, u1 + j, u2 + j);
    }
#undef LOAD
}

void wf_philox_uniforms_avx2(uint32_t k0, uint32_t k1, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first,
                             size_t calls, double *u1, double *u2)
{
    const __m256i m0 = _mm256_set1_epi64x(PHILOX_M4x32_0), m1 = _mm256_set1_epi64x(PHILOX_M4x32_1);
    /* the ten rounds' keys, each in every lane: the key is bumped between rounds */
    __m256i rk0[10], rk1[10];
    for (uint32_t r = 0, key0 = k0, key1 = k1; r < 10; r++, key0 += PHILOX_W32_0, key1 += PHILOX_W32_1)
        rk0[r] = _mm256_set1_epi32((int)key0), rk1[r] = _mm256_set1_epi32((int)key1);
    /* Words 0-2 of the counter are the same in every lane and call: what the first rounds compute of them alone is
     * computed once, here (names: the state's word, after round r). Round 1: both products are constants; x0, x1
     * and x3 come out constant, x2 is a constant xor the lane's word 3. */
    const __m256i c0v = _mm256_set1_epi32((int)c0), c2v = _mm256_set1_epi32((int)c2);
    __m256i p_lo, p_hi, q_lo, q_hi;
    mulhilo8(m0, c0v, &p_lo, &p_hi);
    mulhilo8(m1, c2v, &q_lo, &q_hi);
    const __m256i x0_1 = _mm256_xor_si256(_mm256_xor_si256(q_hi, _mm256_set1_epi32((int)c1)), rk0[0]);
    const __m256i x1_1 = q_lo, x2_1 = _mm256_xor_si256(p_hi, rk1[0]), x3_1 = p_lo;
    /* round 2: the product of x0 is a constant, so x2 and x3 come out constant */
    mulhilo8(m0, x0_1, &p_lo, &p_hi);
    const __m256i k0_2 = _mm256_xor_si256(x1_1, rk0[1]);
    const __m256i x2_2 = _mm256_xor_si256(_mm256_xor_si256(p_hi, x3_1), rk1[1]), x3_2 = p_lo;
    /* round 3: the product of x2 is a constant, so x1 comes out constant */
    mulhilo8(m1, x2_2, &q_lo, &q_hi);
    const __m256i k0_3 = _mm256_xor_si256(q_hi, rk0[2]), x1_3 = q_lo, k2_3 = _mm256_xor_si256(x3_2, rk1[2]);
    const __m256i k0_4 = _mm256_xor_si256(x1_3, rk0[3]);
    for (size_t j = 0; j + 8 <= calls; j += 8) {
        __m256i x3 = _mm256_add_epi32(_mm256_set1_epi32((int)(first + (uint32_t)j)),
                                      _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        __m256i x0, x1, x2, lo0, hi0, lo1, hi1;
        /* round 2 */
        mulhilo8(m1, _mm256_xor_si256(x2_1, x3), &lo1, &hi1);
        x0 = _mm256_xor_si256(hi1, k0_2);
        x1 = lo1;
        /* round 3 */
        mulhilo8(m0, x0, &lo0, &hi0);
        x0 = _mm256_xor_si256(x1, k0_3);
        x2 = _mm256_xor_si256(hi0, k2_3);
        x3 = lo0;
        /* round 4 */
        mulhilo8(m0, x0, &lo0, &hi0);
        mulhilo8(m1, x2, &lo1, &hi1);
        x0 = _mm256_xor_si256(hi1, k0_4);
        x1 = lo1;
        x2 = _mm256_xor_si256(_mm256_xor_si256(hi0, x3), rk1[3]);
        x3 = lo0;
#pragma GCC unroll 6
        for (int r = 4; r < 10; r++) {
            mulhilo8(m0, x0, &lo0, &hi0);
            mulhilo8(m1, x2, &lo1, &hi1);
            x0 = _mm256_xor_si256(_mm256_xor_si256(hi1, x1), rk0[r]);
            x1 = lo1;
            x2 = _mm256_xor_si256(_mm256_xor_si256(hi0, x3), rk1[r]);
            x3 = lo0;
        }
        store_uniforms(x0, x1, x2, x3, u1 + j, u2 + j);
    }
}
#endif
