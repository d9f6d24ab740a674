/* Car-following models (src/models/cf/idm.c, ovm.c, gipps.c) against references computed here: closed-form
 * equilibria re-derived from each paper's equation, free-road limits, hand-computed accelerations, property
 * sweeps over gaps [0, 500] m and speeds [0, 40] m/s, and the registry/spec contract. Parameters are set
 * through the spec tables only, so the tests do not depend on the models' private structs. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wf_test.h"

/* Parameter block big enough for every model (checked in test_spec_tables). */
typedef struct Params {
    double v[16];
} Params;

static Params defaults(const WfCfModel *m)
{
    Params p;
    memset(&p, 0, sizeof p);
    wf_param_defaults(m->spec, m->n_spec, &p);
    return p;
}

static void set(const WfCfModel *m, Params *p, const char *key, double value)
{
    const WfParamSpec *s = wf_param_find(m->spec, m->n_spec, key);
    CHECK(s != NULL, "%s has no key '%s'", m->name, key);
    if (s) *wf_param_ptr(p, s) = value;
}

static double get(const WfCfModel *m, const Params *p, const char *key)
{
    const WfParamSpec *s = wf_param_find(m->spec, m->n_spec, key);
    CHECK(s != NULL, "%s has no key '%s'", m->name, key);
    return s ? wf_param_get(p, s) : NAN;
}

static double acc(const WfCfModel *m, const Params *p, double gap_m, double v_mps, double v_lead_mps)
{
    return m->accel(p, NULL, gap_m, v_mps, v_lead_mps);
}

/* ---------------------------------------------------------------- parameter sets used by several tests */

/* IDM away from the defaults, with a non-integer delta (the pow() branch). */
static Params idm_varied(void)
{
    Params p = defaults(&wf_cf_idm);
    set(&wf_cf_idm, &p, "v0_mps", 33.0);
    set(&wf_cf_idm, &p, "T_s", 1.6);
    set(&wf_cf_idm, &p, "s0_m", 0.1);
    set(&wf_cf_idm, &p, "a_mps2", 0.3);
    set(&wf_cf_idm, &p, "b_mps2", 3.0);
    set(&wf_cf_idm, &p, "delta", 2.5);
    return p;
}

/* Pure Bando OVM (beta = 0) with a stiff relaxation and a long length scale. */
static Params ovm_varied(void)
{
    Params p = defaults(&wf_cf_ovm);
    set(&wf_cf_ovm, &p, "alpha_per_s", 2.0);
    set(&wf_cf_ovm, &p, "beta_m2_per_s", 0.0);
    set(&wf_cf_ovm, &p, "v_max_mps", 33.0);
    set(&wf_cf_ovm, &p, "d0_m", 10.0);
    return p;
}

/* Gipps with b_hat exactly at the smallest value check() accepts: the tightest admissible case. */
static Params gipps_varied(void)
{
    Params p = defaults(&wf_cf_gipps);
    double b = 4.0, tau = 1.0, V = 25.0;
    set(&wf_cf_gipps, &p, "a_mps2", 2.5);
    set(&wf_cf_gipps, &p, "b_mps2", b);
    set(&wf_cf_gipps, &p, "tau_s", tau);
    set(&wf_cf_gipps, &p, "v0_mps", V);
    set(&wf_cf_gipps, &p, "s0_m", 0.0);
    set(&wf_cf_gipps, &p, "b_hat_mps2", b / (1.0 + 1.5 * b * tau / V));
    return p;
}

/* ---------------------------------------------------------------- registry and spec tables */

static void test_registry_find(void)
{
    const WfCfModel *m = NULL;
    WfError err = {0};
    CHECK(wf_cf_model_find("idm", &m, &err) == 0 && m == &wf_cf_idm, "idm not found: %s", err.msg);
    CHECK(wf_cf_model_find("ovm", &m, &err) == 0 && m == &wf_cf_ovm, "ovm not found: %s", err.msg);
    CHECK(wf_cf_model_find("gipps", &m, &err) == 0 && m == &wf_cf_gipps, "gipps not found: %s", err.msg);
    m = NULL;
    int rc = wf_cf_model_find("krauss", &m, &err);
    CHECK(rc == WF_EINPUT && err.code == WF_EINPUT, "unknown name gave %d", rc);
    CHECK(m == NULL, "unknown name must not set the output");
    CHECK(strstr(err.msg, "krauss") != NULL, "message does not name the unknown model: %s", err.msg);
    for (size_t i = 0; wf_cf_models[i]; i++)
        CHECK(strstr(err.msg, wf_cf_models[i]->name) != NULL, "message does not list '%s': %s",
              wf_cf_models[i]->name, err.msg);
}

/* The unit suffix a key must carry for its unit (STYLE: units in names). */
static const char *suffix_for_unit(const char *unit)
{
    static const char *const map[][2] = {
        {"m/s", "_mps"}, {"m/s^2", "_mps2"}, {"s", "_s"}, {"m", "_m"}, {"1/s", "_per_s"}, {"m^2/s", "_m2_per_s"},
        {"1/s^2", "_per_s2"},
    };
    for (size_t i = 0; i < sizeof map / sizeof map[0]; i++)
        if (strcmp(unit, map[i][0]) == 0) return map[i][1];
    return NULL;
}

static int ends_with(const char *s, const char *suffix)
{
    size_t ls = strlen(s), lx = strlen(suffix);
    return ls >= lx && strcmp(s + ls - lx, suffix) == 0;
}

static void test_spec_tables(void)
{
    size_t count = 0;
    for (size_t i = 0; wf_cf_models[i]; i++) {
        const WfCfModel *m = wf_cf_models[i];
        CHECK(m->name && m->name[0] && m->doc && m->doc[0], "model %zu lacks a name or doc", i);
        CHECK(m->param_size <= sizeof(Params), "%s: params larger than the test buffer", m->name);
        /* A struct of doubles fully described by its spec: one entry per double. */
        CHECK(m->n_spec * sizeof(double) == m->param_size, "%s: %zu spec entries for %zu bytes", m->name, m->n_spec,
              m->param_size);
        /* Human-driver models are memoryless; controllers (tests/test_controllers.c) may keep state. */
        int human = !strcmp(m->name, "idm") || !strcmp(m->name, "ovm") || !strcmp(m->name, "gipps");
        count += human;
        if (human)
            CHECK(m->state_size == 0 && m->init_state == NULL && m->update_state == NULL, "%s: memoryless expected",
                  m->name);
        else /* state without an update only for a command set from outside */
            CHECK(m->update_state ? m->state_size > 0 : m->state_size == 0 || m->external,
                  "%s: state without an update, or vice versa", m->name);
        CHECK(m->accel != NULL, "%s: no accel", m->name);
        unsigned seen = 0;
        for (size_t k = 0; k < m->n_spec; k++) {
            const WfParamSpec *s = &m->spec[k];
            CHECK(s->def >= s->min && s->def <= s->max, "%s.%s default %g outside [%g, %g]", m->name, s->key, s->def,
                  s->min, s->max);
            CHECK(s->min < s->max, "%s.%s empty range", m->name, s->key);
            CHECK(s->flags == 0, "%s.%s: every car-following parameter has a default", m->name, s->key);
            CHECK(s->unit && s->unit[0] && s->doc && s->doc[0], "%s.%s lacks unit or doc", m->name, s->key);
            CHECK(s->offset % sizeof(double) == 0 && s->offset < m->param_size, "%s.%s bad offset %zu", m->name,
                  s->key, s->offset);
            size_t slot = s->offset / sizeof(double);
            CHECK(slot < 32 && !(seen & (1u << slot)), "%s.%s shares a field", m->name, s->key);
            if (slot < 32) seen |= 1u << slot;
            CHECK(wf_param_find(m->spec, m->n_spec, s->key) == s, "%s.%s duplicated key", m->name, s->key);
            if (strcmp(s->unit, "1") != 0) {
                const char *suf = suffix_for_unit(s->unit);
                CHECK(suf && ends_with(s->key, suf), "%s.%s: unit %s but key lacks suffix %s", m->name, s->key,
                      s->unit, suf ? suf : "?");
            }
        }
        Params p = defaults(m);
        WfError err = {0};
        if (m->check) CHECK(m->check(&p, &err) == 0, "%s: defaults rejected: %s", m->name, err.msg);
        CHECK(isfinite(acc(m, &p, 10.0, 5.0, 5.0)), "%s: non-finite at defaults", m->name);
    }
    CHECK(count == 3, "expected idm, ovm and gipps in the registry; found %zu of them", count);
}

static void test_gipps_check(void)
{
    const WfCfModel *m = &wf_cf_gipps;
    WfError err = {0};
    Params p = gipps_varied(); /* b_hat exactly at the bound: accepted */
    CHECK(m->check(&p, &err) == 0, "bound itself rejected: %s", err.msg);
    set(m, &p, "b_hat_mps2", get(m, &p, "b_hat_mps2") * (1.0 - 1e-9));
    CHECK(m->check(&p, &err) == WF_EINPUT, "just below the bound accepted");

    /* A driver who thinks the leader brakes at 1 m/s^2 while braking at 5 m/s^2 itself. */
    p = defaults(m);
    set(m, &p, "b_mps2", 5.0);
    set(m, &p, "b_hat_mps2", 1.0);
    memset(&err, 0, sizeof err);
    CHECK(m->check(&p, &err) == WF_EINPUT, "inconsistent set accepted");
    CHECK(strstr(err.msg, "b_hat_mps2") != NULL, "message does not name the key: %s", err.msg);

    /* Why it must be rejected: with v_lead = v, c = b/b_hat - 1 = 4 and d = gap - s0 = 0.5 m, the braking
     * speed exceeds v where Q(v) = -c v^2 + 3 b tau v - 2 b d = -4 v^2 + 9.9 v - 5 is negative, i.e. outside
     * the roots (9.9 -+ sqrt(9.9^2 - 80)) / 8 = 0.7079 and 1.7671 m/s. So accel(s, v, v) is > 0 below 0.7079,
     * < 0 between the roots, > 0 again up to V = 30 m/s and < 0 above: three uniform-flow speeds. */
    double gap = 2.5, r1 = (9.9 - sqrt(9.9 * 9.9 - 80.0)) / 8.0, r2 = (9.9 + sqrt(9.9 * 9.9 - 80.0)) / 8.0;
    CHECK(acc(m, &p, gap, 0.5 * r1, 0.5 * r1) > 0.0, "expected > 0 below the first root");
    CHECK(acc(m, &p, gap, 0.5 * (r1 + r2), 0.5 * (r1 + r2)) < 0.0, "expected < 0 between the roots");
    CHECK(acc(m, &p, gap, 10.0, 10.0) > 0.0, "expected > 0 above the second root");
    CHECK(acc(m, &p, gap, 35.0, 35.0) < 0.0, "expected < 0 above V");
}

/* ---------------------------------------------------------------- property sweeps */

enum { N_GAP_SMALL = 8, N_GAP_LIN = 2000, N_GAP = N_GAP_SMALL + N_GAP_LIN + 1, N_V = 81, N_VL = 41 };

static double sweep_gap(int i)
{
    static const double small[N_GAP_SMALL] = {0.0, 1e-9, 1e-6, 1e-4, 1e-3, 2e-3, 0.01, 0.1};
    return i < N_GAP_SMALL ? small[i] : 0.25 * (i - N_GAP_SMALL + 1); /* 0.25 .. 500.25 m */
}

/* monotone_v: 1 = strictly decreasing in v at v_lead = v (IDM, OVM); 0 = only one sign change from > 0 to
 * <= 0 (Gipps, whose free-road branch rises with v below 0.95 V / 3 by design). gap_all_leaders: accel is
 * non-decreasing in gap for every v_lead (IDM, Gipps) or only for v_lead <= v (OVM: closing in on a faster
 * leader, its follow-the-leader term beta (v_lead - v)/s^2 > 0 shrinks with s). */
static void sweep(const WfCfModel *m, const Params *p, int monotone_v, int gap_all_leaders)
{
    long bad_finite = 0, bad_v = 0, bad_gap = 0;
    for (int i = 0; i < N_GAP; i++) {
        double s = sweep_gap(i);
        int went_nonpositive = 0;
        double prev = 0.0;
        for (int j = 0; j < N_V; j++) {
            double v = 0.5 * j;
            double a = acc(m, p, s, v, v);
            if (monotone_v && j > 0 && !(a < prev)) {
                if (bad_v++ < 3) printf("  %s: not decreasing in v at gap %g: a(%g) = %.17g >= %.17g\n", m->name, s, v,
                                        a, prev);
            }
            if (!monotone_v) {
                if (went_nonpositive && a > 0.0 && bad_v++ < 3)
                    printf("  %s: second sign change at gap %g, v %g: a = %g\n", m->name, s, v, a);
                if (a <= 0.0) went_nonpositive = 1;
            }
            prev = a;
            for (int k = 0; k < N_VL; k++) {
                double vl = 1.0 * k;
                double ak = acc(m, p, s, v, vl);
                if (!isfinite(ak) && bad_finite++ < 3)
                    printf("  %s: non-finite at gap %g v %g v_lead %g\n", m->name, s, v, vl);
                if (i > 0 && (gap_all_leaders || vl <= v)) {
                    double a_prev_gap = acc(m, p, sweep_gap(i - 1), v, vl);
                    if (ak < a_prev_gap && bad_gap++ < 3)
                        printf("  %s: decreasing in gap at %g (v %g, v_lead %g): %.17g < %.17g\n", m->name, s, v, vl,
                               ak, a_prev_gap);
                }
            }
        }
    }
    CHECK(bad_finite == 0, "%s: %ld non-finite values", m->name, bad_finite);
    CHECK(bad_v == 0, "%s: %ld violations of the v-ordering needed by the equilibrium solver", m->name, bad_v);
    CHECK(bad_gap == 0, "%s: %ld points where accel decreases with the gap", m->name, bad_gap);
}

static void test_sweep_idm(void)
{
    Params p = defaults(&wf_cf_idm);
    sweep(&wf_cf_idm, &p, 1, 1);
    p = idm_varied();
    sweep(&wf_cf_idm, &p, 1, 1);
}

static void test_sweep_ovm(void)
{
    Params p = defaults(&wf_cf_ovm);
    sweep(&wf_cf_ovm, &p, 1, 0);
    p = ovm_varied();
    sweep(&wf_cf_ovm, &p, 1, 0);
}

static void test_sweep_gipps(void)
{
    Params p = defaults(&wf_cf_gipps);
    sweep(&wf_cf_gipps, &p, 0, 1);
    p = gipps_varied();
    sweep(&wf_cf_gipps, &p, 0, 1);
}

/* ---------------------------------------------------------------- equilibria */

/* IDM: accel(s, v, v) = 0 with s* = s0 + v T (v_lead = v kills the dynamic term) gives
 * 1 - (v/v0)^delta = ((s0 + v T)/s)^2, i.e. s_e(v) = (s0 + v T) / sqrt(1 - (v/v0)^delta). */
static void idm_equilibrium_case(const Params *p)
{
    const WfCfModel *m = &wf_cf_idm;
    double v0 = get(m, p, "v0_mps"), T = get(m, p, "T_s"), s0 = get(m, p, "s0_m"), delta = get(m, p, "delta");
    double a_max = get(m, p, "a_mps2");
    const double vs[] = {0.5, 3.0, 8.0, 12.5, 17.0, 22.0, 26.0, 0.97 * v0};
    for (size_t i = 0; i < sizeof vs / sizeof vs[0]; i++) {
        double v = vs[i];
        double s_e = (s0 + v * T) / sqrt(1.0 - pow(v / v0, delta));
        double v_e = wf_cf_equilibrium_speed(m, p, s_e, 40.0);
        CHECK_ABS(v_e, v, 1e-9);
        CHECK_ABS(acc(m, p, s_e, v_e, v_e), 0.0, 1e-12 * a_max);
    }
    /* Below the jam distance even a stopped vehicle brakes: equilibrium speed 0. */
    CHECK(wf_cf_equilibrium_speed(m, p, 0.5 * s0, 40.0) == 0.0, "gap < s0 must give 0");
}

static void test_equilibrium_idm(void)
{
    Params p = defaults(&wf_cf_idm);
    idm_equilibrium_case(&p);
    p = idm_varied();
    idm_equilibrium_case(&p);
}

/* OVM: at v_lead = v the follow-the-leader term vanishes and accel = alpha (V(s) - v): the root is V(s). */
static void ovm_equilibrium_case(const Params *p)
{
    const WfCfModel *m = &wf_cf_ovm;
    double vmax = get(m, p, "v_max_mps"), d0 = get(m, p, "d0_m"), alpha = get(m, p, "alpha_per_s");
    const double gaps[] = {0.0, 0.5, 2.0, 4.46, 7.0, 10.0, 20.0, 45.0, 100.0, 500.0};
    for (size_t i = 0; i < sizeof gaps / sizeof gaps[0]; i++) {
        double s = gaps[i];
        double V = vmax * (tanh(s / d0 - 2.0) + tanh(2.0)) / (1.0 + tanh(2.0));
        double v_e = wf_cf_equilibrium_speed(m, p, s, 40.0);
        CHECK_ABS(v_e, V, 1e-12 * vmax);
        CHECK_ABS(acc(m, p, s, v_e, v_e), 0.0, 1e-12 * alpha * vmax);
    }
    /* V(0) = v_max (tanh(-2) + tanh(2)) / (1 + tanh 2) = 0 exactly: a stopped queue stays stopped. */
    CHECK(acc(m, p, 0.0, 0.0, 0.0) == 0.0, "accel(0, 0, 0) = %.17g, want exactly 0", acc(m, p, 0.0, 0.0, 0.0));
}

static void test_equilibrium_ovm(void)
{
    Params p = defaults(&wf_cf_ovm);
    ovm_equilibrium_case(&p);
    p = ovm_varied();
    ovm_equilibrium_case(&p);
}

/* Gipps, braking branch at v_lead = v and d = gap - s0: v_brk = v  <=>  (v + b tau)^2 = b^2 tau^2
 * + b (2 d - v tau + v^2 / b_hat)  <=>  c v^2 - 3 b tau v + 2 b d = 0 with c = b/b_hat - 1. Its smaller
 * non-negative root, written without cancellation (and valid for c = 0, where it is 2d / (3 tau)), is
 * v_b = 4 b d / (3 b tau + sqrt(9 b^2 tau^2 - 8 c b d)). No real root (c > 0 and a large d) means the braking
 * constraint never binds. The free branch crosses zero at v = V, so v_e = min(V, v_b), and 0 when d <= 0. */
static double gipps_equilibrium_reference(const Params *p, double gap)
{
    const WfCfModel *m = &wf_cf_gipps;
    double b = get(m, p, "b_mps2"), bh = get(m, p, "b_hat_mps2"), tau = get(m, p, "tau_s");
    double V = get(m, p, "v0_mps"), d = gap - get(m, p, "s0_m");
    if (d <= 0.0) return 0.0;
    double c = b / bh - 1.0;
    double disc = 9.0 * b * b * tau * tau - 8.0 * c * b * d;
    if (disc < 0.0) return V;
    double vb = 4.0 * b * d / (3.0 * b * tau + sqrt(disc));
    return vb < V ? vb : V;
}

static void gipps_equilibrium_case(const Params *p)
{
    const WfCfModel *m = &wf_cf_gipps;
    const double gaps[] = {0.5, 1.0, 2.5, 3.0, 5.0, 8.0, 12.0, 20.0, 30.0, 40.0, 60.0, 100.0, 500.0};
    for (size_t i = 0; i < sizeof gaps / sizeof gaps[0]; i++) {
        double want = gipps_equilibrium_reference(p, gaps[i]);
        double v_e = wf_cf_equilibrium_speed(m, p, gaps[i], 40.0);
        CHECK_ABS(v_e, want, 1e-9);
        CHECK_ABS(acc(m, p, gaps[i], v_e, v_e), 0.0, 1e-9);
    }
}

static void test_equilibrium_gipps(void)
{
    Params p = defaults(&wf_cf_gipps); /* b = b_hat: v_e = 2 (gap - s0) / (3 tau) below V */
    CHECK_ABS(gipps_equilibrium_reference(&p, 12.0), 2.0 * 10.0 / (3.0 * 0.66), 1e-12);
    gipps_equilibrium_case(&p);
    set(&wf_cf_gipps, &p, "b_hat_mps2", 4.0); /* c < 0: the quadratic term slows the rise */
    gipps_equilibrium_case(&p);
    p = gipps_varied(); /* c > 0 at the admissible bound */
    gipps_equilibrium_case(&p);
}

/* ---------------------------------------------------------------- free road */

static void test_free_road(void)
{
    const double huge = 1e9; /* m: every interaction term is below 1e-15 of the free-road one */
    Params p = defaults(&wf_cf_idm);
    for (int k = 0; k < 2; k++) {
        double a = get(&wf_cf_idm, &p, "a_mps2"), v0 = get(&wf_cf_idm, &p, "v0_mps");
        CHECK_REL(acc(&wf_cf_idm, &p, huge, 0.0, 0.0), a, 1e-12);
        CHECK_ABS(acc(&wf_cf_idm, &p, huge, v0, v0), 0.0, 1e-12 * a);
        p = idm_varied();
    }

    p = defaults(&wf_cf_ovm);
    for (int k = 0; k < 2; k++) {
        double alpha = get(&wf_cf_ovm, &p, "alpha_per_s"), vmax = get(&wf_cf_ovm, &p, "v_max_mps");
        for (double v = 0.0; v < 0.99 * vmax; v += 1.5)
            CHECK_REL(acc(&wf_cf_ovm, &p, huge, v, v), alpha * (vmax - v), 1e-12);
        p = ovm_varied();
    }

    p = defaults(&wf_cf_gipps);
    for (int k = 0; k < 2; k++) {
        double a = get(&wf_cf_gipps, &p, "a_mps2"), tau = get(&wf_cf_gipps, &p, "tau_s");
        double V = get(&wf_cf_gipps, &p, "v0_mps");
        /* v = 0: v_new = 2.5 a tau (1 - 0) sqrt(0.025), so a = 2.5 a tau sqrt(0.025) / tau. */
        CHECK_REL(acc(&wf_cf_gipps, &p, huge, 0.0, 0.0), 2.5 * a * tau * sqrt(0.025) / tau, 1e-12);
        CHECK_ABS(acc(&wf_cf_gipps, &p, huge, V, V), 0.0, 1e-12 * a);
        p = gipps_varied();
    }
}

/* ---------------------------------------------------------------- hand-computed values */

static void test_hand_idm(void)
{
    const WfCfModel *m = &wf_cf_idm;
    Params p = defaults(m); /* v0 30, T 1, s0 2, a 1, b 1.5, delta 4 */
    /* gap 20, v = v_lead = 15: s* = 2 + 15*1 = 17; (15/30)^4 = 0.0625; (17/20)^2 = 0.7225;
     * a = 1 * (1 - 0.0625 - 0.7225) = 0.215 */
    CHECK_REL(acc(m, &p, 20.0, 15.0, 15.0), 0.215, 1e-13);
    /* gap 10, v 10, v_lead 5: 2 sqrt(1 * 1.5) = 2.449489742783178; dyn = 10*1 + 10*5/2.449489742783178
     * = 10 + 20.41241452319315 = 30.41241452319315; s* = 32.41241452319315; (s* / 10)^2 = 10.505646152233023;
     * (10/30)^4 = 1/81 = 0.012345679012345679; a = 1 - 0.012345679012345679 - 10.505646152233023
     * = -9.517991831245369 */
    CHECK_REL(acc(m, &p, 10.0, 10.0, 5.0), -9.5179918312453685, 1e-13);
    /* gap 30, v 5, v_lead 30: dyn = 5 + 5*(-25)/2.449489742783178 = -46.03 < 0, so s* = s0 = 2;
     * (5/30)^4 = 1/1296; (2/30)^2 = 1/225; a = 1 - 1/1296 - 1/225 = 0.99478395061728395 */
    CHECK_REL(acc(m, &p, 30.0, 5.0, 30.0), 1.0 - 1.0 / 1296.0 - 1.0 / 225.0, 1e-14);
    /* gap 0 (floored to 1 mm), v = v_lead = 0: s* = 2; (2 / 0.001)^2 = 4e6; a = 1 - 0 - 4e6 = -3999999 */
    CHECK_REL(acc(m, &p, 0.0, 0.0, 0.0), -3999999.0, 1e-13);
}

static void test_hand_ovm(void)
{
    const WfCfModel *m = &wf_cf_ovm;
    Params p = defaults(m); /* alpha 0.5, beta 20, v_max 35/3.6 = 9.7222222222222222, d0 2.23 */
    /* tanh(2) = 0.96402758007581688; 1 + tanh(2) = 1.9640275800758169.
     * gap 4.46 = 2 d0, v 4, v_lead 6: V = 9.7222222222222222 * (tanh 0 + 0.96402758007581688) / 1.96402758...
     * = 4.7720767554019866; FTL = 20 * 2 / 4.46^2 = 40 / 19.8916 = 2.0108990729755274;
     * a = 0.5 * (4.7720767554019866 - 4) + 2.0108990729755274 = 0.38603837770099331 + 2.0108990729755274
     * = 2.3969374506765207 */
    CHECK_REL(acc(m, &p, 2.0 * 2.23, 4.0, 6.0), 2.3969374506765207, 1e-13);
    /* gap 6.69 = 3 d0, v 8, v_lead 5: tanh(1) = 0.76159415595576489;
     * V = 9.7222222222222222 * (0.76159415595576489 + 0.96402758007581688) / 1.9640275800758169
     * = 8.5420786140631997; FTL = 20 * (-3) / 6.69^2 = -60 / 44.7561 = -1.3405993819836849;
     * a = 0.5 * (8.5420786140631997 - 8) - 1.3405993819836849 = 0.27103930703159986 - 1.3405993819836849
     * = -1.0695600749520850 */
    CHECK_REL(acc(m, &p, 3.0 * 2.23, 8.0, 5.0), -1.0695600749520850, 1e-12);
    /* gap 0 (FTL sees the 1 mm floor), v 1, v_lead 0: V(0) = 0; a = 0.5 * (0 - 1) + 20 * (-1) / 1e-6
     * = -0.5 - 2e7 = -20000000.5 */
    CHECK_REL(acc(m, &p, 0.0, 1.0, 0.0), -20000000.5, 1e-13);
}

static void test_hand_gipps(void)
{
    const WfCfModel *m = &wf_cf_gipps;
    Params p = defaults(m); /* a 1.7, b 3, b_hat 3, V 30, tau 0.66, s0 2 */
    /* gap 22 (d = 20), v = v_lead = 10: u = 1/3; v_acc = 10 + 2.5*1.7*0.66 * (2/3) * sqrt(0.025 + 1/3)
     * = 10 + 2.805 * 0.66666666666666667 * 0.59860949986893236 = 11.119399764754904;
     * radicand = 9*0.4356 + 3*(40 - 6.6 + 100/3) = 3.9204 + 200.2 = 204.1204; v_brk = -1.98 + 14.287071078426117
     * = 12.307071078426117 > v_acc; a = (11.119399764754904 - 10) / 0.66 = 1.6960602496286417 */
    CHECK_REL(acc(m, &p, 22.0, 10.0, 10.0), 1.6960602496286417, 1e-12);
    /* gap 12 (d = 10), v 15, v_lead 5: radicand = 3.9204 + 3*(20 - 9.9 + 25/3) = 3.9204 + 55.3 = 59.2204;
     * v_brk = -1.98 + 7.6954791923570296 = 5.7154791923570296 (v_acc = 16.016 is larger);
     * a = (5.7154791923570296 - 15) / 0.66 = -14.067455769156016 */
    CHECK_REL(acc(m, &p, 12.0, 15.0, 5.0), -14.067455769156016, 1e-12);
    /* gap 1 (d = -1), v 5, v_lead 0: radicand = 3.9204 + 3*(-2 - 3.3 + 0) = -11.9796 < 0: emergency,
     * v_new = 0, a = -5 / 0.66 = -7.5757575757575758 */
    CHECK_REL(acc(m, &p, 1.0, 5.0, 0.0), -5.0 / 0.66, 1e-14);
    /* gap 2 (d = 0), v 1, v_lead 0: radicand = 3.9204 + 3*(0 - 0.66) = 1.9404 > 0 but
     * sqrt(1.9404) = 1.3929824119492680 < 1.98, so v_brk = -0.587 < 0 and v_new is clamped to 0: a = -1 / 0.66 */
    CHECK_REL(acc(m, &p, 2.0, 1.0, 0.0), -1.0 / 0.66, 1e-14);
}

/* Every model with a block kernel: the kernel's accelerations equal accel()'s bit for bit, with one shared
 * parameter set (stride 0, the vectorised loop), with per-vehicle sets (stride = param_size), and for a
 * non-default exponent; inputs span gaps from 0 (the floor) to 500 m and speeds from 0 to 45 m/s. */
static void test_block_kernels(void)
{
    enum { N = 4099 }; /* odd: the vector loop's remainder runs too */
    static double gap[N], v[N], vl[N], a[N], params[N * 16];
    uint64_t st = 0x9e3779b97f4a7c15ull;
    for (size_t k = 0; k < N; k++) {
        double u[3];
        for (int j = 0; j < 3; j++) {
            st = st * 6364136223846793005ull + 1442695040888963407ull;
            u[j] = (double)(st >> 11) * 0x1p-53;
        }
        gap[k] = k % 17 == 0 ? 0.0 : 500.0 * u[0] * u[0];
        v[k] = 45.0 * u[1];
        vl[k] = 45.0 * u[2];
    }
    int tested = 0;
    for (size_t mi = 0; wf_cf_models[mi]; mi++) {
        const WfCfModel *m = wf_cf_models[mi];
        if (!m->accel_block) continue;
        CHECK(m->state_size == 0, "%s: a block kernel on a model with memory", m->name);
        CHECK(m->param_size <= 16 * sizeof(double), "%s: parameter struct too large for the test", m->name);
        double base[16] = {0};
        wf_param_defaults(m->spec, m->n_spec, base);
        for (int variant = 0; variant < 3; variant++) {
            size_t stride = variant == 0 ? 0 : m->param_size;
            for (size_t k = 0; k < N; k++) {
                double *pk = params + k * (m->param_size / sizeof(double));
                memcpy(pk, base, m->param_size);
                /* per-vehicle sets (variant 1), or the exponent 3 everywhere (variant 2, shared) */
                for (size_t p = 0; variant == 1 && p < m->n_spec; p++)
                    *wf_param_ptr(pk, &m->spec[p]) *= 1.0 + 0.1 * sin((double)(k + p));
                const WfParamSpec *d = wf_param_find(m->spec, m->n_spec, "delta");
                if (variant == 2 && d) *wf_param_ptr(pk, d) = 3.0;
            }
            if (variant == 2) stride = 0;
            m->accel_block(params, stride, N, gap, v, vl, a);
            size_t diff = 0;
            for (size_t k = 0; k < N; k++) {
                double want = m->accel(params + (stride ? k * (m->param_size / sizeof(double)) : 0), NULL, gap[k], v[k], vl[k]);
                diff += memcmp(&want, &a[k], sizeof want) != 0;
            }
            CHECK(diff == 0, "%s, variant %d: %zu of %d accelerations differ from accel()", m->name, variant, diff, N);
        }
        tested++;
    }
    CHECK(tested >= 1, "no model has a block kernel");
}

int main(void)
{
    RUN(test_registry_find);
    RUN(test_spec_tables);
    RUN(test_gipps_check);
    RUN(test_sweep_idm);
    RUN(test_sweep_ovm);
    RUN(test_sweep_gipps);
    RUN(test_equilibrium_idm);
    RUN(test_equilibrium_ovm);
    RUN(test_equilibrium_gipps);
    RUN(test_free_road);
    RUN(test_hand_idm);
    RUN(test_hand_ovm);
    RUN(test_hand_gipps);
    RUN(test_block_kernels);
    TEST_EXIT();
}
