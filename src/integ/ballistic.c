/* Ballistic update (Treiber & Kanagaraj 2015): x += v dt + a dt^2/2, v += a dt; a vehicle that would reach
 * v < 0 within the step stops where it reaches v = 0 (x += -v^2/(2a)) and stays there. */
#include "wavefuel/integrator.h"

static void ballistic_step(size_t n, double dt, double *restrict x, double *restrict v, const double *restrict a)
{
    for (size_t i = 0; i < n; i++) {
        double vi = v[i], ai = a[i];
        double vn = vi + ai * dt;
        /* Stopping inside the step: only possible with ai < 0, so the division is safe. */
        double dx = vn >= 0.0 ? vi * dt + 0.5 * ai * dt * dt : -(vi * vi) / (2.0 * (ai < 0.0 ? ai : -1.0));
        x[i] += dx;
        v[i] = vn >= 0.0 ? vn : 0.0;
    }
}

const WfIntegrator wf_integ_ballistic = {
    .name = "ballistic",
    .doc = "ballistic update with exact stopping (Treiber & Kanagaraj 2015), second order in position",
    .step = ballistic_step,
};
