/* Sweeps and ensembles: many runs of one base scenario, each the scenario with `--set` overrides, into one result
 * table (docs/sweeps.md). A sweep file lists axes (scenario keys with a list or a range of values, and a number of
 * seeds) whose Cartesian product is the list of runs, or the runs one by one. Any run can be reproduced alone with
 * the `wavefuel run SCENARIO --set ...` command that wf_sweep_command() prints. */
#ifndef WAVEFUEL_SWEEP_H
#define WAVEFUEL_SWEEP_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/err.h"
#include "wavefuel/stats.h"

#define WF_SWEEP_MAX_AXES 32
#define WF_SWEEP_MAX_RUNS 100000L /* the table is held in memory: about 4 kB per run */

typedef struct WfSweepAxis {
    char   name[64];   /* column name in the result table (/params/NAME) */
    char   keys[512];  /* the scenario keys this axis sets, comma-separated (one, or several with `with`/`points`) */
    char   units[16];  /* unit of the values, from the first key's suffix (_mps -> "m/s"); "1" for plain numbers,
                          "" for text values */
    int    numeric;    /* 1: every value is a finite number (a float64 column), 0: text (a string column) */
    size_t n_values;
} WfSweepAxis;

typedef struct WfSweepRun {
    const char **set;   /* n_set assignments "key=value", applied in this order: the sweep's common `set`, each
                           axis in file order, `seed=N` last; borrowed from the sweep */
    size_t       n_set;
    const char **value; /* one per axis: the value's text, NULL when an explicit run leaves that axis unset */
    int64_t      seed;  /* the `seeds` value of this run, -1 when the sweep does not set seeds */
} WfSweepRun;

typedef struct WfSweep {
    char        path[1024];          /* the sweep file as given */
    char       *text;                /* owned: the sweep file verbatim */
    char        name[128];           /* `name:` or the file stem */
    char        scenario_path[1024]; /* base scenario, resolved against the sweep file's directory */
    char       *scenario_text;       /* owned: the base scenario verbatim, read once: every run uses this text */
    char        output[1024];        /* default result table: `output:` or output/NAME.h5 */
    WfSweepAxis axes[WF_SWEEP_MAX_AXES];
    size_t      n_axes;
    WfSweepRun *runs;                /* owned, n_runs, in table order (first axis outermost, seeds innermost) */
    size_t      n_runs;
    struct WfSweepPool *pool;        /* owned: storage of every string above */
} WfSweep;

/* Read and expand a sweep file; the base scenario's text is read too (not validated: a run whose overrides do not
 * fit it fails alone, recorded in the table). Errors name file:line and key; WF_EINPUT for bad input.
 * Ownership: *out is the caller's, holding copies of everything (no pointer into the arguments), until
 * wf_sweep_destroy(); NULL on failure. */
int  wf_sweep_load(const char *path, WfSweep **out, WfError *err);
/* Same from texts already in memory (MPI ranks get them from rank 0); `path` resolves the scenario path and names
 * errors; scenario_text NULL: read the scenario file. */
int  wf_sweep_load_text(const char *path, const char *text, const char *scenario_text, WfSweep **out,
                        WfError *err);
/* Frees the sweep and sets *sw to NULL; accepts NULL and *sw == NULL. */
void wf_sweep_destroy(WfSweep **sw);

/* The run's overrides, one per line (the format of a result file's /meta/overrides); *out is malloc'ed. Identifies
 * the run when a sweep is resumed. */
int  wf_sweep_overrides(const WfSweep *sw, size_t run, char **out, WfError *err);
/* `PROGRAM run SCENARIO --set k=v ...` for the run, each argument quoted for a POSIX shell where needed. program:
 * how to run wavefuel ("./bin/wavefuel" for the lines printed to the user); NULL gives "wavefuel", the installed
 * name, which the result table's /runs/command holds (it must not depend on how the sweep was invoked). Returns 0,
 * or WF_EINPUT if it does not fit in len bytes. */
int  wf_sweep_command(const WfSweep *sw, size_t run, const char *program, char *buf, size_t len);

/* Before the first run: every key that a run sets must be a key of the base scenario's schema. For each distinct
 * list of keys, the base scenario is loaded with the overrides of the runs that set them, in order, until one load
 * succeeds (keys checked) or fails on an unknown key (WF_EINPUT naming the sweep file, the run and the key); a run
 * whose values are bad is left to fail alone when it runs. *first (first may be NULL): the first scenario that
 * loaded, for its list of inputs; the caller's to destroy; NULL when none loaded or on error. */
struct WfScenario;
int  wf_sweep_check_keys(const WfSweep *sw, struct WfScenario **first, WfError *err);

/* ---- One run ---- */
typedef enum { WF_RUN_PENDING = 0, WF_RUN_OK = 1, WF_RUN_FAILED = 2 } WfRunStatus;
extern const char *const wf_run_status_names[3]; /* "pending", "ok", "failed" */

typedef struct WfSweepResult {
    int       status;          /* WfRunStatus; an interrupted run stays pending */
    int       error_code;      /* WF_E* of a failed run */
    char      error[1024];     /* why it failed (or was interrupted), "" when ok */
    int64_t   seed;            /* the scenario's seed after overrides; the override, or -1, if it did not load */
    WfSummary summary;         /* every aggregate (docs/metrics.md); valid when ok */
    size_t    n_classes;
    char      classes[1024];   /* the classes' names, comma-separated, in the order of summary.cls[] */
    char      file[1024];      /* this run's own result file, "" without per-run files */
    /* timing: not part of the reproducible table (differs between executions) */
    double    wall_s;          /* load, simulation and per-run file, s */
    int       worker;          /* thread number, or MPI rank, that ran it */
    int       threads;         /* OpenMP threads inside the run */
} WfSweepResult;

typedef struct WfSweepRunOpts {
    int         threads;     /* OpenMP threads inside the run, recorded in the result: the engine sizes its team from
                                the calling thread's OpenMP setting, which the caller sets (wf_sweep_execute) */
    const char *per_run_dir; /* NULL: no per-run file; else DIR/run_HASH.h5 (HASH of the overrides), replaced if
                                the table did not record it as complete */
    int         worker;      /* recorded in the result */
} WfSweepRunOpts;

/* Load the run's scenario (the base text + overrides), simulate it on the calling thread's OpenMP team size
 * (omp_get_max_threads(); this function changes no OpenMP setting), fill *res. Never stops the caller: a failure
 * is recorded in res (status failed, error); *stop (may be NULL) set by a signal interrupts the run, which then
 * stays pending. Thread-safe: runs may execute concurrently (HDF5 is used only for per-run files, and the library
 * is built thread-safe; see docs/sweeps.md). */
void wf_sweep_run(const WfSweep *sw, size_t run, const WfSweepRunOpts *o, volatile sig_atomic_t *stop,
                  WfSweepResult *res);

typedef struct WfSweepTiming WfSweepTiming; /* below, with the table */

/* ---- The scheduler: every pending run of a sweep, on threads of this process and on remote workers ---- */
typedef int  (*WfSweepTakeFn)(void *sched, size_t *run); /* 1 and *run: a run to do; 0: none left */
typedef void (*WfSweepFinishFn)(void *sched, size_t run, const WfSweepResult *res);

/* Workers outside this process (the MPI ranks of bin/wavefuel-mpi, src/mpi/), driven from the coordinating
 * thread: poll() records the results that arrived (finish) and hands a run to every free worker (take), without
 * blocking, and returns how many workers still hold a run. */
typedef struct WfSweepRemote {
    int  (*poll)(void *ctx, WfSweepTakeFn take, WfSweepFinishFn finish, void *sched);
    void  *ctx;     /* borrowed */
    int    workers; /* recorded in /timing as the number of workers (MPI: the ranks) */
} WfSweepRemote;

typedef struct WfSweepCounts {
    size_t n_todo;        /* pending runs when wf_sweep_execute was called */
    size_t n_reported;    /* of them, finished or interrupted so far */
    size_t n_ok, n_failed, n_interrupted;
} WfSweepCounts;

typedef struct WfSweepExecOpts {
    int            workers;      /* runs side by side on threads of this process, >= 1 */
    WfSweepRunOpts run;          /* for every run (.worker is set by the scheduler); .threads is recorded only:
                                    see wf_sweep_execute for the threads a run actually gets */
    const char    *table_path;   /* the result table (wf_sweep_table_write), saved while runs finish and at the end */
    double         save_every_s; /* wall time between snapshots: what a killed sweep can lose */
    volatile sig_atomic_t *stop; /* may be NULL; once set (by a signal), no run starts and runs in progress stop
                                    (they stay pending) */
    const WfSweepRemote *remote; /* NULL: none. With remote workers the coordinating thread never runs a run */
    const char    *mode;         /* recorded in /timing: "threads" or "mpi" */
    /* The caller's callbacks, all may be NULL. From the coordinating thread: each finished (or interrupted) run,
     * in order of completion; then, after each batch (about every ms), the counts and wall time so far, s. From
     * each worker thread before its first run: per-thread settings of the program (HDF5's error printing). */
    void (*on_finished)(void *ctx, size_t run, const WfSweepResult *res, const WfSweepCounts *c);
    void (*on_progress)(void *ctx, const WfSweepCounts *c, double wall_s);
    void (*on_thread_start)(void *ctx);
    void  *ctx;
} WfSweepExecOpts;

/* Execute every run whose row of res[] (sw->n_runs entries, filled as runs finish) is pending, in table order,
 * pulled one at a time by o->workers worker threads and the remote workers, while one more thread coordinates.
 * The table is saved every o->save_every_s and at the end (not at all when no run is pending). Each run's engine
 * takes its team size from the OpenMP setting its worker thread inherits from the caller's thread
 * (omp_get_max_threads() at the call): the caller sets it, and enables nested parallelism when it is above 1;
 * the library changes neither. Fills *counts and *timing (may be NULL; timing.workers is the number of worker
 * threads the OpenMP runtime gave, or remote->workers). Returns 0, or the error of a snapshot that
 * could not be written (no run is handed out after it; the table keeps its last good snapshot). */
int wf_sweep_execute(const WfSweep *sw, WfSweepResult *res, const WfSweepExecOpts *o, WfSweepCounts *counts,
                     WfSweepTiming *timing, WfError *err);

/* The metrics of the table are the ring summary's fields: wf_summary_fields and wf_summary_class_fields with a
 * ring description (wavefuel/summary.h), under the names and units of a run file's /summary. */

/* ---- The result table file (src/io/h5sweep.c; layout in docs/sweeps.md) ---- */
typedef struct WfSweepTiming {
    const char *mode;          /* "threads" or "mpi" */
    int         workers;       /* runs executing at once */
    int         threads_per_run;
    double      wall_s;        /* wall time of this invocation so far */
} WfSweepTiming;

/* Write the whole table to `path` atomically: PATH.partial is written, then renamed over PATH, so PATH always holds
 * a complete snapshot (/meta/runs_pending says how many rows remain). timing may be NULL. */
int wf_sweep_table_write(const char *path, const WfSweep *sw, const WfSweepResult *res, const WfSweepTiming *timing,
                         WfError *err);

/* A table read back (resume, tests). */
typedef struct WfSweepSaved {
    size_t         n;
    char         **overrides;     /* owned, n */
    WfSweepResult *res;           /* owned, n */
    char          *scenario_text; /* owned */
    char          *scenario_path; /* owned */
} WfSweepSaved;
/* WF_EINPUT if `path` is not a wavefuel sweep table. *out owns what it holds (the caller frees it with
 * wf_sweep_saved_free(), which zeroes it); on failure it is left empty. */
int  wf_sweep_table_read(const char *path, WfSweepSaved *out, WfError *err);
void wf_sweep_saved_free(WfSweepSaved *s);

/* Resume: copy the finished rows of `saved` (ok, and failed unless retry_failed) into res[] (n_runs entries,
 * matched by their overrides) and count them in *n_reused. WF_EINPUT if the saved table was written from another
 * base scenario text, or holds a run the sweep no longer lists (the rerun would drop it). */
int wf_sweep_resume(const WfSweep *sw, const WfSweepSaved *saved, int retry_failed, WfSweepResult *res,
                    size_t *n_reused, WfError *err);

#endif
