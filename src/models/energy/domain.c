/* The accepted operating points (domain.h): one table of speed, acceleration and grade bounds, and its check. */
#include "wavefuel/domain.h"

#include "util/numfmt.h"

/* 150 m/s (540 km/h) and 20 m/s^2 (about 2 g) are far above any road vehicle, and 0.5 rad (a 55 % slope) above
 * any road: the bounds only keep distances, accelerations and fuel rates finite (1e308 m/s gave inf g/s). */
const WfRange wf_point_range[WF_N_POINT_VARS] = {
    [WF_POINT_SPEED] = {"speed", 0.0, 150.0, "m/s"},
    [WF_POINT_ACCEL] = {"acceleration", -20.0, 20.0, "m/s^2"},
    [WF_POINT_GRADE] = {"road grade", -0.5, 0.5, "rad"},
};

int wf_range_check(const WfRange *r, double x, const char *where, WfError *err)
{
    if (x >= r->min && x <= r->max) return 0; /* false for NaN too */
    return wf_err(err, WF_EINPUT, "%s must be in [%s, %s] %s (got %s)", where, WF_NUM(r->min), WF_NUM(r->max), r->unit,
                  WF_NUM(x));
}
