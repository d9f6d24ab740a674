/* `wavefuel info FILE.h5`: print what a result file says, with units. */
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"
#include "wavefuel/h5out.h"

int wf_cmd_info(int argc, char **argv)
{
    if (argc == 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        printf("usage: wavefuel info FILE.h5\n\nPrints the run status (/meta), the summary values with their units "
               "and the classes of a result file.\n");
        return 0;
    }
    if (argc != 2) {
        fprintf(stderr, "usage: wavefuel info FILE.h5\n");
        return 2;
    }
    WfError err = {0};
    if (wf_h5out_info(argv[1], stdout, &err)) return wf_cli_fail(&err);
    return 0;
}
