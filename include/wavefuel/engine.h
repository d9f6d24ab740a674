/* The engine: a run of one road, a ring (the periodic boundary) or a corridor (the open boundary), stepped by one
 * block kernel (src/core/block.c). Per step (vehicles in blocks, each writing only its own entries): gaps and grade
 * at the step's start, car-following acceleration plus noise, bounded; fuel rate from each class's energy model;
 * statistics; integration; overlap repair; on a corridor also the entrance, exits, detectors and Edie fields. The
 * engine never parses text and never touches files: results go through a WfOutput. */
#ifndef WAVEFUEL_ENGINE_H
#define WAVEFUEL_ENGINE_H

#include <signal.h>
#include <stdint.h>
#include "wavefuel/err.h"
#include "wavefuel/fleet.h"
#include "wavefuel/integrator.h"
#include "wavefuel/ode.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"

typedef struct WfSim WfSim;

/* Phases of a step whose wall time is measured (docs/output.md: /meta/phase_time). fused_step: the one-pass step
 * of the block kernel (noise, car-following, energy, the record's partial sums, statistics, integration). Steps in
 * two passes (a SUNDIALS integrator, trajectory steps, time.fused_step false): car_following is the first pass
 * (noise, car-following and energy per block: energy stays 0), integration the second (statistics, integration) and
 * the overlap check. statistics: combining a time-series record; output: the writer's callbacks. */
enum { WF_PHASE_CAR_FOLLOWING, WF_PHASE_ENERGY, WF_PHASE_INTEGRATION, WF_PHASE_STATISTICS, WF_PHASE_OUTPUT,
       WF_PHASE_FUSED, WF_N_PHASES };
extern const char *const wf_phase_names[WF_N_PHASES];

/* One time-series record: n values (the road's record columns, in the order its writer's column table gives:
 * wf_ts_columns on a ring, wf_corridor_columns on a corridor) and each class's fuel rate (g/s). Borrowed for the
 * call. */
typedef struct WfRecord {
    const double *v;
    size_t        n;
    const double *class_fuel_rate_gps;
} WfRecord;

struct WfTrip;

/* Output sink of a run (HDF5 in src/io/h5result.c; tests use their own). Each callback may be NULL and returns 0
 * or an error code. */
typedef struct WfOutput {
    int (*begin)(void *ctx, const WfSim *sim, WfError *err);
    /* rec describes the instant rec->v[0]; the vehicles may already be one step further (the fused step takes the
     * record and the step in one pass), so a sink that needs them at that instant uses trajectory. */
    int (*record)(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err);
    int (*trajectory)(void *ctx, const WfSim *sim, double t_s, WfError *err); /* x, v, a, fuel rate now */
    /* Open roads: completed trips in blocks as they happen and, at the end, the unfinished ones. */
    int (*trips)(void *ctx, const WfSim *sim, const struct WfTrip *trips, size_t n, WfError *err);
    /* Save everything needed to resume (every checkpoint interval of wall time, and when the run is interrupted),
     * called between steps after every completed trip so far has gone to trips(). */
    int (*checkpoint)(void *ctx, const WfSim *sim, WfError *err);
    /* completed: 1 when the run reached its end; reason otherwise ("interrupted by SIGINT"...). */
    int (*end)(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err);
    void *ctx;
} WfOutput;

typedef void (*WfProgressFn)(void *ctx, double t_s, double duration_s, long step, long n_steps);

/* Build the run of a scenario's road, a ring (road.type ring: the fleet placed on the periodic road) or a corridor
 * (road.type corridor: wavefuel/corridor.h), with everything it needs allocated here and never during the run.
 * Ownership: sc is borrowed and must outlive the run; *out is the caller's until wf_sim_destroy(); NULL on failure
 * (nothing to free). */
int  wf_sim_create(const WfScenario *sc, WfSim **out, WfError *err);
/* The same for this rank's part of a ring split across processes (wavefuel/partition.h, docs/mpi.md; part borrowed,
 * outliving the run; NULL: wf_sim_create). Every rank creates it from the same scenario; a corridor, several lanes,
 * a SUNDIALS integrator, trajectories, two-pass steps and groups commanded from outside are refused (WF_EINPUT). */
struct WfPartition;
int  wf_sim_create_part(const WfScenario *sc, struct WfPartition *part, WfSim **out, WfError *err);
void wf_sim_destroy(WfSim **sim);

/* Run to the end (from the restored step after wf_sim_restored). Checks *stop (may be NULL) once per step and, when
 * it is set, finishes the current step, saves a checkpoint through out->checkpoint, calls out->end(completed = 0)
 * and returns WF_EINTR. progress (may be NULL) is called about 5 times a second of wall time from the calling
 * thread. out may be NULL. */
int wf_sim_run(WfSim *sim, const WfOutput *out, WfProgressFn progress, void *pctx, volatile sig_atomic_t *stop,
               WfError *err);

/* The same run a piece at a time (the Python interface, external controllers): wf_sim_begin (out may be NULL),
 * then wf_sim_step as often as wanted. A run is duration_s / dt_s steps and then the record of its final instant:
 * each call takes up to n of these, so the call after the last step takes the final record (with the commands
 * then set) and ends the run (summary, out->end), as does an error or a stop (WF_EINTR, partial results and a
 * checkpoint as in wf_sim_run). Pieces change nothing: any sequence of calls gives the bits of wf_sim_run.
 * wf_sim_finish ends a run before its end ("stopped by the caller": a partial result and a checkpoint that
 * --resume continues) and returns WF_EINTR; nothing after the end. A run is begun once. */
int    wf_sim_begin(WfSim *sim, const WfOutput *out, WfError *err);
int    wf_sim_step(WfSim *sim, long n, WfError *err);
int    wf_sim_finish(WfSim *sim, WfError *err);
int    wf_sim_done(const WfSim *sim);      /* 1 once the run has ended */
double wf_sim_time_s(const WfSim *sim);    /* simulated time now: steps done x dt */

/* External controllers: driver groups whose model is `external` (the command is the acceleration, m/s^2) or
 * `external_speed` (a set speed, m/s, followed by the acc law), docs/controllers.md. Between steps, a group's
 * vehicles on the road are wf_sim_group_size of them, in road order (a ring: increasing position from x = 0; a
 * corridor: the front vehicle first). wf_sim_observe writes one row per vehicle, [own speed (m/s), leader speed
 * (m/s), bumper-to-bumper gap (m)], the inputs of the next step exactly as the engine computes them; on a corridor
 * the front vehicle's leader is the virtual leader, or on a free road a leader 1e5 m ahead at its own speed.
 * wf_sim_set_actions sets each vehicle's command for the next steps (held until set again; NaN: none, the acc
 * law); noise, limits and the feasible-acceleration rule apply to it as to any model. WF_EINPUT when the group is
 * not external or n is not the group's size. */
size_t wf_sim_group_size(const WfSim *sim, size_t group);
int    wf_sim_observe(const WfSim *sim, size_t group, double *obs, size_t n, WfError *err);
int    wf_sim_set_actions(WfSim *sim, size_t group, const double *actions, size_t n, WfError *err);

/* Batches of runs (src/core/batch.c; the Python VectorEnv): n_sims runs, each begun, borrowed for the call.
 * wf_sims_step calls wf_sim_step(sims[k], n_steps) for every run, in parallel over runs on `threads` OpenMP
 * threads (below 1: 1; the calling thread's OpenMP settings are not changed); each run gives the bits it gives when
 * stepped alone. errs: n_sims entries, the caller's; errs[k].code is 0, or the status of run k with its message
 * (a failed run has ended, as after wf_sim_step). Returns the status of the first failed run in order, else 0.
 * wf_sims_observe and wf_sims_set_actions do what wf_sim_observe and wf_sim_set_actions do for group[k] of every
 * run k, with the runs' rows one after the other in run order (obs: 3 values a row); n_rows / n_actions must be
 * the sum of the groups' sizes (WF_EINPUT otherwise, or the failing run's error prefixed with its index; commands
 * of the runs before a refused one are set). */
int wf_sims_step(WfSim *const *sims, size_t n_sims, long n_steps, int threads, WfError *errs);
int wf_sims_observe(WfSim *const *sims, size_t n_sims, const size_t *group, double *obs, size_t n_rows,
                    WfError *err);
int wf_sims_set_actions(WfSim *const *sims, size_t n_sims, const size_t *group, const double *actions,
                        size_t n_actions, WfError *err);

const WfScenario *wf_sim_scenario(const WfSim *sim);
/* "ring" or "corridor": the boundary (checkpoints and /meta/road_type name it). */
const char       *wf_sim_kind(const WfSim *sim);
/* The ring's fleet (NULL on a corridor), its arrays as the run's last step left them (what an RL batch stepping it
 * side by side still held comes back first); the corridor's engine for its accessors (wavefuel/corridor.h; NULL on
 * a ring). Borrowed from the run. */
const WfFleet    *wf_sim_fleet(const WfSim *sim);
/* A ring's vehicles at the end of its run, for the result's per-vehicle datasets: fn(ctx, lo, hi, err) on the fleet's
 * vehicles [lo, hi), current in wf_sim_fleet's arrays, piece after piece in ring order. One process: one piece, the
 * whole ring. A ring split across processes (wavefuel/partition.h): every rank calls this, rank 0 with fn and the
 * others with NULL; each share is gathered onto rank 0 for its call and given back afterwards (rank 0 holds its own
 * share and one other at a time). fn's first error is returned; 0 and no call for a corridor. */
typedef int (*WfShareFn)(void *ctx, size_t lo, size_t hi, WfError *err);
int               wf_sim_shares(const WfSim *sim, WfShareFn fn, void *ctx, WfError *err);
const struct WfCorridor *wf_sim_corridor(const WfSim *sim);
const WfSummary  *wf_sim_summary(const WfSim *sim); /* valid after wf_sim_run */
double            wf_sim_wall_s(const WfSim *sim);  /* wall time of the step loop */
long              wf_sim_steps_done(const WfSim *sim);
int               wf_sim_threads(const WfSim *sim);
/* Wall time spent in each phase so far (WF_N_PHASES entries, seconds); NULL when the road does not measure them
 * (corridors). */
const double     *wf_sim_phase_times(const WfSim *sim);
/* The complete state of a run, as named byte blocks: positions, speeds, accumulators, controller memory, step
 * counter and the running sums of the statistics (the random numbers are counter-based: the step counter is their
 * state), and on a corridor its entrance queue, virtual leader, detectors and Edie sums. wf_sim_state() fills
 * `vars` (at most max) and returns their number (blocks have fixed sizes for a given scenario); the blocks can be
 * saved, and after writing saved bytes back into them, wf_sim_restored() checks them (WF_EINPUT naming the first
 * inconsistency) and makes the next wf_sim_run continue from the saved step. */
typedef struct WfStateVar {
    const char *name;
    void       *data;
    size_t      size;   /* bytes */
    size_t      stride; /* bytes per vehicle when the block is a ring's per-vehicle array (in road order); else 0 */
    /* A ring split across processes: only bytes [lo, hi) of the block are this process's, the only ones a resumed
     * run reads back (the rest is never taken: docs/mpi.md, Memory). partial 0: the whole block. */
    int         partial;
    size_t      lo, hi;
} WfStateVar;
/* Room for the blocks of a checkpoint: a ring has at most 25 + WF_MAX_GROUPS, a corridor at most 56, and the
 * result writer adds at most 22 (rows of compressed datasets still in memory). */
#define WF_MAX_STATE_VARS 96
size_t wf_sim_state(WfSim *sim, WfStateVar *vars, size_t max);
/* The run's state blocks vars[0..n) (wf_sim_state's) a piece at a time, for a checkpoint: fn(ctx, j, lo, hi, err) on
 * bytes [lo, hi) of block j, current in its memory, the blocks in order and each block's pieces in order; a block
 * held whole is one piece. A ring split across processes holds its per-vehicle blocks and its controllers' memory in
 * shares (WfStateVar.partial): every rank calls this with its own vars, rank 0 with fn and the others with NULL, and
 * each other rank's share of such a block is gathered onto rank 0 for fn and its pages given back afterwards. fn's
 * first error is returned (the gathers still run). */
typedef int (*WfStatePieceFn)(void *ctx, size_t j, size_t lo, size_t hi, WfError *err);
int               wf_sim_state_pieces(WfSim *sim, const WfStateVar *vars, size_t n, WfStatePieceFn fn, void *ctx,
                                      WfError *err);
int    wf_sim_restored(WfSim *sim, WfError *err);
/* Call out->checkpoint every `wall_s` seconds of wall time (0: only when interrupted). */
void   wf_sim_set_checkpoint_interval(WfSim *sim, double wall_s);
/* Solver statistics of a SUNDIALS run: returns 1 and fills *st, or 0 for a fixed-step integrator. */
int               wf_sim_ode_stats(const WfSim *sim, WfOdeStats *st);
/* Time-blocked stepping so far (time.block_steps): the windows stepped and those undone and redone one step at a
 * time (an overlap or a fault in them). Returns the steps per window, or 0 when the run steps one at a time. */
int               wf_sim_window_stats(const WfSim *sim, long *windows, long *redone);
/* The thread governor (time.thread_check_steps): the probes of the other thread count it timed and the switches it
 * made. Returns 1 when it probes (a road that threads can share, on more than one thread, thread_check_steps > 0). */
int               wf_sim_thread_stats(const WfSim *sim, long *probes, long *switches);
/* A multi-lane road's lane observers (borrowed, valid until the next step): per record kept (n_rows of them, row_len
 * doubles each): t, the lane changes and cut-ins since the previous record, then lane after lane the columns of
 * /lanes (src/observe/lanes.c); the run's counts from lane i to lane j (pair, row-major WF_MAX_LANES x
 * WF_MAX_LANES), of cut-ins into each lane, of changes made and cut-ins suffered by each driver group's vehicles, and
 * the time each group's vehicles spent on the road (s, summed over vehicles). Returns 0 (nothing set) unless the
 * road has several lanes. */
typedef struct WfLaneObs {
    size_t         n_lanes, n_rows, row_len;
    const double  *rows;
    const int64_t *pair, *lane_cut_ins, *group_changes, *group_cut_ins;
    const double  *lane_vehicle_s; /* vehicle-seconds spent in each lane */
    double         group_vehicle_s[WF_MAX_GROUPS];
} WfLaneObs;
int               wf_sim_lanes(const WfSim *sim, WfLaneObs *out);

#endif
