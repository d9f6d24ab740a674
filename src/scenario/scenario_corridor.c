/* Scenario keys of open corridors (`road.type: corridor`): the non-periodic grade or elevation profile, zones,
 * and the `corridor` section (inflow, outflow, detectors, Edie grid), read into a WfCorridorSpec. The ring loader
 * (src/scenario/scenario.c) reads everything else and calls wf_corridor_spec_load() before it rejects unread keys.
 * Every key is a row of the tables below (include/wavefuel/keys.h); docs/corridors.md shows them. */
#include "wavefuel/corridor.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scenario/scenario_keys.h"
#include "util/path.h"
#include "wavefuel/config.h"
#include "wavefuel/csv.h"
#include "util/numfmt.h"
#include "util/mem.h"

#define where_of wf_scenario_where

static void profile_free(WfProfile *p)
{
    WF_FREE(p->t, p->y, p->cum);
    memset(p, 0, sizeof *p);
}

void wf_corridor_spec_destroy(WfCorridorSpec **ps)
{
    if (!ps || !*ps) return;
    WfCorridorSpec *s = *ps;
    profile_free(&s->inflow_vph);
    profile_free(&s->leader_speed_mps);
    profile_free(&s->ramp_vph);
    WF_FREE(s->grade_x_m, s->grade_rad, s->elev_z_m, s);
    *ps = NULL;
}

int wf_scenario_pairs(WfScenario *sc, WfCfgNode *map, const WfPairCols *c, double **a_out, double **b_out,
                      size_t *n_out, char *where, size_t wlen, WfError *err)
{
    WfCfgNode *points = NULL;
    const char *csv = NULL;
    char w[1024];
    *a_out = *b_out = NULL;
    *n_out = 0;
    if (wf_cfg_seq_opt(map, "points", &points, err) || wf_cfg_string_opt(map, "csv", &csv, err)) return WF_EINPUT;
    if (!!points == !!csv) {
        char doc[200];
        snprintf(doc, sizeof doc, "a file with header %s,%s", c->name[0], c->name[1]);
        return wf_err(err, WF_EINPUT, "%s: give either 'points' (a list of [%s, %s]) or 'csv' (%s)",
                      where_of(map, w, sizeof w), c->name[0], c->name[1], c->csv_doc ? c->csv_doc : doc);
    }
    char path[2048];
    WfCsv t = {0};
    if (csv) {
        if (wf_path_relative_to(sc->path, csv, path, sizeof path))
            return wf_err(err, WF_EINPUT, "%s: path too long", where_of(wf_cfg_child(map, "csv"), w, sizeof w));
        if (snprintf(where, wlen, "%s", path) >= (int)wlen) where[wlen - 1] = '\0'; /* only for messages */
        if (wf_csv_read(path, 2, c->name, &t, err)) {
            wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(map, "csv"), w, sizeof w));
            return WF_EINPUT;
        }
        if (wf_scenario_add_input(sc, path, err)) {
            wf_csv_free(&t);
            return WF_ESYS;
        }
    } else {
        where_of(points, where, wlen);
    }
    size_t n = points ? points->n_child : t.n_rows;
    double *v[2] = {malloc((n + 1) * sizeof *v[0]), malloc((n + 1) * sizeof *v[1])};
    int rc = !v[0] || !v[1] ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t i = 0; !rc && i < n; i++) {
        WfCfgNode *p = points ? points->child[i] : NULL;
        if (p) p->used = 1;
        if (p && (p->kind != WF_CFG_SEQ || p->n_child != 2))
            rc = wf_err(err, WF_EINPUT, "%s: expected a pair [%s, %s]", where_of(p, w, sizeof w), c->name[0],
                        c->name[1]);
        for (int k = 0; !rc && k < 2; k++) {
            if (p) rc = wf_cfg_node_double(p->child[k], c->min[k], c->max[k], c->unit[k], &v[k][i], err);
            else v[k][i] = t.data[2 * i + (size_t)k];
            if (!p && c->csv_ranges && !(v[k][i] >= c->min[k] && v[k][i] <= c->max[k]))
                rc = wf_err(err, WF_EINPUT, "%s:%d: %s must be in [%s, %s] %s (got %s)", path, t.line[i], c->name[k],
                            WF_NUM(c->min[k]), WF_NUM(c->max[k]), c->unit[k], WF_NUM(v[k][i]));
        }
    }
    wf_csv_free(&t);
    if (rc) {
        free(v[0]);
        free(v[1]);
        return rc;
    }
    *a_out = v[0], *b_out = v[1], *n_out = n;
    return 0;
}

/* A profile from wf_scenario_pairs: at least one point, the first column increasing. The arrays are owned by the
 * caller. `where` receives the location of what was read, for later messages. */
static int read_pairs(WfScenario *sc, WfCfgNode *map, const WfPairCols *c, double **a_out, double **b_out,
                      size_t *n_out, char *where, size_t wlen, WfError *err)
{
    int rc = wf_scenario_pairs(sc, map, c, a_out, b_out, n_out, where, wlen, err);
    const double *a = *a_out;
    size_t n = *n_out;
    if (!rc && n == 0) rc = wf_err(err, WF_EINPUT, "%s: no points", where);
    for (size_t i = 1; !rc && i < n; i++)
        if (!(a[i] > a[i - 1]))
            rc = wf_err(err, WF_EINPUT, "%s: point %zu: %s must increase (got %s after %s)", where, i, c->name[0],
                        WF_NUM(a[i]), WF_NUM(a[i - 1]));
    if (rc) {
        free(*a_out);
        free(*b_out);
        *a_out = *b_out = NULL;
        *n_out = 0;
    }
    return rc;
}

/* A time profile: `KEY: value` (constant) or `csv: FILE` with header time_s,NAME, points linear in between. */
static int read_profile(WfScenario *sc, WfCfgNode *map, const char *key, const char *col, double max,
                        const char *unit, int required, WfProfile *p, WfError *err)
{
    char w[1024];
    WfCfgNode *k = wf_cfg_child(map, key), *c = wf_cfg_child(map, "csv");
    if (!c) c = wf_cfg_child(map, "points");
    if (k && c)
        return wf_err(err, WF_EINPUT, "%s: give either '%s' (a constant) or 'csv' / 'points' (time_s,%s), not both",
                      where_of(map, w, sizeof w), key, col);
    if (!k && !c) {
        if (!required) return 0;
        char what[200];
        snprintf(what, sizeof what, "a number in %s, or 'csv' with columns time_s,%s", unit, col);
        return wf_cfg_missing(map, key, what, err);
    }
    if (k) {
        double v;
        if (wf_cfg_double(map, key, 0, max, unit, &v, err)) return WF_EINPUT;
        p->t = malloc(sizeof *p->t);
        p->y = malloc(sizeof *p->y);
        p->cum = malloc(sizeof *p->cum);
        if (!p->t || !p->y || !p->cum) return wf_err(err, WF_ESYS, "out of memory");
        p->n = 1, p->t[0] = 0.0, p->y[0] = v, p->cum[0] = 0.0;
        return 0;
    }
    const WfPairCols cols = {{"time_s", col}, {"s", unit}, {0, 0}, {1e9, max}, .csv_ranges = 1};
    char where[1024];
    if (read_pairs(sc, map, &cols, &p->t, &p->y, &p->n, where, sizeof where, err)) return WF_EINPUT;
    p->cum = malloc(p->n * sizeof *p->cum);
    if (!p->cum) return wf_err(err, WF_ESYS, "out of memory");
    p->cum[0] = 0.0;
    /* Trapezoids: exact for the piecewise-linear profile. */
    for (size_t i = 1; i < p->n; i++) p->cum[i] = p->cum[i - 1] + 0.5 * (p->y[i] + p->y[i - 1]) * (p->t[i] - p->t[i - 1]);
    return 0;
}

/* road.grade of a corridor: only checked to be a map here; road.elevation (the next row) reads either. */
int wf_corridor_road_grade(WfCfgNode *road, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)t, (void)env;
    WfCfgNode *grade = NULL;
    return wf_cfg_map_opt(road, "grade", &grade, err);
}

/* theta of an elevation profile: on [x_i, x_{i+1}) the angle of the straight segment, atan(dz / dx). */
static int elevation_to_grade(WfCorridorSpec *cs, double *x, double *z, size_t n, const char *where, WfError *err)
{
    double *th = n >= 2 ? malloc(n * sizeof *th) : NULL;
    int rc = n < 2 ? wf_err(err, WF_EINPUT, "%s: an elevation profile needs at least two points", where)
                   : !th ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t i = 0; !rc && i + 1 < n; i++) {
        th[i] = atan((z[i + 1] - z[i]) / (x[i + 1] - x[i]));
        if (fabs(th[i]) > 0.2)
            rc = wf_err(err, WF_EINPUT, "%s: segment %zu climbs at %.6g rad; grades beyond 0.2 rad are outside the "
                        "energy models' range", where, i, th[i]);
    }
    if (rc) {
        free(x), free(z), free(th);
        return rc;
    }
    th[n - 1] = 0.0; /* beyond the last point the road is flat */
    cs->grade_x_m = x, cs->grade_rad = th, cs->elev_z_m = z, cs->n_grade = n, cs->grade_steps = 1;
    return 0;
}

int wf_corridor_road_elevation(WfCfgNode *road, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfScenario *sc = t;
    WfCorridorSpec *cs = sc->corridor;
    WfCfgNode *grade = wf_cfg_child(road, "grade"), *elev = NULL;
    char w[1024], where[1024];
    double L = sc->road.length_m;
    if (wf_cfg_map_opt(road, "elevation", &elev, err)) return WF_EINPUT;
    if (grade && elev)
        return wf_err(err, WF_EINPUT, "%s: give either road.grade or road.elevation, not both",
                      where_of(elev, w, sizeof w));
    if (grade) {
        const WfPairCols cols = {{"x_m", "grade_rad"}, {"m", "rad"}, {0, -0.2}, {L, 0.2}, .csv_ranges = 1};
        return read_pairs(sc, grade, &cols, &cs->grade_x_m, &cs->grade_rad, &cs->n_grade, where, sizeof where, err);
    }
    if (!elev) return 0;
    const WfPairCols cols = {{"x_m", "z_m"}, {"m", "m"}, {0, -1e4}, {L, 1e4}, .csv_ranges = 1};
    double *x = NULL, *z = NULL;
    size_t n = 0;
    if (read_pairs(sc, elev, &cols, &x, &z, &n, where, sizeof where, err)) return WF_EINPUT;
    return elevation_to_grade(cs, x, z, n, where, err);
}

static const char *const zone_types[] = {"speed_limit", "headway", NULL};

/* road.zones[i].lanes: the lanes a zone applies to (their range is checked with the corridor's lanes, in
 * load_lane_drops). */
static int load_zone_lanes(WfCfgNode *e, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)env;
    WfCorridorZone *z = t;
    WfCfgNode *seq = NULL;
    char w[1024];
    z->lane_mask = 0;
    if (wf_cfg_seq_opt(e, row->key, &seq, err)) return WF_EINPUT;
    if (!seq) return 0;
    if (!seq->n_child)
        return wf_err(err, WF_EINPUT, "%s: road.zones[i].lanes: expected at least one lane (or no `lanes` key: every "
                      "lane)", wf_scenario_where(seq, w, sizeof w));
    for (size_t k = 0; k < seq->n_child; k++) {
        double lane;
        if (wf_cfg_node_double(seq->child[k], 0, WF_MAX_LANES - 1, "(lane)", &lane, err)) return WF_EINPUT;
        if (lane != floor(lane) || (z->lane_mask >> (int)lane & 1u))
            return wf_err(err, WF_EINPUT, "%s: road.zones[i].lanes: expected whole lane numbers, each once (got %s)",
                          wf_scenario_where(seq->child[k], w, sizeof w), WF_NUM(lane));
        z->lane_mask |= 1u << (int)lane;
    }
    return 0;
}

static const WfKeySpec zone_rows[] = {
    {.key = "type", .type = WF_KEY_CHOICE, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorZone, type), .choices = zone_types, .need = "speed_limit or headway",
     .doc = "what the zone changes: the speed limit, or the drivers' time headway"},
    {.key = "from_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorZone, from_m), .min = 0, .max_is = WF_BOUND_LENGTH, .unit = "m",
     .doc = "the zone is [from, to)"},
    {.key = "to_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorZone, to_m), .min = 0, .max_is = WF_BOUND_LENGTH, .unit = "m",
     .doc_range = "[0, L], to > from", .doc = "the zone's end"},
    {.key = "speed_limit_mps", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED | WF_KEY_NOREAD,
     .offset = offsetof(WfCorridorZone, value), .min = 0.1, .max = 100, .unit = "m/s",
     .doc_default = "required (speed_limit)", .doc = "the limit inside the zone (overlapping zones: the lowest)"},
    {.key = "factor", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED | WF_KEY_NOREAD,
     .offset = offsetof(WfCorridorZone, value), .min = 0.1, .max = 10, .unit = "(multiplies the headway parameter)",
     .doc_type = "1", .doc_default = "required (headway)",
     .doc = "multiplies the driver-model parameter `key` inside the zone (a lane-drop-like capacity reduction); "
            "overlapping zones multiply"},
    {.key = "key", .type = WF_KEY_TEXT, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD, .doc_default = "`T_s`",
     .doc_range = "a parameter of at least one driver group's model",
     .doc = "the time-headway parameter (IDM, ACC: `T_s`; Gipps: `tau_s`). Groups whose model lacks it are "
            "unaffected; a key no group has is an error"},
    {.key = "lanes", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_zone_lanes,
     .doc_type = "list of lanes", .doc_default = "every lane", .doc_range = "lane numbers of the road, each once",
     .doc = "the lanes the zone applies to, numbered as `corridor.lane_drops` numbers them (the on-ramp's merge "
            "lane 0 when there is one) ([lanes.md](lanes.md))"},
};
const WfKeyTable wf_corridor_zone_keys = {"road.zones[i]", zone_rows, sizeof zone_rows / sizeof *zone_rows};

_Static_assert(sizeof(WfZoneType) == sizeof(int) && sizeof(WfArrivals) == sizeof(int) &&
               sizeof(WfOutflow) == sizeof(int), "choice fields are ints");

/* A headway zone: its factor and the driver parameter it multiplies, which some group's model must have. */
static int headway_zone(WfScenario *sc, WfCfgNode *e, WfCorridorZone *z, WfKeyEnv *env, WfError *err)
{
    const char *key = "T_s";
    char w[1024];
    if (wf_key_read(e, wf_keys_find(&wf_corridor_zone_keys, "factor", WF_ON_CORRIDOR), z, env, err) ||
        wf_cfg_string_opt(e, "key", &key, err))
        return WF_EINPUT;
    if (strlen(key) >= sizeof z->key)
        return wf_err(err, WF_EINPUT, "%s: key '%s' too long", where_of(e, w, sizeof w), key);
    snprintf(z->key, sizeof z->key, "%s", key);
    /* A zone that no driver can feel is a mistake in the scenario, not something to ignore. */
    int any = 0;
    for (size_t g = 0; g < sc->n_groups; g++)
        any |= wf_param_find(sc->groups[g].model->spec, sc->groups[g].model->n_spec, key) != NULL;
    if (!any)
        return wf_err(err, WF_EINPUT, "%s: no driver group's model has a parameter '%s' to multiply (IDM and "
                      "ACC: T_s; Gipps: tau_s)", where_of(e, w, sizeof w), key);
    return 0;
}

int wf_corridor_road_zones(WfCfgNode *road, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfScenario *sc = t;
    WfCorridorSpec *cs = sc->corridor;
    WfCfgNode *seq = NULL;
    char w[1024];
    if (wf_cfg_seq_opt(road, "zones", &seq, err)) return WF_EINPUT;
    if (!seq) return 0;
    if (seq->n_child > WF_CORRIDOR_MAX_ZONES)
        return wf_err(err, WF_EINPUT, "%s: at most %d zones", where_of(seq, w, sizeof w), WF_CORRIDOR_MAX_ZONES);
    for (size_t i = 0; i < seq->n_child; i++) {
        WfCfgNode *e = seq->child[i];
        WfCorridorZone *z = &cs->zones[i];
        e->used = 1;
        if (e->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: expected a map {type: speed_limit, from_m: A, to_m: B, "
                          "speed_limit_mps: V}", where_of(e, w, sizeof w));
        if (wf_keys_read(e, &wf_corridor_zone_keys, WF_KEYS_FIRST, z, env, err)) return WF_EINPUT;
        if (!(z->to_m > z->from_m))
            return wf_err(err, WF_EINPUT, "%s: to_m (%s) must exceed from_m (%s)", where_of(e, w, sizeof w),
                          WF_NUM(z->to_m), WF_NUM(z->from_m));
        if (z->type == WF_ZONE_SPEED_LIMIT
                ? wf_key_read(e, wf_keys_find(&wf_corridor_zone_keys, "speed_limit_mps", WF_ON_CORRIDOR), z, env, err)
                : headway_zone(sc, e, z, env, err))
            return WF_EINPUT;
        cs->n_zones = i + 1;
    }
    return 0;
}

/* What the ring loader read, checked against corridor semantics (fleet.vehicles and `initial` are rejected by
 * their rows' off_msg). */
static int check_fleet(WfScenario *sc, WfCorridorSpec *cs, WfError *err)
{
    if (sc->adaptive)
        return wf_err(err, WF_EINPUT, "%s: corridors run with the fixed-step integrators (ballistic, euler), not '%s'",
                      sc->path, sc->integrator);
    if (sc->placement == WF_PLACE_EXPLICIT)
        return wf_err(err, WF_EINPUT, "%s: fleet.placement explicit lists vehicles of a ring; a corridor draws each "
                      "entering vehicle's class and group (random) or assigns them by share (interleaved)", sc->path);
    cs->interleaved = sc->placement == WF_PLACE_INTERLEAVED;
    for (size_t c = 0; c < sc->n_classes; c++)
        if (isnan(sc->classes[c].fraction))
            return wf_err(err, WF_EINPUT, "%s: fleet.classes[%zu]: a corridor's class mix is given by 'fraction' "
                          "(shares of the entering vehicles), not 'count'", sc->path, c);
    for (size_t g = 0; g < sc->n_groups; g++) {
        if (isnan(sc->groups[g].fraction))
            return wf_err(err, WF_EINPUT, "%s: fleet.drivers[%zu]: a corridor's driver mix is given by 'fraction', "
                          "not 'count'", sc->path, g);
        if (sc->groups[g].placement >= 0)
            return wf_err(err, WF_EINPUT, "%s: fleet.drivers[%zu]: a group's own 'placement' applies to rings; in a "
                          "corridor the group is drawn at entry with its fraction", sc->path, g);
    }
    /* Groups that fix a class take that much of its share. */
    for (size_t c = 0; c < sc->n_classes; c++) {
        double need = 0.0;
        for (size_t g = 0; g < sc->n_groups; g++) need += sc->groups[g].class_index == (int)c ? sc->groups[g].fraction : 0.0;
        if (need > sc->classes[c].fraction + 1e-9)
            return wf_err(err, WF_EINPUT, "%s: driver groups with class %s take %.6g of the vehicles but the class's "
                          "fraction is %.6g", sc->path, sc->classes[c].vc.name, need, sc->classes[c].fraction);
    }
    return 0;
}

/* A period that must be a whole number of time steps. */
static int whole_steps(const WfScenario *sc, WfCfgNode *map, const char *key, double v, WfError *err)
{
    double r = v / sc->dt_s;
    char w[1024];
    if (fabs(r - round(r)) > 1e-9 * r || round(r) < 1)
        return wf_err(err, WF_EINPUT, "%s: %s (%s s) must be a whole multiple of time.dt_s (%s s)",
                      where_of(wf_cfg_child(map, key) ? wf_cfg_child(map, key) : map, w, sizeof w), key, WF_NUM(v),
                      WF_NUM(sc->dt_s));
    return 0;
}

/* A constant or a time profile (read_profile) with the range of its row. */
static int profile_row(WfCfgNode *map, const WfKeySpec *row, WfKeyEnv *env, WfProfile *p, WfError *err)
{
    double lo, hi;
    wf_key_range(row, env, &lo, &hi);
    return read_profile(env->sc, map, row->key, row->key, hi, row->unit, 1, p, err);
}

static int load_inflow(WfCfgNode *in, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    return profile_row(in, row, env, &((WfCorridorSpec *)t)->inflow_vph, err);
}

static const WfKeyTable outflow_keys;

/* corridor.on_ramp's demand (read only when the section is there). */
static int load_ramp_flow(WfCfgNode *ramp, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    if (!ramp) return 0;
    return profile_row(ramp, row, env, &((WfCorridorSpec *)t)->ramp_vph, err);
}

/* corridor.on_ramp: a merge lane inside the road, lane 0 beside lanes 1 .. road.lanes (at most WF_MAX_LANES in all). */
static int check_ramp(WfCfgNode *corr, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    WfCfgNode *ramp = wf_cfg_child(corr, row->key);
    char w[1024];
    if (!ramp) return 0;
    double L = env->sc->road.length_m;
    cs->has_ramp = 1;
    if (!(cs->ramp_from_m >= 0.0 && cs->ramp_from_m < cs->ramp_to_m && cs->ramp_to_m < L))
        return wf_err(err, WF_EINPUT, "%s: corridor.on_ramp: the merge lane [%s, %s] m must lie inside the road "
                      "[0, %s) m with start_m < end_m", wf_scenario_where(ramp, w, sizeof w), WF_NUM(cs->ramp_from_m),
                      WF_NUM(cs->ramp_to_m), WF_NUM(L));
    if (env->sc->n_lanes + 1 > WF_MAX_LANES)
        return wf_err(err, WF_EINPUT, "%s: corridor.on_ramp adds lane 0 to road.lanes = %d: at most %d lanes in all",
                      wf_scenario_where(ramp, w, sizeof w), env->sc->n_lanes, WF_MAX_LANES);
    return 0;
}

/* The road's per-lane keys against the corridor's lanes (known once corridor.on_ramp is read): the zones' lanes
 * in range, and one speed limit per lane (load_lane_limits leaves NaN after the listed ones). */
static int check_lane_keys(WfScenario *sc, int nl, WfError *err)
{
    const WfCorridorSpec *cs = sc->corridor;
    for (size_t z = 0; z < cs->n_zones; z++)
        if (cs->zones[z].lane_mask >> nl)
            return wf_err(err, WF_EINPUT, "%s: road.zones[%zu].lanes: the road has lanes 0 to %d (the on-ramp's merge "
                          "lane counts as lane 0)", sc->path, z, nl - 1);
    int given = 0;
    while (given < WF_MAX_LANES && !isnan(sc->lane_speed_limit_mps[given])) given++;
    if (given < WF_MAX_LANES && given != nl)
        return wf_err(err, WF_EINPUT, "%s: road.lane_speed_limits_mps lists %d lanes but the corridor has %d (road.lanes"
                      "%s)", sc->path, given, nl, cs->has_ramp ? " and the on-ramp's merge lane 0" : "");
    for (int l = given; l < WF_MAX_LANES; l++) sc->lane_speed_limit_mps[l] = sc->road.speed_limit_mps;
    return 0;
}

/* corridor.lane_drops: [{lane: K, at_m: X}, ...]: lane K (numbered with the merge lane, when there is one) ends at X;
 * some lane must reach the exit, and the merge lane ends where the ramp says. */
static int load_lane_drops(WfCfgNode *corr, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    WfCfgNode *seq = NULL;
    char w[1024];
    int nl = (env->sc->n_lanes > 1 ? env->sc->n_lanes : 1) + cs->has_ramp, through = 0;
    double L = env->sc->road.length_m;
    for (int l = 0; l < WF_MAX_LANES; l++) cs->lane_end_m[l] = INFINITY;
    if (cs->has_ramp) cs->lane_end_m[0] = cs->ramp_to_m;
    if (wf_cfg_seq_opt(corr, row->key, &seq, err)) return WF_EINPUT;
    for (size_t k = 0; seq && k < seq->n_child; k++) {
        WfCfgNode *e = seq->child[k];
        double lane, at;
        e->used = 1;
        if (e->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "%s: expected a map {lane: K, at_m: X}", wf_scenario_where(e, w, sizeof w));
        if (wf_cfg_double(e, "lane", cs->has_ramp, nl - 1, "(lane)", &lane, err) ||
            wf_cfg_double(e, "at_m", 1e-3, L, "m", &at, err))
            return WF_EINPUT;
        if (lane != floor(lane))
            return wf_err(err, WF_EINPUT, "%s: corridor.lane_drops[%zu].lane: expected a whole lane number (got %s)",
                          wf_scenario_where(e, w, sizeof w), k, WF_NUM(lane));
        if (isfinite(cs->lane_end_m[(int)lane]))
            return wf_err(err, WF_EINPUT, "%s: corridor.lane_drops[%zu]: lane %d already ends", wf_scenario_where(e, w, sizeof w),
                          k, (int)lane);
        cs->lane_end_m[(int)lane] = at;
    }
    for (int l = 0; l < nl; l++) through += !isfinite(cs->lane_end_m[l]);
    if (!through)
        return wf_err(err, WF_EINPUT, "%s: corridor.lane_drops: every lane ends before the exit: at least one must reach "
                      "x = L", seq ? wf_scenario_where(seq, w, sizeof w) : env->sc->path);
    return check_lane_keys(env->sc, nl, err);
}

/* The virtual leader's speed and start: only for the leader and speed outflows. */
static int load_outflow_speed(WfCfgNode *outf, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    if (cs->outflow == WF_OUTFLOW_FREE) return 0;
    if (profile_row(outf, row, env, &cs->leader_speed_mps, err)) return WF_EINPUT;
    return wf_key_read(outf, wf_keys_find(&outflow_keys, "offset_m", WF_ON_CORRIDOR), t, env, err);
}

/* Detector positions: before the exit, at most WF_CORRIDOR_MAX_DETECTORS. */
static int load_detectors(WfCfgNode *det, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfCorridorSpec *cs = t;
    WfCfgNode *xs = NULL;
    char w[1024];
    double L = env->sc->road.length_m;
    if (wf_cfg_seq_opt(det, "x_m", &xs, err)) return WF_EINPUT;
    if (!xs) return wf_cfg_missing(det, "x_m", "a list of positions in m", err);
    if (xs->n_child > WF_CORRIDOR_MAX_DETECTORS)
        return wf_err(err, WF_EINPUT, "%s: at most %d detectors", where_of(xs, w, sizeof w), WF_CORRIDOR_MAX_DETECTORS);
    for (size_t i = 0; i < xs->n_child; i++) {
        if (wf_cfg_node_double(xs->child[i], 0, L, "m", &cs->det_x_m[i], err)) return WF_EINPUT;
        /* A passage is x_before <= x_d < x_after, and vehicles leave once x >= L: x_d = L would miss some. */
        if (!(cs->det_x_m[i] < L))
            return wf_err(err, WF_EINPUT, "%s: a detector must lie before the exit, in [0, %s) m",
                          where_of(xs->child[i], w, sizeof w), WF_NUM(L));
    }
    cs->n_det = xs->n_child;
    return 0;
}

static int check_detectors(WfCfgNode *corr, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCfgNode *det = wf_cfg_child(corr, row->key);
    return det ? whole_steps(env->sc, det, "interval_s", ((WfCorridorSpec *)t)->det_interval_s, err) : 0;
}

/* Edie's grid: cells of dx by dt (defaults: 100 m and 60 s, at most the road and the run), whole steps. */
static int check_edie(WfCfgNode *corr, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    const WfScenario *sc = env->sc;
    WfCfgNode *edie = wf_cfg_child(corr, row->key);
    double L = sc->road.length_m;
    if (isnan(cs->edie_dx_m)) cs->edie_dx_m = 100.0 < L ? 100.0 : L;
    if (isnan(cs->edie_dt_s)) cs->edie_dt_s = 60.0 < sc->duration_s ? 60.0 : sc->duration_s;
    if (whole_steps(sc, edie ? edie : corr, "dt_s", cs->edie_dt_s, err)) {
        wf_err_prefix(err, "corridor.edie: ");
        return WF_EINPUT;
    }
    double cells = ceil(L / cs->edie_dx_m - 1e-9) * ceil(sc->duration_s / cs->edie_dt_s - 1e-9);
    if (cells > 5e7)
        return wf_err(err, WF_EINPUT, "%s: the Edie grid has %.3g cells (more than 5e7): raise corridor.edie.dx_m or "
                      "dt_s", sc->path, cells);
    return 0;
}

/* corridor.inflow.lane_shares: each lane's share of the demand, summing to 1 (road.lanes is read before it);
 * absent: equal shares. */
static int load_lane_shares(WfCfgNode *in, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    int nl = env->sc->n_lanes > 1 ? env->sc->n_lanes : 1;
    WfCfgNode *seq = NULL;
    char w[1024];
    for (int l = 0; l < nl; l++) cs->lane_share[l] = 1.0 / nl;
    if (wf_cfg_seq_opt(in, row->key, &seq, err)) return WF_EINPUT;
    if (!seq) return 0;
    if (seq->n_child != (size_t)nl)
        return wf_err(err, WF_EINPUT, "%s: corridor.inflow.lane_shares lists %zu lanes but road.lanes is %d",
                      wf_scenario_where(seq, w, sizeof w), seq->n_child, nl);
    double sum = 0.0;
    for (int l = 0; l < nl; l++) {
        if (wf_cfg_node_double(seq->child[l], row->min, row->max, row->unit, &cs->lane_share[l], err)) return WF_EINPUT;
        sum += cs->lane_share[l];
    }
    if (fabs(sum - 1.0) > 1e-9)
        return wf_err(err, WF_EINPUT, "%s: corridor.inflow.lane_shares sum to %s, expected 1",
                      wf_scenario_where(seq, w, sizeof w), WF_NUM(sum));
    return 0;
}

static const char *const arrivals[] = {"deterministic", "poisson", NULL};
static const char *const outflows[] = {"free", "leader", "speed", NULL};

static const WfKeySpec inflow_rows[] = {
    {.key = "arrivals", .type = WF_KEY_CHOICE, .on = WF_ON_CORRIDOR, .offset = offsetof(WfCorridorSpec, arrivals),
     .choices = arrivals, .doc = "below"},
    {.key = "flow_vph", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_inflow, .max = 36000,
     .unit = "veh/h", .doc_type = "veh/h", .doc_default = "required (or `csv`/`points`)", .doc_range = "[0, 36000]",
     .doc = "constant demand at the entrance"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "CSV `time_s,flow_vph`", .doc_range = "t increasing",
     .doc = "time-varying demand, linear between points, end values held"},
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[t, q]`", .doc_range = "t increasing", .doc = "the same as a list"},
    {.key = "entry_speed_mps", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR,
     .offset = offsetof(WfCorridorSpec, entry_speed_mps), .def = INFINITY, .min = 0, .max = 100, .unit = "m/s",
     .doc = "cap on the entry speed"},
    {.key = "insert_decel_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR,
     .offset = offsetof(WfCorridorSpec, insert_decel_mps2), .def = 0.3, .min = 0.01, .max = 20, .unit = "m/s^2",
     .doc = "b of the insertion rule"},
    {.key = "lane_shares", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_lane_shares, .min = 0, .max = 1,
     .unit = "(share of the demand)", .doc_type = "list of shares", .doc_default = "equal shares",
     .doc_range = "one per lane, summing to 1",
     .doc = "each lane's share of the demand: every lane has its own arrivals and queue, and its vehicles enter it "
            "([lanes.md](lanes.md))"},
    {.key = "vehicles", .type = WF_KEY_INTEGER, .on = WF_ON_CORRIDOR, .offset = offsetof(WfCorridorSpec, max_arrivals),
     .size = sizeof(int64_t), .def = -1, .imin = 0, .imax = 1000000000L, .doc_default = "unlimited",
     .doc_range = "≥ 0", .doc = "stop the arrivals after this many vehicles (a platoon)"},
};
static const WfKeyTable inflow_keys = {"corridor.inflow", inflow_rows, sizeof inflow_rows / sizeof *inflow_rows};

static const WfKeySpec outflow_rows[] = {
    {.key = "type", .type = WF_KEY_CHOICE, .on = WF_ON_CORRIDOR, .offset = offsetof(WfCorridorSpec, outflow),
     .choices = outflows, .doc = "downstream boundary, below"},
    {.key = "speed_mps", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_outflow_speed, .max = 100,
     .unit = "m/s", .doc_type = "m/s", .doc_default = "required for `leader` and `speed`", .doc_range = "[0, 100]",
     .doc = "the virtual leader's speed, constant"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "CSV `time_s,speed_mps`", .doc_range = "t increasing",
     .doc = "the virtual leader's speed profile, linear between points, end values held"},
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[t, v]`", .doc_range = "t increasing", .doc = "the same as a list"},
    {.key = "offset_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .offset = offsetof(WfCorridorSpec, leader_offset_m), .def = 0, .min_is = WF_BOUND_NEG_LENGTH, .max = 1e7,
     .unit = "m", .doc = "the virtual leader starts at x = L + offset (negative: inside the road)"},
};
static const WfKeyTable outflow_keys = {"corridor.outflow", outflow_rows, sizeof outflow_rows / sizeof *outflow_rows};

static const WfKeySpec detector_rows[] = {
    {.key = "x_m", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED, .hook = load_detectors,
     .doc_type = "list of m", .doc_default = "none (required in `detectors`)", .doc_range = "[0, L), ≤ 256", .doc = "virtual detector positions"},
    {.key = "interval_s", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR,
     .offset = offsetof(WfCorridorSpec, det_interval_s), .def = 60, .min = 1e-6, .max = 1e9, .unit = "s",
     .doc_range = "a multiple of `dt_s`", .doc = "counting interval (the last may be shorter)"},
};
static const WfKeyTable detector_keys = {"corridor.detectors", detector_rows, 2};

static const WfKeySpec edie_rows[] = {
    {.key = "dx_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .offset = offsetof(WfCorridorSpec, edie_dx_m),
     .def = NAN, .min = 1e-3, .max_is = WF_BOUND_LENGTH, .unit = "m", .doc_default = "min(100, L)",
     .doc_range = "(0, L]", .doc = "Edie cell length (the last cell ends at L and may be shorter)"},
    {.key = "dt_s", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .offset = offsetof(WfCorridorSpec, edie_dt_s),
     .def = NAN, .min = 1e-6, .max_is = WF_BOUND_DURATION, .unit = "s", .doc_default = "min(60, duration)",
     .doc_range = "a multiple of `dt_s`",
     .doc = "Edie cell duration (the last may be shorter); at most 5·10⁷ cells"},
};
static const WfKeyTable edie_keys = {"corridor.edie", edie_rows, 2};

static const WfKeySpec ramp_rows[] = {
    {.key = "start_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorSpec, ramp_from_m), .min = 0, .max_is = WF_BOUND_LENGTH, .unit = "m",
     .doc = "where the merge lane starts: its vehicles enter here"},
    {.key = "end_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorSpec, ramp_to_m), .min = 0, .max_is = WF_BOUND_LENGTH, .unit = "m",
     .doc = "where it ends: its vehicles must merge before (the end stops them)"},
    {.key = "flow_vph", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_ramp_flow, .max = 36000,
     .unit = "veh/h", .doc_type = "veh/h", .doc_default = "required (or `csv`/`points`)", .doc_range = "[0, 36000]",
     .doc = "the ramp's demand, with the arrivals of `corridor.inflow`"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "CSV `time_s,flow_vph`", .doc = "time-varying ramp demand"},
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[t, q]`", .doc = "the same as a list"},
};
static const WfKeyTable ramp_keys = {"corridor.on_ramp", ramp_rows, sizeof ramp_rows / sizeof *ramp_rows};

/* corridor.off_ramp: where it leaves the rightmost main lane, which must reach it. */
static int check_offramp(WfCfgNode *corr, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfCorridorSpec *cs = t;
    WfCfgNode *off = wf_cfg_child(corr, row->key);
    char w[1024];
    if (!off) return 0;
    double L = env->sc->road.length_m;
    cs->has_offramp = 1;
    cs->exit_lane = (size_t)cs->has_ramp;
    if (!(cs->off_at_m > 0.0 && cs->off_at_m < L))
        return wf_err(err, WF_EINPUT, "%s: corridor.off_ramp.at_m %s m must lie inside the road (0, %s) m",
                      wf_scenario_where(off, w, sizeof w), WF_NUM(cs->off_at_m), WF_NUM(L));
    if (!(cs->lane_end_m[cs->exit_lane] > cs->off_at_m))
        return wf_err(err, WF_EINPUT, "%s: corridor.off_ramp leaves lane %zu at %s m, but corridor.lane_drops ends that "
                      "lane at %s m", wf_scenario_where(off, w, sizeof w), cs->exit_lane, WF_NUM(cs->off_at_m),
                      WF_NUM(cs->lane_end_m[cs->exit_lane]));
    return 0;
}

static const WfKeySpec offramp_rows[] = {
    {.key = "at_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorSpec, off_at_m), .min = 0, .max_is = WF_BOUND_LENGTH, .unit = "m",
     .doc_range = "(0, L)", .doc = "where the off-ramp leaves the rightmost main lane: its vehicles leave the road "
                                   "when their front reaches it"},
    {.key = "share", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfCorridorSpec, off_share), .min = 0, .max = 1, .unit = "1",
     .doc = "the share of the vehicles entering upstream of it that take it (each one's draw is keyed by its serial)"},
    {.key = "approach_m", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR,
     .offset = offsetof(WfCorridorSpec, off_approach_m), .def = 1000, .min = 0, .max = 1e5, .unit = "m",
     .doc = "within this distance before it, changing toward the rightmost lane is mandatory for its vehicles (any "
            "gap safe under `b_mandatory_mps2`), they change no other way, ask for cooperation, and once there hold "
            "their lane; one still in another lane at `at_m` misses it and drives on"},
};
static const WfKeyTable offramp_keys = {"corridor.off_ramp", offramp_rows, sizeof offramp_rows / sizeof *offramp_rows};

static const WfKeySpec corridor_rows[] = {
    {.key = "inflow", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_REQUIRED | WF_KEY_FLAT,
     .sub = &inflow_keys, .need = "a map {flow_vph: Q}"},
    {.key = "outflow", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_FLAT, .sub = &outflow_keys},
    {.key = "on_ramp", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_FLAT, .sub = &ramp_keys,
     .hook = check_ramp},
    {.key = "lane_drops", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .hook = load_lane_drops,
     .doc_type = "list of `{lane, at_m}`", .doc_default = "none", .doc_range = "a lane of the road, (0, L]",
     .doc = "lane `lane` ends at `at_m`: its vehicles must change lanes before (the end stops them); lanes are "
            "numbered with the merge lane (`on_ramp`) as lane 0 when there is one ([lanes.md](lanes.md))"},
    {.key = "off_ramp", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_FLAT, .sub = &offramp_keys,
     .hook = check_offramp},
    {.key = "zone_decel_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_CORRIDOR,
     .offset = offsetof(WfCorridorSpec, zone_decel_mps2), .def = 1.0, .min = 0.1, .max = 10, .unit = "m/s^2",
     .doc = "braking with which drivers meet a lower zone limit ahead"},
    {.key = "detectors", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_FLAT, .sub = &detector_keys,
     .hook = check_detectors},
    {.key = "edie", .type = WF_KEY_SECTION, .on = WF_ON_CORRIDOR, .flags = WF_KEY_FLAT, .sub = &edie_keys,
     .hook = check_edie},
};
const WfKeyTable wf_corridor_keys = {"corridor", corridor_rows, sizeof corridor_rows / sizeof *corridor_rows};

static const WfKeySpec grade_rows[] = {
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[x_m, grade_rad]`", .doc_default = "flat",
     .doc_range = "x in [0, L] increasing, \\|θ\\| ≤ 0.2 rad",
     .doc = "θ linear between the points, the end values held before the first and after the last. Not periodic: "
            "the profile need not close"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "CSV `x_m,grade_rad`", .doc = "the same from a file"},
};
const WfKeyTable wf_corridor_grade_keys = {"road.grade", grade_rows, 2};

static const WfKeySpec elevation_rows[] = {
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[x_m, z_m]`", .doc_range = "≥ 2 points, x increasing, \\|θ\\| ≤ 0.2 rad",
     .doc = "instead of `grade`: θ = atan(Δz/Δx), constant on each straight segment, 0 before the first and after "
            "the last point"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NOREAD,
     .doc_type = "CSV `x_m,z_m`", .doc = "the same from a file"},
};
const WfKeyTable wf_corridor_elevation_keys = {"road.elevation", elevation_rows, 2};

int wf_corridor_spec_load(WfScenario *sc, WfCfgNode *root, WfError *err)
{
    WfCorridorSpec *cs = calloc(1, sizeof *cs);
    if (!cs) return wf_err(err, WF_ESYS, "out of memory");
    sc->corridor = cs; /* owned by the scenario from here on, also on failure */
    WfKeyEnv env = {.on = WF_ON_CORRIDOR, .sc = sc};
    WfCfgNode *corr = NULL;
    if (check_fleet(sc, cs, err) ||
        wf_keys_read(wf_cfg_child(root, "road"), &wf_road_keys, WF_KEYS_LATER, sc, &env, err) ||
        wf_cfg_map_opt(root, "corridor", &corr, err))
        return err && err->code ? err->code : WF_EINPUT;
    if (!corr) return wf_cfg_missing(root, "corridor", "a section with at least corridor.inflow", err);
    if (wf_keys_read(corr, &wf_corridor_keys, WF_KEYS_FIRST, cs, &env, err))
        return err && err->code ? err->code : WF_EINPUT;
    return 0;
}

/* ------------------------------------------------------------------------------ profile lookups */

static size_t find_seg(const double *x, size_t n, double v, size_t s)
{
    /* Segment s spans [x_s, x_{s+1}); callers move forward, so the search from the cache is amortised O(1). */
    if (s >= n || x[s] > v) s = 0;
    while (s + 1 < n && x[s + 1] <= v) s++;
    return s;
}

double wf_profile_value(const WfProfile *p, double t, size_t *seg)
{
    if (p->n == 1 || t <= p->t[0]) return p->y[0];
    if (t >= p->t[p->n - 1]) return p->y[p->n - 1];
    size_t s = find_seg(p->t, p->n, t, *seg);
    *seg = s;
    double w = (t - p->t[s]) / (p->t[s + 1] - p->t[s]);
    return p->y[s] + (p->y[s + 1] - p->y[s]) * w;
}

double wf_profile_integral(const WfProfile *p, double t, size_t *seg)
{
    /* Before the first point the value is held at y_0: that piece integrates from 0 (or t) to t_0. */
    double t0 = p->t[0];
    if (t <= t0) return p->y[0] * t;
    double head = p->y[0] * t0;
    size_t n = p->n;
    if (t >= p->t[n - 1]) return head + p->cum[n - 1] + p->y[n - 1] * (t - p->t[n - 1]);
    size_t s = find_seg(p->t, n, t, *seg);
    *seg = s;
    double ys = p->y[s], yt = wf_profile_value(p, t, seg);
    return head + p->cum[s] + 0.5 * (ys + yt) * (t - p->t[s]);
}

double wf_corridor_grade(const WfCorridorSpec *cs, double x, uint32_t *seg)
{
    size_t n = cs->n_grade;
    if (n == 0) return 0.0;
    const double *px = cs->grade_x_m, *th = cs->grade_rad;
    if (x < px[0]) return cs->grade_steps ? 0.0 : th[0];
    if (x >= px[n - 1]) return th[n - 1]; /* steps: 0 (flat beyond the profile); linear: the last value */
    size_t s = find_seg(px, n, x, *seg);
    *seg = (uint32_t)s;
    if (cs->grade_steps) return th[s];
    double w = (x - px[s]) / (px[s + 1] - px[s]);
    return th[s] + (th[s + 1] - th[s]) * w;
}

/* Integral of theta from 0 to x, exact for both profile kinds. */
static double grade_integral(const WfCorridorSpec *cs, double x)
{
    size_t n = cs->n_grade;
    if (n == 0) return 0.0;
    const double *px = cs->grade_x_m, *th = cs->grade_rad;
    double before = cs->grade_steps ? 0.0 : th[0];
    if (x <= px[0]) return before * x;
    double sum = before * px[0];
    for (size_t i = 0; i + 1 < n; i++) {
        double a = px[i], b = px[i + 1] < x ? px[i + 1] : x;
        if (b <= a) break;
        if (cs->grade_steps) {
            sum += th[i] * (b - a);
        } else {
            double tb = th[i] + (th[i + 1] - th[i]) * (b - a) / (px[i + 1] - a);
            sum += 0.5 * (th[i] + tb) * (b - a);
        }
    }
    if (x > px[n - 1]) sum += th[n - 1] * (x - px[n - 1]);
    return sum;
}

double wf_corridor_grade_mean(const WfCorridorSpec *cs, double a, double b)
{
    if (!(b > a)) {
        uint32_t s = 0;
        return wf_corridor_grade(cs, a, &s);
    }
    return (grade_integral(cs, b) - grade_integral(cs, a)) / (b - a);
}
