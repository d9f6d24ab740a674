/* HDF5 result files of corridor runs (docs/corridors.md): provenance, classes and drivers, the road, time series,
 * trips and trajectories appended as the run goes, detectors, Edie fields and the summary at the end. Every HDF5
 * call goes through src/h5util.h (checked, units on every dataset, .partial until the run completes). */
#include "wavefuel/h5corridor.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "h5ckpt.h"
#include "h5util.h"
#include "wavefuel/version.h"

#define TS_BUF     256
#define TS_CHUNK   1024  /* rows per chunk of the time series (uncompressed) */
#define TRIP_CHUNK 4096  /* ... of /trips (compressed) */
#define TRAJ_CHUNK 65536 /* ... of /trajectories (compressed) */
#define N_SERIES   (WF_CTS_N_COLS + 1 + TR_N + 6)

/* Columns of /trips, in the order of WfTrip's fields as written (float64; integers are exact below 2^53). */
enum { TR_SERIAL, TR_CLASS, TR_GROUP, TR_COMPLETED, TR_ARRIVAL, TR_ENTRY, TR_EXIT, TR_TRAVEL, TR_DELAY, TR_VENTRY,
       TR_FUEL, TR_DIST, TR_STOPS, TR_STOPPED, TR_HARD, TR_INFEAS, TR_N };
static const WfColumn trip_cols[TR_N] = {
    {"serial", "1", "arrival number of the vehicle (0, 1, ...): the key of its random draws"},
    {"class_id", "1", "index into /classes"},
    {"group_id", "1", "index into /drivers"},
    {"completed", "1", "1: the vehicle reached x = L; 0: still on the road at the end"},
    {"arrival_time", "s", "time the vehicle reached the entrance (joined the queue)"},
    {"entry_time", "s", "time it was inserted at x = 0"},
    {"exit_time", "s", "time its front reached x = L (end of that step; NaN when not completed)"},
    {"travel_time", "s", "exit_time - entry_time (NaN when not completed)"},
    {"queue_delay", "s", "entry_time - arrival_time"},
    {"entry_speed", "m/s", "speed at insertion"},
    {"fuel", "g", "fuel burnt on the road (whole trip, warm-up included)"},
    {"distance", "m", "distance travelled on the road"},
    {"stops", "1", "stops (docs/metrics.md) during the trip"},
    {"time_stopped", "s", "time slower than statistics.v_stop_mps during the trip"},
    {"hard_brakes", "1", "hard-braking events during the trip"},
    {"infeasible_steps", "1", "steps whose requested acceleration exceeded the class a_max"},
};

/* Columns of /trajectories, one row per vehicle on the road per frame. */
static const WfColumn traj_cols[6] = {
    {"t", "s", "time of each point"},
    {"serial", "1", "vehicle (trips/serial) of each point"},
    {"x", "m", "front-bumper position from the entrance"},
    {"v", "m/s", "speed"},
    {"a", "m/s^2", "acceleration applied from this instant"},
    {"fuel_rate", "g/s", "fuel rate"},
};

struct WfH5Corridor {
    WfH5File  *file;
    int        ended;
    char       final_path[1100];
    char       started[64];
    hid_t      g_ts, g_trips, g_traj;
    WfH5Series ts[WF_CTS_N_COLS], ts_class, trips[TR_N];
    WfH5Series tr_t, tr_id, tr_x, tr_v, tr_a, tr_f;
    double    *buf, *tbuf; /* TS_BUF time-series rows; one trajectory column of up to cap vehicles */
    size_t     n_buf, n_classes, tcap;
    int        resume;     /* reopened .partial of an interrupted run */
};

/* The appended datasets whose rows a checkpoint counts (src/h5ckpt.h). */
enum { CUR_TS, CUR_TRIPS, CUR_TRAJ, N_CUR };
static const char *const cursor_names[N_CUR] = {"timeseries", "trips", "trajectories"};

static int flush_ts(WfH5Corridor *w, WfError *err)
{
    if (!w->n_buf) return 0;
    size_t stride = WF_CTS_N_COLS + w->n_classes;
    double col[TS_BUF], cls[TS_BUF * WF_MAX_CLASSES];
    for (size_t c = 0; c < WF_CTS_N_COLS; c++) {
        for (size_t r = 0; r < w->n_buf; r++) col[r] = w->buf[r * stride + c];
        if (wf_h5_series_append(&w->ts[c], w->n_buf, col, err)) return WF_ESYS;
    }
    for (size_t r = 0; r < w->n_buf; r++)
        for (size_t c = 0; c < w->n_classes; c++) cls[r * w->n_classes + c] = w->buf[r * stride + WF_CTS_N_COLS + c];
    int rc = wf_h5_series_append(&w->ts_class, w->n_buf, cls, err);
    w->n_buf = 0;
    return rc;
}

static int write_meta(hid_t fid, const WfCorridor *c, int completed, const char *reason, const char *started,
                      WfError *err)
{
    const WfScenario *sc = wf_corridor_scenario(c);
    hid_t g = H5Gopen2(fid, "/meta", H5P_DEFAULT);
    int fresh = g < 0, rc = 0;
    if (fresh) g = wf_h5_group(fid, "meta", err);
    if (g < 0) return WF_ESYS;
    if (!fresh) {
        /* Rewritten at the end of the run: drop the provisional values. */
        const char *names[] = {"completed", "reason", "wall_time_s", "steps_done"};
        for (int i = 0; i < 4; i++)
            if (H5Lexists(g, names[i], H5P_DEFAULT) > 0) H5Ldelete(g, names[i], H5P_DEFAULT);
    } else {
        rc = wf_h5_scalar_str(g, "scenario_text", sc->text, "the scenario file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sc->path, "scenario file as given", err) ||
             wf_h5_scalar_str(g, "overrides", sc->overrides, "--set assignments applied, one per line", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", WF_GIT_HASH, "git describe of the source tree", err) ||
             wf_h5_scalar_str(g, "road_type", "corridor", "ring or corridor", err) ||
             wf_h5_scalar_i64(g, "seed", (int64_t)sc->seed, "1", "random seed", err) ||
             wf_h5_scalar_i64(g, "threads", wf_corridor_threads(c), "1", "OpenMP threads available to the run", err) ||
             wf_h5_scalar_str(g, "start_time", started, "wall-clock start, UTC ISO 8601", err) ||
             wf_h5_scalar_str(g, "integrator", sc->integrator, "time integrator", err) ||
             wf_h5_scalar_f64(g, "dt", sc->dt_s, "s", "time step", err) ||
             wf_h5_scalar_f64(g, "duration", sc->duration_s, "s", "simulated duration", err) ||
             wf_h5_scalar_f64(g, "warmup", sc->warmup_s, "s", "warm-up excluded from the window statistics", err) ||
             wf_h5_scalar_f64(g, "road_length", sc->road.length_m, "m", "corridor length L", err);
    }
    if (!rc)
        rc = wf_h5_scalar_i64(g, "completed", completed, "1", "1 when the run reached its end", err) ||
             wf_h5_scalar_str(g, "reason", reason, "why the run stopped early (empty when completed)", err) ||
             wf_h5_scalar_f64(g, "wall_time_s", wf_corridor_wall_s(c), "s", "wall time of the step loop", err) ||
             wf_h5_scalar_i64(g, "steps_done", wf_corridor_steps_done(c), "1", "time steps completed", err);
    H5Gclose(g);
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

/* Every appended dataset: its group, shape, chunking and compression, and the cursor that counts its rows. */
static size_t series_specs(WfH5Corridor *w, const WfScenario *sc, WfCkptSeries *sp)
{
    static const WfColumn class_col = {"class_fuel_rate", "g/s", "fuel rate of each class on the road [time x class]"};
    size_t n = 0;
    for (size_t k = 0; k < WF_CTS_N_COLS; k++)
        sp[n++] = (WfCkptSeries){&w->ts[k], "timeseries", &wf_corridor_columns[k], 0, TS_CHUNK, 0, CUR_TS};
    sp[n++] = (WfCkptSeries){&w->ts_class, "timeseries", &class_col, sc->n_classes, TS_CHUNK, 0, CUR_TS};
    for (size_t k = 0; k < TR_N; k++)
        sp[n++] = (WfCkptSeries){&w->trips[k], "trips", &trip_cols[k], 0, TRIP_CHUNK, 1, CUR_TRIPS};
    WfH5Series *tr[6] = {&w->tr_t, &w->tr_id, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t k = 0; sc->trajectories && k < 6; k++)
        sp[n++] = (WfCkptSeries){tr[k], "trajectories", &traj_cols[k], 0, TRAJ_CHUNK, 1, CUR_TRAJ};
    return n;
}

/* The time-series rows and one trajectory column, buffered (a resumed run reopened its file already). */
static int alloc_buffers(WfH5Corridor *w, const WfCorridor *c, WfError *err)
{
    w->n_classes = wf_corridor_scenario(c)->n_classes;
    w->buf = malloc(TS_BUF * (WF_CTS_N_COLS + w->n_classes) * sizeof *w->buf);
    if (!w->buf) return wf_err(err, WF_ESYS, "out of memory");
    if (wf_corridor_scenario(c)->trajectories) {
        w->tcap = wf_corridor_vehicles(c)->cap;
        w->tbuf = malloc(w->tcap * sizeof *w->tbuf);
        if (!w->tbuf) return wf_err(err, WF_ESYS, "out of memory for trajectories");
    }
    return 0;
}

static int h5_begin(void *ctx, const WfCorridor *c, WfError *err)
{
    WfH5Corridor *w = ctx;
    int rc = alloc_buffers(w, c, err);
    if (rc || w->resume) return rc;
    const WfScenario *sc = wf_corridor_scenario(c);
    hid_t fid = w->file->fid;
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(w->started, sizeof w->started, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    if (write_meta(fid, c, 0, "running", w->started, err) || write_classes_drivers(fid, c, err) ||
        write_road(fid, c, err))
        return WF_ESYS;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    w->g_ts = wf_h5_group(fid, "timeseries", err);
    w->g_trips = w->g_ts < 0 ? H5I_INVALID_HID : wf_h5_group(fid, "trips", err);
    w->g_traj = w->g_trips < 0 || !sc->trajectories ? H5I_INVALID_HID : wf_h5_group(fid, "trajectories", err);
    if (w->g_ts < 0 || w->g_trips < 0 || (sc->trajectories && w->g_traj < 0) ||
        wf_ckpt_series_create(fid, sp, ns, err))
        return WF_ESYS;
    if (sc->trajectories && wf_h5_attr_str(w->g_traj, "layout", "one row per vehicle on the road per frame, road "
                                           "order within a frame (front first)", err))
        return WF_ESYS;
    H5Fflush(fid, H5F_SCOPE_GLOBAL);
    return 0;
}

static int h5_record(void *ctx, const WfCorridor *c, const WfCorridorRow *row, WfError *err)
{
    (void)c;
    WfH5Corridor *w = ctx;
    double *dst = w->buf + w->n_buf * (WF_CTS_N_COLS + w->n_classes);
    memcpy(dst, row->v, WF_CTS_N_COLS * sizeof(double));
    memcpy(dst + WF_CTS_N_COLS, row->class_fuel_rate_gps, w->n_classes * sizeof(double));
    return ++w->n_buf == TS_BUF ? flush_ts(w, err) : 0;
}

/* One trajectory frame: a column at a time through the frame buffer (road order). */
static int h5_trajectory(void *ctx, const WfCorridor *c, double t, WfError *err)
{
    WfH5Corridor *w = ctx;
    const WfCorridorVehicles *vh = wf_corridor_vehicles(c);
    size_t n = vh->n;
    const double *src[] = {NULL, NULL, vh->x_m, vh->v_mps, vh->a_mps2, vh->fuel_rate_gps};
    WfH5Series *dst[] = {&w->tr_t, &w->tr_id, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (int col = 0; col < 6; col++) {
        for (size_t k = 0; k < n; k++) {
            size_t s = wf_corridor_slot(vh, k);
            w->tbuf[k] = col == 0 ? t : col == 1 ? (double)vh->serial[s] : src[col][s];
        }
        if (wf_h5_series_append(dst[col], n, w->tbuf, err)) return WF_ESYS;
    }
    return 0;
}

static int h5_trips(void *ctx, const WfCorridor *c, const WfTrip *tr, size_t n, WfError *err)
{
    (void)c;
    WfH5Corridor *w = ctx;
    double *col = malloc((n ? n : 1) * sizeof *col);
    if (!col) return wf_err(err, WF_ESYS, "out of memory");
    int rc = 0;
    for (size_t k = 0; !rc && k < TR_N; k++) {
        for (size_t i = 0; i < n; i++) {
            const WfTrip *t = &tr[i];
            double v;
            switch (k) {
            case TR_SERIAL: v = (double)t->serial; break;
            case TR_CLASS: v = t->class_id; break;
            case TR_GROUP: v = t->group_id; break;
            case TR_COMPLETED: v = t->completed; break;
            case TR_ARRIVAL: v = t->t_arrival_s; break;
            case TR_ENTRY: v = t->t_entry_s; break;
            case TR_EXIT: v = t->t_exit_s; break;
            case TR_TRAVEL: v = t->t_exit_s - t->t_entry_s; break;
            case TR_DELAY: v = t->t_entry_s - t->t_arrival_s; break;
            case TR_VENTRY: v = t->v_entry_mps; break;
            case TR_FUEL: v = t->fuel_g; break;
            case TR_DIST: v = t->dist_m; break;
            case TR_STOPS: v = t->stops; break;
            case TR_STOPPED: v = t->time_stopped_s; break;
            case TR_HARD: v = t->hard_brakes; break;
            default: v = t->infeasible_steps; break;
            }
            col[i] = v;
        }
        rc = wf_h5_series_append(&w->trips[k], n, col, err);
    }
    free(col);
    return rc ? WF_ESYS : 0;
}

static int write_detectors(hid_t fid, const WfCorridor *c, WfError *err)
{
    const WfDetectors *d = wf_corridor_detectors(c);
    const WfScenario *sc = wf_corridor_scenario(c);
    if (!d->n_det) return 0;
    size_t ni = d->n_int, nd = d->n_det, n = ni * nd;
    hid_t g = wf_h5_group(fid, "detectors", err);
    if (g < 0) return WF_ESYS;
    double *buf = malloc((n + ni + 1) * 5 * sizeof *buf);
    if (!buf) {
        H5Gclose(g);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    double *t0 = buf, *t1 = t0 + ni, *flow = t1 + ni, *vt = flow + n, *vh = vt + n, *occ = vh + n;
    for (size_t j = 0; j < ni; j++) {
        t0[j] = (double)j * d->interval_s;
        t1[j] = fmin((double)(j + 1) * d->interval_s, sc->duration_s);
    }
    for (size_t j = 0; j < ni; j++)
        for (size_t q = 0; q < nd; q++) {
            size_t i = j * nd + q;
            double len = t1[j] - t0[j], cnt = (double)d->count[i];
            flow[i] = cnt / len * 3600.0;
            vt[i] = cnt > 0 ? d->sum_v_mps[i] / cnt : NAN;
            vh[i] = cnt > 0 ? cnt / d->sum_inv_v_spm[i] : NAN;
            occ[i] = d->occupied_s[i] / len;
        }
    hsize_t dims[2] = {ni, nd}, dn = nd, dt = ni;
    int rc = wf_h5_write_f64(g, "x", 1, &dn, d->x_m, "m", "detector positions", err) ||
             wf_h5_write_f64(g, "t_start", 1, &dt, t0, "s", "start of each interval", err) ||
             wf_h5_write_f64(g, "t_end", 1, &dt, t1, "s", "end of each interval", err) ||
             wf_h5_write_i64(g, "count", 2, dims, d->count, "1",
                             "front-bumper passages [interval x detector] (a passage: x_before <= x_d < x_after)", err) ||
             wf_h5_write_f64(g, "flow", 2, dims, flow, "1/h", "passages per hour [interval x detector]", err) ||
             wf_h5_write_f64(g, "speed_time_mean", 2, dims, vt, "m/s",
                             "arithmetic mean speed of the passages (NaN without passages)", err) ||
             wf_h5_write_f64(g, "speed_harmonic_mean", 2, dims, vh, "m/s",
                             "harmonic mean speed of the passages (space-mean estimate; NaN without passages)", err) ||
             wf_h5_write_f64(g, "occupancy", 2, dims, occ, "1",
                             "share of the interval during which a vehicle body covered the detector point", err);
    free(buf);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_edie(hid_t fid, const WfCorridor *c, WfError *err)
{
    const WfEdie *e = wf_corridor_edie(c);
    const WfScenario *sc = wf_corridor_scenario(c);
    size_t nx = e->nx, nt = e->nt, n = nx * nt, nc = sc->n_classes;
    double L = sc->road.length_m;
    hid_t g = wf_h5_group(fid, "edie", err);
    if (g < 0) return WF_ESYS;
    double *buf = malloc((4 * n + 2 * (nx + 1) + 2 * (nt + 1) + nc * nx + 1) * sizeof *buf);
    if (!buf) {
        H5Gclose(g);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    double *xe = buf, *te = xe + nx + 1, *xc = te + nt + 1, *tc = xc + nx + 1, *q = tc + nt + 1, *k = q + n,
           *v = k + n, *f = v + n, *cpk = f + n;
    for (size_t i = 0; i <= nx; i++) xe[i] = i == nx ? L : (double)i * e->dx_m;
    for (size_t j = 0; j <= nt; j++) te[j] = j == nt ? sc->duration_s : (double)j * e->dt_s;
    for (size_t i = 0; i < nx; i++) xc[i] = 0.5 * (xe[i] + xe[i + 1]);
    for (size_t j = 0; j < nt; j++) tc[j] = 0.5 * (te[j] + te[j + 1]);
    /* |A| of each cell in m s (the last row and column may be shorter than dx, dt). */
    for (size_t j = 0; j < nt; j++)
        for (size_t i = 0; i < nx; i++) {
            size_t a = j * nx + i;
            double area = (xe[i + 1] - xe[i]) * (te[j + 1] - te[j]);
            q[a] = e->dist_m[a] / area * 3600.0;       /* veh/s -> veh/h */
            k[a] = e->time_s[a] / area * 1000.0;       /* veh/m -> veh/km */
            v[a] = e->time_s[a] > 0 ? e->dist_m[a] / e->time_s[a] : NAN;
            f[a] = e->fuel_g[a] / area * 3.6e6;        /* g/(m s) -> g/(km h) */
        }
    for (size_t a = 0; a < nc * nx; a++)
        cpk[a] = e->class_dist_m[a] > 0 ? e->class_fuel_g[a] / (e->class_dist_m[a] / 1000.0) : NAN;
    hsize_t d2[2] = {nt, nx}, dc[2] = {nc, nx}, dxe = nx + 1, dte = nt + 1, dx = nx, dt = nt;
    int rc = wf_h5_write_f64(g, "x_edges", 1, &dxe, xe, "m", "cell edges along the road", err) ||
             wf_h5_write_f64(g, "t_edges", 1, &dte, te, "s", "cell edges in time", err) ||
             wf_h5_write_f64(g, "x", 1, &dx, xc, "m", "cell centres along the road", err) ||
             wf_h5_write_f64(g, "t", 1, &dt, tc, "s", "cell centres in time", err) ||
             wf_h5_write_f64(g, "flow", 2, d2, q, "1/h", "Edie flow q = sum of distances / |A| [t x x]", err) ||
             wf_h5_write_f64(g, "density", 2, d2, k, "1/km", "Edie density k = sum of times / |A| [t x x]", err) ||
             wf_h5_write_f64(g, "speed", 2, d2, v, "m/s", "Edie speed v = q / k [t x x] (NaN where k = 0)", err) ||
             wf_h5_write_f64(g, "fuel", 2, d2, f, "g/(km h)",
                             "fuel burnt in the cell per km of road per hour [t x x]", err) ||
             wf_h5_write_f64(g, "distance", 2, d2, e->dist_m, "m", "sum of distances travelled in the cell", err) ||
             wf_h5_write_f64(g, "time", 2, d2, e->time_s, "s", "sum of times spent in the cell", err) ||
             wf_h5_write_f64(g, "fuel_mass", 2, d2, e->fuel_g, "g", "fuel burnt in the cell", err) ||
             wf_h5_write_f64(g, "grade", 1, &dx, e->grade_mean_rad, "rad", "mean grade of each cell column", err) ||
             wf_h5_write_f64(g, "class_fuel", 2, dc, e->class_fuel_g, "g",
                             "fuel burnt per class and cell column in the statistics window [class x x]", err) ||
             wf_h5_write_f64(g, "class_distance", 2, dc, e->class_dist_m, "m",
                             "distance per class and cell column in the statistics window [class x x]", err) ||
             wf_h5_write_f64(g, "class_fuel_per_km", 2, dc, cpk, "g/km",
                             "fuel per vehicle-km per class and cell column in the window (NaN: no distance)", err);
    const char *fields[] = {"flow", "density", "speed", "fuel", "distance", "time", "fuel_mass"};
    for (size_t i = 0; !rc && i < sizeof fields / sizeof fields[0]; i++) {
        hid_t d = H5Dopen2(g, fields[i], H5P_DEFAULT);
        if (d < 0) rc = wf_err(err, WF_ESYS, "HDF5: cannot reopen /edie/%s", fields[i]);
        else rc = wf_h5_attr_str(d, "axes", "t_edges, x_edges (rows: time cells; columns: space cells)", err);
        if (d >= 0) H5Dclose(d);
    }
    if (!rc) rc = wf_h5_attr_f64(g, "dx_m", e->dx_m, err) || wf_h5_attr_f64(g, "dt_s", e->dt_s, err);
    free(buf);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_summary(hid_t fid, const WfCorridor *c, WfError *err)
{
    const WfCorridorSummary *s = wf_corridor_summary(c);
    const WfScenario *sc = wf_corridor_scenario(c);
    const WfCorridorCounts *n = &s->counts;
    hid_t g = wf_h5_group(fid, "summary", err);
    if (g < 0) return WF_ESYS;
    int rc = wf_h5_scalar_f64(g, "window", s->window_s, "s", "statistics window (after warm-up)", err) ||
             wf_h5_scalar_f64(g, "fuel", s->fuel_g, "g", "fuel burnt on the road in the window", err) ||
             wf_h5_scalar_f64(g, "distance", s->dist_m, "m", "distance travelled on the road in the window", err) ||
             wf_h5_scalar_f64(g, "vkt", s->vkt_km, "km", "vehicle-kilometres travelled in the window", err) ||
             wf_h5_scalar_f64(g, "vht", s->vht_h, "h", "vehicle-hours on the road in the window", err) ||
             wf_h5_scalar_f64(g, "l_per_100km", s->l_per_100km, "L/100km", "fleet fuel economy", err) ||
             wf_h5_scalar_f64(g, "mpg", s->mpg, "mi/gal", "fleet fuel economy", err) ||
             wf_h5_scalar_f64(g, "stops_per_vkm", s->stops_per_vkm, "1/km", "stops per vehicle-km", err) ||
             wf_h5_scalar_f64(g, "hard_brakes_per_vkm", s->hard_brakes_per_vkm, "1/km",
                              "hard-braking events per vehicle-km", err) ||
             wf_h5_scalar_f64(g, "mean_speed", s->mean_speed_mps, "m/s", "distance / vehicle-time in the window", err) ||
             wf_h5_scalar_f64(g, "sd_speed_time_avg", s->sd_speed_time_avg_mps, "m/s",
                              "mean over the window's records of the speed s.d. across vehicles", err) ||
             wf_h5_scalar_f64(g, "inflow", s->inflow_vph, "1/h", "entries per hour in the window", err) ||
             wf_h5_scalar_f64(g, "outflow", s->outflow_vph, "1/h", "exits per hour in the window", err) ||
             wf_h5_scalar_f64(g, "infeasible_share", s->infeasible_share, "1",
                              "share of vehicle-steps with an infeasible acceleration request", err) ||
             wf_h5_scalar_f64(g, "time_stopped_share", s->time_stopped_share, "1", "share of time stopped", err) ||
             wf_h5_scalar_i64(g, "trips", s->trips, "1", "completed trips (whole run)", err) ||
             wf_h5_scalar_f64(g, "mean_travel_time", s->mean_travel_time_s, "s", "mean over completed trips", err) ||
             wf_h5_scalar_f64(g, "mean_trip_fuel", s->mean_trip_fuel_g, "g", "mean over completed trips", err) ||
             wf_h5_scalar_f64(g, "mean_queue_delay", s->mean_queue_delay_s, "s", "mean wait of the entered vehicles",
                              err) ||
             wf_h5_scalar_i64(g, "arrived", n->arrived, "1", "vehicles that reached the entrance", err) ||
             wf_h5_scalar_i64(g, "entered", n->entered, "1", "vehicles inserted at x = 0", err) ||
             wf_h5_scalar_i64(g, "exited", n->exited, "1", "vehicles that left at x = L", err) ||
             wf_h5_scalar_i64(g, "on_road", n->entered - n->exited, "1", "vehicles on the road at the end", err) ||
             wf_h5_scalar_i64(g, "queued", n->queued, "1", "vehicles waiting at the entrance at the end", err) ||
             wf_h5_scalar_i64(g, "delayed", n->delayed, "1", "entries that waited at least one step", err) ||
             wf_h5_scalar_i64(g, "max_queue", n->max_queue, "1", "longest entrance queue", err) ||
             wf_h5_scalar_i64(g, "overlaps", n->overlaps, "1", "overlap repairs", err);
    hsize_t nc = sc->n_classes;
    double a[WF_MAX_CLASSES];
#define CLS(name, expr, units, desc)                                  \
    if (!rc) {                                                        \
        for (size_t k = 0; k < nc; k++) a[k] = (double)(s->cls[k].expr); \
        rc = wf_h5_write_f64(g, name, 1, &nc, a, units, desc, err);   \
    }
    CLS("class_entered", entered, "1", "vehicles of the class that entered");
    CLS("class_trips", trips, "1", "completed trips per class");
    CLS("class_fuel", fuel_g, "g", "fuel per class in the window");
    CLS("class_distance", dist_m, "m", "distance per class in the window");
    CLS("class_l_per_100km", l_per_100km, "L/100km", "fuel economy per class");
    CLS("class_mpg", mpg, "mi/gal", "fuel economy per class");
    CLS("class_stops_per_vkm", stops_per_vkm, "1/km", "stops per vehicle-km per class");
    CLS("class_infeasible_share", infeasible_share, "1", "infeasible acceleration share per class");
    CLS("class_g_per_km_up", g_per_km_up, "g/km", "fuel per vehicle-km on climbing cells (mean grade > 1e-4 rad)");
    CLS("class_g_per_km_down", g_per_km_down, "g/km", "fuel per vehicle-km on descending cells (< -1e-4 rad)");
    CLS("class_g_per_km_flat", g_per_km_flat, "g/km", "fuel per vehicle-km on the other cells");
    CLS("class_trip_fuel_mean", trip_fuel_mean_g, "g", "mean fuel of the class's completed trips");
    CLS("class_trip_time_mean", trip_time_mean_s, "s", "mean travel time of the class's completed trips");
#undef CLS
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static void close_series(WfH5Corridor *w)
{
    for (size_t k = 0; k < WF_CTS_N_COLS; k++) wf_h5_series_close(&w->ts[k]);
    for (size_t k = 0; k < TR_N; k++) wf_h5_series_close(&w->trips[k]);
    WfH5Series *o[] = {&w->ts_class, &w->tr_t, &w->tr_id, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t k = 0; k < sizeof o / sizeof o[0]; k++) wf_h5_series_close(o[k]);
    hid_t *gs[] = {&w->g_ts, &w->g_trips, &w->g_traj};
    for (size_t k = 0; k < 3; k++) {
        if (*gs[k] >= 0) H5Gclose(*gs[k]);
        *gs[k] = H5I_INVALID_HID;
    }
}

/* The rows still in memory: the time-series buffer and the incomplete chunks of the compressed series. */
static int flush_all(WfH5Corridor *w, const WfScenario *sc, WfError *err)
{
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    int rc = flush_ts(w, err);
    for (size_t i = 0; !rc && i < ns; i++) rc = wf_h5_series_flush(sp[i].s, err);
    return rc;
}

static int h5_end(void *ctx, const WfCorridor *c, int completed, const char *reason, WfError *err)
{
    WfH5Corridor *w = ctx;
    w->ended = 1;
    hid_t fid = w->file->fid;
    int rc = flush_all(w, wf_corridor_scenario(c), err);
    if (!rc) rc = write_detectors(fid, c, err);
    if (!rc) rc = write_edie(fid, c, err);
    if (!rc) rc = write_summary(fid, c, err);
    if (!rc) rc = write_meta(fid, c, completed, reason, w->started, err);
    /* Open objects would keep the file open past H5Fclose: close them first. */
    close_series(w);
    if (rc || !completed) {
        snprintf(w->final_path, sizeof w->final_path, "%s", w->file->partial);
        wf_h5_abandon(&w->file, 0);
        return rc;
    }
    snprintf(w->final_path, sizeof w->final_path, "%s", w->file->path);
    rc = wf_h5_commit(&w->file, err);
    if (!rc) wf_ckpt_remove(w->final_path); /* the result is complete: its checkpoint is of no further use */
    return rc;
}

/* ---- checkpoints and resumption ---- */

static int h5_checkpoint(void *ctx, const WfCorridor *c, WfError *err)
{
    WfH5Corridor *w = ctx;
    const WfScenario *sc = wf_corridor_scenario(c);
    if (flush_ts(w, err)) return wf_err_prefix(err, "%s: ", w->file->partial);
    /* The result file must hold every row the checkpoint counts (but those it saves) before the checkpoint exists. */
    if (H5Fflush(w->file->fid, H5F_SCOPE_GLOBAL) < 0) return wf_err(err, WF_ESYS, "HDF5: flush %s", w->file->partial);
    WfStateVar vars[WF_MAX_STATE_VARS];
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    /* The blocks are only read here. */
    size_t nv = wf_corridor_state((WfCorridor *)c, vars, WF_MAX_STATE_VARS);
    return wf_ckpt_save(w->file->path, "corridor", sc, wf_corridor_steps_done(c), cursor_names, N_CUR, sp, ns, vars,
                        nv, err);
}

static void init_handles(WfH5Corridor *w)
{
    w->g_ts = w->g_trips = w->g_traj = H5I_INVALID_HID;
    for (size_t k = 0; k < WF_CTS_N_COLS; k++) w->ts[k].dset = H5I_INVALID_HID;
    for (size_t k = 0; k < TR_N; k++) w->trips[k].dset = H5I_INVALID_HID;
    WfH5Series *o[] = {&w->ts_class, &w->tr_t, &w->tr_id, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t k = 0; k < sizeof o / sizeof o[0]; k++) o[k]->dset = H5I_INVALID_HID;
}

int wf_h5corridor_create(const char *path, int force, WfH5Corridor **out, WfCorridorOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Corridor *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_handles(w);
    int rc = wf_h5_create(path, force, &w->file, err);
    if (rc) {
        free(w);
        return rc;
    }
    *ops = (WfCorridorOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                              .trips = h5_trips, .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
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
    init_handles(w);
    w->resume = 1;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sc, sp);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_corridor_state(c, vars, WF_MAX_STATE_VARS);
    /* What the interrupted run wrote at its end (detectors, Edie fields, summary) is written again at the end. */
    static const char *const stale[] = {"detectors", "edie", "summary"};
    /* The checkpoint is read and verified completely before the partial file is touched. */
    int rc = wf_ckpt_restore(result, "corridor", sc, cursor_names, N_CUR, sp, ns, vars, nv, err);
    if (!rc) rc = wf_corridor_restored(c, err);
    if (!rc) rc = wf_ckpt_reopen(result, sc, sp, ns, stale, 3, &w->file, err);
    if (rc) {
        wf_h5corridor_destroy(&w);
        return rc;
    }
    *ops = (WfCorridorOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                              .trips = h5_trips, .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
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
    free(w->tbuf);
    free(w);
    *pw = NULL;
}

const char *wf_h5corridor_path(const WfH5Corridor *w) { return w->final_path; }
