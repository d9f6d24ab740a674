/* Every SUNDIALS call of wavefuel: CVODES (Adams with fixed-point iteration, or BDF with Newton and
 * matrix-free GMRES; fuel as quadrature variables) and ARKODE ERKStep (adaptive explicit Runge-Kutta with a
 * named Butcher table, or classic RK4 at a fixed step; fuel appended to the state since ERKStep has no
 * quadratures). Error weights: speeds relative to themselves; positions relative to the spacing to the leader
 * (x_{i+1} - x_i, one lap added for the last vehicle), not to the unwrapped position, which grows without bound
 * and would make a relative tolerance meaningless; fuel relative to the accumulated fuel. */
#include "wavefuel/ode.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <arkode/arkode_butcher_erk.h>
#include <arkode/arkode_erkstep.h>
#include <cvodes/cvodes.h>
#include <nvector/nvector_openmp.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_spgmr.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include "util/registry.h"

struct WfOde {
    WfOdeConfig        cfg;
    size_t             n, ny;
    double             L;
    SUNContext         sunctx;
    void              *mem;
    N_Vector           y, q;
    SUNLinearSolver    ls;
    SUNNonlinearSolver nls;
    ARKodeButcherTable table;
    WfOdeRhs           rhs;
    void              *ctx;
    double            *fuel_prev, *scratch;
    WfOdeStats         done; /* counters of solver instances before the last re-initialisation */
    char               said[512]; /* SUNDIALS' last own message (error or warning), "" when none */
};

const char *wf_ode_kind_name(WfOdeKind k)
{
    return k == WF_ODE_CVODE ? "cvode" : k == WF_ODE_ARKODE ? "arkode" : "rk4";
}

/* SUNDIALS' own messages (CVodeSetErrHandlerFn / ERKStepSetErrHandlerFn, SUNDIALS 6.4): kept for wavefuel's message
 * instead of printed on stderr, where they would interleave with the progress bar and escape the WfError. Warnings
 * (code > 0) are kept too; a later error replaces them. */
static void on_sundials_message(int code, const char *module, const char *function, char *msg, void *data)
{
    WfOde *o = data;
    snprintf(o->said, sizeof o->said, "%s %s %s: %s", module, code < 0 ? "error in" : "warning in", function, msg);
}

/* ": <SUNDIALS' message>" for a failure message, or "" when SUNDIALS said nothing. */
static const char *said(const WfOde *o, char *buf, size_t len)
{
    snprintf(buf, len, "%s%s", o->said[0] ? ": " : "", o->said);
    return buf;
}

/* One helper names the failing call (SUNDIALS return codes are negative on failure) and adds what SUNDIALS said. */
static int check(const WfOde *o, int flag, const char *call, WfError *err)
{
    if (flag >= 0) return 0;
    char buf[600];
    return wf_err(err, WF_ESYS, "SUNDIALS: %s failed with code %d%s", call, flag, said(o, buf, sizeof buf));
}

/* The explicit tables of ARKODE 5.4 (SUNDIALS 6.4) by name: ARKodeButcherTable_LoadERKByName prints to stderr on an
 * unknown name (no solver memory yet, so no handler), so names are checked here first, and listed when wrong. */
static const char *const erk_tables[] = {
    "ARKODE_HEUN_EULER_2_1_2",     "ARKODE_BOGACKI_SHAMPINE_4_2_3", "ARKODE_ARK324L2SA_ERK_4_2_3",
    "ARKODE_ZONNEVELD_5_3_4",      "ARKODE_ARK436L2SA_ERK_6_3_4",   "ARKODE_SAYFY_ABURUB_6_3_4",
    "ARKODE_CASH_KARP_6_4_5",      "ARKODE_FEHLBERG_6_4_5",         "ARKODE_DORMAND_PRINCE_7_4_5",
    "ARKODE_ARK548L2SA_ERK_8_4_5", "ARKODE_VERNER_8_5_6",           "ARKODE_FEHLBERG_13_7_8",
    "ARKODE_KNOTH_WOLKE_3_3",      "ARKODE_ARK437L2SA_ERK_7_3_4",   "ARKODE_ARK548L2SAb_ERK_8_4_5", NULL};

static N_Vector new_vector(const WfOde *o, size_t len)
{
    if (o->cfg.nvector_openmp) {
        int threads = 1;
#ifdef _OPENMP
        extern int omp_get_max_threads(void);
        threads = omp_get_max_threads();
#endif
        return N_VNew_OpenMP((sunindextype)len, threads, o->sunctx);
    }
    return N_VNew_Serial((sunindextype)len, o->sunctx);
}

static double *data(N_Vector v) { return N_VGetArrayPointer(v); }

static int f_state(realtype t, N_Vector y, N_Vector ydot, void *user)
{
    WfOde *o = user;
    double *yy = data(y), *yd = data(ydot);
    size_t n = o->n;
    /* ARKODE carries the fuel integrals in the state; CVODES computes them as quadratures. */
    return o->rhs(o->ctx, t, yy, yy + n, yd, yd + n, o->cfg.kind == WF_ODE_CVODE ? NULL : yd + 2 * n);
}

static int f_quad(realtype t, N_Vector y, N_Vector qdot, void *user)
{
    WfOde *o = user;
    double *yy = data(y);
    size_t n = o->n;
    return o->rhs(o->ctx, t, yy, yy + n, o->scratch, o->scratch + n, data(qdot));
}

static int ewt_fn(N_Vector y, N_Vector ewt, void *user)
{
    WfOde *o = user;
    const double *yy = data(y);
    double *w = data(ewt), rtol = o->cfg.rtol, L = o->L;
    size_t n = o->n;
    for (size_t i = 0; i < n; i++) {
        double spacing = (i + 1 < n ? yy[i + 1] : yy[0] + L) - yy[i];
        w[i] = 1.0 / (rtol * fabs(spacing) + o->cfg.atol_x_m);
        w[n + i] = 1.0 / (rtol * fabs(yy[n + i]) + o->cfg.atol_v_mps);
    }
    /* Fuel outside error control: a weight so small that it never decides a step (weights must be > 0). */
    for (size_t i = 2 * n; i < o->ny; i++)
        w[i] = o->cfg.fuel_errcon ? 1.0 / (rtol * fabs(yy[i]) + o->cfg.atol_fuel_g) : 1e-200;
    return 0;
}

/* Classic fourth-order Runge-Kutta as a Butcher table for ERKStep (coefficients, not a solver). */
static ARKodeButcherTable classic_rk4(void)
{
    realtype c[4] = {0.0, 0.5, 0.5, 1.0};
    realtype A[16] = {0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 1.0, 0};
    realtype b[4] = {1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0};
    return ARKodeButcherTable_Create(4, 4, 0, c, A, b, NULL);
}

static int setup_solver(WfOde *o, double t0, WfError *err)
{
    const WfOdeConfig *c = &o->cfg;
    int rc;
    if (c->kind == WF_ODE_CVODE) {
        o->mem = CVodeCreate(c->bdf ? CV_BDF : CV_ADAMS, o->sunctx);
        if (!o->mem) return wf_err(err, WF_ESYS, "SUNDIALS: CVodeCreate failed");
        if ((rc = check(o, CVodeSetErrHandlerFn(o->mem, on_sundials_message, o), "CVodeSetErrHandlerFn", err)) ||
            (rc = check(o, CVodeInit(o->mem, f_state, t0, o->y), "CVodeInit", err)) ||
            (rc = check(o, CVodeSetUserData(o->mem, o), "CVodeSetUserData", err)) ||
            (rc = check(o, CVodeWFtolerances(o->mem, ewt_fn), "CVodeWFtolerances", err)) ||
            (rc = check(o, CVodeSetMaxNumSteps(o->mem, c->max_steps), "CVodeSetMaxNumSteps", err)) ||
            (c->max_step_s > 0 && (rc = check(o, CVodeSetMaxStep(o->mem, c->max_step_s), "CVodeSetMaxStep", err))))
            return rc;
        if (c->bdf) {
            o->ls = SUNLinSol_SPGMR(o->y, SUN_PREC_NONE, 0, o->sunctx);
            if (!o->ls) return wf_err(err, WF_ESYS, "SUNDIALS: SUNLinSol_SPGMR failed");
            if ((rc = check(o, CVodeSetLinearSolver(o->mem, o->ls, NULL), "CVodeSetLinearSolver", err))) return rc;
        } else {
            o->nls = SUNNonlinSol_FixedPoint(o->y, 0, o->sunctx);
            if (!o->nls) return wf_err(err, WF_ESYS, "SUNDIALS: SUNNonlinSol_FixedPoint failed");
            if ((rc = check(o, CVodeSetNonlinearSolver(o->mem, o->nls), "CVodeSetNonlinearSolver", err))) return rc;
        }
        if ((rc = check(o, CVodeQuadInit(o->mem, f_quad, o->q), "CVodeQuadInit", err)) ||
            (rc = check(o, CVodeQuadSStolerances(o->mem, c->rtol, c->atol_fuel_g), "CVodeQuadSStolerances", err)))
            return rc;
        return check(o, CVodeSetQuadErrCon(o->mem, c->fuel_errcon), "CVodeSetQuadErrCon", err);
    }
    o->mem = ERKStepCreate(f_state, t0, o->y, o->sunctx);
    if (!o->mem) return wf_err(err, WF_ESYS, "SUNDIALS: ERKStepCreate failed");
    if ((rc = check(o, ERKStepSetErrHandlerFn(o->mem, on_sundials_message, o), "ERKStepSetErrHandlerFn", err)) ||
        (rc = check(o, ERKStepSetUserData(o->mem, o), "ERKStepSetUserData", err)) ||
        (rc = check(o, ERKStepWFtolerances(o->mem, ewt_fn), "ERKStepWFtolerances", err)) ||
        (rc = check(o, ERKStepSetMaxNumSteps(o->mem, c->max_steps), "ERKStepSetMaxNumSteps", err)))
        return rc;
    if (c->kind == WF_ODE_RK4) {
        o->table = classic_rk4();
    } else {
        if (wf_registry_find((const void *const *)erk_tables, WF_REG_STRINGS, c->erk_table, "ARKODE explicit table", err) < 0)
            return wf_err_prefix(err, "solver.method: ");
        o->table = ARKodeButcherTable_LoadERKByName(c->erk_table);
    }
    if (!o->table) return wf_err(err, WF_ESYS, "SUNDIALS: ARKodeButcherTable_Create failed");
    if ((rc = check(o, ERKStepSetTable(o->mem, o->table), "ERKStepSetTable", err))) return rc;
    if (c->kind == WF_ODE_RK4)
        return check(o, ERKStepSetFixedStep(o->mem, c->fixed_step_s), "ERKStepSetFixedStep", err);
    return c->max_step_s > 0 ? check(o, ERKStepSetMaxStep(o->mem, c->max_step_s), "ERKStepSetMaxStep", err) : 0;
}

void wf_ode_destroy(WfOde **po)
{
    if (!po || !*po) return;
    WfOde *o = *po;
    if (o->mem) {
        if (o->cfg.kind == WF_ODE_CVODE) CVodeFree(&o->mem);
        else ERKStepFree(&o->mem);
    }
    if (o->table) ARKodeButcherTable_Free(o->table);
    if (o->ls) SUNLinSolFree(o->ls);
    if (o->nls) SUNNonlinSolFree(o->nls);
    if (o->q) N_VDestroy(o->q);
    if (o->y) N_VDestroy(o->y);
    if (o->sunctx) SUNContext_Free(&o->sunctx);
    free(o->fuel_prev);
    free(o->scratch);
    free(o);
    *po = NULL;
}

int wf_ode_create(const WfOdeConfig *cfg, size_t n, double L, WfOdeRhs rhs, void *ctx, double t0, const double *x0,
                  const double *v0, WfOde **out, WfError *err)
{
    *out = NULL;
    WfOde *o = calloc(1, sizeof *o);
    if (!o) return wf_err(err, WF_ESYS, "out of memory");
    *o = (WfOde){.cfg = *cfg, .n = n, .ny = cfg->kind == WF_ODE_CVODE ? 2 * n : 3 * n, .L = L, .rhs = rhs, .ctx = ctx};
    int rc = check(o, SUNContext_Create(NULL, &o->sunctx), "SUNContext_Create", err);
    if (!rc) {
        o->y = new_vector(o, o->ny);
        o->fuel_prev = calloc(n + 1, sizeof *o->fuel_prev);
        o->scratch = calloc(2 * n + 1, sizeof *o->scratch);
        if (cfg->kind == WF_ODE_CVODE) o->q = new_vector(o, n);
        if (!o->y || !o->fuel_prev || !o->scratch || (cfg->kind == WF_ODE_CVODE && !o->q))
            rc = wf_err(err, WF_ESYS, "out of memory for the solver state (%zu vehicles)", n);
    }
    if (!rc) {
        double *y = data(o->y);
        memcpy(y, x0, n * sizeof *y);
        memcpy(y + n, v0, n * sizeof *y);
        for (size_t i = 2 * n; i < o->ny; i++) y[i] = 0.0;
        if (o->q) N_VConst(0.0, o->q);
        rc = setup_solver(o, t0, err);
    }
    if (rc) {
        wf_ode_destroy(&o);
        return rc;
    }
    *out = o;
    return 0;
}

int wf_ode_advance(WfOde *o, double t_out, double *x, double *v, double *fuel_step, WfError *err)
{
    realtype tret = 0;
    int rc;
    size_t n = o->n;
    const double *fuel_now;
    char buf[600];
    if (o->cfg.kind == WF_ODE_CVODE) {
        /* Stop exactly at t_out: the right-hand side changes there (noise, controller memory). */
        if ((rc = check(o, CVodeSetStopTime(o->mem, t_out), "CVodeSetStopTime", err))) return rc;
        int flag = CVode(o->mem, t_out, o->y, &tret, CV_NORMAL);
        if (flag < 0)
            return wf_err(err, WF_ESYS, "SUNDIALS: CVode failed at t = %.9g s with code %d (%s)%s", (double)tret, flag,
                          CVodeGetReturnFlagName(flag), said(o, buf, sizeof buf));
        if ((rc = check(o, CVodeGetQuad(o->mem, &tret, o->q), "CVodeGetQuad", err))) return rc;
        fuel_now = data(o->q);
    } else {
        int flag = 0;
        if (o->cfg.kind == WF_ODE_RK4) {
            /* Fixed steps: exactly rk4_substeps steps of h. ERKStep of SUNDIALS 6.4 (ARKODE 5.4) reuses the last
             * stage's right-hand side as the first one of the next step for this tableau (c_4 = 1, but it is not
             * first-same-as-last), which makes classic RK4 third order (measured: y' = y and the free-road IDM
             * errors shrink 8x, not 16x, per halving of h). ERKStepReset after each step forces a fresh f(t_n, y_n);
             * tests/test_ode.c checks the 16x. */
            for (int k = 0; k < o->cfg.rk4_substeps && flag >= 0; k++) {
                flag = ERKStepEvolve(o->mem, t_out, o->y, &tret, ARK_ONE_STEP);
                if (flag >= 0) flag = ERKStepReset(o->mem, tret, o->y);
            }
        } else {
            if ((rc = check(o, ERKStepSetStopTime(o->mem, t_out), "ERKStepSetStopTime", err))) return rc;
            flag = ERKStepEvolve(o->mem, t_out, o->y, &tret, ARK_NORMAL);
        }
        if (flag < 0)
            return wf_err(err, WF_ESYS, "SUNDIALS: ERKStepEvolve failed at t = %.9g s with code %d (%s)%s",
                          (double)tret, flag, ERKStepGetReturnFlagName(flag), said(o, buf, sizeof buf));
        fuel_now = data(o->y) + 2 * n;
    }
    const double *y = data(o->y);
    memcpy(x, y, n * sizeof *x);
    memcpy(v, y + n, n * sizeof *v);
    for (size_t i = 0; i < n; i++) {
        fuel_step[i] = fuel_now[i] - o->fuel_prev[i];
        o->fuel_prev[i] = fuel_now[i];
    }
    return 0;
}

int wf_ode_reinit(WfOde *o, double t, const double *x, const double *v, WfError *err)
{
    size_t n = o->n;
    double *y = data(o->y);
    memcpy(y, x, n * sizeof *y);
    memcpy(y + n, v, n * sizeof *y);
    wf_ode_stats(o, &o->done); /* the counters so far, kept: the re-initialisation resets the solver's */
    o->done.reinits++;
    if (o->cfg.kind == WF_ODE_CVODE) {
        int rc = check(o, CVodeReInit(o->mem, t, o->y), "CVodeReInit", err);
        return rc ? rc : check(o, CVodeQuadReInit(o->mem, o->q), "CVodeQuadReInit", err);
    }
    return check(o, ERKStepReInit(o->mem, f_state, t, o->y), "ERKStepReInit", err);
}

/* Counters since the last re-initialisation, added to those of earlier solver instances. */
void wf_ode_stats(const WfOde *o, WfOdeStats *st)
{
    long steps = 0, nfe = 0, nfq = 0, etf = 0, nni = 0, ncf = 0;
    realtype h = 0;
    if (o->cfg.kind == WF_ODE_CVODE) {
        CVodeGetNumSteps(o->mem, &steps);
        CVodeGetNumRhsEvals(o->mem, &nfe);
        CVodeGetQuadNumRhsEvals(o->mem, &nfq);
        CVodeGetNumErrTestFails(o->mem, &etf);
        CVodeGetNumNonlinSolvIters(o->mem, &nni);
        CVodeGetNumNonlinSolvConvFails(o->mem, &ncf);
        CVodeGetLastStep(o->mem, &h);
    } else {
        ERKStepGetNumSteps(o->mem, &steps);
        ERKStepGetNumRhsEvals(o->mem, &nfe);
        ERKStepGetNumErrTestFails(o->mem, &etf);
        ERKStepGetLastStep(o->mem, &h);
    }
    st->steps = o->done.steps + steps;
    st->rhs_evals = o->done.rhs_evals + nfe + nfq;
    st->err_test_fails = o->done.err_test_fails + etf;
    st->nonlin_iters = o->done.nonlin_iters + nni;
    st->nonlin_conv_fails = o->done.nonlin_conv_fails + ncf;
    st->reinits = o->done.reinits;
    st->last_step_s = h;
}
