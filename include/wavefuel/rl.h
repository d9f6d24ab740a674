/* Reinforcement-learning steps of a batch of runs (src/core/rl_batch.c; the Python package's RingEnv, TrajectoryEnv
 * and VectorEnv): in one parallel loop over runs (as wf_sims_step), each run's external group takes its commands,
 * the run steps, and its observation and reward are computed in C in a fixed order: a run gives the same bits alone
 * and in any batch, on any number of threads.
 *
 * The reward of a run for one action (action_steps steps of dt, lasting dt_action = action_steps x dt) is
 * fuel + gap + comfort, each <= 0:
 * - fuel = -w_fuel x the mean fuel rate (g/s per vehicle) of the vehicles in scope: each vehicle's class energy
 *   model on a flat road at its speed at the action's start and the acceleration (v_end - v_start) / dt_action.
 *   Scope: all vehicles, or the platoon: the external group's vehicles and the vehicles behind them (on a ring
 *   every vehicle; on a corridor every vehicle from the front-most of the group back);
 * - gap = -w_gap x the mean over the group of the squared violation of [gap_min_m, gap_max_m] by its
 *   bumper-to-bumper gap at the action's end, m^2;
 * - comfort = -(w_accel x mean a^2 + w_jerk x mean j^2) over the group, a = (v_end - v_start) / dt_action (m/s^2),
 *   j = (a - the previous action's a) / dt_action (m/s^3; 0 on the first action of the batch's life). */
#ifndef WAVEFUEL_RL_H
#define WAVEFUEL_RL_H

#include <stddef.h>

#include "wavefuel/engine.h"
#include "wavefuel/err.h"

typedef struct WfRlReward {
    int    scope_all;             /* 1: every vehicle's fuel; 0: the platoon's */
    double w_fuel;                /* per g/s */
    double gap_min_m, gap_max_m;
    double w_gap;                 /* per m^2 */
    double w_accel;               /* per (m/s^2)^2 */
    double w_jerk;                /* per (m/s^3)^2 */
} WfRlReward;

/* What wf_rl_batch_step reports per run, n_runs x WF_RL_N_INFO, in this order; the last, WF_RL_T_S, is the run's
 * time after the action (s, wf_sim_time_s). */
enum { WF_RL_FUEL, WF_RL_GAP, WF_RL_COMFORT, WF_RL_FUEL_RATE_GPS, WF_RL_MEAN_SPEED_MPS, WF_RL_T_S, WF_RL_N_INFO };

typedef struct WfRlBatch WfRlBatch;

/* A batch of n_runs runs (begun, external group group[k] of run k), their vehicles on the road now (which must
 * stay the same during the batch's life: a ring's; a corridor's once its platoon has entered) and the reward rw.
 * Takes the runs' state now as the first action's start. Ownership: sims borrowed, alive at every call on the batch
 * but wf_rl_batch_destroy, which does not touch them (and not stepped by anything else meanwhile; the batch's steps
 * are not added to wf_sim_wall_s); *out the caller's until wf_rl_batch_destroy; NULL on failure.
 * WF_EINPUT for a group that is not external or is empty, action_steps < 1, dt_action_s <= 0. */
int  wf_rl_batch_create(WfSim *const *sims, size_t n_runs, const size_t *group, const WfRlReward *rw,
                        long action_steps, double dt_action_s, WfRlBatch **out, WfError *err);
void wf_rl_batch_destroy(WfRlBatch **b);
/* Rows of the batch's observations: the groups' sizes added up. */
size_t wf_rl_batch_rows(const WfRlBatch *b);
/* The groups' accelerations of the previous action (n_rows, m/s^2; NaN: none, no jerk at the next action), the
 * batch's: writable, so that a caller replacing one run by rebuilding the batch carries the others' over. */
double *wf_rl_batch_prev_accel(WfRlBatch *b);
/* The observation now (n_rows x 3, wf_sims_observe's rows). */
void wf_rl_batch_observe(const WfRlBatch *b, double *obs);
/* One action: for every run, in parallel over runs (or over blocks of rings stepped side by side:
 * wf_rl_batch_gang_calls) on up to `threads` OpenMP threads, its commands set (its rows of actions, n_rows in all, as
 * wf_sims_set_actions), action_steps steps, then its rows of obs (n_rows x 3, may be NULL), reward (n_runs) and info
 * (n_runs x WF_RL_N_INFO) written. errs: n_runs entries, as wf_sims_step's
 * (messages prefixed with the run's index); returns the first failure's status (0 on success); a run whose vehicles
 * on the road changed fails with WF_EINPUT. How many of the threads a call takes is chosen by timing the calls, as a
 * corridor's steps are (src/core/governor.h): on a machine whose cores other processes also use, all threads can be
 * several times slower than one. The results never depend on it. */
int wf_rl_batch_step(WfRlBatch *b, const double *actions, int threads, double *obs, double *reward, double *info,
                     WfError *errs);
/* wf_rl_batch_step's arguments as one struct, and the call on them: for callers that pay for every argument of a
 * call (Python's ctypes: some 0.15 us each, a tenth of an action of 64 small rings). */
typedef struct WfRlCall {
    WfRlBatch    *b;
    const double *actions;
    int           threads;
    double       *obs, *reward, *info;
    WfError      *errs;
} WfRlCall;
int wf_rl_batch_call(const WfRlCall *c);
/* Bounds of the commands, n_rows each (m/s^2 for an external group's accelerations; copied): every later call
 * clips each command u to them as numpy's minimum(maximum(u, low), high) does (NaN stays NaN; on a tie the bound's
 * zero sign), before the commands are checked. NULL low and high: no bounds (the default). WF_ESYS when out of
 * memory, WF_EINPUT when some low > high or either is NaN (the bounds stay as they were). */
int wf_rl_batch_set_bounds(WfRlBatch *b, const double *low, const double *high, WfError *err);
/* Calls so far whose steps the runs took side by side: rings of at most 256 vehicles (the kernel's block) with the
 * same kernel (integrator, classes, driver groups and their parameters; flat, no speed limit, zone or safety filter;
 * src/core/gang.h) packed into shared blocks, when none of their steps records, ends the run or meets a fault. The
 * same bits as the runs stepped one by one. */
long wf_rl_batch_gang_calls(const WfRlBatch *b);
/* The thread governor's interval: calls between its probes of the other thread count (WF_RL_THREAD_CHECK by
 * default; 0: always `threads`), set and read. Its probes and switches so far into *probes and *switches (either
 * may be NULL). */
enum { WF_RL_THREAD_CHECK = 1024 };
void wf_rl_batch_set_thread_check(WfRlBatch *b, long calls);
long wf_rl_batch_thread_check(const WfRlBatch *b);
void wf_rl_batch_governor(const WfRlBatch *b, long *probes, long *switches);

#endif
