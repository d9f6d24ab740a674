/* Time-blocked stepping of a lane (issue 20): k fused steps at a time, with one synchronisation of the threads per
 * window instead of one per step, and each tile of vehicles kept in cache across its k steps. Written for the ring
 * (below); a corridor's interior uses it as an open range of its circular buffer whose front chunk follows a trace
 * (open_x, front_first, after: src/core/corridor_window.c, docs/corridors.md).
 *
 * On a single lane information flows one way: a vehicle's step reads only itself and its leader at the step's
 * start. The ring is cut into chunks of consecutive blocks (WF_WINDOW_CHUNKS per thread), each stepped by one
 * thread tile by tile from its front to its back, every tile k steps; a tile's leader at each step is the first
 * vehicle of the tile ahead, recorded while that tile ran (its trace). The chunk's front tile follows the next
 * chunk's first vehicle, whose trace the thread computes itself, redundantly, from a copy of the k + 1 vehicles there
 * taken at the window's start (the halo): the same block kernel with the same counter-based noise, so the same bits.
 * Chunks are independent within a window, so they go to whichever thread is free. Records keep one row of
 * block partial sums per record step and are combined in block order afterwards, as the per-step path does.
 *
 * A step that overlaps or faults must be repaired before the next (the repair sweeps the whole ring): when any step
 * of a window flags, the window's state is restored from a copy taken at its start and the caller redoes the steps
 * one at a time, so the results are those of the per-step path, bit for bit, for any k, tile size and threads. */
#ifndef WAVEFUEL_CORE_WINDOW_H
#define WAVEFUEL_CORE_WINDOW_H

#include "core/block.h"

typedef struct WfHalo WfHalo;

typedef struct WfWindow {
    int           k_max;       /* steps per window */
    size_t        tile_blocks; /* blocks of WF_BLOCK vehicles per tile */
    int           nthreads;    /* threads a window asks for (wf_lane_threads; a team may be smaller) */
    size_t        nb;          /* blocks of the lane */
    size_t        b_lo, b_hi;  /* the blocks stepped here: [0, nb), or a part's (include/wavefuel/partition.h) */
    size_t        n;           /* vehicles of the lane */
    size_t        n_chunks;    /* chunks of at least two blocks, stepped by whichever thread is free */
    long          out_every;   /* steps between records */
    WfHalo       *halo;        /* one per chunk */
    WfStatsBlock *rec;         /* rec_rows rows of nb partial sums: the window's record steps in order */
    size_t        rec_rows;
    unsigned char *backup;     /* the state at the window's start */
    size_t        first;       /* the lane's range starts at this slot (a ring's: 0; wf_window_range) */
    size_t        n_halos;     /* chunks allocated */
    /* An open front (a corridor's interior, wf_window_range): the front chunk follows the vehicle ahead through its
     * trace, position and speed at the start of each step of the window, and its length; NULL: periodic (the front
     * chunk follows the lane's back vehicle one period ahead, stepped redundantly as a halo). The front chunk's edge
     * is then left to the caller. */
    const double  *open_x, *open_v;
    double         open_len_m;
    /* An open front whose vehicles ahead step inside the window's parallel region (a corridor's front part): the
     * team's first thread calls front_first(front_ctx), then steps the front chunk, which follows their trace, then
     * takes other chunks; its result in front_rc: nonzero, the front chunk is not stepped (its state is copied all the
     * same, for the undo). NULL: the trace is complete when the window starts. */
    int          (*front_first)(void *ctx);
    void          *front_ctx;
    int            front_rc;
    /* Called inside the window's parallel region by each of its team's nt threads (t in [0, nt)) once every chunk has
     * moved and its edges are checked, with the window's flags (the same on every thread): the boundary's work on
     * the window's result, without a parallel region of its own. NULL: none. */
    void         (*after)(void *ctx, int t, int nt, int flags);
    void          *after_ctx;
    /* windows stepped, and undone to be redone step by step (wf_window_settle); after a redone window no window
     * starts before per_step_until */
    long           windows, redone, per_step_until, end;
    /* On a part of a ring split across processes, set by the caller: the next part's first k + 1 vehicles may still
     * be on their way when the window starts. The part's front chunk, the only one that reads them, is then stepped
     * last, after halo_ready(halo_ctx) returned 0 on the team's first thread (the thread that called
     * wf_window_run); the other chunks step meanwhile. Its result is in halo_rc: nonzero, the front chunk was not
     * stepped. NULL: they are in place at the start. */
    int          (*halo_ready)(void *ctx);
    void          *halo_ctx;
    int            halo_rc;
} WfWindow;

/* Defaults: the vehicles of a tile from the cache of one core (half its L2 over bytes_per_vehicle, the state a step
 * reads and writes), and the steps per window for records every out_every steps: WF_WINDOW_STEPS, or
 * WF_WINDOW_RECORDS * out_every when fewer (a window keeps each of its records' block sums, 0.8 B per vehicle a
 * record). Why 64 steps (bench/README.md, "Session 23"): on idle cores 3-6 % faster than 16 from 10^4 to 10^7
 * vehicles, and beside two busy processes, where every meeting of the threads waits for whichever one the system
 * descheduled, two threads at 10^5 vehicles went from 0.67-0.98 of one thread's rate to 1.09-1.24. */
enum { WF_WINDOW_STEPS = 64, WF_WINDOW_RECORDS = 16, WF_WINDOW_CHUNKS = 8 /* per thread */ };
size_t wf_window_tile_default(size_t bytes_per_vehicle);
int    wf_window_steps_default(long out_every);

/* Whether blocks [b_lo, b_hi) of a periodic lane of n vehicles can step in windows of k steps on nthreads: every
 * chunk at least two blocks and the halo (k + 1 vehicles) inside one block. */
int wf_window_fits(size_t n, size_t b_lo, size_t b_hi, int nthreads, int k);

/* The window of blocks [b_lo, b_hi) of lane ln (its n vehicles, threads and groups; a part of a ring split across
 * processes steps only its own blocks; an open lane: n its capacity, then wf_window_range before each window) for
 * windows of up to k_max steps, tiles of tile_vehicles (rounded up to blocks), records every out_every steps and a
 * backup of state_bytes. Owns everything
 * it allocates until wf_window_destroy; 0 or WF_ESYS (out of memory, with the size). */
int wf_window_create(WfWindow *w, const WfLane *ln, size_t n, size_t b_lo, size_t b_hi, int k_max,
                     size_t tile_vehicles, long out_every, size_t state_bytes, WfError *err);
void wf_window_destroy(WfWindow *w);

/* The backup's pages of the state variables vars (the same list and order as every window's) for the blocks
 * [b_lo, b_hi) this window steps, taken now (util/mem.h), not in the first window; a process stepping a share of a
 * ring (docs/mpi.md) takes only its share's. Part `part` of `parts` of each (threads may take the parts at once). */
void wf_window_prefault(WfWindow *w, const WfStateVar *vars, size_t n_vars, int part, int parts);

/* Steps a window may take from `step` (1: one step at a time): at most k_max and max_steps; none across the opening
 * of the statistics window (warm_steps), a trajectory step (traj_every; 0: none), a record step (rec_every; 0: the
 * window records them, as a ring's does) or the final instant (n_steps), which step one at a time; none before
 * per_step_until. */
long wf_window_steps(const WfWindow *w, long step, long max_steps, long n_steps, long warm_steps, long traj_every,
                     long rec_every);

/* The threads the next windows take (at most those it was created for: wf_lane_threads of them), and as many chunks
 * as they need (WF_WINDOW_CHUNKS each, at most those allocated): one thread of a window created for two steps 8
 * chunks, not 16, each with its halo of k + 1 vehicles stepped again (a tenth more work at 10^4 vehicles). Any count
 * gives the same bits. */
void wf_window_threads(WfWindow *w, int nthreads);

/* An open lane's window over the logical range of n vehicles from slot first (window.h: a corridor's interior),
 * stepped on nthreads: the range's blocks and chunks, as many as were allocated. Returns 0 when the range does not
 * fit (wf_window_fits' rules), else 1. */
int wf_window_range(WfWindow *w, size_t first, size_t n, int nthreads);

/* k fused steps (2 <= k <= k_max) of the window's blocks of the periodic lane's n vehicles from step step0, all
 * inside or all outside the statistics window. vars: the run's complete state (what a checkpoint saves), copied at
 * the start. The k + 1 vehicles after the window's last block are read as they are at step0 (on a part, the
 * caller's copy of the next part's first vehicles), and a part's front edge is left to the caller. Returns the
 * WF_STEP_* flags of the window's steps; rows[j] (j < *n_rows) are the partial sums of the blocks stepped at the
 * j-th step s of the window with (step0 + s) % out_every == 0. Then wf_window_settle. */
int wf_window_run(WfWindow *w, WfLane *ln, size_t n, long step0, int k, int in_window, const WfStateVar *vars,
                  size_t n_vars, size_t *n_rows);
/* The trace of the range's first vehicle (its back one) over the last window: its position and speed at the start
 * of each of its steps. */
void wf_window_back_trace(const WfWindow *w, const double **x_m, const double **v_mps);

/* After wf_window_run, with the flags of every part: 0, the window stands and its safety counts are added to the
 * lane's; else the state of the window's blocks is restored as it was at step0 and nothing is counted: the caller
 * redoes the steps one at a time (and wf_window_steps gives 1 until then). vars with a stride are indexed by slot. */
void wf_window_settle(WfWindow *w, WfLane *ln, const WfStateVar *vars, size_t n_vars, int flags);

#endif
