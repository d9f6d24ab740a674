/* wf_progress_bar (progress.h): a bar of '#' and '.' and a linear estimate of the time left. */
#include "util/progress.h"

double wf_progress_bar(double frac, double wall_s, char *bar)
{
    double f = frac > 1.0 ? 1.0 : frac > 0.0 ? frac : 0.0; /* also maps NaN to 0 */
    int filled = (int)(f * WF_PROGRESS_CELLS);
    for (int i = 0; i < WF_PROGRESS_CELLS; i++) bar[i] = i < filled ? '#' : '.';
    bar[WF_PROGRESS_CELLS] = '\0';
    /* No estimate before anything is done: frac = 0 would divide by zero. */
    return f > 0.0 ? wall_s * (1.0 - f) / f : 0.0;
}
