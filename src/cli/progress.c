/* The progress line of `wavefuel run` (rings and corridors): the bar of src/util/progress.h with simulated time,
 * wall time, time left and steps per second, redrawn in place on stderr. */
#include <stdio.h>

#include "cli/commands.h"
#include "util/clock.h"
#include "util/progress.h"

void wf_cli_run_progress(void *ctx, double t_s, double duration_s, long step, long n_steps)
{
    double wall = wf_wall_now() - *(const double *)ctx, frac = t_s / duration_s;
    char bar[WF_PROGRESS_CELLS + 1];
    double eta = wf_progress_bar(frac, wall, bar);
    (void)n_steps;
    fprintf(stderr, "\r[%s] %5.1f%%  t = %.1f / %.1f s  wall %.1f s  ETA %.1f s  %.3g steps/s   ", bar, 100 * frac,
            t_s, duration_s, wall, eta, wall > 0 ? (double)step / wall : 0.0);
    fflush(stderr);
}
