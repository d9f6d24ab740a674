/* The `fleet` section: its key tables (fleet, fleet.classes[i], fleet.drivers[i] with heterogeneity) and the
 * hooks that read what a table cannot: vehicle classes, driver models and their parameters, shares given as
 * fractions or counts, explicit placement. Keys, units and ranges: docs/scenarios.md (generated from the tables). */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scenario/scenario_keys.h"
#include "util/path.h"
#include "util/registry.h"
#include "wavefuel/cf_plugin.h"
#include "wavefuel/corridor.h"
#include "wavefuel/mlp.h"
#include "wavefuel/tabulated.h"
#include "util/numfmt.h"

#define where_of wf_scenario_where

_Static_assert(sizeof(WfPlacement) == sizeof(int) && sizeof(WfHetDist) == sizeof(int), "choice fields are ints");

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
            return wf_err(err, WF_EINPUT, "%s: expected an integer vehicle index (got %s)",
                          where_of(seq->child[k], w, sizeof w), WF_NUM(v));
        }
        idx[k] = (long)v;
    }
    *out = idx;
    *n_out = seq->n_child;
    return 0;
}

static int class_indices(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfClassShare *cs = t;
    return read_indices(e, env->sc->n_vehicles, &cs->indices, &cs->n_indices, err);
}

static int group_indices(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfDriverGroup *g = t;
    return read_indices(e, env->sc->n_vehicles, &g->indices, &g->n_indices, err);
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
        return wf_err(err, WF_EINPUT, "%s: %s fractions sum to %s, expected 1", where, what, WF_NUM(sum));
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

/* fleet.classes[i].class: a class name or file; sets the class's length as the default of length_m. */
static int load_class_name(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfScenario *sc = env->sc;
    WfClassShare *cs = t;
    size_t i = (size_t)(cs - sc->classes);
    const char *name = NULL;
    char w[1024];
    if (wf_cfg_string(e, "class", &name, err)) return WF_EINPUT;
    /* A class name is looked up in the class directories; a path (with a '/' or ending in .yaml, as
     * wf_vehicle_find tells them apart) resolves against the scenario's directory, like the scenario's other paths. */
    char path[2048];
    size_t nlen = strlen(name);
    int is_path = strchr(name, '/') || (nlen > 5 && !strcmp(name + nlen - 5, ".yaml"));
    if (is_path ? wf_path_relative_to(sc->path, name, path, sizeof path) : snprintf(path, sizeof path, "%s", name) < 0)
        return wf_err(err, WF_EINPUT, "%s: class path too long", where_of(wf_cfg_child(e, "class"), w, sizeof w));
    if (wf_vehicle_find(path, &cs->vc, err)) {
        wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(e, "class"), w, sizeof w));
        return WF_EINPUT;
    }
    sc->n_classes = i + 1;
    /* The class file and the table it names (tabulated model, or a table beside the polynomial) are inputs. */
    char table[4096];
    if (wf_scenario_add_input(sc, cs->vc.path, err) || wf_tabulated_class_table(&cs->vc, table, sizeof table, err) ||
        (table[0] && wf_scenario_add_input(sc, table, err)))
        return err->code;
    for (size_t k = 0; k < i; k++)
        if (strcmp(sc->classes[k].vc.path, cs->vc.path) == 0)
            return wf_err(err, WF_EINPUT, "%s: class '%s' listed twice", where_of(e, w, sizeof w), name);
    cs->length_m = cs->vc.length_m;
    return 0;
}

static const WfKeySpec class_rows[] = {
    {.key = "class", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED, .hook = load_class_name,
     .doc_type = "name or path",
     .doc = "a vehicle class: `vehicles/NAME.yaml` (or `$WAVEFUEL_VEHICLES`), or a path to a class file"},
    {.key = "length_m", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .flags = WF_KEY_PRESET,
     .offset = offsetof(WfClassShare, length_m), .min = 1, .max = 30, .unit = "m",
     .doc_default = "the class's `length_m`", .doc = "vehicle length"},
    {.key = "fraction", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfClassShare, fraction),
     .def = NAN, .min = 0, .max = 1, .unit = "(share of vehicles)", .doc_type = "1", .doc_default = "",
     .doc = "share of the fleet; all entries give fractions summing to 1 (±10⁻⁹), or all give counts"},
    {.key = "count", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfClassShare, count),
     .size = sizeof(long), .def = -1, .max_is = WF_BOUND_VEHICLES, .doc_default = "",
     .doc = "vehicles of the class; counts must sum to N"},
    {.key = "indices", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = class_indices,
     .doc_type = "list of integers", .doc_range = "[0, N)",
     .doc = "with `placement: explicit`: the vehicles of this class"},
};
const WfKeyTable wf_class_keys = {"fleet.classes[i]", class_rows, sizeof class_rows / sizeof *class_rows};

/* The share of one entry (class or driver group) under the placement rules, for resolve_counts: placed
 * explicitly (`listed`), its 'indices' list counts; otherwise exactly one of its 'fraction' (*frac) and 'count'
 * (*count) is given. `noun` names the entry in messages, `needs` what 'indices' needs. */
static int entry_share(WfCfgNode *e, int listed, const long *indices, size_t n_indices, const char *noun,
                       const char *needs, double *frac, long *count, WfError *err)
{
    char w[1024];
    if (listed) {
        if (!indices)
            return wf_err(err, WF_EINPUT, "%s: placement is explicit: list this %s's vehicles in 'indices'",
                          where_of(e, w, sizeof w), noun);
        *count = (long)n_indices;
    } else if (indices) {
        return wf_err(err, WF_EINPUT, "%s: 'indices' needs %s", where_of(e, w, sizeof w), needs);
    } else if (isnan(*frac) == (*count < 0)) {
        return wf_err(err, WF_EINPUT, "%s: give exactly one of 'fraction' or 'count'", where_of(e, w, sizeof w));
    }
    return 0;
}

/* A class placed explicitly has no fraction. */
static int class_share(const WfScenario *sc, WfCfgNode *e, void *entry, double *frac, long *count, WfError *err)
{
    const WfClassShare *cs = entry;
    int listed = sc->placement == WF_PLACE_EXPLICIT;
    *frac = listed ? NAN : cs->fraction;
    *count = cs->count;
    return entry_share(e, listed, cs->indices, cs->n_indices, "class", "fleet.placement: explicit", frac, count,
                       err);
}

_Static_assert(WF_CF_PLUGIN_MAX_PARAMS <= WF_MAX_MODEL_PARAMS, "a plugin's parameters must fit a driver group");

/* `model: mlp`: the network file named by `network`, relative to the scenario file (docs/controllers.md). */
static int load_group_network(WfCfgNode *e, WfDriverGroup *g, WfKeyEnv *env, WfError *err)
{
    const char *file = NULL;
    char path[2048], w[1024];
    WfCfgNode *nn = wf_cfg_child(e, "network");
    if (wf_cfg_child(e, "path"))
        return wf_err(err, WF_EINPUT, "%s: 'path' names a controller library (model: plugin); an mlp group names its "
                      "network file with 'network'", where_of(wf_cfg_child(e, "path"), w, sizeof w));
    if (wf_cfg_string(e, "network", &file, err)) return WF_EINPUT;
    if (wf_path_relative_to(env->sc->path, file, path, sizeof path))
        return wf_err(err, WF_EINPUT, "%s: network path too long", where_of(nn, w, sizeof w));
    if (wf_mlp_load(path, &g->mlp, err)) {
        wf_err_prefix(err, "%s: ", where_of(nn, w, sizeof w));
        return err->code;
    }
    if (wf_scenario_add_input(env->sc, path, err)) return WF_ESYS;
    g->model = wf_mlp_model(g->mlp);
    return 0;
}

/* A driver group's model: a registry name, `plugin` with `path` naming a shared library, or `mlp` with `network`
 * naming a network file. */
static int load_group_model(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfDriverGroup *g = t;
    const char *model = NULL;
    char w[1024];
    if (wf_cfg_string(e, "model", &model, err)) return WF_EINPUT;
    WfCfgNode *pn = wf_cfg_child(e, "path"), *nn = wf_cfg_child(e, "network");
    if (nn && strcmp(model, "mlp") != 0)
        return wf_err(err, WF_EINPUT, "%s: 'network' names a network file and needs model: mlp (model is '%s')",
                      where_of(nn, w, sizeof w), model);
    if (strcmp(model, "mlp") == 0) return load_group_network(e, g, env, err);
    if (strcmp(model, "plugin") == 0) {
        const char *lib = NULL;
        char path[2048];
        if (wf_cfg_string(e, "path", &lib, err)) return WF_EINPUT;
        if (wf_path_relative_to(env->sc->path, lib, path, sizeof path))
            return wf_err(err, WF_EINPUT, "%s: plugin path too long", where_of(pn, w, sizeof w));
        if (wf_cf_plugin_load(path, &g->plugin, err)) {
            wf_err_prefix(err, "%s: ", where_of(pn, w, sizeof w));
            return WF_EINPUT;
        }
        if (wf_scenario_add_input(env->sc, path, err)) return WF_ESYS;
        g->model = wf_cf_plugin_model(g->plugin);
        return 0;
    }
    if (pn)
        return wf_err(err, WF_EINPUT, "%s: 'path' names a controller library and needs model: plugin (model is '%s')",
                      where_of(pn, w, sizeof w), model);
    if (wf_cf_model_find(model, &g->model, err)) {
        char msg[sizeof err->msg];
        memcpy(msg, err->msg, sizeof msg);
        return wf_err(err, WF_EINPUT, "%s: %s, or 'plugin' with 'path: LIBRARY.so', or 'mlp' with 'network: "
                      "FILE.h5'", where_of(wf_cfg_child(e, "model"), w, sizeof w), msg);
    }
    return 0;
}

/* A group's own placement and class (automated vehicles placed apart from the fleet's rule). */
static int load_group_placement(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfScenario *sc = env->sc;
    WfDriverGroup *g = t;
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
        if (wf_cfg_enum_opt(e, "placement", row->choices, &p, err)) return WF_EINPUT;
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

/* The model's parameters from its own table (WfParamSpec), then its completeness and cross-field checks. */
static int load_group_params(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfDriverGroup *g = t;
    WfCfgNode *params = NULL;
    char w[1024], wh[1100];
    if (g->model->param_size > sizeof g->params)
        return wf_err(err, WF_ESYS, "model %s has too many parameters", g->model->name);
    if (wf_cfg_map_opt(e, "params", &params, err)) return WF_EINPUT;
    if (wf_cfg_params(params, g->model->spec, g->model->n_spec, g->params, err)) return WF_EINPUT;
    snprintf(wh, sizeof wh, "%s: ", where_of(e, w, sizeof w));
    if (wf_param_check_complete(g->model->spec, g->model->n_spec, g->params, wh, err)) return WF_EINPUT;
    if (g->model->check && g->model->check(g->params, err)) {
        wf_err_prefix(err, "%s", wh);
        return WF_EINPUT;
    }
    return 0;
}

/* The group's optional safety filter: `safety: {kind: NAME, KEY: VALUE...}`, the kind's keys from its own table
 * (WfParamSpec: defaults, ranges, unknown keys rejected by the loader's unused-key check). */
static int load_group_safety(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfDriverGroup *g = t;
    WfCfgNode *map = NULL;
    const char *kind = NULL;
    char w[1024];
    if (wf_cfg_map_opt(e, "safety", &map, err)) return WF_EINPUT;
    if (!map) return 0;
    if (!wf_cfg_child(map, "kind")) {
        char known[1024];
        wf_registry_names((const void *const *)wf_safety_kinds, offsetof(WfSafetyKind, name), known, sizeof known);
        return wf_err(err, WF_EINPUT, "%s: missing 'kind': the safety filter (%s)", where_of(map, w, sizeof w), known);
    }
    if (wf_cfg_string(map, "kind", &kind, err)) return WF_EINPUT;
    if (wf_safety_find(kind, &g->safety, err)) {
        wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(map, "kind"), w, sizeof w));
        return WF_EINPUT;
    }
    if (g->safety->param_size > sizeof g->safety_params)
        return wf_err(err, WF_ESYS, "safety filter %s has too many parameters", g->safety->name);
    if (wf_cfg_params(map, g->safety->spec, g->safety->n_spec, g->safety_params, err)) return WF_EINPUT;
    if (g->safety->check && g->safety->check(g->safety_params, err)) {
        wf_err_prefix(err, "%s: ", where_of(map, w, sizeof w));
        return WF_EINPUT;
    }
    return 0;
}

/* The group's lane-change model on a multi-lane ring: `lane_change: {model: NAME, KEY: VALUE...}` (the model's keys
 * from its own table), `lane_change: {model: none}` to never change lanes; absent: `mobil` with its defaults. */
static int load_group_lane_change(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfDriverGroup *g = t;
    WfCfgNode *map = NULL;
    const char *name = "mobil";
    char w[1024];
    if (wf_cfg_map_opt(e, "lane_change", &map, err)) return WF_EINPUT;
    if (map && wf_cfg_string(map, "model", &name, err)) return WF_EINPUT;
    g->lc = NULL;
    if (!strcmp(name, "none")) return 0;
    if (wf_lc_model_find(name, &g->lc, err)) {
        wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(map, "model"), w, sizeof w));
        return WF_EINPUT;
    }
    if (g->lc->param_size > sizeof g->lc_params)
        return wf_err(err, WF_ESYS, "lane-change model %s has too many parameters", g->lc->name);
    if (wf_cfg_params(map, g->lc->spec, g->lc->n_spec, g->lc_params, err)) return WF_EINPUT;
    if (g->lc->check && g->lc->check(g->lc_params, err)) {
        wf_err_prefix(err, "%s: ", where_of(map, w, sizeof w));
        return WF_EINPUT;
    }
    return 0;
}

/* fleet.lane_counts: the vehicles of each lane at the start, summing to fleet.vehicles; absent: as equal as
 * possible, the lower lanes taking the remainder. */
static int load_lane_counts(WfCfgNode *fleet, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfScenario *sc = t;
    WfCfgNode *seq = NULL;
    char w[1024];
    long L = sc->n_lanes, n = sc->n_vehicles, sum = 0;
    if (wf_cfg_seq_opt(fleet, "lane_counts", &seq, err)) return WF_EINPUT;
    if (!seq) {
        for (long l = 0; l < L; l++) sc->lane_counts[l] = n / L + (l < n % L);
        return 0;
    }
    if (seq->n_child != (size_t)L)
        return wf_err(err, WF_EINPUT, "%s: fleet.lane_counts lists %zu lanes but road.lanes is %ld",
                      where_of(seq, w, sizeof w), seq->n_child, L);
    for (long l = 0; l < L; l++) {
        double v;
        if (wf_cfg_node_double(seq->child[l], 0, (double)n, "(vehicles)", &v, err)) return WF_EINPUT;
        if (v != floor(v))
            return wf_err(err, WF_EINPUT, "%s: expected a whole number of vehicles (got %s)",
                          where_of(seq->child[l], w, sizeof w), WF_NUM(v));
        sc->lane_counts[l] = (long)v;
        sum += (long)v;
    }
    if (sum != n)
        return wf_err(err, WF_EINPUT, "%s: fleet.lane_counts sum to %ld but fleet.vehicles is %ld",
                      where_of(seq, w, sizeof w), sum, n);
    return 0;
}

/* heterogeneity.spread: one relative spread per key of the model's parameter table. */
static int load_spread(WfCfgNode *het, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)env;
    WfDriverGroup *g = t;
    WfCfgNode *spread = NULL;
    if (wf_cfg_map_opt(het, "spread", &spread, err)) return WF_EINPUT;
    for (size_t k = 0; spread && k < g->model->n_spec; k++)
        if (wf_cfg_double_opt(spread, g->model->spec[k].key, row->min, row->max, row->unit, &g->spread[k], err))
            return WF_EINPUT;
    return 0;
}

static const char *const fleet_places[] = {"random", "interleaved", "explicit", NULL};
static const char *const het_dists[] = {"normal", "uniform", NULL};
static const char *const feasible[] = {"none", "clip", NULL};

static const WfKeySpec het_rows[] = {
    {.key = "distribution", .type = WF_KEY_CHOICE, .on = WF_ON_BOTH, .offset = offsetof(WfDriverGroup, dist),
     .choices = het_dists, .doc = "per-vehicle draws around `params`"},
    {.key = "spread", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_spread, .min = 0, .max = 0.5,
     .unit = "(relative)", .doc_type = "map key → relative spread", .doc_default = "0", .doc_range = "[0, 0.5]",
     .doc = "normal: relative standard deviation, truncated at 2 s.d.; uniform: relative half-width. Draws out of the "
            "key's range or rejected by the model are redrawn"},
};
static const WfKeyTable het_keys = {"fleet.drivers[i].heterogeneity", het_rows, sizeof het_rows / sizeof *het_rows};

static const WfKeySpec driver_rows[] = {
    {.key = "name", .type = WF_KEY_TEXT, .on = WF_ON_BOTH, .flags = WF_KEY_PRESET,
     .offset = offsetof(WfDriverGroup, name), .size = sizeof(((WfDriverGroup *)0)->name), .doc_default = "`groupI`",
     .doc = "group name in the output"},
    {.key = "model", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED, .hook = load_group_model,
     .doc_type = "`idm`, `ovm`, `gipps`, `follower_stopper`, `pi_saturation`, `acc`, `external`, `external_speed`, "
                 "`plugin`, `mlp`",
     .doc = "car-following model ([models.md](models.md)) or automated-vehicle controller "
            "([controllers.md](controllers.md))"},
    {.key = "path", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_NOREAD, .doc_type = "path",
     .doc = "with `model: plugin` only: the controller's shared library, relative to the scenario file "
            "([controllers.md](controllers.md#plug-in-controllers))"},
    {.key = "network", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_NOREAD, .doc_type = "path",
     .doc = "with `model: mlp` only: the network file (HDF5), relative to the scenario file "
            "([controllers.md](controllers.md#mlp-learned-controllers))"},
    {.key = "placement", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_group_placement,
     .choices = fleet_places, .doc_default = "`fleet.placement`",
     .doc = "this group's own placement (automated vehicles), below"},
    {.key = "class", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_NOREAD, .doc_type = "class name",
     .doc_default = "any", .doc_range = "one of `fleet.classes`",
     .doc = "every vehicle of the group has this class (the AVs' energy class)"},
    {.key = "params", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_group_params, .doc_type = "map",
     .doc_default = "model defaults", .doc_range = "per model",
     .doc = "model parameters, keys and ranges in [models.md](models.md)"},
    {.key = "heterogeneity", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_FLAT, .sub = &het_keys},
    {.key = "noise_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfDriverGroup, noise_mps2),
     .def = 0, .min = 0, .max = 10, .unit = "m/s^2",
     .doc = "standard deviation of additive Gaussian acceleration noise, drawn independently for every vehicle and "
            "step, held constant over the step: Box–Muller on 53-bit uniforms from Random123 Philox4x32-10, the pair "
            "of vehicles (2p, 2p+1) of each block of 256 at a step keyed by (seed, block, step, p), so the draws do not "
            "depend on the thread count; the logarithm and sine/cosine come from SLEEF's consistent (no-FMA) "
            "functions, the same bits on every x86-64 vector extension (tests/test_rng.c checks moments, tails and a "
            "Kolmogorov–Smirnov test against Φ)"},
    {.key = "accel_max_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfDriverGroup, accel_max_mps2), .def = 5, .min = 0.1, .max = 20, .unit = "m/s^2",
     .doc = "comfortable acceleration limit"},
    {.key = "decel_max_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfDriverGroup, decel_max_mps2), .def = 9, .min = 0.1, .max = 20, .unit = "m/s^2",
     .doc = "emergency deceleration limit (positive number)"},
    {.key = "feasible_accel", .type = WF_KEY_CHOICE, .on = WF_ON_BOTH,
     .offset = offsetof(WfDriverGroup, clip_feasible), .choices = feasible,
     .doc = "`clip`: also limit a to the class energy model's a_max(v, θ)"},
    {.key = "safety", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_group_safety, .doc_type = "map",
     .doc_default = "none", .doc_range = "`kind`: `gipps`, `ttc`; keys per kind",
     .doc = "a safety filter after the controller: an upper bound on the acceleration, its interventions counted "
            "([controllers.md](controllers.md#safety-filters))"},
    {.key = "lane_change", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_group_lane_change,
     .doc_type = "map", .doc_default = "`model: mobil`", .doc_range = "`model`: `mobil`, `none`; keys per model",
     .doc = "how the group's vehicles change lanes on a multi-lane road; `none`: never ([lanes.md](lanes.md))"},
    {.key = "fraction", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfDriverGroup, fraction),
     .def = NAN, .min = 0, .max = 1, .unit = "(share of vehicles)", .doc_type = "1", .doc_default = "",
     .doc = "as for classes"},
    {.key = "count", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfDriverGroup, count),
     .size = sizeof(long), .def = -1, .max_is = WF_BOUND_VEHICLES, .doc_default = "", .doc = "as for classes"},
    {.key = "indices", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = group_indices,
     .doc_type = "list of integers", .doc_range = "[0, N)",
     .doc = "as for classes, with `placement: explicit` (the fleet's or the group's own)"},
};
const WfKeyTable wf_driver_keys = {"fleet.drivers[i]", driver_rows, sizeof driver_rows / sizeof *driver_rows};

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

/* A group's share under the placement rules (its own placement or the fleet's). */
static int group_share(const WfScenario *sc, WfCfgNode *e, void *entry, double *frac, long *count, WfError *err)
{
    const WfDriverGroup *g = entry;
    char w[1024];
    *frac = g->fraction;
    *count = g->count;
    if (g->placement == WF_PLACE_EXPLICIT && (!isnan(*frac) || *count >= 0))
        return wf_err(err, WF_EINPUT, "%s: placement is explicit: the group's size is its 'indices' list; drop "
                      "'fraction' and 'count'", where_of(e, w, sizeof w));
    return entry_share(e, sc->placement == WF_PLACE_EXPLICIT || g->placement == WF_PLACE_EXPLICIT, g->indices,
                       g->n_indices, "group", "placement: explicit (fleet.placement or the group's own)", frac, count,
                       err);
}

/* The two share lists of the fleet, classes and driver groups: each entry is a map read with `table`, then its
 * share (fraction or count) under the placement rules; resolve_counts turns the shares into counts. */
typedef struct ShareList {
    const char       *key, *need, *shape, *what, *many;
    size_t            max;
    const WfKeyTable *table;
    void *(*entry)(WfScenario *sc, size_t i); /* entry i's struct, its defaults set */
    int (*share)(const WfScenario *sc, WfCfgNode *e, void *entry, double *frac, long *count, WfError *err);
    void (*store)(WfScenario *sc, size_t i, double frac, long count);
} ShareList;

static int load_shares(WfCfgNode *fleet, const ShareList *l, WfScenario *sc, WfKeyEnv *env, WfCfgNode **out,
                       WfError *err)
{
    WfCfgNode *seq = NULL;
    char w[1024];
    if (wf_cfg_seq_opt(fleet, l->key, &seq, err)) return WF_EINPUT;
    if (!seq || seq->n_child == 0)
        return wf_err(err, WF_EINPUT, "%s: missing '%s': %s", where_of(fleet, w, sizeof w), l->key, l->need);
    if (seq->n_child > l->max)
        return wf_err(err, WF_EINPUT, "%s: at most %zu %s", where_of(seq, w, sizeof w), l->max, l->many);
    double frac[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    long count[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    int given[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    for (size_t i = 0; i < seq->n_child; i++) {
        WfCfgNode *e = seq->child[i];
        e->used = 1;
        if (e->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: expected a map %s", where_of(e, w, sizeof w), l->shape);
        void *entry = l->entry(sc, i);
        if (wf_keys_read(e, l->table, WF_KEYS_FIRST, entry, env, err) ||
            l->share(sc, e, entry, &frac[i], &count[i], err))
            return WF_EINPUT;
        given[i] = count[i] >= 0;
    }
    if (resolve_counts(l->what, seq->n_child, frac, count, given, sc->n_vehicles, where_of(seq, w, sizeof w), err))
        return WF_EINPUT;
    for (size_t i = 0; i < seq->n_child; i++) l->store(sc, i, frac[i], count[i]);
    *out = seq;
    return 0;
}

static void *class_entry(WfScenario *sc, size_t i) { return &sc->classes[i]; }
static void class_store(WfScenario *sc, size_t i, double frac, long count)
{
    sc->classes[i].fraction = frac, sc->classes[i].count = count;
}

static void *group_entry(WfScenario *sc, size_t i)
{
    sc->n_groups = i + 1;
    snprintf(sc->groups[i].name, sizeof sc->groups[i].name, "group%zu", i);
    return &sc->groups[i];
}
static void group_store(WfScenario *sc, size_t i, double frac, long count)
{
    sc->groups[i].fraction = frac, sc->groups[i].count = count;
}

static int load_classes(WfCfgNode *fleet, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    static const ShareList classes = {"classes", "a list of {class: NAME, fraction: F} entries",
                                      "{class: NAME, fraction: F}", "class", "classes", WF_MAX_CLASSES,
                                      &wf_class_keys, class_entry, class_share, class_store};
    WfCfgNode *seq = NULL;
    return load_shares(fleet, &classes, t, env, &seq, err);
}

static int load_groups(WfCfgNode *fleet, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    static const ShareList groups = {"drivers", "a list of driver groups {model: idm, fraction: 1, ...}",
                                     "{model: idm, ...}", "driver group", "driver groups", WF_MAX_GROUPS,
                                     &wf_driver_keys, group_entry, group_share, group_store};
    WfCfgNode *seq = NULL;
    char w[1024];
    if (load_shares(fleet, &groups, t, env, &seq, err)) return WF_EINPUT;
    return check_group_claims(t, where_of(seq, w, sizeof w), err);
}

/* Explicit placement: every vehicle index must be claimed exactly once among classes, and among groups. */
int wf_fleet_check_partition(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)root, (void)row, (void)env;
    const WfScenario *sc = t;
    if (sc->placement != WF_PLACE_EXPLICIT) return 0;
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

/* fleet.vehicles: a whole number (rings); corridors take theirs from the inflow. */
static int load_vehicles(WfCfgNode *fleet, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)env;
    WfScenario *sc = t;
    char w[1024];
    double nv;
    if (wf_cfg_double(fleet, row->key, row->min, row->max, row->unit, &nv, err)) return WF_EINPUT;
    if (nv != floor(nv))
        return wf_err(err, WF_EINPUT, "%s: fleet.vehicles must be a whole number (got %s)",
                      where_of(wf_cfg_child(fleet, "vehicles"), w, sizeof w), WF_NUM(nv));
    sc->n_vehicles = (long)nv;
    return 0;
}


static const WfKeySpec fleet_rows[] = {
    {.key = "vehicles", .type = WF_KEY_CUSTOM, .on = WF_ON_RING, .flags = WF_KEY_REQUIRED, .hook = load_vehicles,
     .min = 1, .max = 1e9, .unit = "(count)", .off_msg = "a corridor has no fixed fleet size: vehicles come from "
     "corridor.inflow", .doc_type = "integer", .doc_range = "≥ 1", .doc = "N"},
    {.key = "lane_counts", .type = WF_KEY_CUSTOM, .on = WF_ON_RING, .hook = load_lane_counts,
     .off_msg = "fleet.lane_counts applies to multi-lane rings", .doc_type = "list of integers",
     .doc_default = "equal shares", .doc_range = "one per lane, summing to N",
     .doc = "vehicles of each lane at the start: lane 0 holds vehicles 0, 1, … of the placement, lane 1 the next "
            "ones; each lane starts as a single-lane ring would (`initial`)"},
    {.key = "placement", .type = WF_KEY_CHOICE, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, placement),
     .choices = fleet_places,
     .doc = "how classes and driver groups are laid around the ring: shuffled by seed, spread evenly, or listed with "
            "`indices`"},
    {.key = "classes", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED, .hook = load_classes,
     .sub = &wf_class_keys, .doc_type = "list", .doc_range = "≤ 16 entries", .doc = "the energy-class mix (below)"},
    {.key = "drivers", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED, .hook = load_groups,
     .sub = &wf_driver_keys, .doc_type = "list", .doc_range = "≤ 16 entries", .doc = "driver groups (below)"},
};
const WfKeyTable wf_fleet_keys = {"fleet", fleet_rows, sizeof fleet_rows / sizeof *fleet_rows};
