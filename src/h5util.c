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

int wf_h5_create(const char *path, int force, WfH5File **out, WfError *err)
{
    wf_h5_library_init();
    *out = NULL;
    struct stat st;
    WfH5File *f = calloc(1, sizeof *f);
    if (!f) return wf_err(err, WF_ESYS, "out of memory");
    int w1 = snprintf(f->path, sizeof f->path, "%s", path);
    int w2 = snprintf(f->partial, sizeof f->partial, "%s.partial", path);
    if (w1 < 0 || (size_t)w1 >= sizeof f->path || w2 < 0 || (size_t)w2 >= sizeof f->partial) {
        free(f);
        return wf_err(err, WF_EINPUT, "output path too long: %s", path);
    }
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

int wf_h5_series_create(hid_t loc, const char *name, hsize_t cols, hsize_t chunk_rows, int compress,
                        const char *units, const char *desc, WfH5Series *s, WfError *err)
{
    memset(s, 0, sizeof *s);
    s->dset = H5I_INVALID_HID;
    snprintf(s->name, sizeof s->name, "%s", name);
    int rank = cols ? 2 : 1;
    hsize_t dims[2] = {0, cols}, maxd[2] = {H5S_UNLIMITED, cols}, chunk[2] = {chunk_rows ? chunk_rows : 1, cols};
    /* Keep a chunk near 1 MiB whatever the row width. */
    if (cols && chunk[0] * cols * 8 > (4u << 20)) chunk[0] = (4u << 20) / (cols * 8) + 1;
    hid_t sp = H5Screate_simple(rank, dims, maxd), dcpl = H5Pcreate(H5P_DATASET_CREATE);
    int rc = (sp < 0 || dcpl < 0 || H5Pset_chunk(dcpl, rank, chunk) < 0);
    if (!rc && compress && (H5Pset_shuffle(dcpl) < 0 || H5Pset_deflate(dcpl, 1) < 0)) rc = 1;
    if (!rc && (s->dset = H5Dcreate2(loc, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT)) < 0) rc = 1;
    if (dcpl >= 0) H5Pclose(dcpl);
    if (sp >= 0) H5Sclose(sp);
    if (rc) return h5fail(err, "create dataset", name);
    s->cols = cols;
    return label(s->dset, name, units, desc, err);
}

int wf_h5_series_append(WfH5Series *s, hsize_t n, const double *rows, WfError *err)
{
    if (n == 0) return 0;
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

void wf_h5_series_close(WfH5Series *s)
{
    if (s->dset >= 0) H5Dclose(s->dset);
    s->dset = H5I_INVALID_HID;
}

int wf_h5_series_open(hid_t loc, const char *name, hsize_t keep_rows, WfH5Series *s, WfError *err)
{
    memset(s, 0, sizeof *s);
    snprintf(s->name, sizeof s->name, "%s", name);
    s->dset = H5Dopen2(loc, name, H5P_DEFAULT);
    if (s->dset < 0) return h5fail(err, "open dataset", name);
    hid_t sp = H5Dget_space(s->dset);
    hsize_t dims[2] = {0, 0};
    int rank = sp >= 0 ? H5Sget_simple_extent_dims(sp, dims, NULL) : -1;
    if (sp >= 0) H5Sclose(sp);
    if (rank < 1 || rank > 2) return h5fail(err, "read the shape of", name);
    if (dims[0] < keep_rows)
        return wf_err(err, WF_EINPUT, "dataset '%s' has %llu rows, the checkpoint needs %llu", name,
                      (unsigned long long)dims[0], (unsigned long long)keep_rows);
    s->cols = rank == 2 ? dims[1] : 0;
    s->rows = keep_rows;
    dims[0] = keep_rows;
    /* Rows written after the checkpoint are dropped: the resumed run writes them again. */
    if (H5Dset_extent(s->dset, dims) < 0) return h5fail(err, "truncate dataset", name);
    return 0;
}
