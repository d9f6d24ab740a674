/* Fixed-step integrators of the vehicle dynamics x' = v, v' = a with a held constant over the step.
 * Each is one file in src/integ/; they never let a speed go negative. */
#ifndef WAVEFUEL_INTEGRATOR_H
#define WAVEFUEL_INTEGRATOR_H

#include <stddef.h>
#include "wavefuel/err.h"

typedef struct WfIntegrator {
    const char *name; /* as in scenarios: time.integrator */
    const char *doc;
    /* Advance vehicles [0, n) by dt_s: positions m, speeds m/s, accelerations m/s^2 (read only). */
    void (*step)(size_t n, double dt_s, double *restrict x_m, double *restrict v_mps,
                 const double *restrict a_mps2);
} WfIntegrator;

extern const WfIntegrator *const wf_integrators[];
extern const WfIntegrator wf_integ_ballistic;
extern const WfIntegrator wf_integ_euler;
int wf_integrator_find(const char *name, const WfIntegrator **out, WfError *err);

#endif
