/* The corridor's own structures and the calls its three files share (not installed: the library's interface is
 * include/wavefuel/corridor.h): src/core/corridor.c (the road, the entrance, the lanes, the measurement, the exits,
 * the records and the step), src/core/corridor_window.c (time-blocked windows) and src/core/corridor_part.c (a
 * corridor split across processes). Each function is described where it is defined. */
#ifndef WAVEFUEL_CORRIDOR_IMPL_H
#define WAVEFUEL_CORRIDOR_IMPL_H

#include "wavefuel/corridor.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/fleet.h"
#include "wavefuel/integrator.h"
#include "wavefuel/partition.h"
#include "core/block.h"
#include "core/governor.h"
#include "core/lanes.h"
#include "core/sim.h"
#include "core/window.h"
#include "util/mem.h"

#define TRIP_BUF 1024 /* trips handed to the output per call */


/* The run's state outside the per-slot arrays: a checkpoint saves this struct verbatim (corridor_state), so
 * every scalar that changes during the run lives here; what WfCorridor keeps outside it and outside the arrays
 * listed in corridor_state is derived from the scenario or recomputed at every step. */
typedef struct CorridorRunState {
    /* window totals of vehicles that have left (and, after the run, of those still on the road) */
    double   cls_fuel[WF_MAX_CLASSES], cls_dist[WF_MAX_CLASSES], cls_stops[WF_MAX_CLASSES],
             cls_infeas[WF_MAX_CLASSES], cls_steps[WF_MAX_CLASSES];
    double   tot_hard, tot_stopped_s;
    /* trips */
    int64_t  cls_entered[WF_MAX_CLASSES], cls_trips[WF_MAX_CLASSES];
    double   cls_trip_fuel[WF_MAX_CLASSES], cls_trip_time[WF_MAX_CLASSES];
    int64_t  trips_done;
    double   sum_trip_time, sum_trip_fuel;
    /* each lane's entrance and virtual leader */
    struct CorEntrance {
        int64_t  arrived, entered, queued; /* this lane's */
        size_t   q_head;        /* the index of the queue's head in the lane's part of queue_t */
        double   next_target;   /* this lane's cumulative demand at which its next arrival happens */
        size_t   in_seg;
        int      have_cand;     /* the queue head's class, group and parameters are drawn */
        uint16_t cand_class, cand_group;
        double   cand_len;
        double   cand_params[WF_MAX_MODEL_PARAMS];
        int64_t  assigned_group[WF_MAX_GROUPS], assigned_class[WF_MAX_CLASSES], n_free_class;
        double   vl_x, vl_v, vl_xref, vl_iref; /* the virtual leader ahead of the lane */
        size_t   vl_seg;
    } lane[WF_MAX_LANES];
    /* counters (the road's: every lane's summed) and statistics */
    WfCorridorCounts counts;
    long     steps_done;
    int64_t  w_entries, w_exits;
    double   sd_sum;
    long     n_sd;
} CorridorRunState;

/* One lane of the road: a circular buffer of slots (veh: its first slot, count and capacity, the arrays from the
 * lane's own slots) with every per-slot array the same way, and the lane as the kernel sees it. Lane l's slots are
 * [l cap, (l + 1) cap) of each allocation (held by lane 0's pointers). */
typedef struct CorLane {
    struct WfCorridor *c;   /* the corridor (the road hooks' context is the lane) */
    size_t    index;        /* the lane's number */
    WfCorridorVehicles veh;
    double   *xold;
    double   *v_start;      /* speeds at the step's start, kept by a fused step that records (COR_EXPORT_RECORD) */
    uint32_t *cell;         /* the Edie cell of the step when it lies inside one cell, else UINT32_MAX */
    uint32_t *grade_seg;
    uint8_t  *mode;
    uint8_t  *dest;         /* 1: bound for the off-ramp (corridor.off_ramp) */
    double   *t_arr, *t_ent, *v_ent;
    WfAccum   trip, win;    /* accumulators over the trip and over the statistics window */
    uint32_t *lane_changes, *cut_ins; /* lane changes made; vehicles that entered the lane right ahead of it */
    int64_t  *lc_ready;     /* the first step at which the vehicle may change lanes again */
    WfLane    lane;         /* the vehicles as the kernel sees them */
    /* the lane's demand (a share of a profile), where its vehicles enter and where it ends (+inf: the exit; else a
     * merge lane's end or a lane drop: a standing obstacle there leads its front vehicle) */
    const WfProfile *demand;
    double    share, start_m, end_m;
} CorLane;

/* Time-blocked stepping of a corridor (corridor_window): the front part (the vehicles that may leave within the
 * window, and one more) steps one step at a time with the exits, the interior in the windows of window.c following
 * the front part's rearmost vehicle, then the entrance steps one at a time behind the interior's back vehicle. The
 * measurement (Edie, detectors) and the exits' trips and totals wait for the window: each step's movement of every
 * vehicle is kept in rows, measured after the window step by step in road order. */
typedef struct CorWindow {
    WfWindow  w;              /* the interior's */
    int       active;         /* the moved hook keeps each step's movement in the rows */
    long      step0;
    size_t    first0, n0, n_int; /* the window's back slot and vehicles as it began; the interior's vehicles */
    size_t    road_first, road_n; /* the road's back slot and vehicles as the window began (one process: first0, n0) */
    size_t    n_halo;         /* split across processes, a rank behind the first: the front part's first vehicles are
                               * the rank ahead's rearmost, stepped again here (cor_part_window_begin) */
    size_t   *cr;             /* per step: the vehicles of the rank behind measured here (crossed into the segment) */
    double   *x, *rate;       /* rows of cap slots: positions at the window's start and after each step (k_max + 1),
                               * each step's fuel rate (k_max) */
    uint32_t *cell;           /* each thread's Edie cells of a step (cells_of), cap slots per thread */
    size_t   *nf, *nb;        /* per step: the front part's vehicles (before its exits) and the entered ones */
    double   *fx, *fv;        /* the front part's rearmost vehicle at the start of each step */
    uint32_t *exit_slot;      /* the exits so far, front first, step after step, and their times */
    double   *exit_t;
    size_t    n_exits;
    int       k, in_window, flags; /* the window's steps, statistics gate and flags (window_after) */
    WfError  *err;
    /* the interior's back vehicle at the start of the entrance's step (try_insert reads it there) */
    int       back_on;
    size_t    back_slot;
    double    back_x, back_v;
    /* the per-slot arrays a step changes, and all of them (an entry writes every one), stride = bytes per slot */
    WfStateVar vars[WF_MAX_STATE_VARS], all[WF_MAX_STATE_VARS];
    size_t    n_vars, n_all, slot_bytes, all_bytes;
    unsigned char *keep;      /* the scalars, the front part's slots of vars and the entrance's of all, as the window
                               * began (the interior's are window.c's) */
} CorWindow;

/* A corridor split across processes (docs/mpi.md): what a rank tells every other once a step (the allgather),
 * after the kernel moved its n vehicles: its rear vehicle (x, v, length) and front vehicle's x (x2); those that
 * crossed into the segment ahead (out, the rearmost of them at out_x, out_v, out_len; skip: one crossed a whole
 * segment); those at or past the exit from the front (past, the rearmost at past_x, past_len); its WF_STEP_* flags
 * with its stop request above PART_STOP_SHIFT; the overlap repairs it made alone. From every rank's record each rank
 * knows every rank's vehicles and rear vehicle at the next step's start (the same table, CorPart.pre). */
typedef struct PartRec {
    double   x, v, len, x2, out_x, out_v, out_len, past_x, past_len;
    uint64_t n, out, skip, past, flags, repairs;
} PartRec;
enum { PART_STOP_SHIFT = 8 };

/* This rank's share of a split corridor: its segment of the road (fronts in [cut_lo, cut_hi); rank 0 the exit's,
 * the last rank the entrance's) and its Edie cells, its vehicles (road indices [k_lo, k_lo + n_own), slots from
 * first_own up) and those that crossed into its segment in the step (n_in, behind them). Vehicles keep their slots
 * and every per-slot key on every rank; a rank's copies of the slots it does not hold are stale. */
typedef struct CorPart {
    WfPartition *p;          /* borrowed; NULL: the whole road in this process */
    double   cut_lo, cut_hi;
    size_t   i_lo, i_hi;
    size_t   k_lo, n_own, first_own, n_in;
    size_t   kb, ke;         /* the measurement's road indices */
    PartRec *pre, *post;     /* every rank's vehicles and rear vehicle at the step's start; its record of the step */
    size_t   vbytes;         /* a packed vehicle */
    unsigned char *out, *in, *all; /* packed vehicles: crossing out, crossing in, the whole road */
    size_t  *off;
    WfSafetyCount safety_all; /* every rank's safety counts (what the summary and a checkpoint read) */
    int      repaired;       /* the step's repair brought the whole road onto every rank */
    /* time-blocked windows (cor_part_window_*): the rearmost vehicles packed for the rank behind and the rank ahead's
     * received; the vehicles crossing into the segment ahead with their rows of the window (the positions before and
     * after each step, the fuel rates), and those received; the entrance's back vehicle's trace, from the last rank */
    unsigned char *halo_out, *halo_in, *cross_out, *cross_in;
    size_t   cross_bytes;    /* a packed vehicle with its rows */
    double  *trace;
    PartRec *wrec;           /* every rank's record after a window (its flags, its vehicles, those crossing out) */
    int64_t  overlaps0;      /* the repairs counted as the window began */
    int      halo_rc;        /* the halo's exchange as the front part waited for it */
    WfError  halo_err;
} CorPart;
/* Whether position x_m (a detector's) lies on this rank's segment, whose rank alone measures it. */
static inline int cor_part_holds(const CorPart *pt, double x_m) { return x_m >= pt->cut_lo && x_m < pt->cut_hi; }
#define PART_CROSS_MAX 512   /* vehicles crossing a cut in one window at most (else one step at a time) */
#define PART_MIN_M 50.0      /* a segment's length beyond two of the longest vehicles, at least (part_check) */

typedef double  V2 __attribute__((vector_size(16)));
typedef double  V4 __attribute__((vector_size(32)));
typedef int64_t M4 __attribute__((vector_size(32)));

/* The running sums of a record's first pass, lane after lane. */
typedef struct RecordSums {
    double sv, sg, vmin, vmax, gmin;
    size_t n, ngap, stopped, waves; /* counts: the same values as the sums of 1.0 they replace */
    int    prev_slow;               /* the last vehicle added was slower than the wave speed */
    V4     cf[4];                   /* class fuel rates: classes 4 v .. 4 v + 3 in vector v (lane_masks) */
} RecordSums;

struct WfCorridor {
    WfSim                *sim; /* the run this engine is the boundary of (outputs, threads, summary) */
    const WfScenario     *sc;  /* borrowed */
    const WfCorridorSpec *cs;  /* borrowed: sc->corridor */
    const WfIntegrator   *ig;
    size_t   pstride, sstride; /* doubles of parameters, bytes of controller state, per slot */
    double   L;
    size_t   n_lanes;
    CorLane  ln[WF_MAX_LANES];
    CorridorRunState st;
    /* trips not yet handed to the output (none at a checkpoint) */
    WfTrip   trips[TRIP_BUF];
    size_t   n_trips;
    /* headway zones: offset (in doubles) of the zone's key in each group's parameters, or -1 */
    int      hw_off[WF_MAX_GROUPS][WF_CORRIDOR_MAX_ZONES];
    /* entrance */
    double  *queue_t;       /* arrival time of each waiting vehicle (FIFO ring) */
    size_t   q_cap;
    double   free_share[WF_MAX_CLASSES]; /* class shares among vehicles whose group fixes no class */
    /* each lane's queue head's free speed, kept while it waits (a pure function of its model, parameters and speed
     * cap: not saved, computed again after a resume) */
    struct CorFree {
        int      valid;
        uint16_t group;
        double   v_hi, v_free, params[WF_MAX_MODEL_PARAMS];
    } vfree[WF_MAX_LANES];
    int      has_vl;        /* a virtual leader (outflow leader or speed) */
    /* every vehicle on the road entered with the statistics window open: its window totals are its trip totals
     * (window_total_out in corridor.c), and the kernel adds to the trip's alone and counts the window's steps */
    int      win_is_trip;
    long     meas_step;     /* the step being stepped, for measure_after_step */
    int      meas_in_window;
    /* a record step on several threads: its first thread sums the record inside the step while the others measure
     * (measure_after_step); the sums as bytes (RecordSums holds vectors this allocation need not align) */
    int      rec_in_step, rec_summed;
    unsigned char rec_sums[sizeof(RecordSums)];
    double   rec_m2;
    /* measurement */
    WfDetectors det;
    WfEdie   edie;
    long     det_every, edie_every;
    /* run */
    long     n_steps, out_every, traj_every, warm_steps;
    int      nthreads;      /* the run's threads */
    WfGovernor gov;         /* the threads each step takes (governor.h): at most nthreads */
    long     fault_slot;    /* the slot of a vehicle with a non-finite state in lane fault_lane, or -1 */
    size_t   fault_lane;
    WfRoadOps ops;
    double  *bound_x, *bound_v;
    WfChunkOut *chunks;
    WfCuts   cuts[WF_MAX_LANES]; /* each lane's chunk cuts (WfLane.cuts) */
    double  *cut_arrays;    /* theirs: 3 (nthreads + 1) per lane */
    int      has_cap;       /* a speed limit somewhere: the kernel caps accelerations */
    WfSafetyCount safety;   /* the lanes' safety counts summed (safety_total) */
    /* lane changes (several lanes, some group with a lane-change model): the decisions' scratch, the road as they
     * see it (its arrays: every lane's vehicles back to front, and each one's global slot), what they did */
    WfLaneChanges lcs;
    struct {
        double   *x_m, *v_mps;
        uint16_t *class_id, *group_id;
        int64_t  *ready;
        uint8_t  *exiting;  /* bound for the off-ramp */
        uint32_t *slot;     /* lane l cap + the slot */
        unsigned char *buf; /* one per-slot array in the new order while vehicles move */
    } snap;
    struct {
        WfLaneCounts total;
        int64_t  rec_changes, rec_cut_ins, n_rows; /* since the last record; records kept */
        double   group_vehicle_s[WF_MAX_GROUPS];  /* time on the road of each group's vehicles that left */
    } lk;
    /* cooperation at the lanes' ends (src/core/lanes.h): per global slot the bound of the step (+inf: none), and the
     * slots that have one */
    double  *coop_cap_mps2;
    uint32_t *coop_slot;
    size_t   n_coop;
    uint32_t *off_src, *off_dst; /* an off-ramp exit: the global slots of the vehicles that move up behind it */
    double  *lane_rows;     /* per record: t, changes, cut-ins, then lane after lane the WF_LANE_* columns */
    size_t   lane_row_len, lane_rows_max;
    CorWindow win;
    CorPart   pt;
};

/* The per-slot arrays a checkpoint saves, whole (a vehicle keeps its slot), with their block names, and whether a
 * step changes them (what a time-blocked window keeps to undo); the others (acceleration, gap, leader speed, grade,
 * fuel rate, flag, xold, cell) every step recomputes before reading them. */
#define SAVED_SLOT_ARRAYS(X)                                                                                       \
    X("x", veh.x_m, 1) X("v", veh.v_mps, 1) X("length", veh.length_m, 0) X("serial", veh.serial, 0)                \
    X("class_id", veh.class_id, 0) X("group_id", veh.group_id, 0) X("grade_seg", grade_seg, 1) X("mode", mode, 1)  \
    X("t_arrival", t_arr, 0) X("t_entry", t_ent, 0) X("v_entry", v_ent, 0) X("trip_fuel", trip.fuel_g, 1)          \
    X("trip_dist", trip.dist_m, 1) X("trip_stopped", trip.stopped_s, 1) X("trip_stops", trip.stops, 1)             \
    X("trip_hard", trip.hard_brakes, 1) X("trip_infeasible", trip.infeasible, 1) X("w_fuel", win.fuel_g, 1)        \
    X("w_dist", win.dist_m, 1) X("w_stopped", win.stopped_s, 1) X("w_steps", win.steps, 1)                         \
    X("w_stops", win.stops, 1) X("w_hard", win.hard_brakes, 1) X("w_infeasible", win.infeasible, 1)                \
    X("lane_changes", lane_changes, 0) X("cut_ins", cut_ins, 0) X("lc_ready", lc_ready, 0) X("dest", dest, 0)
#define STEP_SLOT_ARRAYS(X)                                                                                          \
    X("", veh.a_mps2, 0) X("", veh.gap_m, 0) X("", veh.v_lead_mps, 0) X("", veh.theta_rad, 0)                      \
    X("", veh.fuel_rate_gps, 0) X("", veh.flag, 0) X("", xold, 0) X("", cell, 0) X("", v_start, 0)

/* A lane's counter-based key of its n-th arrival or entry: lane 0 keys as a single-lane corridor does, lane l from
 * l 2^40 (trips name vehicles by it: /trips/serial). */
static inline uint64_t lane_key(size_t l, uint64_t n) { return ((uint64_t)l << 40) + n; }

#define ALLOC(ptr, count)                                                                            \
    do {                                                                                             \
        /* +1: never a 0-byte request */                                                             \
        if (!((ptr) = calloc((size_t)(count) + 1, sizeof *(ptr))))                                   \
            return wf_err(err, WF_ESYS, "out of memory for a corridor of %zu vehicles", c->ln[0].veh.cap); \
    } while (0)

/* corridor.c */
int cor_arrivals(WfCorridor *c, double t, WfError *err);
int cor_entrance(WfCorridor *c, double t, long step, WfError *err);
void cor_cells_of(const WfCorridor *c, const double *restrict xa, const double *restrict xb, uint32_t *restrict cell,
                  size_t m);
/* What a step keeps per slot (cor_lane_exports): the fuel rate alone; every value of the step (its first pass, for
 * a trajectory); what a record reads (a fused step that records: gaps, fuel rates, and the speeds before it moved). */
enum { COR_EXPORT_NONE, COR_EXPORT_ALL, COR_EXPORT_RECORD };
void cor_lane_exports(WfCorridor *c, int what);
WfLead cor_front_leader(const WfCorridor *c, size_t l);
void cor_phase_overlaps(WfCorridor *c, CorLane *ln, int in_window, size_t upto);
void cor_measure_span(const WfCorridor *c, const CorLane *ln, size_t i_lo, size_t i_hi, size_t q_lo, size_t q_hi,
                      size_t *k0, size_t *k1);
void cor_measure_range(WfCorridor *c, const CorLane *ln, long step, int in_window, size_t i_lo, size_t i_hi,
                       size_t q_lo, size_t q_hi);
size_t cor_cell_cut(const WfCorridor *c, const CorLane *ln, size_t t, size_t nt);
int cor_finish_vehicle(WfCorridor *c, const CorLane *ln, size_t s, double t_exit, int completed, WfError *err);
int cor_phase_exits(WfCorridor *c, CorLane *ln, double t_end, int in_window, size_t most, WfError *err);
void cor_advance_leader(WfCorridor *c, double t);
/* at_start: the speeds a fused step kept before it moved the vehicles (v_start), else the vehicles' own */
void cor_record_lanes(const WfCorridor *c, size_t l0, size_t l1, size_t k0, size_t k1, int at_start, RecordSums *r);
double cor_record_m2(const WfCorridor *c, size_t l, size_t k0, size_t k1, int at_start, double mean, double m2);
void cor_record(const WfCorridor *c, size_t l0, size_t l1, double t, int at_start, WfCorridorRow *row);
void cor_record_row(const WfCorridor *c, const RecordSums *rs, double m2, double t, WfCorridorRow *row);
int cor_numerical_fault(const WfCorridor *c, long step, WfError *err);

/* corridor_window.c */
int cor_window_init(WfCorridor *c, WfError *err);
void cor_window_free(CorWindow *cw);
int cor_window(WfCorridor *c, long step0, int k, int *done, WfError *err);
int cor_window_back(WfCorridor *c, long step0, int k, int in_window, const double *bx, const double *bv, double x_end,
                    WfError *err);
void cor_window_measure(WfCorridor *c, size_t t, size_t nt);

/* corridor_part.c */
int cor_part_check(const WfCorridor *c, const WfPartition *p, WfError *err);
int cor_part_init(WfCorridor *c, WfPartition *p, WfError *err);
void cor_part_free(CorPart *pt);
int cor_part_step_once(WfCorridor *c, long step, WfError *err);
int cor_part_collect(WfCorridor *c, WfError *err);
void cor_part_restored(WfCorridor *c);
int cor_part_window_begin(WfCorridor *c, int k, int fit, int *go, WfError *err);
int cor_part_window_wait(WfCorridor *c);
int cor_part_window_agree(WfCorridor *c, int flags, WfError *err);
int cor_part_window_end(WfCorridor *c, WfError *err);

#endif
