/* Ring physics of the engine (src/core/engine.c with src/core/fleet.c, src/observe/stats.c, src/integ/, src/models/cf/) against
 * references derived here: the uniform equilibrium of IDM solved in closed form with the CIRCLES fuel rate
 * re-typed from issue 3, the linear stability of the ring (exact per-mode 2x2 map of the ballistic update,
 * with the model derivatives derived analytically), invariants at every output record, and bitwise
 * determinism across thread counts. Scenarios are written to a temporary directory and run through the
 * public API with an in-memory WfOutput. */
#include <complex.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

/* ------------------------------------------------------------------------------------------ harness */

static char tmp_dir[64]; /* mkdtemp directory holding this run's scenario files */

/* Records kept in memory; `check` (may be NULL) examines the fleet at each record. */
typedef struct Recorder {
    WfTsRow *rows;
    size_t   n, cap;
    void   (*check)(void *ctx, const WfSim *sim, const WfTsRow *row);
    void    *check_ctx;
} Recorder;

static int rec_record(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    Recorder *r = ctx;
    if (r->n == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 1024;
        WfTsRow *p = realloc(r->rows, cap * sizeof *p);
        if (!p) return wf_err(err, WF_ESYS, "test recorder: out of memory");
        r->rows = p, r->cap = cap;
    }
    WfTsRow *row = &r->rows[r->n++];
    WF_TEST_KEEP_RECORD(row, rec, wf_sim_scenario(sim)->n_classes);
    if (r->check) r->check(r->check_ctx, sim, row);
    return 0;
}

static void rec_free(Recorder *r)
{
    free(r->rows);
    memset(r, 0, sizeof *r);
}

/* Write `text` to tmp_dir/name and load it as a scenario. Returns NULL (after a failed CHECK) on error. */
static WfScenario *load_text(const char *name, const char *text)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", tmp_dir, name);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL, "cannot write %s", path);
    if (!fp) return NULL;
    fputs(text, fp);
    CHECK(fclose(fp) == 0, "cannot close %s", path);
    WfScenario *sc = NULL;
    WfError err = {0};
    int rc = wf_scenario_load(path, NULL, 0, &sc, &err);
    CHECK(rc == 0, "scenario %s: %s", name, err.msg);
    return rc ? NULL : sc;
}

/* Create and run a simulation of `sc`, recording into `rec`. Returns the simulation (caller destroys) or
 * NULL after a failed CHECK. */
static WfSim *run_sim(const WfScenario *sc, Recorder *rec)
{
    WfSim *sim = NULL;
    WfError err = {0};
    int rc = wf_sim_create(sc, &sim, &err);
    CHECK(rc == 0, "wf_sim_create: %s", err.msg);
    if (rc) return NULL;
    WfOutput out = {.record = rec_record, .ctx = rec};
    rc = wf_sim_run(sim, &out, NULL, NULL, NULL, &err);
    CHECK(rc == 0, "wf_sim_run: %s", err.msg);
    if (rc) wf_sim_destroy(&sim);
    return sim;
}

static int class_index(const WfScenario *sc, const char *name)
{
    for (size_t c = 0; c < sc->n_classes; c++)
        if (strcmp(sc->classes[c].vc.name, name) == 0) return (int)c;
    CHECK(0, "class %s not in the scenario", name);
    return -1;
}

/* ------------------------------------------------------------------- car-following references */

/* IDM parameters as in the scenarios (Treiber et al. 2000). */
typedef struct Idm {
    double v0, T, s0, a, b, delta;
} Idm;
static const Idm IDM_STD = {30.0, 1.0, 2.0, 1.0, 1.5, 4.0};

/* OV-FTL parameters: a = alpha (V(s) - v) + beta (v_l - v) / s^2,
 * V(s) = v_max (tanh(s/d0 - 2) + tanh 2) / (1 + tanh 2). */
typedef struct Ovm {
    double alpha, beta, v_max, d0;
} Ovm;
static const Ovm OVM_STD = {0.5, 20.0, 10.0, 2.23};

/* IDM uniform flow: the speed v at which the gap s equals s_e(v) = (s0 + v T) / sqrt(1 - (v/v0)^delta), the
 * closed form of a = 0 at v_l = v. s_e increases from s0 at v = 0 to infinity at v0: bisection on [0, v0]
 * until the bracket stops shrinking. */
static double idm_v_eq(const Idm *p, double gap_m)
{
    double lo = 0.0, hi = p->v0;
    for (int it = 0; it < 2000; it++) {
        double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        double se = (p->s0 + mid * p->T) / sqrt(1.0 - pow(mid / p->v0, p->delta));
        if (se < gap_m) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

static double ovm_V(const Ovm *p, double s) { return p->v_max * (tanh(s / p->d0 - 2.0) + tanh(2.0)) / (1.0 + tanh(2.0)); }

/* Partial derivatives of a = f(s, v, v_l) at the uniform state (s, v, v_l = v), derived by hand:
 * IDM with s* = s0 + v T + v (v - v_l) / (2 sqrt(a b)):
 *   f_s  = 2 a s*^2 / s^3
 *   f_v  = -a [delta v^(delta-1) / v0^delta + 2 s* / s^2 (T + v / (2 sqrt(a b)))]
 *   f_vl = a s* v / (s^2 sqrt(a b))
 * OV-FTL: f_s = alpha V'(s) (the FTL term's s-derivative carries v_l - v = 0), V'(s) = v_max sech^2(s/d0 - 2)
 *   / (d0 (1 + tanh 2)); f_v = -alpha - beta / s^2; f_vl = beta / s^2. */
typedef struct Deriv {
    double fs, fv, fvl;
} Deriv;

static Deriv idm_deriv(const Idm *p, double s, double v)
{
    double ss = p->s0 + v * p->T, sab = sqrt(p->a * p->b);
    Deriv d;
    d.fs = 2.0 * p->a * ss * ss / (s * s * s);
    d.fv = -p->a * (p->delta * pow(v, p->delta - 1.0) / pow(p->v0, p->delta) + 2.0 * ss / (s * s) * (p->T + v / (2.0 * sab)));
    d.fvl = p->a * ss * v / (s * s * sab);
    return d;
}

static Deriv ovm_deriv(const Ovm *p, double s)
{
    double c = cosh(s / p->d0 - 2.0);
    Deriv d;
    d.fs = p->alpha * p->v_max / (p->d0 * (1.0 + tanh(2.0)) * c * c);
    d.fv = -p->alpha - p->beta / (s * s);
    d.fvl = p->beta / (s * s);
    return d;
}

/* Linear stability of the uniform ring of n vehicles. With y_i, u_i the position and speed deviations and
 * s_i = x_{i+1} - x_i - l, the acceleration deviation is f_s (y_{i+1} - y_i) + f_v u_i + f_vl u_{i+1}. A
 * Fourier mode y_i = Y e^{i phi i}, phi = 2 pi k / n, gives A = alpha Y + beta U with
 * alpha = f_s (e^{i phi} - 1), beta = f_v + f_vl e^{i phi}. The ballistic step (x += v dt + a dt^2/2,
 * v += a dt, acceleration from the step's start) maps (Y, U) by
 *   M = [[1 + alpha dt^2/2, dt + beta dt^2/2], [alpha dt, 1 + beta dt]],
 * whose eigenvalues mu give the rate ln|mu| / dt. The continuous-time eigenvalues solve
 * lambda^2 = alpha + beta lambda. Mode k = 0 (uniform shift) does not change the spatial spread. */
typedef struct Rates {
    double discrete;   /* largest ln|mu|/dt over k = 1..n-1 */
    double second;     /* largest rate among the other wavenumber pairs (k' != k, n - k) */
    double continuous; /* largest Re(lambda) */
    int    k;          /* its wavenumber (the smaller of k, n - k) */
} Rates;

static Rates ring_rates(Deriv d, size_t n, double dt)
{
    Rates r = {-INFINITY, -INFINITY, -INFINITY, 0};
    double *best_k = calloc(n, sizeof *best_k);
    CHECK(best_k != NULL, "out of memory");
    if (!best_k) return r;
    for (size_t k = 1; k < n; k++) {
        double complex e = cexp(I * 2.0 * M_PI * (double)k / (double)n);
        double complex al = d.fs * (e - 1.0), be = d.fv + d.fvl * e;
        double complex m11 = 1.0 + al * dt * dt / 2.0, m12 = dt + be * dt * dt / 2.0;
        double complex m21 = al * dt, m22 = 1.0 + be * dt;
        double complex half_tr = (m11 + m22) / 2.0, det = m11 * m22 - m12 * m21;
        double complex root = csqrt(half_tr * half_tr - det);
        double rk = fmax(log(cabs(half_tr + root)), log(cabs(half_tr - root))) / dt;
        double complex lroot = csqrt(be * be / 4.0 + al);
        double ck = fmax(creal(be / 2.0 + lroot), creal(be / 2.0 - lroot));
        best_k[k] = rk;
        if (rk > r.discrete) r.discrete = rk, r.k = (int)(k <= n - k ? k : n - k);
        if (ck > r.continuous) r.continuous = ck;
    }
    for (size_t k = 1; k < n; k++) {
        size_t kk = k <= n - k ? k : n - k;
        if ((int)kk != r.k && best_k[k] > r.second) r.second = best_k[k];
    }
    free(best_k);
    return r;
}

/* ----------------------------------------------------------------------- CIRCLES reference (issue 3) */

/* The CIRCLES v3.1 parameters of two classes, typed from the table of issue 3 (not read from vehicles/). */
typedef struct Circ {
    double f_idle, c0, c1, c2, c3, p0, p1, p2, q0, q1;
    int    light;
    double v_c, beta, a0, a1, a3; /* light duty (a2, a4 multiply theta = 0) */
    double h0, h1;                /* heavy duty */
} Circ;

static const Circ COMPACT_SEDAN = {0.0972, 0.15918, 0.013463, 0.0, 3.1889e-05, 0.047828, 0.086975, 6.825e-08,
                                   0.0025557, 0.019099, 1, 5.04, 0.0972, -0.26981, -0.0023996, -0.00029215,
                                   NAN, NAN};
static const Circ CLASS8_TRACTOR = {0.2384, 0.59448, 0.082609, 0.0, 0.00027278, 0.20476, 1.1962, 0.019119, 0.0,
                                    0.14424, 0, NAN, NAN, NAN, NAN, NAN, 0.49109, 0.025152};

/* Fuel rate (g/s) at speed v >= 0, acceleration a, grade 0: steps 5-9 of issue 3's evaluation order. */
static double circles_f(const Circ *p, double v, double a)
{
    double P = p->p0 + p->p1 * v + p->p2 * v * v;
    double Q = p->q0 + p->q1 * fmax(v, 1e-12);
    double ap = fmax(a, -P / (2.0 * Q));
    double f = p->c0 + p->c1 * v + p->c2 * v * v + p->c3 * v * v * v + p->p0 * a + p->p1 * a * v +
               p->p2 * a * v * v + p->q0 * ap * ap + p->q1 * ap * ap * v;
    if (p->light) {
        f = fmax(f, v <= p->v_c ? p->beta : 0.0);
        if (v > p->v_c && a <= p->a0 + p->a1 * v + p->a3 * v * v) f = 0.0;
    } else {
        f = fmax(f, p->h0 + p->h1 * v);
    }
    if (v < 0.1 && fabs(a) < 0.01) f = p->f_idle;
    return f;
}

/* --------------------------------------------------------------------------- 1. uniform stable ring */

/* 10 compact sedans and 10 class-8 tractors, interleaved, all IDM, noise-free, at a gap where the uniform
 * flow is linearly stable (checked with ring_rates): the ring must stay uniform and every class burn
 * count x f(v_e, 0, 0) g/s over the statistics window. */
static void test_uniform_stable_ring(void)
{
    const size_t n = 20;
    const long n_sedan = 10, n_truck = 10;
    const double len_sedan = 4.5, len_truck = 20.0, gap = 40.0;
    const double duration = 300.0, warmup = 50.0, dt = 0.1;
    double L = (double)n_sedan * len_sedan + (double)n_truck * len_truck + (double)n * gap;
    double ve = idm_v_eq(&IDM_STD, gap);
    Rates r = ring_rates(idm_deriv(&IDM_STD, gap, ve), n, dt);
    CHECK(r.discrete < 0.0, "the chosen state must be linearly stable (largest rate %.6g 1/s)", r.discrete);

    /* Branches of the fuel formula at (v_e, 0, 0): no fuel cut (its threshold is below 0 = a), no lower
     * bound for the sedan (v_e > v_c); the tractor's polynomial is above its bound h0 + h1 v. */
    const Circ *cs = &COMPACT_SEDAN;
    CHECK(ve > cs->v_c && cs->a0 + cs->a1 * ve + cs->a3 * ve * ve < 0.0, "sedan branch at v_e = %.6g", ve);
    double f_sedan = circles_f(&COMPACT_SEDAN, ve, 0.0), f_truck = circles_f(&CLASS8_TRACTOR, ve, 0.0);
    CHECK(f_sedan > 0.0 && f_truck > CLASS8_TRACTOR.h0 + CLASS8_TRACTOR.h1 * ve, "fuel levels %.6g %.6g", f_sedan,
          f_truck);

    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "seed: 7\n"
             "road: {length_m: %.17g}\n"
             "time: {duration_s: %.17g, dt_s: %.17g, output_interval_s: 1, warmup_s: %.17g, integrator: ballistic}\n"
             "fleet:\n"
             "  vehicles: %zu\n"
             "  placement: interleaved\n"
             "  classes:\n"
             "    - {class: compact_sedan, count: %ld, length_m: %.17g}\n"
             "    - {class: class8_tractor, count: %ld, length_m: %.17g}\n"
             "  drivers:\n"
             "    - {name: idm, model: idm, fraction: 1, noise_mps2: 0,\n"
             "       params: {v0_mps: %.17g, T_s: %.17g, s0_m: %.17g, a_mps2: %.17g, b_mps2: %.17g, delta: %.17g}}\n"
             "initial: {state: equilibrium}\n",
             L, duration, dt, warmup, n, n_sedan, len_sedan, n_truck, len_truck, IDM_STD.v0, IDM_STD.T, IDM_STD.s0,
             IDM_STD.a, IDM_STD.b, IDM_STD.delta);
    WfScenario *sc = load_text("uniform.yaml", yaml);
    if (!sc) return;
    Recorder rec = {0};
    WfSim *sim = run_sim(sc, &rec);
    if (sim) {
        int ci_s = class_index(sc, "compact_sedan"), ci_t = class_index(sc, "class8_tractor");
        double max_sd = 0.0;
        int bad_rate = 0, bad_mean = 0;
        for (size_t k = 0; k < rec.n && ci_s >= 0 && ci_t >= 0; k++) {
            const WfTsRow *row = &rec.rows[k];
            max_sd = fmax(max_sd, row->v[WF_TS_SD_V]);
            bad_mean += !(fabs(row->v[WF_TS_MEAN_V] - ve) <= 1e-9 * ve);
            bad_rate += !(fabs(row->class_fuel_rate_gps[ci_s] - (double)n_sedan * f_sedan) <= 1e-9 * n_sedan * f_sedan);
            bad_rate += !(fabs(row->class_fuel_rate_gps[ci_t] - (double)n_truck * f_truck) <= 1e-9 * n_truck * f_truck);
        }
        CHECK(rec.n == (size_t)lround(duration) + 1, "%zu records", rec.n);
        CHECK(max_sd < 1e-9, "speed spread reached %.3g m/s", max_sd);
        CHECK(bad_mean == 0, "%d records with mean speed off v_e = %.17g", bad_mean, ve);
        CHECK(bad_rate == 0, "%d class fuel rates off count x f(v_e)", bad_rate);
        const WfSummary *s = wf_sim_summary(sim);
        double window = duration - warmup;
        if (ci_s >= 0 && ci_t >= 0) {
            CHECK_REL(s->cls[ci_s].fuel_g, (double)n_sedan * f_sedan * window, 1e-9);
            CHECK_REL(s->cls[ci_t].fuel_g, (double)n_truck * f_truck * window, 1e-9);
        }
        CHECK_REL(s->dist_m, (double)n * ve * window, 1e-9);
        printf("  uniform ring: gap %.0f m, v_e %.12g m/s, largest linear rate %.4g 1/s, max speed s.d. %.3g m/s\n",
               gap, ve, r.discrete, max_sd);
        if (ci_s >= 0 && ci_t >= 0)
            printf("  fuel over %.0f s: sedans %.12g g (expected %.12g), tractors %.12g g (expected %.12g)\n", window,
                   s->cls[ci_s].fuel_g, (double)n_sedan * f_sedan * window, s->cls[ci_t].fuel_g,
                   (double)n_truck * f_truck * window);
    }
    wf_sim_destroy(&sim);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

/* ------------------------------------------------------------------------------ 2. linear stability */

typedef struct StabCase {
    const char *label;
    int         is_idm;
    double      gap, duration, t_fit0, t_fit1;
    int         expect_unstable;
} StabCase;

/* Least-squares slope of ln(sd) against t over the records with t in [t0, t1]. */
static double log_slope(const Recorder *rec, double t0, double t1, double *sd_first, double *sd_max)
{
    double st = 0, sy = 0, stt = 0, sty = 0, m = 0;
    *sd_first = NAN, *sd_max = 0.0;
    for (size_t k = 0; k < rec->n; k++) {
        double t = rec->rows[k].v[WF_TS_T], sd = rec->rows[k].v[WF_TS_SD_V];
        *sd_max = fmax(*sd_max, sd);
        if (t < t0 - 1e-9 || t > t1 + 1e-9) continue;
        if (isnan(*sd_first)) *sd_first = sd;
        double y = log(sd);
        st += t, sy += y, stt += t * t, sty += t * y, m += 1;
    }
    return (m * sty - st * sy) / (m * stt - st * st);
}

/* A noise-free ring of 22 cars 5 m long at the uniform equilibrium, vehicle 0 displaced by 1e-5 m: after the
 * other modes have died out relative to the least stable one, the spatial speed s.d. changes as
 * exp(rate t). The fit window starts where the runner-up mode is down by exp(-(r1 - r2) t0) (checked). */
static void stability_case(const StabCase *c)
{
    const size_t n = 22;
    const double len = 5.0, dt = 0.05, dx = 1e-5;
    double L = (double)n * (c->gap + len), ve;
    Deriv d;
    char params[256];
    if (c->is_idm) {
        ve = idm_v_eq(&IDM_STD, c->gap);
        d = idm_deriv(&IDM_STD, c->gap, ve);
        snprintf(params, sizeof params,
                 "model: idm, params: {v0_mps: %.17g, T_s: %.17g, s0_m: %.17g, a_mps2: %.17g, b_mps2: %.17g, delta: %.17g}",
                 IDM_STD.v0, IDM_STD.T, IDM_STD.s0, IDM_STD.a, IDM_STD.b, IDM_STD.delta);
    } else {
        ve = ovm_V(&OVM_STD, c->gap);
        d = ovm_deriv(&OVM_STD, c->gap);
        snprintf(params, sizeof params,
                 "model: ovm, params: {alpha_per_s: %.17g, beta_m2_per_s: %.17g, v_max_mps: %.17g, d0_m: %.17g}",
                 OVM_STD.alpha, OVM_STD.beta, OVM_STD.v_max, OVM_STD.d0);
    }
    Rates r = ring_rates(d, n, dt);
    CHECK((r.discrete > 0.0) == c->expect_unstable, "%s: predicted rate %.6g 1/s has the wrong sign", c->label,
          r.discrete);
    CHECK((r.discrete - r.second) * c->t_fit0 >= 3.0, "%s: fit window starts too early for the mode gap %.4g 1/s",
          c->label, r.discrete - r.second);

    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "seed: 1\n"
             "road: {length_m: %.17g}\n"
             "time: {duration_s: %.17g, dt_s: %.17g, output_interval_s: 0.5, warmup_s: 0}\n"
             "fleet:\n"
             "  vehicles: %zu\n"
             "  placement: interleaved\n"
             "  classes: [{class: midsize_sedan, fraction: 1, length_m: %.17g}]\n"
             "  drivers: [{name: drivers, fraction: 1, noise_mps2: 0, %s}]\n"
             "initial: {state: equilibrium, perturbation: {vehicle: 0, dx_m: %.17g}}\n",
             L, c->duration, dt, n, len, params, dx);
    char name[64];
    snprintf(name, sizeof name, "stab_%s_%.0f.yaml", c->is_idm ? "idm" : "ovm", c->gap);
    WfScenario *sc = load_text(name, yaml);
    if (!sc) return;
    Recorder rec = {0};
    WfSim *sim = run_sim(sc, &rec);
    if (sim) {
        double sd_first, sd_max;
        double meas = log_slope(&rec, c->t_fit0, c->t_fit1, &sd_first, &sd_max);
        CHECK(fabs(wf_sim_fleet(sim)->v_init_mps - ve) <= 1e-9 * ve, "%s: engine equilibrium %.17g, test %.17g",
              c->label, wf_sim_fleet(sim)->v_init_mps, ve);
        /* Inside the linear regime and far above round-off (speeds ~10 m/s carry ~1e-15 m/s of it). */
        CHECK(sd_max < 0.05 && sd_first > 1e-11, "%s: s.d. %.3g at the window start, max %.3g", c->label, sd_first,
              sd_max);
        CHECK(fabs(meas - r.discrete) <= 0.10 * fabs(r.discrete), "%s: measured rate %.6g 1/s, predicted %.6g 1/s",
              c->label, meas, r.discrete);
        printf("  %-22s gap %4.1f m v_e %7.4f m/s  k=%d: predicted %+.6f 1/s (ballistic map, dt %.2g s; continuous "
               "%+.6f; next mode %+.6f), measured %+.6f 1/s (rel. diff %.2g) over [%g, %g] s\n",
               c->label, c->gap, ve, r.k, r.discrete, dt, r.continuous, r.second, meas,
               (meas - r.discrete) / fabs(r.discrete), c->t_fit0, c->t_fit1);
    }
    wf_sim_destroy(&sim);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

static void test_linear_stability_idm(void)
{
    const StabCase unstable = {"IDM unstable", 1, 10.0, 300.0, 100.0, 300.0, 1};
    const StabCase stable = {"IDM stable", 1, 20.0, 300.0, 100.0, 300.0, 0};
    stability_case(&unstable);
    stability_case(&stable);
}

static void test_linear_stability_ovm(void)
{
    const StabCase unstable = {"OV-FTL unstable", 0, 4.0, 200.0, 60.0, 200.0, 1};
    const StabCase stable = {"OV-FTL stable", 0, 8.0, 250.0, 100.0, 250.0, 0};
    stability_case(&unstable);
    stability_case(&stable);
}

/* --------------------------------------------------------------------------------- 3. invariants */

typedef struct Inv {
    size_t  n;         /* vehicles the scenario asked for */
    double *prev_fuel; /* fuel_g at the previous record */
    double  prev_overlaps;
    long    records, violations;
} Inv;

/* At each record: count conserved, ring order (x increasing, the last vehicle less than a lap behind the
 * first), gaps recomputed from positions >= 0 and equal to the engine's, min_gap column consistent and >= 0,
 * speeds >= 0, fuel accumulators and overlap count non-decreasing. */
/* A violated invariant is counted and reported (the first few through CHECK). */
#define INV(cond, ...)                 \
    do {                               \
        if (!(cond)) {                 \
            bad++;                     \
            CHECK(cond, __VA_ARGS__);  \
        }                              \
    } while (0)

static void inv_check(void *ctx, const WfSim *sim, const WfTsRow *row)
{
    Inv *inv = ctx;
    const WfFleet *f = wf_sim_fleet(sim);
    double L = wf_sim_scenario(sim)->road.length_m, t = row->v[WF_TS_T];
    long bad = 0;
    inv->records++;
    INV(f->n == inv->n, "t = %g: %zu vehicles, expected %zu", t, f->n, inv->n);
    if (f->n != inv->n) {
        inv->violations += bad;
        return;
    }
    double gmin = INFINITY;
    for (size_t i = 0; i < f->n; i++) {
        size_t lead = i + 1 < f->n ? i + 1 : 0;
        double xl = f->x_m[lead] + (lead == 0 ? L : 0.0);
        double g = xl - wf_fleet_length(f, lead) - f->x_m[i];
        gmin = fmin(gmin, g);
        INV(i + 1 == f->n || f->x_m[i + 1] > f->x_m[i], "t = %g: x[%zu] >= x[%zu]", t, i, i + 1);
        INV(g >= 0.0, "t = %g: gap of %zu = %.17g m", t, i, g);
        /* the multi-pass step keeps the gaps it used fleet-wide: they must be the ones recomputed here */
        if (f->gap_m) INV(fabs(g - f->gap_m[i]) <= 1e-9, "t = %g: gap of %zu %.17g m, engine %.17g m", t, i, g, f->gap_m[i]);
        INV(f->v_mps[i] >= 0.0, "t = %g: speed of %zu = %.17g m/s", t, i, f->v_mps[i]);
        INV(f->fuel_g[i] >= inv->prev_fuel[i], "t = %g: fuel of %zu decreased", t, i);
        inv->prev_fuel[i] = f->fuel_g[i];
    }
    INV(f->x_m[f->n - 1] - f->x_m[0] < L, "t = %g: the fleet spans more than a lap", t);
    /* The multi-pass step records before it steps, so the fleet is at the row's instant (the fused step gives the
     * same rows: tests/test_engine_paths.c). */
    if (f->gap_m)
        INV(row->v[WF_TS_MIN_GAP] >= 0.0 && fabs(row->v[WF_TS_MIN_GAP] - gmin) <= 1e-9,
            "t = %g: min_gap column %.17g m, recomputed %.17g m", t, row->v[WF_TS_MIN_GAP], gmin);
    INV(row->v[WF_TS_OVERLAPS] >= inv->prev_overlaps, "t = %g: overlap count decreased", t);
    inv->prev_overlaps = row->v[WF_TS_OVERLAPS];
    for (size_t c = 0; c < f->n_classes; c++)
        INV(row->class_fuel_rate_gps[c] >= 0.0, "t = %g: class %zu fuel rate < 0", t, c);
    inv->violations += bad;
}

/* Run a Sugiyama-like ring (22 IDM cars on 230 m) with the given noise and emergency deceleration,
 * checking the invariants at every record; returns the overlap count of the summary (-1 on failure). */
static long invariant_run(const char *name, double noise, double decel_max, double duration)
{
    const size_t n = 22;
    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "seed: 2008\n"
             "road: {length_m: 230}\n"
             /* multi-pass: the fleet is at the record's instant, so the rows can be recomputed from it */
             "time: {duration_s: %.17g, dt_s: 0.1, output_interval_s: 0.5, warmup_s: 20, fused_step: false}\n"
             "fleet:\n"
             "  vehicles: %zu\n"
             "  placement: interleaved\n"
             "  classes: [{class: midsize_sedan, count: 11, length_m: 4.5}, {class: compact_sedan, count: 11}]\n"
             "  drivers:\n"
             "    - {name: human, model: idm, fraction: 1, noise_mps2: %.17g, decel_max_mps2: %.17g,\n"
             "       params: {v0_mps: 30, T_s: 1.0, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5, delta: 4}}\n"
             "initial: {state: equilibrium, jitter_m: 0.1}\n",
             duration, n, noise, decel_max);
    WfScenario *sc = load_text(name, yaml);
    if (!sc) return -1;
    Inv inv = {n, calloc(n, sizeof(double)), 0.0, 0, 0};
    Recorder rec = {.check = inv_check, .check_ctx = &inv};
    long overlaps = -1;
    WfSim *sim = inv.prev_fuel ? run_sim(sc, &rec) : NULL;
    if (sim) {
        long expect = lround(duration / 0.5) + 1;
        CHECK(inv.records == expect, "%s: %ld records checked, expected %ld", name, inv.records, expect);
        CHECK(inv.violations == 0, "%s: %ld invariant violations", name, inv.violations);
        const WfSummary *s = wf_sim_summary(sim);
        overlaps = (long)s->overlaps;
        CHECK(rec.n > 0 && rec.rows[rec.n - 1].v[WF_TS_OVERLAPS] == (double)s->overlaps,
              "%s: last record's overlaps differ from the summary's %ld", name, overlaps);
        double sd_max = 0;
        for (size_t k = 0; k < rec.n; k++) sd_max = fmax(sd_max, rec.rows[k].v[WF_TS_SD_V]);
        printf("  %s: noise %g m/s^2, decel_max %g m/s^2: %ld records checked, %ld overlap events, max speed s.d. "
               "%.3g m/s\n", name, noise, decel_max, inv.records, overlaps, sd_max);
    }
    wf_sim_destroy(&sim);
    rec_free(&rec);
    free(inv.prev_fuel);
    wf_scenario_destroy(&sc);
    return overlaps;
}

static void test_invariants_noisy_ring(void)
{
    long ov = invariant_run("inv_noisy.yaml", 0.5, 9.0, 300.0);
    CHECK(ov >= 0, "run failed");
}

/* Noise far beyond what the limited brakes can answer: vehicles must run into their leaders, every such
 * event must be counted, and the gaps still stay >= 0. */
static void test_invariants_overlaps(void)
{
    long ov = invariant_run("inv_overlap.yaml", 5.0, 0.5, 120.0);
    CHECK(ov > 0, "expected overlap events, summary reports %ld", ov);
}

/* ------------------------------------------------------------------------------- 4. determinism */

typedef struct Snapshot {
    size_t   n;
    double  *x, *v, *a, *fuel, *dist;
    Recorder rec;
    WfSummary summary;
    int      threads;
} Snapshot;

static void snap_free(Snapshot *s)
{
    free(s->x), free(s->v), free(s->a), free(s->fuel), free(s->dist);
    rec_free(&s->rec);
    memset(s, 0, sizeof *s);
}

static double *copy_array(const double *src, size_t n)
{
    double *p = malloc(n * sizeof *p);
    CHECK(p != NULL, "out of memory");
    if (p) memcpy(p, src, n * sizeof *p);
    return p;
}

static int run_snapshot(const WfScenario *sc, int threads, Snapshot *out)
{
    memset(out, 0, sizeof *out);
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
    WfSim *sim = run_sim(sc, &out->rec);
    if (!sim) return -1;
    const WfFleet *f = wf_sim_fleet(sim);
    out->n = f->n;
    out->x = copy_array(f->x_m, f->n);
    out->v = copy_array(f->v_mps, f->n);
    out->a = copy_array(f->sum_a2, f->n); /* the accelerations, through their accumulated squares */
    out->fuel = copy_array(f->fuel_g, f->n);
    out->dist = copy_array(f->x_start_m, f->n);
    out->summary = *wf_sim_summary(sim);
    out->threads = wf_sim_threads(sim);
    wf_sim_destroy(&sim);
    return out->x && out->v && out->a && out->fuel && out->dist ? 0 : -1;
}

static int same_bits(const double *a, const double *b, size_t n) { return memcmp(a, b, n * sizeof *a) == 0; }

/* 20000 vehicles (above the engine's serial threshold in every phase), two classes and two driver groups
 * placed at random, heterogeneous parameters, noise: 1 and 2 threads must give the same bits. The fleet
 * starts at rest: noise then drives speeds below 0 within steps (the integrator's stopping branch), and the
 * serial heterogeneous-equilibrium solve of wf_fleet_create (about 6 s for 20000 vehicles) is not what this
 * test is about. */
static void test_determinism_threads(void)
{
#ifdef _OPENMP
    int saved = omp_get_max_threads();
#endif
    const char *yaml =
        "seed: 424242\n"
        "road: {length_m: 560000}\n"
        "time: {duration_s: 20, dt_s: 0.1, output_interval_s: 1, warmup_s: 5}\n"
        "fleet:\n"
        "  vehicles: 20000\n"
        "  placement: random\n"
        "  classes: [{class: midsize_sedan, fraction: 0.7}, {class: class8_tractor, fraction: 0.3}]\n"
        "  drivers:\n"
        "    - name: idm\n"
        "      model: idm\n"
        "      fraction: 0.7\n"
        "      params: {v0_mps: 30, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5, delta: 4}\n"
        "      heterogeneity: {distribution: normal, spread: {v0_mps: 0.1, T_s: 0.2, a_mps2: 0.1}}\n"
        "      noise_mps2: 0.4\n"
        "    - name: ovm\n"
        "      model: ovm\n"
        "      fraction: 0.3\n"
        "      params: {alpha_per_s: 0.6, beta_m2_per_s: 20, v_max_mps: 25, d0_m: 6}\n"
        "      heterogeneity: {distribution: uniform, spread: {alpha_per_s: 0.2}}\n"
        "      noise_mps2: 0.4\n"
        "initial: {state: rest, jitter_m: 0.5}\n";
    WfScenario *sc = load_text("determinism.yaml", yaml);
    if (!sc) return;
    Snapshot one, two;
    int rc1 = run_snapshot(sc, 1, &one);
    int rc2 = run_snapshot(sc, 2, &two);
    if (!rc1 && !rc2) {
#ifdef _OPENMP
        CHECK(one.threads == 1 && two.threads == 2, "threads used: %d and %d", one.threads, two.threads);
#endif
        CHECK(one.n == 20000 && two.n == one.n, "fleet sizes %zu %zu", one.n, two.n);
        CHECK(same_bits(one.x, two.x, one.n), "positions differ between 1 and 2 threads");
        CHECK(same_bits(one.v, two.v, one.n), "speeds differ between 1 and 2 threads");
        CHECK(same_bits(one.a, two.a, one.n), "accelerations differ between 1 and 2 threads");
        CHECK(same_bits(one.fuel, two.fuel, one.n), "per-vehicle fuel differs between 1 and 2 threads");
        CHECK(same_bits(one.dist, two.dist, one.n), "per-vehicle distance differs between 1 and 2 threads");
        CHECK(one.rec.n == 21 && two.rec.n == one.rec.n, "record counts %zu %zu", one.rec.n, two.rec.n);
        CHECK(one.rec.n == two.rec.n && memcmp(one.rec.rows, two.rec.rows, one.rec.n * sizeof(WfTsRow)) == 0,
              "time-series records differ between 1 and 2 threads");
        CHECK(memcmp(&one.summary, &two.summary, sizeof one.summary) == 0, "summaries differ");
        /* The run must have done something the check can catch: vehicles moved apart in speed and burnt fuel. */
        CHECK(one.rec.n > 0 && one.rec.rows[one.rec.n - 1].v[WF_TS_SD_V] > 0.01 && one.summary.fuel_g > 0.0,
              "degenerate run (s.d. %.3g m/s, fuel %.3g g)", one.rec.n ? one.rec.rows[one.rec.n - 1].v[WF_TS_SD_V] : 0.0,
              one.summary.fuel_g);
        printf("  determinism: %zu vehicles, threads %d vs %d: fleet fuel %.17g g, final speed s.d. %.6g m/s\n", one.n,
               one.threads, two.threads, one.summary.fuel_g, one.rec.n ? one.rec.rows[one.rec.n - 1].v[WF_TS_SD_V] : 0.0);
    }
    snap_free(&one);
    snap_free(&two);
    wf_scenario_destroy(&sc);
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
}

/* ---------------------------------------------------------------------------------------- main */

static void remove_tmp_dir(void)
{
    static const char *const names[] = {"uniform.yaml", "stab_idm_10.yaml", "stab_idm_20.yaml", "stab_ovm_4.yaml",
                                        "stab_ovm_8.yaml", "inv_noisy.yaml", "inv_overlap.yaml", "determinism.yaml"};
    char path[256];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", tmp_dir, names[i]);
        unlink(path);
    }
    rmdir(tmp_dir);
}

int main(void)
{
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/wf_ring_physics_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
        printf("FAIL setup: mkdtemp: cannot create a temporary directory\n");
        return 1;
    }
    RUN(test_uniform_stable_ring);
    RUN(test_linear_stability_idm);
    RUN(test_linear_stability_ovm);
    RUN(test_invariants_noisy_ring);
    RUN(test_invariants_overlaps);
    RUN(test_determinism_threads);
    remove_tmp_dir();
    TEST_EXIT();
}
