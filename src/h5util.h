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

/* Extendible float64 datasets of shape [rows x cols] (cols = 0 for 1-D), appended a block of rows at a time.
 * Chunked (chunk_rows rows) and deflate-compressed when compress is set. */
typedef struct WfH5Series {
    hid_t   dset;
    hsize_t rows, cols;
    char    name[128];
} WfH5Series;
int  wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t chunk_rows, int compress,
                         const char *units, const char *desc, WfH5Series *s, WfError *err);
/* Reopen an extendible dataset of an existing file, keeping its first keep_rows rows. */
int  wf_h5_series_open(hid_t loc, const char *name, hsize_t keep_rows, WfH5Series *s, WfError *err);
int  wf_h5_series_append(WfH5Series *s, hsize_t n_rows, const double *rows, WfError *err);
void wf_h5_series_close(WfH5Series *s);

#endif
