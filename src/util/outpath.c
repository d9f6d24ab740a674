/* Output paths checked against the inputs of the same command (outpath.h): `run s.yaml -o s.yaml --force` used to
 * replace the scenario with HDF5, and `-o DIR` failed only after the whole run, leaving DIR.partial. */
#include "util/outpath.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

/* Suffixes of the files a writer creates beside its result: the file itself, the partial file written while
 * the command runs, the checkpoint of `run`. */
static const char *const written[] = {"", ".partial", ".ckpt"};

int wf_output_check(const char *what, const char *out, const char *const *inputs, size_t n_inputs, WfError *err)
{
    struct stat so, si;
    if (stat(out, &so) == 0 && S_ISDIR(so.st_mode))
        return wf_err(err, WF_EINPUT, "%s %s: is a directory; give a file name (%s/NAME.h5)", what, out, out);
    for (size_t w = 0; w < sizeof written / sizeof written[0]; w++) {
        char path[4200];
        int n = snprintf(path, sizeof path, "%s%s", out, written[w]);
        if (n < 0 || (size_t)n >= sizeof path) return wf_err(err, WF_EINPUT, "%s %s: path too long", what, out);
        if (stat(path, &so) != 0) continue; /* a file that does not exist is no input */
        for (size_t i = 0; i < n_inputs; i++)
            if (inputs[i] && stat(inputs[i], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino)
                return w ? wf_err(err, WF_EINPUT, "%s %s: %s, written beside the result, is the input %s: refusing to "
                                  "write over it", what, out, path, inputs[i])
                         : wf_err(err, WF_EINPUT, "%s %s: is the input %s: refusing to write the result over it", what,
                                  out, inputs[i]);
    }
    return 0;
}

int wf_output_default_dir(const char *out, WfError *err)
{
    size_t n = strlen(WF_OUTPUT_DEFAULT_DIR);
    if (strncmp(out, WF_OUTPUT_DEFAULT_DIR "/", n + 1) != 0 || strchr(out + n + 1, '/')) return 0;
    if (mkdir(WF_OUTPUT_DEFAULT_DIR, 0777) == 0 || errno == EEXIST) return 0;
    return wf_err(err, WF_EINPUT, "cannot create the result directory %s/ in the working directory: %s",
                  WF_OUTPUT_DEFAULT_DIR, strerror(errno));
}
