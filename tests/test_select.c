/* The block kernel's gather step (src/core/select.c: wf_select_eq16) against its definition, written out here:
 * every length from 0 to 300 (the vector path's groups of 16 and the rest), ids drawn from 1, 2 and 7 values and
 * runs of equal ids, several bases; nothing written past the block. The CPU's widest path (tests/t_simd.sh runs
 * this binary again with the plain loop). */
#include <stdint.h>

#include "core/select.h"
#include "wf_test.h"

#define MAXM 300

static void test_select_matches_definition(void)
{
    uint64_t s = 12345;
    size_t bad = 0, cases = 0;
    uint16_t id[MAXM];
    uint32_t idx[MAXM + 16], want[MAXM];
    for (size_t m = 0; m <= MAXM; m++)
        for (unsigned values = 1; values <= 7; values += 3)
            for (int runs = 0; runs < 2; runs++) {
                for (size_t k = 0; k < m; k++) {
                    s = s * 6364136223846793005ull + 1442695040888963407ull;
                    /* runs: the id changes every 8 to 24 positions, as platoons of one class */
                    id[k] = runs && k % (8 + s % 17) ? (k ? id[k - 1] : 0) : (uint16_t)((s >> 33) % values);
                }
                for (unsigned c = 0; c < values + 1; c++) {
                    uint32_t base = (uint32_t)(c * 256);
                    size_t n_want = 0;
                    for (size_t k = 0; k < m; k++)
                        if (id[k] == c) want[n_want++] = base + (uint32_t)k;
                    for (size_t k = 0; k < MAXM + 16; k++) idx[k] = 0xDEADBEEFu;
                    size_t got = wf_select_eq16(id, m, (uint16_t)c, base, idx);
                    int ok = got == n_want && memcmp(idx, want, n_want * sizeof *idx) == 0;
                    for (size_t k = m; k < MAXM + 16; k++) ok &= idx[k] == 0xDEADBEEFu;
                    if (!ok && bad++ < 3)
                        printf("  m %zu, %u values, runs %d, c %u: %zu selected, want %zu\n", m, values, runs, c, got,
                               n_want);
                    cases++;
                }
            }
    CHECK(bad == 0, "%zu of %zu cases differ from the definition", bad, cases);
}

int main(void)
{
    RUN(test_select_matches_definition);
    TEST_EXIT();
}
