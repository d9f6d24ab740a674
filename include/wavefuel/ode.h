/* Adaptive and high-order integration of the ring with SUNDIALS: CVODES (Adams or BDF, fuel as quadrature
 * variables) and ARKODE's explicit Runge-Kutta (adaptive with a selectable Butcher table, or fixed-step
 * classic RK4). Every SUNDIALS call lives in src/integ/ode.c. The state is y = (x_1..x_N, v_1..v_N); the caller
 * supplies the right-hand side, a pure function of (t, x, v) for the duration of one advance. */
#ifndef WAVEFUEL_ODE_H
#define WAVEFUEL_ODE_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/err.h"

typedef enum { WF_ODE_CVODE = 0, WF_ODE_ARKODE = 1, WF_ODE_RK4 = 2 } WfOdeKind;

typedef struct WfOdeConfig {
    WfOdeKind kind;
    int    bdf;              /* CVODES: 0 Adams-Moulton (fixed-point iteration), 1 BDF (Newton + matrix-free GMRES) */
    char   erk_table[64];    /* ARKODE adaptive: Butcher table name, e.g. ARKODE_DORMAND_PRINCE_7_4_5 */
    double rtol;             /* relative tolerance (positions relative to the vehicle spacing, see ode.c) */
    double atol_x_m, atol_v_mps, atol_fuel_g;
    double max_step_s;       /* 0: no limit */
    long   max_steps;        /* internal steps allowed per advance */
    int    fuel_errcon;      /* include the fuel integrals in error control */
    int    rk4_substeps;     /* RK4: steps per time step dt (h = dt / substeps) */
    double fixed_step_s;     /* RK4: h, set by the engine from dt and rk4_substeps */
    int    nvector_openmp;   /* 1: NVECTOR_OPENMP (reductions depend on the thread count: not bit-reproducible) */
} WfOdeConfig;

/* Right-hand side: given positions x and speeds v (n each), write dx/dt, dv/dt and, when fuel_gps is not NULL,
 * the fuel rate of each vehicle (g/s). Return 0, > 0 for a recoverable failure, < 0 for a fatal one. */
typedef int (*WfOdeRhs)(void *ctx, double t, const double *x, const double *v, double *xdot, double *vdot,
                        double *fuel_gps);

typedef struct WfOdeStats {
    long steps, rhs_evals, err_test_fails, nonlin_iters, nonlin_conv_fails, reinits;
    double last_step_s;
} WfOdeStats;

typedef struct WfOde WfOde;

/* ring_length_m gives the spacing scale of the position tolerances (see ode.c). Ownership: cfg, x0 and v0 are
 * copied; rhs and ctx are borrowed and called until wf_ode_destroy(); *out is the caller's until then, NULL on
 * failure. */
int  wf_ode_create(const WfOdeConfig *cfg, size_t n, double ring_length_m, WfOdeRhs rhs, void *ctx, double t0,
                   const double *x0, const double *v0, WfOde **out, WfError *err);
/* Advance to t_out; write the state and add each vehicle's fuel over [t, t_out] to fuel_step_g (n entries,
 * overwritten). */
int  wf_ode_advance(WfOde *o, double t_out, double *x, double *v, double *fuel_step_g, WfError *err);
/* Restart from a state changed outside the solver (overlap repair, a jump of the piecewise-constant noise). */
int  wf_ode_reinit(WfOde *o, double t, const double *x, const double *v, WfError *err);
void wf_ode_stats(const WfOde *o, WfOdeStats *st);
void wf_ode_destroy(WfOde **o);
/* Names as written in scenarios. */
const char *wf_ode_kind_name(WfOdeKind k);

#endif
