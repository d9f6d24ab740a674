/* Thin, checked helpers over the HDF5 C API used by every writer (simulation results, drive cycles,
 * tables): files written as NAME.partial and renamed on success, datasets that always carry a `units` and a
 * `description` attribute, result datasets allocated in full when the file is created and overwritten in place,
 * and series that grow only after the disk space for them is reserved (docs/output.md, "Write errors"). Every
 * HDF5 call is checked; a failure returns WF_ESYS with the object's path and, when HDF5 saw one, the system
 * error ("No space left on device", "File too large"). Internal to wavefuel (not installed). */
#ifndef WAVEFUEL_H5UTIL_H
#define WAVEFUEL_H5UTIL_H

#include <hdf5.h>
#include <hdf5_hl.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/err.h"

typedef struct WfH5File {
    hid_t fid;
    char  path[1024];     /* final name */
    char  partial[1040];  /* path + ".partial", where writing happens */
} WfH5File;

/* Call before any other HDF5 call (every entry point does): disables HDF5's exit handler. Idempotent. HDF5's own
 * printing of its error stack is left as the program set it: every failure is reported through WfError, and the
 * wavefuel programs turn the printing off (src/cli/process.c); the library never changes it. */
void wf_h5_library_init(void);

/* Create PATH.partial for writing. Fails (WF_EINPUT) if PATH exists and force is 0, or if PATH.partial
 * exists (another run may be writing it) and force is 0; WF_ESYS with the system error if it cannot be created.
 * Raw data is written straight to the file (no sieve buffer), in the order of the calls. */
int wf_h5_create(const char *path, int force, WfH5File **out, WfError *err);
/* Reopen PATH.partial of an interrupted run for writing in place, with the same settings. WF_EINPUT when it is
 * missing or not readable HDF5. */
int wf_h5_reopen(const char *path, WfH5File **out, WfError *err);
/* Write everything HDF5 holds in memory to the file. */
int wf_h5_flush(WfH5File *f, WfError *err);
/* Flush, close and rename PATH.partial to PATH. Frees *f. */
int wf_h5_commit(WfH5File **f, WfError *err);
/* Close without renaming: the .partial file stays for inspection (interrupted or failed run). If
 * remove_file is set the partial file is deleted instead (nothing useful was written). Frees *f. */
void wf_h5_abandon(WfH5File **f, int remove_file);

/* For result files with /meta/completed and /meta/reason (runs): when committing a complete result failed (its last
 * flush, close or rename), reopen PATH.partial and mark it incomplete with the reason, if the device lets us. */
void wf_h5_mark_incomplete(const char *partial, const char *reason);
/* End a run's result file (its objects closed): commit it when `complete`, else close it and keep PATH.partial.
 * A commit that fails leaves PATH.partial marked incomplete (wf_h5_mark_incomplete) and returns the error,
 * prefixed with the file. final_path (len bytes) receives the file's name now. Frees *f. */
int wf_h5_finish(WfH5File **f, int complete, char *final_path, size_t len, WfError *err);

/* Create a group (and missing parents). Returns a handle to close with H5Gclose, or H5I_INVALID_HID. */
hid_t wf_h5_group(hid_t loc, const char *name, WfError *err);

/* Write a complete dataset (rank 1 or 2), contiguous or compressed when large. units is mandatory ("1"
 * for dimensionless), desc a one-line description. For data known when the file is created (it is never
 * rewritten). */
int wf_h5_write_f64(hid_t loc, const char *name, int rank, const hsize_t *dims, const double *data,
                    const char *units, const char *desc, WfError *err);
int wf_h5_write_i64(hid_t loc, const char *name, int rank, const hsize_t *dims, const int64_t *data,
                    const char *units, const char *desc, WfError *err);
int wf_h5_write_u8(hid_t loc, const char *name, int rank, const hsize_t *dims, const uint8_t *data,
                   const char *units, const char *desc, WfError *err);
/* The dataset wf_h5_write_u8 writes (the same layout and labels), created and not yet written: then written in
 * pieces, bytes [first, first + m) at a time (wf_h5_write_u8_at). H5I_INVALID_HID with err set on failure. */
hid_t wf_h5_create_u8(hid_t loc, const char *name, hsize_t n, const char *units, const char *desc, WfError *err);
int wf_h5_write_u8_at(hid_t d, hsize_t first, hsize_t m, const void *data, WfError *err);
/* A 1-D dataset of variable-length strings. */
int wf_h5_write_strings(hid_t loc, const char *name, size_t n, const char *const *s, const char *desc,
                        WfError *err);
/* Scalar datasets. */
int wf_h5_scalar_f64(hid_t loc, const char *name, double v, const char *units, const char *desc, WfError *err);
int wf_h5_scalar_i64(hid_t loc, const char *name, int64_t v, const char *units, const char *desc, WfError *err);
int wf_h5_scalar_str(hid_t loc, const char *name, const char *s, const char *desc, WfError *err);
/* A UTF-8 string type of `size` bytes, NUL-terminated (H5T_VARIABLE: variable-length); H5I_INVALID_HID on failure.
 * Close it with H5Tclose. */
hid_t wf_h5_text_type(size_t size);
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

/* ---- Results written in place ----
 * A writer calls the same function twice: with WF_H5_ALLOCATE when the file is created (the dataset is made at
 * its final size, contiguous, its space allocated and filled: NaN for float64, -1 for int64, "" for text; data
 * is not read), then with WF_H5_FILL when the values are known (the existing dataset is overwritten in place:
 * no metadata changes and the file does not grow, so a failure there cannot damage the file's structure).
 * FILL fails if the dataset does not exist with exactly the given size. */
typedef enum { WF_H5_ALLOCATE, WF_H5_FILL } WfH5Pass;
enum { WF_H5_TEXT_LEN = 1024 }; /* bytes of a fixed-length text dataset, the terminating NUL included */
/* ALLOCATE: create the group (wf_h5_group); FILL: open it. H5I_INVALID_HID on failure. */
hid_t wf_h5_group_pass(hid_t loc, const char *name, WfH5Pass pass, WfError *err);
int wf_h5_put_f64(hid_t loc, const char *name, WfH5Pass pass, int rank, const hsize_t *dims, const double *data,
                  const char *units, const char *desc, WfError *err);
int wf_h5_put_i64(hid_t loc, const char *name, WfH5Pass pass, int rank, const hsize_t *dims, const int64_t *data,
                  const char *units, const char *desc, WfError *err);
/* FILL of rows [first, first + m) of an allocated one-dimensional dataset (int64 when i64, else double): the result's
 * per-vehicle columns a piece at a time (wf_sim_shares). Fails if the dataset has fewer rows. */
int wf_h5_put_rows(hid_t loc, const char *name, int i64, hsize_t first, hsize_t m, const void *data, WfError *err);
int wf_h5_put_scalar_f64(hid_t loc, const char *name, WfH5Pass pass, double v, const char *units, const char *desc,
                         WfError *err);
int wf_h5_put_scalar_i64(hid_t loc, const char *name, WfH5Pass pass, int64_t v, const char *units,
                         const char *desc, WfError *err);
/* Fixed-length UTF-8 text of WF_H5_TEXT_LEN bytes; longer text is cut (at a character boundary). */
int wf_h5_put_text(hid_t loc, const char *name, WfH5Pass pass, const char *s, const char *desc, WfError *err);

/* ---- Series of rows ----
 * Float64 datasets of shape [rows x cols] (cols = 0 for 1-D), of two kinds:
 * - fixed (chunk_rows = 0): contiguous, fixed_rows rows allocated and filled with NaN when created (the size is
 *   known: time series), written a block at a time in place with wf_h5_series_write; rows past `rows` hold NaN
 *   (after a resumption: what the interrupted run wrote there, the same values the resumed run writes again).
 * - appended (chunk_rows > 0): chunked, optionally compressed (shuffle + deflate 1), empty when created, and grown
 *   a whole chunk at a time. The series of one group (the datasets that always hold the same number of rows, such
 *   as the columns of /trips) are appended together with wf_h5_series_append: rows wait in memory (`pend`,
 *   n_pend < chunk_rows rows) until a chunk is complete; then the disk space for the chunk of every series is
 *   reserved (posix_fallocate past the end of the file), the chunks written and the file flushed. So the extent of
 *   an appended dataset is the rows in the file, a chunk is compressed and written once (rewriting a compressed
 *   chunk moves it in the file, HDF5 may reuse its old place at once, and a process killed before the next flush
 *   would leave a file whose index still points there), and a checkpoint saves the pending rows (src/io/h5ckpt.h).
 * Writes go straight to the file (no chunk cache), in call order. */
typedef struct WfH5Series {
    hid_t   dset;
    hsize_t rows;            /* rows in the file (fixed: written so far) */
    hsize_t cap;             /* rows of the dataset's extent (appended: = rows but during an append) */
    hsize_t cols;            /* columns (0: 1-D) */
    hsize_t chunk_rows;      /* appended: rows per chunk; 0: fixed */
    int     compress;
    double *pend;            /* appended: the rows of the incomplete chunk, not yet written (owned) */
    hsize_t n_pend;
    char    name[128];       /* path in the file ("trips/serial"), for messages */
    char    block[140];      /* "pending:trips.serial": the checkpoint state block of the pending rows */
} WfH5Series;
void wf_h5_series_init(WfH5Series *s); /* an unopened series: dset = H5I_INVALID_HID */
/* Rows per chunk of an appended series of `cols` columns: `want`, fewer when a chunk would exceed 4 MiB (>= 1). */
hsize_t wf_h5_series_chunk_rows(hsize_t cols, hsize_t want);
int  wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t fixed_rows, hsize_t chunk_rows,
                         int compress, const char *units, const char *desc, WfH5Series *s, WfError *err);
/* Fixed series: write n rows at row s->rows. WF_ESYS if they do not fit. */
int  wf_h5_series_write(WfH5Series *s, hsize_t n_rows, const double *rows, WfError *err);
/* Buffered time-series records (n_rows rows of n_cols scalars then n_classes per-class values, row-major) into
 * the fixed series col[0..n_cols) (one column each) and the n_classes-wide series cls; scratch holds
 * n_rows * max(n_classes, 1) doubles. */
int  wf_h5_series_write_records(WfH5Series *col, size_t n_cols, WfH5Series *cls, size_t n_classes,
                                const double *records, size_t n_rows, double *scratch, WfError *err);
/* Appended series s[0..n) of one group (same chunk rows, same rows so far): add n_rows rows to each (data[i]:
 * n_rows x cols values, row-major). Every chunk completed is written as described above; when its reservation
 * fails (disk full, file size limit, quota) nothing in the file has changed and the error names `what` and the
 * size; when writing it fails (an I/O error) the extents are put back, so that what HDF5 writes when the file is
 * closed is the state before the chunk. The rows stay pending then (a checkpoint still counts them). */
int  wf_h5_series_append(WfH5File *f, WfH5Series *const *s, size_t n, hsize_t n_rows, const double *const *data,
                         const char *what, WfError *err);
/* Write the pending rows of the group s[0..n) (the last, incomplete chunk), reserved as above: once, when the file
 * is finished (later appends would rewrite that chunk). */
int  wf_h5_series_flush(WfH5File *f, WfH5Series *const *s, size_t n, const char *what, WfError *err);
/* Close the dataset and free the pending rows (unwritten rows are lost: flush first). */
void wf_h5_series_close(WfH5Series *s);
/* Resuming a series that held total_rows rows at a checkpoint, in steps so that the checkpoint and the file are
 * verified before the file is changed. wf_h5_series_resume sets s up for the series `path` (from the file root)
 * created with these arguments: s->rows rows of it are in the file (appended: the whole chunks) and s->n_pend
 * follow in s->pend, which the caller fills from the checkpoint. wf_h5_series_reopen then opens the dataset in the
 * file fid and checks its shape, layout, chunking and compression (WF_EINPUT when the dataset is missing,
 * different or shorter); nothing is changed. Later rows of a fixed series are overwritten as the run goes on; an
 * appended series is cut to s->rows with wf_h5_series_trim (the rows written after the checkpoint are dropped
 * and written again), with the same reservation as an append. */
int  wf_h5_series_resume(WfH5Series *s, const char *path, hsize_t cols, hsize_t fixed_rows, hsize_t chunk_rows,
                         int compress, hsize_t total_rows, WfError *err);
int  wf_h5_series_reopen(hid_t fid, WfH5Series *s, WfError *err);
int  wf_h5_series_trim(WfH5File *f, WfH5Series *const *s, size_t n, WfError *err);

/* A byte count as text: "812 kB", "41.3 MB", "2.10 GB". Returns buf. */
const char *wf_h5_size_text(double bytes, char *buf, size_t len);

/* Before creating a file's datasets: can `bytes` more be written to it? Fails (-1, with the reason in `why`) when
 * the file size limit (RLIMIT_FSIZE, ulimit -f) or the space free on its file system is smaller. */
int wf_h5_check_room(const WfH5File *f, double bytes, char *why, size_t len);

#endif
