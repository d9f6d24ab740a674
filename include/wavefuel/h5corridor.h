/* The HDF5 result file of a corridor run (layout in docs/corridors.md): /meta, /classes, /drivers, /road,
 * /timeseries, /trips, /detectors, /edie, /summary and optional /trajectories. Written as PATH.partial while the
 * run goes and renamed to PATH when it completes (src/io/h5util.h); every dataset carries `units` and
 * `description`. Checkpoints (FILE.h5.ckpt) as for rings (docs/output.md). */
#ifndef WAVEFUEL_H5CORRIDOR_H
#define WAVEFUEL_H5CORRIDOR_H

#include "wavefuel/corridor.h"
#include "wavefuel/err.h"

/* The one result writer (src/io/h5result.c) bound to the corridor. */
typedef struct WfH5Result WfH5Corridor;

/* Create the writer for `path` (refuses to replace an existing result unless force): PATH.partial is created now.
 * *ops is filled with callbacks bound to the writer, valid until it is destroyed. The caller owns *out and frees it
 * with wf_h5corridor_destroy, after the run (the engine borrows *ops during wf_corridor_run). */
int  wf_h5corridor_create(const char *path, int force, WfH5Corridor **out, WfCorridorOutput *ops, WfError *err);
/* Load the checkpoint FILE.h5.ckpt (wavefuel/checkpoint.h) of `result` into `c`, built from the scenario it holds,
 * and reopen FILE.h5.partial to continue writing it from the checkpoint's rows: its row counters are set back,
 * /trips and /trajectories cut to the whole chunks the checkpoint counts; later time-series rows and what the
 * interrupted run wrote at its end are written again in place. WF_EINPUT (nothing changed) when the checkpoint is
 * damaged, of a ring run or of another scenario, or the partial file is not this run's or of another layout;
 * WF_ESYS when setting it back fails (a write error). Ownership and lifetime as for wf_h5corridor_create. */
int  wf_h5corridor_resume(const char *result, WfCorridor *c, WfH5Corridor **out, WfCorridorOutput *ops,
                          WfError *err);
/* Free the writer and clear *w (NULL accepted); a file whose run never reached end() is removed (nothing was
 * produced), unless it was resumed. */
void wf_h5corridor_destroy(WfH5Corridor **w);
/* Final path written ("x.h5" when completed, "x.h5.partial" otherwise; empty before end()); owned by w. */
const char *wf_h5corridor_path(const WfH5Corridor *w);

#endif
