/* The one check of an output path before anything is computed or written: not a directory, and not one of the
 * command's inputs (neither the file itself nor the FILE.partial and FILE.ckpt written beside it). Internal to
 * wavefuel. */
#ifndef WAVEFUEL_OUTPATH_H
#define WAVEFUEL_OUTPATH_H

#include <stddef.h>
#include "wavefuel/err.h"

/* 0 when `out` may be written. WF_EINPUT, with a message naming `what` (the option or key that gave the path,
 * "-o"), the path and the input, when out is an existing directory, or when out, out.partial or out.ckpt exists and
 * is the same file (device and inode, so another spelling or a link is caught) as one of inputs[0..n_inputs) (NULL
 * entries skipped). Touches no file. */
int wf_output_check(const char *what, const char *out, const char *const *inputs, size_t n_inputs, WfError *err);

/* The default result directory, relative to the working directory: results go to output/NAME.h5 unless a path is
 * given. */
#define WF_OUTPUT_DEFAULT_DIR "output"

/* When `out` is a default result path (WF_OUTPUT_DEFAULT_DIR/FILE), create that directory if it is missing, so the
 * default works from any working directory. Other paths are left alone (a missing directory is then the writer's
 * error). WF_EINPUT, naming the directory and the cause, when it cannot be created. */
int wf_output_default_dir(const char *out, WfError *err);

#endif
