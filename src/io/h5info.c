/* `wavefuel info`: a result file's /meta, /summary (in the order of the summary table) and /classes, read back with
 * their units. Works on rings, corridors and .partial files alike. */
#include <stdio.h>
#include <string.h>

#include "io/h5summary.h"
#include "io/h5util.h"
#include "wavefuel/filekind.h"
#include "wavefuel/h5out.h"

typedef struct InfoCtx {
    FILE       *out;
    hid_t       grp;
    int         scalars_only; /* 1: single values only (wf_h5_info_scalars) */
    const char *header;       /* printed before the first value, then cleared (NULL: none) */
} InfoCtx;

/* Prints one scalar or small 1-D numeric dataset with its units. */
static herr_t print_dataset(hid_t g, const char *name, const H5L_info_t *info, void *vctx)
{
    (void)info;
    InfoCtx *c = vctx;
    hid_t d = H5Dopen2(g, name, H5P_DEFAULT);
    if (d < 0) return 0;
    hid_t sp = H5Dget_space(d), t = H5Dget_type(d);
    char units[64];
    WfError ignored = {0}; /* a dataset without units prints none */
    if (wf_h5_read_attr_str(d, "", "units", units, sizeof units, &ignored)) units[0] = '\0';
    hssize_t n = H5Sget_simple_extent_npoints(sp);
    if (c->header && (n == 1 || !c->scalars_only)) {
        fprintf(c->out, "%s:\n", c->header);
        c->header = NULL;
    }
    if (c->scalars_only && n != 1) {
        /* arrays (a cycle's samples, a sweep's columns) are for h5py, not for this listing */
    } else if (H5Tget_class(t) == H5T_STRING && n == 1) {
        char *s = NULL;
        hid_t mt = wf_h5_text_type(H5T_VARIABLE);
        if (H5Tis_variable_str(t) > 0 && H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, &s) >= 0 && s) {
            if (!strchr(s, '\n')) fprintf(c->out, "  %-24s %s\n", name, s);
            H5free_memory(s);
        } else if (H5Tis_variable_str(t) == 0 && H5Tget_size(t) <= 4096) {
            /* Fixed-length text (/meta/reason, rewritten in place): read with a terminating NUL added. */
            char fixed[4097];
            size_t sz = H5Tget_size(t);
            hid_t ft = wf_h5_text_type(sz + 1);
            if (ft >= 0 && H5Dread(d, ft, H5S_ALL, H5S_ALL, H5P_DEFAULT, fixed) >= 0) {
                fixed[sz] = '\0';
                if (!strchr(fixed, '\n')) fprintf(c->out, "  %-24s %s\n", name, fixed);
            }
            if (ft >= 0) H5Tclose(ft);
        }
        if (mt >= 0) H5Tclose(mt);
    } else if ((H5Tget_class(t) == H5T_FLOAT || H5Tget_class(t) == H5T_INTEGER) && n >= 1 && n <= 16) {
        double v[16];
        if (H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0) {
            fprintf(c->out, "  %-24s", name);
            for (hssize_t i = 0; i < n; i++) fprintf(c->out, " %.6g", v[i]);
            fprintf(c->out, " %s\n", strcmp(units, "1") ? units : "");
        }
    }
    H5Tclose(t);
    H5Sclose(sp);
    H5Dclose(d);
    return 0;
}

static void print_summary_field(const char *name, void *vctx)
{
    InfoCtx *c = vctx;
    if (H5Lexists(c->grp, name, H5P_DEFAULT) > 0) print_dataset(c->grp, name, NULL, c);
}

int wf_h5out_info(const char *path, FILE *out, WfError *err)
{
    wf_h5_library_init();
    if (H5Fis_hdf5(path) <= 0) return wf_err(err, WF_EINPUT, "%s: not a readable HDF5 file", path);
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return wf_err(err, WF_EINPUT, "%s: cannot open as HDF5", path);
    if (H5Lexists(f, "meta", H5P_DEFAULT) <= 0 || H5Lexists(f, "summary", H5P_DEFAULT) <= 0) {
        H5Fclose(f);
        return wf_err(err, WF_EINPUT, "%s: not a wavefuel result (no /meta and /summary)", path);
    }
    const char *groups[] = {"meta", "summary", "classes"};
    const char *titles[] = {"run", "summary (statistics window)", "classes"};
    for (int k = 0; k < 3; k++) {
        hid_t g = H5Gopen2(f, groups[k], H5P_DEFAULT);
        if (g < 0) continue;
        fprintf(out, "%s:\n", titles[k]);
        InfoCtx c = {.out = out, .grp = g};
        /* The summary in the order of its table (fleet values, then per class); the other groups by name. */
        if (!strcmp(groups[k], "summary")) wf_h5_summary_each(print_summary_field, &c);
        else H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, print_dataset, &c);
        H5Gclose(g);
    }
    /* As `wavefuel run` warns: results that include repaired collisions say so. */
    long long repaired = 0;
    if (H5Lexists(f, "summary/overlaps", H5P_DEFAULT) > 0 &&
        H5LTread_dataset(f, "summary/overlaps", H5T_NATIVE_LLONG, &repaired) >= 0)
        wf_summary_warn_repairs(out, repaired);
    H5Fclose(f);
    return 0;
}

/* Each group: its single values under a header naming the group. */
static herr_t visit_group(hid_t root, const char *name, const H5O_info_t *info, void *vctx)
{
    InfoCtx *c = vctx;
    if (info->type != H5O_TYPE_GROUP) return 0;
    hid_t g = H5Gopen2(root, name, H5P_DEFAULT);
    if (g < 0) return 0;
    InfoCtx gc = {.out = c->out, .grp = g, .scalars_only = 1, .header = name};
    H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, print_dataset, &gc);
    H5Gclose(g);
    return 0;
}

int wf_h5_info_scalars(const char *path, FILE *out, WfError *err)
{
    wf_h5_library_init();
    hid_t f = H5Fis_hdf5(path) > 0 ? H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT) : H5I_INVALID_HID;
    if (f < 0) return wf_err(err, WF_EINPUT, "%s: cannot open as HDF5", path);
    InfoCtx c = {.out = out, .scalars_only = 1};
    H5Ovisit(f, H5_INDEX_NAME, H5_ITER_INC, visit_group, &c);
    H5Fclose(f);
    return 0;
}
