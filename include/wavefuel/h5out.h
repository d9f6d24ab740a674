/* The HDF5 result file of a run, ring or corridor (layout in docs/output.md and docs/corridors.md): written as
 * PATH.partial while the run goes, renamed to PATH when it completes; an interrupted run leaves PATH.partial with
 * /meta/completed = 0 and the reason, and a checkpoint FILE.h5.ckpt. Every dataset carries `units` and
 * `description` attributes. */
#ifndef WAVEFUEL_H5OUT_H
#define WAVEFUEL_H5OUT_H

#include <stdio.h>

#include "wavefuel/engine.h"
#include "wavefuel/err.h"

/* The one result writer (src/io/h5result.c), with the observers of the run's kind of road. */
typedef struct WfH5Result WfH5Out;

/* Create the writer of sim's result for `path` (refuses to replace an existing result unless force): PATH.partial
 * is created now. *ops is filled with callbacks bound to the writer, valid until it is destroyed. The caller owns
 * *out and frees it with wf_h5out_destroy, after the run (the engine borrows *ops during wf_sim_run). */
int  wf_h5out_create(const WfSim *sim, const char *path, int force, WfH5Out **out, WfOutput *ops, WfError *err);
/* Free the writer and clear *w (NULL accepted); if the run never reached end(), the partial file is removed (nothing
 * was produced), unless it was resumed. */
void wf_h5out_destroy(WfH5Out **w);
/* Final path written ("x.h5" when completed, "x.h5.partial" otherwise; empty before end()); owned by w. */
const char *wf_h5out_path(const WfH5Out *w);
/* The /meta row counters of the file, as text for messages ("/meta/timeseries_rows and trajectory_rows"), into buf
 * (len bytes; cut if too short); returns buf. */
const char *wf_h5out_counters(const WfH5Out *w, char *buf, size_t len);

/* Load the checkpoint FILE.h5.ckpt (wavefuel/checkpoint.h) into `sim`, built from the scenario it holds, and
 * reopen FILE.h5.partial to continue writing it from the checkpoint's rows: its row counters are set back, the
 * appended groups (/trajectories, /trips) cut to the whole chunks the checkpoint counts; later time-series rows and
 * the end-of-run results are written again in place. WF_EINPUT (nothing changed) when the checkpoint is damaged,
 * of another kind of road or of another scenario, or the partial file is not this run's or of another layout;
 * WF_ESYS when setting it back fails (a write error). Ownership and lifetime of *out and *ops as for
 * wf_h5out_create. */
int  wf_h5out_resume(const char *result, WfSim *sim, WfH5Out **out, WfOutput *ops, WfError *err);
/* The checkpoint's state alone into `sim` (checked as by wf_h5out_resume), no file opened for writing: the ranks of
 * a ring split across processes other than the one that writes the result (docs/mpi.md). */
int  wf_h5out_restore(const char *result, WfSim *sim, WfError *err);
/* `wavefuel info`: print a result file's /meta status and every /summary value with its units. Works on
 * .partial files too. WF_EINPUT if the file is not a wavefuel result. */
int wf_h5out_info(const char *path, FILE *out, WfError *err);
#endif
