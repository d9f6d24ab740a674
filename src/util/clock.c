/* wf_wall_now (clock.h): CLOCK_MONOTONIC in seconds. */
#include "util/clock.h"

#include <time.h>

double wf_wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
