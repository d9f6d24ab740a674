/* Small rings stepped side by side (src/core/gang.c): the runs of an RL batch, each a ring of at most WF_BLOCK
 * vehicles, packed into shared blocks of the kernel so that a step of 64 rings of 22 vehicles pays the block
 * kernel's fixed costs 6 times, not 64. Every ring keeps its own draws, leaders, accumulators and bits. Internal
 * (not installed). */
#ifndef WAVEFUEL_CORE_GANG_H
#define WAVEFUEL_CORE_GANG_H

#include <stddef.h>

#include "wavefuel/engine.h"

typedef struct WfGang WfGang;

/* A gang of the runs sims[0 .. n_runs) (borrowed: they must outlive it, and keep their vehicles) when they can be
 * stepped together: at least two single-lane rings on fixed-step integrators, each of at most WF_BLOCK vehicles, with
 * the same kernel (integrator, classes, driver groups and their parameters, shared by all of a group's vehicles; flat
 * road, no speed limit, zone or safety filter); seeds, lengths and states may differ. *out is NULL when they cannot
 * (not an error), else the caller's until wf_gang_destroy. Fails only when out of memory. */
int wf_gang_create(WfSim *const *sims, size_t n_runs, WfGang **out, WfError *err);
void wf_gang_destroy(WfGang **g);
/* Whether every run's next k steps are plain fused steps (wf_sim_gang_plain), every run's statistics window open
 * during them or every run's closed: then the next wf_gang_step takes them (call it next; the count of plain steps
 * known is spent). */
int wf_gang_ready(WfGang *g, long k);
/* What a caller does for each run on the thread that steps it, so that a call is one parallel region: before its
 * steps (returning an error: the run is not stepped, the error is its) and after them (not when they failed). */
typedef struct WfGangHooks {
    int  (*before)(void *ctx, size_t r, WfError *err);
    /* once a block's runs r0 .. r1 - 1 have stepped (whether or not each succeeded), before their `after`; may be
     * NULL. A run that finished its steps outside the block (after another's fault) gets `after` alone. */
    void (*after_block)(void *ctx, size_t r0, size_t r1);
    int  (*after)(void *ctx, size_t r, WfError *err);
    void *ctx;
} WfGangHooks;
/* k steps of every run on `threads` threads (the blocks of rings shared out, each block its k steps in a row: rings
 * never meet), as wf_sim_step would take them one run at a time, each run between the hooks (h may be NULL). errs:
 * one per run, cleared first; a run whose step failed (a numerical fault) has ended with its error there, the others
 * took their k steps. Returns the first failure's status in run order, else 0. */
int wf_gang_step(WfGang *g, long k, int threads, const WfGangHooks *h, WfError *errs);

#endif
