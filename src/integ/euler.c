/* Explicit Euler: x += v dt, v += a dt, speed floored at 0. First order; kept for comparison with the
 * ballistic update (Treiber & Kanagaraj 2015 discuss why it is worse). */
#include "wavefuel/integrator.h"

static void euler_step(size_t n, double dt, double *restrict x, double *restrict v, const double *restrict a)
{
    for (size_t i = 0; i < n; i++) {
        double vn = v[i] + a[i] * dt;
        x[i] += v[i] * dt;
        v[i] = vn >= 0.0 ? vn : 0.0;
    }
}

const WfIntegrator wf_integ_euler = {
    .name = "euler",
    .doc = "explicit Euler, first order",
    .step = euler_step,
};
