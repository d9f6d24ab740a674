/* The block kernel: one time step of a road's vehicles, block by block of WF_BLOCK consecutive vehicles (road
 * order, leader of vehicle i is i + 1), shared by every boundary. Per block: noise, inputs (gap, leader speed,
 * grade), car-following acceleration and its post-rule (noise, group limits, feasible clip, per-vehicle cap, the
 * group's safety filter), fuel rate, the record's partial sums, controller memory, left-point statistics,
 * integration and the statistics of the new state. A boundary (the periodic ring in engine.c, the open corridor in corridor.c) describes its storage as a
 * WfLane and its road features as a WfRoadOps; the vehicles of a step are a logical range of at most two contiguous
 * runs of slots in a circular buffer whose capacity is a multiple of WF_BLOCK, so a block never wraps. */
#ifndef WAVEFUEL_CORE_BLOCK_H
#define WAVEFUEL_CORE_BLOCK_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/engine.h"

#include "wavefuel/integrator.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"
#include "wavefuel/summary.h"
#include "util/clock.h"

/* Vehicles per block; also the ring's noise block (changing it changes the draws) and its statistics block. */
#define WF_BLOCK WF_STATS_BLOCK
#define WF_PAR_MIN 4096 /* vehicles below which a step runs on one thread (OpenMP overhead dominates) */
/* The threads a step of n vehicles asks for, of the run's nthreads. */
static inline int wf_lane_threads(size_t n, int nthreads) { return n >= WF_PAR_MIN ? nthreads : 1; }

/* Parts of a step (wf_lane_step's pass): inputs and acceleration, fuel rate, and the advance (controller memory,
 * statistics, integration). All three in one pass is the fused step; the first two alone export the step's values
 * into the lane's arrays for the outputs, and the advance alone then reads them back. */
enum { WF_PASS_ACCEL = 1, WF_PASS_ENERGY = 2, WF_PASS_ADVANCE = 4, WF_PASS_FUSED = 7 };
/* Added to the pass whose accelerations the step applies (not a final instant's record, nor an adaptive solver's
 * right-hand side): that pass counts the safety filters' interventions. Every pass applies the filters. */
enum { WF_PASS_COUNT = 8 };
/* Flags a step returns: some vehicle overlaps its leader, or has a non-finite state, acceleration or fuel rate (where
 * the step evaluates it: block.c, energy_pass). */
enum { WF_STEP_OVERLAP = 1, WF_STEP_FAULT = 2 };

/* Per-vehicle accumulators of one gate (every step, or only inside the statistics window), indexed by slot; NULL
 * fields are not kept. Left-point rule: values at the step's start held for dt (docs/metrics.md). */
typedef struct WfAccum {
    double   *fuel_g, *stopped_s, *dist_m, *sum_v, *sum_v2, *sum_a, *sum_a2;
    uint32_t *stopped_steps, *steps, *stops, *hard_brakes, *infeasible;
} WfAccum;
/* X(field) for every array of a WfAccum: the code that moves or views all of them. */
#define WF_ACCUM_FIELDS(X)                                                                                         \
    X(fuel_g) X(stopped_s) X(dist_m) X(sum_v) X(sum_v2) X(sum_a) X(sum_a2) X(stopped_steps) X(steps) X(stops)      \
    X(hard_brakes) X(infeasible)

/* What one thread's chunk of a pass reports: its WF_STEP_* flags and, in a counting pass, per driver group, the
 * vehicle-steps under a safety filter and those whose acceleration the filter changed. */
typedef struct WfChunkOut {
    int      flags;    /* of the chunk's steps (its front edge apart) */
    int      edge;     /* of its front edge, checked once every chunk has moved (wf_lane_step_part) */
    double   busy_s;   /* wall time of the chunk's blocks in the step, and how many (WfLane.cuts) */
    size_t   blocks;
    uint64_t safety_steps[WF_MAX_GROUPS], safety_hits[WF_MAX_GROUPS];
} WfChunkOut;

/* Safety-filter counts of a run so far, per driver group (summed over the chunks of every counting pass: integers,
 * so the same for any thread count); the boundary saves them in its checkpoints when some group has a filter. */
typedef struct WfSafetyCount {
    uint64_t steps[WF_MAX_GROUPS], hits[WF_MAX_GROUPS];
} WfSafetyCount;

/* The front vehicle's leader on an open road: a rear bumper at rear_m driving at v_mps, or, when free_gap_m > 0, a
 * far leader at that gap driving at the vehicle's own speed. */
typedef struct WfLead {
    double rear_m, v_mps, free_gap_m;
} WfLead;

/* What a boundary adds to the rules: each hook sees m consecutive slots from lo and their positions / speeds. */
typedef struct WfRoadOps {
    /* grade angle (rad) of m vehicles at x_m; seg: their grade cache (the segment each was last found in); NULL:
     * flat */
    void (*grade)(const void *ctx, uint32_t *seg, size_t m, const double *x_m, double *theta_rad);
    /* a cap on each acceleration (m/s^2; the rule: a > cap ? max(cap, -decel_max) : a) of the m vehicles in slots
     * [lo, lo + m); returns 0 when there is none for these vehicles; NULL: never one */
    int (*cap)(const void *ctx, size_t lo, size_t m, const double *x_m, const double *v_mps, double *cap_mps2);
    /* the parameters a vehicle of a zoned group drives with at x (own, or a copy in buf) */
    const double *(*params_at)(const void *ctx, size_t group, const double *own, double x_m, double *buf);
    /* after a block advanced (x_old_m to x_m) in step `step`: the boundary's per-vehicle bookkeeping of the step, on
     * the thread that stepped the block while it is in cache; NULL: none */
    void (*moved)(const void *ctx, size_t lo, size_t m, long step);
    /* the boundary's work on the whole step's result, shared by the step's threads: called inside the step's
     * parallel region by each of its nt threads (t in [0, nt)) once every vehicle has moved, when the lane asked
     * for it (WfLane.after_wanted) and no chunk flagged an overlap or fault; NULL: none. Saves the boundary a
     * parallel region of its own every step. */
    void (*after_step)(const void *ctx, int t, int nt);
} WfRoadOps;

/* The step's values per slot, written by a pass with WF_PASS_ACCEL / WF_PASS_ENERGY and read by a pass with
 * WF_PASS_ADVANCE alone; NULL where not kept (the fused step keeps them per block). v_mps: each vehicle's speed at
 * the step's start, kept before its advance (what a record reads after a fused step). */
typedef struct WfLaneValues {
    double  *a_mps2, *gap_m, *v_lead_mps, *theta_rad, *fuel_rate_gps;
    uint8_t *flag;
    double  *v_mps;
} WfLaneValues;

/* Chunks of a lane's step on all its threads cut where their wall times come out equal (a corridor's free-flowing
 * front costs more per vehicle than its queue): where chunk t begins, as a fraction of the lane's blocks (at[0] = 0,
 * at[nt] = 1; at[nt] = 0 until the first cuts: an even split), and each chunk's wall time and blocks summed over
 * the fused steps since the cuts last moved. Arrays of nthreads + 1, owned by the boundary. Any cut gives the same
 * bits: a vehicle's step does not depend on its chunk. */
enum { WF_CUT_STEPS = 64 };
typedef struct WfCuts {
    double *at, *busy_s, *blocks;
    long    steps;
} WfCuts;

/* A boundary's vehicles as the kernel sees them. Arrays are indexed by slot and borrowed from the boundary. */
typedef struct WfLane {
    const WfScenario   *sc;
    const WfIntegrator *ig;
    const WfRoadOps    *ops;
    const void         *ctx;        /* passed to the hooks */
    size_t    cap;                  /* slots; a multiple of WF_BLOCK, or the ring's n (its range never wraps) */
    double    period_m;             /* > 0: periodic, the front's leader is the back vehicle one period ahead */
    double   *x_m, *v_mps;
    const uint16_t *class_id, *group_id;
    double    class_length_m[WF_MAX_CLASSES];
    /* each group's parameters and controller memory: vehicle in slot i at base + idx * stride with idx = slot[i]
     * (slot NULL: idx = i) for the parameters and idx = sslot[i] for the memory (sslot NULL: the same as the
     * parameters'); stride 0: one shared block */
    const uint32_t *slot, *sslot;
    const unsigned char *params[WF_MAX_GROUPS];
    unsigned char *state[WF_MAX_GROUPS];
    size_t    pstride[WF_MAX_GROUPS], sstride[WF_MAX_GROUPS];
    uint8_t   zoned[WF_MAX_GROUPS]; /* the group's parameters depend on position (ops->params_at) */
    uint32_t *grade_seg;            /* grade cache per slot (NULL when flat) */
    uint8_t  *mode;                 /* WF_MODE_* per slot */
    WfAccum   always, window;
    WfLaneValues out;               /* where a pass exports the step's values */
    double   *x_old_m;              /* positions at the step's start, per slot (NULL: not kept) */
    int       noisy, nthreads;
    int       stateful;             /* some driver model advances its vehicles' memory every step (update_state) */
    size_t    key0;                 /* slot i draws the noise of slot key0 + i (a halo's copy of other vehicles) */
    double   *bound_x, *bound_v;    /* nthreads + 1 each: each chunk's first vehicle at the step's start */
    WfChunkOut *chunks;             /* nthreads + 1 */
    WfCuts   *cuts;                 /* NULL: chunks of equal blocks */
    int       safe;                 /* some driver group has a safety filter (set by wf_lane_safety_init) */
    int       after_wanted;         /* set by the boundary: an advancing pass calls ops->after_step */
    int       after_done;           /* set by the step: ops->after_step ran for this step */
    WfSafetyCount safety;           /* the counts of the counting passes so far */
} WfLane;

/* After a boundary filled its lane: whether any group has a safety filter, counts zeroed. */
void wf_lane_safety_init(WfLane *ln);
/* The lane's safety counts into the run's summary (groups without a filter stay 0). */
void wf_lane_safety_summary(const WfLane *ln, WfSummary *s);

/* One pass of step `step` over the logical range of n vehicles from slot `first` (road order, wrapping at cap).
 * front: the front vehicle's leader (ignored when periodic). rec: the record's partial sums, one per block, or
 * NULL. Returns WF_STEP_* flags of an advancing pass (overlaps between blocks included, the open front excluded). */
int wf_lane_step(WfLane *ln, size_t first, size_t n, const WfLead *front, long step, int pass, int in_window,
                 WfStatsBlock *rec);
/* The same over blocks [bb0, bb1) of that range only (a part: one rank's share of a ring split across processes,
 * include/wavefuel/partition.h). The leader of the part's last vehicle is the vehicle in the first slot of block
 * bb1 % nb, which the part does not step: the caller holds it at its state at the step's start, and checks the
 * part's front edge (wf_lane_chunk_edge) once it has moved. The whole range is wf_lane_step. */
int wf_lane_step_part(WfLane *ln, size_t first, size_t n, size_t bb0, size_t bb1, const WfLead *front, long step,
                      int pass, int in_window, WfStatsBlock *rec);
/* k steps from step0 of blocks [b0, b1) of that range, block after block at each step: one step is a chunk of
 * wf_lane_step; more are a tile of a time-blocked window (src/core/window.c). The leader of the last block's last
 * vehicle at the start of step step0 + s is lead[s] (a vehicle when k > 1); tx, tv (NULL: not kept) receive the
 * position and speed of the first block's first vehicle at the start of each step (the leader of the tile behind).
 * recs[s]: step step0 + s's record partial sums, indexed by block, or NULL. Checks the edges between the blocks,
 * and the front edge after each step but the last (against lead[s + 1]): the caller checks it after the last step,
 * once the vehicle ahead has moved. co: the safety counts of a counting pass, or NULL. Returns WF_STEP_* flags. */
int wf_lane_tile(WfLane *ln, size_t first, size_t n, size_t b0, size_t b1, long step0, int k, const WfLead *lead,
                 double *tx, double *tv, int pass, int in_window, WfStatsBlock *const *recs, WfChunkOut *co);
/* One ring of a gang block (src/core/gang.c): its vehicles in slots [lo, lo + n) of the gang's lane, its length,
 * its noise seed (the scenario's) and the step it takes. */
typedef struct WfSeg {
    size_t   lo, n;
    double   period_m;
    uint64_t seed;
    long     step;
} WfSeg;
/* A fused, counting step of the rings sg[0 .. ns), which fill consecutive slots of ln (at most WF_BLOCK in all), each
 * as it steps alone on its own periodic lane (the same draws, leaders, accumulators and bits); ln's period_m, seed
 * and key0 are not used. Returns the WF_STEP_* flags of the block (overlaps inside any of its rings, faults) and sets
 * edge[r] to WF_STEP_OVERLAP when ring r's last vehicle overlaps its first one lap ahead, else 0. */
int wf_lane_gang_block(WfLane *ln, const WfSeg *sg, size_t ns, int in_window, WfChunkOut *co, int *edge);
/* WF_STEP_OVERLAP when the last vehicle of the chunk of blocks ending at b1 overlaps the vehicle ahead (the next
 * chunk's first, or on a periodic lane the back vehicle one period ahead), once both have moved. */
int wf_lane_chunk_edge(const WfLane *ln, size_t first, size_t n, size_t b1, size_t nb);
/* The chunks' counts of a counting pass into the run's: integer sums, so the same whatever the chunks. */
void wf_lane_safety_add(WfLane *ln, const WfChunkOut *cf, int nth);
/* Number of blocks of that range (the length of rec). */
size_t wf_lane_blocks(size_t first, size_t n);
/* Logical block j of that range: its first slot in *lo, and its vehicles returned (blocks end at multiples of
 * WF_BLOCK in slots, so one never wraps). */
size_t wf_lane_block_at(const WfLane *ln, size_t first, size_t n, size_t j, size_t *lo);
/* Fuel rate and flag of slots [lo, lo + n) at speeds v and accelerations a (grades theta_rad), class by class. */
void wf_lane_energy(const WfLane *ln, size_t lo, size_t n, const double *v, const double *a, const double *th,
                    double *fr, uint8_t *fl);
/* The statistics before and after an integration done elsewhere (the SUNDIALS path): before, without fuel, from
 * the exported values; after, the stops and distances of the new state. */
void wf_lane_stats_before(WfLane *ln, size_t lo, size_t n, int in_window);
void wf_lane_stats_after(WfLane *ln, size_t lo, size_t n, int in_window);
/* Controller memory of slots [lo, lo + n) from the exported gaps and leader speeds and the speeds v. */
void wf_lane_controllers(WfLane *ln, size_t lo, size_t n, const double *v);

/* A run, shared by the boundaries: steps from *steps_done to n_steps; after each call of step (one step, or a
 * window of several), the stop flag, the checkpoint every checkpoint_every_s of wall time and the progress (about 5
 * times a second); then, when a signal stopped the
 * run, a checkpoint (an interrupted run can always be resumed), the boundary's close and the output's end. */
enum { WF_LOOP_END = -1 };
typedef struct WfLoop {
    void  *ctx;
    /* Steps from `step`, at most max_steps of them (a boundary may take several at once: time-blocked windows),
     * their number in *steps: 0, WF_LOOP_END after the final instant, or an error */
    int  (*step)(void *ctx, long step, long max_steps, long *steps, WfError *err);
    int  (*checkpoint)(void *ctx, WfError *err);       /* NULL: none */
    int  (*close)(void *ctx, WfError *err);            /* summaries of the run (also after an error) */
    int  (*end)(void *ctx, int completed, const char *reason, WfError *err); /* NULL: none */
    long  *steps_done;
    double *wall_s;                                    /* wall time of the step loop; NULL: not timed */
    long   n_steps;
    double dt_s, duration_s, checkpoint_every_s;
    WfProgressFn progress;                             /* may be NULL */
    void  *pctx;
    volatile sig_atomic_t *stop;                       /* may be NULL */
} WfLoop;
/* Where a run stands between calls of wf_loop_advance. */
typedef struct WfLoopState {
    double      last_progress, last_ckpt; /* wall clock of the last progress call and checkpoint */
    const char *reason;                   /* set when a signal stopped the run */
    int         at_end;                   /* the final instant was recorded */
} WfLoopState;
void wf_loop_start(WfLoopState *st);
/* Up to n more iterations of the loop (a step each, the last one the final instant); stops early at the end, on a
 * signal (st->reason) or an error, which it returns. Adds its wall time to *lp->wall_s (when not NULL). */
int wf_loop_advance(const WfLoop *lp, WfLoopState *st, long n, WfError *err);
/* After the last wf_loop_advance (rc: what it returned): the checkpoint of an interrupted run, the close, the end.
 * 0 when the run reached its end; WF_EINTR when a signal stopped it; else the first error. */
int wf_loop_finish(const WfLoop *lp, WfLoopState *st, int rc, WfError *err);

#endif
