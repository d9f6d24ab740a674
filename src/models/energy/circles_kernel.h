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
static inline V FN(vmin_nan)(V x, V y) { return FN(vselect)((x < y) | (y != y), x, y); } /* min_nan */
static inline V FN(vmax_nan)(V x, V y) { return FN(vselect)((x > y) | (y != y), x, y); } /* max_nan */

static void WF_KERNEL(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                      const double *restrict a_in, const double *restrict th_in, int project, double *restrict fuel,
                      uint8_t *restrict flag)
{
    const V b1 = FN(vsplat)(p->b1), b2 = FN(vsplat)(p->b2), b3 = FN(vsplat)(p->b3), b4 = FN(vsplat)(p->b4),
            b5 = FN(vsplat)(p->b5), b6 = FN(vsplat)(p->b6);
    const V c0 = FN(vsplat)(p->c0), c1 = FN(vsplat)(p->c1), c2 = FN(vsplat)(p->c2), c3 = FN(vsplat)(p->c3);
    const V p0 = FN(vsplat)(p->p0), p1 = FN(vsplat)(p->p1), p2 = FN(vsplat)(p->p2), q0 = FN(vsplat)(p->q0),
            q1 = FN(vsplat)(p->q1);
    const V z0 = FN(vsplat)(p->z0), z1 = FN(vsplat)(p->z1), z2 = FN(vsplat)(p->z2), f_idle = FN(vsplat)(p->f_idle);
    const V a0 = FN(vsplat)(p->a0), a1 = FN(vsplat)(p->a1), a2 = FN(vsplat)(p->a2), a3 = FN(vsplat)(p->a3),
            a4 = FN(vsplat)(p->a4);
    const V cut_v = FN(vsplat)(p->cut_v), lb_beta = FN(vsplat)(p->lb_beta), lb_h0 = FN(vsplat)(p->lb_h0),
            lb_h1 = FN(vsplat)(p->lb_h1);
    const V zero = FN(vsplat)(0.0), v_floor = FN(vsplat)(1e-12), two = FN(vsplat)(2.0);
    const V idle_v = FN(vsplat)(0.1), idle_a = FN(vsplat)(0.01);
    M proj, abs_bits;
    for (int l = 0; l < WF_LANES; l++) proj[l] = project ? -1 : 0, abs_bits[l] = INT64_MAX;
    for (size_t i = 0; i < n; i += WF_LANES) {
        size_t lanes = n - i < WF_LANES ? n - i : WF_LANES;
        /* The tail's lanes go through arrays: a vector written lane by lane would live in memory, stored and
         * reloaded in every iteration. */
        const double *pv = v_in + i, *pa = a_in + i, *pt = th_in + i;
        double tv[WF_LANES], ta[WF_LANES], tt[WF_LANES];
        if (lanes < WF_LANES) { /* the tail: the last point fills the missing lanes, which are not stored */
            for (size_t l = 0; l < WF_LANES; l++) {
                size_t j = i + (l < lanes ? l : lanes - 1);
                tv[l] = v_in[j], ta[l] = a_in[j], tt[l] = th_in[j];
            }
            pv = tv, pa = ta, pt = tt;
        }
        V v, a, th;
        memcpy(&v, pv, sizeof v);
        memcpy(&a, pa, sizeof a);
        memcpy(&th, pt, sizeof th);
        /* 1-2. a_max from the raw v; flag from the original a: 2 if v < 0, else 1 if a > a_max. */
        V amax = FN(vmin)(b1, b2 / FN(vmax)(v, v_floor) - b3 * v * v) - FN(vmin)(b4, b5 + b6 * v) * th;
        M negative = v < zero, above = a > amax;
        /* 3-5. Projection, v >= 0, a+ (v floored at 1e-12 inside Q keeps Q off 0 at rest when q0 = 0). */
        a = FN(vselect)(proj, FN(vmin_nan)(a, amax), a);
        v = FN(vmax)(v, zero);
        V P = p0 + p1 * v + p2 * v * v;
        V Q = q0 + q1 * FN(vmax)(v, v_floor);
        V ap = FN(vmax_nan)(a, -P / (two * Q));
        /* 6. Only the two squared terms use a+. */
        V f = c0 + c1 * v + c2 * v * v + c3 * v * v * v + p0 * a + p1 * a * v + p2 * a * v * v + q0 * ap * ap +
              q1 * ap * ap * v + z0 * th + z1 * th * v + z2 * th * v * v;
        /* 7. Light duty: beta below v_c, 0 above (lb_h0 = lb_h1 = 0 add exact zeros).
         *    Heavy duty: h0 + h1 v (lb_beta = 0, cut_v = inf). */
        V lb = FN(vselect)(v <= cut_v, lb_beta, zero) + lb_h0 + lb_h1 * v;
        f = FN(vmax)(f, lb);
        /* 8. Fuel cut (never for heavy duty: v > inf is false). */
        V a_cut = a0 + a1 * v + a2 * th + a3 * v * v + a4 * v * th;
        f = FN(vselect)((v > cut_v) & (a <= a_cut), zero, f);
        /* 9. Idle, with the v of step 4 and the a of step 3. */
        V abs_a = (V)((M)a & abs_bits);
        f = FN(vselect)((v < idle_v) & (abs_a < idle_a), f_idle, f);
        if (lanes == WF_LANES) { /* vector stores: lane by lane, the stores cost a fifth of the kernel */
            memcpy(fuel + i, &f, sizeof f);
            if (flag) FN(flag_bytes)(negative, above, flag + i);
        } else {
            double tf[WF_LANES];
            uint8_t fb[WF_LANES];
            memcpy(tf, &f, sizeof f);
            memcpy(fuel + i, tf, lanes * sizeof *tf);
            if (flag) {
                FN(flag_bytes)(negative, above, fb);
                memcpy(flag + i, fb, lanes);
            }
        }
    }
}

#undef V
#undef M
#undef FN
