/* The one result writer of runs (src/io/h5result.h). Every dataset whose size is known is created at that size
 * before the first step and then only overwritten in place (time series in blocks of rows, the row counters, the
 * end-of-run results and the status); the appended groups grow a chunk at a time after the disk space is reserved,
 * the rows of the incomplete chunk waiting in memory and in checkpoints (src/io/h5util.h, src/io/h5ckpt.h). */
#include "io/h5result.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "io/h5summary.h"
#include "util/mem.h"
#include "wavefuel/h5out.h"
#include "wavefuel/vehicle.h"
#include "wavefuel/version.h"

#define TS_BUF 256 /* time-series records buffered between writes */

struct WfH5Result {
    const WfH5Boundary *b;
    WfH5File   *file;
    int         ended;
    int         resume;                 /* reopened .partial of an interrupted run */
    /* A write to the cursor's group failed: nothing more is written to it (its count stays true). */
    int         failed[WF_H5_MAX_CURSORS];
    char        final_path[1100];
    char        started[64];
    hid_t       g_meta;
    WfH5Series  ser[WF_H5_MAX_SERIES];
    WfCkptSeries sp[WF_H5_MAX_SERIES];  /* ser[k] described: sp[k].s = &ser[k] */
    size_t      ns;
    WfH5Series *grp[WF_H5_MAX_CURSORS][WF_H5_MAX_SERIES]; /* the series of each cursor, appended together */
    size_t      n_grp[WF_H5_MAX_CURSORS];
    int64_t     counted[WF_H5_MAX_CURSORS]; /* the row counters as last written (-1: not yet) */
    const char *cur[WF_H5_MAX_CURSORS];     /* each cursor's group: its name in checkpoints */
    double     *buf;    /* TS_BUF x (n_ts_cols + n_classes) */
    double     *cls;    /* TS_BUF x max(n_classes, 1): scratch of wf_h5_series_write_records */
    double     *frame;  /* scratch of the boundary's trajectory frame */
    size_t      n_buf, n_classes;
};

/* What the writer reads of the run, at every callback (the phase times only while the run goes on). */
static WfH5Run run_of(const WfSim *sim)
{
    return (WfH5Run){.sim = sim, .sc = wf_sim_scenario(sim), .summary = wf_sim_summary(sim),
                     .wall_s = wf_sim_wall_s(sim), .steps_done = wf_sim_steps_done(sim),
                     .threads = wf_sim_threads(sim), .phase_s = wf_sim_phase_times(sim)};
}

int wf_h5_put_columns(hid_t g, const WfObsColumn *cols, const WfObsData *data, size_t n, WfH5Pass pass,
                      WfError *err)
{
    int rc = 0;
    for (size_t k = 0; !rc && k < n; k++) {
        const WfColumn *c = &cols[k].col;
        const WfObsData *d = &data[k];
        hsize_t dims[2] = {d->dims[0], d->dims[1]};
        if (cols[k].at_start && pass != WF_H5_ALLOCATE) continue;
        if (cols[k].at_start)
            rc = cols[k].type == WF_COL_I64
                     ? wf_h5_write_i64(g, c->name, d->rank, dims, d->data, c->units, c->desc, err)
                     : wf_h5_write_f64(g, c->name, d->rank, dims, d->data, c->units, c->desc, err);
        else
            rc = cols[k].type == WF_COL_I64
                     ? wf_h5_put_i64(g, c->name, pass, d->rank, dims, d->data, c->units, c->desc, err)
                     : wf_h5_put_f64(g, c->name, pass, d->rank, dims, d->data, c->units, c->desc, err);
    }
    return rc;
}

/* The writer of the run's kind of road (its observers: src/io/h5ring.c, src/io/h5corridor.c). */
static const WfH5Boundary *boundary_of(const WfSim *sim, WfError *err)
{
    static const WfH5Boundary *const all[] = {&wf_h5_ring, &wf_h5_corridor};
    for (size_t k = 0; k < sizeof all / sizeof all[0]; k++)
        if (!strcmp(all[k]->kind, wf_sim_kind(sim))) return all[k];
    wf_err(err, WF_EINPUT, "no result writer for a %s run", wf_sim_kind(sim));
    return NULL;
}

/* A writer for the run's kind of road, nothing written yet; NULL with err set. */
static WfH5Result *new_writer(const WfSim *sim, WfError *err)
{
    const WfH5Boundary *b = boundary_of(sim, err);
    WfH5Result *w = b ? calloc(1, sizeof *w) : NULL;
    if (!w) {
        if (b) wf_err(err, WF_ESYS, "out of memory");
        return NULL;
    }
    w->b = b;
    w->g_meta = H5I_INVALID_HID;
    for (size_t k = 0; k < WF_H5_MAX_SERIES; k++) wf_h5_series_init(&w->ser[k]);
    for (size_t k = 0; k < WF_H5_MAX_CURSORS; k++) w->counted[k] = -1;
    for (size_t c = 0; c < b->n_cursors; c++) w->cur[c] = b->cursor[c].group;
    return w;
}

/* Every series: the time series (fixed: every record allocated at the start), then the boundary's appended ones;
 * and the series of each cursor, in order. */
static void build_series(WfH5Result *w, const WfH5Run *r)
{
    const WfH5Boundary *b = w->b;
    hsize_t ts_rows = (hsize_t)wf_scenario_records(r->sc, wf_scenario_output_every(r->sc));
    size_t n = 0;
    for (size_t k = 0; k <= b->n_ts_cols; k++)
        w->sp[n++] = (WfCkptSeries){.col = k < b->n_ts_cols ? &b->ts_cols[k] : b->ts_class_col,
                                    .cols = k < b->n_ts_cols ? 0 : r->sc->n_classes, .fixed_rows = ts_rows};
    n += b->series(r, w->sp + n);
    w->ns = n;
    for (size_t k = 0; k < n; k++) {
        size_t c = w->sp[k].cursor;
        w->sp[k].s = &w->ser[k];
        w->sp[k].group = b->cursor[c].group;
        w->grp[c][w->n_grp[c]++] = &w->ser[k];
    }
}

/* /meta's row counters: how many rows of each group are in the file, written in place when they changed. Raw data
 * reaches the file in call order (src/io/h5util.c), and the counters are written after their rows, so they never
 * count a row that is not there. */
static int write_counts(WfH5Result *w, WfH5Pass pass, WfError *err)
{
    int64_t n[WF_H5_MAX_CURSORS] = {0};
    for (size_t c = 0; c < w->b->n_cursors; c++) n[c] = w->n_grp[c] ? (int64_t)w->grp[c][0]->rows : 0;
    if (pass == WF_H5_FILL && !memcmp(n, w->counted, sizeof n)) return 0;
    for (size_t c = 0; c < w->b->n_cursors; c++)
        if (wf_h5_put_scalar_i64(w->g_meta, w->b->cursor[c].meta, pass, n[c], "1", w->b->cursor[c].desc, err))
            return WF_ESYS;
    if (pass == WF_H5_FILL) memcpy(w->counted, n, sizeof n);
    return 0;
}

static int flush_ts(WfH5Result *w, WfError *err)
{
    if (!w->n_buf) return 0;
    if (wf_h5_series_write_records(w->grp[0][0], w->b->n_ts_cols, w->grp[0][w->b->n_ts_cols], w->n_classes, w->buf,
                                   w->n_buf, w->cls, err))
        return WF_ESYS;
    w->n_buf = 0;
    return write_counts(w, WF_H5_FILL, err);
}

/* What /meta says about the run's progress: written in place (ALLOCATE when the file is created, FILL when the
 * run ends or resumes). */
static int meta_status(hid_t g, WfH5Pass pass, const WfH5Run *r, int completed, const char *reason, WfError *err)
{
    hsize_t np = WF_N_PHASES;
    int rc = wf_h5_put_text(g, "reason", pass, reason,
                            "why the run stopped early: running while it runs, empty when completed", err) ||
             wf_h5_put_scalar_f64(g, "wall_time_s", pass, r->wall_s, "s", "wall time of the step loop", err) ||
             wf_h5_put_scalar_i64(g, "steps_done", pass, r->steps_done, "1", "time steps completed", err) ||
             (r->phase_s && wf_h5_put_f64(g, "phase_time", pass, 1, &np, r->phase_s, "s",
                                          "wall time per phase of the step loop, in the order of phase_name", err)) ||
             /* Last: a file says completed only once everything else is written. */
             wf_h5_put_scalar_i64(g, "completed", pass, completed, "1", "1 when the run reached its end", err);
    return rc ? WF_ESYS : 0;
}

/* /meta at creation: provenance (final), the status (completed = 0, reason "running") and the row counters. */
static int write_meta(WfH5Result *w, const WfH5Run *r, WfError *err)
{
    const WfScenario *sc = r->sc;
    hid_t g = w->g_meta = wf_h5_group(w->file->fid, "meta", err);
    if (g < 0) return WF_ESYS;
    int rc = wf_h5_scalar_str(g, "scenario_text", sc->text, "the scenario file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sc->path, "scenario file as given", err) ||
             wf_h5_scalar_str(g, "overrides", sc->overrides, "--set assignments applied, one per line", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", wf_git_hash(), "git describe of the source tree", err) ||
             wf_h5_scalar_i64(g, "seed", (int64_t)sc->seed, "1", "random seed", err) ||
             wf_h5_scalar_i64(g, "threads", r->threads, "1", "OpenMP threads available to the run", err) ||
             wf_h5_scalar_str(g, "start_time", w->started, "wall-clock start, UTC ISO 8601", err) ||
             wf_h5_scalar_str(g, "integrator", sc->integrator, "time integrator", err) ||
             wf_h5_scalar_f64(g, "dt", sc->dt_s, "s", "time step", err) ||
             wf_h5_scalar_f64(g, "duration", sc->duration_s, "s", "simulated duration", err) ||
             wf_h5_scalar_f64(g, "warmup", sc->warmup_s, "s", w->b->warmup_desc, err) ||
             wf_h5_scalar_f64(g, "road_length", sc->road.length_m, "m", w->b->road_length_desc, err) ||
             w->b->meta(g, r, err) || meta_status(g, WF_H5_ALLOCATE, r, 0, "", err) ||
             meta_status(g, WF_H5_FILL, r, 0, "running", err) || write_counts(w, WF_H5_ALLOCATE, err) ||
             write_counts(w, WF_H5_FILL, err);
    return rc ? WF_ESYS : 0;
}

/* /classes and /drivers: what every boundary has, then the boundary's own (counts or shares). */
static int write_classes_drivers(hid_t fid, const WfH5Boundary *b, const WfH5Run *r, WfError *err)
{
    const WfScenario *sc = r->sc;
    const char *names[WF_MAX_CLASSES], *labels[WF_MAX_CLASSES], *fuels[WF_MAX_CLASSES], *duty[WF_MAX_CLASSES];
    double len[WF_MAX_CLASSES], dens[WF_MAX_CLASSES], kw[WF_MAX_CLASSES];
    hsize_t nc = sc->n_classes, ng = sc->n_groups;
    for (size_t c = 0; c < sc->n_classes; c++) {
        const WfVehicleClass *vc = &sc->classes[c].vc;
        names[c] = vc->name, labels[c] = vc->label, fuels[c] = wf_fuel_name(vc->fuel), duty[c] = wf_duty_name(vc->duty);
        len[c] = sc->classes[c].length_m, dens[c] = vc->fuel_density_g_per_l, kw[c] = vc->kw_per_gps;
    }
    const char *gn[WF_MAX_GROUPS], *gm[WF_MAX_GROUPS], *gs[WF_MAX_GROUPS];
    double noise[WF_MAX_GROUPS];
    for (size_t k = 0; k < sc->n_groups; k++) {
        gn[k] = sc->groups[k].name, gm[k] = sc->groups[k].model->name, noise[k] = sc->groups[k].noise_mps2;
        gs[k] = sc->groups[k].safety ? sc->groups[k].safety->name : "none";
    }
    hid_t g = wf_h5_group(fid, "classes", err), d = g < 0 ? g : wf_h5_group(fid, "drivers", err);
    int rc = g < 0 || d < 0 ||
             wf_h5_write_strings(g, "name", nc, names, "class name (vehicles/NAME.yaml); index = class_id", err) ||
             wf_h5_write_strings(g, "label", nc, labels, "human-readable class name", err) ||
             wf_h5_write_strings(g, "fuel", nc, fuels, "fuel type", err) ||
             wf_h5_write_strings(g, "duty", nc, duty, "light or heavy duty", err) ||
             wf_h5_write_f64(g, "length", 1, &nc, len, "m", "vehicle length used", err) ||
             wf_h5_write_f64(g, "fuel_density", 1, &nc, dens, "g/L", "fuel density for volume units", err) ||
             wf_h5_write_f64(g, "kw_per_gps", 1, &nc, kw, "kW/(g/s)", "equivalent power per fuel rate", err) ||
             wf_h5_write_strings(d, "name", ng, gn, "driver group name; index = group_id", err) ||
             wf_h5_write_strings(d, "model", ng, gm, "car-following model or controller", err) ||
             wf_h5_write_f64(d, "noise", 1, &ng, noise, "m/s^2", "acceleration noise standard deviation", err) ||
             /* only with a filter, like the summary's safety fields: other results keep their datasets */
             (wf_scenario_has_safety(sc) &&
              wf_h5_write_strings(d, "safety", ng, gs, "safety filter kind (none: no filter)", err)) ||
             b->fleet(g, d, r, err);
    if (g >= 0) H5Gclose(g);
    if (d >= 0) H5Gclose(d);
    return rc ? WF_ESYS : 0;
}

/* A failure while the file is set up (`why`, or the error in err): what the file needs, and that nothing is kept
 * (destroy removes a file whose run never started). */
static int setup_failed(WfH5Result *w, double ts, double app, double end, const char *why, WfError *err)
{
    char a[32], b[32], c[32], d[32], need[256], inner[sizeof err->msg];
    snprintf(inner, sizeof inner, "%s", why ? why : err->msg);
    if (app >= 0)
        snprintf(need, sizeof need, "up to about %s (time series %s, trajectories %s, end-of-run results %s)",
                 wf_h5_size_text(ts + app + end, a, sizeof a), wf_h5_size_text(ts, b, sizeof b),
                 wf_h5_size_text(app, c, sizeof c), wf_h5_size_text(end, d, sizeof d));
    else
        snprintf(need, sizeof need, "about %s to start (time series %s, end-of-run results %s) and more as %s are added",
                 wf_h5_size_text(ts + end, a, sizeof a), wf_h5_size_text(ts, b, sizeof b),
                 wf_h5_size_text(end, d, sizeof d), w->b->grows);
    return wf_err(err, why || !err->code ? WF_ESYS : err->code,
                  "%s: cannot create the result file, which needs %s: %s; nothing was simulated and the file is removed",
                  w->file->partial, need, inner);
}

/* Every group of the file and every dataset allocated at its final size (or created empty, for appended ones). */
static int create_structure(WfH5Result *w, const WfH5Run *r, WfError *err)
{
    hid_t fid = w->file->fid;
    int rc = write_meta(w, r, err) || write_classes_drivers(fid, w->b, r, err) ||
             w->b->results(fid, r, WF_H5_ALLOCATE, err) ||
             wf_h5_summary_write(fid, r->summary, r->sc, w->b->summary, WF_H5_ALLOCATE, err);
    for (size_t c = 0; !rc && c < w->b->n_cursors; c++) {
        if (!w->n_grp[c]) continue;
        hid_t g = wf_h5_group(fid, w->b->cursor[c].group, err);
        rc = g < 0 || (c == w->b->traj_cursor && w->b->traj_attrs(g, r, err));
        if (g >= 0) H5Gclose(g);
    }
    /* From here on the structure changes only when chunks of appended groups are added, after reserving space. */
    return rc || wf_ckpt_series_create(fid, w->sp, w->ns, err) || wf_h5_flush(w->file, err);
}

static int h5_begin(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Result *w = ctx;
    WfH5Run run = run_of(sim), *r = &run;
    const WfH5Boundary *b = w->b;
    size_t nf = b->frame_len(r);
    w->n_classes = r->sc->n_classes;
    w->buf = malloc(TS_BUF * (b->n_ts_cols + w->n_classes) * sizeof *w->buf);
    w->cls = malloc(TS_BUF * (w->n_classes ? w->n_classes : 1) * sizeof *w->cls);
    w->frame = malloc((nf ? nf : 1) * sizeof *w->frame);
    if (!w->buf || !w->cls || !w->frame) return wf_err(err, WF_ESYS, "out of memory");
    if (w->resume) return 0; /* wf_h5out_resume reopened the file and set it back to the checkpoint */
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(w->started, sizeof w->started, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    build_series(w, r);
    double ts = (double)w->sp[0].fixed_rows * (double)(b->n_ts_cols + w->n_classes) * 8.0, app, end;
    b->size(r, &app, &end);
    /* Refuse a run whose result cannot fit before simulating it (appended groups are allocated as they grow, so
     * this is the only early warning for them). */
    char why[200];
    if (wf_h5_check_room(w->file, ts + (app > 0 ? app : 0) + end, why, sizeof why))
        return setup_failed(w, ts, app, end, why, err);
    return create_structure(w, r, err) ? setup_failed(w, ts, app, end, NULL, err) : 0;
}

/* A write error in the run: the file keeps what was written before it (its row counters say how much). */
static int write_failed(WfH5Result *w, size_t cur, WfError *err)
{
    w->failed[cur] = 1;
    return wf_err_prefix(err, "%s: ", w->file->partial);
}

/* Refuse to write to a group whose write failed before (the run stops at the first error anyway). */
static int group_failed(const WfH5Result *w, size_t cur, WfError *err)
{
    return w->failed[cur] ? wf_err(err, WF_ESYS, "%s: not written after an earlier write error", w->file->partial)
                          : 0;
}

static int h5_record(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    (void)sim;
    WfH5Result *w = ctx;
    if (group_failed(w, 0, err)) return WF_ESYS;
    size_t nc = w->b->n_ts_cols;
    double *dst = w->buf + w->n_buf * (nc + w->n_classes);
    memcpy(dst, rec->v, nc * sizeof(double));
    memcpy(dst + nc, rec->class_fuel_rate_gps, w->n_classes * sizeof(double));
    if (++w->n_buf == TS_BUF && flush_ts(w, err)) return write_failed(w, 0, err);
    return 0;
}

int wf_h5r_append(WfH5Result *w, size_t cur, size_t n_rows, const double *const *data, WfError *err)
{
    if (group_failed(w, cur, err)) return WF_ESYS;
    char what[64];
    snprintf(what, sizeof what, "/%s", w->b->cursor[cur].group);
    if (wf_h5_series_append(w->file, w->grp[cur], w->n_grp[cur], n_rows, data, what, err) ||
        write_counts(w, WF_H5_FILL, err))
        return write_failed(w, cur, err);
    return 0;
}

/* One frame of the boundary's trajectory observer; a complete chunk is written (src/io/h5util.h), then counted. */
static int h5_trajectory(void *ctx, const WfSim *sim, double t_s, WfError *err)
{
    WfH5Result *w = ctx;
    WfH5Run r = run_of(sim);
    const double *cols[WF_H5_MAX_SERIES];
    size_t n = w->b->frame(&r, &t_s, w->frame, cols);
    return wf_h5r_append(w, w->b->traj_cursor, n, cols, err);
}

static void close_objects(WfH5Result *w)
{
    for (size_t k = 0; k < WF_H5_MAX_SERIES; k++) wf_h5_series_close(&w->ser[k]);
    /* An open group would keep the file open past H5Fclose (weak close degree): close it too. */
    if (w->g_meta >= 0) H5Gclose(w->g_meta);
    w->g_meta = H5I_INVALID_HID;
}

/* The buffered records and the pending rows of the appended groups (their last chunk), unless writing their group
 * failed before (its counter stays true); then the counters. */
static int flush_all(WfH5Result *w, WfError *err)
{
    if (!w->failed[0] && flush_ts(w, err)) return WF_ESYS;
    for (size_t c = 1; c < w->b->n_cursors; c++) {
        char what[64];
        snprintf(what, sizeof what, "/%s", w->b->cursor[c].group);
        if (!w->failed[c] && w->n_grp[c] && w->grp[c][0]->dset >= 0 &&
            wf_h5_series_flush(w->file, w->grp[c], w->n_grp[c], what, err))
            return WF_ESYS;
    }
    return write_counts(w, WF_H5_FILL, err);
}

static int h5_trips(void *ctx, const WfSim *sim, const struct WfTrip *trips, size_t n, WfError *err)
{
    (void)sim;
    WfH5Result *w = ctx;
    return w->b->trips(w, trips, n, err);
}

static int h5_end(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    WfH5Result *w = ctx;
    WfH5Run run = run_of(sim), *r = &run;
    w->ended = 1;
    hid_t fid = w->file->fid;
    /* The end-of-run results and the status are written whatever happened: in place, they cannot damage the
     * file, and they may well succeed. Only the first error is reported. */
    int rc = flush_all(w, err);
    WfError later = {0};
    WfError *e = rc ? &later : err;
    if (w->b->results(fid, r, WF_H5_FILL, e) ||
        wf_h5_summary_write(fid, r->summary, r->sc, w->b->summary, WF_H5_FILL, e)) {
        if (!rc) rc = WF_ESYS;
        e = &later;
    }
    /* A run that was to complete but could not be written is incomplete, for this reason; an interrupted or
     * failed run keeps its first cause. */
    if (rc && completed) completed = 0, reason = err->msg;
    if (meta_status(w->g_meta, WF_H5_FILL, r, completed, reason, e)) {
        if (!rc) rc = WF_ESYS;
        /* The status itself failed: say so in the file if the device still lets us. */
        if (completed) meta_status(w->g_meta, WF_H5_FILL, r, 0, err->msg, &later);
    }
    close_objects(w);
    if (rc) wf_err_prefix(err, "%s: ", w->file->partial);
    int done = !rc && completed;
    if (wf_h5_finish(&w->file, done, w->final_path, sizeof w->final_path, err)) return WF_ESYS;
    if (done) wf_ckpt_remove(w->final_path); /* the result is complete: its checkpoint is of no further use */
    return rc;
}

/* WfCkptWalk: the engine's blocks as the run hands them over, a piece at a time on a split ring. */
static int state_walk(void *sim, const WfStateVar *vars, size_t n, WfStatePieceFn put, void *ctx, WfError *err)
{
    return wf_sim_state_pieces(sim, vars, n, put, ctx, err);
}

/* ---- checkpoints (FILE.h5.ckpt, src/io/h5ckpt.h) and resumption ---- */

static int h5_checkpoint(void *ctx, const WfSim *sim, WfError *err)
{
    WfH5Result *w = ctx;
    /* The result file must hold every row the checkpoint counts (but the pending rows it saves) before the
     * checkpoint exists. */
    if (flush_ts(w, err)) return write_failed(w, 0, err);
    if (wf_h5_flush(w->file, err)) {
        for (size_t c = 1; c < w->b->n_cursors; c++) w->failed[c] = 1;
        return write_failed(w, 0, err);
    }
    WfStateVar vars[WF_MAX_STATE_VARS];
    /* The state function packs the engine's scalars before listing the blocks; they are only read here. */
    size_t nv = wf_sim_state((WfSim *)sim, vars, WF_MAX_STATE_VARS);
    return wf_ckpt_save(w->file->path, w->b->kind, wf_sim_scenario(sim), wf_sim_steps_done(sim), w->cur,
                        w->b->n_cursors, w->sp, w->ns, vars, nv, state_walk, (void *)sim, err);
}

/* The reopened file back at the checkpoint: the counters at its rows (lowering a counter is always safe), the
 * appended groups cut to the whole chunks it counts (their later rows are written again), then the status back to
 * "running" (should the cut fail, the file keeps the interrupted run's reason). */
static int resume_file(WfH5Result *w, const WfH5Run *r, WfError *err)
{
    w->g_meta = H5Gopen2(w->file->fid, "meta", H5P_DEFAULT);
    int rc = w->g_meta < 0 ? wf_err(err, WF_EINPUT, "no group /meta") : write_counts(w, WF_H5_FILL, err);
    for (size_t c = 1; !rc && c < w->b->n_cursors; c++) rc = wf_h5_series_trim(w->file, w->grp[c], w->n_grp[c], err);
    if (!rc) rc = meta_status(w->g_meta, WF_H5_FILL, r, 0, "running", err) || wf_h5_flush(w->file, err);
    return rc ? wf_err_prefix(err, "%s: ", w->file->partial) : 0;
}

static WfOutput ops_of(WfH5Result *w)
{
    return (WfOutput){.begin = h5_begin, .record = h5_record, .trajectory = h5_trajectory,
                      .trips = w->b->trips ? h5_trips : NULL, .checkpoint = h5_checkpoint, .end = h5_end, .ctx = w};
}

/* A writer for `result` whose run is set back to its checkpoint (nothing written yet); NULL with err set. */
static WfH5Result *restored_writer(const char *result, WfSim *sim, WfError *err)
{
    WfH5Result *w = new_writer(sim, err);
    if (!w) return NULL;
    const WfH5Boundary *b = w->b;
    WfH5Run r = run_of(sim);
    w->resume = 1;
    build_series(w, &r);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS);
    /* The checkpoint and the partial file are read and verified completely before the file is changed. */
    int rc = wf_ckpt_restore(result, b->kind, r.sc, w->cur, b->n_cursors, w->sp, w->ns, vars, nv, err);
    if (!rc) rc = wf_sim_restored(sim, err);
    if (rc) wf_h5out_destroy(&w);
    return w;
}

int wf_h5out_restore(const char *result, WfSim *sim, WfError *err)
{
    WfH5Result *w = restored_writer(result, sim, err);
    if (!w) return err->code ? err->code : WF_EINPUT;
    wf_h5out_destroy(&w);
    return 0;
}

int wf_h5out_resume(const char *result, WfSim *sim, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Result *w = restored_writer(result, sim, err);
    if (!w) return err->code ? err->code : WF_EINPUT;
    WfH5Run r = run_of(sim);
    int rc = wf_ckpt_reopen(result, r.sc, w->sp, w->ns, &w->file, err);
    if (!rc) rc = resume_file(w, &r, err);
    if (rc) {
        wf_h5out_destroy(&w);
        return rc;
    }
    *out = w;
    *ops = ops_of(w);
    return 0;
}

int wf_h5out_create(const WfSim *sim, const char *path, int force, WfH5Out **out, WfOutput *ops, WfError *err)
{
    *out = NULL;
    WfH5Result *w = new_writer(sim, err);
    if (!w) return err->code;
    int rc = wf_h5_create(path, force, &w->file, err);
    if (rc) {
        free(w);
        return rc;
    }
    *out = w;
    *ops = ops_of(w);
    return 0;
}

void wf_h5out_destroy(WfH5Out **pw)
{
    if (!pw || !*pw) return;
    WfH5Result *w = *pw;
    close_objects(w);
    /* A run that never started writing removes its file (nothing was simulated); a resumed one never deletes
     * what it reopened. */
    if (w->file) wf_h5_abandon(&w->file, !w->ended && !w->resume);
    WF_FREE(w->buf, w->cls, w->frame, w);
    *pw = NULL;
}

const char *wf_h5out_path(const WfH5Out *w) { return w->final_path; }

const char *wf_h5out_counters(const WfH5Out *w, char *buf, size_t len)
{
    size_t n = w->b->n_cursors, used = 0;
    buf[0] = '\0';
    for (size_t c = 0; c < n; c++) {
        int k = snprintf(buf + used, len - used, "%s%s", c == 0 ? "/meta/" : c + 1 == n ? " and " : ", ",
                         w->b->cursor[c].meta);
        if (k < 0 || (size_t)k >= len - used) break;
        used += (size_t)k;
    }
    return buf;
}
