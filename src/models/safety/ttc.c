/* Time-to-collision safety filter: the speed at the end of the step may not exceed the speed whose time to
 * collision with the leader, at the leader's current speed and the current gap less a margin, is T:
 *   v' <= max(0, v_lead + (gap - s0) / T),   a <= (max(0, v_lead + (gap - s0) / T) - v) / dt
 * (closing at 1/T of the margin per second at most, and opening the gap when it is below s0). A kinematic bound in
 * the spirit of the TTC surrogate safety measure (Hayward 1972; Vogel 2003, Accid. Anal. Prev. 35, 427); unlike the
 * Gipps bound it assumes no leader deceleration. Units: m, m/s, m/s^2, s. Docs: docs/controllers.md#safety-filters. */
#include <stddef.h>

#include "wavefuel/safety.h"

typedef struct TtcSafety {
    double ttc_s;     /* T: the smallest time to collision allowed */
    double gap_min_m; /* s0: margin kept at standstill */
} TtcSafety;

static const WfParamSpec ttc_safety_spec[] = {
    {"ttc_s", offsetof(TtcSafety, ttc_s), 2.0, 0.1, 20.0, "s", 0,
     "T: smallest time to collision (with the leader at its current speed) allowed after the step"},
    {"gap_min_m", offsetof(TtcSafety, gap_min_m), 1.0, 0.0, 20.0, "m", 0, "s0: margin subtracted from the gap"},
};

static void ttc_safety_bound(const void *params, double dt_s, size_t n, const double *restrict gap_m,
                             const double *restrict v_mps, const double *restrict v_lead_mps, double *restrict a_max)
{
    const TtcSafety *p = params;
    /* T >= 0.1 s by the spec range; dt > 0 by the time keys. */
    double inv_t = 1.0 / p->ttc_s, s0 = p->gap_min_m, inv_dt = 1.0 / dt_s;
    for (size_t k = 0; k < n; k++) {
        double vs = v_lead_mps[k] + (gap_m[k] - s0) * inv_t;
        vs = vs > 0.0 ? vs : 0.0;
        a_max[k] = (vs - v_mps[k]) * inv_dt;
    }
}

const WfSafetyKind wf_safety_ttc = {
    .name = "ttc",
    .doc = "time-to-collision bound: the next speed keeps a time to collision of at least T with the leader",
    .param_size = sizeof(TtcSafety),
    .spec = ttc_safety_spec,
    .n_spec = sizeof ttc_safety_spec / sizeof ttc_safety_spec[0],
    .bound = ttc_safety_bound,
};
