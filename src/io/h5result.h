/* Writing observers from their column tables (src/observe/columns.h) into a result file. Internal to wavefuel. */
#ifndef WAVEFUEL_IO_H5RESULT_H
#define WAVEFUEL_IO_H5RESULT_H

#include "io/h5util.h"
#include "observe/columns.h"

/* Write the columns cols[0..n) of one group g with their values data[0..n): a column known at the start is written
 * in the allocating pass only, the others are allocated (ALLOCATE) and written in place (FILL), as wf_h5_put_f64. */
int wf_h5_put_columns(hid_t g, const WfObsColumn *cols, const WfObsData *data, size_t n, WfH5Pass pass,
                      WfError *err);

#endif
