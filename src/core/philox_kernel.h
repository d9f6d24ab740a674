/* Philox4x32-10 (Random123's philox4x32) over PK_LANES counters at once, and the uniforms wf_rng_normal_block makes
 * of each call's words, written once for a vector width: src/core/philox_avx2.c (8 lanes, compiled with -mavx2) and
 * src/core/philox_avx512.c (16 lanes, -mavx512f) define the vector type and operations and include it; each is
 * called only where the CPU has its instructions. The compiler's vectorisation of Random123's scalar round forms
 * 64-bit products and spends most of its time shuffling them apart (perf: 13 % of the scaling ring's step); here each
 * of the four words stays in one vector, and the 32 x 32 -> 64-bit products of even and odd lanes are blended back
 * into low and high words; what the first three rounds compute from the counter's words 0-2 alone, the same in every
 * call, is computed once a call. Integer arithmetic and exact conversions: the same bits as the scalar call at every
 * width (tests/test_rng.c compares them). The constants are Random123's.
 *
 * The includer defines: PK_LANES; PK_V (PK_LANES 32-bit words) and PK_D (PK_LANES / 2 doubles); PK_MUL(a, b) (the
 * 64-bit products of the even words), PK_SRL64, PK_SLL64, PK_SRL32 (shifts by a constant), PK_ODD(a, b) (a's even
 * words, b's odd), PK_XOR, PK_ADD32, PK_SET1_32, PK_SET1_64, PK_LOAD(p), PK_IOTA (0, 1, ..., PK_LANES - 1);
 * PK_HALF_PD(v, h) (words h PK_LANES / 2 onwards of v as doubles), PK_DADD, PK_DMUL, PK_DSET1, PK_DSTORE; and the
 * two functions' names PK_UNIFORMS and PK_UNIFORMS_LANES (their contracts: core/noise.h). */
#include <stddef.h>
#include <stdint.h>
#include <Random123/philox.h>

/* lo, hi: the low and high words of m x a, lane by lane. */
static inline void mulhilo(PK_V m, PK_V a, PK_V *lo, PK_V *hi)
{
    PK_V even = PK_MUL(a, m), odd = PK_MUL(PK_SRL64(a, 32), m);
    *lo = PK_ODD(even, PK_SLL64(odd, 32));
    *hi = PK_ODD(PK_SRL64(even, 32), odd);
}

/* (double)(w0:w1 >> 11) for the lanes of half h: w0 * 2^21 + (w1 >> 11), each term exact. */
static inline PK_D top53(PK_V w0, PK_V w1, int h)
{
    PK_V s0 = PK_XOR(w0, PK_SET1_32((int)0x80000000u)), s1 = PK_SRL32(w1, 11);
    PK_D hi = PK_DADD(PK_HALF_PD(s0, h), PK_DSET1(2147483648.0));
    return PK_DADD(PK_DMUL(hi, PK_DSET1(0x1p21)), PK_HALF_PD(s1, h));
}

/* The two uniforms of each lane's words: u1 from words 0 and 1, u2 from words 2 and 3. */
static inline void store_uniforms(PK_V x0, PK_V x1, PK_V x2, PK_V x3, double *u1, double *u2)
{
    const PK_D half = PK_DSET1(0.5), scale = PK_DSET1(0x1p-53);
    for (int h = 0; h < 2; h++) {
        PK_DSTORE(u1 + PK_LANES / 2 * h, PK_DMUL(PK_DADD(top53(x0, x1, h), half), scale));
        PK_DSTORE(u2 + PK_LANES / 2 * h, PK_DMUL(PK_DADD(top53(x2, x3, h), half), scale));
    }
}

void PK_UNIFORMS_LANES(const uint32_t *const k[2], const uint32_t *const c[4], size_t calls, double *u1, double *u2)
{
    const PK_V m0 = PK_SET1_64(PHILOX_M4x32_0), m1 = PK_SET1_64(PHILOX_M4x32_1);
    const PK_V w0 = PK_SET1_32((int)PHILOX_W32_0), w1 = PK_SET1_32((int)PHILOX_W32_1);
    for (size_t j = 0; j + PK_LANES <= calls; j += PK_LANES) {
        PK_V x0 = PK_LOAD(c[0] + j), x1 = PK_LOAD(c[1] + j), x2 = PK_LOAD(c[2] + j), x3 = PK_LOAD(c[3] + j),
             key0 = PK_LOAD(k[0] + j), key1 = PK_LOAD(k[1] + j), lo0, hi0, lo1, hi1;
#pragma GCC unroll 10
        for (int r = 0; r < 10; r++) {
            mulhilo(m0, x0, &lo0, &hi0);
            mulhilo(m1, x2, &lo1, &hi1);
            x0 = PK_XOR(PK_XOR(hi1, x1), key0);
            x1 = lo1;
            x2 = PK_XOR(PK_XOR(hi0, x3), key1);
            x3 = lo0;
            key0 = PK_ADD32(key0, w0), key1 = PK_ADD32(key1, w1);
        }
        store_uniforms(x0, x1, x2, x3, u1 + j, u2 + j);
    }
}

void PK_UNIFORMS(uint32_t k0, uint32_t k1, uint32_t c0, uint32_t c1, uint32_t c2, uint32_t first, size_t calls,
                 double *u1, double *u2)
{
    const PK_V m0 = PK_SET1_64(PHILOX_M4x32_0), m1 = PK_SET1_64(PHILOX_M4x32_1);
    /* the ten rounds' keys, each in every lane: the key is bumped between rounds */
    PK_V rk0[10], rk1[10];
    for (uint32_t r = 0, key0 = k0, key1 = k1; r < 10; r++, key0 += PHILOX_W32_0, key1 += PHILOX_W32_1)
        rk0[r] = PK_SET1_32((int)key0), rk1[r] = PK_SET1_32((int)key1);
    /* Words 0-2 of the counter are the same in every lane and call: what the first rounds compute of them alone is
     * computed once, here (names: the state's word, after round r). Round 1: both products are constants; x0, x1
     * and x3 come out constant, x2 is a constant xor the lane's word 3. */
    const PK_V c0v = PK_SET1_32((int)c0), c2v = PK_SET1_32((int)c2);
    PK_V p_lo, p_hi, q_lo, q_hi;
    mulhilo(m0, c0v, &p_lo, &p_hi);
    mulhilo(m1, c2v, &q_lo, &q_hi);
    const PK_V x0_1 = PK_XOR(PK_XOR(q_hi, PK_SET1_32((int)c1)), rk0[0]);
    const PK_V x1_1 = q_lo, x2_1 = PK_XOR(p_hi, rk1[0]), x3_1 = p_lo;
    /* round 2: the product of x0 is a constant, so x2 and x3 come out constant */
    mulhilo(m0, x0_1, &p_lo, &p_hi);
    const PK_V k0_2 = PK_XOR(x1_1, rk0[1]);
    const PK_V x2_2 = PK_XOR(PK_XOR(p_hi, x3_1), rk1[1]), x3_2 = p_lo;
    /* round 3: the product of x2 is a constant, so x1 comes out constant */
    mulhilo(m1, x2_2, &q_lo, &q_hi);
    const PK_V k0_3 = PK_XOR(q_hi, rk0[2]), x1_3 = q_lo, k2_3 = PK_XOR(x3_2, rk1[2]);
    const PK_V k0_4 = PK_XOR(x1_3, rk0[3]);
    for (size_t j = 0; j + PK_LANES <= calls; j += PK_LANES) {
        PK_V x3 = PK_ADD32(PK_SET1_32((int)(first + (uint32_t)j)), PK_IOTA);
        PK_V x0, x1, x2, lo0, hi0, lo1, hi1;
        /* round 2 */
        mulhilo(m1, PK_XOR(x2_1, x3), &lo1, &hi1);
        x0 = PK_XOR(hi1, k0_2);
        x1 = lo1;
        /* round 3 */
        mulhilo(m0, x0, &lo0, &hi0);
        x0 = PK_XOR(x1, k0_3);
        x2 = PK_XOR(hi0, k2_3);
        x3 = lo0;
        /* round 4 */
        mulhilo(m0, x0, &lo0, &hi0);
        mulhilo(m1, x2, &lo1, &hi1);
        x0 = PK_XOR(hi1, k0_4);
        x1 = lo1;
        x2 = PK_XOR(PK_XOR(hi0, x3), rk1[3]);
        x3 = lo0;
#pragma GCC unroll 6
        for (int r = 4; r < 10; r++) {
            mulhilo(m0, x0, &lo0, &hi0);
            mulhilo(m1, x2, &lo1, &hi1);
            x0 = PK_XOR(PK_XOR(hi1, x1), rk0[r]);
            x1 = lo1;
            x2 = PK_XOR(PK_XOR(hi0, x3), rk1[r]);
            x3 = lo0;
        }
        store_uniforms(x0, x1, x2, x3, u1 + j, u2 + j);
    }
}
