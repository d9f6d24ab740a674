/* Lane-change models: an optional per-driver-group rule deciding, from the accelerations its car-following model
 * gives, whether a vehicle of a multi-lane road moves to a neighbouring lane (`lane_change: {model: NAME, ...}`).
 * The engine (src/core/lanes.c) evaluates, for each vehicle and each neighbouring lane, the accelerations a change
 * would give the three drivers it concerns, with each driver's own car-following model or controller; the model
 * turns them into an advantage. One file per model in src/models/lc/, listed once in src/models/lc/registry.c.
 * Rules, keys and references: docs/lanes.md. */
#ifndef WAVEFUEL_LANECHANGE_H
#define WAVEFUEL_LANECHANGE_H

#include <stddef.h>
#include "wavefuel/err.h"
#include "wavefuel/param.h"

#define WF_MAX_LC_PARAMS 8 /* doubles in one model's parameter struct */

/* Passing rules of a road (road.lane_rule). Lane 0 is the rightmost lane. A change out of a lane that ends (a merge
 * lane, a lane drop) is mandatory: it is judged by WF_LANE_RULE_MANDATORY whatever the road's rule. */
enum { WF_LANE_RULE_SYMMETRIC = 0, WF_LANE_RULE_KEEP_RIGHT = 1, WF_LANE_RULE_MANDATORY = 2 };
/* Directions of a change. */
enum { WF_LANE_RIGHT = -1, WF_LANE_LEFT = 1 };

/* The accelerations (m/s^2, from the car-following models, before noise and limits) a change concerns, at the
 * step's start: the changer's in its lane now and behind its leader in the target lane; the target lane's follower
 * (the new follower) behind its leader now and behind the changer; the follower left behind (the old follower)
 * behind the changer now and behind the changer's leader. has_new / has_old: 0 when there is no such vehicle. */
typedef struct WfLcCase {
    double own_now, own_new;
    double new_now, new_new;
    double old_now, old_new;
    int    has_new, has_old;
} WfLcCase;

typedef struct WfLaneChangeModel {
    const char        *name;       /* as written in scenarios: `lane_change: {model: mobil}` */
    const char        *doc;        /* one line: the rule and its reference */
    size_t             param_size; /* bytes of the parameter struct (doubles, described by spec) */
    const WfParamSpec *spec;
    size_t             n_spec;
    /* Cross-field checks; may be NULL. */
    int (*check)(const void *params, WfError *err);
    /* The advantage (m/s^2) of the change in direction dir (WF_LANE_LEFT, WF_LANE_RIGHT) under passing rule `rule`
     * (WF_LANE_RULE_*): the driver wants to change when it is > 0; -INFINITY when the change is unsafe. Pure. */
    double (*advantage)(const void *params, int dir, int rule, const WfLcCase *c);
    /* The least time between two changes of a vehicle (s). */
    double (*min_interval_s)(const void *params);
    /* Cooperation at a lane's end (docs/lanes.md, "Cooperation"): the hardest braking (m/s^2, magnitude; 0: never)
     * a driver accepts to let a vehicle that must leave an ending lane in ahead of it, and how far (m) before its
     * own lane's end such a driver asks for it. */
    void (*cooperation)(const void *params, double *yield_decel_mps2, double *request_range_m);
} WfLaneChangeModel;

/* NULL-terminated registry of every lane-change model. */
extern const WfLaneChangeModel *const wf_lc_models[];
/* By name; an unknown name is an error listing the known ones. */
int wf_lc_model_find(const char *name, const WfLaneChangeModel **out, WfError *err);

#endif
