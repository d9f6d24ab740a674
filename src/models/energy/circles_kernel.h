/* The CIRCLES array kernel, written once for any SIMD width: src/models/energy/circles.c includes this file once per
 * width with WF_LANES (2, 4 or 8) and WF_KERNEL (the function's name) defined, the 4-lane copy compiled for AVX2
 * and the 8-lane one for x86-64-v4.
 * GNU C vector types: lane-wise IEEE arithmetic, the same operations in the same order as the scalar formula
 * (circles_eval1), so every lane's result is bitwise the scalar result whatever the width (contraction into
 * FMA is off project-wide). GCC 12 does not vectorise the scalar loop at the project's -O2: the very-cheap cost
 * model refuses unknown trip counts, and with the default -ftrapping-math it will not if-convert the selects. */
#define WF_CAT2(a, b) a##b
#define WF_CAT(a, b)  WF_CAT2(a, b)
#define V   WF_CAT(WfVec, WF_LANES)
#define M   WF_CAT(WfMask, WF_LANES)
#define FN(name) WF_CAT(name, WF_LANES)

typedef double  V __attribute__((vector_size(8 * WF_LANES)));
typedef int64_t M __attribute__((vector_size(8 * WF_LANES))); /* lanes all-ones (true) or zero */
typedef uint8_t FN(Flags) __attribute__((vector_size(WF_LANES)));  /* a vector's flags, one byte each */

static inline V FN(vsplat)(double x)
{
    V r;
    for (int l = 0; l < WF_LANES; l++) r[l] = x;
    return r;
}
#if WF_LANES == 4 && defined(__x86_64__)
/* AVX: one blend, and vminpd / vmaxpd, which are min1 / max1 exactly (each returns its second operand unless the
 * first compares less / greater, NaNs and signed zeros included): the generic forms take three and four
 * instructions, a fifth of the kernel. */
static inline V FN(vselect)(M m, V x, V y) { return (V)_mm256_blendv_pd((__m256d)y, (__m256d)x, (__m256d)m); }
static inline V FN(vmin)(V x, V y) { return (V)_mm256_min_pd((__m256d)x, (__m256d)y); } /* min1 per lane */
static inline V FN(vmax)(V x, V y) { return (V)_mm256_max_pd((__m256d)x, (__m256d)y); } /* max1 per lane */
#else
static inline V FN(vselect)(M m, V x, V y) { return (V)((m & (M)x) | (~m & (M)y)); }
static inline V FN(vmin)(V x, V y) { return FN(vselect)(x < y, x, y); }                  /* min1 per lane */
static inline V FN(vmax)(V x, V y) { return FN(vselect)(x > y, x, y); }                  /* max1 per lane */
#endif
#if WF_LANES == 4 && defined(__x86_64__)
/* The flags' bytes (2 where v < 0, else 1 where a > a_max, else 0) from the masks' sign bits (vmovmskpd): one
 * multiplication spreads bit l to byte l (the four shifted copies of the 4 bits do not overlap, so nothing carries),
 * little-endian byte l being lane l. The generic conversion of 64-bit lanes to bytes took 16 instructions. */
static inline void FN(flag_bytes)(M negative, M above, uint8_t *out)
{
    uint32_t nb = (uint32_t)_mm256_movemask_pd((__m256d)negative);
    uint32_t ab = (uint32_t)_mm256_movemask_pd((__m256d)above) & ~nb;
    uint32_t b = ((nb * 0x204081u) & 0x01010101u) * WF_NEGATIVE_SPEED |
                 ((ab * 0x204081u) & 0x01010101u) * WF_INFEASIBLE_ACCEL;
    memcpy(out, &b, sizeof b);
}
#else
static inline void FN(flag_bytes)(M negative, M above, uint8_t *out)
{
    FN(Flags) fb = __builtin_convertvector((negative & WF_NEGATIVE_SPEED) | (above & ~negative & WF_INFEASIBLE_ACCEL),
                                           FN(Flags));
    memcpy(out, &fb, sizeof fb);
}
#endif
/* lanes (<= WF_LANES) points from src + i; a tail's missing lanes repeat its last point (they are not stored). The
 * tail goes through an array: a vector written lane by lane would live in memory, stored and reloaded in every
 * iteration. */
static inline __attribute__((always_inline)) V FN(vload)(const double *src, size_t i, size_t lanes)
{
    double t[WF_LANES];
    const double *p = src + i;
    if (lanes < WF_LANES) {
        for (size_t l = 0; l < WF_LANES; l++) t[l] = src[i + (l < lanes ? l : lanes - 1)];
        p = t;
    }
    V x;
    memcpy(&x, p, sizeof x);
    return x;
}

/* The fuel rates of lanes (<= WF_LANES) points, and their flags when flag is not NULL: a whole vector by vector
 * stores (stored lane by lane, the stores cost a fifth of the kernel), a tail through arrays. */
static inline __attribute__((always_inline)) void FN(vstore)(V f, M negative, M above, size_t lanes, double *fuel,
                                                             uint8_t *flag)
{
    if (lanes == WF_LANES) {
        memcpy(fuel, &f, sizeof f);
        if (flag) FN(flag_bytes)(negative, above, flag);
        return;
    }
    double tf[WF_LANES];
    uint8_t fb[WF_LANES];
    memcpy(tf, &f, sizeof f);
    memcpy(fuel, tf, lanes * sizeof *tf);
    if (flag) {
        FN(flag_bytes)(negative, above, fb);
        memcpy(flag, fb, lanes);
    }
}

static inline V FN(vmin_nan)(V x, V y) { return FN(vselect)((x < y) | (y != y), x, y); } /* min_nan */
static inline V FN(vmax_nan)(V x, V y) { return FN(vselect)((x > y) | (y != y), x, y); } /* max_nan */

/* The kernel twice from one body (circles_kernel_body.h): the full form, WF_KERNEL, and the flat road's,
 * WF_KERNEL##_flat. */
#define WF_KBODY WF_KERNEL
#include "models/energy/circles_kernel_body.h"
#undef WF_KBODY
#define WF_FLAT
#define WF_KBODY WF_CAT(WF_KERNEL, _flat)
#include "models/energy/circles_kernel_body.h"
#undef WF_KBODY
#undef WF_FLAT

#undef V
#undef M
#undef FN
