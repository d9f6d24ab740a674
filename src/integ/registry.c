/* The one list of integrators, fixed-step and adaptive; adding one is one line here (and, for a fixed-step one,
 * its file in src/integ/). The adaptive entries name the SUNDIALS solver that src/integ/ode.c builds. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/integrator.h"
#include "wavefuel/ode.h"

static const WfIntegrator integ_cvode = {
    .name = "cvode",
    .doc = "SUNDIALS CVODES, Adams-Moulton or BDF (solver.method), fuel as quadrature variables",
    .kind = WF_INTEG_ADAPTIVE,
    .ode_kind = WF_ODE_CVODE,
};
static const WfIntegrator integ_arkode = {
    .name = "arkode",
    .doc = "SUNDIALS ARKODE explicit Runge-Kutta, adaptive, with a selectable Butcher table (solver.method)",
    .kind = WF_INTEG_ADAPTIVE,
    .ode_kind = WF_ODE_ARKODE,
};
static const WfIntegrator integ_rk4 = {
    .name = "rk4",
    .doc = "SUNDIALS ARKODE, classic RK4 tableau at fixed steps of dt / solver.rk4_substeps",
    .kind = WF_INTEG_ADAPTIVE,
    .ode_kind = WF_ODE_RK4,
};

const WfIntegrator *const wf_integrators[] = {&wf_integ_ballistic, &wf_integ_euler, &integ_cvode, &integ_arkode,
                                              &integ_rk4, NULL};

const char *wf_integ_kind_name(WfIntegKind kind) { return kind == WF_INTEG_ADAPTIVE ? "adaptive (SUNDIALS)" : "fixed-step"; }

WF_REGISTRY_FINDER(wf_integrator_find, WfIntegrator, wf_integrators, "integrator")
