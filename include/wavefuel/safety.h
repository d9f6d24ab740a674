/* Safety filters: an optional per-driver-group guard on top of any car-following model or controller (as Flow's
 * fail-safes are). A filter kind computes, for each vehicle, an upper bound on its acceleration from the step's
 * inputs (gap, own and leader speed, time step); the engine applies it as the last rule of the step's acceleration
 * (src/core/block.c: after the controller, its noise, the group's limits, the feasible clip and the road's caps):
 *     a' = a > bound ? max(bound, -decel_max) : a
 * and counts the vehicle-steps where a' != a (the filter's interventions). One file per kind in src/models/safety/,
 * listed once in src/models/safety/registry.c. Rules, keys and references: docs/controllers.md#safety-filters. */
#ifndef WAVEFUEL_SAFETY_H
#define WAVEFUEL_SAFETY_H

#include <stddef.h>
#include "wavefuel/err.h"
#include "wavefuel/param.h"

#define WF_MAX_SAFETY_PARAMS 8 /* doubles in one filter's parameter struct */

typedef struct WfSafetyKind {
    const char        *name;       /* as written in scenarios: `safety: {kind: gipps}` */
    const char        *doc;        /* one line: the rule and its reference */
    size_t             param_size; /* bytes of the parameter struct (doubles, described by spec) */
    const WfParamSpec *spec;
    size_t             n_spec;
    /* Cross-field checks; may be NULL. */
    int (*check)(const void *params, WfError *err);
    /* Upper bound on the acceleration (m/s^2) of n vehicles given their bumper-to-bumper gaps (m, may be < 0 in a
     * state the engine is about to repair), own and leader speeds (m/s, >= 0) and the time step dt_s (s, > 0):
     * pure, finite for every input, with the same arithmetic for any n (the engine calls it per block). */
    void (*bound)(const void *params, double dt_s, size_t n, const double *gap_m, const double *v_mps,
                  const double *v_lead_mps, double *a_max_mps2);
} WfSafetyKind;

/* NULL-terminated registry of every filter kind. */
extern const WfSafetyKind *const wf_safety_kinds[];
/* By name; an unknown name is an error listing the known ones. */
int wf_safety_find(const char *name, const WfSafetyKind **out, WfError *err);

#endif
