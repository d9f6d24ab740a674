/* Thin, checked helpers over the HDF5 C API used by every writer (simulation results, drive cycles,
 * tables): files written as NAME.partial and renamed on success, datasets that always carry a `units` and a
 * `description` attribute, and extendible datasets for time series. Every HDF5 call is checked; a failure
 * returns WF_ESYS with the HDF5 object name in the message. Internal to wavefuel (not installed). */
#ifndef WAVEFUEL_H5UTIL_H
#define WAVEFUEL_H5UTIL_H

#include <hdf5.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/err.h"

typedef struct WfH5File {
    hid_t fid;
    char  path[1024];     /* final name */
    char  partial[1040];  /* path + ".partial", where writing happens */
} WfH5File;

/* Call before any other HDF5 call (every entry point does): disables HDF5's own error printing and its exit
 * handler. Idempotent. */
void wf_h5_library_init(void);

/* Create PATH.partial for writing. Fails (WF_EINPUT) if PATH exists and force is 0, or if PATH.partial
 * exists (another run may be writing it) and force is 0. Silences HDF5's own error printing. */
int wf_h5_create(const char *path, int force, WfH5File **out, WfError *err);
/* Reopen PATH.partial of an interrupted run for writing. WF_EINPUT when it is missing or not readable HDF5. */
int wf_h5_reopen(const char *path, WfH5File **out, WfError *err);
/* Flush, close and rename PATH.partial to PATH. Frees *f. */
int wf_h5_commit(WfH5File **f, WfError *err);
/* Close without renaming: the .partial file stays for inspection (interrupted or failed run). If
 * remove_file is set the partial file is deleted instead (nothing useful was written). Frees *f. */
void wf_h5_abandon(WfH5File **f, int remove_file);

/* Create a group (and missing parents). Returns a handle to close with H5Gclose, or H5I_INVALID_HID. */
hid_t wf_h5_group(hid_t loc, const char *name, WfError *err);

/* Write a complete dataset (rank 1 or 2), contiguous or compressed when large. units is mandatory ("1"
 * for dimensionless), desc a one-line description. */
int wf_h5_write_f64(hid_t loc, const char *name, int rank, const hsize_t *dims, const double *data,
                    const char *units, const char *desc, WfError *err);
int wf_h5_write_i64(hid_t loc, const char *name, int rank, const hsize_t *dims, const int64_t *data,
                    const char *units, const char *desc, WfError *err);
int wf_h5_write_u8(hid_t loc, const char *name, int rank, const hsize_t *dims, const uint8_t *data,
                   const char *units, const char *desc, WfError *err);
/* A 1-D dataset of variable-length strings. */
int wf_h5_write_strings(hid_t loc, const char *name, size_t n, const char *const *s, const char *desc,
                        WfError *err);
/* Scalar datasets. */
int wf_h5_scalar_f64(hid_t loc, const char *name, double v, const char *units, const char *desc, WfError *err);
int wf_h5_scalar_i64(hid_t loc, const char *name, int64_t v, const char *units, const char *desc, WfError *err);
int wf_h5_scalar_str(hid_t loc, const char *name, const char *s, const char *desc, WfError *err);
/* Attributes on any object. */
int wf_h5_attr_str(hid_t obj, const char *name, const char *value, WfError *err);
int wf_h5_attr_f64(hid_t obj, const char *name, double value, WfError *err);
int wf_h5_attr_i64(hid_t obj, const char *name, int64_t value, WfError *err);

/* Readers of what the functions above write. `file` names the file in messages. A missing object or one of
 * another type is WF_EINPUT ("FILE: no attribute 'NAME'"), a failed read WF_ESYS. */
/* A fixed-length string attribute into out (len bytes, NUL-terminated; a longer value is an error). */
int wf_h5_read_attr_str(hid_t obj, const char *file, const char *name, char *out, size_t len, WfError *err);
/* An integer attribute. */
int wf_h5_read_attr_i64(hid_t obj, const char *file, const char *name, int64_t *out, WfError *err);
/* A scalar variable-length string dataset; *out is malloc'd (the caller frees it). */
int wf_h5_read_scalar_str(hid_t loc, const char *file, const char *name, char **out, WfError *err);

/* Extendible float64 datasets of shape [rows x cols] (cols = 0 for 1-D), appended a block of rows at a time,
 * chunked (chunk_rows rows, fewer for wide rows: wf_h5_series_chunk_rows). A compressed series (deflate with
 * shuffle) writes whole chunks only: appended rows wait in memory (`pend`, n_pend < chunk_rows rows) until a
 * chunk is complete, and wf_h5_series_flush writes the last, incomplete one when the file is finished. A chunk is
 * therefore compressed and written once: rewriting a compressed chunk moves it in the file, HDF5 may reuse its
 * old place at once, and a process killed before the next flush would leave a file whose index still points
 * there (rows the last checkpoint counted, unreadable). Uncompressed chunks keep their place when rewritten. */
typedef struct WfH5Series {
    hid_t   dset;
    hsize_t rows, cols;      /* rows in the file, columns (0: 1-D) */
    hsize_t chunk_rows;
    int     compress;
    double *pend;            /* compressed series with chunks of several rows: rows not yet written (owned) */
    hsize_t n_pend;
    char    name[128];       /* path in the file ("trips/serial"), for messages */
    char    block[140];      /* "pending:trips.serial": the checkpoint state block of the pending rows */
} WfH5Series;
hsize_t wf_h5_series_chunk_rows(hsize_t cols, hsize_t chunk_rows);
int  wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t chunk_rows, int compress,
                         const char *units, const char *desc, WfH5Series *s, WfError *err);
int  wf_h5_series_append(WfH5Series *s, hsize_t n_rows, const double *rows, WfError *err);
/* Write the pending rows: once, when the file is finished (later appends would rewrite that chunk). */
int  wf_h5_series_flush(WfH5Series *s, WfError *err);
/* Close the dataset and free the pending rows (unwritten rows are lost: flush first). */
void wf_h5_series_close(WfH5Series *s);
/* Resuming a series that held total_rows rows at a checkpoint, in two steps so that the checkpoint is verified
 * before the file is changed. wf_h5_series_resume sets s up for the series `path` (from the file root) created
 * with these arguments: s->rows rows of it are in the file and s->n_pend follow in s->pend, which the caller
 * fills from the checkpoint. wf_h5_series_reopen then opens the dataset in the file fid, checks its shape,
 * chunking and compression, and truncates it to s->rows (the rows written after the checkpoint are dropped).
 * WF_EINPUT when the dataset is missing, different or shorter. */
int  wf_h5_series_resume(WfH5Series *s, const char *path, hsize_t cols, hsize_t chunk_rows, int compress,
                         hsize_t total_rows, WfError *err);
int  wf_h5_series_reopen(hid_t fid, WfH5Series *s, WfError *err);

#endif
