/* SUNDIALS integrators against independent references: the closed-form free-road IDM trajectory, the
 * convergence orders of the fixed-step schemes towards a tight CVODES solution, and CVODES against ARKODE. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

static char dir[] = "/tmp/wf_test_ode.XXXXXX";

/* Run a scenario text with overrides; returns final x, v of vehicle arrays (caller frees) and fleet fuel. */
typedef struct Result {
    size_t  n;
    double *x, *v, fuel_g;
    long    rhs_evals;
} Result;

static int run(const char *yaml, const char *const *set, size_t n_set, Result *r)
{
    char path[256];
    snprintf(path, sizeof path, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(yaml, f);
    fclose(f);
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    memset(r, 0, sizeof *r);
    if (wf_scenario_load(path, set, n_set, &sc, &err) || wf_sim_create(sc, &sim, &err) ||
        wf_sim_run(sim, NULL, NULL, NULL, NULL, &err)) {
        printf("  run failed: %s\n", err.msg);
        wf_sim_destroy(&sim);
        wf_scenario_destroy(&sc);
        return -1;
    }
    const WfFleet *fl = wf_sim_fleet(sim);
    r->n = fl->n;
    r->x = malloc(fl->n * sizeof *r->x);
    r->v = malloc(fl->n * sizeof *r->v);
    memcpy(r->x, fl->x_m, fl->n * sizeof *r->x);
    memcpy(r->v, fl->v_mps, fl->n * sizeof *r->v);
    r->fuel_g = wf_sim_summary(sim)->fuel_g;
    WfOdeStats st;
    if (wf_sim_ode_stats(sim, &st)) r->rhs_evals = st.rhs_evals;
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return 0;
}

static void result_free(Result *r)
{
    free(r->x);
    free(r->v);
}

/* One vehicle alone on a 10^7 m ring starting at rest: the interaction term (s_star / s)^2 < 1e-11, so
 * dv/dt = a (1 - (v/v0)^4). With u = v/v0: t(u) = (v0/a) (atanh u + atan u)/2 and x(u) = (v0^2/a) atanh(u^2)/2
 * (integrals of 1/(1-u^4) and u/(1-u^4)). */
static const char *free_yaml =
    "road: {length_m: 1.0e7}\n"
    "time: {duration_s: 40, dt_s: 1.0, output_interval_s: 1.0}\n"
    "fleet:\n  vehicles: 1\n  classes: [{class: midsize_sedan, count: 1, length_m: 5}]\n"
    "  drivers: [{model: idm, count: 1, params: {v0_mps: 30, T_s: 1, s0_m: 2, a_mps2: 1, b_mps2: 1.5, delta: 4}}]\n"
    "initial: {state: rest}\n";

static void test_free_vehicle_closed_form(void)
{
    const double v0 = 30, a = 1, T = 40;
    /* Solve t(u) = T by bisection (t is increasing in u). */
    double lo = 0, hi = 1 - 1e-15;
    for (int i = 0; i < 200; i++) {
        double u = 0.5 * (lo + hi);
        double t = v0 / a * 0.5 * (atanh(u) + atan(u));
        if (t < T) lo = u;
        else hi = u;
    }
    double u = 0.5 * (lo + hi), v_ref = v0 * u, dx_ref = v0 * v0 / a * 0.5 * atanh(u * u);
    const char *integrators[] = {"integrator=cvode", "integrator=arkode"};
    for (int k = 0; k < 2; k++) {
        char integ[64];
        snprintf(integ, sizeof integ, "time.%s", integrators[k]);
        const char *set[] = {integ, "solver.rtol=1e-10", "solver.atol_x_m=1e-10", "solver.atol_v_mps=1e-10"};
        Result r;
        CHECK(run(free_yaml, set, 4, &r) == 0, "%s failed", integ);
        if (!r.x) continue;
        double x0 = 5.0; /* the front bumper starts at the vehicle's length */
        printf("  %s: v(40 s) = %.12f (exact %.12f), x = %.9f (exact %.9f), %ld RHS evaluations\n", integrators[k],
               r.v[0], v_ref, r.x[0] - x0, dx_ref, r.rhs_evals);
        CHECK_REL(r.v[0], v_ref, 1e-7);
        CHECK_REL(r.x[0] - x0, dx_ref, 1e-7);
        result_free(&r);
    }
}

/* A smooth ring: IDM, linearly stable density, a 2 m perturbation decaying, no noise, no stops. */
static const char *smooth_yaml =
    "seed: 1\nroad: {length_m: 440}\n"
    "time: {duration_s: 40, dt_s: 0.1, output_interval_s: 0.4}\n"
    "fleet:\n  vehicles: 22\n  placement: interleaved\n"
    "  classes: [{class: midsize_sedan, fraction: 0.5, length_m: 5}, {class: class8_tractor, fraction: 0.5, length_m: 5}]\n"
    "  drivers: [{model: idm, fraction: 1, params: {v0_mps: 30, T_s: 1, s0_m: 2, a_mps2: 1, b_mps2: 1.5, delta: 4}}]\n"
    "initial: {state: equilibrium, perturbation: {vehicle: 3, dx_m: 2.0}}\n";

static double max_abs_diff(const Result *a, const Result *b)
{
    double m = 0;
    for (size_t i = 0; i < a->n; i++) m = fmax(m, fabs(a->x[i] - b->x[i]));
    return m;
}

static void test_convergence_orders(void)
{
    const char *ref_set[] = {"time.integrator=cvode", "solver.rtol=1e-11", "solver.atol_x_m=1e-11",
                             "solver.atol_v_mps=1e-11", "solver.atol_fuel_g=1e-11", "solver.fuel_error_control=true"};
    Result ref;
    CHECK(run(smooth_yaml, ref_set, 6, &ref) == 0, "reference run failed");
    if (!ref.x) return;
    /* First-order schemes: errors halve when dt halves. dt = 0.1, 0.05, 0.025 (output interval 0.4 s). */
    const char *schemes[] = {"time.integrator=ballistic", "time.integrator=euler"};
    const char *dts[] = {"time.dt_s=0.1", "time.dt_s=0.05", "time.dt_s=0.025"};
    for (int s = 0; s < 2; s++) {
        double ex[3], ef[3];
        for (int k = 0; k < 3; k++) {
            const char *set[] = {schemes[s], dts[k]};
            Result r;
            CHECK(run(smooth_yaml, set, 2, &r) == 0, "run failed");
            if (!r.x) return;
            ex[k] = max_abs_diff(&r, &ref);
            ef[k] = fabs(r.fuel_g - ref.fuel_g);
            result_free(&r);
        }
        printf("  %-26s x errors %.3e %.3e %.3e (ratios %.2f %.2f); fuel errors %.3e %.3e %.3e g (ratios %.2f %.2f)\n",
               schemes[s], ex[0], ex[1], ex[2], ex[0] / ex[1], ex[1] / ex[2], ef[0], ef[1], ef[2], ef[0] / ef[1],
               ef[1] / ef[2]);
        for (int k = 0; k < 2; k++) {
            CHECK(ex[k] / ex[k + 1] > 1.7 && ex[k] / ex[k + 1] < 2.3, "%s: position error ratio %.3f not ~2",
                  schemes[s], ex[k] / ex[k + 1]);
            CHECK(ef[k] / ef[k + 1] > 1.7 && ef[k] / ef[k + 1] < 2.3, "%s: fuel error ratio %.3f not ~2", schemes[s],
                  ef[k] / ef[k + 1]);
        }
    }
    /* Classic RK4: errors shrink 16x when h halves (h = dt / substeps with dt fixed at 0.4 s). */
    const char *subs[] = {"solver.rk4_substeps=1", "solver.rk4_substeps=2", "solver.rk4_substeps=4"};
    double ex[3], ef[3];
    for (int k = 0; k < 3; k++) {
        const char *set[] = {"time.integrator=rk4", "time.dt_s=0.4", subs[k]};
        Result r;
        CHECK(run(smooth_yaml, set, 3, &r) == 0, "rk4 run failed");
        if (!r.x) return;
        ex[k] = max_abs_diff(&r, &ref);
        ef[k] = fabs(r.fuel_g - ref.fuel_g);
        result_free(&r);
    }
    printf("  %-26s x errors %.3e %.3e %.3e (ratios %.1f %.1f); fuel errors %.3e %.3e %.3e g (ratios %.1f %.1f)\n",
           "rk4 (h = 0.4, 0.2, 0.1 s)", ex[0], ex[1], ex[2], ex[0] / ex[1], ex[1] / ex[2], ef[0], ef[1], ef[2],
           ef[0] / ef[1], ef[1] / ef[2]);
    /* Positions: fourth order. Fuel: the CIRCLES rate is continuous but only piecewise smooth in (v, a) (the a+
     * clamp at a = -P/(2Q) is a kink, as are the lower bound and the fuel cut), so the integrand of the fuel has
     * kinks in time and no quadrature of it can be fourth order; it must still converge (at least first order). */
    for (int k = 0; k < 2; k++) {
        CHECK(ex[k] / ex[k + 1] > 12 && ex[k] / ex[k + 1] < 20, "rk4 position error ratio %.2f not ~16",
              ex[k] / ex[k + 1]);
        CHECK(ef[k] / ef[k + 1] > 1.8, "rk4 fuel error ratio %.2f: not converging", ef[k] / ef[k + 1]);
    }
    CHECK(ef[2] < 1e-6 * ref.fuel_g, "rk4 fuel error %.3e g too large", ef[2]);
    result_free(&ref);
}

/* CVODES (Adams and BDF) and ARKODE on the Sugiyama ring without noise, with a wave forming from a 1 m
 * perturbation. At rtol 1e-9 the global differences are bounded by ~1e-6 relative even after the instability
 * has grown the perturbation (growth rate ~0.013/s over 120 s: a factor ~5). */
static void test_cvode_vs_arkode(void)
{
    const char *yaml =
        "seed: 5\nroad: {length_m: 230}\n"
        "time: {duration_s: 120, dt_s: 0.1, output_interval_s: 1}\n"
        "fleet:\n  vehicles: 22\n  classes: [{class: midsize_sedan, count: 22, length_m: 4.5}]\n"
        "  drivers: [{model: idm, count: 22}]\n"
        "initial: {state: equilibrium, perturbation: {vehicle: 0, dx_m: 1.0}}\n";
    const char *tol[] = {"solver.rtol=1e-9", "solver.atol_x_m=1e-9", "solver.atol_v_mps=1e-9"};
    const char *set_cv[] = {"time.integrator=cvode", tol[0], tol[1], tol[2]};
    const char *set_bdf[] = {"time.integrator=cvode", "solver.method=bdf", tol[0], tol[1], tol[2]};
    const char *set_ark[] = {"time.integrator=arkode", tol[0], tol[1], tol[2]};
    Result cv, bdf, ark;
    CHECK(run(yaml, set_cv, 4, &cv) == 0, "cvode failed");
    CHECK(run(yaml, set_bdf, 5, &bdf) == 0, "bdf failed");
    CHECK(run(yaml, set_ark, 4, &ark) == 0, "arkode failed");
    if (!cv.x || !bdf.x || !ark.x) return;
    double dx = max_abs_diff(&cv, &ark), dxb = max_abs_diff(&cv, &bdf);
    printf("  fuel: adams %.10f g, bdf %.10f g, arkode %.10f g; max |dx| adams-arkode %.2e m, adams-bdf %.2e m\n",
           cv.fuel_g, bdf.fuel_g, ark.fuel_g, dx, dxb);
    CHECK_REL(ark.fuel_g, cv.fuel_g, 1e-6);
    CHECK_REL(bdf.fuel_g, cv.fuel_g, 1e-6);
    CHECK(dx < 1e-4 && dxb < 1e-4, "positions differ by %.3e / %.3e m", dx, dxb);
    result_free(&cv);
    result_free(&bdf);
    result_free(&ark);
}

static void test_solver_errors(void)
{
    const char *set[] = {"time.integrator=arkode", "solver.method=ARKODE_NO_SUCH_TABLE"};
    Result r;
    char path[256];
    snprintf(path, sizeof path, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    fputs(free_yaml, f);
    fclose(f);
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    CHECK(wf_scenario_load(path, set, 2, &sc, &err) == 0, "%s", err.msg);
    int rc = sc ? wf_sim_create(sc, &sim, &err) : -1;
    CHECK(rc == WF_EINPUT && strstr(err.msg, "unknown ARKODE explicit table"), "rc %d: %s", rc, err.msg);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    const char *set2[] = {"solver.rtol=1e-6"};
    rc = wf_scenario_load(path, set2, 1, &sc, &err);
    CHECK(rc == WF_EINPUT && strstr(err.msg, "configures cvode, arkode and rk4"), "rc %d: %s", rc, err.msg);
    wf_scenario_destroy(&sc);
    (void)r;
}

int main(void)
{
    if (!mkdtemp(dir)) return 1;
    RUN(test_free_vehicle_closed_form);
    RUN(test_convergence_orders);
    RUN(test_cvode_vs_arkode);
    RUN(test_solver_errors);
    char path[300];
    snprintf(path, sizeof path, "%s/s.yaml", dir);
    unlink(path);
    rmdir(dir);
    TEST_EXIT();
}
