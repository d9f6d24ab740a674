/* The one HDF5 result writer of runs (docs/output.md), for rings and corridors alike: the file created as
 * PATH.partial, /meta with provenance, status and row counters, /classes and /drivers, /summary, the time series
 * buffered and written in blocks, the appended groups (trajectories; trips) grown a chunk at a time, the size
 * estimate, checkpoints and resumption, and the end of the run. What differs between boundaries is a WfH5Boundary:
 * its observers' series and column tables (src/observe/columns.h), its end-of-run groups and a few extra datasets.
 * The boundary files (src/io/h5out.c ring, src/io/h5corridor.c corridor) bind it to their engine's output
 * callbacks. A write error at any point leaves a file whose structure is intact (docs/output.md, "Write errors").
 * Internal to wavefuel (not installed). */
#ifndef WAVEFUEL_IO_H5RESULT_H
#define WAVEFUEL_IO_H5RESULT_H

#include "io/h5ckpt.h"
#include "io/h5util.h"
#include "observe/columns.h"
#include "wavefuel/summary.h"

/* Write the columns cols[0..n) of one group g with their values data[0..n): a column known at the start is written
 * in the allocating pass only, the others are allocated (ALLOCATE) and written in place (FILL), as wf_h5_put_f64. */
int wf_h5_put_columns(hid_t g, const WfObsColumn *cols, const WfObsData *data, size_t n, WfH5Pass pass,
                      WfError *err);

/* What the writer reads of the engine at a callback (filled by the boundary file; everything borrowed). */
typedef struct WfH5Run {
    const void       *eng;       /* the engine: const WfSim * or const WfCorridor *, for the boundary's hooks */
    const WfScenario *sc;
    const WfSummary  *summary;   /* valid at the end */
    double            wall_s;
    long              steps_done;
    int               threads;
    const double     *phase_s;   /* WF_N_PHASES wall times of the step loop, or NULL when not measured */
} WfH5Run;

/* A group of series counted together (cursor): its group in the file and checkpoint, its counter in /meta. */
typedef struct WfH5Cursor {
    const char *group, *meta, *desc;
} WfH5Cursor;

enum { WF_H5_MAX_CURSORS = 4, WF_H5_MAX_SERIES = 48 };

typedef struct WfH5Boundary {
    const char        *kind;          /* checkpoint kind: "ring" or "corridor" */
    WfSummaryBoundary  summary;
    const char        *road_length_desc, *warmup_desc; /* of /meta/road_length and /meta/warmup */
    const WfH5Cursor  *cursor;        /* cursor[0]: /timeseries (fixed rows); the others appended */
    size_t             n_cursors, traj_cursor;
    const WfColumn    *ts_cols;       /* the record's scalar columns, then the per-class column */
    size_t             n_ts_cols;
    const WfColumn    *ts_class_col;
    const char        *grows;         /* appended groups whose size cannot be estimated, or NULL */
    /* The appended series into sp (col, cols, chunk_rows, compress, cursor; the writer sets s and group), at
     * most WF_H5_MAX_SERIES minus the time series. Returns how many. */
    size_t (*series)(const WfH5Run *r, WfCkptSeries *sp);
    /* Bytes the appended groups need (negative: not known in advance) and the end-of-run results. */
    void   (*size)(const WfH5Run *r, double *appended, double *end);
    /* Datasets of /meta, /classes and /drivers and attributes of /trajectories only this boundary has, written
     * when the file is created. */
    int    (*meta)(hid_t g, const WfH5Run *r, WfError *err);
    int    (*fleet)(hid_t classes, hid_t drivers, const WfH5Run *r, WfError *err);
    int    (*traj_attrs)(hid_t g, const WfH5Run *r, WfError *err);
    /* The boundary's own groups: ALLOCATE when the file is created, FILL at the end (/summary is the writer's). */
    int    (*results)(hid_t fid, const WfH5Run *r, WfH5Pass pass, WfError *err);
    /* A trajectory frame: doubles of scratch it needs, and the frame at t (cols: one array per column of the
     * trajectory cursor, in scratch or borrowed). Returns its rows. */
    size_t (*frame_len)(const WfH5Run *r);
    size_t (*frame)(const WfH5Run *r, const double *t_s, double *scratch, const double **cols);
    /* The engine's state blocks (engine.h: WfStateVar) and its check after they were written back. */
    size_t (*state)(void *eng, WfStateVar *vars, size_t max);
    int    (*restored)(void *eng, WfError *err);
} WfH5Boundary;

typedef struct WfH5Result WfH5Result;

/* Create the writer of boundary b (static, borrowed) for `path` (refuses to replace an existing result unless
 * force): PATH.partial is created now, its contents at begin. The caller frees it with wf_h5r_destroy. */
int  wf_h5r_create(const char *path, int force, const WfH5Boundary *b, WfH5Result **out, WfError *err);
/* Load the checkpoint of `result` into the engine r->eng (built from the scenario it holds) and reopen
 * PATH.partial to continue writing from the checkpoint's rows (src/io/h5ckpt.h). WF_EINPUT when the checkpoint
 * or the file is not this run's; WF_ESYS when setting the file back fails. Freed with wf_h5r_destroy. */
int  wf_h5r_resume(const char *result, const WfH5Boundary *b, const WfH5Run *r, void *eng, WfH5Result **out,
                   WfError *err);
/* Free the writer; a file whose run never reached end() is removed unless it was resumed. Accepts NULL. */
void wf_h5r_destroy(WfH5Result **w);
/* Final path written ("x.h5" when completed, "x.h5.partial" otherwise; empty before end()). Owned by w. */
const char *wf_h5r_path(const WfH5Result *w);

/* The output callbacks, as the engines' WfOutput and WfCorridorOutput describe them. */
int wf_h5r_begin(WfH5Result *w, const WfH5Run *r, WfError *err);
/* One record: the boundary's scalar columns v, then the class fuel rates cls. */
int wf_h5r_record(WfH5Result *w, const double *v, const double *cls, WfError *err);
int wf_h5r_trajectory(WfH5Result *w, const WfH5Run *r, double t_s, WfError *err);
/* n_rows rows of the appended cursor `cur` (data[k]: the rows of its k-th series), counted in /meta after. */
int wf_h5r_append(WfH5Result *w, size_t cur, size_t n_rows, const double *const *data, WfError *err);
int wf_h5r_checkpoint(WfH5Result *w, const WfH5Run *r, void *eng, WfError *err);
int wf_h5r_end(WfH5Result *w, const WfH5Run *r, int completed, const char *reason, WfError *err);

/* The engine callbacks h5_begin, h5_record, h5_trajectory, h5_checkpoint and h5_end of an engine type Eng whose
 * records are of type Row (with members v and class_fuel_rate_gps), calling the functions above with the WfH5Run
 * that run_of(const Eng *) makes: the ring's WfOutput and the corridor's WfCorridorOutput differ only in these
 * types, so a boundary file defines its callbacks with this one line instead of a copy. */
#define WF_H5R_CALLBACKS(Eng, Row, run_of)                                                                  \
    static int h5_begin(void *ctx, const Eng *e, WfError *err)                                              \
    {                                                                                                        \
        WfH5Run r = run_of(e);                                                                               \
        return wf_h5r_begin(ctx, &r, err);                                                                   \
    }                                                                                                        \
    static int h5_record(void *ctx, const Eng *e, const Row *row, WfError *err)                             \
    {                                                                                                        \
        (void)e;                                                                                             \
        return wf_h5r_record(ctx, row->v, row->class_fuel_rate_gps, err);                                    \
    }                                                                                                        \
    static int h5_trajectory(void *ctx, const Eng *e, double t_s, WfError *err)                             \
    {                                                                                                        \
        WfH5Run r = run_of(e);                                                                               \
        return wf_h5r_trajectory(ctx, &r, t_s, err);                                                         \
    }                                                                                                        \
    /* The engine's state functions only read it (they pack its scalars first). */                          \
    static int h5_checkpoint(void *ctx, const Eng *e, WfError *err)                                         \
    {                                                                                                        \
        WfH5Run r = run_of(e);                                                                               \
        return wf_h5r_checkpoint(ctx, &r, (Eng *)e, err);                                                    \
    }                                                                                                        \
    static int h5_end(void *ctx, const Eng *e, int completed, const char *reason, WfError *err)             \
    {                                                                                                        \
        WfH5Run r = run_of(e);                                                                               \
        return wf_h5r_end(ctx, &r, completed, reason, err);                                                  \
    }

#endif
