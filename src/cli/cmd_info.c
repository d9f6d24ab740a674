/* `wavefuel info FILE`: print what a wavefuel file says, with units: a run's result (complete or partial), a sweep
 * table or a drive-cycle result; any other file is named for what it is (missing, a directory, not HDF5, another
 * kind of wavefuel file) with exit status 2. */
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"
#include "cli/options.h"
#include "wavefuel/filekind.h"
#include "wavefuel/h5out.h"

int wf_cmd_info(int argc, char **argv)
{
    static const struct option opts[] = {{"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    WfCliOpts cli = {.cmd = "info", .longopts = opts, .shortopts = "h"};
    int o;
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        if (o != 'h') return o == WF_CLI_DONE ? 0 : 2;
        printf("usage: wavefuel info FILE.h5\n\nPrints what a wavefuel file holds, with units: a run's result (the "
               "run status /meta, the summary values and the classes; also a .partial file), a sweep table or a "
               "drive-cycle result (every single value by group). Other files are named for what they are (exit "
               "status 2).\n");
        return 0;
    }
    if (argc - optind != 1) {
        fprintf(stderr, "usage: wavefuel info FILE.h5\n");
        return 2;
    }
    const char *path = argv[optind];
    WfError err = {0};
    WfFileKind kind = wf_file_kind(path, NULL);
    int rc = 0;
    switch (kind) {
    case WF_FILE_RESULT: rc = wf_h5out_info(path, stdout, &err); break;
    case WF_FILE_SWEEP:
    case WF_FILE_CYCLE:
        printf("%s: %s\n", path, wf_file_kind_text(kind));
        rc = wf_h5_info_scalars(path, stdout, &err);
        break;
    case WF_FILE_TABLE:
        rc = wf_err(&err, WF_EINPUT, "%s: is %s: `wavefuel table info %s` describes it", path, wf_file_kind_text(kind),
                    path);
        break;
    case WF_FILE_CHECKPOINT:
        rc = wf_err(&err, WF_EINPUT, "%s: is %s: `wavefuel run --resume %s` continues its run", path,
                    wf_file_kind_text(kind), path);
        break;
    case WF_FILE_MISSING: rc = wf_err(&err, WF_EINPUT, "%s: no such file", path); break;
    default: rc = wf_err(&err, WF_EINPUT, "%s: is %s, not a wavefuel result", path, wf_file_kind_text(kind)); break;
    }
    return rc ? wf_cli_fail(&err) : 0;
}
