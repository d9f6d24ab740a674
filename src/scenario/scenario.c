/* Scenario loading: YAML + --set overrides -> WfScenario, with every key typed, range-checked and named in
 * errors (file:line: path), unknown keys rejected with a suggestion, and cross-field consistency checked. */
#include "wavefuel/scenario.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/cf_plugin.h"
#include "wavefuel/config.h"
#include "wavefuel/corridor.h"
#include "wavefuel/csv.h"
#include "wavefuel/integrator.h"

static const char *where_of(WfCfgNode *n, char *buf, size_t len)
{
    char w[600], p[400];
    snprintf(buf, len, "%s: %s", wf_cfg_where(n, w, sizeof w), wf_cfg_path(n, p, sizeof p));
    return buf;
}

void wf_scenario_destroy(WfScenario **psc)
{
    if (!psc || !*psc) return;
    WfScenario *sc = *psc;
    for (size_t i = 0; i < sc->n_classes; i++) {
        wf_vehicle_free(&sc->classes[i].vc);
        free(sc->classes[i].indices);
    }
    for (size_t i = 0; i < sc->n_groups; i++) {
        free(sc->groups[i].indices);
        wf_cf_plugin_close(&sc->groups[i].plugin);
    }
    wf_road_free(&sc->road);
    wf_corridor_spec_destroy(&sc->corridor);
    free(sc->text);
    free(sc->overrides);
    free(sc);
    *psc = NULL;
}

long wf_scenario_n_steps(const WfScenario *sc) { return lround(sc->duration_s / sc->dt_s); }
long wf_scenario_output_every(const WfScenario *sc) { return lround(sc->output_interval_s / sc->dt_s); }
long wf_scenario_trajectory_every(const WfScenario *sc)
{
    long k = lround(sc->trajectory_interval_s / sc->dt_s);
    return k < 1 ? 1 : k;
}
long wf_scenario_records(const WfScenario *sc, long every) { return wf_scenario_n_steps(sc) / every + 1; }

/* A list of vehicle indices (explicit placement). */
static int read_indices(WfCfgNode *map, long n_veh, long **out, size_t *n_out, WfError *err)
{
    WfCfgNode *seq = NULL;
    *out = NULL;
    *n_out = 0;
    if (wf_cfg_seq_opt(map, "indices", &seq, err)) return WF_EINPUT;
    if (!seq) return 0;
    long *idx = malloc((seq->n_child + 1) * sizeof *idx);
    if (!idx) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t k = 0; k < seq->n_child; k++) {
        double v;
        if (wf_cfg_node_double(seq->child[k], 0, (double)(n_veh - 1), "(vehicle index)", &v, err)) {
            free(idx);
            return WF_EINPUT;
        }
        if (v != floor(v)) {
            char w[1024];
            free(idx);
            return wf_err(err, WF_EINPUT, "%s: expected an integer vehicle index (got %.17g)",
                          where_of(seq->child[k], w, sizeof w), v);
        }
        idx[k] = (long)v;
    }
    *out = idx;
    *n_out = seq->n_child;
    return 0;
}

/* Shares given as fraction or count: exactly one of them per entry, all entries alike. Resolves counts by
 * largest remainder (ties to the earlier entry) so they sum to n exactly. */
static int resolve_counts(const char *what, size_t m, double *fraction, long *count, int *given_count, long n,
                          const char *where, WfError *err)
{
    int any_count = 0, any_frac = 0;
    for (size_t i = 0; i < m; i++) any_count |= given_count[i], any_frac |= !given_count[i];
    if (any_count && any_frac)
        return wf_err(err, WF_EINPUT, "%s: give every %s a 'count' or every one a 'fraction', not a mix", where, what);
    if (any_count) {
        long sum = 0;
        for (size_t i = 0; i < m; i++) sum += count[i];
        if (sum != n)
            return wf_err(err, WF_EINPUT, "%s: %s counts sum to %ld but fleet.vehicles is %ld", where, what, sum, n);
        return 0;
    }
    double sum = 0.0;
    for (size_t i = 0; i < m; i++) sum += fraction[i];
    if (fabs(sum - 1.0) > 1e-9)
        return wf_err(err, WF_EINPUT, "%s: %s fractions sum to %.12g, expected 1", where, what, sum);
    long assigned = 0;
    double rem[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    for (size_t i = 0; i < m; i++) {
        /* Fractions are normalised by their sum (within 1e-9 of 1): floors of un-normalised shares could add up to
         * more than n for a billion vehicles. */
        double exact = fraction[i] / sum * (double)n;
        if (exact > (double)n) exact = (double)n;
        count[i] = (long)floor(exact);
        rem[i] = exact - (double)count[i];
        assigned += count[i];
    }
    while (assigned < n) {
        size_t best = 0;
        for (size_t i = 1; i < m; i++)
            if (rem[i] > rem[best]) best = i;
        count[best]++;
        rem[best] = -1.0;
        assigned++;
    }
    return 0;
}

static int load_grade(WfScenario *sc, WfCfgNode *road, WfError *err)
{
    WfCfgNode *grade = NULL, *points = NULL;
    const char *csv = NULL;
    char w[1024];
    if (wf_cfg_map_opt(road, "grade", &grade, err)) return WF_EINPUT;
    if (!grade) return 0;
    if (wf_cfg_seq_opt(grade, "points", &points, err) || wf_cfg_string_opt(grade, "csv", &csv, err))
        return WF_EINPUT;
    if (!!points == !!csv)
        return wf_err(err, WF_EINPUT, "%s: give either 'points' (a list of [x_m, grade_rad]) or 'csv' (a file)",
                      where_of(grade, w, sizeof w));
    double *x = NULL, *th = NULL;
    size_t n = 0;
    int rc = 0;
    if (points) {
        n = points->n_child;
        x = malloc((n + 1) * sizeof *x);
        th = malloc((n + 1) * sizeof *th);
        if (!x || !th) {
            rc = wf_err(err, WF_ESYS, "out of memory");
            goto done;
        }
        for (size_t i = 0; i < n; i++) {
            WfCfgNode *p = points->child[i];
            p->used = 1;
            if (p->kind != WF_CFG_SEQ || p->n_child != 2) {
                rc = wf_err(err, WF_EINPUT, "%s: expected a pair [x_m, grade_rad]", where_of(p, w, sizeof w));
                goto done;
            }
            if ((rc = wf_cfg_node_double(p->child[0], 0, 1e9, "m", &x[i], err))) goto done;
            if ((rc = wf_cfg_node_double(p->child[1], -0.2, 0.2, "rad", &th[i], err))) goto done;
        }
        rc = wf_road_set_grade(&sc->road, n, x, th, where_of(points, w, sizeof w), err);
    } else {
        /* Relative paths are relative to the scenario file, so a scenario and its profile travel together. */
        char path[2048];
        const char *slash = strrchr(sc->path, '/');
        if (csv[0] == '/' || !slash)
            snprintf(path, sizeof path, "%s", csv);
        else
            snprintf(path, sizeof path, "%.*s/%s", (int)(slash - sc->path), sc->path, csv);
        static const char *const names[] = {"x_m", "grade_rad"};
        WfCsv t;
        if ((rc = wf_csv_read(path, 2, names, &t, err))) {
            wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(grade, "csv"), w, sizeof w));
            goto done;
        }
        n = t.n_rows;
        x = malloc((n + 1) * sizeof *x);
        th = malloc((n + 1) * sizeof *th);
        if (!x || !th) rc = wf_err(err, WF_ESYS, "out of memory");
        for (size_t i = 0; !rc && i < n; i++) x[i] = t.data[2 * i], th[i] = t.data[2 * i + 1];
        if (!rc && n == 0) rc = wf_err(err, WF_EINPUT, "%s: no rows", path);
        if (!rc) rc = wf_road_set_grade(&sc->road, n, x, th, path, err);
        wf_csv_free(&t);
    }
done:
    free(x);
    free(th);
    return rc;
}

static int load_classes(WfScenario *sc, WfCfgNode *fleet, WfError *err)
{
    WfCfgNode *seq = NULL;
    char w[1024];
    if (wf_cfg_seq_opt(fleet, "classes", &seq, err)) return WF_EINPUT;
    if (!seq || seq->n_child == 0)
        return wf_err(err, WF_EINPUT, "%s: missing 'classes': a list of {class: NAME, fraction: F} entries",
                      where_of(fleet, w, sizeof w));
    if (seq->n_child > WF_MAX_CLASSES)
        return wf_err(err, WF_EINPUT, "%s: at most %d classes", where_of(seq, w, sizeof w), WF_MAX_CLASSES);
    double frac[WF_MAX_CLASSES];
    long count[WF_MAX_CLASSES];
    int given[WF_MAX_CLASSES];
    for (size_t i = 0; i < seq->n_child; i++) {
        WfCfgNode *e = seq->child[i];
        e->used = 1;
        if (e->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: expected a map {class: NAME, fraction: F}", where_of(e, w, sizeof w));
        WfClassShare *cs = &sc->classes[i];
        const char *name = NULL;
        if (wf_cfg_string(e, "class", &name, err)) return WF_EINPUT;
        /* Class files named by relative path resolve against the scenario's directory. */
        char path[2048];
        const char *slash = strrchr(sc->path, '/');
        if (strchr(name, '/') && name[0] != '/' && slash)
            snprintf(path, sizeof path, "%.*s/%s", (int)(slash - sc->path), sc->path, name);
        else
            snprintf(path, sizeof path, "%s", name);
        if (wf_vehicle_find(path, &cs->vc, err)) {
            wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(e, "class"), w, sizeof w));
            return WF_EINPUT;
        }
        sc->n_classes = i + 1;
        for (size_t k = 0; k < i; k++)
            if (strcmp(sc->classes[k].vc.path, cs->vc.path) == 0)
                return wf_err(err, WF_EINPUT, "%s: class '%s' listed twice", where_of(e, w, sizeof w), name);
        cs->length_m = cs->vc.length_m;
        if (wf_cfg_double_opt(e, "length_m", 1, 30, "m", &cs->length_m, err)) return WF_EINPUT;
        frac[i] = NAN;
        count[i] = -1;
        if (wf_cfg_double_opt(e, "fraction", 0, 1, "(share of vehicles)", &frac[i], err)) return WF_EINPUT;
        if (wf_cfg_long_opt(e, "count", 0, sc->n_vehicles, &count[i], err)) return WF_EINPUT;
        if (read_indices(e, sc->n_vehicles, &cs->indices, &cs->n_indices, err)) return WF_EINPUT;
        if (sc->placement == WF_PLACE_EXPLICIT) {
            if (!cs->indices)
                return wf_err(err, WF_EINPUT, "%s: placement is explicit: list this class's vehicles in 'indices'",
                              where_of(e, w, sizeof w));
            count[i] = (long)cs->n_indices;
            frac[i] = NAN;
        } else if (cs->indices) {
            return wf_err(err, WF_EINPUT, "%s: 'indices' needs fleet.placement: explicit", where_of(e, w, sizeof w));
        } else if (isnan(frac[i]) == (count[i] < 0)) {
            return wf_err(err, WF_EINPUT, "%s: give exactly one of 'fraction' or 'count'", where_of(e, w, sizeof w));
        }
        given[i] = count[i] >= 0;
    }
    if (resolve_counts("class", seq->n_child, frac, count, given, sc->n_vehicles, where_of(seq, w, sizeof w), err))
        return WF_EINPUT;
    for (size_t i = 0; i < seq->n_child; i++) sc->classes[i].fraction = frac[i], sc->classes[i].count = count[i];
    return 0;
}

/* A path as written in the scenario: absolute, or relative to the scenario file's directory. Returns -1 when it
 * does not fit in buf. */
static int relative_to_scenario(const WfScenario *sc, const char *name, char *buf, size_t len)
{
    const char *slash = strrchr(sc->path, '/');
    int n = name[0] == '/' || !slash ? snprintf(buf, len, "%s", name)
                                     : snprintf(buf, len, "%.*s/%s", (int)(slash - sc->path), sc->path, name);
    return n < 0 || (size_t)n >= len ? -1 : 0;
}

_Static_assert(WF_CF_PLUGIN_MAX_PARAMS <= WF_MAX_MODEL_PARAMS, "a plugin's parameters must fit a driver group");

/* A driver group's model: a registry name, or `plugin` with `path` naming a shared library. */
static int load_group_model(WfScenario *sc, WfCfgNode *e, WfDriverGroup *g, WfError *err)
{
    const char *model = NULL;
    char w[1024];
    if (wf_cfg_string(e, "model", &model, err)) return WF_EINPUT;
    WfCfgNode *pn = wf_cfg_child(e, "path");
    if (strcmp(model, "plugin") == 0) {
        const char *lib = NULL;
        char path[2048];
        if (wf_cfg_string(e, "path", &lib, err)) return WF_EINPUT;
        if (relative_to_scenario(sc, lib, path, sizeof path))
            return wf_err(err, WF_EINPUT, "%s: plugin path too long", where_of(pn, w, sizeof w));
        if (wf_cf_plugin_load(path, &g->plugin, err)) {
            wf_err_prefix(err, "%s: ", where_of(pn, w, sizeof w));
            return WF_EINPUT;
        }
        g->model = wf_cf_plugin_model(g->plugin);
        return 0;
    }
    if (pn)
        return wf_err(err, WF_EINPUT, "%s: 'path' names a controller library and needs model: plugin (model is '%s')",
                      where_of(pn, w, sizeof w), model);
    if (wf_cf_model_find(model, &g->model, err)) {
        char msg[sizeof err->msg];
        memcpy(msg, err->msg, sizeof msg);
        return wf_err(err, WF_EINPUT, "%s: %s, or 'plugin' with 'path: LIBRARY.so'",
                      where_of(wf_cfg_child(e, "model"), w, sizeof w), msg);
    }
    return 0;
}

/* A group's own placement and class (automated vehicles placed apart from the fleet's rule). */
static int load_group_placement(WfScenario *sc, WfCfgNode *e, WfDriverGroup *g, WfError *err)
{
    static const char *const places[] = {"random", "interleaved", "explicit", NULL};
    char w[1024];
    const char *cls = NULL;
    g->placement = -1;
    g->class_index = -1;
    if (sc->placement == WF_PLACE_EXPLICIT && (wf_cfg_child(e, "placement") || wf_cfg_child(e, "class")))
        return wf_err(err, WF_EINPUT,
                      "%s: fleet.placement is explicit: the group's vehicles and their classes are the 'indices' "
                      "lists; drop this group's 'placement' and 'class'",
                      where_of(e, w, sizeof w));
    if (wf_cfg_child(e, "placement")) {
        int p = 0;
        if (wf_cfg_enum_opt(e, "placement", places, &p, err)) return WF_EINPUT;
        g->placement = p;
    }
    if (wf_cfg_string_opt(e, "class", &cls, err)) return WF_EINPUT;
    if (cls) {
        char known[512] = "";
        size_t used = 0;
        for (size_t c = 0; c < sc->n_classes && g->class_index < 0; c++) {
            if (strcmp(sc->classes[c].vc.name, cls) == 0) g->class_index = (int)c;
            int n = snprintf(known + used, sizeof known - used, "%s%s", c ? ", " : "", sc->classes[c].vc.name);
            if (n > 0 && (size_t)n < sizeof known - used) used += (size_t)n;
        }
        if (g->class_index < 0)
            return wf_err(err, WF_EINPUT, "%s: class '%s' is not in fleet.classes (%s)",
                          where_of(wf_cfg_child(e, "class"), w, sizeof w), cls, known);
    }
    return 0;
}

/* After the counts are known: groups that name a class fit in it, and groups placed explicitly on their own
 * (fleet.placement not explicit) claim distinct vehicles. */
static int check_group_claims(const WfScenario *sc, const char *where, WfError *err)
{
    for (size_t c = 0; c < sc->n_classes; c++) {
        long need = 0;
        for (size_t g = 0; g < sc->n_groups; g++) need += sc->groups[g].class_index == (int)c ? sc->groups[g].count : 0;
        if (need > sc->classes[c].count)
            return wf_err(err, WF_EINPUT, "%s: driver groups with class %s have %ld vehicles but the class has %ld",
                          where, sc->classes[c].vc.name, need, sc->classes[c].count);
    }
    if (sc->placement == WF_PLACE_EXPLICIT) return 0; /* check_partition covers it */
    unsigned char *seen = calloc((size_t)sc->n_vehicles, 1);
    if (!seen) return wf_err(err, WF_ESYS, "out of memory");
    int rc = 0;
    for (size_t g = 0; !rc && g < sc->n_groups; g++)
        for (size_t k = 0; !rc && sc->groups[g].placement == WF_PLACE_EXPLICIT && k < sc->groups[g].n_indices; k++)
            if (seen[sc->groups[g].indices[k]]++)
                rc = wf_err(err, WF_EINPUT, "%s: vehicle %ld is listed twice in driver groups' indices", where,
                            sc->groups[g].indices[k]);
    free(seen);
    return rc;
}

static int load_groups(WfScenario *sc, WfCfgNode *fleet, WfError *err)
{
    WfCfgNode *seq = NULL;
    char w[1024];
    if (wf_cfg_seq_opt(fleet, "drivers", &seq, err)) return WF_EINPUT;
    if (!seq || seq->n_child == 0)
        return wf_err(err, WF_EINPUT, "%s: missing 'drivers': a list of driver groups {model: idm, fraction: 1, ...}",
                      where_of(fleet, w, sizeof w));
    if (seq->n_child > WF_MAX_GROUPS)
        return wf_err(err, WF_EINPUT, "%s: at most %d driver groups", where_of(seq, w, sizeof w), WF_MAX_GROUPS);
    double frac[WF_MAX_GROUPS];
    long count[WF_MAX_GROUPS];
    int given[WF_MAX_GROUPS];
    static const char *const dists[] = {"normal", "uniform", NULL};
    static const char *const feas[] = {"none", "clip", NULL};
    for (size_t i = 0; i < seq->n_child; i++) {
        WfCfgNode *e = seq->child[i], *params = NULL, *het = NULL;
        e->used = 1;
        if (e->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: expected a map {model: idm, ...}", where_of(e, w, sizeof w));
        WfDriverGroup *g = &sc->groups[i];
        sc->n_groups = i + 1;
        const char *name = NULL;
        snprintf(g->name, sizeof g->name, "group%zu", i);
        if (wf_cfg_string_opt(e, "name", &name, err)) return WF_EINPUT;
        if (name) snprintf(g->name, sizeof g->name, "%s", name);
        if (load_group_model(sc, e, g, err) || load_group_placement(sc, e, g, err)) return WF_EINPUT;
        if (g->model->param_size > sizeof g->params)
            return wf_err(err, WF_ESYS, "model %s has too many parameters", g->model->name);
        if (wf_cfg_map_opt(e, "params", &params, err)) return WF_EINPUT;
        if (wf_cfg_params(params, g->model->spec, g->model->n_spec, g->params, err)) return WF_EINPUT;
        char wh[1100];
        snprintf(wh, sizeof wh, "%s: ", where_of(e, w, sizeof w));
        if (wf_param_check_complete(g->model->spec, g->model->n_spec, g->params, wh, err)) return WF_EINPUT;
        if (g->model->check && g->model->check(g->params, err)) {
            wf_err_prefix(err, "%s", wh);
            return WF_EINPUT;
        }
        if (wf_cfg_map_opt(e, "heterogeneity", &het, err)) return WF_EINPUT;
        int dist = WF_HET_NORMAL;
        if (het) {
            WfCfgNode *spread = NULL;
            if (wf_cfg_enum_opt(het, "distribution", dists, &dist, err)) return WF_EINPUT;
            if (wf_cfg_map_opt(het, "spread", &spread, err)) return WF_EINPUT;
            for (size_t k = 0; spread && k < g->model->n_spec; k++)
                if (wf_cfg_double_opt(spread, g->model->spec[k].key, 0, 0.5, "(relative)", &g->spread[k], err))
                    return WF_EINPUT;
        }
        g->dist = (WfHetDist)dist;
        if (wf_cfg_double_opt(e, "noise_mps2", 0, 10, "m/s^2", &g->noise_mps2, err)) return WF_EINPUT;
        g->accel_max_mps2 = 5.0;
        g->decel_max_mps2 = 9.0;
        if (wf_cfg_double_opt(e, "accel_max_mps2", 0.1, 20, "m/s^2", &g->accel_max_mps2, err)) return WF_EINPUT;
        if (wf_cfg_double_opt(e, "decel_max_mps2", 0.1, 20, "m/s^2", &g->decel_max_mps2, err)) return WF_EINPUT;
        int fe = 0;
        if (wf_cfg_enum_opt(e, "feasible_accel", feas, &fe, err)) return WF_EINPUT;
        g->clip_feasible = fe;
        frac[i] = NAN;
        count[i] = -1;
        if (wf_cfg_double_opt(e, "fraction", 0, 1, "(share of vehicles)", &frac[i], err)) return WF_EINPUT;
        if (wf_cfg_long_opt(e, "count", 0, sc->n_vehicles, &count[i], err)) return WF_EINPUT;
        if (read_indices(e, sc->n_vehicles, &g->indices, &g->n_indices, err)) return WF_EINPUT;
        if (g->placement == WF_PLACE_EXPLICIT && (!isnan(frac[i]) || count[i] >= 0))
            return wf_err(err, WF_EINPUT, "%s: placement is explicit: the group's size is its 'indices' list; drop "
                          "'fraction' and 'count'", where_of(e, w, sizeof w));
        if (sc->placement == WF_PLACE_EXPLICIT || g->placement == WF_PLACE_EXPLICIT) {
            if (!g->indices)
                return wf_err(err, WF_EINPUT, "%s: placement is explicit: list this group's vehicles in 'indices'",
                              where_of(e, w, sizeof w));
            count[i] = (long)g->n_indices;
        } else if (g->indices) {
            return wf_err(err, WF_EINPUT, "%s: 'indices' needs placement: explicit (fleet.placement or the group's own)",
                          where_of(e, w, sizeof w));
        } else if (isnan(frac[i]) == (count[i] < 0)) {
            return wf_err(err, WF_EINPUT, "%s: give exactly one of 'fraction' or 'count'", where_of(e, w, sizeof w));
        }
        given[i] = count[i] >= 0;
    }
    if (resolve_counts("driver group", seq->n_child, frac, count, given, sc->n_vehicles, where_of(seq, w, sizeof w),
                       err))
        return WF_EINPUT;
    for (size_t i = 0; i < seq->n_child; i++) sc->groups[i].fraction = frac[i], sc->groups[i].count = count[i];
    return check_group_claims(sc, where_of(seq, w, sizeof w), err);
}

/* Explicit placement: every vehicle index must be claimed exactly once among classes, and among groups. */
static int check_partition(const WfScenario *sc, WfError *err)
{
    unsigned char *seen = calloc((size_t)sc->n_vehicles, 2);
    if (!seen) return wf_err(err, WF_ESYS, "out of memory");
    int rc = 0;
    for (size_t c = 0; !rc && c < sc->n_classes; c++)
        for (size_t k = 0; !rc && k < sc->classes[c].n_indices; k++)
            if (seen[2 * sc->classes[c].indices[k]]++)
                rc = wf_err(err, WF_EINPUT, "%s: fleet.classes: vehicle %ld is listed in two classes", sc->path,
                            sc->classes[c].indices[k]);
    for (size_t g = 0; !rc && g < sc->n_groups; g++)
        for (size_t k = 0; !rc && k < sc->groups[g].n_indices; k++)
            if (seen[2 * sc->groups[g].indices[k] + 1]++)
                rc = wf_err(err, WF_EINPUT, "%s: fleet.drivers: vehicle %ld is listed in two driver groups", sc->path,
                            sc->groups[g].indices[k]);
    for (long i = 0; !rc && i < sc->n_vehicles; i++)
        if (!seen[2 * i] || !seen[2 * i + 1])
            rc = wf_err(err, WF_EINPUT, "%s: explicit placement: vehicle %ld has no %s", sc->path, i,
                        !seen[2 * i] ? "class (fleet.classes[].indices)" : "driver group (fleet.drivers[].indices)");
    free(seen);
    return rc;
}

/* `solver`: settings of the SUNDIALS integrators (docs/scenarios.md). Present only with one of them. */
static int load_solver(WfScenario *sc, WfCfgNode *root, const char *integ, WfError *err)
{
    WfCfgNode *sv = NULL;
    char w[1024];
    WfOdeConfig *c = &sc->solver;
    memset(c, 0, sizeof *c);
    c->kind = !strcmp(integ, "cvode") ? WF_ODE_CVODE : !strcmp(integ, "arkode") ? WF_ODE_ARKODE : WF_ODE_RK4;
    c->rtol = 1e-6;
    c->atol_x_m = 1e-6;
    c->atol_v_mps = 1e-6;
    c->atol_fuel_g = 1e-6;
    c->max_steps = 100000;
    c->rk4_substeps = 1;
    snprintf(c->erk_table, sizeof c->erk_table, "ARKODE_DORMAND_PRINCE_7_4_5");
    if (wf_cfg_map_opt(root, "solver", &sv, err)) return WF_EINPUT;
    if (!sv) return 0;
    if (!sc->adaptive)
        return wf_err(err, WF_EINPUT, "%s: 'solver' configures cvode, arkode and rk4; time.integrator is '%s'",
                      where_of(sv, w, sizeof w), integ);
    static const char *const nvecs[] = {"serial", "openmp", NULL};
    const char *method = NULL;
    int nv = 0;
    if (wf_cfg_double_opt(sv, "rtol", 1e-14, 1e-1, "1", &c->rtol, err) ||
        wf_cfg_double_opt(sv, "atol_x_m", 1e-14, 10, "m", &c->atol_x_m, err) ||
        wf_cfg_double_opt(sv, "atol_v_mps", 1e-14, 10, "m/s", &c->atol_v_mps, err) ||
        wf_cfg_double_opt(sv, "atol_fuel_g", 1e-14, 10, "g", &c->atol_fuel_g, err) ||
        wf_cfg_double_opt(sv, "max_step_s", 0, 1e6, "s", &c->max_step_s, err) ||
        wf_cfg_long_opt(sv, "max_steps", 1, 1000000000L, &c->max_steps, err) ||
        wf_cfg_bool_opt(sv, "fuel_error_control", &c->fuel_errcon, err) ||
        wf_cfg_enum_opt(sv, "nvector", nvecs, &nv, err) || wf_cfg_string_opt(sv, "method", &method, err))
        return WF_EINPUT;
    long sub = 1;
    if (wf_cfg_long_opt(sv, "rk4_substeps", 1, 1000000, &sub, err)) return WF_EINPUT;
    c->rk4_substeps = (int)sub;
    c->nvector_openmp = nv;
    if (method && c->kind == WF_ODE_CVODE) {
        if (strcmp(method, "adams") && strcmp(method, "bdf"))
            return wf_err(err, WF_EINPUT, "%s: solver.method for cvode is 'adams' or 'bdf' (got '%s')",
                          where_of(wf_cfg_child(sv, "method"), w, sizeof w), method);
        c->bdf = !strcmp(method, "bdf");
    } else if (method && c->kind == WF_ODE_ARKODE) {
        snprintf(c->erk_table, sizeof c->erk_table, "%s", method);
    } else if (method) {
        return wf_err(err, WF_EINPUT, "%s: rk4 has no method to choose (it is the classic RK4 tableau)",
                      where_of(wf_cfg_child(sv, "method"), w, sizeof w));
    }
    return 0;
}

static int load_tree(WfScenario *sc, WfCfg *cfg, WfError *err)
{
    WfCfgNode *root = cfg->root, *road = NULL, *time = NULL, *fleet = NULL, *init = NULL, *stats = NULL,
              *out = NULL, *pert = NULL;
    char w[1024];
    const char *s = NULL;
    static const char *const road_types[] = {"ring", "corridor", NULL};
    static const char *const places[] = {"random", "interleaved", "explicit", NULL};
    static const char *const inits[] = {"equilibrium", "rest", NULL};
    int rtype = 0, place = WF_PLACE_RANDOM, init_state = WF_INIT_EQUILIBRIUM;

    const char *stem = strrchr(sc->path, '/');
    snprintf(sc->name, sizeof sc->name, "%.127s", stem ? stem + 1 : sc->path);
    char *dot = strrchr(sc->name, '.');
    if (dot) *dot = '\0';
    if (wf_cfg_string_opt(root, "name", &s, err)) return WF_EINPUT;
    if (s) snprintf(sc->name, sizeof sc->name, "%.127s", s);
    long seed = 1;
    if (wf_cfg_long_opt(root, "seed", 0, 0x7fffffffffffffffL, &seed, err)) return WF_EINPUT;
    sc->seed = (uint64_t)seed;

    if (wf_cfg_map_opt(root, "road", &road, err)) return WF_EINPUT;
    if (!road) return wf_cfg_missing(root, "road", "a section", err);
    if (wf_cfg_enum_opt(road, "type", road_types, &rtype, err)) return WF_EINPUT;
    if (wf_cfg_double(road, "length_m", 1, 1e10, "m", &sc->road.length_m, err)) return WF_EINPUT;
    sc->road.speed_limit_mps = INFINITY;
    if (wf_cfg_double_opt(road, "speed_limit_mps", 0.1, 100, "m/s", &sc->road.speed_limit_mps, err)) return WF_EINPUT;
    /* A corridor's grade profile is not periodic: src/scenario/scenario_corridor.c reads it. */
    if (rtype == 0 && load_grade(sc, road, err)) return WF_EINPUT;

    if (wf_cfg_map_opt(root, "time", &time, err)) return WF_EINPUT;
    if (!time) return wf_cfg_missing(root, "time", "a section", err);
    if (wf_cfg_double(time, "duration_s", 1e-6, 1e9, "s", &sc->duration_s, err)) return WF_EINPUT;
    sc->dt_s = 0.1;
    if (wf_cfg_double_opt(time, "dt_s", 1e-6, 10, "s", &sc->dt_s, err)) return WF_EINPUT;
    sc->output_interval_s = 1.0;
    if (wf_cfg_double_opt(time, "output_interval_s", 1e-6, 1e9, "s", &sc->output_interval_s, err)) return WF_EINPUT;
    if (wf_cfg_double_opt(time, "warmup_s", 0, 1e9, "s", &sc->warmup_s, err)) return WF_EINPUT;
    const char *integ = "ballistic";
    if (wf_cfg_string_opt(time, "integrator", &integ, err)) return WF_EINPUT;
    const WfIntegrator *ig;
    sc->adaptive = !strcmp(integ, "cvode") || !strcmp(integ, "arkode") || !strcmp(integ, "rk4");
    if (!sc->adaptive && wf_integrator_find(integ, &ig, NULL)) {
        char known[256] = "";
        for (size_t i = 0; wf_integrators[i]; i++)
            snprintf(known + strlen(known), sizeof known - strlen(known), "%s, ", wf_integrators[i]->name);
        return wf_err(err, WF_EINPUT, "%s: unknown integrator '%s' (known: %scvode, arkode, rk4)",
                      where_of(wf_cfg_child(time, "integrator"), w, sizeof w), integ, known);
    }
    snprintf(sc->integrator, sizeof sc->integrator, "%s", integ);
    if (load_solver(sc, root, integ, err)) return WF_EINPUT;
    sc->fused_step = 1;
    if (wf_cfg_bool_opt(time, "fused_step", &sc->fused_step, err)) return WF_EINPUT;
    /* The step must divide the output interval and the duration: records then fall on steps exactly. */
    double ratio = sc->output_interval_s / sc->dt_s, nsteps = sc->duration_s / sc->dt_s;
    if (sc->dt_s > sc->output_interval_s || fabs(ratio - round(ratio)) > 1e-9 * ratio)
        return wf_err(err, WF_EINPUT,
                      "%s: time.output_interval_s (%.17g s) must be a whole multiple of time.dt_s (%.17g s)", sc->path,
                      sc->output_interval_s, sc->dt_s);
    if (fabs(nsteps - round(nsteps)) > 1e-9 * nsteps)
        return wf_err(err, WF_EINPUT, "%s: time.duration_s (%.17g s) must be a whole multiple of time.dt_s (%.17g s)",
                      sc->path, sc->duration_s, sc->dt_s);
    if (nsteps > 1e12) return wf_err(err, WF_EINPUT, "%s: more than 1e12 steps: reduce duration or raise dt", sc->path);
    if (sc->warmup_s >= sc->duration_s)
        return wf_err(err, WF_EINPUT, "%s: time.warmup_s (%.17g s) must be shorter than time.duration_s (%.17g s)",
                      sc->path, sc->warmup_s, sc->duration_s);

    if (wf_cfg_map_opt(root, "fleet", &fleet, err)) return WF_EINPUT;
    if (!fleet) return wf_cfg_missing(root, "fleet", "a section", err);
    /* Corridors: vehicles come from the inflow; class and group fractions resolve against a nominal count. */
    double nv = (double)WF_CORRIDOR_SHARE_BASE;
    if (rtype == 0 && wf_cfg_double(fleet, "vehicles", 1, 1e9, "(count)", &nv, err)) return WF_EINPUT;
    if (nv != floor(nv))
        return wf_err(err, WF_EINPUT, "%s: fleet.vehicles must be a whole number (got %.17g)",
                      where_of(wf_cfg_child(fleet, "vehicles"), w, sizeof w), nv);
    sc->n_vehicles = (long)nv;
    if (wf_cfg_enum_opt(fleet, "placement", places, &place, err)) return WF_EINPUT;
    sc->placement = (WfPlacement)place;
    if (load_classes(sc, fleet, err) || load_groups(sc, fleet, err)) return WF_EINPUT;
    if (sc->placement == WF_PLACE_EXPLICIT && check_partition(sc, err)) return WF_EINPUT;

    sc->perturb_vehicle = -1;
    if (wf_cfg_map_opt(root, "initial", &init, err)) return WF_EINPUT;
    if (init) {
        if (wf_cfg_enum_opt(init, "state", inits, &init_state, err)) return WF_EINPUT;
        if (wf_cfg_double_opt(init, "jitter_m", 0, 1e3, "m", &sc->jitter_m, err)) return WF_EINPUT;
        if (wf_cfg_map_opt(init, "perturbation", &pert, err)) return WF_EINPUT;
        if (pert) {
            sc->perturb_vehicle = 0;
            if (wf_cfg_long_opt(pert, "vehicle", 0, sc->n_vehicles - 1, &sc->perturb_vehicle, err)) return WF_EINPUT;
            if (wf_cfg_double_opt(pert, "dx_m", -1e3, 1e3, "m", &sc->perturb_dx_m, err)) return WF_EINPUT;
            if (wf_cfg_double_opt(pert, "dv_mps", -100, 100, "m/s", &sc->perturb_dv_mps, err)) return WF_EINPUT;
        }
    }
    sc->init_state = (WfInitState)init_state;

    sc->v_stop_mps = 0.5;
    sc->v_go_mps = 2.0;
    sc->hard_brake_mps2 = 1.0;
    sc->wave_speed_mps = NAN;
    if (wf_cfg_map_opt(root, "statistics", &stats, err)) return WF_EINPUT;
    if (stats) {
        if (wf_cfg_double_opt(stats, "v_stop_mps", 0, 50, "m/s", &sc->v_stop_mps, err)) return WF_EINPUT;
        if (wf_cfg_double_opt(stats, "v_go_mps", 0, 50, "m/s", &sc->v_go_mps, err)) return WF_EINPUT;
        if (wf_cfg_double_opt(stats, "hard_brake_mps2", 0.01, 20, "m/s^2", &sc->hard_brake_mps2, err))
            return WF_EINPUT;
        if (wf_cfg_double_opt(stats, "wave_speed_mps", 0, 100, "m/s", &sc->wave_speed_mps, err)) return WF_EINPUT;
    }
    if (!(sc->v_go_mps > sc->v_stop_mps))
        return wf_err(err, WF_EINPUT, "%s: statistics.v_go_mps (%.17g) must exceed statistics.v_stop_mps (%.17g)",
                      sc->path, sc->v_go_mps, sc->v_stop_mps);
    if (isnan(sc->wave_speed_mps)) sc->wave_speed_mps = sc->v_go_mps;

    snprintf(sc->output_path, sizeof sc->output_path, "output/%s.h5", sc->name);
    sc->trajectory_interval_s = sc->output_interval_s;
    if (wf_cfg_map_opt(root, "output", &out, err)) return WF_EINPUT;
    if (out) {
        s = NULL;
        if (wf_cfg_string_opt(out, "path", &s, err)) return WF_EINPUT;
        if (s) snprintf(sc->output_path, sizeof sc->output_path, "%s", s);
        if (wf_cfg_bool_opt(out, "trajectories", &sc->trajectories, err)) return WF_EINPUT;
        if (wf_cfg_double_opt(out, "trajectory_interval_s", 1e-6, 1e9, "s", &sc->trajectory_interval_s, err))
            return WF_EINPUT;
        double r2 = sc->trajectory_interval_s / sc->dt_s;
        if (fabs(r2 - round(r2)) > 1e-9 * r2)
            return wf_err(err, WF_EINPUT, "%s: output.trajectory_interval_s must be a whole multiple of time.dt_s",
                          sc->path);
    }

    if (rtype == 1) return wf_corridor_spec_load(sc, root, err) ? WF_EINPUT : wf_cfg_check_unused(cfg, err);

    /* The fleet must fit: total length plus each driver group's minimum standstill gap (its equilibrium gap at
     * v = 0 is not model-generic, so the fit check uses the vehicles' lengths; the engine checks gaps >= 0). */
    double total_len = 0.0;
    for (size_t c = 0; c < sc->n_classes; c++) total_len += (double)sc->classes[c].count * sc->classes[c].length_m;
    if (total_len >= sc->road.length_m)
        return wf_err(err, WF_EINPUT,
                      "%s: %ld vehicles of total length %.6g m cannot fit on a ring of road.length_m = %.6g m", sc->path,
                      sc->n_vehicles, total_len, sc->road.length_m);
    return wf_cfg_check_unused(cfg, err);
}

static int load_cfg(WfCfg *cfg, const char *path, const char *const *set, size_t n_set, WfScenario **out,
                    WfError *err);

int wf_scenario_load(const char *path, const char *const *set, size_t n_set, WfScenario **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_file(path, &cfg, err);
    return rc ? rc : load_cfg(cfg, path, set, n_set, out, err);
}

int wf_scenario_load_text(const char *path, const char *text, const char *const *set, size_t n_set,
                          WfScenario **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_string(path, text, strlen(text), &cfg, err);
    return rc ? rc : load_cfg(cfg, path, set, n_set, out, err);
}

/* Takes ownership of cfg. */
static int load_cfg(WfCfg *cfg, const char *path, const char *const *set, size_t n_set, WfScenario **out,
                    WfError *err)
{
    int rc = 0;
    WfScenario *sc = calloc(1, sizeof *sc);
    if (!sc) {
        wf_cfg_destroy(&cfg);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    snprintf(sc->path, sizeof sc->path, "%s", path);
    size_t olen = 1;
    for (size_t i = 0; i < n_set; i++) olen += strlen(set[i]) + 1;
    sc->overrides = calloc(olen, 1);
    sc->text = strdup(cfg->text);
    if (!sc->overrides || !sc->text) {
        rc = wf_err(err, WF_ESYS, "out of memory");
        goto fail;
    }
    for (size_t i = 0; i < n_set; i++) {
        strcat(sc->overrides, set[i]);
        strcat(sc->overrides, "\n");
        if ((rc = wf_cfg_set(cfg, set[i], err))) goto fail;
    }
    if ((rc = load_tree(sc, cfg, err))) goto fail;
    wf_cfg_destroy(&cfg);
    *out = sc;
    return 0;
fail:
    wf_cfg_destroy(&cfg);
    wf_scenario_destroy(&sc);
    return rc ? rc : WF_EINPUT;
}
