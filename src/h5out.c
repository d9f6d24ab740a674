/* HDF5 result files of simulation runs: /meta, /classes, /drivers, /vehicles, /timeseries, /summary and
 * optional /trajectories (docs/output.md). Time series are buffered and appended in blocks of rows. */
#include "wavefuel/h5out.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "h5ckpt.h"
#include "h5util.h"
#include "wavefuel/version.h"

#define TS_BUF 256

/* Columns of /trajectories. */
static const WfColumn traj_cols[5] = {
    {"t", "s", "time of each frame"},
    {"x", "m", "unwrapped front-bumper position [time x vehicle]"},
    {"v", "m/s", "speed [time x vehicle]"},
    {"a", "m/s^2", "acceleration applied from this instant"},
    {"fuel_rate", "g/s", "fuel rate [time x vehicle]"},
};

/* The appended datasets whose rows a checkpoint counts (src/h5ckpt.h). */
enum { CUR_TS, CUR_TRAJ, N_CUR };
static const char *const cursor_names[N_CUR] = {"timeseries", "trajectories"};
#define N_SERIES (WF_TS_N_COLS + 1 + 5)

struct WfH5Out {
    WfH5File  *file;
    int        ended;
    char       final_path[1100];
    hid_t      g_ts, g_traj;
    WfH5Series ts[WF_TS_N_COLS], ts_class;
    WfH5Series tr_t, tr_x, tr_v, tr_a, tr_f;
    double    *buf;      /* TS_BUF x (WF_TS_N_COLS + n_classes) */
    size_t     n_buf, n_classes;
    char       started[64];
    int        resume;                  /* reopened .partial of an interrupted run */
};

/* Every appended dataset: group, shape, chunking, compression and the cursor that counts its rows. Time series
 * and frame times are uncompressed; the [time x vehicle] arrays compressed, in chunks of up to 16 frames. */
static size_t series_specs(WfH5Out *w, const WfSim *sim, WfCkptSeries *sp)
{
    static const WfColumn class_col = {"class_fuel_rate", "g/s", "fuel rate of each class [time x class]"};
    const WfScenario *sc = wf_sim_scenario(sim);
    hsize_t n = wf_sim_fleet(sim)->n;
    size_t k = 0;
    for (size_t c = 0; c < WF_TS_N_COLS; c++)
        sp[k++] = (WfCkptSeries){&w->ts[c], "timeseries", &wf_ts_columns[c], 0, 1024, 0, CUR_TS};
    sp[k++] = (WfCkptSeries){&w->ts_class, "timeseries", &class_col, sc->n_classes, 1024, 0, CUR_TS};
    WfH5Series *tr[5] = {&w->tr_t, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t i = 0; sc->trajectories && i < 5; i++)
        sp[k++] = (WfCkptSeries){tr[i], "trajectories", &traj_cols[i], i ? n : 0, i ? 16 : 1024, i > 0, CUR_TRAJ};
    return k;
}

static int flush_ts(WfH5Out *w, WfError *err)
{
    if (!w->n_buf) return 0;
    size_t stride = WF_TS_N_COLS + w->n_classes;
    double col[TS_BUF];
    for (size_t c = 0; c < WF_TS_N_COLS; c++) {
        for (size_t r = 0; r < w->n_buf; r++) col[r] = w->buf[r * stride + c];
        if (wf_h5_series_append(&w->ts[c], w->n_buf, col, err)) return WF_ESYS;
    }
    double *cls = malloc(w->n_buf * (w->n_classes ? w->n_classes : 1) * sizeof *cls);
    if (!cls) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t r = 0; r < w->n_buf; r++)
        for (size_t c = 0; c < w->n_classes; c++) cls[r * w->n_classes + c] = w->buf[r * stride + WF_TS_N_COLS + c];
    int rc = wf_h5_series_append(&w->ts_class, w->n_buf, cls, err);
    free(cls);
    w->n_buf = 0;
    return rc;
}

static int write_meta(hid_t fid, const WfSim *sim, int completed, const char *reason, const char *started,
                      WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    hid_t g = H5Gopen2(fid, "/meta", H5P_DEFAULT);
    int fresh = g < 0;
    if (fresh) g = wf_h5_group(fid, "meta", err);
    if (g < 0) return WF_ESYS;
    int rc = 0;
    if (!fresh) {
        /* Rewritten at the end of the run: drop the provisional values. */
        const char *names[] = {"completed", "reason", "wall_time_s", "steps_done"};
        for (int i = 0; i < 4; i++)
            if (H5Lexists(g, names[i], H5P_DEFAULT) > 0) H5Ldelete(g, names[i], H5P_DEFAULT);
    }
    if (fresh) {
        rc = wf_h5_scalar_str(g, "scenario_text", sc->text, "the scenario file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sc->path, "scenario file as given", err) ||
             wf_h5_scalar_str(g, "overrides", sc->overrides, "--set assignments applied, one per line", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", WF_GIT_HASH, "git describe of the source tree", err) ||
             wf_h5_scalar_i64(g, "seed", (int64_t)sc->seed, "1", "random seed", err) ||
             wf_h5_scalar_i64(g, "threads", wf_sim_threads(sim), "1", "OpenMP threads available to the run", err) ||
             wf_h5_scalar_str(g, "start_time", started, "wall-clock start, UTC ISO 8601", err) ||
             wf_h5_scalar_str(g, "integrator", sc->integrator, "time integrator", err) ||
             wf_h5_scalar_f64(g, "dt", sc->dt_s, "s", "time step", err) ||
             wf_h5_scalar_f64(g, "duration", sc->duration_s, "s", "simulated duration", err) ||
             wf_h5_scalar_f64(g, "warmup", sc->warmup_s, "s", "warm-up excluded from statistics", err) ||
             wf_h5_scalar_f64(g, "road_length", sc->road.length_m, "m", "ring length", err) ||
             wf_h5_scalar_f64(g, "initial_speed", wf_sim_fleet(sim)->v_init_mps, "m/s",
                              "common speed of the initial equilibrium (0 when starting at rest)", err);
    }
    if (!rc)
        rc = wf_h5_scalar_i64(g, "completed", completed, "1", "1 when the run reached its end", err) ||
             wf_h5_scalar_str(g, "reason", reason, "why the run stopped early (empty when completed)", err) ||
             wf_h5_scalar_f64(g, "wall_time_s", wf_sim_wall_s(sim), "s", "wall time of the step loop", err) ||
             wf_h5_scalar_i64(g, "steps_done", wf_sim_steps_done(sim), "1", "time steps completed", err);
    if (!rc) {
        hsize_t np = WF_N_PHASES;
        if (H5Lexists(g, "phase_time", H5P_DEFAULT) > 0) H5Ldelete(g, "phase_time", H5P_DEFAULT);
        if (H5Lexists(g, "phase_name", H5P_DEFAULT) > 0) H5Ldelete(g, "phase_name", H5P_DEFAULT);
        rc = wf_h5_write_f64(g, "phase_time", 1, &np, wf_sim_phase_times(sim), "s",
                             "wall time per phase of the step loop, in the order of phase_name", err) ||
             wf_h5_write_strings(g, "phase_name", np, wf_phase_names, "phases of phase_time", err);
    }
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_classes_drivers(hid_t fid, const WfSim *sim, WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    const WfFleet *f = wf_sim_fleet(sim);
    hid_t g = wf_h5_group(fid, "classes", err);
    if (g < 0) return WF_ESYS;
    const char *names[WF_MAX_CLASSES], *labels[WF_MAX_CLASSES], *fuels[WF_MAX_CLASSES], *duty[WF_MAX_CLASSES];
    int64_t counts[WF_MAX_CLASSES];
    double len[WF_MAX_CLASSES], dens[WF_MAX_CLASSES], kw[WF_MAX_CLASSES];
    hsize_t nc = sc->n_classes;
    for (size_t c = 0; c < sc->n_classes; c++) {
        const WfVehicleClass *vc = &sc->classes[c].vc;
        names[c] = vc->name, labels[c] = vc->label, fuels[c] = wf_fuel_name(vc->fuel), duty[c] = wf_duty_name(vc->duty);
        counts[c] = (int64_t)f->class_n[c];
        len[c] = sc->classes[c].length_m, dens[c] = vc->fuel_density_g_per_l, kw[c] = vc->kw_per_gps;
    }
    int rc = wf_h5_write_strings(g, "name", nc, names, "class name (vehicles/NAME.yaml); index = class_id", err) ||
             wf_h5_write_strings(g, "label", nc, labels, "human-readable class name", err) ||
             wf_h5_write_strings(g, "fuel", nc, fuels, "fuel type", err) ||
             wf_h5_write_strings(g, "duty", nc, duty, "light or heavy duty", err) ||
             wf_h5_write_i64(g, "count", 1, &nc, counts, "1", "vehicles of the class", err) ||
             wf_h5_write_f64(g, "length", 1, &nc, len, "m", "vehicle length used", err) ||
             wf_h5_write_f64(g, "fuel_density", 1, &nc, dens, "g/L", "fuel density for volume units", err) ||
             wf_h5_write_f64(g, "kw_per_gps", 1, &nc, kw, "kW/(g/s)", "equivalent power per fuel rate", err);
    /* Each class's energy-model parameters, one scalar per key, with the key's unit. */
    for (size_t c = 0; !rc && c < sc->n_classes; c++) {
        const WfVehicleClass *vc = &sc->classes[c].vc;
        char path[200];
        snprintf(path, sizeof path, "params/%s", vc->name);
        hid_t pg = wf_h5_group(g, path, err);
        if (pg < 0) {
            rc = WF_ESYS;
            break;
        }
        rc = wf_h5_attr_str(pg, "energy_model", vc->model->name, err) || wf_h5_attr_str(pg, "file", vc->path, err);
        for (size_t k = 0; !rc && k < vc->model->n_spec; k++) {
            double v = wf_param_get(vc->params, &vc->model->spec[k]);
            if (!isnan(v))
                rc = wf_h5_scalar_f64(pg, vc->model->spec[k].key, v, vc->model->spec[k].unit, vc->model->spec[k].doc,
                                      err);
        }
        H5Gclose(pg);
    }
    H5Gclose(g);
    if (rc) return WF_ESYS;

    g = wf_h5_group(fid, "drivers", err);
    if (g < 0) return WF_ESYS;
    const char *gn[WF_MAX_GROUPS], *gm[WF_MAX_GROUPS];
    int64_t gc[WF_MAX_GROUPS];
    double noise[WF_MAX_GROUPS];
    hsize_t ng = sc->n_groups;
    for (size_t k = 0; k < sc->n_groups; k++)
        gn[k] = sc->groups[k].name, gm[k] = sc->groups[k].model->name, gc[k] = (int64_t)f->group_n[k],
        noise[k] = sc->groups[k].noise_mps2;
    rc = wf_h5_write_strings(g, "name", ng, gn, "driver group name; index = group_id", err) ||
         wf_h5_write_strings(g, "model", ng, gm, "car-following model or controller", err) ||
         wf_h5_write_i64(g, "count", 1, &ng, gc, "1", "vehicles in the group", err) ||
         wf_h5_write_f64(g, "noise", 1, &ng, noise, "m/s^2", "acceleration noise standard deviation", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int h5_begin(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Out *w = ctx;
    const WfScenario *sc = wf_sim_scenario(sim);
    w->n_classes = sc->n_classes;
    w->buf = malloc(TS_BUF * (WF_TS_N_COLS + w->n_classes) * sizeof *w->buf);
    if (!w->buf) return wf_err(err, WF_ESYS, "out of memory");
    if (w->resume) return 0; /* wf_h5out_resume reopened the file and its datasets */
    hid_t fid = w->file->fid;
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(w->started, sizeof w->started, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    if (write_meta(fid, sim, 0, "running", w->started, err) || write_classes_drivers(fid, sim, err)) return WF_ESYS;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    w->g_ts = wf_h5_group(fid, "timeseries", err);
    w->g_traj = w->g_ts < 0 || !sc->trajectories ? H5I_INVALID_HID : wf_h5_group(fid, "trajectories", err);
    if (w->g_ts < 0 || (sc->trajectories && w->g_traj < 0) || wf_ckpt_series_create(fid, sp, ns, err))
        return WF_ESYS;
    if (sc->trajectories && wf_h5_attr_f64(w->g_traj, "ring_length_m", sc->road.length_m, err)) return WF_ESYS;
    H5Fflush(fid, H5F_SCOPE_GLOBAL);
    return 0;
}

static int h5_record(void *ctx, const WfSim *sim, const WfTsRow *row, WfError *err)
{
    (void)sim;
    WfH5Out *w = ctx;
    double *dst = w->buf + w->n_buf * (WF_TS_N_COLS + w->n_classes);
    memcpy(dst, row->v, WF_TS_N_COLS * sizeof(double));
    memcpy(dst + WF_TS_N_COLS, row->class_fuel_rate_gps, w->n_classes * sizeof(double));
    if (++w->n_buf == TS_BUF && flush_ts(w, err)) return wf_err_prefix(err, "%s: ", w->file->partial);
    return 0;
}

static int h5_trajectory(void *ctx, const WfSim *sim, double t, WfError *err)
{
    WfH5Out *w = ctx;
    const WfFleet *f = wf_sim_fleet(sim);
    if (wf_h5_series_append(&w->tr_t, 1, &t, err) || wf_h5_series_append(&w->tr_x, 1, f->x_m, err) ||
        wf_h5_series_append(&w->tr_v, 1, f->v_mps, err) || wf_h5_series_append(&w->tr_a, 1, f->a_mps2, err) ||
        wf_h5_series_append(&w->tr_f, 1, f->fuel_rate_gps, err))
        return wf_err_prefix(err, "%s: ", w->file->partial);
    return 0;
}

static int write_vehicles(hid_t fid, const WfSim *sim, WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    const WfFleet *f = wf_sim_fleet(sim);
    const WfSummary *s = wf_sim_summary(sim);
    size_t n = f->n;
    hsize_t dn = n;
    double win_steps = s->window_s / sc->dt_s;
    hid_t g = wf_h5_group(fid, "vehicles", err);
    if (g < 0) return WF_ESYS;
    /* One buffer for both element types (8 bytes each): at 10^7 vehicles a second one would be 80 MB more peak. */
    double *d = malloc(n * sizeof *d);
    int64_t *k = (int64_t *)d;
    int rc = !d ? wf_err(err, WF_ESYS, "out of memory") : 0;
#define I64(name, expr, units, desc)                                                   \
    if (!rc) {                                                                         \
        for (size_t i = 0; i < n; i++) k[i] = (int64_t)(expr);                         \
        rc = wf_h5_write_i64(g, name, 1, &dn, k, units, desc, err);                    \
    }
#define F64(name, expr, units, desc)                                                   \
    if (!rc) {                                                                         \
        for (size_t i = 0; i < n; i++) d[i] = (expr);                                  \
        rc = wf_h5_write_f64(g, name, 1, &dn, d, units, desc, err);                    \
    }
    I64("class_id", f->class_id[i], "1", "index into /classes");
    I64("group_id", f->group_id[i], "1", "index into /drivers");
    F64("length", wf_fleet_length(f, i), "m", "vehicle length");
    F64("distance", wf_fleet_distance(f, i), "m", "distance travelled in the statistics window");
    F64("fuel", f->fuel_g[i], "g", "fuel burnt in the statistics window");
    F64("l_per_100km", wf_l_per_100km(&sc->classes[f->class_id[i]].vc, f->fuel_g[i], wf_fleet_distance(f, i)), "L/100km",
        "fuel economy (volume per distance)");
    F64("mpg", wf_mpg(&sc->classes[f->class_id[i]].vc, f->fuel_g[i], wf_fleet_distance(f, i)), "mi/gal",
        "fuel economy (US miles per US gallon)");
    I64("stops", f->stops[i], "1", "stops: speed fell below v_stop after exceeding v_go");
    F64("time_stopped", (double)f->stopped_steps[i] * sc->dt_s, "s", "time spent slower than v_stop");
    F64("mean_speed", s->window_s > 0 ? wf_fleet_distance(f, i) / s->window_s : 0.0, "m/s", "distance / window length");
    F64("speed_var",
        win_steps > 0 ? fmax(0.0, f->sum_v2[i] / win_steps - (f->sum_v[i] / win_steps) * (f->sum_v[i] / win_steps))
                      : 0.0,
        "m^2/s^2", "variance of the vehicle's speed over time (step samples)");
    F64("accel_var",
        win_steps > 0 ? fmax(0.0, f->sum_a2[i] / win_steps - (f->sum_a[i] / win_steps) * (f->sum_a[i] / win_steps))
                      : 0.0,
        "m^2/s^4", "variance of the vehicle's acceleration over time (step samples)");
    I64("hard_brakes", f->hard_brakes[i], "1", "hard-braking events: a fell below -statistics.hard_brake_mps2");
    I64("infeasible_steps", f->infeasible_steps[i], "1", "steps whose acceleration exceeded the class a_max");
    F64("final_x", f->x_m[i], "m", "unwrapped position at the end");
    F64("final_v", f->v_mps[i], "m/s", "speed at the end");
    /* Every driver-model parameter drawn for each vehicle; NaN for vehicles whose model lacks the key. */
    for (size_t gi = 0; !rc && gi < sc->n_groups; gi++) {
        const WfCfModel *m = sc->groups[gi].model;
        for (size_t p = 0; !rc && p < m->n_spec; p++) {
            char name[160];
            snprintf(name, sizeof name, "param_%s", m->spec[p].key);
            if (H5Lexists(g, name, H5P_DEFAULT) > 0) continue;
            for (size_t i = 0; i < n; i++) {
                const WfCfModel *mi = sc->groups[f->group_id[i]].model;
                const WfParamSpec *sp = wf_param_find(mi->spec, mi->n_spec, m->spec[p].key);
                d[i] = sp ? wf_param_get(wf_fleet_params(f, sc, i), sp) : NAN;
            }
            rc = wf_h5_write_f64(g, name, 1, &dn, d, m->spec[p].unit, m->spec[p].doc, err);
        }
    }
#undef I64
#undef F64
    free(d);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_summary(hid_t fid, const WfSim *sim, WfError *err)
{
    const WfSummary *s = wf_sim_summary(sim);
    const WfScenario *sc = wf_sim_scenario(sim);
    hid_t g = wf_h5_group(fid, "summary", err);
    if (g < 0) return WF_ESYS;
    int rc = wf_h5_scalar_f64(g, "window", s->window_s, "s", "statistics window (after warm-up)", err) ||
             wf_h5_scalar_f64(g, "fuel", s->fuel_g, "g", "fleet fuel in the window", err) ||
             wf_h5_scalar_f64(g, "distance", s->dist_m, "m", "fleet distance in the window", err) ||
             wf_h5_scalar_f64(g, "vkt", s->vkt_km, "km", "vehicle-kilometres travelled", err) ||
             wf_h5_scalar_f64(g, "l_per_100km", s->l_per_100km, "L/100km", "fleet fuel economy", err) ||
             wf_h5_scalar_f64(g, "mpg", s->mpg, "mi/gal", "fleet fuel economy", err) ||
             wf_h5_scalar_f64(g, "stops_per_vkm", s->stops_per_vkm, "1/km", "stops per vehicle-km", err) ||
             wf_h5_scalar_f64(g, "hard_brakes_per_vkm", s->hard_brakes_per_vkm, "1/km",
                              "hard-braking events per vehicle-km", err) ||
             wf_h5_scalar_f64(g, "mean_speed", s->mean_speed_mps, "m/s", "fleet mean speed", err) ||
             wf_h5_scalar_f64(g, "sd_speed_time_avg", s->sd_speed_time_avg_mps, "m/s",
                              "time average of the spatial speed standard deviation", err) ||
             wf_h5_scalar_f64(g, "throughput", s->throughput_vph, "1/h", "passages of x = 0 per hour", err) ||
             wf_h5_scalar_f64(g, "infeasible_share", s->infeasible_share, "1",
                              "share of vehicle-steps with an infeasible acceleration request", err) ||
             wf_h5_scalar_f64(g, "time_stopped_share", s->time_stopped_share, "1", "share of time stopped", err) ||
             wf_h5_scalar_i64(g, "overlaps", s->overlaps, "1", "overlap events repaired", err);
    hsize_t nc = sc->n_classes;
    double a[WF_MAX_CLASSES];
#define CLS(name, field, units, desc)                                              \
    if (!rc) {                                                                     \
        for (size_t c = 0; c < nc; c++) a[c] = s->cls[c].field;                     \
        rc = wf_h5_write_f64(g, name, 1, &nc, a, units, desc, err);                \
    }
    CLS("class_fuel", fuel_g, "g", "fuel per class in the window");
    CLS("class_distance", dist_m, "m", "distance per class in the window");
    CLS("class_l_per_100km", l_per_100km, "L/100km", "fuel economy per class");
    CLS("class_mpg", mpg, "mi/gal", "fuel economy per class");
    CLS("class_infeasible_share", infeasible_share, "1", "infeasible acceleration share per class");
    CLS("class_stops_per_vkm", stops_per_vkm, "1/km", "stops per vehicle-km per class");
#undef CLS
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

/* Solver statistics of a SUNDIALS run (absent for the fixed-step schemes). */
static int write_solver(hid_t fid, const WfSim *sim, WfError *err)
{
    WfOdeStats st;
    if (!wf_sim_ode_stats(sim, &st)) return 0;
    const WfOdeConfig *c = &wf_sim_scenario(sim)->solver;
    hid_t g = wf_h5_group(fid, "solver", err);
    if (g < 0) return WF_ESYS;
    const char *method = c->kind == WF_ODE_CVODE ? (c->bdf ? "bdf" : "adams") : c->kind == WF_ODE_ARKODE ? c->erk_table
                                                                                                          : "classic RK4";
    int rc = wf_h5_scalar_str(g, "integrator", wf_ode_kind_name(c->kind), "SUNDIALS package used", err) ||
             wf_h5_scalar_str(g, "method", method, "method or Butcher table", err) ||
             wf_h5_scalar_f64(g, "rtol", c->rtol, "1", "relative tolerance", err) ||
             wf_h5_scalar_f64(g, "atol_x", c->atol_x_m, "m", "absolute tolerance of positions", err) ||
             wf_h5_scalar_f64(g, "atol_v", c->atol_v_mps, "m/s", "absolute tolerance of speeds", err) ||
             wf_h5_scalar_i64(g, "fuel_error_control", c->fuel_errcon, "1", "fuel integrals in error control", err) ||
             wf_h5_scalar_i64(g, "steps", st.steps, "1", "internal solver steps", err) ||
             wf_h5_scalar_i64(g, "rhs_evals", st.rhs_evals, "1", "right-hand-side evaluations (with quadratures)",
                              err) ||
             wf_h5_scalar_i64(g, "err_test_fails", st.err_test_fails, "1", "local error test failures", err) ||
             wf_h5_scalar_i64(g, "nonlin_iters", st.nonlin_iters, "1", "nonlinear solver iterations (CVODES)", err) ||
             wf_h5_scalar_i64(g, "nonlin_conv_fails", st.nonlin_conv_fails, "1",
                              "nonlinear convergence failures (CVODES)", err) ||
             wf_h5_scalar_i64(g, "reinits", st.reinits, "1",
                              "restarts at discontinuities (noise changes, controller memory, overlap repairs)", err) ||
             wf_h5_scalar_f64(g, "last_step", st.last_step_s, "s", "last internal step size", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int h5_end(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    WfH5Out *w = ctx;
    w->ended = 1;
    hid_t fid = w->file->fid;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    int rc = flush_ts(w, err);
    for (size_t i = 0; !rc && i < ns; i++) rc = wf_h5_series_flush(sp[i].s, err);
    if (rc) wf_err_prefix(err, "%s: ", w->file->partial);
    for (size_t i = 0; i < ns; i++) wf_h5_series_close(sp[i].s);
    if (!rc) rc = write_vehicles(fid, sim, err);
    if (!rc) rc = write_summary(fid, sim, err);
    if (!rc) rc = write_solver(fid, sim, err);
    if (!rc) rc = write_meta(fid, sim, completed, reason, w->started, err);
    /* Open groups would keep the file open past H5Fclose (weak close degree): close them first. */
    if (w->g_ts >= 0) H5Gclose(w->g_ts);
    if (w->g_traj >= 0) H5Gclose(w->g_traj);
    w->g_ts = w->g_traj = H5I_INVALID_HID;
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

/* ---- checkpoints (FILE.h5.ckpt, src/h5ckpt.h) and resumption ---- */

static int h5_checkpoint(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Out *w = ctx;
    int rc = flush_ts(w, err);
    if (rc) return wf_err_prefix(err, "%s: ", w->file->partial);
    /* The result file must hold every row the checkpoint counts (but those it saves) before the checkpoint exists. */
    if (H5Fflush(w->file->fid, H5F_SCOPE_GLOBAL) < 0) return wf_err(err, WF_ESYS, "HDF5: flush %s", w->file->partial);
    WfStateVar vars[WF_MAX_STATE_VARS];
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    /* wf_sim_state packs the scalars into the engine before listing the blocks; they are only read here. */
    size_t nv = wf_sim_state((WfSim *)sim, vars, WF_MAX_STATE_VARS);
    return wf_ckpt_save(w->file->path, "ring", wf_sim_scenario(sim), wf_sim_steps_done(sim), cursor_names, N_CUR, sp,
                        ns, vars, nv, err);
}

static void init_handles(WfH5Out *w)
{
    w->g_ts = w->g_traj = H5I_INVALID_HID;
    WfH5Series *all[] = {&w->ts_class, &w->tr_t, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t i = 0; i < 6; i++) all[i]->dset = H5I_INVALID_HID;
    for (size_t c = 0; c < WF_TS_N_COLS; c++) w->ts[c].dset = H5I_INVALID_HID;
}

int wf_h5out_resume(const char *result, WfSim *sim, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    const WfScenario *sc = wf_sim_scenario(sim);
    WfH5Out *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_handles(w);
    w->resume = 1;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS);
    /* What the interrupted run wrote at its end is written again at the end of this one. */
    static const char *const stale[] = {"vehicles", "summary", "solver"};
    /* The checkpoint is read and verified completely before the partial file is touched. */
    int rc = wf_ckpt_restore(result, "ring", sc, cursor_names, N_CUR, sp, ns, vars, nv, err);
    if (!rc) {
        wf_sim_restored(sim);
        rc = wf_ckpt_reopen(result, sc, sp, ns, stale, 3, &w->file, err);
    }
    if (rc) {
        wf_h5out_destroy(&w);
        return rc;
    }
    *ops = (WfOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                      .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
    *out = w;
    return 0;
}

int wf_h5out_create(const char *path, int force, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Out *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_handles(w);
    int rc = wf_h5_create(path, force, &w->file, err);
    if (rc) {
        free(w);
        return rc;
    }
    *ops = (WfOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                      .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
    *out = w;
    return 0;
}

void wf_h5out_destroy(WfH5Out **pw)
{
    if (!pw || !*pw) return;
    WfH5Out *w = *pw;
    for (size_t c = 0; c < WF_TS_N_COLS; c++) wf_h5_series_close(&w->ts[c]);
    WfH5Series *all[] = {&w->ts_class, &w->tr_t, &w->tr_x, &w->tr_v, &w->tr_a, &w->tr_f};
    for (size_t i = 0; i < 6; i++) wf_h5_series_close(all[i]);
    if (w->g_ts >= 0) H5Gclose(w->g_ts);
    if (w->g_traj >= 0) H5Gclose(w->g_traj);
    /* A run that never started writing removes its empty file; a resumed one never deletes what it reopened. */
    if (w->file) wf_h5_abandon(&w->file, !w->ended && !w->resume);
    free(w->buf);
    free(w);
    *pw = NULL;
}

const char *wf_h5out_path(const WfH5Out *w) { return w->final_path; }

/* ---- reading back (wavefuel info) ---- */

static int read_str_attr(hid_t obj, const char *name, char *buf, size_t len)
{
    buf[0] = '\0';
    if (H5Aexists(obj, name) <= 0) return -1;
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT), t = H5Aget_type(a);
    int rc = -1;
    size_t sz = H5Tget_size(t);
    if (a >= 0 && t >= 0 && H5Tget_class(t) == H5T_STRING && !H5Tis_variable_str(t) && sz < len) {
        hid_t mt = H5Tcopy(t);
        if (H5Aread(a, mt, buf) >= 0) rc = 0, buf[sz] = '\0';
        H5Tclose(mt);
    }
    if (t >= 0) H5Tclose(t);
    if (a >= 0) H5Aclose(a);
    return rc;
}

typedef struct InfoCtx {
    FILE *out;
    hid_t grp;
} InfoCtx;

/* Prints one scalar or small 1-D numeric dataset with its units. */
static herr_t print_dataset(hid_t g, const char *name, const H5L_info_t *info, void *vctx)
{
    (void)info;
    InfoCtx *c = vctx;
    hid_t d = H5Dopen2(g, name, H5P_DEFAULT);
    if (d < 0) return 0;
    hid_t sp = H5Dget_space(d), t = H5Dget_type(d);
    char units[64];
    read_str_attr(d, "units", units, sizeof units);
    hssize_t n = H5Sget_simple_extent_npoints(sp);
    if (H5Tget_class(t) == H5T_STRING && n == 1) {
        char *s = NULL;
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, H5T_VARIABLE);
        H5Tset_cset(mt, H5T_CSET_UTF8);
        if (H5Tis_variable_str(t) > 0 && H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, &s) >= 0 && s) {
            if (!strchr(s, '\n')) fprintf(c->out, "  %-24s %s\n", name, s);
            H5free_memory(s);
        }
        H5Tclose(mt);
    } else if ((H5Tget_class(t) == H5T_FLOAT || H5Tget_class(t) == H5T_INTEGER) && n >= 1 && n <= 16) {
        double v[16];
        if (H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0) {
            fprintf(c->out, "  %-24s", name);
            for (hssize_t i = 0; i < n; i++) fprintf(c->out, " %.6g", v[i]);
            fprintf(c->out, " %s\n", strcmp(units, "1") ? units : "");
        }
    }
    H5Tclose(t);
    H5Sclose(sp);
    H5Dclose(d);
    return 0;
}

int wf_h5out_info(const char *path, FILE *out, WfError *err)
{
    wf_h5_library_init();
    if (H5Fis_hdf5(path) <= 0) return wf_err(err, WF_EINPUT, "%s: not a readable HDF5 file", path);
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return wf_err(err, WF_EINPUT, "%s: cannot open as HDF5", path);
    if (H5Lexists(f, "meta", H5P_DEFAULT) <= 0 || H5Lexists(f, "summary", H5P_DEFAULT) <= 0) {
        H5Fclose(f);
        return wf_err(err, WF_EINPUT, "%s: not a wavefuel result (no /meta and /summary)", path);
    }
    const char *groups[] = {"meta", "summary", "classes"};
    const char *titles[] = {"run", "summary (statistics window)", "classes"};
    for (int k = 0; k < 3; k++) {
        hid_t g = H5Gopen2(f, groups[k], H5P_DEFAULT);
        if (g < 0) continue;
        fprintf(out, "%s:\n", titles[k]);
        InfoCtx c = {.out = out, .grp = g};
        H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, print_dataset, &c);
        H5Gclose(g);
    }
    H5Fclose(f);
    return 0;
}
