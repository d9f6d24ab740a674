/* Checked HDF5 helpers: partial-file protocol, datasets with units, extendible series. */
#include "h5util.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int h5fail(WfError *err, const char *what, const char *name)
{
    return wf_err(err, WF_ESYS, "HDF5: %s '%s' failed (disk full, permission or a damaged file?)", what, name);
}

void wf_h5_library_init(void)
{
    /* No HDF5 clean-up at exit: after a failed H5Fclose (disk full), HDF5 1.10's exit handler closes the file
     * again and crashes; the operating system releases everything anyway. Only effective before the library
     * initialises; later calls return an error, which is harmless. */
    H5dont_atexit();
    /* Per thread in HDF5 (each sweep worker calls this): wavefuel reports errors itself, naming the object. */
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

/* A new WfH5File for PATH and PATH.partial, not yet open. */
static int file_new(const char *path, WfH5File **out, WfError *err)
{
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

int wf_h5_reopen(const char *path, WfH5File **out, WfError *err)
{
    wf_h5_library_init();
    *out = NULL;
    WfH5File *f = NULL;
    int rc = file_new(path, &f, err);
    if (rc) return rc;
    f->fid = H5Fopen(f->partial, H5F_ACC_RDWR, H5P_DEFAULT);
    if (f->fid < 0) {
        rc = wf_err(err, WF_EINPUT, "%s: cannot reopen the partial result (missing, or damaged by a hard kill?)",
                    f->partial);
        free(f);
        return rc;
    }
    *out = f;
    return 0;
}

int wf_h5_create(const char *path, int force, WfH5File **out, WfError *err)
{
    wf_h5_library_init();
    *out = NULL;
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
    f->fid = H5Fcreate(f->partial, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (f->fid < 0) {
        int e = errno;
        int rc = wf_err(err, WF_ESYS, "%s: cannot create (%s)", f->partial, e ? strerror(e) : "HDF5 error");
        free(f);
        return rc;
    }
    *out = f;
    return 0;
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

hid_t wf_h5_group(hid_t loc, const char *name, WfError *err)
{
    hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    if (lcpl < 0) {
        h5fail(err, "property list for group", name);
        return H5I_INVALID_HID;
    }
    H5Pset_create_intermediate_group(lcpl, 1);
    hid_t g = H5Gcreate2(loc, name, lcpl, H5P_DEFAULT, H5P_DEFAULT);
    H5Pclose(lcpl);
    if (g < 0) h5fail(err, "create group", name);
    return g;
}

int wf_h5_attr_str(hid_t obj, const char *name, const char *value, WfError *err)
{
    hid_t t = H5Tcopy(H5T_C_S1), sp = H5Screate(H5S_SCALAR), a = H5I_INVALID_HID;
    int rc = 0;
    if (t < 0 || sp < 0 || H5Tset_size(t, strlen(value) + 1) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0) rc = 1;
    if (!rc && (a = H5Acreate2(obj, name, t, sp, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && H5Awrite(a, t, value) < 0) rc = 1;
    if (a >= 0) H5Aclose(a);
    if (sp >= 0) H5Sclose(sp);
    if (t >= 0) H5Tclose(t);
    return rc ? h5fail(err, "write attribute", name) : 0;
}

static int attr_scalar(hid_t obj, const char *name, hid_t type, const void *v, WfError *err)
{
    hid_t sp = H5Screate(H5S_SCALAR), a = H5I_INVALID_HID;
    int rc = sp < 0;
    if (!rc && (a = H5Acreate2(obj, name, type, sp, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && H5Awrite(a, type, v) < 0) rc = 1;
    if (a >= 0) H5Aclose(a);
    if (sp >= 0) H5Sclose(sp);
    return rc ? h5fail(err, "write attribute", name) : 0;
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
    hid_t sp = d >= 0 ? H5Dget_space(d) : H5I_INVALID_HID, t = H5Tcopy(H5T_C_S1);
    char *s = NULL;
    int rc = 0;
    if (ft < 0 || sp < 0 || H5Tget_class(ft) != H5T_STRING || H5Tis_variable_str(ft) <= 0 ||
        H5Sget_simple_extent_npoints(sp) != 1)
        rc = wf_err(err, WF_EINPUT, "%s: '%s' is not a scalar string", file, name);
    else if (t < 0 || H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0 ||
             H5Dread(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, &s) < 0 || !s)
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

static int label(hid_t d, const char *name, const char *units, const char *desc, WfError *err)
{
    if (units && wf_h5_attr_str(d, "units", units, err)) return WF_ESYS;
    if (desc && wf_h5_attr_str(d, "description", desc, err)) return WF_ESYS;
    (void)name;
    return 0;
}

static int write_any(hid_t loc, const char *name, int rank, const hsize_t *dims, hid_t mem_type, hid_t file_type,
                     const void *data, const char *units, const char *desc, WfError *err)
{
    hsize_t total = 1;
    for (int i = 0; i < rank; i++) total *= dims[i];
    hid_t sp = H5Screate_simple(rank, dims, NULL), dcpl = H5Pcreate(H5P_DATASET_CREATE), d = H5I_INVALID_HID;
    int rc = (sp < 0 || dcpl < 0);
    /* Large arrays are chunked and compressed; small ones stay contiguous (cheaper to read). */
    if (!rc && total >= 4096) {
        hsize_t chunk[2] = {dims[0], rank > 1 ? dims[1] : 1};
        hsize_t row_bytes = (rank > 1 ? dims[1] : 1) * 8;
        hsize_t max_rows = (1u << 20) / (row_bytes ? row_bytes : 1);
        if (max_rows < 1) max_rows = 1;
        if (chunk[0] > max_rows) chunk[0] = max_rows;
        if (rank > 1 && chunk[1] * 8 > (1u << 20)) chunk[1] = (1u << 20) / 8, chunk[0] = 1;
        if (H5Pset_chunk(dcpl, rank, chunk) < 0 || H5Pset_deflate(dcpl, 4) < 0) rc = 1;
    }
    if (!rc && (d = H5Dcreate2(loc, name, file_type, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && total && H5Dwrite(d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0) rc = 1;
    if (rc) rc = h5fail(err, "write dataset", name);
    if (!rc) rc = label(d, name, units, desc, err);
    if (d >= 0) H5Dclose(d);
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    return rc;
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
    hid_t t = H5Tcopy(H5T_C_S1), sp = H5Screate_simple(1, &dim, NULL), d = H5I_INVALID_HID;
    int rc = (t < 0 || sp < 0 || H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0);
    if (!rc && (d = H5Dcreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && n && H5Dwrite(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, s) < 0) rc = 1;
    if (rc) rc = h5fail(err, "write dataset", name);
    if (!rc) rc = label(d, name, "1", desc, err);
    if (d >= 0) H5Dclose(d);
    if (sp >= 0) H5Sclose(sp);
    if (t >= 0) H5Tclose(t);
    return rc;
}

static int scalar_any(hid_t loc, const char *name, hid_t mem, hid_t file, const void *v, const char *units,
                      const char *desc, WfError *err)
{
    hid_t sp = H5Screate(H5S_SCALAR), d = H5I_INVALID_HID;
    int rc = sp < 0;
    if (!rc && (d = H5Dcreate2(loc, name, file, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT)) < 0) rc = 1;
    if (!rc && H5Dwrite(d, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) < 0) rc = 1;
    if (rc) rc = h5fail(err, "write dataset", name);
    if (!rc) rc = label(d, name, units, desc, err);
    if (d >= 0) H5Dclose(d);
    if (sp >= 0) H5Sclose(sp);
    return rc;
}

int wf_h5_scalar_f64(hid_t loc, const char *name, double v, const char *units, const char *desc, WfError *err)
{
    return scalar_any(loc, name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &v, units, desc, err);
}

int wf_h5_scalar_i64(hid_t loc, const char *name, int64_t v, const char *units, const char *desc, WfError *err)
{
    return scalar_any(loc, name, H5T_NATIVE_INT64, H5T_STD_I64LE, &v, units, desc, err);
}

int wf_h5_scalar_str(hid_t loc, const char *name, const char *s, const char *desc, WfError *err)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    if (t < 0 || H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0) {
        if (t >= 0) H5Tclose(t);
        return h5fail(err, "string type for", name);
    }
    int rc = scalar_any(loc, name, t, t, &s, "1", desc, err);
    H5Tclose(t);
    return rc;
}

hsize_t wf_h5_series_chunk_rows(hsize_t cols, hsize_t chunk_rows)
{
    hsize_t r = chunk_rows ? chunk_rows : 1;
    /* Keep a chunk near 4 MiB whatever the row width. */
    if (cols && r * cols * 8 > (4u << 20)) r = (4u << 20) / (cols * 8) + 1;
    return r;
}

/* "pending:" + the path with '.' for '/' (a checkpoint keeps its blocks as datasets of one group). */
static void series_block_name(WfH5Series *s)
{
    snprintf(s->block, sizeof s->block, "pending:%s", s->name);
    for (char *p = s->block; *p; p++)
        if (*p == '/') *p = '.';
}

/* The identity of a series in messages and checkpoints (its path in the file), and the pending buffer of a
 * compressed one. */
static int series_setup(WfH5Series *s, const char *path, hsize_t cols, hsize_t chunk_rows, int compress,
                        WfError *err)
{
    memset(s, 0, sizeof *s);
    s->dset = H5I_INVALID_HID;
    snprintf(s->name, sizeof s->name, "%s", path[0] == '/' ? path + 1 : path);
    series_block_name(s);
    s->cols = cols;
    s->compress = compress != 0;
    s->chunk_rows = wf_h5_series_chunk_rows(cols, chunk_rows);
    /* A one-row chunk is complete at every append: nothing waits. */
    if (compress && s->chunk_rows > 1) {
        s->pend = malloc(s->chunk_rows * (cols ? cols : 1) * sizeof *s->pend);
        if (!s->pend) return wf_err(err, WF_ESYS, "out of memory for the rows of dataset '%s'", s->name);
    }
    return 0;
}

int wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t chunk_rows, int compress,
                        const char *units, const char *desc, WfH5Series *s, WfError *err)
{
    int rc = series_setup(s, name, cols, chunk_rows, compress, err);
    if (rc) return rc;
    int rank = cols ? 2 : 1;
    hsize_t dims[2] = {0, cols}, maxd[2] = {H5S_UNLIMITED, cols}, chunk[2] = {s->chunk_rows, cols};
    hid_t sp = H5Screate_simple(rank, dims, maxd), dcpl = H5Pcreate(H5P_DATASET_CREATE);
    rc = (sp < 0 || dcpl < 0 || H5Pset_chunk(dcpl, rank, chunk) < 0);
    if (!rc && compress && (H5Pset_shuffle(dcpl) < 0 || H5Pset_deflate(dcpl, 1) < 0)) rc = 1;
    if (!rc && (s->dset = H5Dcreate2(loc, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT)) < 0) rc = 1;
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    if (rc) return h5fail(err, "create dataset", name);
    /* From here on the series is named by its path in the file ("trips/serial"). */
    char path[sizeof s->name];
    ssize_t len = H5Iget_name(s->dset, path, sizeof path);
    if (len > 0 && (size_t)len < sizeof path) {
        snprintf(s->name, sizeof s->name, "%s", path[0] == '/' ? path + 1 : path);
        series_block_name(s);
    }
    return label(s->dset, name, units, desc, err);
}

/* Rows written to the file, extending it. */
static int series_write(WfH5Series *s, hsize_t n, const double *rows, WfError *err)
{
    int rank = s->cols ? 2 : 1;
    hsize_t newdims[2] = {s->rows + n, s->cols}, start[2] = {s->rows, 0}, count[2] = {n, s->cols};
    if (H5Dset_extent(s->dset, newdims) < 0) return h5fail(err, "extend dataset", s->name);
    hid_t fsp = H5Dget_space(s->dset), msp = H5Screate_simple(rank, count, NULL);
    int rc = (fsp < 0 || msp < 0 || H5Sselect_hyperslab(fsp, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
              H5Dwrite(s->dset, H5T_NATIVE_DOUBLE, msp, fsp, H5P_DEFAULT, rows) < 0);
    if (msp >= 0) H5Sclose(msp);
    if (fsp >= 0) H5Sclose(fsp);
    if (rc) return h5fail(err, "append to dataset", s->name);
    s->rows += n;
    return 0;
}

int wf_h5_series_append(WfH5Series *s, hsize_t n, const double *rows, WfError *err)
{
    if (!s->pend) return n ? series_write(s, n, rows, err) : 0;
    size_t width = s->cols ? s->cols : 1;
    while (n > 0) {
        hsize_t take = s->chunk_rows - s->n_pend < n ? s->chunk_rows - s->n_pend : n;
        memcpy(s->pend + s->n_pend * width, rows, take * width * sizeof *rows);
        s->n_pend += take, rows += take * width, n -= take;
        if (s->n_pend == s->chunk_rows) {
            int rc = series_write(s, s->n_pend, s->pend, err);
            if (rc) return rc;
            s->n_pend = 0;
        }
    }
    return 0;
}

int wf_h5_series_flush(WfH5Series *s, WfError *err)
{
    if (!s->n_pend) return 0;
    int rc = series_write(s, s->n_pend, s->pend, err);
    if (!rc) s->n_pend = 0;
    return rc;
}

void wf_h5_series_close(WfH5Series *s)
{
    if (s->dset >= 0) H5Dclose(s->dset);
    s->dset = H5I_INVALID_HID;
    free(s->pend);
    s->pend = NULL;
    s->n_pend = 0;
}

int wf_h5_series_resume(WfH5Series *s, const char *path, hsize_t cols, hsize_t chunk_rows, int compress,
                        hsize_t total_rows, WfError *err)
{
    int rc = series_setup(s, path, cols, chunk_rows, compress, err);
    if (rc) return rc;
    s->n_pend = s->pend ? total_rows % s->chunk_rows : 0;
    s->rows = total_rows - s->n_pend;
    return 0;
}

int wf_h5_series_reopen(hid_t fid, WfH5Series *s, WfError *err)
{
    const char *name = s->name;
    s->dset = H5Lexists(fid, name, H5P_DEFAULT) > 0 ? H5Dopen2(fid, name, H5P_DEFAULT) : H5I_INVALID_HID;
    if (s->dset < 0) return wf_err(err, WF_EINPUT, "no dataset '%s'", name);
    hid_t sp = H5Dget_space(s->dset), dcpl = H5Dget_create_plist(s->dset);
    hsize_t dims[2] = {0, 0}, chunk[2] = {0, 0};
    int rank = sp >= 0 ? H5Sget_simple_extent_dims(sp, dims, NULL) : -1;
    int crank = dcpl >= 0 && H5Pget_layout(dcpl) == H5D_CHUNKED ? H5Pget_chunk(dcpl, 2, chunk) : -1;
    int nfilt = dcpl >= 0 ? H5Pget_nfilters(dcpl) : -1;
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    if (rank < 1 || rank > 2 || crank != rank || nfilt < 0) return h5fail(err, "read the layout of", name);
    /* The resumed run must write the rows the interrupted one would have: same shape, chunks and filters. */
    if ((rank == 2 ? dims[1] : 0) != s->cols || chunk[0] != s->chunk_rows || (nfilt > 0) != s->compress)
        return wf_err(err, WF_EINPUT, "dataset '%s' has another shape, chunking or compression than this run writes",
                      name);
    if (dims[0] < s->rows)
        return wf_err(err, WF_EINPUT, "dataset '%s' has %llu rows, the checkpoint needs %llu", name,
                      (unsigned long long)dims[0], (unsigned long long)s->rows);
    dims[0] = s->rows;
    /* Rows written after the checkpoint are dropped: the resumed run writes them again. */
    if (H5Dset_extent(s->dset, dims) < 0) return h5fail(err, "truncate dataset", name);
    return 0;
}
