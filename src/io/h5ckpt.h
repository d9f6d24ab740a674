/* Checkpoints FILE.h5.ckpt of the result writer (src/io/h5result.c: rings and corridors), and the
 * resumption of the partial result FILE.h5.partial they belong to. A checkpoint has the attributes `kind` (ring
 * or corridor), `scenario_path`, `steps_done`, `rows_NAME` (the cursor of each group of series: rows written,
 * those still in memory included, when it was taken) and `checksum` (FNV-1a over everything restored), and the
 * datasets `scenario_text`, `overrides` and `state/NAME`: each engine state block, and the rows of appended
 * datasets still in memory (`pending:PATH`, h5util.h), as raw bytes. It is written to FILE.h5.ckpt.tmp and
 * renamed, so a kill at any moment leaves either the previous checkpoint or the new one. Internal to wavefuel. */
#ifndef WAVEFUEL_H5CKPT_H
#define WAVEFUEL_H5CKPT_H

#include <stdint.h>

#include "io/h5util.h"
#include "wavefuel/checkpoint.h"
#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"

/* One series of a result (src/io/h5util.h): its group and name, how it was created (fixed_rows rows of a fixed
 * series, or chunk_rows per chunk of an appended one) and which cursor (index into the writer's cursor names)
 * counts its rows. The series of one cursor always hold the same number of rows; the appended ones among them
 * are appended together (wf_h5_series_append). */
typedef struct WfCkptSeries {
    WfH5Series     *s;
    const char     *group;
    const WfColumn *col;   /* name, units, description */
    hsize_t         cols, fixed_rows, chunk_rows;
    int             compress;
    size_t          cursor;
} WfCkptSeries;

/* Create the series sp[0..n) in the file fid (their groups must exist). WF_ESYS naming the dataset. */
int wf_ckpt_series_create(hid_t fid, const WfCkptSeries *sp, size_t n, WfError *err);

/* How the engine's blocks reach the saver (wf_sim_state_pieces): put(put_ctx, j, lo, hi, err) for bytes [lo, hi) of
 * block j, current in its memory, the blocks in order and each one's pieces in order. */
typedef int (*WfCkptWalk)(void *walk_ctx, const WfStateVar *vars, size_t n_vars, WfStatePieceFn put, void *put_ctx,
                          WfError *err);

/* Replace the checkpoint of `result` with one of this run: its scenario, kind, step, the engine's state blocks
 * vars[0..n_vars) (read only; the array has room for WF_MAX_STATE_VARS, the series' pending rows are added to it),
 * handed over by walk (NULL: each block whole, from its memory; a ring split across processes has rank 0 gather the
 * other ranks' shares of a block one at a time), and the series, whose file rows must already be flushed. The cursors
 * are named cursor[0..n_cur). WF_ESYS naming the file on failure; the previous checkpoint then stays. */
int wf_ckpt_save(const char *result, const char *kind, const WfScenario *sc, int64_t steps_done,
                 const char *const *cursor, size_t n_cur, const WfCkptSeries *sp, size_t ns, WfStateVar *vars,
                 size_t n_vars, WfCkptWalk walk, void *walk_ctx, WfError *err);

/* Resume, step 1: read the checkpoint of `result` into the engine blocks vars[0..n_vars) (room for
 * WF_MAX_STATE_VARS) of an engine built from the scenario `sc` the checkpoint holds, and set up the series with
 * the rows that were still in memory; nothing is written. The file must be a checkpoint of this kind, with
 * exactly these blocks of exactly these sizes and a matching checksum: otherwise WF_EINPUT naming the file and
 * what is wrong (damaged, of another kind, scenario or version), and the blocks' contents are undefined. */
int wf_ckpt_restore(const char *result, const char *kind, const WfScenario *sc, const char *const *cursor,
                    size_t n_cur, const WfCkptSeries *sp, size_t ns, WfStateVar *vars, size_t n_vars, WfError *err);

/* Resume, step 2 (after the engine accepted the restored state): reopen FILE.h5.partial of `result` for writing
 * after checking that it is the result of the run `sc` (its /meta/scenario_text and /meta/overrides), and reopen
 * the series, checking their layout and that they hold the checkpoint's rows. Nothing in the file is changed:
 * the writer then sets its row counters back to the checkpoint's and cuts the appended series to their rows in
 * the file (wf_h5_series_trim); what the interrupted run wrote at its end (allocated in place) is overwritten at
 * the end of the resumed one. WF_EINPUT when the file is missing, unreadable, of another run or shorter. */
int wf_ckpt_reopen(const char *result, const WfScenario *sc, const WfCkptSeries *sp, size_t ns, WfH5File **out,
                   WfError *err);

/* Remove the checkpoint of `result` (the run completed). */
void wf_ckpt_remove(const char *result);

#endif
