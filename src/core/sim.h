/* A run of one road (wavefuel/engine.h: WfSim) and the boundaries that make the road a ring or a corridor. What
 * every boundary shares lives in WfSim: the scenario, the output, the step loop (src/core/block.c: wf_loop_advance), the
 * wall time, threads, checkpoint interval and the summary. What differs is a WfBoundary: how the vehicles are
 * stored and stepped (both on the block kernel), what a step observes, the state a checkpoint saves. Adding a
 * boundary is one file defining a WfBoundary and one line in src/core/sim.c's table. Internal (not installed). */
#ifndef WAVEFUEL_CORE_SIM_H
#define WAVEFUEL_CORE_SIM_H

#include "core/block.h"
#include "core/governor.h"
#include "core/window.h"
#include "wavefuel/engine.h"
#include "wavefuel/partition.h"

typedef void (*WfGroupVisit)(void *ctx, size_t k, unsigned char *state, double v_mps, double v_lead_mps,
                             double gap_m);

typedef struct WfBoundary {
    const char *kind;                                   /* "ring", "corridor": checkpoints and /meta/road_type */
    /* Build the boundary's engine for sim->sc into sim->eng, and point sim->steps_done at its step counter (which
     * its state blocks save). Everything the run needs is allocated here. */
    int    (*create)(WfSim *sim, WfError *err);
    void   (*destroy)(void *eng);
    /* Steps from `step` (wf_loop_run's step): one, or up to max_steps at once, their number in *steps; 0,
     * WF_LOOP_END after the final instant, or an error. Outputs go through sim->out, which may be NULL. */
    int    (*step)(void *eng, long step, long max_steps, long *steps, WfError *err);
    /* Before sim->out->checkpoint: hand the output what it must hold at a checkpoint (NULL: nothing). */
    int    (*flush)(void *eng, WfError *err);
    /* After the last step (or an interruption or error): the run's totals into sim->summary. */
    int    (*close)(void *eng, WfError *err);
    size_t (*state)(void *eng, WfStateVar *vars, size_t max);
    int    (*restored)(void *eng, WfError *err);
    /* The vehicles of driver group g on the road, in road order, each with its controller state and its inputs of
     * the next step (own speed, leader speed, bumper-to-bumper gap, as the kernel computes them); fn may be NULL.
     * Returns their number. */
    size_t (*group)(void *eng, size_t g, WfGroupVisit fn, void *ctx);
    /* The lane observers of a road of several lanes (wf_sim_lanes); NULL, or 0 returned: one lane. */
    int    (*lanes)(const void *eng, WfLaneObs *out);
    /* A ring's vehicles at the end, a share at a time (wf_sim_shares); NULL: not a ring. */
    int    (*shares)(void *eng, WfShareFn fn, void *ctx, WfError *err);
    /* A checkpoint's state blocks a piece at a time (wf_sim_state_pieces); NULL: each whole. */
    int    (*state_pieces)(void *eng, const WfStateVar *vars, size_t n, WfStatePieceFn fn, void *ctx, WfError *err);
} WfBoundary;

extern const WfBoundary wf_boundary_periodic, wf_boundary_open;

/* wf_sim_step without adding its wall time to wf_sim_wall_s: an RL batch's steps (src/core/rl_batch.c, which times
 * its own call), where two clock reads a call, 30-60 ns each on a VM, were some 5 % of an action of 22-vehicle
 * rings. */
int wf_sim_step_untimed(WfSim *s, long n, WfError *err);

/* Rings stepped side by side (src/core/gang.c), one ring's part. wf_ring_gang_lane: a single-lane ring's lane as the
 * kernel sees it (fixed-step, not split across processes), else NULL. wf_ring_gang_plain: how many of its next steps
 * are plain fused steps (its statistics window open for all of them or closed for all, *in_window which, no record,
 * trajectory frame or final instant among them, no fault). wf_ring_gang_settle: what ring_step does after a plain
 * step's pass, whose flags were `flags` (the overlap repair, the numerical fault's error). wf_sim_gang_plain: the same
 * for the run (0 unless begun, not ended, no mlp group, no progress, checkpoint or stop flag to serve, a ring);
 * wf_sim_gang_done: k of them were taken; wf_sim_gang_fail: the run ends with the error rc (as the step loop ends
 * it). */
/* Where group g's vehicles keep their controller state (an external group's command: the first 8 bytes), in road
 * order as wf_sim_set_actions sets them, into out; returns their number. A single-lane ring's stay where they are
 * while the run lives. */
size_t  wf_sim_group_states(WfSim *s, size_t g, unsigned char **out);
/* wf_sim_observe's rows without its checks, for a caller that made them once and whose group cannot change size (a
 * ring's); returns the rows written. */
size_t  wf_sim_observe_rows(const WfSim *s, size_t g, double *obs);
WfLane *wf_ring_gang_lane(WfSim *sim);
/* The ring's fleet as wf_sim_fleet gives it, without bringing back what a gang holds (WfSim.held): for the gang and
 * its batch, which read only what comes back after every call. */
const WfFleet *wf_ring_fleet(const WfSim *sim);
/* What a gang holds of the run back into its arrays (WfSim.held), if anything. */
void    wf_sim_sync(WfSim *s);
long    wf_ring_gang_plain(const WfSim *sim, int *in_window);
int     wf_ring_gang_settle(WfSim *sim, long step, int flags, WfError *err);
long    wf_sim_gang_plain(const WfSim *s, int *in_window);
void    wf_sim_gang_done(WfSim *s, long k);
int     wf_sim_gang_fail(WfSim *s, int rc, WfError *err);

struct WfSim {
    const WfScenario *sc;       /* borrowed */
    const WfBoundary *b;
    void             *eng;      /* the boundary's engine: owned */
    const WfOutput   *out;      /* borrowed, during wf_sim_run */
    long             *steps_done;
    const WfWindow   *win;      /* the engine's time-blocked windows (wf_sim_window_stats), set by create */
    const WfGovernor *gov;      /* the engine's thread governor (wf_sim_thread_stats), set by create */
    const double     *phase_s;  /* WF_N_PHASES wall times, or NULL when the boundary does not measure them */
    double            wall_s, checkpoint_every_s;
    int               nthreads;
    WfSummary         summary;
    WfLoop            loop;     /* set by wf_sim_begin */
    WfLoopState       ls;
    int               begun, finished;
    /* Counts the changes of the run by anything but a gang (src/core/gang.c): its beginning, steps through the step
     * loop, restores from a checkpoint, its end, a new checkpoint interval. A gang that holds a copy of the state
     * (and knows how many plain steps follow) knows it is still the run's. */
    unsigned long     epoch;
    /* After a gang's call (src/core/gang.c) the gang may still hold the newest copy of what no caller views between
     * calls (the stop modes and the statistics sums but the fuel: the positions, speeds, window fuel and controller
     * memory come back at the end of every call). fn(gang, r, 0) brings it back into the run's arrays, fn(gang, r, 1)
     * drops it (the run is gone, or restored from a checkpoint); each clears `held`. Every function that reads or
     * writes those arrays outside the gang calls wf_sim_sync first: the steps, the end, the checkpoints' state,
     * wf_sim_fleet. */
    struct WfHeld {
        void (*fn)(void *gang, size_t r, int drop);
        void  *gang;
        size_t r;
    } held;
    /* `model: mlp` groups (src/core/sim.c: mlp_command): the observation rows and commands of one group's batch,
     * room for the most vehicles a group can have on the road; NULL when no group is mlp. Owned. */
    double           *mlp_rows, *mlp_cmd;
    /* A ring split across processes (wavefuel/partition.h): this rank's communicator, borrowed; NULL: the whole
     * road is stepped here. */
    WfPartition      *part;
};

#endif
