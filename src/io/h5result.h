/* The one HDF5 result writer of runs (docs/output.md), for rings and corridors alike: the file created as
 * PATH.partial, /meta with provenance, status and row counters, /classes and /drivers, /summary, the time series
 * buffered and written in blocks, the appended groups (trajectories; trips) grown a chunk at a time, the size
 * estimate, checkpoints and resumption, and the end of the run; its public face is wavefuel/h5out.h. What differs
 * between boundaries is a WfH5Boundary: its observers' series and column tables (src/observe/columns.h), its
 * end-of-run groups and a few extra datasets (src/io/h5ring.c, src/io/h5corridor.c); the writer picks the one of
 * the run's kind (wf_sim_kind). A write error at any point leaves a file whose structure is intact (docs/output.md,
 * "Write errors"). Internal to wavefuel (not installed). */
#ifndef WAVEFUEL_IO_H5RESULT_H
#define WAVEFUEL_IO_H5RESULT_H

#include "io/h5ckpt.h"
#include "io/h5util.h"
#include "observe/columns.h"
#include "wavefuel/engine.h"
#include "wavefuel/summary.h"

/* Write the columns cols[0..n) of one group g with their values data[0..n): a column known at the start is written
 * in the allocating pass only, the others are allocated (ALLOCATE) and written in place (FILL), as wf_h5_put_f64. */
int wf_h5_put_columns(hid_t g, const WfObsColumn *cols, const WfObsData *data, size_t n, WfH5Pass pass,
                      WfError *err);

/* /lanes of a road of several lanes (src/io/h5lanes.c): nothing on one lane. */
int wf_h5_write_lanes(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err);

/* What the writer reads of the run at a callback (everything borrowed). */
typedef struct WfH5Run {
    const WfSim      *sim;
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

typedef struct WfH5Result WfH5Result;
struct WfTrip;

typedef struct WfH5Boundary {
    const char        *kind;          /* the runs it writes: wf_sim_kind */
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
    /* Rows of trips (open roads; NULL otherwise), through wf_h5r_append. */
    int    (*trips)(WfH5Result *w, const struct WfTrip *trips, size_t n, WfError *err);
} WfH5Boundary;

extern const WfH5Boundary wf_h5_ring, wf_h5_corridor;

/* n_rows rows of the appended cursor `cur` (data[k]: the rows of its k-th series), counted in /meta after. */
int wf_h5r_append(WfH5Result *w, size_t cur, size_t n_rows, const double *const *data, WfError *err);

#endif
