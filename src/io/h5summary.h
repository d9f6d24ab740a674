/* /summary of a result file, written from the summary table (wavefuel/summary.h), and read back in its order by
 * `wavefuel info`. */
#ifndef WAVEFUEL_IO_H5SUMMARY_H
#define WAVEFUEL_IO_H5SUMMARY_H

#include "io/h5util.h"
#include "wavefuel/summary.h"

/* Write (or, with the allocating pass, create) /summary: every field of the tables that boundary b has and the
 * scenario's run includes (wf_summary_field_on), fleet values as scalars, class values as arrays over the
 * scenario's classes, group values as arrays over its driver groups. */
int wf_h5_summary_write(hid_t fid, const WfSummary *s, const WfScenario *sc, WfSummaryBoundary b, WfH5Pass pass,
                        WfError *err);

/* Calls print(name) for every dataset of /summary the table knows, in the table's order (fleet values, then
 * class values, then group values). */
void wf_h5_summary_each(void (*print)(const char *name, void *ctx), void *ctx);

#endif
