/* Numeric CSV tables (cycles, grade profiles, energy queries, tabulated models): comma-separated numbers,
 * an optional header line, blank lines and '#' comments skipped. Quoted fields are rejected: wavefuel's
 * tables are numbers only. Every error names the file, the line and the field. */
#ifndef WAVEFUEL_CSV_H
#define WAVEFUEL_CSV_H

#include <stddef.h>
#include "wavefuel/domain.h"
#include "wavefuel/err.h"

typedef struct WfCsv {
    size_t  n_rows, n_cols;
    double *data;     /* owned; row-major: data[r * n_cols + c] */
    int    *line;     /* owned; 1-based source line of each row, for later messages */
    int     had_header;
} WfCsv;

/* Read `path` ("-" is standard input). n_cols columns are required on every row. If `names` is not NULL
 * (n_cols entries), a header line, when present, must spell exactly these names; a header is a first
 * non-comment line whose first field is not a number. Ownership: out's arrays are the caller's until
 * wf_csv_free() (the struct itself is the caller's); on failure nothing is left to free. */
int wf_csv_read(const char *path, size_t n_cols, const char *const *names, WfCsv *out, WfError *err);
void wf_csv_free(WfCsv *csv);

/* Each column c with ranges[c] not NULL: every value within it (domain.h), else WF_EINPUT naming file, line,
 * field number and name (names[c], may be NULL) and the value. `path` as given to wf_csv_read. */
int wf_csv_check_ranges(const WfCsv *csv, const char *path, const char *const *names, const WfRange *const *ranges,
                        WfError *err);

#endif
