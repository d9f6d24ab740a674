/* HDF5 result files of corridor runs (docs/corridors.md): provenance, classes and drivers, the road, time series,
 * trips and trajectories appended as the run goes, detectors, Edie fields and the summary at the end. Everything
 * whose size is known is created at that size before the first step and overwritten in place; trips and
 * trajectories, whose number is not known, grow a compressed chunk at a time after its disk space is reserved,
 * the rows of the incomplete chunk waiting in memory and in checkpoints (src/io/h5util.h, src/io/h5ckpt.h), so a write
 * error at any point leaves a file whose structure is intact (docs/output.md, "Write errors"). */
#include "wavefuel/h5corridor.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "io/h5ckpt.h"
#include "io/h5result.h"
#include "io/h5summary.h"
#include "io/h5util.h"
#include "wavefuel/version.h"

#define TS_BUF     256
#define TRIP_CHUNK 4096  /* rows per chunk of /trips (32 kB per column, compressed) */
#define TRAJ_CHUNK 65536 /* ... of /trajectories (512 kB per column, compressed) */
#define N_SERIES   (WF_CTS_N_COLS + 1 + TR_N + N_TRAJ)

enum { TR_N = WF_TRIP_N_COLS, N_TRAJ = WF_CORRIDOR_TRAJ_N_COLS };
#define trip_cols wf_trip_columns
#define traj_cols wf_corridor_traj_columns

/* The series whose rows a checkpoint counts (src/io/h5ckpt.h), and /meta's counter of each. */
enum { CUR_TS, CUR_TRIPS, CUR_TRAJ, N_CUR };
static const char *const cursor_names[N_CUR] = {"timeseries", "trips", "trajectories"};

struct WfH5Corridor {
    WfH5File  *file;
    int        ended;
    int        resume;     /* reopened .partial of an interrupted run */
    /* A write to the group failed: nothing more is written to it (its count stays true); the others go on. */
    int        ts_failed, trips_failed, traj_failed;
    char       final_path[1100];
    char       started[64];
    hid_t      g_meta;
    WfH5Series ts[WF_CTS_N_COLS], ts_class, trips[TR_N], tr[N_TRAJ];
    WfH5Series *trip_s[TR_N], *traj_s[N_TRAJ]; /* the groups appended together */
    int64_t    counted[N_CUR]; /* the row counters as last written (-1: not yet) */
    double    *buf, *cls;  /* TS_BUF time-series rows; scratch of wf_h5_series_write_records */
    double    *frame;      /* one trajectory frame: N_TRAJ columns of up to tcap points */
    size_t     n_buf, n_classes, tcap;
};

static void init_writer(WfH5Corridor *w)
{
    w->g_meta = H5I_INVALID_HID;
    for (size_t k = 0; k < WF_CTS_N_COLS; k++) wf_h5_series_init(&w->ts[k]);
    wf_h5_series_init(&w->ts_class);
    for (size_t k = 0; k < TR_N; k++) wf_h5_series_init(&w->trips[k]), w->trip_s[k] = &w->trips[k];
    for (size_t k = 0; k < N_TRAJ; k++) wf_h5_series_init(&w->tr[k]), w->traj_s[k] = &w->tr[k];
    for (size_t k = 0; k < N_CUR; k++) w->counted[k] = -1;
}

/* Every series: its group, shape and layout, and the cursor that counts its rows. The time series are fixed (every
 * record allocated at the start), trips and trajectories appended and compressed. */
static size_t series_specs(WfH5Corridor *w, const WfScenario *sc, WfCkptSeries *sp)
{
    hsize_t ts_rows = (hsize_t)wf_scenario_records(sc, wf_scenario_output_every(sc));
    size_t n = 0;
    for (size_t k = 0; k < WF_CTS_N_COLS; k++)
        sp[n++] = (WfCkptSeries){.s = &w->ts[k], .group = "timeseries", .col = &wf_corridor_columns[k],
                                 .fixed_rows = ts_rows, .cursor = CUR_TS};
    sp[n++] = (WfCkptSeries){.s = &w->ts_class, .group = "timeseries", .col = &wf_corridor_class_column, .cols = sc->n_classes,
                             .fixed_rows = ts_rows, .cursor = CUR_TS};
    for (size_t k = 0; k < TR_N; k++)
        sp[n++] = (WfCkptSeries){.s = &w->trips[k], .group = "trips", .col = &trip_cols[k], .chunk_rows = TRIP_CHUNK,
                                 .compress = 1, .cursor = CUR_TRIPS};
    for (size_t k = 0; sc->trajectories && k < N_TRAJ; k++)
        sp[n++] = (WfCkptSeries){.s = &w->tr[k], .group = "trajectories", .col = &traj_cols[k],
                                 .chunk_rows = TRAJ_CHUNK, .compress = 1, .cursor = CUR_TRAJ};
    return n;
}

/* /meta/timeseries_rows, trip_rows, trajectory_rows: the rows of each group in the file, written in place after
 * them when they changed (so they never count a row that is not there). */
static int write_counts(WfH5Corridor *w, WfH5Pass pass, WfError *err)
{
    int64_t n[N_CUR] = {(int64_t)w->ts[0].rows, (int64_t)w->trips[0].rows, (int64_t)w->tr[0].rows};
    if (pass == WF_H5_FILL && !memcmp(n, w->counted, sizeof n)) return 0;
    if (wf_h5_put_scalar_i64(w->g_meta, "timeseries_rows", pass, n[CUR_TS], "1",
                             "rows of /timeseries that hold data (the others are NaN until written)", err) ||
        wf_h5_put_scalar_i64(w->g_meta, "trip_rows", pass, n[CUR_TRIPS], "1", "rows of /trips that hold data", err) ||
        wf_h5_put_scalar_i64(w->g_meta, "trajectory_rows", pass, n[CUR_TRAJ], "1",
                             "points of /trajectories that hold data (0 without trajectories)", err))
        return WF_ESYS;
    if (pass == WF_H5_FILL) memcpy(w->counted, n, sizeof n);
    return 0;
}

static int flush_ts(WfH5Corridor *w, WfError *err)
{
    if (!w->n_buf) return 0;
    if (wf_h5_series_write_records(w->ts, WF_CTS_N_COLS, &w->ts_class, w->n_classes, w->buf, w->n_buf, w->cls, err))
        return WF_ESYS;
    w->n_buf = 0;
    return write_counts(w, WF_H5_FILL, err);
}

/* What /meta says about the run's progress, written in place. */
static int meta_status(hid_t g, WfH5Pass pass, const WfCorridor *c, int completed, const char *reason, WfError *err)
{
    int rc = wf_h5_put_text(g, "reason", pass, reason,
                            "why the run stopped early: running while it runs, empty when completed", err) ||
             wf_h5_put_scalar_f64(g, "wall_time_s", pass, wf_corridor_wall_s(c), "s", "wall time of the step loop",
                                  err) ||
             wf_h5_put_scalar_i64(g, "steps_done", pass, wf_corridor_steps_done(c), "1", "time steps completed", err) ||
             /* Last: a file says completed only once everything else is written. */
             wf_h5_put_scalar_i64(g, "completed", pass, completed, "1", "1 when the run reached its end", err);
    return rc ? WF_ESYS : 0;
}

static int write_meta(WfH5Corridor *w, const WfCorridor *c, WfError *err)
{
    const WfScenario *sc = wf_corridor_scenario(c);
    hid_t g = w->g_meta = wf_h5_group(w->file->fid, "meta", err);
    if (g < 0) return WF_ESYS;
    int rc = wf_h5_scalar_str(g, "scenario_text", sc->text, "the scenario file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sc->path, "scenario file as given", err) ||
             wf_h5_scalar_str(g, "overrides", sc->overrides, "--set assignments applied, one per line", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", WF_GIT_HASH, "git describe of the source tree", err) ||
             wf_h5_scalar_str(g, "road_type", "corridor", "ring or corridor", err) ||
             wf_h5_scalar_i64(g, "seed", (int64_t)sc->seed, "1", "random seed", err) ||
             wf_h5_scalar_i64(g, "threads", wf_corridor_threads(c), "1", "OpenMP threads available to the run", err) ||
             wf_h5_scalar_str(g, "start_time", w->started, "wall-clock start, UTC ISO 8601", err) ||
             wf_h5_scalar_str(g, "integrator", sc->integrator, "time integrator", err) ||
             wf_h5_scalar_f64(g, "dt", sc->dt_s, "s", "time step", err) ||
             wf_h5_scalar_f64(g, "duration", sc->duration_s, "s", "simulated duration", err) ||
             wf_h5_scalar_f64(g, "warmup", sc->warmup_s, "s", "warm-up excluded from the window statistics", err) ||
             wf_h5_scalar_f64(g, "road_length", sc->road.length_m, "m", "corridor length L", err) ||
             meta_status(g, WF_H5_ALLOCATE, c, 0, "", err) || meta_status(g, WF_H5_FILL, c, 0, "running", err) ||
             write_counts(w, WF_H5_ALLOCATE, err) || write_counts(w, WF_H5_FILL, err);
    return rc ? WF_ESYS : 0;
}

static int write_classes_drivers(hid_t fid, const WfCorridor *c, WfError *err)
{
    const WfScenario *sc = wf_corridor_scenario(c);
    hid_t g = wf_h5_group(fid, "classes", err);
    if (g < 0) return WF_ESYS;
    const char *names[WF_MAX_CLASSES], *labels[WF_MAX_CLASSES], *fuels[WF_MAX_CLASSES], *duty[WF_MAX_CLASSES];
    double frac[WF_MAX_CLASSES], len[WF_MAX_CLASSES], dens[WF_MAX_CLASSES], kw[WF_MAX_CLASSES];
    hsize_t nc = sc->n_classes;
    for (size_t k = 0; k < sc->n_classes; k++) {
        const WfVehicleClass *vc = &sc->classes[k].vc;
        names[k] = vc->name, labels[k] = vc->label, fuels[k] = wf_fuel_name(vc->fuel), duty[k] = wf_duty_name(vc->duty);
        frac[k] = sc->classes[k].fraction, len[k] = sc->classes[k].length_m, dens[k] = vc->fuel_density_g_per_l;
        kw[k] = vc->kw_per_gps;
    }
    int rc = wf_h5_write_strings(g, "name", nc, names, "class name (vehicles/NAME.yaml); index = class_id", err) ||
             wf_h5_write_strings(g, "label", nc, labels, "human-readable class name", err) ||
             wf_h5_write_strings(g, "fuel", nc, fuels, "fuel type", err) ||
             wf_h5_write_strings(g, "duty", nc, duty, "light or heavy duty", err) ||
             wf_h5_write_f64(g, "fraction", 1, &nc, frac, "1", "share of the entering vehicles", err) ||
             wf_h5_write_f64(g, "length", 1, &nc, len, "m", "vehicle length used", err) ||
             wf_h5_write_f64(g, "fuel_density", 1, &nc, dens, "g/L", "fuel density for volume units", err) ||
             wf_h5_write_f64(g, "kw_per_gps", 1, &nc, kw, "kW/(g/s)", "equivalent power per fuel rate", err);
    H5Gclose(g);
    if (rc) return WF_ESYS;
    g = wf_h5_group(fid, "drivers", err);
    if (g < 0) return WF_ESYS;
    const char *gn[WF_MAX_GROUPS], *gm[WF_MAX_GROUPS];
    double gf[WF_MAX_GROUPS], noise[WF_MAX_GROUPS];
    hsize_t ng = sc->n_groups;
    for (size_t k = 0; k < sc->n_groups; k++)
        gn[k] = sc->groups[k].name, gm[k] = sc->groups[k].model->name, gf[k] = sc->groups[k].fraction,
        noise[k] = sc->groups[k].noise_mps2;
    rc = wf_h5_write_strings(g, "name", ng, gn, "driver group name; index = group_id", err) ||
         wf_h5_write_strings(g, "model", ng, gm, "car-following model or controller", err) ||
         wf_h5_write_f64(g, "fraction", 1, &ng, gf, "1", "share of the entering vehicles", err) ||
         wf_h5_write_f64(g, "noise", 1, &ng, noise, "m/s^2", "acceleration noise standard deviation", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_road(hid_t fid, const WfCorridor *c, WfError *err)
{
    const WfScenario *sc = wf_corridor_scenario(c);
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

/* A gridded observer's group from its column table: `fields` fills the values into scratch (`n_scratch` doubles). */
static int write_grid(hid_t fid, const char *group, const WfObsColumn *cols, size_t n, size_t n_scratch,
                      void (*fields)(const void *obs, const WfScenario *sc, double *scratch, WfObsData *out),
                      const void *obs, const WfScenario *sc, WfH5Pass pass, WfError *err)
{
    hid_t g = wf_h5_group_pass(fid, group, pass, err);
    if (g < 0) return WF_ESYS;
    double *buf = malloc(n_scratch * sizeof *buf);
    WfObsData data[WF_EDIE_N_COLS];
    int rc = !buf ? wf_err(err, WF_ESYS, "out of memory") : 0;
    if (!rc) {
        fields(obs, sc, buf, data);
        rc = wf_h5_put_columns(g, cols, data, n, pass, err);
    }
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

static int write_detectors(hid_t fid, const WfCorridor *c, WfH5Pass pass, WfError *err)
{
    const WfDetectors *d = wf_corridor_detectors(c);
    if (!d->n_det) return 0;
    return write_grid(fid, "detectors", wf_detector_columns, WF_DET_N_COLS, wf_detectors_scratch(d), detector_fields,
                      d, wf_corridor_scenario(c), pass, err);
}

/* /edie, its grid and the axes of its fields said in attributes when the file is created. */
static int write_edie(hid_t fid, const WfCorridor *c, WfH5Pass pass, WfError *err)
{
    const WfEdie *e = wf_corridor_edie(c);
    const WfScenario *sc = wf_corridor_scenario(c);
    if (write_grid(fid, "edie", wf_edie_columns, WF_EDIE_N_COLS, wf_edie_scratch(e, sc->n_classes), edie_fields, e,
                   sc, pass, err))
        return WF_ESYS;
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

static int write_summary(hid_t fid, const WfCorridor *c, WfH5Pass pass, WfError *err)
{
    return wf_h5_summary_write(fid, wf_corridor_summary(c), wf_corridor_scenario(c)->n_classes, WF_SUMMARY_CORRIDOR,
                               pass, err);
}

/* A failure while the file is set up (`why`, or the error in err): what the file needs, and that nothing is kept
 * (destroy removes a file whose run never started). */
static int setup_failed(WfH5Corridor *w, double ts, double end, const char *why, WfError *err)
{
    char a[32], b[32], d[32], inner[sizeof err->msg];
    snprintf(inner, sizeof inner, "%s", why ? why : err->msg);
    return wf_err(err, why || !err->code ? WF_ESYS : err->code,
                  "%s: cannot create the result file, which needs about %s to start (time series %s, end-of-run "
                  "results %s) and more as trips and trajectories are added: %s; nothing was simulated and the file "
                  "is removed",
                  w->file->partial, wf_h5_size_text(ts + end, a, sizeof a), wf_h5_size_text(ts, b, sizeof b),
                  wf_h5_size_text(end, d, sizeof d), inner);
}

static int h5_begin(void *ctx, const WfCorridor *c, WfError *err)
{
    WfH5Corridor *w = ctx;
    const WfScenario *sc = wf_corridor_scenario(c);
    w->n_classes = sc->n_classes;
    w->buf = malloc(TS_BUF * (WF_CTS_N_COLS + w->n_classes) * sizeof *w->buf);
    w->cls = malloc(TS_BUF * (w->n_classes ? w->n_classes : 1) * sizeof *w->cls);
    if (!w->buf || !w->cls) return wf_err(err, WF_ESYS, "out of memory");
    if (sc->trajectories) {
        w->tcap = wf_corridor_vehicles(c)->cap;
        w->frame = malloc(N_TRAJ * (w->tcap ? w->tcap : 1) * sizeof *w->frame);
        if (!w->frame) return wf_err(err, WF_ESYS, "out of memory for trajectories");
    }
    if (w->resume) return 0; /* wf_h5corridor_resume reopened the file and set it back to the checkpoint */
    hid_t fid = w->file->fid;
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(w->started, sizeof w->started, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    const WfDetectors *det = wf_corridor_detectors(c);
    const WfEdie *e = wf_corridor_edie(c);
    double ts_bytes = (double)sp[0].fixed_rows * (double)(WF_CTS_N_COLS + w->n_classes) * 8.0;
    double end_bytes = ((double)det->n_int * (double)det->n_det * 5.0 +
                        (double)e->nt * (double)e->nx * 7.0 + (double)e->nx * (double)sc->n_classes * 3.0) * 8.0;
    /* Trips and trajectories cannot be estimated: each chunk is checked as it is added. */
    char why[200];
    if (wf_h5_check_room(w->file, ts_bytes + end_bytes, why, sizeof why))
        return setup_failed(w, ts_bytes, end_bytes, why, err);
    const char *groups[] = {"timeseries", "trips", "trajectories"};
    int rc = write_meta(w, c, err) || write_classes_drivers(fid, c, err) || write_road(fid, c, err) ||
             write_detectors(fid, c, WF_H5_ALLOCATE, err) || write_edie(fid, c, WF_H5_ALLOCATE, err) ||
             write_summary(fid, c, WF_H5_ALLOCATE, err);
    for (size_t k = 0; !rc && k < (sc->trajectories ? 3u : 2u); k++) {
        hid_t g = wf_h5_group(fid, groups[k], err);
        rc = g < 0 || (k == 2 && wf_h5_attr_str(g, "layout", "one row per vehicle on the road per frame, road order "
                                                "within a frame (front first)", err));
        if (g >= 0) H5Gclose(g);
    }
    /* From here on the structure changes only when chunks of /trips or /trajectories are added, after reserving
     * the space. */
    if (rc || wf_ckpt_series_create(fid, sp, ns, err) || wf_h5_flush(w->file, err))
        return setup_failed(w, ts_bytes, end_bytes, NULL, err);
    return 0;
}

/* A write error in the run: the file keeps what was written before it (its row counters say how much). */
static int write_failed(WfH5Corridor *w, int *group_failed, WfError *err)
{
    *group_failed = 1;
    return wf_err_prefix(err, "%s: ", w->file->partial);
}

/* Refuse to write to a group whose write failed before (the run stops at the first error anyway). */
static int group_failed(const WfH5Corridor *w, int failed, WfError *err)
{
    return failed ? wf_err(err, WF_ESYS, "%s: not written after an earlier write error", w->file->partial) : 0;
}

static int h5_record(void *ctx, const WfCorridor *c, const WfCorridorRow *row, WfError *err)
{
    (void)c;
    WfH5Corridor *w = ctx;
    if (group_failed(w, w->ts_failed, err)) return WF_ESYS;
    double *dst = w->buf + w->n_buf * (WF_CTS_N_COLS + w->n_classes);
    memcpy(dst, row->v, WF_CTS_N_COLS * sizeof(double));
    memcpy(dst + WF_CTS_N_COLS, row->class_fuel_rate_gps, w->n_classes * sizeof(double));
    if (++w->n_buf == TS_BUF && flush_ts(w, err)) return write_failed(w, &w->ts_failed, err);
    return 0;
}

/* One trajectory frame, in road order, through the frame buffer into the points' chunk; complete chunks are
 * written (src/io/h5util.h), then counted. */
static int h5_trajectory(void *ctx, const WfCorridor *c, double t, WfError *err)
{
    WfH5Corridor *w = ctx;
    if (group_failed(w, w->traj_failed, err)) return WF_ESYS;
    const double *data[N_TRAJ];
    size_t n = wf_corridor_traj_frame(wf_corridor_vehicles(c), t, w->frame, w->tcap, data);
    if (wf_h5_series_append(w->file, w->traj_s, N_TRAJ, n, data, "/trajectories", err) ||
        write_counts(w, WF_H5_FILL, err))
        return write_failed(w, &w->traj_failed, err);
    return 0;
}

/* Trips, a row at a time, into their chunk; complete chunks are written, then counted. */
static int h5_trips(void *ctx, const WfCorridor *c, const WfTrip *tr, size_t n, WfError *err)
{
    (void)c;
    WfH5Corridor *w = ctx;
    if (group_failed(w, w->trips_failed, err)) return WF_ESYS;
    for (size_t i = 0; i < n; i++) {
        double row[TR_N];
        const double *cols[TR_N];
        for (size_t k = 0; k < TR_N; k++) row[k] = wf_trip_value(&tr[i], k), cols[k] = &row[k];
        if (wf_h5_series_append(w->file, w->trip_s, TR_N, 1, cols, "/trips", err))
            return write_failed(w, &w->trips_failed, err);
    }
    if (write_counts(w, WF_H5_FILL, err)) return write_failed(w, &w->trips_failed, err);
    return 0;
}

static void close_series(WfH5Corridor *w)
{
    for (size_t k = 0; k < WF_CTS_N_COLS; k++) wf_h5_series_close(&w->ts[k]);
    wf_h5_series_close(&w->ts_class);
    for (size_t k = 0; k < TR_N; k++) wf_h5_series_close(&w->trips[k]);
    for (size_t k = 0; k < N_TRAJ; k++) wf_h5_series_close(&w->tr[k]);
    /* An open group would keep the file open past H5Fclose (weak close degree): close it too. */
    if (w->g_meta >= 0) H5Gclose(w->g_meta);
    w->g_meta = H5I_INVALID_HID;
}

static int h5_end(void *ctx, const WfCorridor *c, int completed, const char *reason, WfError *err)
{
    WfH5Corridor *w = ctx;
    w->ended = 1;
    hid_t fid = w->file->fid;
    /* The buffered records, trips and points, unless writing their group failed before (its counter stays true);
     * the end-of-run results and the status are written in place whatever happened before. Only the first error
     * is reported. */
    int rc = w->ts_failed ? 0 : flush_ts(w, err);
    if (!rc && !w->trips_failed && wf_h5_series_flush(w->file, w->trip_s, TR_N, "/trips", err)) rc = WF_ESYS;
    if (!rc && !w->traj_failed && w->tr[0].dset >= 0 &&
        wf_h5_series_flush(w->file, w->traj_s, N_TRAJ, "/trajectories", err))
        rc = WF_ESYS;
    if (!rc && write_counts(w, WF_H5_FILL, err)) rc = WF_ESYS;
    WfError later = {0};
    WfError *e = rc ? &later : err;
    if (write_detectors(fid, c, WF_H5_FILL, e) || write_edie(fid, c, WF_H5_FILL, e) ||
        write_summary(fid, c, WF_H5_FILL, e)) {
        if (!rc) rc = WF_ESYS;
        e = &later;
    }
    if (rc && completed) completed = 0, reason = err->msg;
    if (meta_status(w->g_meta, WF_H5_FILL, c, completed, reason, e) && !rc) rc = WF_ESYS;
    /* Open objects would keep the file open past H5Fclose: close them first. */
    close_series(w);
    if (rc) wf_err_prefix(err, "%s: ", w->file->partial);
    int done = !rc && completed;
    if (wf_h5_finish(&w->file, done, w->final_path, sizeof w->final_path, err)) return WF_ESYS;
    if (done) wf_ckpt_remove(w->final_path); /* the result is complete: its checkpoint is of no further use */
    return rc;
}

/* ---- checkpoints and resumption ---- */

static int h5_checkpoint(void *ctx, const WfCorridor *c, WfError *err)
{
    WfH5Corridor *w = ctx;
    const WfScenario *sc = wf_corridor_scenario(c);
    /* The result file must hold every row the checkpoint counts (but the pending rows it saves) before the
     * checkpoint exists. */
    if (flush_ts(w, err)) return write_failed(w, &w->ts_failed, err);
    if (wf_h5_flush(w->file, err)) return w->trips_failed = w->traj_failed = 1, write_failed(w, &w->ts_failed, err);
    WfStateVar vars[WF_MAX_STATE_VARS];
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    /* The blocks are only read here. */
    size_t nv = wf_corridor_state((WfCorridor *)c, vars, WF_MAX_STATE_VARS);
    return wf_ckpt_save(w->file->path, "corridor", sc, wf_corridor_steps_done(c), cursor_names, N_CUR, sp, ns, vars,
                        nv, err);
}

/* The reopened file back at the checkpoint: the counters at its rows (lowering a counter is always safe), trips and
 * trajectories cut to the whole chunks it counts (later rows are written again), then the status back to "running"
 * (should the cut fail, the file keeps the interrupted run's reason). */
static int resume_file(WfH5Corridor *w, const WfCorridor *c, WfError *err)
{
    w->g_meta = H5Gopen2(w->file->fid, "meta", H5P_DEFAULT);
    int rc = w->g_meta < 0 ? wf_err(err, WF_EINPUT, "no group /meta") : 0;
    if (!rc && (write_counts(w, WF_H5_FILL, err) || wf_h5_series_trim(w->file, w->trip_s, TR_N, err) ||
                wf_h5_series_trim(w->file, w->traj_s, wf_corridor_scenario(c)->trajectories ? N_TRAJ : 0, err) ||
                meta_status(w->g_meta, WF_H5_FILL, c, 0, "running", err) || wf_h5_flush(w->file, err)))
        rc = WF_ESYS;
    return rc ? wf_err_prefix(err, "%s: ", w->file->partial) : 0;
}

static WfCorridorOutput ops_of(WfH5Corridor *w)
{
    return (WfCorridorOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                              .trips = h5_trips, .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
}

int wf_h5corridor_create(const char *path, int force, WfH5Corridor **out, WfCorridorOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Corridor *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_writer(w);
    int rc = wf_h5_create(path, force, &w->file, err);
    if (rc) {
        free(w);
        return rc;
    }
    *ops = ops_of(w);
    *out = w;
    return 0;
}

int wf_h5corridor_resume(const char *result, WfCorridor *c, WfH5Corridor **out, WfCorridorOutput *ops,
                         WfError *err)
{
    *out = NULL;
    const WfScenario *sc = wf_corridor_scenario(c);
    WfH5Corridor *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_writer(w);
    w->resume = 1;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_corridor_state(c, vars, WF_MAX_STATE_VARS);
    /* The checkpoint and the partial file are read and verified completely before the file is changed. */
    int rc = wf_ckpt_restore(result, "corridor", sc, cursor_names, N_CUR, sp, ns, vars, nv, err);
    if (!rc) rc = wf_corridor_restored(c, err);
    if (!rc) rc = wf_ckpt_reopen(result, sc, sp, ns, &w->file, err);
    if (!rc) rc = resume_file(w, c, err);
    if (rc) {
        wf_h5corridor_destroy(&w);
        return rc;
    }
    *ops = ops_of(w);
    *out = w;
    return 0;
}

void wf_h5corridor_destroy(WfH5Corridor **pw)
{
    if (!pw || !*pw) return;
    WfH5Corridor *w = *pw;
    close_series(w);
    /* A run that never reached end() produced nothing useful; a resumed one never deletes what it reopened. */
    if (w->file) wf_h5_abandon(&w->file, !w->ended && !w->resume);
    free(w->buf);
    free(w->cls);
    free(w->frame);
    free(w);
    *pw = NULL;
}

const char *wf_h5corridor_path(const WfH5Corridor *w) { return w->final_path; }
