/* File kinds (filekind.h): each wavefuel HDF5 file is recognised by what its writer always puts in it (h5out.c and
 * h5corridor.c /meta/completed, h5sweep.c /meta/kind, cycle_out.c the root's command and layout, tabulated.c the
 * root's format, h5ckpt.c the root's kind). */
#include "wavefuel/filekind.h"

#include <stdint.h>
#include <sys/stat.h>

#include "io/h5util.h"

static int has_attr(hid_t f, const char *name) { return H5Aexists(f, name) > 0; }

static int has_link(hid_t f, const char *group, const char *name)
{
    return H5Lexists(f, group, H5P_DEFAULT) > 0 && (!name || H5Lexists(f, name, H5P_DEFAULT) > 0);
}

/* /meta/completed as an integer, -1 when it cannot be read. */
static int read_completed(hid_t f)
{
    int64_t v = -1;
    if (H5LTread_dataset(f, "meta/completed", H5T_NATIVE_INT64, &v) < 0) v = -1;
    return v == 0 || v == 1 ? (int)v : -1;
}

WfFileKind wf_file_kind(const char *path, int *completed)
{
    if (completed) *completed = -1;
    struct stat st;
    if (stat(path, &st) != 0) return WF_FILE_MISSING;
    if (S_ISDIR(st.st_mode)) return WF_FILE_DIRECTORY;
    wf_h5_library_init();
    if (!S_ISREG(st.st_mode) || H5Fis_hdf5(path) <= 0) return WF_FILE_NOT_HDF5;
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return WF_FILE_NOT_HDF5;
    WfFileKind k = WF_FILE_HDF5_OTHER;
    if (has_attr(f, "kind") && has_attr(f, "scenario_path")) k = WF_FILE_CHECKPOINT;
    else if (has_attr(f, "format")) k = WF_FILE_TABLE;
    else if (has_link(f, "meta", "meta/kind") && has_link(f, "runs", NULL)) k = WF_FILE_SWEEP;
    else if (has_link(f, "meta", "meta/completed") && has_link(f, "summary", NULL)) k = WF_FILE_RESULT;
    else if (has_attr(f, "command") && has_attr(f, "layout")) k = WF_FILE_CYCLE;
    if (k == WF_FILE_RESULT && completed) *completed = read_completed(f);
    H5Fclose(f);
    return k;
}

const char *wf_file_kind_text(WfFileKind kind)
{
    static const char *const text[] = {
        [WF_FILE_MISSING] = "a missing file",
        [WF_FILE_DIRECTORY] = "a directory",
        [WF_FILE_NOT_HDF5] = "not an HDF5 file (or a damaged one)",
        [WF_FILE_HDF5_OTHER] = "an HDF5 file that wavefuel did not write",
        [WF_FILE_RESULT] = "a wavefuel result",
        [WF_FILE_SWEEP] = "a wavefuel sweep table",
        [WF_FILE_CYCLE] = "a wavefuel drive-cycle result",
        [WF_FILE_TABLE] = "a wavefuel energy table",
        [WF_FILE_CHECKPOINT] = "a wavefuel checkpoint",
    };
    return kind >= 0 && kind <= WF_FILE_CHECKPOINT ? text[kind] : "an unknown kind of file";
}
