/* The positions of one class or driver group in a block of ids (core/select.h), the first step of every gather of
 * the block kernel. The plain loop (idx[cnt] = k, cnt += id[k] == c) chains each store's address through the
 * count: perf put 15 % of the scaling ring's run_block on it. With AVX2, 16 ids are compared at once, and each
 * byte of the comparison's bit mask looks up the positions of its set bits in a table of 256 entries (8 offsets
 * of one byte each), widened and stored as one vector: a store every 8 ids, the count advanced by a popcount. */
#include "core/select.h"

#include <pthread.h>

#include "core/simd.h"

static size_t select_plain(const uint16_t *id, size_t m, uint16_t c, uint32_t base, uint32_t *idx)
{
    size_t cnt = 0;
    for (size_t k = 0; k < m; k++) idx[cnt] = base + (uint32_t)k, cnt += id[k] == c;
    return cnt;
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

/* offsets[mask]: the positions (0-7) of mask's set bits, lowest first, one per byte. */
static uint64_t offsets[256];
static pthread_once_t offsets_once = PTHREAD_ONCE_INIT;

static void offsets_init(void)
{
    for (unsigned mask = 0; mask < 256; mask++) {
        uint64_t e = 0;
        unsigned n = 0;
        for (unsigned b = 0; b < 8; b++)
            if (mask >> b & 1u) e |= (uint64_t)b << (8 * n++);
        offsets[mask] = e;
    }
}

__attribute__((target("avx2,popcnt"))) static size_t select_avx2(const uint16_t *id, size_t m, uint16_t c,
                                                                  uint32_t base, uint32_t *idx)
{
    const __m256i want = _mm256_set1_epi16((short)c);
    size_t cnt = 0, k = 0;
    for (; k + 16 <= m; k += 16) {
        __m256i eq = _mm256_cmpeq_epi16(_mm256_loadu_si256((const __m256i *)(id + k)), want);
        /* 16 words to 16 bytes (packs works within 128-bit halves: put the halves' results side by side) */
        __m128i bytes = _mm_packs_epi16(_mm256_castsi256_si128(eq), _mm256_extracti128_si256(eq, 1));
        unsigned bits = (unsigned)_mm_movemask_epi8(bytes);
        for (unsigned h = 0; h < 2; h++) {
            unsigned mask = bits >> (8 * h) & 0xFFu;
            __m256i pos = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128((long long)offsets[mask]));
            pos = _mm256_add_epi32(pos, _mm256_set1_epi32((int)(base + (uint32_t)(k + 8 * h))));
            _mm256_storeu_si256((__m256i *)(idx + cnt), pos);
            cnt += (size_t)__builtin_popcount(mask);
        }
    }
    return cnt + select_plain(id + k, m - k, c, base + (uint32_t)k, idx + cnt);
}
#endif

size_t wf_select_eq16(const uint16_t *id, size_t m, uint16_t c, uint32_t base, uint32_t *idx)
{
#if defined(__x86_64__) && defined(__GNUC__)
    if (m >= 16 && wf_simd_level() >= WF_SIMD_AVX2) {
        pthread_once(&offsets_once, offsets_init);
        return select_avx2(id, m, c, base, idx);
    }
#endif
    return select_plain(id, m, c, base, idx);
}
