/* Box-Muller over arrays of uniforms, written once for a SIMD width: src/core/noise_sse2.c (2 lanes),
 * src/core/noise_avx.c (4 lanes, compiled with -mavx) and src/core/noise_avx512.c (8 lanes, -mavx512f) include it
 * with the vector type and SLEEF's functions defined, and NK_STORE2 (the interleaving store) where the width has
 * shuffles for it.
 * SLEEF's "cinz" functions (consistent, no FMA) return the same bits for every vector extension, and the rest
 * is IEEE arithmetic (sqrt, products), so every width gives the same deviates. */
#include <stddef.h>
#include <string.h>

/* z[2p], z[2p+1] from u1[p] in (0, 1) and u2[p] in [0, 1): r = sqrt(-2 ln u1), (z0, z1) = r (cos, sin)(2 pi u2).
 * pairs is a multiple of NK_LANES (the caller pads). */
static void NK_NAME(size_t pairs, const double *restrict u1, const double *restrict u2, double *restrict z)
{
    const NK_VEC minus_two = NK_SPLAT(-2.0), two = NK_SPLAT(2.0);
    for (size_t p = 0; p < pairs; p += NK_LANES) {
        NK_VEC a, b;
        memcpy(&a, u1 + p, sizeof a);
        memcpy(&b, u2 + p, sizeof b);
        NK_VEC r = NK_SQRT(NK_MUL(minus_two, NK_LOG(a)));
        NK_SC sc = NK_SINCOSPI(NK_MUL(two, b)); /* .x = sin, .y = cos */
        NK_VEC zc = NK_MUL(r, sc.y), zs = NK_MUL(r, sc.x);
#ifdef NK_STORE2
        NK_STORE2(z + 2 * p, zc, zs); /* c0 s0 c1 s1 ...: the width's own shuffles */
#else
        /* The products as vectors, then interleaved lane by lane: copying sc's halves to arrays first made GCC
         * reload them with loads wider than its stores, which the CPU cannot forward (a third of this kernel's
         * time on one Zen 5 core). */
        double c[NK_LANES], s[NK_LANES];
        memcpy(c, &zc, sizeof c);
        memcpy(s, &zs, sizeof s);
        for (size_t l = 0; l < NK_LANES; l++) {
            z[2 * (p + l)] = c[l];
            z[2 * (p + l) + 1] = s[l];
        }
#endif
    }
}
