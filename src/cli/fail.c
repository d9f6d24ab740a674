/* The one place that turns an error record into a message and an exit status. */
#include <stdio.h>
#include <sys/stat.h>

#include "cli/commands.h"

int wf_cli_fail(const WfError *err)
{
    fprintf(stderr, "wavefuel: %s\n", err->msg[0] ? err->msg : "unknown error");
    return err->code == WF_EINPUT ? 2 : err->code == WF_EINTR ? 3 : 1;
}

void wf_cli_note_partial(const char *partial, const char *result, const char *counters)
{
    char ck[1100];
    struct stat st;
    int w = snprintf(ck, sizeof ck, "%s.ckpt", result);
    int resumable = w > 0 && (size_t)w < sizeof ck && stat(ck, &st) == 0;
    fprintf(stderr, "wavefuel: partial result kept in %s (/meta/reason says why; %s count the rows written)%s\n",
            partial, counters, resumable ? "; resume with --resume" : "");
}
