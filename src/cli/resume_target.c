/* `wavefuel run --resume ARG`: ARG may name the result X.h5, its partial file X.h5.partial or its checkpoint
 * X.h5.ckpt; and a file that is none of those is called what it is (it used to be "complete: nothing to resume"
 * for garbage and a finished run alike). */
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"
#include "wavefuel/filekind.h"

static const char *const suffixes[] = {".partial", ".ckpt"};

/* The kind of path as a message fragment: "is not an HDF5 file", "is a wavefuel sweep table". */
static int not_resumable(const char *arg, const char *path, WfFileKind k, WfError *err)
{
    return wf_err(err, WF_EINPUT, "--resume %s: %s is %s, not a wavefuel partial result or checkpoint", arg, path,
                  wf_file_kind_text(k));
}

int wf_cli_resume_target(const char *arg, char *result, size_t len, WfError *err)
{
    size_t n = strlen(arg);
    for (size_t s = 0; s < sizeof suffixes / sizeof suffixes[0]; s++) {
        size_t k = strlen(suffixes[s]);
        if (n > k && !strcmp(arg + n - k, suffixes[s])) n -= k;
    }
    char partial[1200], ckpt[1200];
    if (n + 1 > len || snprintf(partial, sizeof partial, "%.*s.partial", (int)n, arg) >= (int)sizeof partial ||
        snprintf(ckpt, sizeof ckpt, "%.*s.ckpt", (int)n, arg) >= (int)sizeof ckpt)
        return wf_err(err, WF_EINPUT, "--resume %s: path too long", arg);
    snprintf(result, len, "%.*s", (int)n, arg);
    /* The file given must be one of the three kinds whatever the others are. */
    int completed = -1;
    WfFileKind given = wf_file_kind(arg, &completed);
    if (given == WF_FILE_MISSING && wf_file_kind(result, NULL) == WF_FILE_MISSING &&
        wf_file_kind(partial, NULL) == WF_FILE_MISSING && wf_file_kind(ckpt, NULL) == WF_FILE_MISSING)
        return wf_err(err, WF_EINPUT, "--resume %s: no such file, and no checkpoint %s or partial result %s", arg, ckpt,
                      partial);
    if (given != WF_FILE_MISSING && given != WF_FILE_RESULT && given != WF_FILE_CHECKPOINT)
        return not_resumable(arg, arg, given, err);
    WfFileKind ck = wf_file_kind(ckpt, NULL);
    if (ck != WF_FILE_MISSING && ck != WF_FILE_CHECKPOINT)
        return wf_err(err, WF_EINPUT, "--resume %s: %s is not a readable checkpoint: it is %s", arg, ckpt,
                      wf_file_kind_text(ck));
    WfFileKind res = wf_file_kind(result, &completed);
    if (res == WF_FILE_RESULT && completed == 1)
        return wf_err(err, WF_EINPUT, "--resume %s: %s is complete: nothing to resume", arg, result);
    if (res != WF_FILE_MISSING && res != WF_FILE_RESULT) return not_resumable(arg, result, res, err);
    WfFileKind part = wf_file_kind(partial, &completed);
    if (part != WF_FILE_MISSING && part != WF_FILE_RESULT) return not_resumable(arg, partial, part, err);
    if (ck == WF_FILE_MISSING)
        return wf_err(err, WF_EINPUT, "--resume %s: no checkpoint %s: %s cannot be continued (runs leave a checkpoint "
                      "when interrupted, or with --checkpoint-every)", arg, ckpt,
                      part == WF_FILE_RESULT ? partial : "the run");
    return 0;
}
