/* Gipps's safe speed as a safety filter (Gipps 1981, Transp. Res. B 15, 105, eq. 5 with the extra delay theta =
 * tau / 2): the highest speed v' at the end of the step from which the vehicle can still stop behind its leader
 * when the leader brakes at b_hat from now on and the vehicle, after the reaction time tau = dt, brakes at b:
 *   v_safe = max(0, -b tau + sqrt(max(0, b^2 tau^2 + b (2 (gap - s0) - v tau + v_lead^2 / b_hat))))
 *   a <= (v_safe - v) / tau
 * Decelerations are positive magnitudes. Units: m, m/s, m/s^2, s. Docs: docs/controllers.md#safety-filters. */
#include <math.h>
#include <stddef.h>

#include "wavefuel/safety.h"

typedef struct GippsSafety {
    double decel_mps2;        /* b: the braking the vehicle is assumed to use (magnitude) */
    double leader_decel_mps2; /* b_hat: the leader's assumed most severe braking (magnitude) */
    double gap_min_m;         /* s0: gap kept when both have stopped */
} GippsSafety;

static const WfParamSpec gipps_safety_spec[] = {
    {"decel_mps2", offsetof(GippsSafety, decel_mps2), 3.0, 0.5, 20.0, "m/s^2", 0,
     "b: braking the vehicle is assumed to use after its reaction time (magnitude; at most the group's "
     "`decel_max_mps2` for the bound to be reachable)"},
    {"leader_decel_mps2", offsetof(GippsSafety, leader_decel_mps2), 3.0, 0.5, 20.0, "m/s^2", 0,
     "b̂: the leader's assumed most severe braking (magnitude)"},
    {"gap_min_m", offsetof(GippsSafety, gap_min_m), 1.0, 0.0, 20.0, "m", 0, "s0: gap kept once both have stopped"},
};

/* A loop without branches: it vectorises (sqrt and the max are lane-wise). */
static void gipps_safety_bound(const void *params, double dt_s, size_t n, const double *restrict gap_m,
                               const double *restrict v_mps, const double *restrict v_lead_mps, double *restrict a_max)
{
    const GippsSafety *p = params;
    /* b >= 0.5 and b_hat >= 0.5 m/s^2 by the spec ranges; dt > 0 by the time keys. */
    double b = p->decel_mps2, tau = dt_s, inv_bh = 1.0 / p->leader_decel_mps2, s0 = p->gap_min_m;
    double btau = b * tau, inv_tau = 1.0 / tau;
    for (size_t k = 0; k < n; k++) {
        double v = v_mps[k], vl = v_lead_mps[k];
        double rad = btau * btau + b * (2.0 * (gap_m[k] - s0) - v * tau + vl * vl * inv_bh);
        /* A negative radicand: no speed lets the vehicle stop in time; the bound asks for a stop (v_safe = 0). */
        double vs = -btau + sqrt(rad > 0.0 ? rad : 0.0);
        vs = vs > 0.0 ? vs : 0.0;
        a_max[k] = (vs - v) * inv_tau;
    }
}

const WfSafetyKind wf_safety_gipps = {
    .name = "gipps",
    .doc = "Gipps (1981) safe speed: stop behind a leader braking at b_hat after a reaction time of one step",
    .param_size = sizeof(GippsSafety),
    .spec = gipps_safety_spec,
    .n_spec = sizeof gipps_safety_spec / sizeof gipps_safety_spec[0],
    .bound = gipps_safety_bound,
};
