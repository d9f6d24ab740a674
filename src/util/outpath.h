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

#endif
