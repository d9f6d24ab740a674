/* The corridor's result file (docs/output.md, docs/corridors.md): the one result writer (src/io/h5result.c) with
 * the corridor's observers: time series (wf_corridor_columns), trips and trajectory points appended as the run goes
 * (src/observe/trips.c, trajectories.c), detectors and Edie fields at the end (src/observe/detectors.c, edie.c),
 * and its own datasets: /road, the shares of each class and group, the road type. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/h5result.h"
#include "wavefuel/corridor.h"

#define TRIP_CHUNK 4096  /* rows per chunk of /trips (32 kB per column, compressed) */
#define TRAJ_CHUNK 65536 /* ... of /trajectories (512 kB per column, compressed) */

enum { CUR_TS, CUR_TRIPS, CUR_TRAJ, N_CUR };
static const WfH5Cursor cursors[N_CUR] = {
    {"timeseries", "timeseries_rows", "rows of /timeseries that hold data (the others are NaN until written)"},
    {"trips", "trip_rows", "rows of /trips that hold data"},
    {"trajectories", "trajectory_rows", "points of /trajectories that hold data (0 without trajectories)"},
};

/* Trips and trajectories, appended and compressed. */
static size_t corridor_series(const WfH5Run *r, WfCkptSeries *sp)
{
    size_t n = 0, lanes = wf_corridor_n_lanes(wf_sim_corridor(r->sim)) > 1;
    for (size_t k = 0; k < (lanes ? WF_TRIP_N_COLS : WF_TRIP_N_SINGLE); k++)
        sp[n++] = (WfCkptSeries){.col = &wf_trip_columns[k], .chunk_rows = TRIP_CHUNK, .compress = 1,
                                 .cursor = CUR_TRIPS};
    for (size_t k = 0; r->sc->trajectories && k < (lanes ? WF_CORRIDOR_TRAJ_N_COLS : WF_CORRIDOR_TRAJ_SINGLE); k++)
        sp[n++] = (WfCkptSeries){.col = &wf_corridor_traj_columns[k], .chunk_rows = TRAJ_CHUNK, .compress = 1,
                                 .cursor = CUR_TRAJ};
    return n;
}

/* Trips and trajectories cannot be estimated: each chunk is checked as it is added. */
static void corridor_size(const WfH5Run *r, double *appended, double *end)
{
    const WfDetectors *det = wf_corridor_detectors(wf_sim_corridor(r->sim));
    const WfEdie *e = wf_corridor_edie(wf_sim_corridor(r->sim));
    *appended = -1;
    *end = ((double)det->n_int * (double)det->n_det * 5.0 + (double)e->nt * (double)e->nx * 7.0 +
            (double)e->nx * (double)r->sc->n_classes * 3.0) * 8.0;
}

static int corridor_meta(hid_t g, const WfH5Run *r, WfError *err)
{
    (void)r;
    return wf_h5_scalar_str(g, "road_type", "corridor", "ring or corridor", err);
}

/* The share of the entering vehicles of each class and group. */
static int corridor_fleet(hid_t classes, hid_t drivers, const WfH5Run *r, WfError *err)
{
    const WfScenario *sc = r->sc;
    double frac[WF_MAX_CLASSES], gf[WF_MAX_GROUPS];
    hsize_t nc = sc->n_classes, ng = sc->n_groups;
    for (size_t k = 0; k < sc->n_classes; k++) frac[k] = sc->classes[k].fraction;
    for (size_t k = 0; k < sc->n_groups; k++) gf[k] = sc->groups[k].fraction;
    return wf_h5_write_f64(classes, "fraction", 1, &nc, frac, "1", "share of the entering vehicles", err) ||
           wf_h5_write_f64(drivers, "fraction", 1, &ng, gf, "1", "share of the entering vehicles", err);
}

static int corridor_traj_attrs(hid_t g, const WfH5Run *r, WfError *err)
{
    (void)r;
    return wf_h5_attr_str(g, "layout", "one row per vehicle on the road per frame, road order within a frame "
                          "(front first)", err);
}

static int write_road(hid_t fid, const WfScenario *sc, WfError *err)
{
    const WfCorridorSpec *cs = sc->corridor;
    hid_t g = wf_h5_group(fid, "road", err);
    if (g < 0) return WF_ESYS;
    hsize_t ng = cs->n_grade, nz = cs->n_zones, nd = cs->n_det;
    int rc = wf_h5_scalar_f64(g, "length", sc->road.length_m, "m", "corridor length L", err) ||
             wf_h5_scalar_f64(g, "speed_limit", sc->road.speed_limit_mps, "m/s", "road speed limit (inf: none)", err) ||
             wf_h5_scalar_str(g, "grade_kind", cs->grade_steps ? "steps" : "linear",
                              "linear: theta linear between points; steps: constant on each segment (from elevation)",
                              err);
    if (!rc && ng)
        rc = wf_h5_write_f64(g, "grade_x", 1, &ng, cs->grade_x_m, "m", "grade profile points", err) ||
             wf_h5_write_f64(g, "grade", 1, &ng, cs->grade_rad, "rad",
                             "grade angle at each point (steps: on the segment that starts there)", err);
    if (!rc && ng && cs->elev_z_m)
        rc = wf_h5_write_f64(g, "elevation", 1, &ng, cs->elev_z_m, "m", "elevation at grade_x (input profile)", err);
    if (!rc && nz) {
        const char *type[WF_CORRIDOR_MAX_ZONES], *key[WF_CORRIDOR_MAX_ZONES];
        double from[WF_CORRIDOR_MAX_ZONES], to[WF_CORRIDOR_MAX_ZONES], lim[WF_CORRIDOR_MAX_ZONES],
            fac[WF_CORRIDOR_MAX_ZONES];
        for (size_t z = 0; z < cs->n_zones; z++) {
            const WfCorridorZone *zn = &cs->zones[z];
            int speed = zn->type == WF_ZONE_SPEED_LIMIT;
            type[z] = speed ? "speed_limit" : "headway";
            key[z] = speed ? "" : zn->key;
            from[z] = zn->from_m, to[z] = zn->to_m;
            lim[z] = speed ? zn->value : NAN;
            fac[z] = speed ? NAN : zn->value;
        }
        rc = wf_h5_write_strings(g, "zone_type", nz, type, "speed_limit or headway", err) ||
             wf_h5_write_f64(g, "zone_from", 1, &nz, from, "m", "zone start", err) ||
             wf_h5_write_f64(g, "zone_to", 1, &nz, to, "m", "zone end", err) ||
             wf_h5_write_f64(g, "zone_speed_limit", 1, &nz, lim, "m/s", "speed-limit zones: the limit (NaN otherwise)",
                             err) ||
             wf_h5_write_f64(g, "zone_factor", 1, &nz, fac, "1", "headway zones: the factor (NaN otherwise)", err) ||
             wf_h5_write_strings(g, "zone_key", nz, key, "headway zones: the driver parameter multiplied", err);
    }
    if (!rc && nd)
        rc = wf_h5_write_f64(g, "detector_x", 1, &nd, cs->det_x_m, "m", "virtual detector positions", err);
    const char *outflow[] = {"free", "leader", "speed"};
    if (!rc) rc = wf_h5_scalar_str(g, "outflow", outflow[cs->outflow], "downstream boundary", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

/* A gridded observer's group from its column table: `fields` fills the values into scratch (`n_scratch` doubles);
 * the columns `keep` accepts are written (all when keep is NULL). */
static int write_grid(hid_t fid, const char *group, const WfObsColumn *cols, size_t n, size_t n_scratch,
                      void (*fields)(const void *obs, const WfScenario *sc, double *scratch, WfObsData *out),
                      int (*keep)(size_t col), const void *obs, const WfScenario *sc, WfH5Pass pass, WfError *err)
{
    hid_t g = wf_h5_group_pass(fid, group, pass, err);
    if (g < 0) return WF_ESYS;
    double *buf = malloc(n_scratch * sizeof *buf);
    WfObsData data[WF_EDIE_N_COLS];
    int rc = !buf ? wf_err(err, WF_ESYS, "out of memory") : 0;
    if (!rc) fields(obs, sc, buf, data);
    for (size_t k = 0; !rc && k < n; k++)
        if (!keep || keep(k)) rc = wf_h5_put_columns(g, &cols[k], &data[k], 1, pass, err);
    free(buf);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static void detector_fields(const void *d, const WfScenario *sc, double *scratch, WfObsData *out)
{
    wf_detectors_fields(d, sc, scratch, out);
}

static void edie_fields(const void *e, const WfScenario *sc, double *scratch, WfObsData *out)
{
    wf_edie_fields(e, sc, scratch, out);
}

static int write_detectors(hid_t fid, const WfH5Run *r, WfH5Pass pass, WfError *err)
{
    const WfDetectors *d = wf_corridor_detectors(wf_sim_corridor(r->sim));
    if (!d->n_det) return 0;
    return write_grid(fid, "detectors", wf_detector_columns, WF_DET_N_COLS, wf_detectors_scratch(d), detector_fields,
                      NULL, d, r->sc, pass, err);
}

/* /edie, its grid and the axes of its fields said in attributes when the file is created; on several lanes, each
 * lane's fields in lanes/edie/laneL (the fields only; the grid and class profiles are the road's). */
static int write_edie(hid_t fid, const WfH5Run *r, WfH5Pass pass, WfError *err)
{
    const WfEdie *all = wf_corridor_edie(wf_sim_corridor(r->sim));
    const WfScenario *sc = r->sc;
    /* the road's fields: every lane's cell sums added in lane order (the lane's own on one lane) */
    double *sum = all->n_lanes > 1 ? malloc(3 * all->nx * all->nt * sizeof *sum) : NULL;
    if (all->n_lanes > 1 && !sum) return wf_err(err, WF_ESYS, "out of memory");
    WfEdie road = wf_corridor_edie_lane(all, -1, sum);
    const WfEdie *e = &road;
    int bad = write_grid(fid, "edie", wf_edie_columns, WF_EDIE_N_COLS, wf_edie_scratch(e, sc->n_classes), edie_fields,
                         NULL, e, sc, pass, err);
    if (!bad && all->n_lanes > 1) { /* /lanes exists (wf_h5_write_lanes runs first) */
        hid_t g = wf_h5_group_pass(fid, "lanes/edie", pass, err);
        bad = g < 0;
        if (g >= 0) H5Gclose(g);
    }
    for (size_t l = 0; !bad && all->n_lanes > 1 && l < all->n_lanes; l++) {
        WfEdie lane = wf_corridor_edie_lane(all, (int)l, NULL);
        char name[64];
        snprintf(name, sizeof name, "lanes/edie/lane%zu", l);
        bad = write_grid(fid, name, wf_edie_columns, WF_EDIE_N_COLS, wf_edie_scratch(&lane, sc->n_classes),
                         edie_fields, wf_edie_is_field, &lane, sc, pass, err);
    }
    free(sum);
    if (bad) return WF_ESYS;
    if (pass == WF_H5_FILL) return 0;
    hid_t g = H5Gopen2(fid, "edie", H5P_DEFAULT);
    int rc = g < 0 ? wf_err(err, WF_ESYS, "HDF5: cannot reopen /edie")
                   : wf_h5_attr_f64(g, "dx_m", e->dx_m, err) || wf_h5_attr_f64(g, "dt_s", e->dt_s, err);
    for (size_t k = 0; !rc && k < WF_EDIE_N_COLS; k++) {
        if (!wf_edie_is_field(k)) continue;
        hid_t ds = H5Dopen2(g, wf_edie_columns[k].col.name, H5P_DEFAULT);
        if (ds < 0) rc = wf_err(err, WF_ESYS, "HDF5: cannot reopen /edie/%s", wf_edie_columns[k].col.name);
        else rc = wf_h5_attr_str(ds, "axes", "t_edges, x_edges (rows: time cells; columns: space cells)", err);
        if (ds >= 0) H5Dclose(ds);
    }
    if (g >= 0) H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int corridor_results(hid_t fid, const WfH5Run *r, WfH5Pass pass, WfError *err)
{
    return (pass == WF_H5_ALLOCATE && write_road(fid, r->sc, err)) || write_detectors(fid, r, pass, err) ||
                   wf_h5_write_lanes(fid, r->sim, pass, err) || write_edie(fid, r, pass, err)
               ? WF_ESYS
               : 0;
}

/* Room for every lane's buffer in each column. */
static size_t frame_cap(const WfH5Run *r)
{
    const WfCorridor *c = wf_sim_corridor(r->sim);
    return wf_corridor_n_lanes(c) * wf_corridor_vehicles(c)->cap;
}

static size_t corridor_frame_len(const WfH5Run *r)
{
    return r->sc->trajectories ? WF_CORRIDOR_TRAJ_N_COLS * frame_cap(r) : 0;
}

static size_t corridor_frame(const WfH5Run *r, const double *t_s, double *scratch, const double **cols)
{
    const WfCorridor *c = wf_sim_corridor(r->sim);
    const WfCorridorVehicles *lanes[WF_MAX_LANES];
    size_t nl = wf_corridor_n_lanes(c);
    for (size_t l = 0; l < nl; l++) lanes[l] = wf_corridor_lane(c, l);
    return wf_corridor_traj_frame(lanes, nl, *t_s, scratch, frame_cap(r), cols);
}

/* Trips, a row at a time, into their chunk; complete chunks are written, then counted. */
static int corridor_trips(WfH5Result *w, const WfTrip *tr, size_t n, WfError *err)
{
    for (size_t i = 0; i < n; i++) {
        double row[WF_TRIP_N_COLS];
        const double *cols[WF_TRIP_N_COLS];
        /* the columns past WF_TRIP_N_SINGLE, when the series have them, are read only on multi-lane roads */
        for (size_t k = 0; k < WF_TRIP_N_COLS; k++) row[k] = wf_trip_value(&tr[i], k), cols[k] = &row[k];
        if (wf_h5r_append(w, CUR_TRIPS, 1, cols, err)) return WF_ESYS;
    }
    return 0;
}

const WfH5Boundary wf_h5_corridor = {
    .kind = "corridor", .summary = WF_SUMMARY_CORRIDOR, .road_length_desc = "corridor length L",
    .warmup_desc = "warm-up excluded from the window statistics", .cursor = cursors, .n_cursors = N_CUR,
    .traj_cursor = CUR_TRAJ, .ts_cols = wf_corridor_columns, .n_ts_cols = WF_CTS_N_COLS,
    .ts_class_col = &wf_corridor_class_column, .grows = "trips and trajectories", .series = corridor_series,
    .size = corridor_size, .meta = corridor_meta, .fleet = corridor_fleet, .traj_attrs = corridor_traj_attrs,
    .results = corridor_results, .frame_len = corridor_frame_len, .frame = corridor_frame, .trips = corridor_trips,
};
