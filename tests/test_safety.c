/* Safety filters (src/models/safety/): the Gipps bound against Gipps's (1981) closed form re-derived here and against
 * the stopping condition it solves (distance to stop after one reaction step = gap - s0 + the leader's stopping
 * distance), the time-to-collision bound against its definition, monotonicity over a grid, the same bits for any
 * n, and the registry and parameter tables. Parameters are set through the spec tables only. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/safety.h"
#include "wf_test.h"

typedef struct Params {
    double v[WF_MAX_SAFETY_PARAMS];
} Params;

static const WfSafetyKind *kind(const char *name)
{
    const WfSafetyKind *k = NULL;
    WfError err = {0};
    CHECK(wf_safety_find(name, &k, &err) == 0, "%s: %s", name, err.msg);
    return k;
}

static Params with(const WfSafetyKind *k, const char *const *keys, const double *vals, size_t n)
{
    Params p;
    memset(&p, 0, sizeof p);
    wf_param_defaults(k->spec, k->n_spec, &p);
    for (size_t i = 0; i < n; i++) {
        const WfParamSpec *s = wf_param_find(k->spec, k->n_spec, keys[i]);
        CHECK(s != NULL, "%s has no key %s", k->name, keys[i]);
        if (s) *wf_param_ptr(&p, s) = vals[i];
    }
    return p;
}

static double bound1(const WfSafetyKind *k, const Params *p, double dt, double gap, double v, double vl)
{
    double a;
    k->bound(p, dt, 1, &gap, &v, &vl, &a);
    return a;
}

static void test_registry(void)
{
    size_t n = 0;
    for (; wf_safety_kinds[n]; n++) {
        const WfSafetyKind *k = wf_safety_kinds[n];
        CHECK(k->param_size <= WF_MAX_SAFETY_PARAMS * sizeof(double), "%s: %zu bytes", k->name, k->param_size);
        CHECK(k->n_spec * sizeof(double) == k->param_size, "%s: spec covers the struct", k->name);
        CHECK(kind(k->name) == k, "%s found by name", k->name);
        for (size_t i = 0; i < k->n_spec; i++)
            CHECK(k->spec[i].def >= k->spec[i].min && k->spec[i].def <= k->spec[i].max, "%s.%s default in range",
                  k->name, k->spec[i].key);
    }
    CHECK(n >= 1, "at least one kind");
    const WfSafetyKind *k = NULL;
    WfError err = {0};
    CHECK(wf_safety_find("gips", &k, &err) == WF_EINPUT, "unknown kind refused");
    CHECK(strstr(err.msg, "gips") && strstr(err.msg, wf_safety_kinds[0]->name), "message names it and the known: %s",
          err.msg);
}

/* Gipps (1981) eq. 5 with decelerations as magnitudes, written here from the paper, for v_new >= 0. */
static double gipps_paper(double b, double bh, double tau, double d, double v, double vl)
{
    double rad = b * b * tau * tau + b * (2.0 * d - v * tau + vl * vl / bh);
    double vn = rad > 0.0 ? -b * tau + sqrt(rad) : 0.0;
    return vn > 0.0 ? vn : 0.0;
}

static void test_gipps_formula(void)
{
    const WfSafetyKind *k = kind("gipps");
    if (!k) return;
    static const char *const keys[] = {"decel_mps2", "leader_decel_mps2", "gap_min_m"};
    const double bs[] = {1.5, 3.0, 6.0}, bhs[] = {2.0, 3.0, 8.0}, s0s[] = {0.0, 1.0, 4.0}, dts[] = {0.05, 0.1, 0.5};
    size_t n = 0, stop_cases = 0, run_cases = 0;
    for (int ib = 0; ib < 3; ib++)
        for (int ih = 0; ih < 3; ih++)
            for (int is = 0; is < 3; is++) {
                double vals[] = {bs[ib], bhs[ih], s0s[is]};
                Params p = with(k, keys, vals, 3);
                for (int it = 0; it < 3; it++)
                    for (double gap = -2.0; gap <= 120.0; gap += 3.7)
                        for (double v = 0.0; v <= 35.0; v += 2.9)
                            for (double vl = 0.0; vl <= 35.0; vl += 4.3) {
                                double dt = dts[it], b = bs[ib], bh = bhs[ih], s0 = s0s[is];
                                double a = bound1(k, &p, dt, gap, v, vl), vn = v + a * dt;
                                double want = gipps_paper(b, bh, dt, gap - s0, v, vl);
                                CHECK_ABS(vn, want, 1e-11 * (1.0 + want));
                                if (want > 1e-6) {
                                    /* The stopping condition v_new solves (theta = tau/2): the distance covered
                                     * in the step, then tau/2 at v_new, then braking at b, equals the gap less
                                     * s0 plus the leader's braking distance at bh. */
                                    double need = 0.5 * (v + vn) * dt + 0.5 * vn * dt + vn * vn / (2.0 * b);
                                    double have = gap - s0 + vl * vl / (2.0 * bh);
                                    CHECK_ABS(need, have, 1e-9 * (1.0 + fabs(have)));
                                    run_cases++;
                                } else {
                                    CHECK_ABS(vn, 0.0, 1e-12 * (1.0 + v));
                                    stop_cases++;
                                }
                                n++;
                            }
            }
    CHECK(run_cases > 1000 && stop_cases > 100, "both branches covered (%zu running, %zu stopping of %zu)",
          run_cases, stop_cases, n);
}

/* Hand-computed: b = bh = 3, s0 = 1, tau = 1 s, gap 21 m, v = 10, vl = 0: rad = 9 + 3 (40 - 10) = 99,
 * v_new = -3 + sqrt(99) = 6.9498743710662 m/s, a = -3.0501256289338 m/s^2. */
static void test_gipps_hand(void)
{
    const WfSafetyKind *k = kind("gipps");
    if (!k) return;
    static const char *const keys[] = {"decel_mps2", "leader_decel_mps2", "gap_min_m"};
    double vals[] = {3.0, 3.0, 1.0};
    Params p = with(k, keys, vals, 3);
    CHECK_REL(bound1(k, &p, 1.0, 21.0, 10.0, 0.0), -13.0 + sqrt(99.0), 1e-14);
    CHECK_REL(-13.0 + sqrt(99.0), -3.0501256289338, 1e-12);
    /* Monotone: more gap or a faster leader never lowers the bound; a faster vehicle never raises its speed bound. */
    for (double gap = 0.0; gap < 80.0; gap += 0.5)
        for (double v = 0.0; v < 30.0; v += 1.5) {
            double a0 = bound1(k, &p, 0.1, gap, v, 5.0);
            CHECK(bound1(k, &p, 0.1, gap + 0.5, v, 5.0) >= a0, "gap monotone at %g %g", gap, v);
            CHECK(bound1(k, &p, 0.1, gap, v, 6.0) >= a0, "leader-speed monotone at %g %g", gap, v);
            CHECK(v + 1.5 + bound1(k, &p, 0.1, gap, v + 1.5, 5.0) * 0.1 <= v + a0 * 0.1 + 1e-12,
                  "safe speed non-increasing in own speed at %g %g", gap, v);
        }
}

static void test_ttc(void)
{
    const WfSafetyKind *k = kind("ttc");
    if (!k) return;
    static const char *const keys[] = {"ttc_s", "gap_min_m"};
    const double ts[] = {0.5, 2.0, 6.0}, s0s[] = {0.0, 2.0};
    for (int it = 0; it < 3; it++)
        for (int is = 0; is < 2; is++) {
            double vals[] = {ts[it], s0s[is]};
            Params p = with(k, keys, vals, 2);
            for (double gap = -1.0; gap <= 90.0; gap += 2.3)
                for (double v = 0.0; v <= 35.0; v += 3.1)
                    for (double vl = 0.0; vl <= 35.0; vl += 3.7) {
                        double dt = 0.1, vn = v + bound1(k, &p, dt, gap, v, vl) * dt, d = gap - s0s[is];
                        if (vn > 1e-9 && vn > vl + 1e-9) {
                            /* closing: the time to collision at the new speed is T */
                            CHECK_REL(d / (vn - vl), ts[it], 1e-9);
                        } else if (vn > 1e-9) {
                            /* not closing: only at a gap at or below s0, where the bound opens it at d / T */
                            CHECK(d <= 1e-9, "not closing with d = %g", d);
                            CHECK_ABS(vn, vl + d / ts[it], 1e-9);
                        } else {
                            CHECK(vl + d / ts[it] <= 1e-9, "stop only when v_lead + d / T <= 0");
                        }
                    }
        }
}

/* The bound's arithmetic does not depend on n (the engine calls it per block of any length). */
static void test_block_form(void)
{
    enum { N = 300 };
    double gap[N], v[N], vl[N], a[N];
    for (int i = 0; i < N; i++) {
        gap[i] = -1.0 + 0.37 * i, v[i] = fmod(0.71 * i, 33.0), vl[i] = fmod(1.13 * i, 31.0);
    }
    for (size_t j = 0; wf_safety_kinds[j]; j++) {
        const WfSafetyKind *k = wf_safety_kinds[j];
        Params p = with(k, NULL, NULL, 0);
        k->bound(&p, 0.1, N, gap, v, vl, a);
        int same = 1;
        for (int i = 0; i < N; i++) {
            double a1 = bound1(k, &p, 0.1, gap[i], v[i], vl[i]);
            same &= memcmp(&a1, &a[i], sizeof a1) == 0 && isfinite(a1);
        }
        CHECK(same, "%s: block and one-by-one bounds bit-identical and finite", k->name);
    }
}

int main(void)
{
    RUN(test_registry);
    RUN(test_gipps_formula);
    RUN(test_gipps_hand);
    RUN(test_ttc);
    RUN(test_block_form);
    TEST_EXIT();
}
