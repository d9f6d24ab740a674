/* /summary of a result file, written from the summary table (wavefuel/summary.h), and read back in its order by
 * `wavefuel info`. */
#ifndef WAVEFUEL_IO_H5SUMMARY_H
#define WAVEFUEL_IO_H5SUMMARY_H

#include "io/h5util.h"
#include "wavefuel/summary.h"

/* Write (or, with the allocating pass, create) /summary: every field of the table that boundary b has, fleet
 * values as scalars, class values as arrays over the n_classes classes. */
int wf_h5_summary_write(hid_t fid, const WfSummary *s, size_t n_classes, WfSummaryBoundary b, WfH5Pass pass,
                        WfError *err);

/* Calls print(name) for every dataset of /summary the table knows, in the table's order (fleet values, then
 * class values). */
void wf_h5_summary_each(void (*print)(const char *name, void *ctx), void *ctx);

#endif
