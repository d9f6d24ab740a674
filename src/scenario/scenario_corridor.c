/* Scenario keys of open corridors (`road.type: corridor`): the non-periodic grade or elevation profile, zones,
 * and the `corridor` section (inflow, outflow, detectors, Edie grid), read into a WfCorridorSpec. The ring loader
 * (src/scenario/scenario.c) reads everything else and calls wf_corridor_spec_load() before it rejects unread keys.
 * Keys, units and defaults: docs/corridors.md. */
#include "wavefuel/corridor.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/config.h"
#include "wavefuel/csv.h"

static const char *where_of(const WfCfgNode *n, char *buf, size_t len)
{
    char w[600], p[400];
    snprintf(buf, len, "%s: %s", wf_cfg_where(n, w, sizeof w), wf_cfg_path(n, p, sizeof p));
    return buf;
}

static void profile_free(WfProfile *p)
{
    free(p->t);
    free(p->y);
    free(p->cum);
    memset(p, 0, sizeof *p);
}

void wf_corridor_spec_destroy(WfCorridorSpec **ps)
{
    if (!ps || !*ps) return;
    WfCorridorSpec *s = *ps;
    free(s->grade_x_m);
    free(s->grade_rad);
    free(s->elev_z_m);
    profile_free(&s->inflow_vph);
    profile_free(&s->leader_speed_mps);
    free(s);
    *ps = NULL;
}

/* A path written in the scenario: absolute, or relative to the scenario file's directory. */
static int resolve_path(const WfScenario *sc, const char *name, char *buf, size_t len)
{
    const char *slash = strrchr(sc->path, '/');
    int n = name[0] == '/' || !slash ? snprintf(buf, len, "%s", name)
                                     : snprintf(buf, len, "%.*s/%s", (int)(slash - sc->path), sc->path, name);
    return n < 0 || (size_t)n >= len ? -1 : 0;
}

/* Two-column numbers from either `points: [[a, b], ...]` or `csv: FILE` (header `names`) of `map`. The arrays
 * are owned by the caller. `where` receives the location of what was read, for later messages. */
static int read_pairs(const WfScenario *sc, WfCfgNode *map, const char *const names[2], double min0, double max0,
                      const char *unit0, double min1, double max1, const char *unit1, double **a_out,
                      double **b_out, size_t *n_out, char *where, size_t wlen, WfError *err)
{
    WfCfgNode *points = NULL;
    const char *csv = NULL;
    char w[1024];
    *a_out = *b_out = NULL;
    *n_out = 0;
    if (wf_cfg_seq_opt(map, "points", &points, err) || wf_cfg_string_opt(map, "csv", &csv, err)) return WF_EINPUT;
    if (!!points == !!csv)
        return wf_err(err, WF_EINPUT, "%s: give either 'points' (a list of [%s, %s]) or 'csv' (a file with header "
                      "%s,%s)", where_of(map, w, sizeof w), names[0], names[1], names[0], names[1]);
    size_t n = 0;
    double *a = NULL, *b = NULL;
    int rc = 0;
    if (points) {
        n = points->n_child;
        where_of(points, where, wlen);
        a = malloc((n + 1) * sizeof *a);
        b = malloc((n + 1) * sizeof *b);
        if (!a || !b) rc = wf_err(err, WF_ESYS, "out of memory");
        for (size_t i = 0; !rc && i < n; i++) {
            WfCfgNode *p = points->child[i];
            p->used = 1;
            if (p->kind != WF_CFG_SEQ || p->n_child != 2)
                rc = wf_err(err, WF_EINPUT, "%s: expected a pair [%s, %s]", where_of(p, w, sizeof w), names[0],
                            names[1]);
            else if (wf_cfg_node_double(p->child[0], min0, max0, unit0, &a[i], err) ||
                     wf_cfg_node_double(p->child[1], min1, max1, unit1, &b[i], err))
                rc = WF_EINPUT;
        }
    } else {
        char path[2048];
        WfCsv t;
        if (resolve_path(sc, csv, path, sizeof path))
            return wf_err(err, WF_EINPUT, "%s: path too long", where_of(wf_cfg_child(map, "csv"), w, sizeof w));
        if (snprintf(where, wlen, "%s", path) >= (int)wlen) where[wlen - 1] = '\0'; /* only for messages */
        if (wf_csv_read(path, 2, names, &t, err)) {
            wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(map, "csv"), w, sizeof w));
            return WF_EINPUT;
        }
        n = t.n_rows;
        a = malloc((n + 1) * sizeof *a);
        b = malloc((n + 1) * sizeof *b);
        if (!a || !b) rc = wf_err(err, WF_ESYS, "out of memory");
        for (size_t i = 0; !rc && i < n; i++) {
            a[i] = t.data[2 * i], b[i] = t.data[2 * i + 1];
            if (!(a[i] >= min0 && a[i] <= max0))
                rc = wf_err(err, WF_EINPUT, "%s:%d: %s must be in [%.10g, %.10g] %s (got %.17g)", path, t.line[i],
                            names[0], min0, max0, unit0, a[i]);
            else if (!(b[i] >= min1 && b[i] <= max1))
                rc = wf_err(err, WF_EINPUT, "%s:%d: %s must be in [%.10g, %.10g] %s (got %.17g)", path, t.line[i],
                            names[1], min1, max1, unit1, b[i]);
        }
        wf_csv_free(&t);
    }
    if (!rc && n == 0) rc = wf_err(err, WF_EINPUT, "%s: no points", where);
    for (size_t i = 1; !rc && i < n; i++)
        if (!(a[i] > a[i - 1]))
            rc = wf_err(err, WF_EINPUT, "%s: point %zu: %s must increase (got %.17g after %.17g)", where, i, names[0],
                        a[i], a[i - 1]);
    if (rc) {
        free(a);
        free(b);
        return rc;
    }
    *a_out = a, *b_out = b, *n_out = n;
    return 0;
}

/* A time profile: `KEY: value` (constant) or `csv: FILE` with header time_s,NAME, points linear in between. */
static int read_profile(const WfScenario *sc, WfCfgNode *map, const char *key, const char *col, double max,
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
    const char *names[2] = {"time_s", col};
    char where[1024];
    if (read_pairs(sc, map, names, 0, 1e9, "s", 0, max, unit, &p->t, &p->y, &p->n, where, sizeof where, err))
        return WF_EINPUT;
    p->cum = malloc(p->n * sizeof *p->cum);
    if (!p->cum) return wf_err(err, WF_ESYS, "out of memory");
    p->cum[0] = 0.0;
    /* Trapezoids: exact for the piecewise-linear profile. */
    for (size_t i = 1; i < p->n; i++) p->cum[i] = p->cum[i - 1] + 0.5 * (p->y[i] + p->y[i - 1]) * (p->t[i] - p->t[i - 1]);
    return 0;
}

static int load_grade(WfScenario *sc, WfCorridorSpec *cs, WfCfgNode *road, WfError *err)
{
    WfCfgNode *grade = NULL, *elev = NULL;
    char w[1024], where[1024];
    double L = sc->road.length_m;
    if (wf_cfg_map_opt(road, "grade", &grade, err) || wf_cfg_map_opt(road, "elevation", &elev, err)) return WF_EINPUT;
    if (grade && elev)
        return wf_err(err, WF_EINPUT, "%s: give either road.grade or road.elevation, not both",
                      where_of(elev, w, sizeof w));
    if (grade) {
        static const char *const names[2] = {"x_m", "grade_rad"};
        return read_pairs(sc, grade, names, 0, L, "m", -0.2, 0.2, "rad", &cs->grade_x_m, &cs->grade_rad,
                          &cs->n_grade, where, sizeof where, err);
    }
    if (!elev) return 0;
    static const char *const names[2] = {"x_m", "z_m"};
    double *x = NULL, *z = NULL;
    size_t n = 0;
    if (read_pairs(sc, elev, names, 0, L, "m", -1e4, 1e4, "m", &x, &z, &n, where, sizeof where, err)) return WF_EINPUT;
    if (n < 2) {
        free(x);
        free(z);
        return wf_err(err, WF_EINPUT, "%s: an elevation profile needs at least two points", where);
    }
    /* theta on [x_i, x_{i+1}) is the angle of the straight segment: atan(dz / dx). */
    double *th = malloc(n * sizeof *th);
    if (!th) {
        free(x);
        free(z);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    for (size_t i = 0; i + 1 < n; i++) {
        th[i] = atan((z[i + 1] - z[i]) / (x[i + 1] - x[i]));
        if (fabs(th[i]) > 0.2) {
            double bad = th[i];
            free(x), free(z), free(th);
            return wf_err(err, WF_EINPUT, "%s: segment %zu climbs at %.6g rad; grades beyond 0.2 rad are outside the "
                          "energy models' range", where, i, bad);
        }
    }
    th[n - 1] = 0.0; /* beyond the last point the road is flat */
    cs->grade_x_m = x, cs->grade_rad = th, cs->elev_z_m = z, cs->n_grade = n, cs->grade_steps = 1;
    return 0;
}

static int load_zones(WfScenario *sc, WfCorridorSpec *cs, WfCfgNode *road, WfError *err)
{
    static const char *const types[] = {"speed_limit", "headway", NULL};
    WfCfgNode *seq = NULL;
    char w[1024];
    double L = sc->road.length_m;
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
        int type = -1;
        if (!wf_cfg_child(e, "type")) return wf_cfg_missing(e, "type", "speed_limit or headway", err);
        if (wf_cfg_enum_opt(e, "type", types, &type, err)) return WF_EINPUT;
        z->type = (WfZoneType)type;
        if (wf_cfg_double(e, "from_m", 0, L, "m", &z->from_m, err) || wf_cfg_double(e, "to_m", 0, L, "m", &z->to_m, err))
            return WF_EINPUT;
        if (!(z->to_m > z->from_m))
            return wf_err(err, WF_EINPUT, "%s: to_m (%.17g) must exceed from_m (%.17g)", where_of(e, w, sizeof w),
                          z->to_m, z->from_m);
        if (z->type == WF_ZONE_SPEED_LIMIT) {
            if (wf_cfg_double(e, "speed_limit_mps", 0.1, 100, "m/s", &z->value, err)) return WF_EINPUT;
        } else {
            const char *key = "T_s";
            if (wf_cfg_double(e, "factor", 0.1, 10, "(multiplies the headway parameter)", &z->value, err) ||
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
        }
        cs->n_zones = i + 1;
    }
    return 0;
}

/* What the ring loader read, checked against corridor semantics. */
static int check_fleet(WfScenario *sc, WfCorridorSpec *cs, WfCfgNode *root, WfError *err)
{
    char w[1024];
    WfCfgNode *fleet = wf_cfg_child(root, "fleet"), *n;
    if ((n = wf_cfg_child(fleet, "vehicles")))
        return wf_err(err, WF_EINPUT, "%s: a corridor has no fixed fleet size: vehicles come from corridor.inflow",
                      where_of(n, w, sizeof w));
    if ((n = wf_cfg_child(root, "initial")))
        return wf_err(err, WF_EINPUT, "%s: a corridor starts empty and fills from the inflow: 'initial' applies to rings",
                      where_of(n, w, sizeof w));
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
        return wf_err(err, WF_EINPUT, "%s: %s (%.17g s) must be a whole multiple of time.dt_s (%.17g s)",
                      where_of(wf_cfg_child(map, key) ? wf_cfg_child(map, key) : map, w, sizeof w), key, v, sc->dt_s);
    return 0;
}

static int load_section(WfScenario *sc, WfCorridorSpec *cs, WfCfgNode *root, WfError *err)
{
    static const char *const arrivals[] = {"deterministic", "poisson", NULL};
    static const char *const outflows[] = {"free", "leader", "speed", NULL};
    WfCfgNode *corr = NULL, *in = NULL, *outf = NULL, *det = NULL, *edie = NULL;
    char w[1024];
    double L = sc->road.length_m;
    if (wf_cfg_map_opt(root, "corridor", &corr, err)) return WF_EINPUT;
    if (!corr) return wf_cfg_missing(root, "corridor", "a section with at least corridor.inflow", err);
    if (wf_cfg_map_opt(corr, "inflow", &in, err)) return WF_EINPUT;
    if (!in) return wf_cfg_missing(corr, "inflow", "a map {flow_vph: Q}", err);
    int arr = WF_ARRIVALS_DETERMINISTIC;
    if (wf_cfg_enum_opt(in, "arrivals", arrivals, &arr, err)) return WF_EINPUT;
    cs->arrivals = (WfArrivals)arr;
    if (read_profile(sc, in, "flow_vph", "flow_vph", 36000, "veh/h", 1, &cs->inflow_vph, err)) return WF_EINPUT;
    cs->entry_speed_mps = INFINITY;
    if (wf_cfg_double_opt(in, "entry_speed_mps", 0, 100, "m/s", &cs->entry_speed_mps, err)) return WF_EINPUT;
    cs->insert_decel_mps2 = 0.3;
    if (wf_cfg_double_opt(in, "insert_decel_mps2", 0.01, 20, "m/s^2", &cs->insert_decel_mps2, err)) return WF_EINPUT;
    long maxv = -1;
    if (wf_cfg_long_opt(in, "vehicles", 0, 1000000000L, &maxv, err)) return WF_EINPUT;
    cs->max_arrivals = maxv;

    int of = WF_OUTFLOW_FREE;
    if (wf_cfg_map_opt(corr, "outflow", &outf, err)) return WF_EINPUT;
    if (outf && wf_cfg_enum_opt(outf, "type", outflows, &of, err)) return WF_EINPUT;
    cs->outflow = (WfOutflow)of;
    if (outf && of != WF_OUTFLOW_FREE) {
        if (read_profile(sc, outf, "speed_mps", "speed_mps", 100, "m/s", 1, &cs->leader_speed_mps, err))
            return WF_EINPUT;
        if (wf_cfg_double_opt(outf, "offset_m", -L, 1e7, "m", &cs->leader_offset_m, err)) return WF_EINPUT;
    }

    cs->zone_decel_mps2 = 1.0;
    if (wf_cfg_double_opt(corr, "zone_decel_mps2", 0.1, 10, "m/s^2", &cs->zone_decel_mps2, err)) return WF_EINPUT;

    cs->det_interval_s = 60.0;
    if (wf_cfg_map_opt(corr, "detectors", &det, err)) return WF_EINPUT;
    if (det) {
        WfCfgNode *xs = NULL;
        if (wf_cfg_seq_opt(det, "x_m", &xs, err) || wf_cfg_double_opt(det, "interval_s", 1e-6, 1e9, "s",
                                                                       &cs->det_interval_s, err))
            return WF_EINPUT;
        if (!xs) return wf_cfg_missing(det, "x_m", "a list of positions in m", err);
        if (xs->n_child > WF_CORRIDOR_MAX_DETECTORS)
            return wf_err(err, WF_EINPUT, "%s: at most %d detectors", where_of(xs, w, sizeof w),
                          WF_CORRIDOR_MAX_DETECTORS);
        for (size_t i = 0; i < xs->n_child; i++) {
            if (wf_cfg_node_double(xs->child[i], 0, L, "m", &cs->det_x_m[i], err)) return WF_EINPUT;
            /* A passage is x_before <= x_d < x_after, and vehicles leave once x >= L: x_d = L would miss some. */
            if (!(cs->det_x_m[i] < L))
                return wf_err(err, WF_EINPUT, "%s: a detector must lie before the exit, in [0, %.17g) m",
                              where_of(xs->child[i], w, sizeof w), L);
        }
        cs->n_det = xs->n_child;
        if (whole_steps(sc, det, "interval_s", cs->det_interval_s, err)) return WF_EINPUT;
    }

    cs->edie_dx_m = 100.0 < L ? 100.0 : L;
    cs->edie_dt_s = 60.0 < sc->duration_s ? 60.0 : sc->duration_s;
    if (wf_cfg_map_opt(corr, "edie", &edie, err)) return WF_EINPUT;
    if (edie && (wf_cfg_double_opt(edie, "dx_m", 1e-3, L, "m", &cs->edie_dx_m, err) ||
                 wf_cfg_double_opt(edie, "dt_s", 1e-6, sc->duration_s, "s", &cs->edie_dt_s, err)))
        return WF_EINPUT;
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

int wf_corridor_spec_load(WfScenario *sc, WfCfgNode *root, WfError *err)
{
    WfCorridorSpec *cs = calloc(1, sizeof *cs);
    if (!cs) return wf_err(err, WF_ESYS, "out of memory");
    sc->corridor = cs; /* owned by the scenario from here on, also on failure */
    WfCfgNode *road = wf_cfg_child(root, "road");
    if (check_fleet(sc, cs, root, err) || load_grade(sc, cs, road, err) || load_zones(sc, cs, road, err) ||
        load_section(sc, cs, root, err))
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
