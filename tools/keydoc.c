/* keydoc: prints the generated tables of the docs from the library's own tables (tools/gen-key-docs.sh).
 *   keydoc keys SECTION ring|corridor   a scenario section's key table (include/wavefuel/keys.h)
 *   keydoc params MODEL                 a car-following model's parameter table (WfParamSpec)
 *   keydoc safety KIND                  a safety filter's parameter table (WfParamSpec)
 *   keydoc lanechange MODEL             a lane-change model's parameter table (WfParamSpec)
 *   keydoc integrators                  the integrator registry
 *   keydoc list                         every table the docs must hold: "keys SECTION BOUNDARY", "params MODEL",
 *                                       "safety KIND", "lanechange MODEL", "integrators", one a line
 * Exit status 2 for an unknown section or model. The rows come from the tables the loader reads (keys.h, param.h,
 * integrator.h); the doc text of a row is its doc_* fields, or derived from its type, unit, default and range. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wavefuel/integrator.h"
#include "wavefuel/keys.h"
#include "wavefuel/lanechange.h"
#include "wavefuel/param.h"
#include "wavefuel/safety.h"

/* A number as the docs write it: %g without exponent padding ("1e-6", "1e10"), a typographic minus. */
static const char *num(double v, char *buf, size_t len)
{
    char t[64];
    snprintf(t, sizeof t, "%g", fabs(v));
    char *e = strchr(t, 'e');
    if (e) {
        char *d = e + 1, *src = e + 1;
        int neg = *src == '-';
        src += *src == '-' || *src == '+';
        while (*src == '0' && src[1]) src++;
        if (neg) *d++ = '-';
        memmove(d, src, strlen(src) + 1);
    }
    snprintf(buf, len, "%s%s", v < 0 ? "−" : "", t);
    return buf;
}

/* The symbol of a dynamic bound. */
static const char *bound_name(WfKeyBound b, double fixed, char *buf, size_t len)
{
    static const char *const names[] = {NULL, "L", "−L", "duration", "N", "N − 1"};
    return b == WF_BOUND_FIXED ? num(fixed, buf, len) : names[b];
}

/* "m/s^2" -> "m/s²", "m2/s" -> "m²/s". */
static const char *pretty_unit(const char *u, char *buf, size_t len)
{
    size_t o = 0;
    for (const char *p = u; *p && o + 3 < len; p++) {
        int squared = (p[0] == '^' && p[1] == '2') || (p[0] == '2' && p > u && p[-1] == 'm');
        if (!squared) {
            buf[o++] = *p;
            continue;
        }
        memcpy(buf + o, "²", 2);
        o += 2;
        p += *p == '^';
    }
    buf[o] = '\0';
    return buf;
}

static void choices_text(const char *const *c, char *buf, size_t len)
{
    size_t o = 0;
    buf[0] = '\0';
    for (int i = 0; c[i]; i++) {
        int w = snprintf(buf + o, len - o, "%s`%s`", i ? ", " : "", c[i]);
        if (w > 0 && (size_t)w < len - o) o += (size_t)w;
    }
}

static void type_text(const WfKeySpec *r, char *buf, size_t len)
{
    if (r->doc_type) snprintf(buf, len, "%s", r->doc_type);
    else if (r->choices) choices_text(r->choices, buf, len);
    else if (r->type == WF_KEY_NUMBER) pretty_unit(r->unit, buf, len);
    else if (r->type == WF_KEY_INTEGER) snprintf(buf, len, "integer");
    else if (r->type == WF_KEY_BOOL) snprintf(buf, len, "bool");
    else if (r->type == WF_KEY_TEXT) snprintf(buf, len, "text");
    else if (r->type == WF_KEY_SECTION) snprintf(buf, len, "map");
    else buf[0] = '\0';
}

static void default_text(const WfKeySpec *r, char *buf, size_t len)
{
    if (r->doc_default) snprintf(buf, len, "%s", r->doc_default);
    else if (r->flags & WF_KEY_REQUIRED) snprintf(buf, len, "required");
    else if (r->type == WF_KEY_NUMBER && isinf(r->def)) snprintf(buf, len, "none");
    else if (r->type == WF_KEY_NUMBER || r->type == WF_KEY_INTEGER) num(r->def, buf, len);
    else if (r->type == WF_KEY_BOOL) snprintf(buf, len, "%s", r->def != 0 ? "true" : "false");
    else if (r->choices) snprintf(buf, len, "`%s`", r->choices[(int)r->def]);
    else buf[0] = '\0';
}

static void range_text(const WfKeySpec *r, char *buf, size_t len)
{
    char a[64], b[64];
    if (r->doc_range) {
        snprintf(buf, len, "%s", r->doc_range);
    } else if (r->type == WF_KEY_NUMBER) {
        snprintf(buf, len, "[%s, %s]", bound_name(r->min_is, r->min, a, sizeof a),
                 bound_name(r->max_is, r->max, b, sizeof b));
    } else if (r->type == WF_KEY_INTEGER) {
        snprintf(buf, len, "[%s, %s]", bound_name(r->min_is, (double)r->imin, a, sizeof a),
                 bound_name(r->max_is, (double)r->imax, b, sizeof b));
    } else {
        buf[0] = '\0';
    }
}

static void rows(FILE *out, const WfKeyTable *t, int on, const char *prefix)
{
    for (size_t i = 0; i < t->n; i++) {
        const WfKeySpec *r = &t->keys[i];
        if (!(r->on & on) || (r->flags & WF_KEY_NODOC)) continue;
        char key[200], ty[400], def[200], range[200];
        snprintf(key, sizeof key, "%s%s", prefix, r->key);
        if (r->flags & WF_KEY_FLAT) {
            char sub[210];
            snprintf(sub, sizeof sub, "%s.", key);
            rows(out, r->sub, on, sub);
            continue;
        }
        type_text(r, ty, sizeof ty);
        default_text(r, def, sizeof def);
        range_text(r, range, sizeof range);
        const char *cell[4] = {ty, def, range, r->doc ? r->doc : ""};
        fprintf(out, "| `%s` |", key);
        for (int c = 0; c < 4; c++) fprintf(out, cell[c][0] ? " %s |" : " |", cell[c]);
        fputc('\n', out);
    }
}

static int keys_markdown(FILE *out, const WfKeyTable *t, int on)
{
    fprintf(out, "| key | type, unit | default | range | meaning |\n|---|---|---|---|---|\n");
    rows(out, t, on, "");
    return ferror(out) ? WF_ESYS : 0;
}

static int param_markdown(FILE *out, const WfParamSpec *spec, size_t n)
{
    fprintf(out, "| key | unit | default | range | meaning |\n|---|---|---|---|---|\n");
    for (size_t i = 0; i < n; i++) {
        const WfParamSpec *s = &spec[i];
        char u[64], d[64], lo[64], hi[64];
        const char *def = (s->flags & WF_PARAM_REQUIRED) ? "required"
                          : (s->flags & WF_PARAM_OPTIONAL) ? "none" : num(s->def, d, sizeof d);
        fprintf(out, "| `%s` | %s | %s | [%s, %s] | %s |\n", s->key, pretty_unit(s->unit, u, sizeof u), def,
                num(s->min, lo, sizeof lo), num(s->max, hi, sizeof hi), s->doc ? s->doc : "");
    }
    return ferror(out) ? WF_ESYS : 0;
}

/* Whether a table has a doc row whose boundary set is exactly `on`, or includes it (exact = 0). */
static int has_rows(const WfKeyTable *t, int on, int exact)
{
    for (size_t i = 0; i < t->n; i++)
        if (!(t->keys[i].flags & WF_KEY_NODOC) && (exact ? t->keys[i].on == on : (t->keys[i].on & on) != 0)) return 1;
    return 0;
}

static int list(void)
{
    /* A section is shown for rings when it has ring keys, and for corridors when it has keys of corridors only
     * (sections whose keys all apply to both are described once, in docs/scenarios.md). */
    for (size_t i = 0; wf_key_tables[i]; i++) {
        if (has_rows(wf_key_tables[i], WF_ON_RING, 0)) printf("keys %s ring\n", wf_key_tables[i]->name);
        if (has_rows(wf_key_tables[i], WF_ON_CORRIDOR, 1)) printf("keys %s corridor\n", wf_key_tables[i]->name);
    }
    for (size_t i = 0; wf_cf_models[i]; i++) printf("params %s\n", wf_cf_models[i]->name);
    for (size_t i = 0; wf_safety_kinds[i]; i++) printf("safety %s\n", wf_safety_kinds[i]->name);
    for (size_t i = 0; wf_lc_models[i]; i++) printf("lanechange %s\n", wf_lc_models[i]->name);
    printf("integrators\n");
    return 0;
}

static int integrators(void)
{
    printf("| name | kind | method |\n|---|---|---|\n");
    for (size_t i = 0; wf_integrators[i]; i++)
        printf("| `%s` | %s | %s |\n", wf_integrators[i]->name, wf_integ_kind_name(wf_integrators[i]->kind),
               wf_integrators[i]->doc);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && !strcmp(argv[1], "list")) return list();
    if (argc == 2 && !strcmp(argv[1], "integrators")) return integrators();
    if (argc == 3 && !strcmp(argv[1], "params")) {
        const WfCfModel *m = NULL;
        WfError err = {0};
        if (wf_cf_model_find(argv[2], &m, &err)) {
            fprintf(stderr, "keydoc: %s\n", err.msg);
            return 2;
        }
        return param_markdown(stdout, m->spec, m->n_spec) ? 1 : 0;
    }
    if (argc == 3 && !strcmp(argv[1], "safety")) {
        const WfSafetyKind *k = NULL;
        WfError err = {0};
        if (wf_safety_find(argv[2], &k, &err)) {
            fprintf(stderr, "keydoc: %s\n", err.msg);
            return 2;
        }
        return param_markdown(stdout, k->spec, k->n_spec) ? 1 : 0;
    }
    if (argc == 3 && !strcmp(argv[1], "lanechange")) {
        const WfLaneChangeModel *m = NULL;
        WfError err = {0};
        if (wf_lc_model_find(argv[2], &m, &err)) {
            fprintf(stderr, "keydoc: %s\n", err.msg);
            return 2;
        }
        return param_markdown(stdout, m->spec, m->n_spec) ? 1 : 0;
    }
    if (argc == 4 && !strcmp(argv[1], "keys")) {
        const WfKeyTable *t = wf_key_table_find(argv[2]);
        int on = !strcmp(argv[3], "ring") ? WF_ON_RING : !strcmp(argv[3], "corridor") ? WF_ON_CORRIDOR : 0;
        if (!t || !on) {
            fprintf(stderr, "keydoc: unknown section '%s' or boundary '%s'\n", argv[2], argv[3]);
            return 2;
        }
        return keys_markdown(stdout, t, on) ? 1 : 0;
    }
    fprintf(stderr, "usage: keydoc keys SECTION ring|corridor | params MODEL | safety KIND | lanechange MODEL | integrators | list\n");
    return 2;
}
