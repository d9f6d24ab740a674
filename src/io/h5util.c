/* Checked HDF5 helpers: partial-file protocol, datasets with units, results written in place, series grown a
 * whole chunk at a time after their disk space is reserved, and what resuming an interrupted run needs. */
#include "io/h5util.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

/* The system error behind the HDF5 error now on this thread's stack: HDF5's file drivers put "errno = N" in
 * their messages. 0 when there is none. Must run before any other HDF5 API call, which would clear the stack. */
static herr_t find_errno(unsigned n, const H5E_error2_t *e, void *data)
{
    (void)n;
    const char *p = e->desc ? strstr(e->desc, "errno = ") : NULL;
    if (!p) return 0;
    long v = strtol(p + 8, NULL, 10);
    *(int *)data = v > 0 && v < 4096 ? (int)v : 0;
    return *(int *)data ? 1 : 0; /* positive: stop walking */
}

static int stack_errno(void)
{
    int e = 0;
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, find_errno, &e);
    return e;
}

/* strerror, with the usual cause spelt out for the errors a full disk or a limit gives. */
static void errno_text(int e, char *buf, size_t len)
{
    const char *hint = e == ENOSPC   ? " (disk full)"
                       : e == EFBIG  ? " (the file size limit, ulimit -f, was reached)"
                                     : "";
    snprintf(buf, len, "%s%s", strerror(e), hint);
}

/* The HDF5 path of object `name` under loc ("/timeseries/t"), for messages. */
static void obj_path(hid_t loc, const char *name, char *out, size_t len)
{
    char base[256] = "";
    ssize_t n = loc >= 0 ? H5Iget_name(loc, base, sizeof base) : -1;
    if (n <= 0 || (size_t)n >= sizeof base) base[0] = '\0';
    int slash = base[0] && base[strlen(base) - 1] != '/';
    snprintf(out, len, "%s%s%s", base, slash ? "/" : "", name);
}

/* Record the failure of `what` on `name` under loc. Call it right after the failing HDF5 call. */
static int h5fail_at(WfError *err, const char *what, hid_t loc, const char *name)
{
    int e = stack_errno();
    char path[512], why[200];
    obj_path(loc, name, path, sizeof path);
    if (!e) return wf_err(err, WF_ESYS, "HDF5: %s '%s' failed (disk full, permission or a damaged file?)", what, path);
    errno_text(e, why, sizeof why);
    return wf_err(err, WF_ESYS, "HDF5: %s '%s' failed: %s", what, path, why);
}

static int h5fail(WfError *err, const char *what, const char *name)
{
    return h5fail_at(err, what, H5I_INVALID_HID, name);
}

const char *wf_h5_size_text(double bytes, char *buf, size_t len)
{
    if (bytes < 1e6) snprintf(buf, len, "%.0f kB", ceil(bytes / 1e3));
    else if (bytes < 1e9) snprintf(buf, len, "%.1f MB", bytes / 1e6);
    else snprintf(buf, len, "%.2f GB", bytes / 1e9);
    return buf;
}

void wf_h5_library_init(void)
{
    /* No HDF5 clean-up at exit: after a failed H5Fclose (disk full), HDF5 1.10's exit handler closes the file
     * again and crashes; the operating system releases everything anyway. Only effective before the library
     * initialises; later calls return an error, which is harmless. */
    H5dont_atexit();
}

/* File access: no sieve buffer, so every H5Dwrite reaches the file at once and in call order (a row count
 * written after its rows is never on disk before them). */
static hid_t file_access(void)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    if (fapl >= 0 && H5Pset_sieve_buf_size(fapl, 0) < 0) {
        H5Pclose(fapl);
        return H5I_INVALID_HID;
    }
    return fapl;
}

/* A new WfH5File for PATH and PATH.partial, not yet open (HDF5 initialised for it). */
static int file_new(const char *path, WfH5File **out, WfError *err)
{
    wf_h5_library_init();
    *out = NULL;
    WfH5File *f = calloc(1, sizeof *f);
    if (!f) return wf_err(err, WF_ESYS, "out of memory");
    int w1 = snprintf(f->path, sizeof f->path, "%s", path);
    int w2 = snprintf(f->partial, sizeof f->partial, "%s.partial", path);
    if (w1 < 0 || (size_t)w1 >= sizeof f->path || w2 < 0 || (size_t)w2 >= sizeof f->partial) {
        free(f);
        return wf_err(err, WF_EINPUT, "output path too long: %s", path);
    }
    f->fid = H5I_INVALID_HID;
    *out = f;
    return 0;
}

int wf_h5_create(const char *path, int force, WfH5File **out, WfError *err)
{
    struct stat st;
    WfH5File *f = NULL;
    int rc0 = file_new(path, &f, err);
    if (rc0) return rc0;
    if (!force && stat(path, &st) == 0) {
        free(f);
        return wf_err(err, WF_EINPUT, "%s exists: results are never overwritten silently (use --force, or -o another file)",
                      path);
    }
    if (!force && stat(f->partial, &st) == 0) {
        free(f);
        return wf_err(err, WF_EINPUT, "%s.partial exists (an interrupted or running job?): remove it or use --force",
                      path);
    }
    hid_t fapl = file_access();
    errno = 0;
    f->fid = fapl < 0 ? H5I_INVALID_HID : H5Fcreate(f->partial, H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    if (f->fid < 0) {
        int e = stack_errno();
        if (!e) e = errno;
        char why[200] = "HDF5 error";
        if (e) errno_text(e, why, sizeof why);
        int rc = wf_err(err, WF_ESYS, "%s: cannot create (%s)", f->partial, why);
        if (fapl >= 0) H5Pclose(fapl);
        free(f);
        return rc;
    }
    H5Pclose(fapl);
    *out = f;
    return 0;
}

int wf_h5_reopen(const char *path, WfH5File **out, WfError *err)
{
    WfH5File *f = NULL;
    int rc0 = file_new(path, &f, err);
    if (rc0) return rc0;
    hid_t fapl = file_access();
    f->fid = fapl < 0 ? H5I_INVALID_HID : H5Fopen(f->partial, H5F_ACC_RDWR, fapl);
    if (fapl >= 0) H5Pclose(fapl);
    if (f->fid < 0) {
        int rc = wf_err(err, WF_EINPUT, "%s: cannot reopen the partial result (missing, or not an HDF5 file)",
                        f->partial);
        free(f);
        return rc;
    }
    *out = f;
    return 0;
}

int wf_h5_flush(WfH5File *f, WfError *err)
{
    return H5Fflush(f->fid, H5F_SCOPE_GLOBAL) < 0 ? h5fail(err, "flush", f->partial) : 0;
}

int wf_h5_commit(WfH5File **pf, WfError *err)
{
    WfH5File *f = *pf;
    *pf = NULL;
    if (!f) return 0;
    int rc = 0;
    if (H5Fflush(f->fid, H5F_SCOPE_GLOBAL) < 0) rc = h5fail(err, "flush", f->partial);
    if (H5Fclose(f->fid) < 0 && !rc) rc = h5fail(err, "close", f->partial);
    if (!rc && rename(f->partial, f->path) != 0)
        rc = wf_err(err, WF_ESYS, "rename %s -> %s: %s", f->partial, f->path, strerror(errno));
    free(f);
    return rc;
}

void wf_h5_abandon(WfH5File **pf, int remove_file)
{
    WfH5File *f = *pf;
    *pf = NULL;
    if (!f) return;
    H5Fflush(f->fid, H5F_SCOPE_GLOBAL);
    H5Fclose(f->fid);
    if (remove_file) unlink(f->partial);
    free(f);
}

void wf_h5_mark_incomplete(const char *partial, const char *reason)
{
    hid_t fapl = file_access();
    hid_t f = fapl < 0 ? H5I_INVALID_HID : H5Fopen(partial, H5F_ACC_RDWR, fapl);
    if (fapl >= 0) H5Pclose(fapl);
    if (f < 0) return;
    hid_t g = H5Gopen2(f, "meta", H5P_DEFAULT);
    if (g >= 0) {
        if (!wf_h5_put_text(g, "reason", WF_H5_FILL, reason, NULL, NULL))
            wf_h5_put_scalar_i64(g, "completed", WF_H5_FILL, 0, NULL, NULL, NULL);
        H5Gclose(g);
    }
    H5Fclose(f);
}

int wf_h5_finish(WfH5File **pf, int complete, char *final_path, size_t len, WfError *err)
{
    WfH5File *f = *pf;
    char partial[sizeof f->partial];
    snprintf(partial, sizeof partial, "%s", f->partial);
    snprintf(final_path, len, "%s", complete ? f->path : partial);
    if (!complete) {
        wf_h5_abandon(pf, 0);
        return 0;
    }
    if (!wf_h5_commit(pf, err)) return 0;
    snprintf(final_path, len, "%s", partial);
    wf_h5_mark_incomplete(partial, err->msg);
    return wf_err_prefix(err, "%s: ", partial);
}

hid_t wf_h5_group(hid_t loc, const char *name, WfError *err)
{
    hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    if (lcpl < 0) {
        h5fail(err, "property list for group", name);
        return H5I_INVALID_HID;
    }
    H5Pset_create_intermediate_group(lcpl, 1);
    hid_t g = H5Gcreate2(loc, name, lcpl, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0) h5fail_at(err, "create group", loc, name);
    H5Pclose(lcpl);
    return g;
}

hid_t wf_h5_group_pass(hid_t loc, const char *name, WfH5Pass pass, WfError *err)
{
    if (pass == WF_H5_ALLOCATE) return wf_h5_group(loc, name, err);
    hid_t g = H5Gopen2(loc, name, H5P_DEFAULT);
    if (g < 0) h5fail_at(err, "open group", loc, name);
    return g;
}

hid_t wf_h5_text_type(size_t size)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    if (t >= 0 && (H5Tset_size(t, size) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0)) {
        H5Tclose(t);
        return H5I_INVALID_HID;
    }
    return t;
}

static int attr_scalar(hid_t obj, const char *name, hid_t type, const void *v, WfError *err)
{
    hid_t sp = H5Screate(H5S_SCALAR), a = H5I_INVALID_HID;
    int rc = sp < 0;
    if (!rc && (a = H5Acreate2(obj, name, type, sp, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && H5Awrite(a, type, v) < 0) rc = 1;
    if (rc) rc = h5fail_at(err, "write attribute", obj, name);
    if (a >= 0) H5Aclose(a);
    if (sp >= 0) H5Sclose(sp);
    return rc;
}

int wf_h5_attr_str(hid_t obj, const char *name, const char *value, WfError *err)
{
    hid_t t = wf_h5_text_type(strlen(value) + 1);
    int rc = t < 0 ? h5fail_at(err, "write attribute", obj, name) : attr_scalar(obj, name, t, value, err);
    if (t >= 0) H5Tclose(t);
    return rc;
}

int wf_h5_attr_f64(hid_t obj, const char *name, double value, WfError *err)
{
    return attr_scalar(obj, name, H5T_NATIVE_DOUBLE, &value, err);
}

int wf_h5_attr_i64(hid_t obj, const char *name, int64_t value, WfError *err)
{
    return attr_scalar(obj, name, H5T_NATIVE_INT64, &value, err);
}

int wf_h5_read_attr_str(hid_t obj, const char *file, const char *name, char *out, size_t len, WfError *err)
{
    if (H5Aexists(obj, name) <= 0) return wf_err(err, WF_EINPUT, "%s: no attribute '%s'", file, name);
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT), t = a >= 0 ? H5Aget_type(a) : H5I_INVALID_HID;
    size_t sz = t >= 0 ? H5Tget_size(t) : 0;
    int rc = 0;
    if (t < 0 || H5Tget_class(t) != H5T_STRING || H5Tis_variable_str(t) != 0 || sz >= len)
        rc = wf_err(err, WF_EINPUT, "%s: attribute '%s' is not a string of at most %zu bytes", file, name, len - 1);
    else if (H5Aread(a, t, out) < 0)
        rc = wf_err(err, WF_ESYS, "%s: HDF5: read attribute '%s' failed", file, name);
    else
        out[sz] = '\0';
    if (t >= 0) H5Tclose(t);
    if (a >= 0) H5Aclose(a);
    return rc;
}

int wf_h5_read_attr_i64(hid_t obj, const char *file, const char *name, int64_t *out, WfError *err)
{
    if (H5Aexists(obj, name) <= 0) return wf_err(err, WF_EINPUT, "%s: no attribute '%s'", file, name);
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT), t = a >= 0 ? H5Aget_type(a) : H5I_INVALID_HID;
    int rc = 0;
    if (t < 0 || H5Tget_class(t) != H5T_INTEGER)
        rc = wf_err(err, WF_EINPUT, "%s: attribute '%s' is not an integer", file, name);
    else if (H5Aread(a, H5T_NATIVE_INT64, out) < 0)
        rc = wf_err(err, WF_ESYS, "%s: HDF5: read attribute '%s' failed", file, name);
    if (t >= 0) H5Tclose(t);
    if (a >= 0) H5Aclose(a);
    return rc;
}

int wf_h5_read_scalar_str(hid_t loc, const char *file, const char *name, char **out, WfError *err)
{
    *out = NULL;
    if (H5Lexists(loc, name, H5P_DEFAULT) <= 0) return wf_err(err, WF_EINPUT, "%s: no dataset '%s'", file, name);
    hid_t d = H5Dopen2(loc, name, H5P_DEFAULT), ft = d >= 0 ? H5Dget_type(d) : H5I_INVALID_HID;
    hid_t sp = d >= 0 ? H5Dget_space(d) : H5I_INVALID_HID, t = wf_h5_text_type(H5T_VARIABLE);
    char *s = NULL;
    int rc = 0;
    if (ft < 0 || sp < 0 || H5Tget_class(ft) != H5T_STRING || H5Tis_variable_str(ft) <= 0 ||
        H5Sget_simple_extent_npoints(sp) != 1)
        rc = wf_err(err, WF_EINPUT, "%s: '%s' is not a scalar string", file, name);
    else if (t < 0 || H5Dread(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, &s) < 0 || !s)
        rc = wf_err(err, WF_ESYS, "%s: HDF5: read dataset '%s' failed", file, name);
    else if (!(*out = strdup(s)))
        rc = wf_err(err, WF_ESYS, "out of memory");
    if (s) H5free_memory(s);
    if (t >= 0) H5Tclose(t);
    if (sp >= 0) H5Sclose(sp);
    if (ft >= 0) H5Tclose(ft);
    if (d >= 0) H5Dclose(d);
    return rc;
}

static int label(hid_t d, const char *units, const char *desc, WfError *err)
{
    if (units && wf_h5_attr_str(d, "units", units, err)) return WF_ESYS;
    if (desc && wf_h5_attr_str(d, "description", desc, err)) return WF_ESYS;
    return 0;
}

/* The dataset write_any writes, created and labelled, nothing written; rank 0: a scalar. H5I_INVALID_HID on
 * failure. */
static hid_t create_any(hid_t loc, const char *name, int rank, const hsize_t *dims, hid_t file_type,
                        const char *units, const char *desc, WfError *err)
{
    hsize_t total = 1;
    for (int i = 0; i < rank; i++) total *= dims[i];
    hid_t sp = rank ? H5Screate_simple(rank, dims, NULL) : H5Screate(H5S_SCALAR);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE), d = H5I_INVALID_HID;
    int rc = (sp < 0 || dcpl < 0);
    /* Large arrays are chunked and compressed (shuffle + deflate 1, as the appended series: deflate 4 took a third of
     * a one-step 10^7-vehicle run for the same file size); small ones stay contiguous (cheaper to read). */
    if (!rc && total >= 4096) {
        hsize_t chunk[2] = {dims[0], rank > 1 ? dims[1] : 1};
        hsize_t row_bytes = (rank > 1 ? dims[1] : 1) * 8;
        hsize_t max_rows = (1u << 20) / (row_bytes ? row_bytes : 1);
        if (max_rows < 1) max_rows = 1;
        if (chunk[0] > max_rows) chunk[0] = max_rows;
        if (rank > 1 && chunk[1] * 8 > (1u << 20)) chunk[1] = (1u << 20) / 8, chunk[0] = 1;
        if (H5Pset_chunk(dcpl, rank, chunk) < 0 || H5Pset_shuffle(dcpl) < 0 || H5Pset_deflate(dcpl, 1) < 0) rc = 1;
    }
    if (!rc && (d = H5Dcreate2(loc, name, file_type, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT)) < 0) rc = 1;
    if (rc) h5fail_at(err, "write dataset", loc, name);
    if (!rc && label(d, units, desc, err)) rc = 1;
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    if (rc && d >= 0) H5Dclose(d);
    return rc ? H5I_INVALID_HID : d;
}

static int write_any(hid_t loc, const char *name, int rank, const hsize_t *dims, hid_t mem_type, hid_t file_type,
                     const void *data, const char *units, const char *desc, WfError *err)
{
    hsize_t total = 1;
    for (int i = 0; i < rank; i++) total *= dims[i];
    hid_t d = create_any(loc, name, rank, dims, file_type, units, desc, err);
    if (d < 0) return WF_ESYS;
    int rc = total && H5Dwrite(d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0
                 ? h5fail_at(err, "write dataset", loc, name) : 0;
    H5Dclose(d);
    return rc;
}

hid_t wf_h5_create_u8(hid_t loc, const char *name, hsize_t n, const char *units, const char *desc, WfError *err)
{
    return create_any(loc, name, 1, &n, H5T_STD_U8LE, units, desc, err);
}

int wf_h5_write_u8_at(hid_t d, hsize_t first, hsize_t m, const void *data, WfError *err)
{
    if (!m) return 0;
    hid_t fsp = H5Dget_space(d), msp = H5Screate_simple(1, &m, NULL);
    int rc = fsp < 0 || msp < 0 || H5Sselect_hyperslab(fsp, H5S_SELECT_SET, &first, NULL, &m, NULL) < 0 ||
             H5Dwrite(d, H5T_NATIVE_UINT8, msp, fsp, H5P_DEFAULT, data) < 0;
    if (msp >= 0) H5Sclose(msp);
    if (fsp >= 0) H5Sclose(fsp);
    return rc ? h5fail_at(err, "write dataset", d, ".") : 0;
}

int wf_h5_write_f64(hid_t loc, const char *name, int rank, const hsize_t *dims, const double *data,
                    const char *units, const char *desc, WfError *err)
{
    return write_any(loc, name, rank, dims, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, data, units, desc, err);
}

int wf_h5_write_i64(hid_t loc, const char *name, int rank, const hsize_t *dims, const int64_t *data,
                    const char *units, const char *desc, WfError *err)
{
    return write_any(loc, name, rank, dims, H5T_NATIVE_INT64, H5T_STD_I64LE, data, units, desc, err);
}

int wf_h5_write_u8(hid_t loc, const char *name, int rank, const hsize_t *dims, const uint8_t *data,
                   const char *units, const char *desc, WfError *err)
{
    return write_any(loc, name, rank, dims, H5T_NATIVE_UINT8, H5T_STD_U8LE, data, units, desc, err);
}

int wf_h5_write_strings(hid_t loc, const char *name, size_t n, const char *const *s, const char *desc,
                        WfError *err)
{
    hsize_t dim = n;
    hid_t t = wf_h5_text_type(H5T_VARIABLE), sp = H5Screate_simple(1, &dim, NULL), d = H5I_INVALID_HID;
    int rc = t < 0 || sp < 0;
    if (!rc && (d = H5Dcreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && n && H5Dwrite(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, s) < 0) rc = 1;
    if (rc) rc = h5fail_at(err, "write dataset", loc, name);
    if (!rc) rc = label(d, "1", desc, err);
    if (d >= 0) H5Dclose(d);
    if (sp >= 0) H5Sclose(sp);
    if (t >= 0) H5Tclose(t);
    return rc;
}

int wf_h5_scalar_f64(hid_t loc, const char *name, double v, const char *units, const char *desc, WfError *err)
{
    return write_any(loc, name, 0, NULL, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &v, units, desc, err);
}

int wf_h5_scalar_i64(hid_t loc, const char *name, int64_t v, const char *units, const char *desc, WfError *err)
{
    return write_any(loc, name, 0, NULL, H5T_NATIVE_INT64, H5T_STD_I64LE, &v, units, desc, err);
}

int wf_h5_scalar_str(hid_t loc, const char *name, const char *s, const char *desc, WfError *err)
{
    hid_t t = wf_h5_text_type(H5T_VARIABLE);
    if (t < 0) return h5fail_at(err, "string type for", loc, name);
    int rc = write_any(loc, name, 0, NULL, t, t, &s, "1", desc, err);
    H5Tclose(t);
    return rc;
}

/* ---- Results written in place ---- */

/* Contiguous, allocated when created and filled with `fill` then (so the blocks exist on disk: a full disk shows
 * up now, and unwritten values read as the fill value rather than as zeros). */
static hid_t allocated_plist(hid_t type, const void *fill)
{
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (dcpl < 0) return dcpl;
    if (H5Pset_layout(dcpl, H5D_CONTIGUOUS) < 0 || H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_EARLY) < 0 ||
        H5Pset_fill_time(dcpl, H5D_FILL_TIME_ALLOC) < 0 || H5Pset_fill_value(dcpl, type, fill) < 0) {
        H5Pclose(dcpl);
        return H5I_INVALID_HID;
    }
    return dcpl;
}

static int put_any(hid_t loc, const char *name, WfH5Pass pass, int rank, const hsize_t *dims, hid_t mem_type,
                   hid_t file_type, const void *fill, const void *data, const char *units, const char *desc,
                   WfError *err)
{
    hsize_t total = 1;
    for (int i = 0; i < rank; i++) total *= dims[i];
    hid_t d = H5I_INVALID_HID;
    int rc = 0;
    if (pass == WF_H5_ALLOCATE) {
        hid_t sp = rank ? H5Screate_simple(rank, dims, NULL) : H5Screate(H5S_SCALAR);
        hid_t dcpl = allocated_plist(mem_type, fill);
        if (sp < 0 || dcpl < 0 || (d = H5Dcreate2(loc, name, file_type, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT)) < 0)
            rc = h5fail_at(err, "allocate dataset", loc, name);
        if (dcpl >= 0) H5Pclose(dcpl);
        if (sp >= 0) H5Sclose(sp);
        if (!rc) rc = label(d, units, desc, err);
    } else {
        d = H5Dopen2(loc, name, H5P_DEFAULT);
        if (d < 0) return h5fail_at(err, "open dataset", loc, name);
        hid_t sp = H5Dget_space(d);
        hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
        if (sp >= 0) H5Sclose(sp);
        if (np != (hssize_t)total) {
            char path[512];
            obj_path(loc, name, path, sizeof path);
            rc = wf_err(err, WF_ESYS, "HDF5: dataset '%s' has %lld values, %llu expected (written by another "
                        "version of wavefuel?)", path, (long long)np, (unsigned long long)total);
        } else if (total && H5Dwrite(d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0) {
            rc = h5fail_at(err, "write dataset", loc, name);
        }
    }
    if (d >= 0) H5Dclose(d);
    return rc;
}

int wf_h5_put_rows(hid_t loc, const char *name, int i64, hsize_t first, hsize_t m, const void *data, WfError *err)
{
    if (!m) return 0;
    hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
    if (d < 0) return h5fail_at(err, "open dataset", loc, name);
    hid_t fsp = H5Dget_space(d), msp = H5Screate_simple(1, &m, NULL);
    hssize_t np = fsp >= 0 ? H5Sget_simple_extent_npoints(fsp) : -1;
    int rc = 0;
    if (np < (hssize_t)(first + m)) {
        char path[512];
        obj_path(loc, name, path, sizeof path);
        rc = wf_err(err, WF_ESYS, "HDF5: dataset '%s' has %lld values, %llu expected (written by another version of "
                    "wavefuel?)", path, (long long)np, (unsigned long long)(first + m));
    } else if (msp < 0 || H5Sselect_hyperslab(fsp, H5S_SELECT_SET, &first, NULL, &m, NULL) < 0 ||
               H5Dwrite(d, i64 ? H5T_NATIVE_INT64 : H5T_NATIVE_DOUBLE, msp, fsp, H5P_DEFAULT, data) < 0) {
        rc = h5fail_at(err, "write dataset", loc, name);
    }
    if (msp >= 0) H5Sclose(msp);
    if (fsp >= 0) H5Sclose(fsp);
    H5Dclose(d);
    return rc;
}

int wf_h5_put_f64(hid_t loc, const char *name, WfH5Pass pass, int rank, const hsize_t *dims, const double *data,
                  const char *units, const char *desc, WfError *err)
{
    const double nan = NAN;
    return put_any(loc, name, pass, rank, dims, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &nan, data, units, desc, err);
}

int wf_h5_put_i64(hid_t loc, const char *name, WfH5Pass pass, int rank, const hsize_t *dims, const int64_t *data,
                  const char *units, const char *desc, WfError *err)
{
    const int64_t none = -1;
    return put_any(loc, name, pass, rank, dims, H5T_NATIVE_INT64, H5T_STD_I64LE, &none, data, units, desc, err);
}

int wf_h5_put_scalar_f64(hid_t loc, const char *name, WfH5Pass pass, double v, const char *units, const char *desc,
                         WfError *err)
{
    return wf_h5_put_f64(loc, name, pass, 0, NULL, &v, units, desc, err);
}

int wf_h5_put_scalar_i64(hid_t loc, const char *name, WfH5Pass pass, int64_t v, const char *units,
                         const char *desc, WfError *err)
{
    return wf_h5_put_i64(loc, name, pass, 0, NULL, &v, units, desc, err);
}

int wf_h5_put_text(hid_t loc, const char *name, WfH5Pass pass, const char *s, const char *desc, WfError *err)
{
    char buf[WF_H5_TEXT_LEN];
    memset(buf, 0, sizeof buf);
    size_t n = strlen(s);
    if (n >= sizeof buf) {
        n = sizeof buf - 1;
        while (n > 0 && ((unsigned char)s[n] & 0xC0) == 0x80) n--; /* not inside a UTF-8 sequence */
    }
    memcpy(buf, s, n);
    hid_t t = wf_h5_text_type(sizeof buf);
    if (t < 0 || H5Tset_strpad(t, H5T_STR_NULLTERM) < 0) {
        int rc = h5fail_at(err, "text type for", loc, name);
        if (t >= 0) H5Tclose(t);
        return rc;
    }
    static const char empty[WF_H5_TEXT_LEN];
    int rc = put_any(loc, name, pass, 0, NULL, t, t, empty, buf, "1", desc, err);
    H5Tclose(t);
    return rc;
}

/* ---- Series ---- */

void wf_h5_series_init(WfH5Series *s)
{
    memset(s, 0, sizeof *s);
    s->dset = H5I_INVALID_HID;
}

hsize_t wf_h5_series_chunk_rows(hsize_t cols, hsize_t want)
{
    hsize_t r = want ? want : 1, max = cols ? (4u << 20) / (8 * cols) : r;
    if (max < 1) max = 1;
    return r < max ? r : max;
}

/* "pending:" + the path with '.' for '/' (a checkpoint keeps its blocks as datasets of one group). */
static void series_block_name(WfH5Series *s)
{
    snprintf(s->block, sizeof s->block, "pending:%s", s->name);
    for (char *p = s->block; *p; p++)
        if (*p == '/') *p = '.';
}

/* The identity of a series in messages and checkpoints (its path in the file), its shape, and the pending buffer
 * of an appended one. */
static int series_setup(WfH5Series *s, const char *path, hsize_t cols, hsize_t fixed_rows, hsize_t chunk_rows,
                        int compress, WfError *err)
{
    wf_h5_series_init(s);
    snprintf(s->name, sizeof s->name, "%s", path[0] == '/' ? path + 1 : path);
    series_block_name(s);
    s->cols = cols, s->chunk_rows = chunk_rows, s->compress = compress != 0;
    s->cap = chunk_rows ? 0 : fixed_rows;
    if (chunk_rows) {
        s->pend = malloc((size_t)(chunk_rows * (cols ? cols : 1)) * sizeof *s->pend);
        if (!s->pend) return wf_err(err, WF_ESYS, "out of memory for the rows of dataset '/%s'", s->name);
    }
    return 0;
}

/* A failed HDF5 call on the series (call it right after). */
static int series_fail(WfError *err, const char *what, const WfH5Series *s)
{
    char path[sizeof s->name + 1];
    snprintf(path, sizeof path, "/%s", s->name);
    return h5fail(err, what, path);
}

/* Dataset access without a chunk cache: rows reach the file when written, not when a chunk is evicted. */
static hid_t series_access(void)
{
    hid_t dapl = H5Pcreate(H5P_DATASET_ACCESS);
    if (dapl >= 0 && H5Pset_chunk_cache(dapl, 0, 0, 1.0) < 0) {
        H5Pclose(dapl);
        return H5I_INVALID_HID;
    }
    return dapl;
}

int wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t fixed_rows, hsize_t chunk_rows,
                        int compress, const char *units, const char *desc, WfH5Series *s, WfError *err)
{
    char path[sizeof s->name];
    obj_path(loc, name, path, sizeof path);
    int rc = series_setup(s, path, cols, fixed_rows, chunk_rows, compress, err);
    if (rc) return rc;
    int rank = cols ? 2 : 1;
    hsize_t dims[2] = {s->cap, cols}, maxd[2] = {chunk_rows ? H5S_UNLIMITED : fixed_rows, cols};
    const double nan = NAN;
    hid_t sp = H5Screate_simple(rank, dims, maxd), dcpl = H5I_INVALID_HID, dapl = series_access();
    if (chunk_rows) {
        /* Appended: chunks are allocated as rows are appended (wf_h5_series_append), compressed if asked. */
        hsize_t chunk[2] = {chunk_rows, cols};
        dcpl = H5Pcreate(H5P_DATASET_CREATE);
        if (dcpl >= 0 && (H5Pset_chunk(dcpl, rank, chunk) < 0 || H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, &nan) < 0 ||
                          (compress && (H5Pset_shuffle(dcpl) < 0 || H5Pset_deflate(dcpl, 1) < 0)))) {
            H5Pclose(dcpl);
            dcpl = H5I_INVALID_HID;
        }
    } else {
        dcpl = allocated_plist(H5T_NATIVE_DOUBLE, &nan);
    }
    rc = sp < 0 || dcpl < 0 || dapl < 0 ||
         (s->dset = H5Dcreate2(loc, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, dcpl, dapl)) < 0;
    if (rc) rc = h5fail_at(err, "allocate dataset", loc, name);
    if (dapl >= 0) H5Pclose(dapl);
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    return rc ? rc : label(s->dset, units, desc, err);
}

/* Write n rows at row s->rows, inside the current extent. */
static int write_rows(WfH5Series *s, hsize_t n, const double *rows, WfError *err)
{
    int rank = s->cols ? 2 : 1;
    hsize_t start[2] = {s->rows, 0}, count[2] = {n, s->cols};
    hid_t fsp = H5Dget_space(s->dset), msp = H5Screate_simple(rank, count, NULL);
    int rc = (fsp < 0 || msp < 0 || H5Sselect_hyperslab(fsp, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
              H5Dwrite(s->dset, H5T_NATIVE_DOUBLE, msp, fsp, H5P_DEFAULT, rows) < 0);
    if (rc) rc = series_fail(err, "write to dataset", s);
    if (msp >= 0) H5Sclose(msp);
    if (fsp >= 0) H5Sclose(fsp);
    if (!rc) s->rows += n;
    return rc;
}

int wf_h5_series_write_records(WfH5Series *col, size_t n_cols, WfH5Series *cls, size_t n_classes,
                                const double *records, size_t n_rows, double *scratch, WfError *err)
{
    size_t stride = n_cols + n_classes;
    for (size_t c = 0; c < n_cols; c++) {
        for (size_t r = 0; r < n_rows; r++) scratch[r] = records[r * stride + c];
        if (wf_h5_series_write(&col[c], n_rows, scratch, err)) return WF_ESYS;
    }
    for (size_t r = 0; r < n_rows; r++)
        for (size_t c = 0; c < n_classes; c++) scratch[r * n_classes + c] = records[r * stride + n_cols + c];
    return wf_h5_series_write(cls, n_rows, scratch, err) ? WF_ESYS : 0;
}

int wf_h5_series_write(WfH5Series *s, hsize_t n, const double *rows, WfError *err)
{
    if (n == 0) return 0;
    if (s->chunk_rows || s->rows + n > s->cap)
        return wf_err(err, WF_ESYS, "HDF5: dataset '/%s' holds %llu rows, %llu would not fit", s->name,
                      (unsigned long long)s->cap, (unsigned long long)(s->rows + n));
    return write_rows(s, n, rows, err);
}

void wf_h5_series_close(WfH5Series *s)
{
    if (s->dset >= 0) H5Dclose(s->dset);
    s->dset = H5I_INVALID_HID;
    free(s->pend);
    s->pend = NULL;
    s->n_pend = 0;
}

/* Make sure `bytes` more bytes can be written past the end of the file: posix_fallocate allocates the blocks
 * (a full disk or a file size limit fails here, before HDF5 changes anything). On failure the file gets its old
 * length back and `why` the system error. */
static int reserve(WfH5File *f, hsize_t bytes, char *why, size_t len)
{
    int *fd = NULL;
    struct stat st;
    if (H5Fget_vfd_handle(f->fid, H5P_DEFAULT, (void **)&fd) < 0 || !fd) {
        snprintf(why, len, "cannot reach the file descriptor");
        return -1;
    }
    if (fstat(*fd, &st) != 0) {
        errno_text(errno, why, len);
        return -1;
    }
    int e = posix_fallocate(*fd, st.st_size, (off_t)bytes);
    if (e) {
        errno_text(e, why, len);
        /* Give the file its old length back; should that fail too, HDF5 ignores a tail past its end of data. */
        int t = ftruncate(*fd, st.st_size);
        (void)t;
        return -1;
    }
    return 0;
}

/* Give back what a reservation left past HDF5's end of data. HDF5 truncates the file to its end of data when it
 * flushes only if that differs from the end it last wrote, which a write into the reserved space may match:
 * without this the reserved tail would stay in the file. Nothing of HDF5's lies past H5Fget_filesize. */
static void release(WfH5File *f)
{
    int *fd = NULL;
    hsize_t end = 0;
    struct stat st;
    if (H5Fget_vfd_handle(f->fid, H5P_DEFAULT, (void **)&fd) < 0 || !fd || H5Fget_filesize(f->fid, &end) < 0 ||
        fstat(*fd, &st) != 0 || (hsize_t)st.st_size <= end)
        return;
    int t = ftruncate(*fd, (off_t)end);
    (void)t; /* a tail left past the end of data is harmless (HDF5 ignores it), only wasted */
}

/* Reserve `bytes` (plus room for the chunk index and the object headers HDF5 rewrites), run `change` on the
 * series, flush so the file on disk has the new shape, and give back the unused reservation. If the change or the
 * flush fails (an I/O error: the space is there), `undo` puts the series back as they were, so that what HDF5
 * still holds in memory and writes when the file is closed is the consistent state before the change. */
static int reserved_change(WfH5File *f, double bytes, const char *what, int (*change)(void *, WfError *),
                           void (*undo)(void *), void *ctx, WfError *err)
{
    char why[200], size[32];
    double margin = (double)(1u << 20) + bytes / 32;
    if (reserve(f, (hsize_t)(bytes + margin), why, sizeof why))
        return bytes > 0 ? wf_err(err, WF_ESYS, "cannot %s (%s): %s", what, wf_h5_size_text(bytes, size, sizeof size),
                                  why)
                         : wf_err(err, WF_ESYS, "cannot %s: %s", what, why);
    if (change(ctx, err) || wf_h5_flush(f, err)) {
        if (undo) undo(ctx);
        return WF_ESYS;
    }
    release(f);
    return 0;
}

enum { GROUP_MAX = 64 }; /* series appended together, at most */

/* The series of one group, appended together: all appended, with the same chunk rows, rows and pending rows. */
static int check_group(WfH5Series *const *s, size_t n, WfError *err)
{
    if (n == 0 || n > GROUP_MAX) return wf_err(err, WF_ESYS, "HDF5: %zu series appended together (1 to %d)", n, GROUP_MAX);
    for (size_t i = 0; i < n; i++) {
        if (!s[i]->chunk_rows)
            return wf_err(err, WF_ESYS, "HDF5: dataset '/%s' has a fixed size (%llu rows)", s[i]->name,
                          (unsigned long long)s[i]->cap);
        if (s[i]->chunk_rows != s[0]->chunk_rows || s[i]->rows != s[0]->rows || s[i]->n_pend != s[0]->n_pend)
            return wf_err(err, WF_ESYS, "HDF5: datasets '/%s' and '/%s' are appended together but differ in chunks "
                          "or rows", s[0]->name, s[i]->name);
    }
    return 0;
}

typedef struct Append {
    WfH5Series *const *s;
    size_t              n;
    hsize_t             old_rows[GROUP_MAX], old_cap[GROUP_MAX];
} Append;

/* Every series' pending rows into the file, past its rows. */
static int do_append(void *ctx, WfError *err)
{
    Append *a = ctx;
    for (size_t i = 0; i < a->n; i++) a->old_rows[i] = a->s[i]->rows, a->old_cap[i] = a->s[i]->cap;
    for (size_t i = 0; i < a->n; i++) {
        WfH5Series *s = a->s[i];
        hsize_t dims[2] = {s->rows + s->n_pend, s->cols};
        if (dims[0] > s->cap) {
            if (H5Dset_extent(s->dset, dims) < 0) return series_fail(err, "extend dataset", s);
            s->cap = dims[0];
        }
        if (write_rows(s, s->n_pend, s->pend, err)) return WF_ESYS;
    }
    return 0;
}

/* Back to the extents before the append: the chunks it added leave the index (their space is lost). */
static void undo_append(void *ctx)
{
    const Append *a = ctx;
    for (size_t i = 0; i < a->n; i++) {
        WfH5Series *s = a->s[i];
        hsize_t dims[2] = {a->old_cap[i], s->cols};
        if (s->cap != a->old_cap[i] && H5Dset_extent(s->dset, dims) >= 0) s->cap = a->old_cap[i];
        s->rows = a->old_rows[i];
    }
}

/* The pending rows of the group s[0..n) into the file, after reserving their space. */
static int write_pending(WfH5File *f, WfH5Series *const *s, size_t n, const char *what, WfError *err)
{
    hsize_t k = s[0]->n_pend;
    if (!k) return 0;
    /* The chunks the rows touch are (re)written whole, compressed or not: at most their raw size each. */
    double bytes = 0;
    for (size_t i = 0; i < n; i++) {
        hsize_t c = s[i]->chunk_rows, first = s[i]->rows / c, last = (s[i]->rows + k - 1) / c;
        bytes += (double)(last - first + 1) * (double)c * (double)(s[i]->cols ? s[i]->cols : 1) * 8.0;
    }
    char action[300];
    snprintf(action, sizeof action, "add %llu rows to %s", (unsigned long long)k, what);
    Append a = {.s = s, .n = n};
    int rc = reserved_change(f, bytes, action, do_append, undo_append, &a, err);
    for (size_t i = 0; !rc && i < n; i++) s[i]->n_pend = 0;
    return rc;
}

int wf_h5_series_append(WfH5File *f, WfH5Series *const *s, size_t n, hsize_t n_rows, const double *const *data,
                        const char *what, WfError *err)
{
    int rc = check_group(s, n, err);
    for (hsize_t done = 0; !rc && done < n_rows;) {
        hsize_t take = s[0]->chunk_rows - s[0]->n_pend;
        if (take > n_rows - done) take = n_rows - done;
        for (size_t i = 0; i < n; i++) {
            size_t width = s[i]->cols ? (size_t)s[i]->cols : 1;
            memcpy(s[i]->pend + s[i]->n_pend * width, data[i] + done * width, (size_t)take * width * sizeof(double));
            s[i]->n_pend += take;
        }
        done += take;
        /* A complete chunk is written at once; should that fail, its rows stay pending. */
        if (s[0]->n_pend == s[0]->chunk_rows) rc = write_pending(f, s, n, what, err);
    }
    return rc;
}

int wf_h5_series_flush(WfH5File *f, WfH5Series *const *s, size_t n, const char *what, WfError *err)
{
    int rc = check_group(s, n, err);
    return rc ? rc : write_pending(f, s, n, what, err);
}

int wf_h5_series_resume(WfH5Series *s, const char *path, hsize_t cols, hsize_t fixed_rows, hsize_t chunk_rows,
                        int compress, hsize_t total_rows, WfError *err)
{
    int rc = series_setup(s, path, cols, fixed_rows, chunk_rows, compress, err);
    if (rc) return rc;
    if (!chunk_rows && total_rows > fixed_rows)
        return wf_err(err, WF_EINPUT, "the checkpoint counts %llu rows of '/%s', which has %llu",
                      (unsigned long long)total_rows, s->name, (unsigned long long)fixed_rows);
    s->n_pend = chunk_rows ? total_rows % chunk_rows : 0;
    s->rows = total_rows - s->n_pend;
    return 0;
}

int wf_h5_series_reopen(hid_t fid, WfH5Series *s, WfError *err)
{
    const char *name = s->name;
    hid_t dapl = series_access();
    s->dset = dapl >= 0 && H5Lexists(fid, name, H5P_DEFAULT) > 0 ? H5Dopen2(fid, name, dapl) : H5I_INVALID_HID;
    if (dapl >= 0) H5Pclose(dapl);
    if (s->dset < 0) return wf_err(err, WF_EINPUT, "no dataset '/%s'", name);
    hid_t sp = H5Dget_space(s->dset), dcpl = H5Dget_create_plist(s->dset);
    hsize_t dims[2] = {0, 0}, chunk[2] = {0, 0};
    int rank = sp >= 0 ? H5Sget_simple_extent_dims(sp, dims, NULL) : -1;
    H5D_layout_t layout = dcpl >= 0 ? H5Pget_layout(dcpl) : H5D_LAYOUT_ERROR;
    int crank = layout == H5D_CHUNKED ? H5Pget_chunk(dcpl, 2, chunk) : 0;
    int nfilt = dcpl >= 0 ? H5Pget_nfilters(dcpl) : -1;
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    if (rank < 1 || rank > 2 || layout == H5D_LAYOUT_ERROR || crank < 0 || nfilt < 0)
        return series_fail(err, "read the layout of", s);
    /* The resumed run must write the rows the interrupted one would have: same shape, layout, chunks, filters. */
    int same = (rank == 2 ? dims[1] : 0) == s->cols && (nfilt > 0) == s->compress &&
               (s->chunk_rows ? layout == H5D_CHUNKED && crank == rank && chunk[0] == s->chunk_rows
                              : layout == H5D_CONTIGUOUS && dims[0] == s->cap);
    if (!same)
        return wf_err(err, WF_EINPUT, "dataset '/%s' has another shape, layout, chunking or compression than this run "
                      "writes (written by another version of wavefuel?)", name);
    if (dims[0] < s->rows)
        return wf_err(err, WF_EINPUT, "dataset '/%s' has %llu rows, the checkpoint needs %llu", name,
                      (unsigned long long)dims[0], (unsigned long long)s->rows);
    if (s->chunk_rows) s->cap = dims[0];
    return 0;
}

typedef struct Trim {
    WfH5Series *const *s;
    size_t              n;
} Trim;

static int do_trim(void *ctx, WfError *err)
{
    const Trim *t = ctx;
    for (size_t i = 0; i < t->n; i++) {
        WfH5Series *s = t->s[i];
        if (!s->chunk_rows || s->cap == s->rows) continue;
        hsize_t dims[2] = {s->rows, s->cols};
        if (H5Dset_extent(s->dset, dims) < 0) return series_fail(err, "shrink dataset", s);
        s->cap = s->rows;
    }
    return 0;
}

int wf_h5_series_trim(WfH5File *f, WfH5Series *const *s, size_t n, WfError *err)
{
    int change = 0;
    for (size_t i = 0; i < n; i++) change |= s[i]->chunk_rows && s[i]->cap != s[i]->rows;
    if (!change) return 0;
    Trim t = {s, n};
    return reserved_change(f, 0, "cut the series to the rows of the checkpoint", do_trim, NULL, &t, err);
}

int wf_h5_check_room(const WfH5File *f, double bytes, char *why, size_t len)
{
    char have[32];
    struct rlimit rl;
    if (getrlimit(RLIMIT_FSIZE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY && (double)rl.rlim_cur < bytes) {
        snprintf(why, len, "the file size limit (ulimit -f) is %s",
                 wf_h5_size_text((double)rl.rlim_cur, have, sizeof have));
        return -1;
    }
    int *fd = NULL;
    struct statvfs vfs;
    if (H5Fget_vfd_handle(f->fid, H5P_DEFAULT, (void **)&fd) >= 0 && fd && fstatvfs(*fd, &vfs) == 0) {
        double avail = (double)vfs.f_bavail * (double)vfs.f_frsize;
        if (avail < bytes) {
            snprintf(why, len, "only %s free on its file system (disk full)",
                     wf_h5_size_text(avail, have, sizeof have));
            return -1;
        }
    }
    return 0;
}
