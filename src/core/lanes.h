/* Lane changes on a multi-lane ring (road.lanes > 1; docs/lanes.md). The fleet keeps its vehicles ordered by lane,
 * then along the lane (wavefuel/fleet.h), so the block kernel steps each lane as a ring of its own. Before a step,
 * every vehicle's lane-change model decides from the state at the step's start (wavefuel/lanechange.h); the changes
 * are then made at once, and the vehicles that changed move to their new slots with every per-vehicle array.
 *
 * Neighbours in the lanes beside a vehicle come from one merge-like walk of each pair of neighbouring lanes in the
 * order of positions around the ring (O(1) per vehicle, no sort). Conflicts follow one fixed rule: a gap between two
 * consecutive vehicles of a lane (or an empty lane) takes at most one vehicle per step, the one with the larger
 * advantage; at equal advantages the first in slot order (the lower lane, then the first along the lane's order). So
 * the changes depend only on the state, never on the threads. Internal (not installed). */
#ifndef WAVEFUEL_CORE_LANES_H
#define WAVEFUEL_CORE_LANES_H

#include <stddef.h>
#include <stdint.h>

#include "wavefuel/engine.h"
#include "wavefuel/fleet.h"
#include "wavefuel/scenario.h"

/* Scratch of the lane changes, sized for the fleet once (nothing is allocated while stepping). */
typedef struct WfLaneChanges {
    size_t    n, n_lanes;
    int       active;        /* some driver group has a lane-change model */
    double   *p_m;           /* per slot: position around the ring, in [0, L) */
    uint32_t *tgt[2];        /* per slot: the leader's index in the lane to the right [0] / left [1]; UINT32_MAX:
                                that lane is empty */
    int8_t   *dir;           /* per slot: the change made (WF_LANE_LEFT, WF_LANE_RIGHT) or 0 */
    double   *adv_mps2;      /* per slot: its advantage */
    uint32_t *claim;         /* per lane l, from lane_first(l) + l: the slot + 1 claiming each gap (0: none) */
    uint32_t *perm;          /* per new slot: the old slot */
    double   *shift_m;       /* per new slot: what its position moves by (whole laps, to stay in lane order) */
    unsigned char *scratch;  /* one per-vehicle array while it is permuted */
    uint32_t *blk;           /* the first slot of each block of the decisions */
    int64_t   interval_steps[WF_MAX_GROUPS]; /* each group's least steps between two changes */
} WfLaneChanges;

/* Ownership: lc's arrays are lc's until wf_lanes_destroy. */
int  wf_lanes_create(WfLaneChanges *lc, const WfScenario *sc, size_t n, size_t n_lanes, WfError *err);
void wf_lanes_destroy(WfLaneChanges *lc);

/* What lane changes did, summed over steps (integers: the same for any thread count). */
typedef struct WfLaneCounts {
    int64_t changes, cut_ins;                         /* cut-ins: changes into a gap that had a follower */
    int64_t pair[WF_MAX_LANES][WF_MAX_LANES];         /* changes from lane i to lane j */
    int64_t lane_cut_ins[WF_MAX_LANES];               /* cut-ins into each lane */
} WfLaneCounts;

/* The lane changes of step `step`: decisions from the state at its start, then the moves; their counts are added to
 * *cnt, and their number returned. vars: every per-vehicle array of the ring's state (stride > 0), permuted with the
 * vehicles; f's lane counts, lanes, ids and slots of ids follow. nthreads: the decisions run in parallel (their
 * result does not depend on it). */
long wf_lanes_change(WfLaneChanges *lc, const WfScenario *sc, WfFleet *f, long step, const WfStateVar *vars,
                     size_t nv, int nthreads, WfLaneCounts *cnt);

/* Slot of the leader of the vehicle in slot i, and in *lap_m what to add to its position (the ring's length for the
 * lane's last vehicle, whose leader is the lane's first); a vehicle alone in its lane leads itself. */
static inline size_t wf_lanes_leader(const WfFleet *f, double L, size_t i, double *lap_m)
{
    size_t first = 0, l = f->lane ? f->lane[i] : 0;
    for (size_t k = 0; k < l; k++) first += f->lane_n[k];
    size_t next = i + 1 < first + f->lane_n[l] ? i + 1 : first;
    *lap_m = next <= i ? L : 0.0;
    return next;
}

#endif
