/* Sweep files -> lists of runs (docs/sweeps.md): a base scenario, common overrides, and axes whose Cartesian
 * product (seeds innermost) gives the runs, or an explicit list of runs. Each run is the base scenario's text with
 * `--set` assignments; wf_sweep_run() executes one and records its outcome, never stopping the sweep. */
#include "wavefuel/sweep.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "util/clock.h"
#include "util/hash.h"
#include "util/numfmt.h"
#include "util/outpath.h"
#include "util/path.h"
#include "wavefuel/config.h"
#include "wavefuel/engine.h"
#include "wavefuel/h5out.h"
#include "wavefuel/scenario.h"
#include "util/mem.h"

const char *const wf_run_status_names[3] = {"pending", "ok", "failed"};


/* ---- String storage: every string of a sweep lives until wf_sweep_destroy ---- */
struct WfSweepPool {
    void  **ptr;
    size_t  n, cap;
};

static void *pool_keep(struct WfSweepPool *p, void *mem)
{
    if (!mem) return NULL;
    if (p->n == p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 64;
        void **q = realloc(p->ptr, cap * sizeof *q);
        if (!q) {
            free(mem);
            return NULL;
        }
        p->ptr = q, p->cap = cap;
    }
    return p->ptr[p->n++] = mem;
}

static char *pool_strdup(struct WfSweepPool *p, const char *s) { return pool_keep(p, strdup(s)); }
static void *pool_calloc(struct WfSweepPool *p, size_t n, size_t size) { return pool_keep(p, calloc(n ? n : 1, size)); }

static void pool_free(struct WfSweepPool **pp)
{
    struct WfSweepPool *p = *pp;
    if (!p) return;
    for (size_t i = 0; i < p->n; i++) free(p->ptr[i]);
    free(p->ptr);
    free(p);
    *pp = NULL;
}

void wf_sweep_destroy(WfSweep **psw)
{
    if (!psw || !*psw) return;
    WfSweep *sw = *psw;
    pool_free(&sw->pool);
    WF_FREE(sw->text, sw->scenario_text, sw->runs, sw);
    *psw = NULL;
}

/* ---- Parsing ---- */

/* One point of an axis: its label (the table's value) and the assignments it makes. */
typedef struct Point {
    const char  *label;
    const char **set;
    size_t       n_set;
} Point;

typedef struct AxisDef {
    Point *pt;
    size_t n;
} AxisDef;

/* A growable list of assignments; its arrays live in the pool (outgrown ones too, until the sweep is destroyed). */
typedef struct SetList {
    const char **s;
    size_t       n, cap;
} SetList;

static int setlist_add(SetList *l, struct WfSweepPool *pool, const char *key, const char *value, WfError *err)
{
    size_t len = strlen(key) + strlen(value) + 2;
    char *a = pool_keep(pool, malloc(len));
    if (!a) return wf_err(err, WF_ESYS, "out of memory");
    snprintf(a, len, "%s=%s", key, value);
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 8;
        const char **q = pool_calloc(pool, cap, sizeof *q);
        if (!q) return wf_err(err, WF_ESYS, "out of memory");
        if (l->n) memcpy(q, l->s, l->n * sizeof *q);
        l->s = q, l->cap = cap;
    }
    l->s[l->n++] = a;
    return 0;
}

static const char *where(const WfCfgNode *n, char *buf, size_t len)
{
    char w[600], p[400];
    snprintf(buf, len, "%s: %s", wf_cfg_where(n, w, sizeof w), wf_cfg_path(n, p, sizeof p));
    return buf;
}

/* A key or value of an override: an override is one line "key=value", so neither may hold a newline, and the key
 * no '=' (the first '=' separates them). */
static int check_text(const WfCfgNode *n, const char *s, int is_key, WfError *err)
{
    char w[1100];
    if (!s[0] && is_key) return wf_err(err, WF_EINPUT, "%s: empty key", where(n, w, sizeof w));
    if (strchr(s, '\n') || (is_key && strchr(s, '=')))
        return wf_err(err, WF_EINPUT, "%s: '%s': a %s of an override may not contain %s", where(n, w, sizeof w), s,
                      is_key ? "key" : "value", is_key ? "'=' or a newline" : "a newline");
    return 0;
}

static int scalar_of(WfCfgNode *n, const char *what, const char **out, WfError *err)
{
    char w[1100];
    n->used = 1;
    if (n->kind != WF_CFG_SCALAR)
        return wf_err(err, WF_EINPUT, "%s: expected %s (a single value, got a map or list)", where(n, w, sizeof w),
                      what);
    *out = n->value;
    return check_text(n, n->value, 0, err);
}

/* A map of overrides, nested maps flattened into dotted keys: {time: {dt_s: 0.05}} = {time.dt_s: 0.05}. */
static int flatten(WfCfgNode *map, const char *prefix, SetList *l, struct WfSweepPool *pool, WfError *err)
{
    map->used = 1;
    for (size_t i = 0; i < map->n_child; i++) {
        WfCfgNode *c = map->child[i];
        char key[512], w[1100];
        int n = snprintf(key, sizeof key, "%s%s%s", prefix, prefix[0] ? "." : "", c->key);
        if (n < 0 || (size_t)n >= sizeof key) return wf_err(err, WF_EINPUT, "%s: key too long", where(c, w, sizeof w));
        if (check_text(c, c->key, 1, err)) return WF_EINPUT;
        if (c->kind == WF_CFG_MAP) {
            if (flatten(c, key, l, pool, err)) return WF_EINPUT;
            continue;
        }
        const char *v = NULL;
        if (scalar_of(c, "a value (overrides replace single values; a list cannot be set)", &v, err) ||
            setlist_add(l, pool, key, v, err))
            return err->code;
    }
    return 0;
}

/* The unit implied by the suffix of a key (its first n characters; keys carry their unit: length_m, U_mps, T_s); "1"
 * when it names none. */
static const char *unit_of_key(const char *key, size_t n)
{
    static const struct { const char *suffix, *unit; } tab[] = {
        {"_per_s2", "1/s^2"}, {"_per_s", "1/s"}, {"_mps2", "m/s^2"}, {"_mps", "m/s"}, {"_gps", "g/s"},
        {"_rad", "rad"},      {"_kw", "kW"},     {"_m", "m"},         {"_s", "s"},     {"_g", "g"},
    };
    for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++) {
        size_t k = strlen(tab[i].suffix);
        if (n > k && strncmp(key + n - k, tab[i].suffix, k) == 0) return tab[i].unit;
    }
    return "1";
}

/* Range values: start + i*step, rounded to 12 significant digits so that 0.1 steps give 0.3, not
 * 0.30000000000000004 (the text is what the run's override carries). */
static int range_values(WfCfgNode *range, const char ***out, size_t *n_out, struct WfSweepPool *pool, WfError *err)
{
    double start, stop, step;
    char w[1100];
    if (wf_cfg_double(range, "start", -1e300, 1e300, "", &start, err) ||
        wf_cfg_double(range, "stop", -1e300, 1e300, "", &stop, err) ||
        wf_cfg_double(range, "step", -1e300, 1e300, "", &step, err))
        return WF_EINPUT;
    double span = (stop - start) / step;
    if (step == 0.0 || !(span >= -1e-9))
        return wf_err(err, WF_EINPUT, "%s: step %s cannot go from start %s to stop %s", where(range, w, sizeof w),
                      WF_NUM(step), WF_NUM(start), WF_NUM(stop));
    /* The 1e-9 keeps a stop that the steps reach up to rounding ((0.3 - 0) / 0.1 = 2.9999999999999996). */
    double count = floor(span + 1e-9) + 1.0;
    if (count > 100000)
        return wf_err(err, WF_EINPUT, "%s: %.0f values: more than 100000 (is the step right?)",
                      where(range, w, sizeof w), count);
    size_t n = (size_t)count;
    const char **v = pool_calloc(pool, n, sizeof *v);
    if (!v) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t i = 0; i < n; i++) {
        char buf[64];
        snprintf(buf, sizeof buf, "%.12g", start + (double)i * step);
        if (!(v[i] = pool_strdup(pool, buf))) return wf_err(err, WF_ESYS, "out of memory");
    }
    *out = v;
    *n_out = n;
    return 0;
}

/* An axis given by `points`: each a label (`value`) and a map of overrides (`set`); the keys of the first point
 * name the axis's keys. */
static int parse_points(WfCfgNode *points, WfSweepAxis *ax, AxisDef *def, struct WfSweepPool *pool, WfError *err)
{
    char w[1100];
    def->n = points->n_child;
    def->pt = pool_calloc(pool, def->n, sizeof *def->pt);
    if (!def->pt) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t j = 0; j < def->n; j++) {
        WfCfgNode *p = points->child[j], *set = NULL;
        const char *label = NULL;
        p->used = 1;
        if (p->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: a point is a map {value: ..., set: {key: value, ...}}",
                          where(p, w, sizeof w));
        if (wf_cfg_string(p, "value", &label, err) || check_text(wf_cfg_child(p, "value"), label, 0, err) ||
            wf_cfg_map_opt(p, "set", &set, err))
            return WF_EINPUT;
        if (!set) return wf_cfg_missing(p, "set", "a map of overrides", err);
        SetList l = {0};
        int rc = flatten(set, "", &l, pool, err);
        if (rc) return rc;
        /* Labels outlive the configuration tree: copy them. */
        if (!(label = pool_strdup(pool, label))) return wf_err(err, WF_ESYS, "out of memory");
        def->pt[j] = (Point){label, l.s, l.n};
        size_t used = strlen(ax->keys);
        for (size_t k = 0; k < l.n && j == 0; k++) {
            const char *a = l.s[k];
            int n = snprintf(ax->keys + used, sizeof ax->keys - used, "%s%.*s", used ? "," : "",
                             (int)(strchr(a, '=') - a), a);
            if (n > 0 && (size_t)n < sizeof ax->keys - used) used += (size_t)n;
        }
    }
    return 0;
}

/* An axis given by `key` and `values` or a `range`, with optional `with` keys set alongside (one value each). */
static int parse_values(const char *key, WfCfgNode *values, WfCfgNode *range, WfCfgNode *with, WfSweepAxis *ax,
                        AxisDef *def, struct WfSweepPool *pool, WfError *err)
{
    char w[1100];
    const char **v = NULL;
    size_t n = 0;
    if (range) {
        if (range_values(range, &v, &n, pool, err)) return WF_EINPUT;
    } else {
        n = values->n_child;
        v = pool_calloc(pool, n, sizeof *v);
        if (!v) return wf_err(err, WF_ESYS, "out of memory");
        for (size_t j = 0; j < n; j++) {
            if (scalar_of(values->child[j], "a value", &v[j], err)) return WF_EINPUT;
            if (!(v[j] = pool_strdup(pool, v[j]))) return wf_err(err, WF_ESYS, "out of memory");
        }
    }
    size_t n_with = with ? with->n_child : 0;
    if (with) with->used = 1;
    for (size_t k = 0; k < n_with; k++) {
        WfCfgNode *c = with->child[k];
        c->used = 1;
        if (check_text(c, c->key, 1, err)) return WF_EINPUT;
        if (c->kind != WF_CFG_SEQ || c->n_child != n)
            return wf_err(err, WF_EINPUT, "%s: expected a list of %zu values, one per value of %s",
                          where(c, w, sizeof w), n, key);
    }
    def->n = n;
    def->pt = pool_calloc(pool, n, sizeof *def->pt);
    if (!def->pt) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t j = 0; j < n; j++) {
        SetList l = {0};
        int rc = setlist_add(&l, pool, key, v[j], err);
        for (size_t k = 0; !rc && k < n_with; k++) {
            const char *wv = NULL;
            rc = scalar_of(with->child[k]->child[j], "a value", &wv, err) ||
                 setlist_add(&l, pool, with->child[k]->key, wv, err);
        }
        if (rc) return err->code;
        def->pt[j] = (Point){v[j], l.s, l.n};
    }
    size_t used = (size_t)snprintf(ax->keys, sizeof ax->keys, "%s", key);
    for (size_t k = 0; k < n_with && used < sizeof ax->keys; k++) {
        int m = snprintf(ax->keys + used, sizeof ax->keys - used, ",%s", with->child[k]->key);
        if (m > 0) used += (size_t)m;
    }
    return 0;
}

/* `key` + `values` | `range` [+ `with`], or `points`. Fills the axis definition and the table column. */
static int parse_axis(WfCfgNode *e, WfSweepAxis *ax, AxisDef *def, struct WfSweepPool *pool, WfError *err)
{
    char w[1100];
    e->used = 1;
    if (e->kind != WF_CFG_MAP)
        return wf_err(err, WF_EINPUT, "%s: an axis is a map (key + values, key + range, or points)",
                      where(e, w, sizeof w));
    const char *name = NULL, *key = NULL;
    WfCfgNode *values = NULL, *range = NULL, *with = NULL, *points = NULL;
    if (wf_cfg_string_opt(e, "name", &name, err) || wf_cfg_string_opt(e, "key", &key, err) ||
        wf_cfg_seq_opt(e, "values", &values, err) || wf_cfg_map_opt(e, "range", &range, err) ||
        wf_cfg_map_opt(e, "with", &with, err) || wf_cfg_seq_opt(e, "points", &points, err))
        return WF_EINPUT;
    /* A missing part is reported through wf_cfg_missing, which names a misspelled key next to it instead. */
    if (points && (key || values || range || with))
        return wf_err(err, WF_EINPUT, "%s: an axis given by `points` has no `key`, `values`, `range` or `with`",
                      where(e, w, sizeof w));
    if (!points && !key) return wf_cfg_missing(e, "key", "the scenario key the axis sets (or give `points`)", err);
    if (!points && !values && !range) return wf_cfg_missing(e, "values", "a list of values (or a `range`)", err);
    if (values && range)
        return wf_err(err, WF_EINPUT, "%s: give `values` or `range`, not both", where(e, w, sizeof w));
    if (key && check_text(wf_cfg_child(e, "key"), key, 1, err)) return WF_EINPUT;

    int rc = points ? parse_points(points, ax, def, pool, err)
                    : parse_values(key, values, range, with, ax, def, pool, err);
    if (rc) return rc;
    if (!name && points) return wf_cfg_missing(e, "name", "the column name of an axis given by points", err);
    if (!name) {
        /* The key's last component names the column: fleet.drivers[1].count -> count. */
        const char *dot = strrchr(key, '.');
        name = dot ? dot + 1 : key;
    }
    if (def->n == 0) return wf_err(err, WF_EINPUT, "%s: the axis has no values", where(e, w, sizeof w));
    if (strlen(name) >= sizeof ax->name || strchr(name, '/') || !name[0])
        return wf_err(err, WF_EINPUT, "%s: axis name '%s': 1 to %zu characters, no '/'", where(e, w, sizeof w), name,
                      sizeof ax->name - 1);
    snprintf(ax->name, sizeof ax->name, "%s", name);
    ax->n_values = def->n;
    double x;
    ax->numeric = 1;
    for (size_t j = 0; j < def->n; j++) ax->numeric &= !wf_parse_double(def->pt[j].label, &x);
    /* The first key's unit. */
    snprintf(ax->units, sizeof ax->units, "%s", ax->numeric ? unit_of_key(ax->keys, strcspn(ax->keys, ",")) : "");
    return 0;
}

/* seeds: N (seeds 1..N) or a list of seeds. n_seeds = 0: the scenario's own seed. */
static int parse_seeds(WfCfgNode *root, int64_t **out, size_t *n_out, struct WfSweepPool *pool, WfError *err)
{
    WfCfgNode *c = wf_cfg_child(root, "seeds"), *seq = NULL;
    long n = 0;
    *n_out = 0;
    if (c && c->kind == WF_CFG_SEQ) {
        if (wf_cfg_seq_opt(root, "seeds", &seq, err)) return WF_EINPUT;
        if (!seq->n_child) return wf_err(err, WF_EINPUT, "%s:%d: seeds: an empty list", seq->file, seq->line);
        n = (long)seq->n_child;
    } else if (wf_cfg_long_opt(root, "seeds", 1, 1000000, &n, err)) {
        return WF_EINPUT;
    }
    if (!n) return 0;
    int64_t *s = pool_calloc(pool, (size_t)n, sizeof *s);
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    for (long i = 0; i < n; i++) {
        long v = i + 1;
        WfCfgNode *it = seq ? seq->child[i] : NULL;
        char w[1100];
        if (it) it->used = 1;
        if (it && (it->kind != WF_CFG_SCALAR || wf_parse_long(it->value, 0, 2147483647L, &v)))
            return wf_err(err, WF_EINPUT, "%s: expected a seed, an integer in [0, 2147483647] (got '%s')",
                          where(it, w, sizeof w), it->kind == WF_CFG_SCALAR ? it->value : "a map or list");
        s[i] = v;
    }
    *out = s;
    *n_out = (size_t)n;
    return 0;
}

/* Explicit runs: each a map of overrides; the table gets one column per distinct key, named by the key. */
static int parse_runs(WfSweep *sw, WfCfgNode *runs, SetList **lists_out, WfError *err)
{
    char w[1100];
    size_t n = runs->n_child;
    SetList *lists = pool_calloc(sw->pool, n, sizeof *lists);
    if (!lists) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t i = 0; i < n; i++) {
        WfCfgNode *r = runs->child[i];
        if (r->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: a run is a map of overrides {key: value, ...}", where(r, w, sizeof w));
        if (flatten(r, "", &lists[i], sw->pool, err)) return err->code;
        for (size_t k = 0; k < lists[i].n; k++) {
            const char *a = lists[i].s[k];
            size_t klen = (size_t)(strchr(a, '=') - a), ax;
            for (ax = 0; ax < sw->n_axes; ax++)
                if (strlen(sw->axes[ax].keys) == klen && !strncmp(sw->axes[ax].keys, a, klen)) break;
            if (ax == sw->n_axes) {
                if (ax == WF_SWEEP_MAX_AXES)
                    return wf_err(err, WF_EINPUT, "%s: the runs set more than %d distinct keys", where(r, w, sizeof w),
                                  WF_SWEEP_MAX_AXES);
                if (klen >= sizeof sw->axes[ax].name)
                    return wf_err(err, WF_EINPUT, "%s: key '%.*s' longer than %zu characters (it names a column)",
                                  where(r, w, sizeof w), (int)klen, a, sizeof sw->axes[ax].name - 1);
                WfSweepAxis *x = &sw->axes[sw->n_axes++];
                snprintf(x->name, sizeof x->name, "%.*s", (int)klen, a);
                snprintf(x->keys, sizeof x->keys, "%.*s", (int)klen, a);
                x->numeric = 1;
            }
            double d;
            if (wf_parse_double(a + klen + 1, &d)) sw->axes[ax].numeric = 0;
            sw->axes[ax].n_values++;
        }
    }
    for (size_t ax = 0; ax < sw->n_axes; ax++)
        snprintf(sw->axes[ax].units, sizeof sw->axes[ax].units, "%s",
                 sw->axes[ax].numeric ? unit_of_key(sw->axes[ax].keys, strlen(sw->axes[ax].keys)) : "");
    *lists_out = lists;
    return 0;
}

/* Builds the runs: common overrides, then each axis's point (first axis outermost), then the seed. */
static int expand(WfSweep *sw, const SetList *common, const AxisDef *defs, size_t n_defs, const SetList *explicit_runs,
                  size_t n_explicit, const int64_t *seeds, size_t n_seeds, WfError *err)
{
    size_t n_points = 1;
    if (explicit_runs) n_points = n_explicit;
    for (size_t a = 0; a < n_defs; a++) {
        if (defs[a].n > (size_t)WF_SWEEP_MAX_RUNS / n_points)
            return wf_err(err, WF_EINPUT, "%s: more than %ld runs", sw->path, WF_SWEEP_MAX_RUNS);
        n_points *= defs[a].n;
    }
    size_t ns = n_seeds ? n_seeds : 1;
    if (ns > (size_t)WF_SWEEP_MAX_RUNS / n_points)
        return wf_err(err, WF_EINPUT, "%s: more than %ld runs", sw->path, WF_SWEEP_MAX_RUNS);
    if (n_points == 0) return wf_err(err, WF_EINPUT, "%s: the sweep has no runs", sw->path);
    sw->n_runs = n_points * ns;
    sw->runs = calloc(sw->n_runs, sizeof *sw->runs);
    if (!sw->runs) return wf_err(err, WF_ESYS, "out of memory for %zu runs", sw->n_runs);
    for (size_t r = 0; r < sw->n_runs; r++) {
        WfSweepRun *run = &sw->runs[r];
        size_t p = r / ns, s = r % ns, n_set = common->n + (n_seeds ? 1 : 0);
        size_t idx[WF_SWEEP_MAX_AXES];
        /* Mixed-radix digits of the point index, last axis fastest. */
        for (size_t a = n_defs, q = p; a-- > 0;) idx[a] = q % defs[a].n, q /= defs[a].n;
        for (size_t a = 0; a < n_defs; a++) n_set += defs[a].pt[idx[a]].n_set;
        if (explicit_runs) n_set += explicit_runs[p].n;
        run->set = pool_calloc(sw->pool, n_set, sizeof *run->set);
        run->value = pool_calloc(sw->pool, sw->n_axes, sizeof *run->value);
        if (!run->set || !run->value) return wf_err(err, WF_ESYS, "out of memory");
        size_t k = 0;
        for (size_t i = 0; i < common->n; i++) run->set[k++] = common->s[i];
        for (size_t a = 0; a < n_defs; a++) {
            const Point *pt = &defs[a].pt[idx[a]];
            for (size_t i = 0; i < pt->n_set; i++) run->set[k++] = pt->set[i];
            run->value[a] = pt->label;
        }
        if (explicit_runs) {
            const SetList *l = &explicit_runs[p];
            for (size_t i = 0; i < l->n; i++) {
                run->set[k++] = l->s[i];
                size_t klen = (size_t)(strchr(l->s[i], '=') - l->s[i]);
                for (size_t a = 0; a < sw->n_axes; a++)
                    if (strlen(sw->axes[a].keys) == klen && !strncmp(sw->axes[a].keys, l->s[i], klen))
                        run->value[a] = l->s[i] + klen + 1;
            }
        }
        run->seed = -1;
        if (n_seeds) {
            char buf[40];
            snprintf(buf, sizeof buf, "seed=%lld", (long long)seeds[s]);
            if (!(run->set[k++] = pool_strdup(sw->pool, buf))) return wf_err(err, WF_ESYS, "out of memory");
            run->seed = seeds[s];
        }
        run->n_set = k;
    }
    return 0;
}

static int build(WfSweep *sw, WfCfg *cfg, WfError *err)
{
    WfCfgNode *root = cfg->root, *set = NULL, *axes = NULL, *runs = NULL;
    const char *name = NULL, *scen = NULL, *output = NULL;
    char w[1100];
    if (wf_cfg_string_opt(root, "name", &name, err) || wf_cfg_string(root, "scenario", &scen, err) ||
        wf_cfg_string_opt(root, "output", &output, err) || wf_cfg_map_opt(root, "set", &set, err) ||
        wf_cfg_seq_opt(root, "axes", &axes, err) || wf_cfg_seq_opt(root, "runs", &runs, err))
        return WF_EINPUT;
    if (axes && runs)
        return wf_err(err, WF_EINPUT, "%s: give either `axes` (a Cartesian product) or `runs` (an explicit list), "
                      "not both", where(runs, w, sizeof w));
    /* The name names output/NAME.h5 (and the table's rows): a plain file name that fits, never cut. */
    const char *base = wf_path_base(sw->path);
    char stem[1024];
    snprintf(stem, sizeof stem, "%.*s", (int)strcspn(base, "."), base);
    const char *chosen = name ? name : stem, *problem = wf_path_plain_name_problem(chosen, sizeof sw->name - 1);
    if (problem)
        return wf_err(err, WF_EINPUT, "%s '%.200s' %s (at most %zu bytes)%s",
                      name ? where(wf_cfg_child(root, "name"), w, sizeof w) : sw->path, chosen, problem,
                      sizeof sw->name - 1, name ? "" : ": the file's stem is the default name; set `name:`");
    memcpy(sw->name, chosen, strlen(chosen) + 1); /* fits: checked above */
    if (wf_path_relative_to(sw->path, scen, sw->scenario_path, sizeof sw->scenario_path))
        return wf_err(err, WF_EINPUT, "%s: scenario path too long", sw->path);
    int n = output ? snprintf(sw->output, sizeof sw->output, "%s", output)
                   : snprintf(sw->output, sizeof sw->output, WF_OUTPUT_DEFAULT_DIR "/%s.h5", sw->name);
    if (n < 0 || (size_t)n >= sizeof sw->output) return wf_err(err, WF_EINPUT, "%s: output path too long", sw->path);

    SetList common = {0}, *explicit_runs = NULL;
    AxisDef defs[WF_SWEEP_MAX_AXES];
    size_t n_defs = 0, n_seeds = 0;
    int64_t *seeds = NULL;
    int rc = set ? flatten(set, "", &common, sw->pool, err) : 0;
    if (rc) return rc;
    if (axes) {
        if (axes->n_child > WF_SWEEP_MAX_AXES)
            return wf_err(err, WF_EINPUT, "%s: more than %d axes", where(axes, w, sizeof w), WF_SWEEP_MAX_AXES);
        for (size_t a = 0; a < axes->n_child; a++) {
            if ((rc = parse_axis(axes->child[a], &sw->axes[a], &defs[a], sw->pool, err))) return rc;
            for (size_t b = 0; b < a; b++)
                if (!strcmp(sw->axes[a].name, sw->axes[b].name))
                    return wf_err(err, WF_EINPUT, "%s: two axes are named '%s': give one a `name`",
                                  where(axes->child[a], w, sizeof w), sw->axes[a].name);
        }
        n_defs = sw->n_axes = axes->n_child;
    }
    if (runs && !runs->n_child) return wf_err(err, WF_EINPUT, "%s: `runs` is empty", where(runs, w, sizeof w));
    if ((runs && (rc = parse_runs(sw, runs, &explicit_runs, err))) ||
        (rc = parse_seeds(root, &seeds, &n_seeds, sw->pool, err)) || (rc = wf_cfg_check_unused(cfg, err)))
        return rc;
    return expand(sw, &common, defs, n_defs, explicit_runs, runs ? runs->n_child : 0, seeds, n_seeds, err);
}

/* The sweep of cfg into sw (zeroed); each error returned where it is found. */
static int fill_sweep(WfSweep *sw, const char *path, WfCfg *cfg, const char *scenario_text, WfError *err)
{
    if (!(sw->pool = calloc(1, sizeof *sw->pool)) || !(sw->text = strdup(cfg->text)))
        return wf_err(err, WF_ESYS, "out of memory");
    if (snprintf(sw->path, sizeof sw->path, "%s", path) >= (int)sizeof sw->path)
        return wf_err(err, WF_EINPUT, "sweep path too long: %s", path);
    int rc = build(sw, cfg, err);
    if (rc) return rc;
    if (scenario_text)
        return (sw->scenario_text = strdup(scenario_text)) ? 0 : wf_err(err, WF_ESYS, "out of memory");
    /* Read once: every run uses this text, so editing the file during a sweep changes no run. */
    WfCfg *sc = NULL;
    rc = wf_cfg_load_file(sw->scenario_path, &sc, err);
    if (rc) wf_err_prefix(err, "%s: scenario: ", sw->path);
    else if (!(sw->scenario_text = strdup(sc->text))) rc = wf_err(err, WF_ESYS, "out of memory");
    wf_cfg_destroy(&sc);
    return rc;
}

static int load_common(const char *path, WfCfg *cfg, const char *scenario_text, WfSweep **out, WfError *err)
{
    WfSweep *sw = calloc(1, sizeof *sw);
    int rc = sw ? fill_sweep(sw, path, cfg, scenario_text, err) : wf_err(err, WF_ESYS, "out of memory");
    wf_cfg_destroy(&cfg);
    if (rc) wf_sweep_destroy(&sw);
    *out = sw;
    return rc;
}

int wf_sweep_load(const char *path, WfSweep **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_file(path, &cfg, err);
    return rc ? rc : load_common(path, cfg, NULL, out, err);
}

int wf_sweep_load_text(const char *path, const char *text, const char *scenario_text, WfSweep **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_string(path, text, strlen(text), &cfg, err);
    return rc ? rc : load_common(path, cfg, scenario_text, out, err);
}

/* ---- Text of a run ---- */

int wf_sweep_overrides(const WfSweep *sw, size_t run, char **out, WfError *err)
{
    const WfSweepRun *r = &sw->runs[run];
    size_t len = 1;
    for (size_t i = 0; i < r->n_set; i++) len += strlen(r->set[i]) + 1;
    char *s = malloc(len), *p = s;
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    /* Same format as a scenario's `overrides` (each assignment followed by a newline). */
    for (size_t i = 0; i < r->n_set; i++) {
        p = stpcpy(p, r->set[i]);
        *p++ = '\n';
    }
    *p = '\0';
    *out = s;
    return 0;
}

/* Appends one shell word, single-quoted unless it holds only characters no POSIX shell treats specially (a quote
 * is not one of them, so only a quoted word has any). */
static int append_word(char *buf, size_t len, size_t *used, const char *w)
{
    static const char safe[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+./=:,@%";
    int plain = w[0] && strspn(w, safe) == strlen(w);
    size_t need = strlen(w) + (plain ? 0 : 2);
    for (const char *c = w; *c; c++) need += *c == '\'' ? 3 : 0; /* ' becomes '\'' */
    if (*used + need + 2 > len) return WF_EINPUT;
    char *p = buf + *used;
    if (*used) *p++ = ' ';
    if (!plain) *p++ = '\'';
    for (const char *c = w; *c; c++) {
        if (*c == '\'') {
            memcpy(p, "'\\''", 4);
            p += 4;
        } else
            *p++ = *c;
    }
    if (!plain) *p++ = '\'';
    *p = '\0';
    *used = (size_t)(p - buf);
    return 0;
}

int wf_sweep_command(const WfSweep *sw, size_t run, const char *program, char *buf, size_t len)
{
    const WfSweepRun *r = &sw->runs[run];
    size_t used = 0;
    if (len) buf[0] = '\0';
    if (!program) program = "wavefuel";
    if (append_word(buf, len, &used, program) || append_word(buf, len, &used, "run") ||
        append_word(buf, len, &used, sw->scenario_path))
        return WF_EINPUT;
    for (size_t i = 0; i < r->n_set; i++)
        if (append_word(buf, len, &used, "--set") || append_word(buf, len, &used, r->set[i])) return WF_EINPUT;
    return 0;
}

/* ---- One run ---- */

static void record_error(WfSweepResult *res, const WfError *err)
{
    res->status = err->code == WF_EINTR ? WF_RUN_PENDING : WF_RUN_FAILED;
    res->error_code = err->code ? err->code : WF_ESYS;
    snprintf(res->error, sizeof res->error, "%s", err->msg[0] ? err->msg : "unknown error");
}

void wf_sweep_run(const WfSweep *sw, size_t i, const WfSweepRunOpts *o, volatile sig_atomic_t *stop,
                  WfSweepResult *res)
{
    const WfSweepRun *run = &sw->runs[i];
    memset(res, 0, sizeof *res);
    res->seed = run->seed;
    res->worker = o->worker;
    res->threads = o->threads;
    double t0 = wf_wall_now();
    WfError err = {0};
    if (stop && *stop) {
        wf_err(&err, WF_EINTR, "interrupted before it started");
        record_error(res, &err);
        return;
    }
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfH5Out *h5 = NULL;
    WfOutput ops, *out = NULL;
    int rc = wf_scenario_load_text(sw->scenario_path, sw->scenario_text, run->set, run->n_set, &sc, &err);
    if (!rc) {
        res->seed = (int64_t)sc->seed;
        res->n_classes = sc->n_classes;
        size_t used = 0;
        for (size_t c = 0; c < sc->n_classes; c++) {
            int n = snprintf(res->classes + used, sizeof res->classes - used, "%s%s", c ? "," : "",
                             sc->classes[c].vc.name);
            if (n > 0 && (size_t)n < sizeof res->classes - used) used += (size_t)n;
        }
        /* The sweep table holds the ring's summary fields (src/io/h5sweep.c). */
        rc = sc->corridor ? wf_err(&err, WF_EINPUT, "%s: road.type corridor: sweeps tabulate ring metrics; run "
                                   "corridors with `wavefuel run` for now", sc->path)
                          : wf_sim_create(sc, &sim, &err);
    }
    if (!rc && o->per_run_dir) {
        char *ov = NULL;
        rc = wf_sweep_overrides(sw, i, &ov, &err);
        if (!rc) {
            /* FNV-1a of the overrides names the run's own file, so the name stays when the sweep is extended. */
            int n = snprintf(sc->output_path, sizeof sc->output_path, "%s/run_%016llx.h5", o->per_run_dir,
                             (unsigned long long)wf_fnv1a64(WF_FNV1A64_INIT, ov, strlen(ov)));
            if (n < 0 || (size_t)n >= sizeof sc->output_path)
                rc = wf_err(&err, WF_EINPUT, "per-run directory path too long: %s", o->per_run_dir);
        }
        free(ov);
        /* force: the table does not hold this run as complete, so a file left by an earlier attempt is stale. */
        if (!rc) rc = wf_h5out_create(sim, sc->output_path, 1, &h5, &ops, &err);
        if (!rc) out = &ops;
    }
    if (!rc) rc = wf_sim_run(sim, out, NULL, NULL, stop, &err);
    if (h5 && wf_h5out_path(h5)[0]) snprintf(res->file, sizeof res->file, "%s", wf_h5out_path(h5));
    if (rc)
        record_error(res, &err);
    else {
        res->status = WF_RUN_OK;
        res->summary = *wf_sim_summary(sim);
    }
    wf_h5out_destroy(&h5);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    res->wall_s = wf_wall_now() - t0;
}

/* ---- Resume ---- */

typedef struct Keyed {
    const char *key;
    size_t      index;
} Keyed;

static int by_key(const void *a, const void *b) { return strcmp(((const Keyed *)a)->key, ((const Keyed *)b)->key); }

int wf_sweep_resume(const WfSweep *sw, const WfSweepSaved *saved, int retry_failed, WfSweepResult *res,
                    size_t *n_reused, WfError *err)
{
    *n_reused = 0;
    if (strcmp(saved->scenario_text, sw->scenario_text) != 0)
        return wf_err(err, WF_EINPUT,
                      "the table was written from another version of the base scenario (%s): its rows would not match "
                      "the runs; use --force to start over, or -o another file",
                      saved->scenario_path);
    Keyed *k = calloc(sw->n_runs, sizeof *k);
    char **ov = calloc(sw->n_runs, sizeof *ov);
    int rc = (!k || !ov) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t i = 0; !rc && i < sw->n_runs; i++) {
        rc = wf_sweep_overrides(sw, i, &ov[i], err);
        k[i] = (Keyed){ov ? ov[i] : NULL, i};
    }
    if (!rc) qsort(k, sw->n_runs, sizeof *k, by_key);
    size_t orphans = 0, first_orphan = 0;
    for (size_t j = 0; !rc && j < saved->n; j++) {
        const WfSweepResult *s = &saved->res[j];
        if (s->status == WF_RUN_PENDING) continue;
        Keyed want = {saved->overrides[j], 0};
        const Keyed *hit = bsearch(&want, k, sw->n_runs, sizeof *k, by_key);
        if (!hit) {
            if (!orphans++) first_orphan = j;
            continue;
        }
        if (s->status == WF_RUN_FAILED && retry_failed) continue;
        res[hit->index] = *s;
        ++*n_reused;
    }
    if (!rc && orphans) {
        char one[300];
        snprintf(one, sizeof one, "%s", saved->overrides[first_orphan]);
        for (char *c = one; *c; c++)
            if (*c == '\n') *c = ' ';
        rc = wf_err(err, WF_EINPUT,
                    "the table holds %zu finished runs that the sweep no longer lists (the first: %s); resuming would "
                    "drop them: use -o another file, or --force to start over",
                    orphans, one[0] ? one : "(no overrides)");
    }
    for (size_t i = 0; ov && i < sw->n_runs; i++) free(ov[i]);
    free(ov);
    free(k);
    return rc;
}
