/* Checkpoints of interrupted runs (docs/output.md): FILE.h5.ckpt, next to FILE.h5.partial, holds the scenario text
 * and --set overrides, the kind of run (ring or corridor), the rows written so far to each appended dataset of the
 * result, and the engine's complete state, under a checksum. The result writer (src/io/h5result.c)
 * saves and loads them; `wavefuel run --resume` rebuilds the scenario from what this reader returns. */
#ifndef WAVEFUEL_CHECKPOINT_H
#define WAVEFUEL_CHECKPOINT_H

#include "wavefuel/err.h"

typedef struct WfCheckpointInfo {
    char *scenario_text, *overrides; /* owned: the scenario file verbatim, the overrides one per line */
    char  scenario_path[1024];       /* as given to the interrupted run */
    char  kind[16];                  /* "ring" or "corridor" */
} WfCheckpointInfo;

/* Read what rebuilds the scenario of the interrupted run whose result is `result` (FILE.h5, checkpoint
 * FILE.h5.ckpt). WF_EINPUT when FILE.h5 exists (the run is complete), when there is no checkpoint, or when it is
 * not a readable checkpoint of this version; *ck is then empty. Free with wf_checkpoint_info_free. */
int  wf_checkpoint_read_info(const char *result, WfCheckpointInfo *ck, WfError *err);
void wf_checkpoint_info_free(WfCheckpointInfo *ck);

#endif
