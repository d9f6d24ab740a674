/* Tabulated (semi-principled) energy model of the CIRCLES release: fuel rate g/s on a regular (v, a, theta)
 * grid, read from the release's CSV, stored as compressed HDF5 with its grid, source and a checksum, and
 * evaluated as the release's MATLAB wrappers do (trilinear interpolation; flag from the interpolated
 * Infeasible column; projection onto the bilinear interpolation of each column's largest feasible grid
 * acceleration). Outside the grid the release returns NaN; wavefuel clamps to the edge and counts. */
#include "wavefuel/tabulated.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/h5util.h"
#include "util/hash.h"
#include "util/path.h"
#include "wavefuel/config.h"
#include "wavefuel/csv.h"
#include "wavefuel/version.h"
#include "util/numfmt.h"
#include "util/mem.h"

#define TABLE_FORMAT "wavefuel tabulated energy model"
#define TABLE_FORMAT_VERSION 1
/* Bucket index size cap per axis (entries of 4 bytes): a table axis has at most a few thousand nodes. */
#define MAX_BUCKETS 65536

static const char *const column_names[] = {"Velocity", "Acceleration", "Road Grade", "Fuel Rate", "Infeasible"};

/* ---------------------------------------------------------------------------------------------------------
 * Grid construction and checks */

void wf_table_destroy(WfTable **pt)
{
    if (!pt || !*pt) return;
    WfTable *t = *pt;
    WfTableAxis *axes[3] = {&t->v, &t->a, &t->theta};
    for (int c = 0; c < 3; c++) WF_FREE(axes[c]->x, axes[c]->inv_w, axes[c]->bucket);
    WF_FREE(t->fuel_gps, t->infeasible, t->a_max_mps2, t);
    *pt = NULL;
}

/* Takes ownership of nodes[n + 1] (n >= 1 finite values, strictly ascending; the last slot is padding) and
 * builds the bucket index. `what` names the axis for messages. */
static int axis_init(WfTableAxis *ax, double *nodes, size_t n, const char *file, const char *what, WfError *err)
{
    /* One node: the padding makes x[k + 1] - x[k] = 1, so t = 0 without a division by zero; up = 0 keeps
     * both "corners" on the single node. */
    nodes[n] = n > 1 ? nodes[n - 1] + (nodes[n - 1] - nodes[n - 2]) : nodes[0] + 1.0;
    *ax = (WfTableAxis){.n = n, .lo = nodes[0], .hi = nodes[n - 1], .kmax = n > 1 ? n - 2 : 0, .up = n > 1 ? 1 : 0,
                        .x = nodes};
    /* Buckets no wider than the narrowest cell hold at most two cells, so locate() steps at most twice. */
    double min_w = INFINITY;
    for (size_t k = 0; k + 1 < n; k++) min_w = fmin(min_w, nodes[k + 1] - nodes[k]);
    double want = n > 1 ? ceil((ax->hi - ax->lo) / min_w) : 1.0;
    if (n > (size_t)UINT32_MAX)
        return wf_err(err, WF_EINPUT, "%s: %s has %zu values: too many for a table axis", file, what, n);
    ax->n_bucket = want > MAX_BUCKETS ? MAX_BUCKETS : (size_t)want;
    if (ax->n_bucket < 1) ax->n_bucket = 1;
    ax->bucket_scale = n > 1 ? (double)ax->n_bucket / (ax->hi - ax->lo) : 0.0;
    ax->bucket = malloc(ax->n_bucket * sizeof *ax->bucket);
    ax->inv_w = malloc(n * sizeof *ax->inv_w);
    if (!ax->bucket || !ax->inv_w) return wf_err(err, WF_ESYS, "out of memory for the %s axis of %s", what, file);
    for (size_t k = 0; k < n; k++) ax->inv_w[k] = 1.0 / (nodes[k + 1] - nodes[k]);
    /* Spacings so small that their reciprocals overflow would turn the weights into NaN (0 x inf). */
    for (size_t k = 0; k < n; k++)
        if (!isfinite(ax->inv_w[k]) || !isfinite(ax->bucket_scale))
            return wf_err(err, WF_EINPUT, "%s: %s values %s and %s are too close together for a table axis",
                          file, what, WF_NUM(nodes[k]), WF_NUM(nodes[k + 1]));
    size_t k = 0;
    for (size_t b = 0; b < ax->n_bucket; b++) {
        double edge = ax->lo + (double)b * (ax->hi - ax->lo) / (double)ax->n_bucket;
        while (k < ax->kmax && nodes[k + 1] <= edge) k++;
        /* One cell lower than the edge's own: a coordinate that rounds into this bucket may lie a hair
         * below its edge. */
        ax->bucket[b] = (uint32_t)(k > 0 ? k - 1 : 0);
    }
    return 0;
}

/* Largest feasible grid acceleration of each (v, theta) column. A column with no feasible node (partial
 * tables such as the release's 63-row sample) gets the lowest grid acceleration: the closest the table
 * comes to a feasible value. */
static void derive_a_max(WfTable *t)
{
    size_t na = t->a.n, nt = t->theta.n;
    for (size_t iv = 0; iv < t->v.n; iv++)
        for (size_t it = 0; it < nt; it++) {
            double best = t->a.lo;
            for (size_t ia = na; ia-- > 0;)
                if (t->infeasible[(iv * na + ia) * nt + it] == 0) {
                    best = t->a.x[ia];
                    break;
                }
            t->a_max_mps2[iv * nt + it] = best;
        }
}

static int cmp_double(const void *pa, const void *pb)
{
    double a = *(const double *)pa, b = *(const double *)pb;
    return (a > b) - (a < b);
}

/* Distinct values of column `col` of the CSV, ascending, with one padding slot after them. */
static int distinct(const WfCsv *csv, size_t col, double **out, size_t *n_out, WfError *err)
{
    double *x = malloc((csv->n_rows + 1) * sizeof *x);
    if (!x) return wf_err(err, WF_ESYS, "out of memory reading a table");
    for (size_t r = 0; r < csv->n_rows; r++) x[r] = csv->data[r * csv->n_cols + col];
    qsort(x, csv->n_rows, sizeof *x, cmp_double);
    size_t n = 0;
    for (size_t r = 0; r < csv->n_rows; r++)
        if (n == 0 || x[r] != x[n - 1]) x[n++] = x[r];
    *out = x;
    *n_out = n;
    return 0;
}

/* Index of value x among the axis nodes (present by construction: the nodes are the column's values). */
static size_t node_index(const WfTableAxis *ax, double x)
{
    size_t lo = 0, hi = ax->n - 1;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (ax->x[mid] < x) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static uint64_t fnv_u64(uint64_t h, uint64_t x)
{
    unsigned char b[8];
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(x >> (8 * i)); /* little-endian on every host */
    return wf_fnv1a64(h, b, 8);
}

static uint64_t fnv_f64s(uint64_t h, const double *x, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint64_t bits;
        memcpy(&bits, &x[i], sizeof bits);
        h = fnv_u64(h, bits);
    }
    return h;
}

uint64_t wf_table_checksum(const WfTable *t)
{
    uint64_t h = WF_FNV1A64_INIT;
    size_t n = t->v.n * t->a.n * t->theta.n;
    h = fnv_u64(h, t->v.n);
    h = fnv_u64(h, t->a.n);
    h = fnv_u64(h, t->theta.n);
    h = fnv_f64s(h, t->v.x, t->v.n);
    h = fnv_f64s(h, t->a.x, t->a.n);
    h = fnv_f64s(h, t->theta.x, t->theta.n);
    h = fnv_f64s(h, t->fuel_gps, n);
    return wf_fnv1a64(h, t->infeasible, n);
}

static int file_fnv(const char *path, uint64_t *out, WfError *err)
{
    FILE *f = fopen(path, "rb");
    if (!f) return wf_err(err, WF_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    unsigned char buf[1 << 16];
    uint64_t h = WF_FNV1A64_INIT;
    size_t k;
    while ((k = fread(buf, 1, sizeof buf, f)) > 0) h = wf_fnv1a64(h, buf, k);
    int bad = ferror(f);
    fclose(f);
    if (bad) return wf_err(err, WF_ESYS, "%s: read error", path);
    *out = h;
    return 0;
}

/* Allocates the value arrays of a table whose axes are set. */
static int alloc_values(WfTable *t, WfError *err)
{
    size_t n = t->v.n * t->a.n * t->theta.n;
    t->fuel_gps = malloc(n * sizeof *t->fuel_gps);
    t->infeasible = malloc(n ? n : 1);
    t->a_max_mps2 = malloc(t->v.n * t->theta.n * sizeof *t->a_max_mps2);
    if (!t->fuel_gps || !t->infeasible || !t->a_max_mps2) return wf_err(err, WF_ESYS, "out of memory for a table");
    return 0;
}

/* The grid of a CSV table: header and rows checked, the axes from the distinct values of the first three columns,
 * the value arrays allocated. */
static int csv_grid(WfTable *t, const WfCsv *csv, const char *path, WfError *err)
{
    if (!csv->had_header)
        return wf_err(err, WF_EINPUT, "%s: the first line must be the header 'Velocity,Acceleration,Road Grade,Fuel "
                                      "Rate,Infeasible' (the release's format)", path);
    if (csv->n_rows == 0) return wf_err(err, WF_EINPUT, "%s: no data rows", path);
    for (size_t r = 0; r < csv->n_rows; r++) {
        double inf = csv->data[r * 5 + 4];
        if (inf != 0.0 && inf != 1.0)
            return wf_err(err, WF_EINPUT, "%s:%d: field 5 (Infeasible) must be 0 or 1 (got %s)", path, csv->line[r],
                          WF_NUM(inf));
    }
    WfTableAxis *axes[3] = {&t->v, &t->a, &t->theta};
    for (size_t c = 0; c < 3; c++) {
        double *nodes = NULL;
        size_t n = 0;
        int rc = distinct(csv, c, &nodes, &n, err);
        if (rc || (rc = axis_init(axes[c], nodes, n, path, column_names[c], err))) return rc;
    }
    size_t nv = t->v.n, na = t->a.n, nt = t->theta.n;
    /* The product is bounded before it is formed: each axis has at most n_rows values. */
    double product = (double)nv * (double)na * (double)nt;
    /* A few missing rows are reported by name below; a product far beyond the row count is not a grid. */
    if (product > 4.0 * (double)csv->n_rows + 1024.0)
        return wf_err(err, WF_EINPUT,
                      "%s: not a regular grid: %zu distinct speeds x %zu accelerations x %zu grades would need "
                      "%.0f rows, the file has %zu",
                      path, nv, na, nt, product, csv->n_rows);
    return alloc_values(t, err);
}

/* The rows' values into the grid: exactly one row per grid point. row_line (zeroed, one per point) receives the line
 * of the row that filled each point. */
static int csv_values(WfTable *t, const WfCsv *csv, const char *path, int *row_line, WfError *err)
{
    size_t nv = t->v.n, na = t->a.n, nt = t->theta.n, n = nv * na * nt;
    for (size_t r = 0; r < csv->n_rows; r++) {
        const double *row = csv->data + r * 5;
        size_t idx = (node_index(&t->v, row[0]) * na + node_index(&t->a, row[1])) * nt + node_index(&t->theta, row[2]);
        if (row_line[idx])
            return wf_err(err, WF_EINPUT,
                          "%s:%d: duplicate row for Velocity=%s, Acceleration=%s, Road Grade=%s (first on line %d)",
                          path, csv->line[r], WF_NUM(row[0]), WF_NUM(row[1]), WF_NUM(row[2]), row_line[idx]);
        row_line[idx] = csv->line[r];
        t->fuel_gps[idx] = row[3];
        t->infeasible[idx] = (uint8_t)row[4];
    }
    for (size_t idx = 0; idx < n; idx++)
        if (!row_line[idx]) {
            size_t it = idx % nt, ia = (idx / nt) % na, iv = idx / (nt * na);
            return wf_err(err, WF_EINPUT,
                          "%s: not a regular grid: no row for Velocity=%s, Acceleration=%s, Road Grade=%s (the "
                          "distinct values make %zu speeds x %zu accelerations x %zu grades = %zu points, the file "
                          "has %zu rows: rows are missing, or the points do not lie on one grid)",
                          path, WF_NUM(t->v.x[iv]), WF_NUM(t->a.x[ia]), WF_NUM(t->theta.x[it]), nv, na, nt, n,
                          csv->n_rows);
        }
    return 0;
}

int wf_table_read_csv(const char *path, WfTable **out, WfError *err)
{
    *out = NULL;
    if (!strcmp(path, "-"))
        return wf_err(err, WF_EINPUT, "a table must be read from a file (its checksum is recorded), not '-'");
    WfCsv csv;
    int rc = wf_csv_read(path, 5, column_names, &csv, err);
    if (rc) return rc;
    WfTable *t = calloc(1, sizeof *t);
    int *row_line = NULL;
    rc = t ? csv_grid(t, &csv, path, err) : wf_err(err, WF_ESYS, "out of memory reading %s", path);
    if (!rc && !(row_line = calloc(t->v.n * t->a.n * t->theta.n, sizeof *row_line)))
        rc = wf_err(err, WF_ESYS, "out of memory reading %s", path);
    if (!rc) rc = csv_values(t, &csv, path, row_line, err);
    if (!rc) {
        derive_a_max(t);
        snprintf(t->source, sizeof t->source, "%s", path);
        t->data_fnv1a64 = wf_table_checksum(t);
        rc = file_fnv(path, &t->source_fnv1a64, err);
    }
    free(row_line);
    wf_csv_free(&csv);
    if (rc) wf_table_destroy(&t);
    *out = t;
    return rc;
}

/* The axes and values of wf_table_from_grid into t (allocated and zeroed); each error returned where it is found. */
static int grid_fill(WfTable *t, const size_t *sizes, const double *const *in, const double *fuel,
                     const uint8_t *infeasible, const char *source, WfError *err)
{
    static const char *const what[3] = {"velocity", "acceleration", "grade"};
    WfTableAxis *axes[3] = {&t->v, &t->a, &t->theta};
    int rc;
    for (int c = 0; c < 3; c++) {
        size_t n = sizes[c];
        if (n == 0) return wf_err(err, WF_EINPUT, "%s: the %s axis is empty", source, what[c]);
        for (size_t k = 0; k < n; k++)
            if (!isfinite(in[c][k]) || (k && !(in[c][k] > in[c][k - 1])))
                return wf_err(err, WF_EINPUT, "%s: %s node %zu (%s) is not finite or not above the one before",
                              source, what[c], k, WF_NUM(in[c][k]));
        double *nodes = malloc((n + 1) * sizeof *nodes);
        if (!nodes) return wf_err(err, WF_ESYS, "out of memory");
        memcpy(nodes, in[c], n * sizeof *nodes);
        if ((rc = axis_init(axes[c], nodes, n, source, what[c], err))) return rc;
    }
    if ((rc = alloc_values(t, err))) return rc;
    for (size_t i = 0; i < sizes[0] * sizes[1] * sizes[2]; i++) {
        if (!isfinite(fuel[i]) || infeasible[i] > 1)
            return wf_err(err, WF_EINPUT, "%s: value %zu: fuel must be finite and infeasible 0 or 1", source, i);
        t->fuel_gps[i] = fuel[i];
        t->infeasible[i] = infeasible[i];
    }
    derive_a_max(t);
    snprintf(t->source, sizeof t->source, "%s", source);
    t->data_fnv1a64 = wf_table_checksum(t); /* source_fnv1a64 stays 0: no source file */
    return 0;
}

int wf_table_from_grid(size_t nv, const double *v, size_t na, const double *a, size_t nt, const double *theta,
                       const double *fuel, const uint8_t *infeasible, const char *source, WfTable **out, WfError *err)
{
    const size_t sizes[3] = {nv, na, nt};
    const double *const in[3] = {v, a, theta};
    WfTable *t = calloc(1, sizeof *t);
    int rc = t ? grid_fill(t, sizes, in, fuel, infeasible, source, err) : wf_err(err, WF_ESYS, "out of memory");
    if (rc) wf_table_destroy(&t);
    *out = t;
    return rc;
}

/* ---------------------------------------------------------------------------------------------------------
 * HDF5 form */

int wf_table_write_h5(const WfTable *t, const char *path, int force, WfError *err)
{
    WfH5File *f = NULL;
    int rc = wf_h5_create(path, force, &f, err);
    if (rc) return rc;
    size_t nv = t->v.n, na = t->a.n, nt = t->theta.n;
    char hex_src[32], hex_data[32], created[128];
    snprintf(hex_src, sizeof hex_src, "%016llx", (unsigned long long)t->source_fnv1a64);
    snprintf(hex_data, sizeof hex_data, "%016llx", (unsigned long long)t->data_fnv1a64);
    snprintf(created, sizeof created, "wavefuel %s (%s)", WF_VERSION, wf_git_hash());
    hsize_t dv = nv, da = na, dt = nt, dvals[2] = {nv * na, nt}, damax[2] = {nv, nt};
    hid_t root = f->fid;
    if ((rc = wf_h5_attr_str(root, "format", TABLE_FORMAT, err)) ||
        (rc = wf_h5_attr_i64(root, "format_version", TABLE_FORMAT_VERSION, err)) ||
        (rc = wf_h5_attr_str(root, "source", t->source, err)) ||
        (rc = wf_h5_attr_str(root, "source_fnv1a64", hex_src, err)) ||
        (rc = wf_h5_attr_str(root, "data_fnv1a64", hex_data, err)) ||
        (rc = wf_h5_attr_str(root, "created_by", created, err)) ||
        (rc = wf_h5_attr_str(root, "layout",
                             "fuel_gps and infeasible are (n_velocity * n_acceleration, n_grade): reshape to "
                             "(n_velocity, n_acceleration, n_grade); axes ascending", err)) ||
        (rc = wf_h5_write_f64(root, "velocity_mps", 1, &dv, t->v.x, "m/s", "speed nodes, ascending", err)) ||
        (rc = wf_h5_write_f64(root, "acceleration_mps2", 1, &da, t->a.x, "m/s^2",
                              "acceleration nodes, ascending", err)) ||
        (rc = wf_h5_write_f64(root, "grade_rad", 1, &dt, t->theta.x, "rad", "road grade nodes, ascending",
                              err)) ||
        (rc = wf_h5_write_f64(root, "fuel_gps", 2, dvals, t->fuel_gps, "g/s", "fuel rate at each grid node", err)) ||
        (rc = wf_h5_write_u8(root, "infeasible", 2, dvals, t->infeasible, "1",
                             "1 where the vehicle cannot reach that acceleration at that speed and grade", err)) ||
        (rc = wf_h5_write_f64(root, "a_max_mps2", 2, damax, t->a_max_mps2, "m/s^2",
                              "largest feasible grid acceleration per (velocity, grade) column; derived, "
                              "recomputed on load", err))) {
        wf_h5_abandon(&f, 1);
        return rc;
    }
    return wf_h5_commit(&f, err);
}

int wf_table_import(const char *csv_path, const char *h5_path, int force, WfError *err)
{
    WfTable *t = NULL;
    int rc = wf_table_read_csv(csv_path, &t, err);
    if (!rc) rc = wf_table_write_h5(t, h5_path, force, err);
    wf_table_destroy(&t);
    return rc;
}

/* Reading: the HDF5 file was written by wf_table_write_h5; every call is checked, and a file of another
 * shape is an input error naming the object. */
static int read_str_attr(hid_t obj, const char *path, const char *name, char *out, size_t len, WfError *err)
{
    if (H5Aexists(obj, name) <= 0)
        return wf_err(err, WF_EINPUT, "%s: missing attribute '%s': not a wavefuel table", path, name);
    /* This check before the shared reader keeps the table's own message for a variable-length or other type. */
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT), ty = a >= 0 ? H5Aget_type(a) : H5I_INVALID_HID;
    int fixed = ty >= 0 && H5Tget_class(ty) == H5T_STRING && H5Tis_variable_str(ty) == 0;
    if (ty >= 0) H5Tclose(ty);
    if (a >= 0) H5Aclose(a);
    if (!fixed) return wf_err(err, WF_EINPUT, "%s: attribute '%s' is not a fixed-length string", path, name);
    return wf_h5_read_attr_str(obj, path, name, out, len, err);
}

/* Reads dataset `name` of rank `rank`; dims[] receives its shape; *out (malloc'd) its values as mem_type. */
static int read_dataset(hid_t fid, const char *path, const char *name, int rank, hid_t mem_type, size_t elem,
                        hsize_t *dims, void **out, WfError *err)
{
    *out = NULL;
    if (H5Lexists(fid, name, H5P_DEFAULT) <= 0)
        return wf_err(err, WF_EINPUT, "%s: missing dataset '%s': not a wavefuel table", path, name);
    int got = -1;
    if (H5LTget_dataset_ndims(fid, name, &got) < 0)
        return wf_err(err, WF_ESYS, "%s: HDF5: open dataset '%s' failed", path, name);
    if (got != rank || H5LTget_dataset_info(fid, name, dims, NULL, NULL) < 0)
        return wf_err(err, WF_EINPUT, "%s: dataset '%s' should have rank %d", path, name, rank);
    size_t total = 1;
    for (int i = 0; i < rank; i++) total *= (size_t)dims[i];
    /* One spare element: callers of the axes use it as padding. */
    void *buf = malloc((total + 1) * elem);
    if (!buf) return wf_err(err, WF_ESYS, "out of memory reading %s", path);
    if (total && H5LTread_dataset(fid, name, mem_type, buf) < 0) {
        free(buf);
        return wf_err(err, WF_ESYS, "%s: HDF5: read dataset '%s' failed (damaged file?)", path, name);
    }
    *out = buf;
    return 0;
}

/* The contents of a table file into t (allocated and zeroed); each error returned where it is found. */
static int h5_table(hid_t fid, const char *path, WfTable *t, WfError *err)
{
    char fmt[128], hex_src[64], hex_data[64];
    int rc = read_str_attr(fid, path, "format", fmt, sizeof fmt, err);
    if (rc) return rc;
    if (strcmp(fmt, TABLE_FORMAT) != 0)
        return wf_err(err, WF_EINPUT, "%s: format is '%s', expected '%s'", path, fmt, TABLE_FORMAT);
    long long version = -1;
    if (H5Aexists(fid, "format_version") <= 0 || H5LTget_attribute_long_long(fid, ".", "format_version", &version) < 0)
        version = -1;
    if (version != TABLE_FORMAT_VERSION)
        return wf_err(err, WF_EINPUT, "%s: format_version %lld, this wavefuel reads version %d", path, version,
                      TABLE_FORMAT_VERSION);
    if ((rc = read_str_attr(fid, path, "source", t->source, sizeof t->source, err)) ||
        (rc = read_str_attr(fid, path, "source_fnv1a64", hex_src, sizeof hex_src, err)) ||
        (rc = read_str_attr(fid, path, "data_fnv1a64", hex_data, sizeof hex_data, err)))
        return rc;
    t->source_fnv1a64 = strtoull(hex_src, NULL, 16);
    t->data_fnv1a64 = strtoull(hex_data, NULL, 16);
    static const char *const axis_sets[] = {"velocity_mps", "acceleration_mps2", "grade_rad"};
    WfTableAxis *axes[3] = {&t->v, &t->a, &t->theta};
    for (int c = 0; c < 3; c++) {
        hsize_t dims[1];
        void *buf;
        if ((rc = read_dataset(fid, path, axis_sets[c], 1, H5T_NATIVE_DOUBLE, sizeof(double), dims, &buf, err)))
            return rc;
        const double *x = buf;
        size_t n = (size_t)dims[0];
        for (size_t k = 0; k < n; k++)
            if (!isfinite(x[k]) || (k && !(x[k] > x[k - 1]))) n = 0;
        if (n == 0) {
            free(buf);
            return wf_err(err, WF_EINPUT, "%s: %s must be finite, ascending and non-empty", path, axis_sets[c]);
        }
        /* buf is the axis's from here, even when axis_init fails */
        if ((rc = axis_init(axes[c], buf, n, path, axis_sets[c], err))) return rc;
    }
    size_t nv = t->v.n, na = t->a.n, nt = t->theta.n, n = nv * na * nt;
    hsize_t dims[2];
    void *buf;
    if ((rc = read_dataset(fid, path, "fuel_gps", 2, H5T_NATIVE_DOUBLE, sizeof(double), dims, &buf, err))) return rc;
    t->fuel_gps = buf;
    if (dims[0] != nv * na || dims[1] != nt)
        return wf_err(err, WF_EINPUT, "%s: fuel_gps is %llu x %llu, the grid needs %zu x %zu", path,
                      (unsigned long long)dims[0], (unsigned long long)dims[1], nv * na, nt);
    if ((rc = read_dataset(fid, path, "infeasible", 2, H5T_NATIVE_UINT8, 1, dims, &buf, err))) return rc;
    t->infeasible = buf;
    if (dims[0] != nv * na || dims[1] != nt) return wf_err(err, WF_EINPUT, "%s: infeasible has the wrong shape", path);
    if (!(t->a_max_mps2 = malloc(nv * nt * sizeof *t->a_max_mps2)))
        return wf_err(err, WF_ESYS, "out of memory loading %s", path);
    for (size_t i = 0; i < n; i++)
        if (t->infeasible[i] > 1 || !isfinite(t->fuel_gps[i]))
            return wf_err(err, WF_EINPUT, "%s: value %zu of fuel_gps / infeasible is not finite / 0 or 1", path, i);
    uint64_t sum = wf_table_checksum(t);
    if (sum != t->data_fnv1a64)
        return wf_err(err, WF_EINPUT, "%s: checksum mismatch (stored %s, computed %016llx): the file was damaged or "
                                      "edited; import the CSV again",
                      path, hex_data, (unsigned long long)sum);
    derive_a_max(t);
    return 0;
}

int wf_table_load_h5(const char *path, WfTable **out, WfError *err)
{
    *out = NULL;
    if (access(path, R_OK) != 0) return wf_err(err, WF_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    wf_h5_library_init();
    hid_t fid = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (fid < 0)
        return wf_err(err, WF_EINPUT, "%s: not an HDF5 file (import a CSV table first: wavefuel table import)", path);
    WfTable *t = calloc(1, sizeof *t);
    int rc = t ? h5_table(fid, path, t, err) : wf_err(err, WF_ESYS, "out of memory");
    H5Fclose(fid);
    if (rc) wf_table_destroy(&t);
    *out = t;
    return rc;
}

/* ---------------------------------------------------------------------------------------------------------
 * Evaluation. Every coordinate is clamped to the grid before the cell is located, so the kernels never read
 * outside the arrays whatever the input (NaN included: it reads the first node). The helpers are forced
 * inline: as calls, with the project and flag switches left as run-time branches, the array loop is several
 * times slower. Comparisons replace fmin/fmax, which GCC emits as library calls under strict IEEE rules. */
#if defined(__GNUC__)
#define TAB_INLINE __attribute__((always_inline)) inline
#else
#define TAB_INLINE inline
#endif

/* Cell k and weight t in [0, 1] of coordinate x: nodes x[k] <= x <= x[k + 1]. The bucket gives a cell at most
 * two below the right one (buckets are no wider than the narrowest cell, and hold one cell less for
 * rounding), so two branch-free steps finish; the loop only runs when the bucket count was capped. At a node
 * t is exactly 0 (or 1 at the last node), so grid values come back exactly. */
static TAB_INLINE size_t locate(const WfTableAxis *ax, double x, double *t)
{
    double xc = !(x >= ax->lo) ? ax->lo : (x > ax->hi ? ax->hi : x);
    size_t b = (size_t)(long)((xc - ax->lo) * ax->bucket_scale);
    size_t k = ax->bucket[b < ax->n_bucket ? b : ax->n_bucket - 1];
    k += (size_t)((k < ax->kmax) & (xc >= ax->x[k + 1]));
    k += (size_t)((k < ax->kmax) & (xc >= ax->x[k + 1]));
    while (k < ax->kmax && xc >= ax->x[k + 1]) k++;
    double w = (xc - ax->x[k]) * ax->inv_w[k];
    *t = xc >= ax->x[k + 1] ? 1.0 : w;
    return k;
}

/* (1 - t) x0 + t x1: exact at t = 0 and t = 1 (unlike x0 + t (x1 - x0)). */
static TAB_INLINE double lerp(double x0, double x1, double t) { return (1.0 - t) * x0 + t * x1; }

static TAB_INLINE double trilinear(const double *F, size_t base, size_t sv, size_t sa, size_t st, double tv,
                                   double ta, double tt)
{
    double c00 = lerp(F[base], F[base + st], tt);
    double c01 = lerp(F[base + sa], F[base + sa + st], tt);
    double c10 = lerp(F[base + sv], F[base + sv + st], tt);
    double c11 = lerp(F[base + sv + sa], F[base + sv + sa + st], tt);
    return lerp(lerp(c00, c01, ta), lerp(c10, c11, ta), tv);
}

/* The same interpolation over the 0/1 Infeasible bytes (1 byte per node keeps them in cache). */
static TAB_INLINE double trilinear_u8(const uint8_t *I, size_t base, size_t sv, size_t sa, size_t st,
                                      double tv, double ta, double tt)
{
    double c00 = lerp(I[base], I[base + st], tt);
    double c01 = lerp(I[base + sa], I[base + sa + st], tt);
    double c10 = lerp(I[base + sv], I[base + sv + st], tt);
    double c11 = lerp(I[base + sv + sa], I[base + sv + sa + st], tt);
    return lerp(lerp(c00, c01, ta), lerp(c10, c11, ta), tv);
}

static TAB_INLINE int inside(const WfTableAxis *ax, double x) { return x >= ax->lo && x <= ax->hi; }

static TAB_INLINE double amax_at(const WfTable *t, size_t iv, double tv, size_t it, double tt)
{
    size_t nt = t->theta.n, b = iv * nt + it, sv = t->v.up * nt, st = t->theta.up;
    const double *M = t->a_max_mps2;
    return lerp(lerp(M[b], M[b + st], tt), lerp(M[b + sv], M[b + sv + st], tt), tv);
}

/* One evaluation, inlined into each loop below with project / want_flag as constants there. want_flag = 0
 * skips the Infeasible interpolation. */
static TAB_INLINE double eval1(const WfTable *t, double v, double a, double th, int project, int want_flag,
                               uint8_t *flag, int *outside)
{
    size_t na = t->a.n, nt = t->theta.n;
    size_t sv = t->v.up * na * nt, sa = t->a.up * nt, st = t->theta.up;
    double vv = v > 0.0 ? v : 0.0, tv, tt, ta; /* NaN reads as 0, like fmax */
    size_t iv = locate(&t->v, vv, &tv), it = locate(&t->theta, th, &tt);
    /* The flag reads the Infeasible column at the original acceleration, before any projection; the fuel
     * reads the same cell unless the projection moves a (NaN a reads as a_max, like fmin). */
    size_t ia = locate(&t->a, a, &ta);
    if (want_flag) {
        double inf = trilinear_u8(t->infeasible, (iv * na + ia) * nt + it, sv, sa, st, tv, ta, tt);
        *flag = (uint8_t)(v < 0.0 ? WF_NEGATIVE_SPEED : (inf != 0.0 ? WF_INFEASIBLE_ACCEL : WF_FEASIBLE));
    }
    double au = a;
    if (project) {
        double am = amax_at(t, iv, tv, it, tt);
        if (!(a <= am)) {
            au = am;
            ia = locate(&t->a, au, &ta);
        }
    }
    if (outside) *outside = !(inside(&t->v, vv) && inside(&t->a, au) && inside(&t->theta, th));
    return trilinear(t->fuel_gps, (iv * na + ia) * nt + it, sv, sa, st, tv, ta, tt);
}

double wf_table_fuel(const WfTable *t, double v, double a, double th, int project, uint8_t *flag, int *outside)
{
    uint8_t fl = 0;
    double f = eval1(t, v, a, th, project, 1, &fl, outside);
    if (flag) *flag = fl;
    return f;
}

double wf_table_a_max(const WfTable *t, double v, double th)
{
    double tv, tt;
    size_t iv = locate(&t->v, v > 0.0 ? v : 0.0, &tv), it = locate(&t->theta, th, &tt);
    return amax_at(t, iv, tv, it, tt);
}

void wf_table_eval(const WfTable *t, size_t n, const double *restrict v, const double *restrict a,
                   const double *restrict th, int project, double *restrict fuel, uint8_t *restrict flag)
{
    /* Four loops so that each inlined body has its switches as constants. */
    if (flag && project)
        for (size_t i = 0; i < n; i++) fuel[i] = eval1(t, v[i], a[i], th[i], 1, 1, &flag[i], NULL);
    else if (flag)
        for (size_t i = 0; i < n; i++) fuel[i] = eval1(t, v[i], a[i], th[i], 0, 1, &flag[i], NULL);
    else if (project)
        for (size_t i = 0; i < n; i++) fuel[i] = eval1(t, v[i], a[i], th[i], 1, 0, NULL, NULL);
    else
        for (size_t i = 0; i < n; i++) fuel[i] = eval1(t, v[i], a[i], th[i], 0, 0, NULL, NULL);
}

size_t wf_table_n_outside(const WfTable *t, size_t n, const double *v, const double *a, const double *th,
                          int project)
{
    size_t count = 0;
    for (size_t i = 0; i < n; i++) {
        int outside; /* as the evaluation finds it: the one form of the clamping and projection rule */
        eval1(t, v[i], a[i], th[i], project, 0, NULL, &outside);
        count += (size_t)outside;
    }
    return count;
}

/* ---------------------------------------------------------------------------------------------------------
 * The energy-model family */

static void tab_eval(const void *params, size_t n, const double *v, const double *a, const double *th, int project,
                     double *fuel, uint8_t *flag)
{
    wf_table_eval(((const WfTabulatedParams *)params)->table, n, v, a, th, project, fuel, flag);
}

static double tab_a_max(const void *params, double v, double th)
{
    return wf_table_a_max(((const WfTabulatedParams *)params)->table, v, th);
}

static size_t tab_n_outside(const void *params, size_t n, const double *v, const double *a, const double *th,
                            int project)
{
    return wf_table_n_outside(((const WfTabulatedParams *)params)->table, n, v, a, th, project);
}

/* `table: PATH` relative to the class file's directory (absolute paths kept). */
static int resolve_table(const char *class_path, const char *rel, char *out, size_t len, WfError *err)
{
    if (wf_path_relative_to(class_path, rel, out, len))
        return wf_err(err, WF_EINPUT, "%s: table path too long: %s", class_path, rel);
    return 0;
}

static int load_for_class(WfTabulatedParams *p, const char *class_path, const char *path, WfError *err)
{
    size_t len = strlen(path);
    if (len > 4 && !strcmp(path + len - 4, ".csv"))
        return wf_err(err, WF_EINPUT,
                      "%s: table: %s is a CSV table; convert it once with `wavefuel table import %s -o TABLE.h5` and "
                      "name the .h5 file",
                      class_path, path, path);
    int rc = wf_table_load_h5(path, &p->table, err);
    if (rc) wf_err_prefix(err, "%s: table: ", class_path);
    return rc;
}

static int tab_load(void *params, const char *class_path, struct WfCfgNode *class_map, WfError *err)
{
    const char *rel = NULL;
    int rc = wf_cfg_string(class_map, "table", &rel, err);
    if (rc) return rc;
    char path[4096];
    if ((rc = resolve_table(class_path, rel, path, sizeof path, err))) return rc;
    return load_for_class(params, class_path, path, err);
}

static void tab_release(void *params)
{
    if (params) wf_table_destroy(&((WfTabulatedParams *)params)->table);
}

const WfEnergyModel wf_energy_tabulated = {
    .name = "tabulated",
    .param_size = sizeof(WfTabulatedParams),
    .eval = tab_eval,
    .a_max = tab_a_max,
    .load = tab_load,
    .release = tab_release,
    .n_outside = tab_n_outside,
    .project_default = 1,
};

int wf_tabulated_class_table(const WfVehicleClass *vc, char *path, size_t len, WfError *err)
{
    path[0] = '\0';
    if (!vc->path[0]) return 0;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_file(vc->path, &cfg, err);
    if (rc) return rc;
    WfCfgNode *node = wf_cfg_child(cfg->root, "table");
    if (node && (node->kind != WF_CFG_SCALAR || !node->value[0])) {
        char where[1200];
        rc = wf_err(err, WF_EINPUT, "%s: table: expected a file path", wf_cfg_where(node, where, sizeof where));
    } else if (node) {
        rc = resolve_table(vc->path, node->value, path, len, err);
    }
    wf_cfg_destroy(&cfg);
    return rc;
}

int wf_tabulated_class(const WfVehicleClass *base, const char *table_path, WfVehicleClass *out, WfError *err)
{
    *out = *base;
    out->model = &wf_energy_tabulated;
    out->params = calloc(1, sizeof(WfTabulatedParams));
    if (!out->params) return wf_err(err, WF_ESYS, "out of memory");
    int rc = load_for_class(out->params, base->path[0] ? base->path : base->name, table_path, err);
    if (rc) wf_vehicle_free(out);
    return rc;
}
