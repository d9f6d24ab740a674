/* Parallel loops over the runs of a batch (src/core/batch.c), for the batch functions of engine.h and rl.h.
 * Internal (not installed). */
#ifndef WAVEFUEL_CORE_BATCH_H
#define WAVEFUEL_CORE_BATCH_H

#include <stddef.h>

#include "wavefuel/err.h"

/* fn(ctx, k, &errs[k]) for k = 0 .. n - 1 in parallel on `threads` OpenMP threads (below 1: 1), each call touching
 * run k only. errs: n entries, cleared first; a failing call's status is kept in errs[k].code. Returns the first
 * failure's status in run order, else 0. */
int wf_runs_each(size_t n, int threads, int (*fn)(void *ctx, size_t k, WfError *err), void *ctx, WfError *errs);

#endif
