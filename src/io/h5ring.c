/* The ring's result file (docs/output.md): the one result writer (src/io/h5result.c) with the ring's observers:
 * time series (wf_ts_columns), trajectory frames [time x vehicle] and the per-vehicle statistics (/vehicles, from
 * src/observe/vehicles.c), and the ring's own datasets: /solver, the energy-model parameters of each class, the
 * class and group counts, the initial speed and the phase times. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/h5result.h"

enum { CUR_TS, CUR_TRAJ, N_CUR };
static const WfH5Cursor cursors[N_CUR] = {
    {"timeseries", "timeseries_rows", "rows of /timeseries that hold data (the others are NaN until written)"},
    {"trajectories", "trajectory_rows", "frames of /trajectories that hold data (0 without trajectories)"},
};

static hsize_t frames_of(const WfScenario *sc)
{
    return sc->trajectories ? (hsize_t)wf_scenario_records(sc, wf_scenario_trajectory_every(sc)) : 0;
}

/* The trajectories: appended in chunks of 16 frames, fewer when that exceeds 4 MiB or the run has fewer frames,
 * uncompressed: shuffle + deflate 1 saved 24 % of the file but made a run writing a frame every 10 steps 5x slower
 * (10^6 vehicles, 2 threads: 7.3e6 against 3.7e7 vehicle-steps/s, bench/README.md). */
static size_t ring_series(const WfH5Run *r, WfCkptSeries *sp)
{
    hsize_t n = wf_sim_fleet(r->sim)->n, frames = frames_of(r->sc);
    hsize_t cr = wf_h5_series_chunk_rows(n, frames < 16 ? frames : 16);
    size_t k = 0;
    size_t ncol = wf_sim_fleet(r->sim)->n_lanes > 1 ? WF_RING_TRAJ_N_COLS : WF_RING_TRAJ_LANE;
    for (size_t i = 0; r->sc->trajectories && i < ncol; i++)
        sp[k++] = (WfCkptSeries){.col = &wf_ring_traj_columns[i], .cols = i == 4 ? 0 : n, .chunk_rows = cr,
                                 .cursor = CUR_TRAJ};
    return k;
}

static void ring_size(const WfH5Run *r, double *appended, double *end)
{
    double n = (double)wf_sim_fleet(r->sim)->n;
    *appended = (double)frames_of(r->sc) * (1.0 + 4.0 * n) * 8.0;
    *end = n * 16.0 * 8.0;
}

static int ring_meta(hid_t g, const WfH5Run *r, WfError *err)
{
    hsize_t np = WF_N_PHASES;
    return wf_h5_scalar_f64(g, "initial_speed", wf_sim_fleet(r->sim)->v_init_mps, "m/s",
                            "common speed of the initial equilibrium (0 when starting at rest)", err) ||
           wf_h5_write_strings(g, "phase_name", np, wf_phase_names, "phases of phase_time", err);
}

/* The counts of each class and group, and each class's energy-model parameters, one scalar per key with the key's
 * unit. */
static int ring_fleet(hid_t g, hid_t drivers, const WfH5Run *r, WfError *err)
{
    const WfScenario *sc = r->sc;
    const WfFleet *f = wf_sim_fleet(r->sim);
    int64_t counts[WF_MAX_CLASSES], gc[WF_MAX_GROUPS];
    hsize_t nc = sc->n_classes, ng = sc->n_groups;
    for (size_t c = 0; c < sc->n_classes; c++) counts[c] = (int64_t)f->class_n[c];
    for (size_t k = 0; k < sc->n_groups; k++) gc[k] = (int64_t)f->group_n[k];
    int rc = wf_h5_write_i64(g, "count", 1, &nc, counts, "1", "vehicles of the class", err) ||
             wf_h5_write_i64(drivers, "count", 1, &ng, gc, "1", "vehicles in the group", err);
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
    return rc;
}

static int ring_traj_attrs(hid_t g, const WfH5Run *r, WfError *err)
{
    return wf_h5_attr_f64(g, "ring_length_m", r->sc->road.length_m, err);
}

/* The end-of-run columns of /vehicles for vehicles [lo, hi) (a piece of wf_sim_shares). */
typedef struct VehicleRows {
    hid_t          g;
    WfVehicleView  view;
    size_t         ncol;
} VehicleRows;

static int vehicle_rows(void *ctx, size_t lo, size_t hi, WfError *err)
{
    const VehicleRows *vr = ctx;
    /* One buffer for both element types (8 bytes each) */
    double *d = malloc((hi > lo ? hi - lo : 1) * sizeof *d);
    int rc = !d ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t c = 0; !rc && c < vr->ncol; c++) {
        const WfObsColumn *col = &wf_vehicle_columns[c];
        if (col->at_start) continue;
        for (size_t i = lo; i < hi; i++) {
            double x = wf_vehicle_value(&vr->view, c, i);
            if (col->type == WF_COL_I64) {
                int64_t k = (int64_t)x;
                memcpy(&d[i - lo], &k, sizeof k);
            } else d[i - lo] = x;
        }
        rc = wf_h5_put_rows(vr->g, col->col.name, col->type == WF_COL_I64, lo, hi - lo, d, err);
    }
    free(d);
    return rc;
}

/* /vehicles from its column table (src/observe/vehicles.c), then every driver-model parameter drawn for each vehicle
 * (fixed from the start). ALLOCATE writes what is known from the start and allocates the end-of-run statistics;
 * FILL writes those, a piece of the ring at a time (wf_sim_shares: a ring split across processes has its shares
 * gathered on rank 0 one after another). */
static int write_vehicles(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    const WfFleet *f = wf_sim_fleet(sim);
    size_t n = f->n, ncol = f->n_lanes > 1 ? WF_VEH_N_COLS : WF_VEH_N_SINGLE;
    hid_t g = wf_h5_group_pass(fid, "vehicles", pass, err);
    if (pass == WF_H5_FILL) {
        /* every rank of a split ring gathers, whatever rank 0's file does */
        VehicleRows vr = {g, {.f = f, .sc = sc, .window_s = wf_sim_summary(sim)->window_s}, ncol};
        int rc = wf_sim_shares(sim, g >= 0 ? vehicle_rows : NULL, &vr, err);
        if (g >= 0) H5Gclose(g);
        return rc || g < 0 ? WF_ESYS : 0;
    }
    if (g < 0) return WF_ESYS;
    WfVehicleView view = {.f = f, .sc = sc};
    /* One buffer for both element types (8 bytes each): at 10^7 vehicles a second one would be 80 MB more peak. */
    double *d = malloc((n ? n : 1) * sizeof *d);
    int rc = !d ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t c = 0; !rc && c < ncol; c++) {
        const WfObsColumn *col = &wf_vehicle_columns[c];
        for (size_t i = 0; col->at_start && i < n; i++) {
            double x = wf_vehicle_value(&view, c, i);
            if (col->type == WF_COL_I64) {
                int64_t k = (int64_t)x;
                memcpy(&d[i], &k, sizeof k);
            } else d[i] = x;
        }
        WfObsData data = {d, 1, {n, 0}};
        rc = wf_h5_put_columns(g, col, &data, 1, pass, err);
    }
    /* NaN for vehicles whose model lacks the key; a key shared by several groups' models is written once. A
     * vehicle of another process's share (a split ring) has its parameters drawn again into pbuf. */
    hsize_t dn = n;
    size_t most = 0;
    for (size_t gi = 0; gi < sc->n_groups; gi++)
        if (sc->groups[gi].model->param_size > most) most = sc->groups[gi].model->param_size;
    double *pbuf = malloc(most + sizeof(double));
    if (!rc && !pbuf) rc = wf_err(err, WF_ESYS, "out of memory");
    for (size_t gi = 0; !rc && gi < sc->n_groups; gi++) {
        const WfCfModel *m = sc->groups[gi].model;
        for (size_t p = 0; !rc && p < m->n_spec; p++) {
            char name[160];
            snprintf(name, sizeof name, "param_%s", m->spec[p].key);
            if (H5Lexists(g, name, H5P_DEFAULT) > 0) continue;
            const WfParamSpec *sp_of[WF_MAX_GROUPS]; /* the key in each group's model (NULL: none) */
            for (size_t gj = 0; gj < sc->n_groups; gj++) {
                const WfCfModel *mj = sc->groups[gj].model;
                sp_of[gj] = wf_param_find(mj->spec, mj->n_spec, m->spec[p].key);
            }
            for (size_t id = 0; !rc && id < n; id++) {
                size_t i = f->pos ? f->pos[id] : id; /* its slot */
                const WfParamSpec *sp = sp_of[f->group_id[i]];
                const void *pv = sp ? wf_fleet_params_of(f, sc, i, pbuf, err) : NULL;
                if (sp && !pv) rc = WF_EINPUT;
                d[id] = pv ? wf_param_get(pv, sp) : NAN;
            }
            if (!rc) rc = wf_h5_write_f64(g, name, 1, &dn, d, m->spec[p].unit, m->spec[p].doc, err);
        }
    }
    free(d);
    free(pbuf);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
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

static int ring_results(hid_t fid, const WfH5Run *r, WfH5Pass pass, WfError *err)
{
    return write_vehicles(fid, r->sim, pass, err) || write_solver(fid, r->sim, pass, err) ||
                   wf_h5_write_lanes(fid, r->sim, pass, err)
               ? WF_ESYS
               : 0;
}

static size_t ring_frame_len(const WfH5Run *r)
{
    const WfFleet *f = wf_sim_fleet(r->sim);
    return f->n_lanes > 1 && r->sc->trajectories ? 5 * f->n : 0; /* else the frame is the fleet's arrays */
}

/* The per-step arrays exist at trajectory steps (the engine takes its multi-pass path then). */
static size_t ring_frame(const WfH5Run *r, const double *t_s, double *scratch, const double **cols)
{
    wf_ring_traj_frame(wf_sim_fleet(r->sim), t_s, scratch, cols);
    return 1;
}

const WfH5Boundary wf_h5_ring = {
    .kind = "ring", .summary = WF_SUMMARY_RING, .road_length_desc = "ring length",
    .warmup_desc = "warm-up excluded from statistics", .cursor = cursors, .n_cursors = N_CUR,
    .traj_cursor = CUR_TRAJ, .ts_cols = wf_ts_columns, .n_ts_cols = WF_TS_N_COLS, .ts_class_col = &wf_ts_class_column,
    .series = ring_series, .size = ring_size, .meta = ring_meta, .fleet = ring_fleet, .traj_attrs = ring_traj_attrs,
    .results = ring_results, .frame_len = ring_frame_len, .frame = ring_frame,
};
