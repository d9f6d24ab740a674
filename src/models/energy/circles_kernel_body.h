/* The body of the CIRCLES array kernel (circles_kernel.h, which defines its vector type V, mask type M and helpers
 * FN(...) for one width and includes this file twice): WF_KBODY is the function's name; with WF_FLAT defined, the
 * flat road's form (no theta, project 0), which WfEnergyModel.eval_flat is. */
#ifdef WF_FLAT
/* The flat road's form (theta = +0, project 0, v finite): every term with theta is a signed zero, v >= +0 where the
 * fuel terms use it, so z0 th + z1 th v + z2 th v^2 adds +0, or -0 when z0, z1 and z2 are all -0, which changes
 * only the sign of a zero f; a_max and a_cut lose a zero that changes only the sign of a zero, which their
 * comparisons ignore. So the bits are the full form's. Only the lines marked WF_FLAT differ between the forms. */
static void WF_KBODY(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                     const double *restrict a_in, double *restrict fuel, uint8_t *restrict flag)
#else
static void WF_KBODY(const WfCirclesParams *restrict p, size_t n, const double *restrict v_in,
                     const double *restrict a_in, const double *restrict th_in, int project, double *restrict fuel,
                     uint8_t *restrict flag)
#endif
{
    const V b1 = FN(vsplat)(p->b1), b2 = FN(vsplat)(p->b2), b3 = FN(vsplat)(p->b3);
    const V c0 = FN(vsplat)(p->c0), c1 = FN(vsplat)(p->c1), c2 = FN(vsplat)(p->c2), c3 = FN(vsplat)(p->c3);
    const V p0 = FN(vsplat)(p->p0), p1 = FN(vsplat)(p->p1), p2 = FN(vsplat)(p->p2), q0 = FN(vsplat)(p->q0),
            q1 = FN(vsplat)(p->q1), f_idle = FN(vsplat)(p->f_idle);
    const V a0 = FN(vsplat)(p->a0), a1 = FN(vsplat)(p->a1), a3 = FN(vsplat)(p->a3);
#ifdef WF_FLAT
    const V zfix = FN(vsplat)(signbit(p->z0) && signbit(p->z1) && signbit(p->z2) ? -0.0 : 0.0);
#else
    const V b4 = FN(vsplat)(p->b4), b5 = FN(vsplat)(p->b5), b6 = FN(vsplat)(p->b6);
    const V z0 = FN(vsplat)(p->z0), z1 = FN(vsplat)(p->z1), z2 = FN(vsplat)(p->z2);
    const V a2 = FN(vsplat)(p->a2), a4 = FN(vsplat)(p->a4);
    M proj;
    for (int l = 0; l < WF_LANES; l++) proj[l] = project ? -1 : 0;
#endif
    const V cut_v = FN(vsplat)(p->cut_v), lb_beta = FN(vsplat)(p->lb_beta), lb_h0 = FN(vsplat)(p->lb_h0),
            lb_h1 = FN(vsplat)(p->lb_h1);
    const V zero = FN(vsplat)(0.0), v_floor = FN(vsplat)(1e-12), two = FN(vsplat)(2.0);
    const V idle_v = FN(vsplat)(0.1), idle_a = FN(vsplat)(0.01);
    M abs_bits;
    for (int l = 0; l < WF_LANES; l++) abs_bits[l] = INT64_MAX;
    for (size_t i = 0; i < n; i += WF_LANES) {
        size_t lanes = n - i < WF_LANES ? n - i : WF_LANES;
        V v = FN(vload)(v_in, i, lanes), a = FN(vload)(a_in, i, lanes);
#ifndef WF_FLAT
        V th = FN(vload)(th_in, i, lanes);
#endif
        /* 1-2. a_max from the raw v; flag from the original a: 2 if v < 0, else 1 if a > a_max. */
#ifdef WF_FLAT
        V amax = FN(vmin)(b1, b2 / FN(vmax)(v, v_floor) - b3 * v * v);
#else
        V amax = FN(vmin)(b1, b2 / FN(vmax)(v, v_floor) - b3 * v * v) - FN(vmin)(b4, b5 + b6 * v) * th;
#endif
        M negative = v < zero, above = a > amax;
        /* 3-5. Projection, v >= 0, a+ (v floored at 1e-12 inside Q keeps Q off 0 at rest when q0 = 0). */
#ifndef WF_FLAT
        a = FN(vselect)(proj, FN(vmin_nan)(a, amax), a);
#endif
        v = FN(vmax)(v, zero);
        V P = p0 + p1 * v + p2 * v * v;
        V Q = q0 + q1 * FN(vmax)(v, v_floor);
        V ap = FN(vmax_nan)(a, -P / (two * Q));
        /* 6. Only the two squared terms use a+. */
#ifdef WF_FLAT
        V f = c0 + c1 * v + c2 * v * v + c3 * v * v * v + p0 * a + p1 * a * v + p2 * a * v * v + q0 * ap * ap +
              q1 * ap * ap * v + zfix;
#else
        V f = c0 + c1 * v + c2 * v * v + c3 * v * v * v + p0 * a + p1 * a * v + p2 * a * v * v + q0 * ap * ap +
              q1 * ap * ap * v + z0 * th + z1 * th * v + z2 * th * v * v;
#endif
        /* 7. Light duty: beta below v_c, 0 above (lb_h0 = lb_h1 = 0 add exact zeros).
         *    Heavy duty: h0 + h1 v (lb_beta = 0, cut_v = inf). */
        V lb = FN(vselect)(v <= cut_v, lb_beta, zero) + lb_h0 + lb_h1 * v;
        f = FN(vmax)(f, lb);
        /* 8. Fuel cut (never for heavy duty: v > inf is false). */
#ifdef WF_FLAT
        V a_cut = a0 + a1 * v + a3 * v * v;
#else
        V a_cut = a0 + a1 * v + a2 * th + a3 * v * v + a4 * v * th;
#endif
        f = FN(vselect)((v > cut_v) & (a <= a_cut), zero, f);
        /* 9. Idle, with the v of step 4 and the a of step 3. */
        V abs_a = (V)((M)a & abs_bits);
        f = FN(vselect)((v < idle_v) & (abs_a < idle_a), f_idle, f);
        FN(vstore)(f, negative, above, lanes, fuel + i, flag ? flag + i : NULL);
    }
}
