/* Integrators of the vehicle dynamics x' = v, v' = a: one registry holding both kinds.
 * Fixed-step ones (ballistic, euler) hold a constant over the step; each is one file in src/integ/ and never lets a
 * speed go negative. Adaptive and high-order ones (cvode, arkode, rk4) are SUNDIALS solvers (src/integ/ode.c,
 * include/wavefuel/ode.h) configured by the scenario's `solver` section; they have no `step`. The scenario loader,
 * its error messages and the docs table of time.integrator all read this registry. */
#ifndef WAVEFUEL_INTEGRATOR_H
#define WAVEFUEL_INTEGRATOR_H

#include <stddef.h>
#include "wavefuel/err.h"

typedef enum { WF_INTEG_FIXED = 0, WF_INTEG_ADAPTIVE = 1 } WfIntegKind;

typedef struct WfIntegrator {
    const char *name; /* as in scenarios: time.integrator */
    const char *doc;
    WfIntegKind kind;
    int         ode_kind; /* adaptive: the WfOdeKind of ode.h */
    /* Fixed-step only (NULL for adaptive ones): advance vehicles [0, n) by dt_s: positions m, speeds m/s,
     * accelerations m/s^2 (read only). */
    void (*step)(size_t n, double dt_s, double *restrict x_m, double *restrict v_mps,
                 const double *restrict a_mps2);
} WfIntegrator;

/* Every integrator, fixed-step first; NULL-terminated. */
extern const WfIntegrator *const wf_integrators[];
extern const WfIntegrator wf_integ_ballistic;
extern const WfIntegrator wf_integ_euler;
/* Any kind by name; unknown: "unknown integrator 'x' (known: ballistic, euler, ...)". */
int wf_integrator_find(const char *name, const WfIntegrator **out, WfError *err);
/* Kind as written in the docs: "fixed-step" or "adaptive (SUNDIALS)". */
const char *wf_integ_kind_name(WfIntegKind kind);

#endif
