/* The one place that turns an error record into a message and an exit status. */
#include <stdio.h>

#include "cli/commands.h"

int wf_cli_fail(const WfError *err)
{
    fprintf(stderr, "wavefuel: %s\n", err->msg[0] ? err->msg : "unknown error");
    return err->code == WF_EINPUT ? 2 : err->code == WF_EINTR ? 3 : 1;
}
