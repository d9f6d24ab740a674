/* Ballistic update (Treiber & Kanagaraj 2015): x += v dt + a dt^2/2, v += a dt; a vehicle that would reach
 * v < 0 within the step stops where it reaches v = 0 (x += -v^2/(2a)) and stays there. */
#include "wavefuel/integrator.h"
#include "core/simd.h"

WF_SIMD_CLONES
static void ballistic_step(size_t n, double dt, double *restrict x, double *restrict v, const double *restrict a)
{
#pragma omp simd
    for (size_t i = 0; i < n; i++) {
        double vi = v[i], ai = a[i];
        double vn = vi + ai * dt;
        /* Stopping inside the step: only possible with ai < 0 (the denominator is -2 otherwise, never 0). Both
         * displacements are computed and one is selected: no branch, so the loop vectorises. */
        double dx_run = vi * dt + 0.5 * ai * dt * dt, dx_stop = -(vi * vi) / (2.0 * (ai < 0.0 ? ai : -1.0));
        int running = vn >= 0.0;
        x[i] += running ? dx_run : dx_stop;
        v[i] = running ? vn : 0.0;
    }
}

const WfIntegrator wf_integ_ballistic = {
    .name = "ballistic",
    .doc = "ballistic update with exact stopping (Treiber & Kanagaraj 2015), second order in position",
    .step = ballistic_step,
};
