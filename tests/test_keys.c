/* The scenario key tables (include/wavefuel/keys.h) drive the loader: for every typed row of every table (the rows
 * come from wf_key_tables, never from a list here), a bad value set at the row's path must be rejected with the
 * message the row's type and range imply, worded here independently of the loader; a key of the other boundary must
 * be rejected with its row's message; the integrator registry's names must all load, and an unknown one must list
 * them all. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wf_test.h"
#include "wavefuel/corridor.h"
#include "wavefuel/integrator.h"
#include "wavefuel/keys.h"
#include "wavefuel/scenario.h"
#include "util/numfmt.h"

static const char ring_yaml[] = "road: {length_m: 1000}\n"
                                "time: {duration_s: 10}\n"
                                "fleet:\n"
                                "  vehicles: 10\n"
                                "  classes: [{class: midsize_sedan, fraction: 1}]\n"
                                "  drivers: [{model: idm, fraction: 1}]\n";
static const double ring_L = 1000, ring_duration = 10, ring_n = 10;

static const char corridor_yaml[] = "road:\n"
                                    "  type: corridor\n"
                                    "  length_m: 2000\n"
                                    "  zones: [{type: speed_limit, from_m: 100, to_m: 200, speed_limit_mps: 8}]\n"
                                    "time: {duration_s: 60}\n"
                                    "fleet:\n"
                                    "  classes: [{class: midsize_sedan, fraction: 1}]\n"
                                    "  drivers: [{model: idm, fraction: 1}]\n"
                                    "corridor:\n"
                                    "  inflow: {flow_vph: 1000}\n"
                                    "  detectors: {x_m: [500]}\n";
static const double corridor_L = 2000, corridor_duration = 60, corridor_n = WF_CORRIDOR_SHARE_BASE;

static int load(int corridor, const char *const *set, size_t n_set, WfError *err)
{
    WfScenario *sc = NULL;
    memset(err, 0, sizeof *err);
    int rc = wf_scenario_load_text("keys.yaml", corridor ? corridor_yaml : ring_yaml, set, n_set, &sc, err);
    wf_scenario_destroy(&sc);
    return rc;
}

static double bound_value(WfKeyBound b, double fixed, int corridor)
{
    double L = corridor ? corridor_L : ring_L, n = corridor ? corridor_n : ring_n;
    switch (b) {
    case WF_BOUND_LENGTH: return L;
    case WF_BOUND_NEG_LENGTH: return -L;
    case WF_BOUND_DURATION: return corridor ? corridor_duration : ring_duration;
    case WF_BOUND_VEHICLES: return n;
    case WF_BOUND_LAST_VEHICLE: return n - 1;
    default: return fixed;
    }
}

/* What the message must say after "PATH: expected ". */
static void expected_text(const WfKeySpec *r, int corridor, char *buf, size_t len)
{
    if (r->type == WF_KEY_NUMBER) {
        /* Bounds in the shortest form that reads back as the bound (src/util/numfmt.c, tests/t_numfmt.sh). */
        snprintf(buf, len, "a number in [%s, %s] %s", WF_NUM(bound_value(r->min_is, r->min, corridor)),
                 WF_NUM(bound_value(r->max_is, r->max, corridor)), r->unit);
    } else if (r->type == WF_KEY_INTEGER) {
        long lo = r->min_is ? (long)bound_value(r->min_is, 0, corridor) : r->imin;
        long hi = r->max_is ? (long)bound_value(r->max_is, 0, corridor) : r->imax;
        snprintf(buf, len, "an integer in [%ld, %ld]", lo, hi);
    } else if (r->type == WF_KEY_BOOL) {
        snprintf(buf, len, "true or false");
    } else {
        size_t o = (size_t)snprintf(buf, len, "one of");
        for (int i = 0; r->choices[i] && o < len; i++) o += (size_t)snprintf(buf + o, len - o, "%s %s", i ? "," : "", r->choices[i]);
    }
}

static int n_checked;

/* One bad value at the row's path; `extra` sets what the section needs first (an adaptive integrator for solver;
 * several settings separated by ';'). */
static void reject(const char *path, const WfKeySpec *r, const char *value, int corridor, const char *extra)
{
    char set[256], want[600], what[400], pre[256] = "";
    snprintf(set, sizeof set, "%s=%s", path, value);
    const char *sets[4];
    size_t n = 0;
    if (extra) {
        snprintf(pre, sizeof pre, "%s", extra);
        for (char *tok = strtok(pre, ";"); tok && n < 3; tok = strtok(NULL, ";")) sets[n++] = tok;
    }
    sets[n++] = set;
    expected_text(r, corridor, what, sizeof what);
    snprintf(want, sizeof want, "%s: expected %s (got '%s')", path, what, value);
    WfError err;
    int rc = load(corridor, sets, n, &err);
    CHECK(rc == WF_EINPUT && strstr(err.msg, want), "--set %s (%s): rc %d, message '%s', want '%s'", set,
          corridor ? "corridor" : "ring", rc, err.msg, want);
    n_checked++;
}

static void check_table(const WfKeyTable *t, const char *prefix, const char *extra)
{
    for (size_t i = 0; i < t->n; i++) {
        const WfKeySpec *r = &t->keys[i];
        char path[256];
        snprintf(path, sizeof path, "%s%s", prefix, r->key);
        if (r->type == WF_KEY_SECTION) {
            char sub[260];
            snprintf(sub, sizeof sub, "%s.", path);
            check_table(r->sub, sub,
                        !strcmp(path, "corridor.on_ramp")    ? "corridor.on_ramp.start_m=100"
                        : !strcmp(path, "corridor.off_ramp") ? "corridor.off_ramp.at_m=100;corridor.off_ramp.share=0.5"
                                                             : extra);
            continue;
        }
        if ((r->flags & WF_KEY_NOREAD) || r->type == WF_KEY_CUSTOM || r->type == WF_KEY_TEXT) continue;
        int corridor = !(r->on & WF_ON_RING);
        reject(path, r, "abc", corridor, extra);
        char v[64];
        if (r->type == WF_KEY_NUMBER) {
            double hi = bound_value(r->max_is, r->max, corridor);
            snprintf(v, sizeof v, "%.17g", hi + (hi > 0 ? hi : 1));
            reject(path, r, v, corridor, extra);
        } else if (r->type == WF_KEY_INTEGER) {
            long hi = r->max_is ? (long)bound_value(r->max_is, 0, corridor) : r->imax;
            if (hi < LONG_MAX) snprintf(v, sizeof v, "%ld", hi + 1);
            else snprintf(v, sizeof v, "%ld", r->imin - 1);
            reject(path, r, v, corridor, extra);
        }
    }
}

static void test_every_typed_key_checked(void)
{
    n_checked = 0;
    for (size_t i = 0; wf_key_tables[i]; i++) {
        const WfKeyTable *t = wf_key_tables[i];
        char prefix[128] = "";
        if (strcmp(t->name, "top")) {
            /* "fleet.drivers[i]" -> "fleet.drivers[0]." */
            size_t o = 0;
            for (const char *p = t->name; *p && o + 3 < sizeof prefix; p++) prefix[o++] = *p == 'i' && p > t->name && p[-1] == '[' ? '0' : *p;
            prefix[o++] = '.', prefix[o] = '\0';
        }
        /* a section whose keys need a sibling first: the solver an adaptive integrator, an on-ramp its start */
        const char *extra = !strcmp(t->name, "solver") ? "time.integrator=cvode" : NULL;
        check_table(t, prefix, extra);
    }
    CHECK(n_checked > 0, "no typed key found in the tables");
    printf("  %d bad values rejected with the message of their row\n", n_checked);
}

/* Keys that apply to one boundary only and carry their own message are rejected on the other one. */
static void off_boundary(const WfKeyTable *t, const char *prefix, int *n)
{
    for (size_t i = 0; i < t->n; i++) {
        const WfKeySpec *r = &t->keys[i];
        if (!r->off_msg) continue;
        char set[256];
        int corridor = r->on == WF_ON_RING;
        /* A section is present with any key of its table; a plain key with any value. */
        snprintf(set, sizeof set, "%s%s%s%s=1", prefix, r->key, r->sub ? "." : "", r->sub ? r->sub->keys[0].key : "");
        const char *sets[1] = {set};
        WfError err;
        int rc = load(corridor, sets, 1, &err);
        CHECK(rc == WF_EINPUT && strstr(err.msg, r->off_msg), "--set %s: rc %d, message '%s', want '%s'", set, rc,
              err.msg, r->off_msg);
        ++*n;
    }
}

static void test_other_boundary_rejected(void)
{
    int n = 0;
    for (size_t i = 0; wf_key_tables[i]; i++) {
        char prefix[128] = "";
        if (strcmp(wf_key_tables[i]->name, "top")) snprintf(prefix, sizeof prefix, "%s.", wf_key_tables[i]->name);
        if (!strchr(prefix, '[')) off_boundary(wf_key_tables[i], prefix, &n);
    }
    CHECK(n > 0, "no key with a boundary message");
}

static void test_integrator_registry(void)
{
    char known[512] = "";
    for (size_t i = 0; wf_integrators[i]; i++) {
        char set[64];
        snprintf(set, sizeof set, "time.integrator=%s", wf_integrators[i]->name);
        const char *sets[1] = {set};
        WfScenario *sc = NULL;
        WfError err = {0};
        int rc = wf_scenario_load_text("keys.yaml", ring_yaml, sets, 1, &sc, &err);
        CHECK(rc == 0, "%s: %s", set, err.msg);
        if (rc == 0) {
            CHECK(!strcmp(sc->integrator, wf_integrators[i]->name), "integrator %s", sc->integrator);
            CHECK(sc->adaptive == (wf_integrators[i]->kind == WF_INTEG_ADAPTIVE), "%s: adaptive %d", set, sc->adaptive);
            CHECK(!sc->adaptive || (int)sc->solver.kind == wf_integrators[i]->ode_kind, "%s: solver kind %d", set,
                  sc->solver.kind);
            CHECK((wf_integrators[i]->step != NULL) == !sc->adaptive, "%s: a fixed-step entry steps", set);
        }
        wf_scenario_destroy(&sc);
        snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", i ? ", " : "", wf_integrators[i]->name);
    }
    const char *bad[1] = {"time.integrator=rk45"};
    WfError err;
    char want[600];
    snprintf(want, sizeof want, "unknown integrator 'rk45' (known: %s)", known);
    CHECK(load(0, bad, 1, &err) == WF_EINPUT && strstr(err.msg, want), "got '%s', want '%s'", err.msg, want);
}

int main(void)
{
    RUN(test_every_typed_key_checked);
    RUN(test_other_boundary_rejected);
    RUN(test_integrator_registry);
    return wf_test_fail_total_ ? 1 : 0;
}
