/* HDF5 result files of simulation runs: /meta, /classes, /drivers, /vehicles, /timeseries, /summary and
 * optional /trajectories (docs/output.md). Every dataset whose size is known is created at that size before the
 * first step and then only overwritten in place (time series in blocks of rows, the row counters, the end-of-run
 * results and the status); trajectory frames are added a compressed chunk at a time after the disk space is
 * reserved, the frames of the incomplete chunk waiting in memory and in checkpoints (src/io/h5util.h, src/io/h5ckpt.h).
 * A write error at any point leaves a file whose structure is intact (docs/output.md, "Write errors"). */
#include "wavefuel/h5out.h"

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

#define TS_BUF 256

enum { N_TRAJ = WF_RING_TRAJ_N_COLS };
#define traj_cols wf_ring_traj_columns

/* The series whose rows a checkpoint counts (src/io/h5ckpt.h), and /meta's counter of each. */
enum { CUR_TS, CUR_TRAJ, N_CUR };
static const char *const cursor_names[N_CUR] = {"timeseries", "trajectories"};
#define N_SERIES (WF_TS_N_COLS + 1 + N_TRAJ)

struct WfH5Out {
    WfH5File  *file;
    int        ended;
    int        resume;                  /* reopened .partial of an interrupted run */
    /* A write to the group failed: nothing more is written to it (its count stays true); the others go on. */
    int        ts_failed, traj_failed;
    char       final_path[1100];
    hid_t      g_meta;
    WfH5Series ts[WF_TS_N_COLS], ts_class;
    WfH5Series tr[N_TRAJ];              /* x, v, a, fuel_rate, t (traj_cols) */
    WfH5Series *traj[N_TRAJ];           /* the same, as the group appended together */
    int64_t    counted[N_CUR];          /* the row counters as last written (-1: not yet) */
    double    *buf;      /* TS_BUF x (WF_TS_N_COLS + n_classes) */
    double    *cls;      /* TS_BUF x max(n_classes, 1): scratch of wf_h5_series_write_records */
    size_t     n_buf, n_classes;
    char       started[64];
};

static void init_writer(WfH5Out *w)
{
    w->g_meta = H5I_INVALID_HID;
    for (size_t c = 0; c < WF_TS_N_COLS; c++) wf_h5_series_init(&w->ts[c]);
    wf_h5_series_init(&w->ts_class);
    for (size_t i = 0; i < N_TRAJ; i++) wf_h5_series_init(&w->tr[i]), w->traj[i] = &w->tr[i];
    for (size_t i = 0; i < N_CUR; i++) w->counted[i] = -1;
}

/* Records the run writes: at the steps 0, out_every, ... n_steps; frames likewise every trajectory interval. */
static hsize_t ts_rows_of(const WfScenario *sc) { return (hsize_t)wf_scenario_records(sc, wf_scenario_output_every(sc)); }
static hsize_t frames_of(const WfScenario *sc)
{
    return sc->trajectories ? (hsize_t)wf_scenario_records(sc, wf_scenario_trajectory_every(sc)) : 0;
}

/* Every series: group, shape, layout and the cursor that counts its rows. The time series are fixed (every record
 * allocated at the start), the trajectories appended in chunks of 16 frames, fewer when that exceeds 4 MiB or the
 * run has fewer frames, uncompressed: shuffle + deflate 1 saved 24 % of the file but made a run writing a frame
 * every 10 steps 5x slower (10^6 vehicles, 2 threads: 7.3e6 against 3.7e7 vehicle-steps/s, bench/README.md). */
static size_t series_specs(WfH5Out *w, const WfSim *sim, WfCkptSeries *sp)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    hsize_t n = wf_sim_fleet(sim)->n, ts_rows = ts_rows_of(sc), frames = frames_of(sc);
    size_t k = 0;
    for (size_t c = 0; c < WF_TS_N_COLS; c++)
        sp[k++] = (WfCkptSeries){.s = &w->ts[c], .group = "timeseries", .col = &wf_ts_columns[c],
                                 .fixed_rows = ts_rows, .cursor = CUR_TS};
    sp[k++] = (WfCkptSeries){.s = &w->ts_class, .group = "timeseries", .col = &wf_ts_class_column, .cols = sc->n_classes,
                             .fixed_rows = ts_rows, .cursor = CUR_TS};
    hsize_t cr = wf_h5_series_chunk_rows(n, frames < 16 ? frames : 16);
    for (size_t i = 0; sc->trajectories && i < N_TRAJ; i++)
        sp[k++] = (WfCkptSeries){.s = w->traj[i], .group = "trajectories", .col = &traj_cols[i],
                                 .cols = i < 4 ? n : 0, .chunk_rows = cr, .compress = 0, .cursor = CUR_TRAJ};
    return k;
}

/* /meta/timeseries_rows and /meta/trajectory_rows: how many rows of each group are in the file, written in place
 * when they changed. Raw data reaches the file in call order (src/io/h5util.c), and the counters are written after
 * their rows, so they never count a row that is not there. */
static int write_counts(WfH5Out *w, WfH5Pass pass, WfError *err)
{
    int64_t n[N_CUR] = {(int64_t)w->ts[0].rows, (int64_t)w->tr[4].rows};
    if (pass == WF_H5_FILL && !memcmp(n, w->counted, sizeof n)) return 0;
    if (wf_h5_put_scalar_i64(w->g_meta, "timeseries_rows", pass, n[CUR_TS], "1",
                             "rows of /timeseries that hold data (the others are NaN until written)", err) ||
        wf_h5_put_scalar_i64(w->g_meta, "trajectory_rows", pass, n[CUR_TRAJ], "1",
                             "frames of /trajectories that hold data (0 without trajectories)", err))
        return WF_ESYS;
    if (pass == WF_H5_FILL) memcpy(w->counted, n, sizeof n);
    return 0;
}

static int flush_ts(WfH5Out *w, WfError *err)
{
    if (!w->n_buf) return 0;
    if (wf_h5_series_write_records(w->ts, WF_TS_N_COLS, &w->ts_class, w->n_classes, w->buf, w->n_buf, w->cls, err))
        return WF_ESYS;
    w->n_buf = 0;
    return write_counts(w, WF_H5_FILL, err);
}

/* What /meta says about the run's progress: written in place (ALLOCATE when the file is created, FILL when the
 * run ends or resumes). */
static int meta_status(hid_t g, WfH5Pass pass, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    hsize_t np = WF_N_PHASES;
    int rc = wf_h5_put_text(g, "reason", pass, reason,
                            "why the run stopped early: running while it runs, empty when completed", err) ||
             wf_h5_put_scalar_f64(g, "wall_time_s", pass, wf_sim_wall_s(sim), "s", "wall time of the step loop",
                                  err) ||
             wf_h5_put_scalar_i64(g, "steps_done", pass, wf_sim_steps_done(sim), "1", "time steps completed", err) ||
             wf_h5_put_f64(g, "phase_time", pass, 1, &np, wf_sim_phase_times(sim), "s",
                           "wall time per phase of the step loop, in the order of phase_name", err) ||
             /* Last: a file says completed only once everything else is written. */
             wf_h5_put_scalar_i64(g, "completed", pass, completed, "1", "1 when the run reached its end", err);
    return rc ? WF_ESYS : 0;
}

/* /meta at creation: provenance (final), the status (completed = 0, reason "running") and the row counters. */
static int write_meta(WfH5Out *w, const WfSim *sim, WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    hid_t g = w->g_meta = wf_h5_group(w->file->fid, "meta", err);
    if (g < 0) return WF_ESYS;
    hsize_t np = WF_N_PHASES;
    int rc = wf_h5_scalar_str(g, "scenario_text", sc->text, "the scenario file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sc->path, "scenario file as given", err) ||
             wf_h5_scalar_str(g, "overrides", sc->overrides, "--set assignments applied, one per line", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", WF_GIT_HASH, "git describe of the source tree", err) ||
             wf_h5_scalar_i64(g, "seed", (int64_t)sc->seed, "1", "random seed", err) ||
             wf_h5_scalar_i64(g, "threads", wf_sim_threads(sim), "1", "OpenMP threads available to the run", err) ||
             wf_h5_scalar_str(g, "start_time", w->started, "wall-clock start, UTC ISO 8601", err) ||
             wf_h5_scalar_str(g, "integrator", sc->integrator, "time integrator", err) ||
             wf_h5_scalar_f64(g, "dt", sc->dt_s, "s", "time step", err) ||
             wf_h5_scalar_f64(g, "duration", sc->duration_s, "s", "simulated duration", err) ||
             wf_h5_scalar_f64(g, "warmup", sc->warmup_s, "s", "warm-up excluded from statistics", err) ||
             wf_h5_scalar_f64(g, "road_length", sc->road.length_m, "m", "ring length", err) ||
             wf_h5_scalar_f64(g, "initial_speed", wf_sim_fleet(sim)->v_init_mps, "m/s",
                              "common speed of the initial equilibrium (0 when starting at rest)", err) ||
             wf_h5_write_strings(g, "phase_name", np, wf_phase_names, "phases of phase_time", err) ||
             meta_status(g, WF_H5_ALLOCATE, sim, 0, "", err) || meta_status(g, WF_H5_FILL, sim, 0, "running", err) ||
             write_counts(w, WF_H5_ALLOCATE, err) || write_counts(w, WF_H5_FILL, err);
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

/* /vehicles from its column table (src/observe/vehicles.c), then every driver-model parameter drawn for each vehicle
 * (fixed from the start). ALLOCATE writes what is known from the start and allocates the end-of-run statistics;
 * FILL writes those. */
static int write_vehicles(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    const WfFleet *f = wf_sim_fleet(sim);
    WfVehicleView view = {.f = f, .sc = sc, .window_s = wf_sim_summary(sim)->window_s};
    size_t n = f->n;
    int fill = pass == WF_H5_FILL;
    hid_t g = wf_h5_group_pass(fid, "vehicles", pass, err);
    if (g < 0) return WF_ESYS;
    /* One buffer for both element types (8 bytes each): at 10^7 vehicles a second one would be 80 MB more peak. */
    double *d = malloc((n ? n : 1) * sizeof *d);
    int rc = !d ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t c = 0; !rc && c < WF_VEH_N_COLS; c++) {
        const WfObsColumn *col = &wf_vehicle_columns[c];
        if (col->at_start && fill) continue;
        for (size_t i = 0; (col->at_start || fill) && i < n; i++) {
            double x = wf_vehicle_value(&view, c, i);
            if (col->type == WF_COL_I64) {
                int64_t k = (int64_t)x;
                memcpy(&d[i], &k, sizeof k);
            } else d[i] = x;
        }
        WfObsData data = {d, 1, {n, 0}};
        rc = wf_h5_put_columns(g, col, &data, 1, pass, err);
    }
    /* NaN for vehicles whose model lacks the key; a key shared by several groups' models is written once. */
    hsize_t dn = n;
    for (size_t gi = 0; !rc && !fill && gi < sc->n_groups; gi++) {
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
    free(d);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_summary(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err)
{
    return wf_h5_summary_write(fid, wf_sim_summary(sim), wf_sim_scenario(sim)->n_classes, WF_SUMMARY_RING, pass, err);
}

/* Solver statistics of a SUNDIALS run (absent for the fixed-step schemes): the settings are written when the file
 * is created, the counters at the end. */
static int write_solver(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err)
{
    WfOdeStats st;
    if (!wf_sim_ode_stats(sim, &st)) return 0;
    const WfOdeConfig *c = &wf_sim_scenario(sim)->solver;
    hid_t g = wf_h5_group_pass(fid, "solver", pass, err);
    if (g < 0) return WF_ESYS;
    const char *method = c->kind == WF_ODE_CVODE ? (c->bdf ? "bdf" : "adams") : c->kind == WF_ODE_ARKODE ? c->erk_table
                                                                                                          : "classic RK4";
    int rc = 0;
    if (pass == WF_H5_ALLOCATE)
        rc = wf_h5_scalar_str(g, "integrator", wf_ode_kind_name(c->kind), "SUNDIALS package used", err) ||
             wf_h5_scalar_str(g, "method", method, "method or Butcher table", err) ||
             wf_h5_scalar_f64(g, "rtol", c->rtol, "1", "relative tolerance", err) ||
             wf_h5_scalar_f64(g, "atol_x", c->atol_x_m, "m", "absolute tolerance of positions", err) ||
             wf_h5_scalar_f64(g, "atol_v", c->atol_v_mps, "m/s", "absolute tolerance of speeds", err) ||
             wf_h5_scalar_i64(g, "fuel_error_control", c->fuel_errcon, "1", "fuel integrals in error control", err);
#define COUNT(name, v, desc) wf_h5_put_scalar_i64(g, name, pass, v, "1", desc, err)
    rc = rc || COUNT("steps", st.steps, "internal solver steps") ||
         COUNT("rhs_evals", st.rhs_evals, "right-hand-side evaluations (with quadratures)") ||
         COUNT("err_test_fails", st.err_test_fails, "local error test failures") ||
         COUNT("nonlin_iters", st.nonlin_iters, "nonlinear solver iterations (CVODES)") ||
         COUNT("nonlin_conv_fails", st.nonlin_conv_fails, "nonlinear convergence failures (CVODES)") ||
         COUNT("reinits", st.reinits,
               "restarts at discontinuities (noise changes, controller memory, overlap repairs)") ||
         wf_h5_put_scalar_f64(g, "last_step", pass, st.last_step_s, "s", "last internal step size", err);
#undef COUNT
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

/* A failure while the file is set up (`why`, or the error in err): the message says what the file needs and that
 * nothing is kept (the writer's destroy removes a file whose run never started). */
static int setup_failed(WfH5Out *w, double ts, double traj, double end, const char *why, WfError *err)
{
    char a[32], b[32], c[32], d[32], inner[sizeof err->msg];
    snprintf(inner, sizeof inner, "%s", why ? why : err->msg);
    return wf_err(err, why || !err->code ? WF_ESYS : err->code,
                  "%s: cannot create the result file, which needs up to about %s (time series %s, trajectories %s, "
                  "end-of-run results %s): %s; nothing was simulated and the file is removed",
                  w->file->partial, wf_h5_size_text(ts + traj + end, a, sizeof a), wf_h5_size_text(ts, b, sizeof b),
                  wf_h5_size_text(traj, c, sizeof c), wf_h5_size_text(end, d, sizeof d), inner);
}

static int h5_begin(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Out *w = ctx;
    const WfScenario *sc = wf_sim_scenario(sim);
    w->n_classes = sc->n_classes;
    w->buf = malloc(TS_BUF * (WF_TS_N_COLS + w->n_classes) * sizeof *w->buf);
    w->cls = malloc(TS_BUF * (w->n_classes ? w->n_classes : 1) * sizeof *w->cls);
    if (!w->buf || !w->cls) return wf_err(err, WF_ESYS, "out of memory");
    if (w->resume) return 0; /* wf_h5out_resume reopened the file and set it back to the checkpoint */
    hid_t fid = w->file->fid;
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(w->started, sizeof w->started, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    double n = (double)wf_sim_fleet(sim)->n;
    double ts_bytes = (double)ts_rows_of(sc) * (double)(WF_TS_N_COLS + w->n_classes) * 8.0;
    double traj_bytes = (double)frames_of(sc) * (1.0 + 4.0 * n) * 8.0;
    double end_bytes = n * 16.0 * 8.0;
    /* Refuse a run whose result cannot fit before simulating it (trajectories are allocated as they grow, so this
     * is the only early warning for them). */
    char why[200];
    if (wf_h5_check_room(w->file, ts_bytes + traj_bytes + end_bytes, why, sizeof why))
        return setup_failed(w, ts_bytes, traj_bytes, end_bytes, why, err);
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    hid_t g_ts = H5I_INVALID_HID, g_traj = H5I_INVALID_HID;
    int rc = write_meta(w, sim, err) || write_classes_drivers(fid, sim, err) ||
             write_vehicles(fid, sim, WF_H5_ALLOCATE, err) || write_summary(fid, sim, WF_H5_ALLOCATE, err) ||
             write_solver(fid, sim, WF_H5_ALLOCATE, err) || (g_ts = wf_h5_group(fid, "timeseries", err)) < 0 ||
             (sc->trajectories && ((g_traj = wf_h5_group(fid, "trajectories", err)) < 0 ||
                                   wf_h5_attr_f64(g_traj, "ring_length_m", sc->road.length_m, err))) ||
             wf_ckpt_series_create(fid, sp, ns, err) ||
             /* From here on the structure changes only when trajectory chunks are added, after reserving space. */
             wf_h5_flush(w->file, err);
    if (g_ts >= 0) H5Gclose(g_ts);
    if (g_traj >= 0) H5Gclose(g_traj);
    return rc ? setup_failed(w, ts_bytes, traj_bytes, end_bytes, NULL, err) : 0;
}

/* A write error in the run: the file keeps what was written before it (its row counters say how much). */
static int write_failed(WfH5Out *w, int *group_failed, WfError *err)
{
    *group_failed = 1;
    return wf_err_prefix(err, "%s: ", w->file->partial);
}

static int h5_record(void *ctx, const WfSim *sim, const WfTsRow *row, WfError *err)
{
    (void)sim;
    WfH5Out *w = ctx;
    double *dst = w->buf + w->n_buf * (WF_TS_N_COLS + w->n_classes);
    memcpy(dst, row->v, WF_TS_N_COLS * sizeof(double));
    memcpy(dst + WF_TS_N_COLS, row->class_fuel_rate_gps, w->n_classes * sizeof(double));
    if (++w->n_buf == TS_BUF && flush_ts(w, err)) return write_failed(w, &w->ts_failed, err);
    return 0;
}

/* One frame into the trajectories' chunk; a complete chunk is written (src/io/h5util.h), then counted. The per-step
 * arrays exist at trajectory steps (the engine takes its multi-pass path then). */
static int h5_trajectory(void *ctx, const WfSim *sim, double t, WfError *err)
{
    WfH5Out *w = ctx;
    const WfFleet *f = wf_sim_fleet(sim);
    const double *frame[N_TRAJ];
    wf_ring_traj_frame(f, &t, frame);
    if (wf_h5_series_append(w->file, w->traj, N_TRAJ, 1, frame, "/trajectories", err) ||
        write_counts(w, WF_H5_FILL, err))
        return write_failed(w, &w->traj_failed, err);
    return 0;
}

static void close_objects(WfH5Out *w)
{
    for (size_t c = 0; c < WF_TS_N_COLS; c++) wf_h5_series_close(&w->ts[c]);
    wf_h5_series_close(&w->ts_class);
    for (size_t i = 0; i < N_TRAJ; i++) wf_h5_series_close(&w->tr[i]);
    /* An open group would keep the file open past H5Fclose (weak close degree): close it too. */
    if (w->g_meta >= 0) H5Gclose(w->g_meta);
    w->g_meta = H5I_INVALID_HID;
}

static int h5_end(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    WfH5Out *w = ctx;
    w->ended = 1;
    hid_t fid = w->file->fid;
    /* The buffered records and frames, unless writing their group failed before (its counter stays true); the
     * end-of-run results and the status are written whatever happened: in place, they cannot damage the file,
     * and they may well succeed. Only the first error is reported. */
    int rc = w->ts_failed ? 0 : flush_ts(w, err);
    if (!rc && !w->traj_failed && w->tr[0].dset >= 0 &&
        (wf_h5_series_flush(w->file, w->traj, N_TRAJ, "/trajectories", err) || write_counts(w, WF_H5_FILL, err)))
        rc = WF_ESYS;
    WfError later = {0};
    WfError *e = rc ? &later : err;
    if (write_vehicles(fid, sim, WF_H5_FILL, e) || write_summary(fid, sim, WF_H5_FILL, e) ||
        write_solver(fid, sim, WF_H5_FILL, e)) {
        if (!rc) rc = WF_ESYS;
        e = &later;
    }
    /* A run that was to complete but could not be written is incomplete, for this reason; an interrupted or
     * failed run keeps its first cause. */
    if (rc && completed) completed = 0, reason = err->msg;
    if (meta_status(w->g_meta, WF_H5_FILL, sim, completed, reason, e)) {
        if (!rc) rc = WF_ESYS;
        /* The status itself failed: say so in the file if the device still lets us. */
        if (completed) meta_status(w->g_meta, WF_H5_FILL, sim, 0, err->msg, &later);
    }
    close_objects(w);
    if (rc) wf_err_prefix(err, "%s: ", w->file->partial);
    int done = !rc && completed;
    if (wf_h5_finish(&w->file, done, w->final_path, sizeof w->final_path, err)) return WF_ESYS;
    if (done) wf_ckpt_remove(w->final_path); /* the result is complete: its checkpoint is of no further use */
    return rc;
}

/* ---- checkpoints (FILE.h5.ckpt, src/io/h5ckpt.h) and resumption ---- */

static int h5_checkpoint(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Out *w = ctx;
    /* The result file must hold every row the checkpoint counts (but the pending frames it saves) before the
     * checkpoint exists. */
    if (flush_ts(w, err)) return write_failed(w, &w->ts_failed, err);
    if (wf_h5_flush(w->file, err)) return w->traj_failed = 1, write_failed(w, &w->ts_failed, err);
    WfStateVar vars[WF_MAX_STATE_VARS];
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    /* wf_sim_state packs the scalars into the engine before listing the blocks; they are only read here. */
    size_t nv = wf_sim_state((WfSim *)sim, vars, WF_MAX_STATE_VARS);
    return wf_ckpt_save(w->file->path, "ring", wf_sim_scenario(sim), wf_sim_steps_done(sim), cursor_names, N_CUR, sp,
                        ns, vars, nv, err);
}

/* The reopened file back at the checkpoint: the counters at its rows (lowering a counter is always safe), the
 * trajectories cut to the whole chunks it counts (their later frames are written again), then the status back to
 * "running" (should the cut fail, the file keeps the interrupted run's reason). */
static int resume_file(WfH5Out *w, const WfSim *sim, WfError *err)
{
    w->g_meta = H5Gopen2(w->file->fid, "meta", H5P_DEFAULT);
    int rc = w->g_meta < 0 ? wf_err(err, WF_EINPUT, "no group /meta") : 0;
    if (!rc && (write_counts(w, WF_H5_FILL, err) ||
                wf_h5_series_trim(w->file, w->traj, wf_sim_scenario(sim)->trajectories ? N_TRAJ : 0, err) ||
                meta_status(w->g_meta, WF_H5_FILL, sim, 0, "running", err) || wf_h5_flush(w->file, err)))
        rc = WF_ESYS;
    return rc ? wf_err_prefix(err, "%s: ", w->file->partial) : 0;
}

static WfOutput ops_of(WfH5Out *w)
{
    return (WfOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                      .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
}

int wf_h5out_resume(const char *result, WfSim *sim, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    const WfScenario *sc = wf_sim_scenario(sim);
    WfH5Out *w = calloc(1, sizeof *w);
    if (!w) return wf_err(err, WF_ESYS, "out of memory");
    init_writer(w);
    w->resume = 1;
    WfCkptSeries sp[N_SERIES];
    size_t ns = series_specs(w, sim, sp);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS);
    /* The checkpoint and the partial file are read and verified completely before the file is changed. */
    int rc = wf_ckpt_restore(result, "ring", sc, cursor_names, N_CUR, sp, ns, vars, nv, err);
    if (!rc) {
        wf_sim_restored(sim);
        rc = wf_ckpt_reopen(result, sc, sp, ns, &w->file, err);
    }
    if (!rc) rc = resume_file(w, sim, err);
    if (rc) {
        wf_h5out_destroy(&w);
        return rc;
    }
    *ops = ops_of(w);
    *out = w;
    return 0;
}

int wf_h5out_create(const char *path, int force, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Out *w = calloc(1, sizeof *w);
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

void wf_h5out_destroy(WfH5Out **pw)
{
    if (!pw || !*pw) return;
    WfH5Out *w = *pw;
    close_objects(w);
    /* A run that never started writing removes its file (nothing was simulated); a resumed one never deletes
     * what it reopened. */
    if (w->file) wf_h5_abandon(&w->file, !w->ended && !w->resume);
    free(w->buf);
    free(w->cls);
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
        } else if (H5Tis_variable_str(t) == 0 && H5Tget_size(t) <= 4096) {
            /* Fixed-length text (/meta/reason, rewritten in place): read with a terminating NUL added. */
            char fixed[4097];
            size_t sz = H5Tget_size(t);
            hid_t ft = H5Tcopy(H5T_C_S1);
            if (ft >= 0 && H5Tset_size(ft, sz + 1) >= 0 && H5Tset_cset(ft, H5T_CSET_UTF8) >= 0 &&
                H5Dread(d, ft, H5S_ALL, H5S_ALL, H5P_DEFAULT, fixed) >= 0) {
                fixed[sz] = '\0';
                if (!strchr(fixed, '\n')) fprintf(c->out, "  %-24s %s\n", name, fixed);
            }
            if (ft >= 0) H5Tclose(ft);
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

static void print_summary_field(const char *name, void *vctx)
{
    InfoCtx *c = vctx;
    if (H5Lexists(c->grp, name, H5P_DEFAULT) > 0) print_dataset(c->grp, name, NULL, c);
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
        /* The summary in the order of its table (fleet values, then per class); the other groups by name. */
        if (!strcmp(groups[k], "summary")) wf_h5_summary_each(print_summary_field, &c);
        else H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, print_dataset, &c);
        H5Gclose(g);
    }
    H5Fclose(f);
    return 0;
}
