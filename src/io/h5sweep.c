/* The result table of a sweep (docs/sweeps.md): one row per run in /runs, /params, /metrics and /class_metrics
 * (reproducible: identical for any number of threads or ranks), wall times in /timing. Written whole and atomically
 * (PATH.partial, then a rename), so PATH is always a consistent snapshot a rerun can resume from. */
#include "wavefuel/sweep.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "io/h5util.h"
#include "util/mem.h"
#include "wavefuel/version.h"


static int write_meta(hid_t fid, const WfSweep *sw, const WfSweepResult *res, WfError *err)
{
    int64_t n_ok = 0, n_failed = 0, n_pending = 0;
    for (size_t i = 0; i < sw->n_runs; i++) {
        n_ok += res[i].status == WF_RUN_OK;
        n_failed += res[i].status == WF_RUN_FAILED;
        n_pending += res[i].status == WF_RUN_PENDING;
    }
    char when[64];
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    hid_t g = wf_h5_group(fid, "meta", err);
    if (g < 0) return WF_ESYS;
    int rc = wf_h5_scalar_str(g, "kind", "wavefuel sweep", "marks a sweep result table", err) ||
             wf_h5_scalar_str(g, "name", sw->name, "sweep name", err) ||
             wf_h5_scalar_str(g, "sweep_path", sw->path, "sweep file as given", err) ||
             wf_h5_scalar_str(g, "sweep_text", sw->text, "the sweep file, verbatim", err) ||
             wf_h5_scalar_str(g, "scenario_path", sw->scenario_path, "base scenario of every run", err) ||
             wf_h5_scalar_str(g, "scenario_text", sw->scenario_text,
                              "the base scenario, verbatim, as every run used it", err) ||
             wf_h5_scalar_str(g, "version", WF_VERSION, "wavefuel version", err) ||
             wf_h5_scalar_str(g, "git_hash", wf_git_hash(), "git describe of the source tree", err) ||
             wf_h5_scalar_str(g, "written", when, "time of this snapshot, UTC ISO 8601", err) ||
             wf_h5_scalar_i64(g, "runs", (int64_t)sw->n_runs, "1", "rows of the table", err) ||
             wf_h5_scalar_i64(g, "runs_ok", n_ok, "1", "runs completed", err) ||
             wf_h5_scalar_i64(g, "runs_failed", n_failed, "1", "runs that failed (error in /runs/error)", err) ||
             wf_h5_scalar_i64(g, "runs_pending", n_pending, "1", "runs not done yet (a rerun does them)", err) ||
             wf_h5_scalar_i64(g, "complete", n_pending == 0, "1", "1 when no run is pending", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_params(hid_t fid, const WfSweep *sw, WfError *err)
{
    hid_t g = wf_h5_group(fid, "params", err);
    if (g < 0) return WF_ESYS;
    size_t n = sw->n_runs;
    hsize_t dn = n;
    double *d = malloc(n * sizeof *d);
    const char **s = malloc(n * sizeof *s);
    int rc = (!d || !s) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t a = 0; !rc && a < sw->n_axes; a++) {
        const WfSweepAxis *ax = &sw->axes[a];
        char desc[700];
        snprintf(desc, sizeof desc, "sweep axis: the value this run gave %s%s", ax->keys,
                 ax->numeric ? " (NaN: not set by the run)" : " (empty: not set by the run)");
        if (ax->numeric) {
            for (size_t i = 0; i < n; i++) {
                const char *v = sw->runs[i].value[a];
                if (!v || wf_parse_double(v, &d[i])) d[i] = NAN;
            }
            rc = wf_h5_write_f64(g, ax->name, 1, &dn, d, ax->units, desc, err);
        } else {
            for (size_t i = 0; i < n; i++) s[i] = sw->runs[i].value[a] ? sw->runs[i].value[a] : "";
            rc = wf_h5_write_strings(g, ax->name, n, s, desc, err);
        }
        if (!rc) {
            hid_t ds = H5Dopen2(g, ax->name, H5P_DEFAULT);
            rc = ds < 0 ? wf_err(err, WF_ESYS, "HDF5: cannot reopen /params/%s", ax->name)
                        : wf_h5_attr_str(ds, "keys", ax->keys, err);
            if (ds >= 0) H5Dclose(ds);
        }
    }
    free(d);
    free(s);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_runs(hid_t fid, const WfSweep *sw, const WfSweepResult *res, WfError *err)
{
    size_t n = sw->n_runs;
    hsize_t dn = n;
    hid_t g = wf_h5_group(fid, "runs", err);
    if (g < 0) return WF_ESYS;
    int64_t *k = malloc(n * sizeof *k);
    const char **s = malloc(n * sizeof *s);
    char **owned = calloc(n, sizeof *owned);
    int rc = (!k || !s || !owned) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    if (!rc) {
        for (size_t i = 0; i < n; i++) k[i] = (int64_t)i;
        rc = wf_h5_write_i64(g, "index", 1, &dn, k, "1", "row number: the run's place in the sweep's order", err);
    }
#define STRINGS(name, expr, desc)                                  \
    if (!rc) {                                                     \
        for (size_t i = 0; i < n; i++) s[i] = (expr);              \
        rc = wf_h5_write_strings(g, name, n, s, desc, err);        \
    }
    STRINGS("status", wf_run_status_names[res[i].status], "ok, failed, or pending (not done yet: a rerun does it)");
    STRINGS("error", res[i].error, "why the run failed (empty when ok)");
    STRINGS("file", res[i].file, "the run's own result file (--per-run-files), empty without one");
    STRINGS("classes", res[i].classes, "vehicle classes of the run, comma-separated: the columns of /class_metrics");
#undef STRINGS
    if (!rc) {
        for (size_t i = 0; i < n; i++) k[i] = res[i].seed;
        rc = wf_h5_write_i64(g, "seed", 1, &dn, k, "1", "the run's random seed (-1: its scenario did not load)", err);
    }
    for (size_t i = 0; !rc && i < n; i++) rc = wf_sweep_overrides(sw, i, &owned[i], err);
    if (!rc) rc = wf_h5_write_strings(g, "overrides", n, (const char *const *)owned,
                                      "the run's --set assignments, one per line (identifies the run on resume)", err);
    for (size_t i = 0; !rc && i < n; i++) {
        /* Each command is at most the overrides plus quoting, the scenario path and the words around them. */
        size_t len = 4 * strlen(owned[i]) + 4 * strlen(sw->scenario_path) + 16 * sw->runs[i].n_set + 64;
        free(owned[i]);
        owned[i] = malloc(len);
        if (!owned[i]) rc = wf_err(err, WF_ESYS, "out of memory");
        else if (wf_sweep_command(sw, i, NULL, owned[i], len))
            rc = wf_err(err, WF_ESYS, "command of run %zu too long", i);
    }
    if (!rc) rc = wf_h5_write_strings(g, "command", n, (const char *const *)owned,
                                      "the `wavefuel run` command that reproduces the run alone", err);
    for (size_t i = 0; owned && i < n; i++) free(owned[i]);
    WF_FREE(owned, s, k);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

/* The sweep table's metrics are the ring's summary fields (wavefuel/summary.h), one column each; a class field is a
 * [run x class] array. Rows that are not ok hold NaN (and -1 in the integer columns): no value was measured. */
static int write_metric(hid_t g, const WfSummaryField *f, int per_class, size_t n, size_t nc, const WfSweepResult *res,
                        double *d, int64_t *k, WfError *err)
{
    hsize_t dims[2] = {n, per_class ? nc : 1};
    size_t w = per_class ? nc : 1;
    int integer = f->type != WF_SUMMARY_F64;
    for (size_t i = 0; i < n; i++)
        for (size_t c = 0; c < w; c++) {
            int ok = res[i].status == WF_RUN_OK && (!per_class || c < res[i].n_classes);
            double v = ok ? wf_summary_value(per_class ? (const void *)&res[i].summary.cls[c] : &res[i].summary, f) : NAN;
            if (integer) k[i * w + c] = ok ? (int64_t)v : -1;
            else d[i * w + c] = v;
        }
    char desc[300];
    snprintf(desc, sizeof desc, "%s%s%s", f->desc[WF_SUMMARY_RING],
             per_class ? (integer ? " [run x class]" : " [run x class, classes named in /runs/classes]") : "",
             integer ? " (-1: no value)" : "");
    return integer ? wf_h5_write_i64(g, f->name, per_class ? 2 : 1, dims, k, f->units, desc, err)
                   : wf_h5_write_f64(g, f->name, per_class ? 2 : 1, dims, d, f->units, desc, err);
}

static int write_metrics(hid_t fid, const WfSweep *sw, const WfSweepResult *res, WfError *err)
{
    size_t n = sw->n_runs, nc = 1;
    for (size_t i = 0; i < n; i++)
        if (res[i].status == WF_RUN_OK && res[i].n_classes > nc) nc = res[i].n_classes;
    hid_t g = wf_h5_group(fid, "metrics", err), gc = H5I_INVALID_HID;
    if (g < 0) return WF_ESYS;
    gc = wf_h5_group(fid, "class_metrics", err);
    double *d = malloc(n * nc * sizeof *d);
    int64_t *k = malloc(n * nc * sizeof *k);
    int rc = (gc < 0) ? WF_ESYS : (!d || !k) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t m = 0; !rc && m < wf_summary_n_fields; m++)
        if (wf_summary_in_sweep(&wf_summary_fields[m]))
            rc = write_metric(g, &wf_summary_fields[m], 0, n, nc, res, d, k, err);
    for (size_t m = 0; !rc && m < wf_summary_n_class_fields; m++)
        if (wf_summary_in_sweep(&wf_summary_class_fields[m]))
            rc = write_metric(gc, &wf_summary_class_fields[m], 1, n, nc, res, d, k, err);
    free(d);
    free(k);
    if (gc >= 0) H5Gclose(gc);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

static int write_timing(hid_t fid, const WfSweep *sw, const WfSweepResult *res, const WfSweepTiming *t, WfError *err)
{
    size_t n = sw->n_runs;
    hsize_t dn = n;
    hid_t g = wf_h5_group(fid, "timing", err);
    if (g < 0) return WF_ESYS;
    double *d = malloc(n * sizeof *d);
    int64_t *k = malloc(n * sizeof *k);
    int rc = (!d || !k) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    if (!rc) {
        for (size_t i = 0; i < n; i++) d[i] = res[i].status == WF_RUN_PENDING ? NAN : res[i].wall_s;
        rc = wf_h5_write_f64(g, "wall_time", 1, &dn, d, "s", "wall time of the run: load, simulate, per-run file", err);
    }
    static const char *const ints[][2] = {{"worker", "thread number or MPI rank that ran it"},
                                          {"threads", "OpenMP threads inside the run"}};
    for (int q = 0; !rc && q < 2; q++) {
        for (size_t i = 0; i < n; i++) k[i] = res[i].status == WF_RUN_PENDING ? -1 : q ? res[i].threads : res[i].worker;
        rc = wf_h5_write_i64(g, ints[q][0], 1, &dn, k, "1", ints[q][1], err);
    }
    if (!rc && t)
        rc = wf_h5_scalar_str(g, "mode", t->mode, "threads (one machine) or mpi", err) ||
             wf_h5_scalar_i64(g, "workers", t->workers, "1", "runs executing at once in the last invocation", err) ||
             wf_h5_scalar_i64(g, "threads_per_run", t->threads_per_run, "1", "OpenMP threads inside each run", err) ||
             wf_h5_scalar_f64(g, "sweep_wall_time", t->wall_s, "s", "wall time of the last invocation", err);
    free(d);
    free(k);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

int wf_sweep_table_write(const char *path, const WfSweep *sw, const WfSweepResult *res, const WfSweepTiming *timing,
                         WfError *err)
{
    WfH5File *f = NULL;
    /* force: PATH is this sweep's previous snapshot (cmd_sweep checked it may be replaced before starting). */
    int rc = wf_h5_create(path, 1, &f, err);
    if (rc) return rc;
    rc = write_meta(f->fid, sw, res, err);
    if (!rc) rc = write_params(f->fid, sw, err);
    if (!rc) rc = write_runs(f->fid, sw, res, err);
    if (!rc) rc = write_metrics(f->fid, sw, res, err);
    if (!rc) rc = write_timing(f->fid, sw, res, timing, err);
    if (rc) {
        wf_h5_abandon(&f, 1);
        return rc;
    }
    return wf_h5_commit(&f, err);
}

/* ---- Reading a table back ---- */

static int bad(WfError *err, const char *path, const char *what)
{
    return wf_err(err, WF_EINPUT, "%s: not a wavefuel sweep table, or damaged (%s)", path, what);
}

/* Number of rows of the 1-D or 2-D dataset `name`; cols gets the second dimension (1 for 1-D). */
static int shape(hid_t loc, const char *name, hsize_t *rows, hsize_t *cols)
{
    hsize_t dims[2] = {0, 1};
    int rank = -1;
    /* H5LTget_dataset_info writes one entry per dimension: asked only once the rank fits dims[]. */
    if (H5LTget_dataset_ndims(loc, name, &rank) < 0 || rank < 1 || rank > 2 ||
        H5LTget_dataset_info(loc, name, dims, NULL, NULL) < 0)
        return -1;
    *rows = dims[0];
    *cols = rank == 2 ? dims[1] : 1;
    return 0;
}

/* A 1-D string column of exactly n rows; fn(i, text) is called for each. */
static int read_strings(hid_t loc, const char *name, size_t n, void (*fn)(WfSweepSaved *, size_t, const char *),
                        WfSweepSaved *sv)
{
    hid_t t = wf_h5_text_type(H5T_VARIABLE);
    hsize_t rows = 0, cols = 0;
    char **s = calloc(n ? n : 1, sizeof *s);
    int rc = !s || t < 0 || shape(loc, name, &rows, &cols) || rows != n || cols != 1;
    if (!rc && n && H5LTread_dataset(loc, name, t, s) < 0) rc = 1;
    for (size_t i = 0; !rc && i < n; i++) {
        fn(sv, i, s[i] ? s[i] : "");
        H5free_memory(s[i]); /* HDF5 allocated each string */
    }
    free(s);
    if (t >= 0) H5Tclose(t);
    return rc;
}

/* A numeric column of n rows and `cols` columns (cols = 1 also accepts a 1-D dataset); cols 0: any width, stored
 * in *got_cols. Returns a malloc'ed array or NULL. */
static void *read_numeric(hid_t loc, const char *name, hid_t type, size_t size, size_t n, size_t *cols)
{
    hsize_t rows = 0, c = 0;
    void *buf = NULL;
    if (!shape(loc, name, &rows, &c) && rows == n && (*cols == 0 || c == *cols)) {
        buf = malloc((size_t)(rows * c > 0 ? rows * c : 1) * size);
        if (buf && H5LTread_dataset(loc, name, type, buf) < 0) {
            free(buf);
            buf = NULL;
        }
        *cols = (size_t)c;
    }
    return buf;
}

/* One metric column back into the rows' summaries; per_class: a [run x class] array of width *wc (learnt from
 * the first class column read). */
static int read_metric(hid_t g, const WfSummaryField *f, int per_class, WfSweepSaved *sv, size_t *wc, const char *path,
                       WfError *err)
{
    size_t w = per_class ? *wc : 1;
    int integer = f->type != WF_SUMMARY_F64;
    void *buf = read_numeric(g, f->name, integer ? H5T_NATIVE_INT64 : H5T_NATIVE_DOUBLE, 8, sv->n, &w);
    if (!buf || w > WF_MAX_CLASSES) {
        free(buf);
        return bad(err, path, f->name);
    }
    if (per_class) *wc = w;
    for (size_t i = 0; i < sv->n; i++)
        for (size_t c = 0; c < w; c++) {
            void *base = per_class ? (void *)&sv->res[i].summary.cls[c] : (void *)&sv->res[i].summary;
            if (!integer) *(double *)((char *)base + f->offset) = ((const double *)buf)[i * w + c];
            else if (f->type == WF_SUMMARY_LONG) *(long *)((char *)base + f->offset) = (long)((const int64_t *)buf)[i * w + c];
            else *(int64_t *)((char *)base + f->offset) = ((const int64_t *)buf)[i * w + c];
        }
    free(buf);
    return 0;
}

static void put_overrides(WfSweepSaved *sv, size_t i, const char *s) { sv->overrides[i] = strdup(s); }
static void put_error(WfSweepSaved *sv, size_t i, const char *s)
{
    snprintf(sv->res[i].error, sizeof sv->res[i].error, "%s", s);
}
static void put_file(WfSweepSaved *sv, size_t i, const char *s)
{
    snprintf(sv->res[i].file, sizeof sv->res[i].file, "%s", s);
}
static void put_classes(WfSweepSaved *sv, size_t i, const char *s)
{
    snprintf(sv->res[i].classes, sizeof sv->res[i].classes, "%s", s);
    sv->res[i].n_classes = s[0] ? 1 : 0;
    for (const char *c = s; *c; c++) sv->res[i].n_classes += *c == ',';
}
static void put_status(WfSweepSaved *sv, size_t i, const char *s)
{
    sv->res[i].status = -1;
    for (int k = 0; k < 3; k++)
        if (!strcmp(s, wf_run_status_names[k])) sv->res[i].status = k;
}

void wf_sweep_saved_free(WfSweepSaved *sv)
{
    for (size_t i = 0; sv->overrides && i < sv->n; i++) free(sv->overrides[i]);
    WF_FREE(sv->overrides, sv->res, sv->scenario_text, sv->scenario_path);
    memset(sv, 0, sizeof *sv);
}

/* /metrics and /class_metrics into sv->res[].summary (sv->n rows). */
static int read_metrics(hid_t met, hid_t cm, const char *path, WfSweepSaved *sv, WfError *err)
{
    int rc = 0;
    size_t wc = 0;
    for (size_t m = 0; !rc && m < wf_summary_n_fields; m++)
        if (wf_summary_in_sweep(&wf_summary_fields[m])) rc = read_metric(met, &wf_summary_fields[m], 0, sv, &wc, path, err);
    for (size_t m = 0; !rc && m < wf_summary_n_class_fields; m++)
        if (wf_summary_in_sweep(&wf_summary_class_fields[m]))
            rc = read_metric(cm, &wf_summary_class_fields[m], 1, sv, &wc, path, err);
    return rc;
}

/* /timing: each run's wall time, worker and threads. */
static int read_timing(hid_t tim, const char *path, WfSweepSaved *sv, WfError *err)
{
    size_t w1 = 1;
    double *d = read_numeric(tim, "wall_time", H5T_NATIVE_DOUBLE, sizeof *d, sv->n, &w1);
    if (!d) return bad(err, path, "wall_time");
    for (size_t i = 0; i < sv->n; i++) sv->res[i].wall_s = d[i];
    free(d);
    const char *ints[] = {"worker", "threads"};
    for (int q = 0; q < 2; q++) {
        w1 = 1;
        int64_t *k = read_numeric(tim, ints[q], H5T_NATIVE_INT64, sizeof *k, sv->n, &w1);
        if (!k) return bad(err, path, ints[q]);
        for (size_t i = 0; i < sv->n; i++) *(q ? &sv->res[i].threads : &sv->res[i].worker) = (int)k[i];
        free(k);
    }
    return 0;
}

int wf_sweep_table_read(const char *path, WfSweepSaved *sv, WfError *err)
{
    memset(sv, 0, sizeof *sv);
    wf_h5_library_init();
    if (H5Fis_hdf5(path) <= 0) return bad(err, path, "not an HDF5 file");
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return wf_err(err, WF_ESYS, "%s: cannot open", path);
    int rc = 0;
    char *kind = NULL;
    hid_t runs = H5I_INVALID_HID, met = H5I_INVALID_HID, cm = H5I_INVALID_HID, tim = H5I_INVALID_HID;
    hsize_t n = 0, one = 0;
    /* The messages of the readers are replaced by one naming what is missing. */
    if (wf_h5_read_scalar_str(f, path, "meta/kind", &kind, err) || strcmp(kind, "wavefuel sweep") != 0)
        rc = bad(err, path, "/meta/kind");
    if (!rc && (wf_h5_read_scalar_str(f, path, "meta/scenario_text", &sv->scenario_text, err) ||
                wf_h5_read_scalar_str(f, path, "meta/scenario_path", &sv->scenario_path, err)))
        rc = bad(err, path, "/meta/scenario_text");
    if (!rc && ((runs = H5Gopen2(f, "runs", H5P_DEFAULT)) < 0 || (met = H5Gopen2(f, "metrics", H5P_DEFAULT)) < 0 ||
                (cm = H5Gopen2(f, "class_metrics", H5P_DEFAULT)) < 0 || (tim = H5Gopen2(f, "timing", H5P_DEFAULT)) < 0))
        rc = bad(err, path, "groups /runs, /metrics, /class_metrics, /timing");
    if (!rc && (shape(runs, "overrides", &n, &one) || one != 1)) rc = bad(err, path, "/runs/overrides");
    if (!rc) {
        sv->n = (size_t)n;
        sv->overrides = calloc(sv->n ? sv->n : 1, sizeof *sv->overrides);
        sv->res = calloc(sv->n ? sv->n : 1, sizeof *sv->res);
        if (!sv->overrides || !sv->res) rc = wf_err(err, WF_ESYS, "out of memory");
    }
    struct { const char *name; void (*fn)(WfSweepSaved *, size_t, const char *); } cols[] = {
        {"overrides", put_overrides}, {"status", put_status}, {"error", put_error},
        {"file", put_file},           {"classes", put_classes},
    };
    for (size_t c = 0; !rc && c < sizeof cols / sizeof cols[0]; c++)
        if (read_strings(runs, cols[c].name, sv->n, cols[c].fn, sv)) rc = bad(err, path, cols[c].name);
    for (size_t i = 0; !rc && i < sv->n; i++) {
        if (!sv->overrides[i]) rc = wf_err(err, WF_ESYS, "out of memory");
        else if (sv->res[i].status < 0) rc = bad(err, path, "/runs/status");
    }
    size_t w1 = 1;
    int64_t *k = NULL;
    if (!rc) {
        if (!(k = read_numeric(runs, "seed", H5T_NATIVE_INT64, sizeof *k, sv->n, &w1))) rc = bad(err, path, "seed");
        for (size_t i = 0; !rc && i < sv->n; i++) sv->res[i].seed = k[i];
        free(k);
    }
    if (!rc) rc = read_metrics(met, cm, path, sv, err);
    if (!rc) rc = read_timing(tim, path, sv, err);
    /* Failed rows keep their error; their code is not stored (an input error is the usual cause). */
    for (size_t i = 0; !rc && i < sv->n; i++)
        if (sv->res[i].status == WF_RUN_FAILED) sv->res[i].error_code = WF_EINPUT;
    free(kind);
    if (tim >= 0) H5Gclose(tim);
    if (cm >= 0) H5Gclose(cm);
    if (met >= 0) H5Gclose(met);
    if (runs >= 0) H5Gclose(runs);
    H5Fclose(f);
    if (rc) wf_sweep_saved_free(sv);
    return rc;
}
