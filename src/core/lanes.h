/* Lane changes of a multi-lane road (road.lanes > 1; docs/lanes.md). A boundary describes its lanes at the start of
 * a step as a WfLcRoad (each lane's vehicles in order along it); wf_lanes_decide takes every vehicle's decision from
 * that state, by its driver group's lane-change model (wavefuel/lanechange.h), and settles the conflicts; the
 * boundary then moves the vehicles that changed (the ring: wf_lanes_apply_ring; the corridor, its own buffers).
 *
 * Neighbours in the lanes beside a vehicle come from one merge-like walk of each pair of neighbouring lanes in the
 * order of positions (O(1) per vehicle, no sort). Conflicts follow one fixed rule: a gap between two consecutive
 * vehicles of a lane (or ahead of an open road's front vehicle, or an empty lane) takes at most one vehicle per step,
 * the one with the larger advantage; at equal advantages the first in index order (the lower lane, then the first
 * along the lane's order). So the changes depend only on the state, never on the threads. Internal (not installed). */
#ifndef WAVEFUEL_CORE_LANES_H
#define WAVEFUEL_CORE_LANES_H

#include <stddef.h>
#include <stdint.h>

#include "core/block.h"
#include "wavefuel/engine.h"
#include "wavefuel/fleet.h"
#include "wavefuel/scenario.h"

/* A road's lanes as the decisions see them (borrowed arrays, indexed by vehicle index i). Lane l holds the indices
 * first[l] .. first[l] + count[l] - 1, in order along the lane: positions x_m increase with the index (the vehicle at
 * index i + 1 leads the one at i). On a ring (periodic) the lane's last leads its first, one lap ahead, and x_m are
 * unwrapped; p_m are then the positions around the ring, in [0, L), and rot[l] the index (from first[l]) of the
 * lane's rearmost p. On an open road p_m = x_m, rot is 0 and front[l] leads the lane's last vehicle. */
typedef struct WfLcRoad {
    const WfScenario *sc;
    int               periodic;
    double            L;                        /* ring length (periodic) */
    size_t            n, n_lanes, first[WF_MAX_LANES], count[WF_MAX_LANES], rot[WF_MAX_LANES];
    WfLead            front[WF_MAX_LANES];
    /* where each lane ends (+inf: it runs on; a merge lane or a dropped lane otherwise): nobody changes into a lane
     * that ends, and a vehicle in one leaves it by WF_LANE_RULE_MANDATORY */
    double            end_m[WF_MAX_LANES];
    const double     *x_m, *p_m, *v_mps;
    const uint16_t   *class_id, *group_id;
    const int64_t    *ready_step;               /* the first step at which each vehicle may change lanes again */
    /* an off-ramp leaving lane exit_lane at exit_at_m: each vehicle bound for it (exiting NULL: none is) must reach
     * that lane within exit_approach_m before it (docs/lanes.md, "Off-ramps") */
    const uint8_t    *exiting;
    size_t            exit_lane;
    double            exit_at_m, exit_approach_m;
    const double     *class_length_m;
    /* each group's one parameter set, or NULL when its vehicles have their own; every vehicle's parameters and
     * controller memory (NULL: none) */
    const void       *group_params[WF_MAX_GROUPS];
    const void *(*params)(const struct WfLcRoad *r, size_t i);
    const void *(*state)(const struct WfLcRoad *r, size_t i);
    const void       *ctx;                      /* the boundary's, for params and state */
} WfLcRoad;

/* Scratch and results of the decisions, sized for a road of n vehicles once (nothing is allocated while stepping). */
typedef struct WfLaneChanges {
    size_t    n, n_lanes;
    int       active;        /* some driver group has a lane-change model */
    double   *p_m;           /* per vehicle: the ring's positions in [0, L) (filled by the ring) */
    uint32_t *tgt[2];        /* per vehicle: its leader's index, from the lane's first, in the lane to the right [0] /
                                left [1]; the lane's count: none ahead (open road) or an empty lane */
    int8_t   *dir;           /* per vehicle: the change it makes (WF_LANE_LEFT, WF_LANE_RIGHT) or 0 */
    double   *adv_mps2;      /* per vehicle: its advantage */
    uint32_t *claim;         /* per lane l, from first[l] + l: the index + 1 of the vehicle taking each gap (0: none):
                                gap k lies behind the lane's vehicle k, gap count[l] ahead of its last */
    uint32_t *perm;          /* ring: per new slot, the old slot */
    double   *shift_m;       /* ring: per new slot, what its position moves by (whole laps, to stay in lane order) */
    unsigned char *scratch;  /* ring: one per-vehicle array while it is permuted */
    uint32_t *blk;           /* the first index of each block of the decisions */
    uint8_t  *blkl;          /* ... and its lane */
    int64_t   interval_steps[WF_MAX_GROUPS]; /* each group's least steps between two changes */
    int       coop;          /* some group yields to merging vehicles (its coop decel > 0) */
    uint32_t *coop_who;      /* the cooperation of a step: who yields (road index) ... */
    double   *coop_cap_mps2; /* ... and the acceleration it keeps to at most */
} WfLaneChanges;

/* Ownership: lc's arrays are lc's until wf_lanes_destroy. n: the most vehicles the road holds. */
int  wf_lanes_create(WfLaneChanges *lc, const WfScenario *sc, size_t n, size_t n_lanes, WfError *err);
void wf_lanes_destroy(WfLaneChanges *lc);

/* What lane changes did, summed over steps (integers: the same for any thread count). */
typedef struct WfLaneCounts {
    int64_t changes, cut_ins;                         /* cut-ins: changes into a gap that had a follower */
    int64_t pair[WF_MAX_LANES][WF_MAX_LANES];         /* changes from lane i to lane j */
    int64_t lane_cut_ins[WF_MAX_LANES];               /* cut-ins into each lane */
    int64_t group_changes[WF_MAX_GROUPS];             /* changes made by each driver group's vehicles */
    int64_t group_cut_ins[WF_MAX_GROUPS];             /* cut-ins suffered by each driver group's vehicles */
    double  lane_vehicle_s[WF_MAX_LANES];             /* vehicle-seconds spent in each lane (steps stepped) */
} WfLaneCounts;

/* The decisions of step `step` on road r (lc->dir, lc->tgt and lc->claim: who takes each gap); returns the number of
 * changes. nthreads: the decisions run in parallel (their result does not depend on it). */
long wf_lanes_decide(WfLaneChanges *lc, const WfLcRoad *r, long step, int nthreads);

/* Cooperation at the lanes' ends (docs/lanes.md), from the state of road r after the step's changes: a vehicle in
 * a lane that ends, within its driver's request range of the end, asks the vehicle right behind it in each lane it
 * may enter; that follower yields when its driver cooperates and following the asker as a leader needs no harder
 * braking than the driver accepts: its acceleration is then at most that. Returns the number of (follower, bound)
 * pairs in lc->coop_who / lc->coop_cap_mps2 (a follower asked from two sides appears twice: the lower bound holds). */
size_t wf_lanes_cooperate(WfLaneChanges *lc, const WfLcRoad *r);

/* A ring's changes decided on r (built from f with p in lc->p_m): the vehicles move to their new slots with every
 * per-vehicle array of the ring's state in vars (stride > 0); f's lane counts, lanes, ids and slots of ids follow;
 * the counts go to cnt. */
void wf_lanes_apply_ring(WfLaneChanges *lc, const WfLcRoad *r, WfFleet *f, long step, const WfStateVar *vars,
                         size_t nv, WfLaneCounts *cnt);

/* The ring's road for the decisions (positions around the ring into lc->p_m). */
void wf_lanes_ring_road(WfLaneChanges *lc, const WfScenario *sc, const WfFleet *f, WfLcRoad *r);

/* Slot of the leader of the vehicle in slot i of a ring, and in *lap_m what to add to its position (the ring's length
 * for the lane's last vehicle, whose leader is the lane's first); a vehicle alone in its lane leads itself. */
static inline size_t wf_lanes_leader(const WfFleet *f, double L, size_t i, double *lap_m)
{
    size_t first = 0, l = f->lane ? f->lane[i] : 0;
    for (size_t k = 0; k < l; k++) first += f->lane_n[k];
    size_t next = i + 1 < first + f->lane_n[l] ? i + 1 : first;
    *lap_m = next <= i ? L : 0.0;
    return next;
}

#endif
