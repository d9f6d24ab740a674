/* The one place that turns an error record into a message and an exit status. */
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"

int wf_cli_fail(const WfError *err)
{
    fprintf(stderr, "wavefuel: %s\n", err->msg[0] ? err->msg : "unknown error");
    return err->code == WF_EINPUT ? 2 : err->code == WF_EINTR ? 3 : 1;
}

void wf_cli_note_partial(const WfError *err, const char *path)
{
    fprintf(stderr, err->code == WF_ESYS && strstr(err->msg, "HDF5")
                        ? "wavefuel: %s is incomplete and may be unreadable after this write error\n"
                        : "wavefuel: partial result kept in %s (resume with --resume)\n",
            path);
}
