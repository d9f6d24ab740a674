/* What kind of file a path names, for the commands that take a file and must say what is wrong with it
 * (`wavefuel info`, `wavefuel run --resume`): missing, a directory, not HDF5, or which of wavefuel's HDF5 files. */
#ifndef WAVEFUEL_FILEKIND_H
#define WAVEFUEL_FILEKIND_H

#include <stdio.h>
#include "wavefuel/err.h"

typedef enum WfFileKind {
    WF_FILE_MISSING,    /* no such file (or it cannot be looked at) */
    WF_FILE_DIRECTORY,
    WF_FILE_NOT_HDF5,   /* a file that is not HDF5, or HDF5 that cannot be opened (damaged) */
    WF_FILE_HDF5_OTHER, /* HDF5 that no wavefuel command wrote */
    WF_FILE_RESULT,     /* `wavefuel run`: /meta/completed and /summary (complete, or a partial result) */
    WF_FILE_SWEEP,      /* `wavefuel sweep` table: /meta/kind = "wavefuel sweep" */
    WF_FILE_CYCLE,      /* `wavefuel cycle -o`: root attributes command and layout */
    WF_FILE_TABLE,      /* tabulated energy model (`wavefuel table import`): root attribute format */
    WF_FILE_CHECKPOINT  /* `wavefuel run` checkpoint (FILE.h5.ckpt): root attribute kind */
} WfFileKind;

/* The kind of `path`; for WF_FILE_RESULT, *completed (may be NULL) is /meta/completed (1 complete, 0 partial; -1
 * when unreadable). Opens the file read-only and changes nothing; never fails (an unreadable file is NOT_HDF5). */
WfFileKind wf_file_kind(const char *path, int *completed);
/* The kind as a phrase: "a missing file", "a directory", "not an HDF5 file (or a damaged one)", "an HDF5 file that
 * wavefuel did not write", "a wavefuel result", "a wavefuel sweep table", "a wavefuel drive-cycle result", "a
 * wavefuel energy table", "a wavefuel checkpoint". Static strings. */
const char *wf_file_kind_text(WfFileKind kind);

/* `wavefuel info` of a sweep table or a drive-cycle result: every group holding single values (text or numbers), by
 * path, with those values and their units (a sweep's /meta and /timing; each cycle run's fuel, distance, economy).
 * WF_EINPUT when the file cannot be opened as HDF5. */
int wf_h5_info_scalars(const char *path, FILE *out, WfError *err);

#endif
