/* Vehicle class files (vehicles/NAME.yaml): loading, validation, search path and fuel economy units. */
#include "wavefuel/vehicle.h"

#include <dirent.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "util/path.h"
#include "wavefuel/config.h"

const char *wf_duty_name(WfDuty d) { return d == WF_DUTY_HEAVY ? "heavy" : "light"; }
const char *wf_fuel_name(WfFuelType f) { return f == WF_FUEL_DIESEL ? "diesel" : "gasoline"; }

void wf_vehicle_free(WfVehicleClass *vc)
{
    if (!vc) return;
    if (vc->params && vc->model && vc->model->release) vc->model->release(vc->params);
    free(vc->params);
    vc->params = NULL;
}

static void stem_of(const char *path, char *out, size_t len)
{
    snprintf(out, len, "%s", wf_path_base(path));
    char *dot = strrchr(out, '.');
    if (dot && (strcmp(dot, ".yaml") == 0 || strcmp(dot, ".yml") == 0)) *dot = '\0';
}

/* Keys of `energy` that the model's table does not know. Checked right after the parameters are read, before
 * the completeness check: a misspelled key (c33 for c3) is then reported as itself, with a suggestion,
 * rather than as the missing key it was meant to be. */
static int unknown_energy_key(const WfCfgNode *energy, const WfEnergyModel *m, WfError *err)
{
    for (size_t i = 0; energy && i < energy->n_child; i++) {
        const WfCfgNode *c = energy->child[i];
        if (c->used) continue;
        char where[600];
        const char *best = wf_param_suggest(m->spec, m->n_spec, c->key);
        return wf_err(err, WF_EINPUT, "%s: unknown key '%s' in energy for model %s%s%s%s",
                      wf_cfg_where(c, where, sizeof where), c->key, m->name, best ? " (did you mean '" : "",
                      best ? best : "", best ? "'?)" : "");
    }
    return 0;
}

#define K(field, min, max, unit, flags, doc) {#field, offsetof(WfVehicleClass, field), NAN, min, max, unit, flags, doc}
/* The numeric top-level keys of a class file, in file order. None of them enters a fuel rate: the model's
 * parameters are under `energy` (tests/test_vehicle.c changes both masses and compares fuel bit for bit). */
const WfParamSpec wf_vehicle_keys[] = {
    K(mass_kg, 100, 100000, "kg", WF_PARAM_REQUIRED, "test mass stated in the release's model header"),
    K(paper_mass_kg, 100, 100000, "kg", WF_PARAM_OPTIONAL,
      "mass in the paper's Table 1, where it differs from the release's header"),
    K(length_m, 1, 30, "m", WF_PARAM_REQUIRED, "default vehicle length in simulations"),
    K(kw_per_gps, 1, 100, "kW/(g/s)", WF_PARAM_REQUIRED, "equivalent power per unit fuel rate"),
    K(fuel_density_g_per_l, 500, 1200, "g/L", WF_PARAM_OPTIONAL,
      "fuel density for L/100 km and mpg; default from the fuel type"),
};
#undef K
const size_t wf_vehicle_n_keys = sizeof wf_vehicle_keys / sizeof wf_vehicle_keys[0];

/* Required keys through the required-key getter (its message names a misspelt key beside the missing one);
 * optional ones stay NaN when absent. */
static int read_numeric_keys(WfCfgNode *root, WfVehicleClass *vc, WfError *err)
{
    for (size_t i = 0; i < wf_vehicle_n_keys; i++) {
        const WfParamSpec *k = &wf_vehicle_keys[i];
        double *out = wf_param_ptr(vc, k);
        *out = NAN;
        int rc = (k->flags & WF_PARAM_REQUIRED) ? wf_cfg_double(root, k->key, k->min, k->max, k->unit, out, err)
                                                : wf_cfg_double_opt(root, k->key, k->min, k->max, k->unit, out, err);
        if (rc) return rc;
    }
    return 0;
}

/* The class file's contents into vc (zeroed; name and path set); each error returned where it is found. */
static int read_class(WfCfg *cfg, const char *path, WfVehicleClass *vc, WfError *err)
{
    WfCfgNode *root = cfg->root, *energy = NULL, *source = NULL;
    const char *label = NULL, *model_name = "circles_polynomial";
    int duty = -1, fuel = -1, rc;
    static const char *const duties[] = {"light", "heavy", NULL};
    static const char *const fuels[] = {"gasoline", "diesel", NULL};

    if ((rc = wf_cfg_string(root, "name", &label, err))) return rc;
    snprintf(vc->label, sizeof vc->label, "%s", label);
    if ((rc = wf_cfg_enum_opt(root, "duty", duties, &duty, err)) ||
        (rc = wf_cfg_enum_opt(root, "fuel", fuels, &fuel, err)))
        return rc;
    if (duty < 0 || fuel < 0) {
        /* Absent: the required-key getter reports it with file:line, or names the misspelt key beside it. */
        const char *absent = NULL;
        rc = wf_cfg_string(root, duty < 0 ? "duty" : "fuel", &absent, err);
        return rc ? rc : wf_err(err, WF_EINPUT, "%s: missing key '%s'", path, duty < 0 ? "duty" : "fuel");
    }
    vc->duty = (WfDuty)duty;
    vc->fuel = (WfFuelType)fuel;
    if ((rc = read_numeric_keys(root, vc, err))) return rc;
    if (isnan(vc->fuel_density_g_per_l))
        vc->fuel_density_g_per_l =
            (fuel == WF_FUEL_DIESEL ? WF_DIESEL_G_PER_GAL : WF_GASOLINE_G_PER_GAL) / WF_L_PER_US_GAL;
    /* Provenance is documentation for people: accepted as free text, not interpreted. */
    if ((rc = wf_cfg_map_opt(root, "source", &source, err))) return rc;
    if (source) wf_cfg_mark_used(source);
    if ((rc = wf_cfg_string_opt(root, "energy_model", &model_name, err))) return rc;
    if ((rc = wf_energy_model_find(model_name, &vc->model, err))) {
        char model_at[1040];
        wf_err_prefix(err, "%s: energy_model: ", wf_cfg_where(wf_cfg_child(root, "energy_model"), model_at, sizeof model_at));
        return rc;
    }
    if ((rc = wf_cfg_map_opt(root, "energy", &energy, err))) return rc;
    if (!energy && vc->model->n_spec > 0) /* a tabulated model has no numeric parameters */
        return wf_err(err, WF_EINPUT, "%s: missing map 'energy' with the model parameters", path);
    if (!(vc->params = calloc(1, vc->model->param_size))) return wf_err(err, WF_ESYS, "out of memory");
    if ((rc = wf_cfg_params(energy, vc->model->spec, vc->model->n_spec, vc->params, err)) ||
        (rc = unknown_energy_key(energy, vc->model, err)))
        return rc;
    /* Whole-map errors (a required key absent, inconsistent keys) point at the line of `energy:`. */
    char where[1100], energy_at[1040];
    if (energy) wf_cfg_where(energy, energy_at, sizeof energy_at);
    else snprintf(energy_at, sizeof energy_at, "%s", path);
    snprintf(where, sizeof where, "%s: energy: ", energy_at);
    if ((rc = wf_param_check_complete(vc->model->spec, vc->model->n_spec, vc->params, where, err))) return rc;
    if (vc->model->check && (rc = vc->model->check(vc->params, err))) {
        wf_err_prefix(err, "%s: ", energy_at);
        return rc;
    }
    /* `table: FILE.h5`: the tabulated model's data (its load hook reads the key), or, beside an explicit
     * model, the class's tabulated twin that `wavefuel cycle --protocol` compares with (docs/cycles.md). */
    const char *table = NULL;
    if (vc->model->load) rc = vc->model->load(vc->params, path, root, err);
    else rc = wf_cfg_string_opt(root, "table", &table, err);
    if (rc) return rc;
    /* The duty declared must match the lower-bound keys given (light: v_c...; heavy: h0, h1). */
    if (vc->model == &wf_energy_circles) {
        const WfCirclesParams *cp = vc->params;
        int heavy_keys = isinf(cp->cut_v);
        char duty_at[1040];
        if (heavy_keys != (vc->duty == WF_DUTY_HEAVY))
            return wf_err(err, WF_EINPUT, "%s: duty is '%s' but energy gives the %s-duty keys",
                          wf_cfg_where(wf_cfg_child(root, "duty"), duty_at, sizeof duty_at), wf_duty_name(vc->duty),
                          heavy_keys ? "heavy" : "light");
    }
    return wf_cfg_check_unused(cfg, err);
}

int wf_vehicle_load(const char *path, WfVehicleClass *vc, WfError *err)
{
    memset(vc, 0, sizeof *vc);
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_file(path, &cfg, err);
    if (rc) return rc;
    stem_of(path, vc->name, sizeof vc->name);
    snprintf(vc->path, sizeof vc->path, "%s", path);
    if ((rc = read_class(cfg, path, vc, err))) wf_vehicle_free(vc);
    wf_cfg_destroy(&cfg);
    return rc;
}

/* The search path: set by the program (wf_vehicle_search_path_set), empty until then. Written only at start-up,
 * before any lookup (the header's contract), so lookups from several threads read it without a lock. */
static char search_path[WF_VEHICLE_PATH_MAX];

int wf_vehicle_search_path_set(const char *dirs, WfError *err)
{
    const char *d = dirs ? dirs : "";
    if (strlen(d) >= sizeof search_path)
        return wf_err(err, WF_EINPUT, "vehicle class search path longer than %zu bytes: %.60s...",
                      sizeof search_path - 1, d);
    memcpy(search_path, d, strlen(d) + 1);
    return 0;
}

const char *wf_vehicle_search_path(void) { return search_path; }

/* Calls fn(dir) for each directory of the search path, in order; stops at a non-zero return. */
static int for_each_dir(int (*fn)(const char *dir, void *ctx), void *ctx)
{
    char buf[WF_VEHICLE_PATH_MAX];
    memcpy(buf, search_path, sizeof buf);
    char *save = NULL;
    for (char *d = strtok_r(buf, ":", &save); d; d = strtok_r(NULL, ":", &save)) {
        int rc = fn(d, ctx);
        if (rc) return rc;
    }
    return 0;
}

typedef struct FindCtx {
    const char *name;
    char        found[PATH_MAX + 64];
} FindCtx;

static int find_in(const char *dir, void *vctx)
{
    FindCtx *c = vctx;
    snprintf(c->found, sizeof c->found, "%s/%s.yaml", dir, c->name);
    return access(c->found, R_OK) == 0 ? 1 : 0;
}

typedef struct NamesCtx {
    char   known[1024];
    size_t used;
} NamesCtx;

static int names_in(const char *dir, void *vctx)
{
    NamesCtx *c = vctx;
    DIR *d = opendir(dir);
    if (!d) return 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".yaml") != 0) continue;
        int w = snprintf(c->known + c->used, sizeof c->known - c->used, "%s%.*s", c->used ? ", " : "",
                         (int)(len - 5), e->d_name);
        if (w > 0 && (size_t)w < sizeof c->known - c->used) c->used += (size_t)w;
    }
    closedir(d);
    return 0;
}

int wf_vehicle_find(const char *name, WfVehicleClass *vc, WfError *err)
{
    size_t len = strlen(name);
    if (strchr(name, '/') || (len > 5 && strcmp(name + len - 5, ".yaml") == 0)) return wf_vehicle_load(name, vc, err);
    FindCtx c = {.name = name};
    if (for_each_dir(find_in, &c) == 1) return wf_vehicle_load(c.found, vc, err);
    /* Names from the file names alone: one broken class file must not hide the others from this message. */
    NamesCtx nc = {.used = 0};
    for_each_dir(names_in, &nc);
    return wf_err(err, WF_EINPUT,
                  "vehicle class '%s' not found in the class search path %s (known: %s)", name,
                  search_path[0] ? search_path : "(none set)", nc.used ? nc.known : "none");
}

typedef struct ListCtx {
    WfVehicleClass *v;
    size_t          n, cap;
    WfError        *err;
    int             rc;
} ListCtx;

static int list_in(const char *dir, void *vctx)
{
    ListCtx *c = vctx;
    DIR *d = opendir(dir);
    if (!d) return 0; /* a search-path entry that does not exist holds no classes */
    struct dirent *e;
    while (!c->rc && (e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".yaml") != 0) continue;
        char stem[256];
        stem_of(e->d_name, stem, sizeof stem);
        int dup = 0;
        for (size_t i = 0; i < c->n; i++) dup |= strcmp(c->v[i].name, stem) == 0;
        if (dup) continue;
        if (c->n == c->cap) {
            size_t cap = c->cap ? 2 * c->cap : 8;
            WfVehicleClass *p = realloc(c->v, cap * sizeof *p);
            if (!p) {
                c->rc = wf_err(c->err, WF_ESYS, "out of memory");
                break;
            }
            c->v = p;
            c->cap = cap;
        }
        char path[PATH_MAX + 300];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (!(c->rc = wf_vehicle_load(path, &c->v[c->n], c->err))) c->n++;
    }
    closedir(d);
    return c->rc != 0; /* 1 stops the search */
}

static int by_name(const void *a, const void *b)
{
    return strcmp(((const WfVehicleClass *)a)->name, ((const WfVehicleClass *)b)->name);
}

int wf_vehicle_list(WfVehicleClass **out, size_t *n, WfError *err)
{
    ListCtx c = {.err = err};
    for_each_dir(list_in, &c);
    if (c.rc) {
        for (size_t i = 0; i < c.n; i++) wf_vehicle_free(&c.v[i]);
        free(c.v);
        return c.rc;
    }
    if (c.n) qsort(c.v, c.n, sizeof *c.v, by_name);
    *out = c.v;
    *n = c.n;
    return 0;
}

double wf_l_per_100km(const WfVehicleClass *vc, double fuel_g, double dist_m)
{
    double litres = fuel_g / vc->fuel_density_g_per_l;
    return dist_m > 0 ? litres / (dist_m / 1e5) : INFINITY;
}

double wf_mpg(const WfVehicleClass *vc, double fuel_g, double dist_m)
{
    double gallons = fuel_g / vc->fuel_density_g_per_l / WF_L_PER_US_GAL;
    return gallons > 0 ? (dist_m / WF_M_PER_MILE) / gallons : 0.0;
}
