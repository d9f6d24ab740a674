/* Small rings stepped side by side (gang.h). A ring of 22 vehicles is one short block of the kernel, whose loops'
 * set-up, the engine's step and the step loop then cost more than its vehicles (64 RL rings: some 3 k instructions
 * a ring-step of fixed costs against 1.3 k of its vehicles' own work, bench/README.md). Here the rings' vehicles are
 * copied into one lane, run after run, and whole rings are packed into blocks of at most WF_BLOCK vehicles; each
 * block steps as one (wf_lane_gang_block), every ring with its own noise stream, its last vehicle following its
 * first one lap ahead, its own accumulators: the bits of the ring stepped alone. The rings' state is copied in at
 * the start of a call when the run changed since, and what callers view of it goes out at its end (the rest when
 * the run asks: WfSim.held). */
#include "core/gang.h"

#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "core/batch.h"
#include "core/block.h"
#include "core/sim.h"
#include "util/mem.h"
#include "wavefuel/fleet.h"

struct WfGang {
    WfSim *const *sims;      /* borrowed: alive while the gang steps them */
    WfLane      **rl;        /* per run: its ring's lane (the run's, fixed for its life) */
    const WfFleet **fl;      /* per run: its fleet (the same) */
    uint8_t      *holds;     /* per run: the gang holds the newest of its arrays nobody views (WfSim.held) */
    size_t        n_runs, n_blocks;
    WfLane        ln;        /* the rings' vehicles in one lane, run after run (owned arrays) */
    WfRoadOps     ops;       /* a flat road without limits: no hooks */
    size_t       *off, *nv;  /* run r's vehicles are slots [off[r], off[r] + nv[r]); off[n_runs]: the lane's slots */
    size_t       *first;     /* n_blocks + 1: block j holds runs [first[j], first[j + 1]) */
    size_t       *sbase;     /* [r * WF_MAX_GROUPS + q]: run r's first member of group q in ln.state[q] */
    WfSeg        *seg;       /* per run: its slots, length, seed and step */
    WfError      *berr;      /* per block (wf_runs_each's; the blocks report through errs) */
    WfError      *errs;      /* the call's, per run */
    const WfGangHooks *h;    /* the call's */
    unsigned long *seen;     /* per run: its WfSim.epoch when its state last went out (ULONG_MAX: never) */
    long         *left;      /* per run, while seen is its epoch: its plain steps left (wf_gang_ready) */
    uint8_t      *win;       /* and whether its statistics window is open during them */
    int           in_window; /* the call's: every run's window open (or every run's closed) */
    long          k;         /* the call's steps */
};

/* Whether ring lane b steps with the kernel of ring lane a: what the kernel reads of the scenario and the lane,
 * but the noise seed, the length and the state. */
static int same_kernel(const WfLane *a, const WfLane *b)
{
    if (!b || b->cap < 1 || b->cap > WF_BLOCK || a->ig != b->ig || b->ops->grade || b->ops->cap || b->safe ||
        b->grade_seg || b->x_old_m || b->sslot || a->noisy != b->noisy || a->stateful != b->stateful ||
        !a->slot != !b->slot)
        return 0;
    const WfScenario *p = a->sc, *q = b->sc;
    if (p->dt_s != q->dt_s || p->v_stop_mps != q->v_stop_mps || p->v_go_mps != q->v_go_mps ||
        p->hard_brake_mps2 != q->hard_brake_mps2 || p->n_classes != q->n_classes || p->n_groups != q->n_groups)
        return 0;
    for (size_t c = 0; c < p->n_classes; c++) {
        const WfVehicleClass *u = &p->classes[c].vc, *w = &q->classes[c].vc;
        if (a->class_length_m[c] != b->class_length_m[c] || u->model != w->model ||
            memcmp(u->params, w->params, u->model->param_size))
            return 0;
    }
    for (size_t g = 0; g < p->n_groups; g++) {
        const WfDriverGroup *u = &p->groups[g], *w = &q->groups[g];
        if (u->model != w->model || u->noise_mps2 != w->noise_mps2 || u->accel_max_mps2 != w->accel_max_mps2 ||
            u->decel_max_mps2 != w->decel_max_mps2 || u->clip_feasible != w->clip_feasible || u->safety ||
            w->safety || a->zoned[g] || b->zoned[g] || a->pstride[g] || b->pstride[g] ||
            a->sstride[g] != b->sstride[g] || memcmp(a->params[g], b->params[g], u->model->param_size))
            return 0;
    }
#define SAME(fld)                                                                                                   \
    if (!a->always.fld != !b->always.fld || !a->window.fld != !b->window.fld) return 0;
    WF_ACCUM_FIELDS(SAME)
#undef SAME
    return 1;
}

/* Run r's arrays between its ring's lane and the gang's, in (ring to gang) or out: `viewed` those a caller may
 * hold views of between calls (positions, speeds, fuel: wavefuel.Simulation.state()), else the others (stop modes,
 * the other statistics sums). */
static void move_arrays(WfGang *g, size_t r, int in, int viewed)
{
    const WfLane *rl = g->rl[r];
    WfLane *gl = &g->ln;
    size_t o = g->off[r], n = g->nv[r];
#define MOVE(gang, ring)                                                                                            \
    if (ring)                                                                                                       \
        memcpy(in ? (void *)((gang) + o) : (void *)(ring), in ? (const void *)(ring) : (const void *)((gang) + o),   \
               n * sizeof *(ring));
    if (viewed) {
        MOVE(gl->x_m, rl->x_m);
        MOVE(gl->v_mps, rl->v_mps);
        MOVE(gl->always.fuel_g, rl->always.fuel_g);
        if (in || g->in_window) MOVE(gl->window.fuel_g, rl->window.fuel_g); /* a closed window's stays as it came */
        return;
    }
    MOVE(gl->mode, rl->mode);
#define ACC(fld)                                                                                                    \
    if (strcmp(#fld, "fuel_g")) {                                                                                   \
        MOVE(gl->always.fld, rl->always.fld);                                                                       \
        MOVE(gl->window.fld, rl->window.fld);                                                                       \
    }
    WF_ACCUM_FIELDS(ACC)
#undef ACC
#undef MOVE
}

/* What the gang holds of run r back into its arrays (WfSim.held), or dropped (the run is gone, or restored). */
static void give_back(void *ctx, size_t r, int drop)
{
    WfGang *g = ctx;
    g->sims[r]->held = (struct WfHeld){0};
    g->holds[r] = 0;
    if (!drop) move_arrays(g, r, 0, 0);
}

/* Run r's per-vehicle state between its ring's lane and the gang's. In: the controllers' memory (an external
 * group's commands), and the rest unless the gang's copy is the ring's (the ring has not stepped or been restored
 * since this copy went out: WfSim.epoch) and `all` is not asked. Out: everything when `all` is asked, else what
 * callers view, the rest held by the gang until the run asks for it (wf_sim_sync: a copy a call of the arrays
 * nobody reads between calls cost a tenth of a 22-vehicle ring's action). */
static void move_run(WfGang *g, size_t r, int in, int all)
{
    WfSim *sim = g->sims[r];
    const WfLane *rl = g->rl[r];
    WfLane *gl = &g->ln;
    const WfFleet *f = g->fl[r];
    /* the controllers' memory: in at every call (the commands), out when the steps may have advanced it */
    for (size_t q = 0; (in || all || gl->stateful) && q < f->n_groups; q++)
        if (gl->sstride[q] && f->group_n[q]) {
            unsigned char *gs = gl->state[q] + g->sbase[r * WF_MAX_GROUPS + q] * gl->sstride[q];
            size_t bytes = f->group_n[q] * gl->sstride[q];
            memcpy(in ? gs : rl->state[q], in ? rl->state[q] : gs, bytes);
        }
    if (in) {
        if (all || g->seen[r] != sim->epoch) move_arrays(g, r, 1, 1), move_arrays(g, r, 1, 0);
        return;
    }
    g->seen[r] = sim->epoch;
    move_arrays(g, r, 0, 1);
    if (all) {
        move_arrays(g, r, 0, 0);
        if (g->holds[r]) sim->held = (struct WfHeld){0}, g->holds[r] = 0;
    } else if (!g->holds[r]) {
        sim->held = (struct WfHeld){give_back, g, r};
        g->holds[r] = 1;
    }
}

void wf_gang_destroy(WfGang **pg)
{
    if (!pg || !*pg) return;
    WfGang *g = *pg;
    for (size_t r = 0; g->holds && r < g->n_runs; r++) /* a run whose arrays the gang holds is alive (give_back) */
        if (g->holds[r]) give_back(g, r, 0);
    WfLane *l = &g->ln;
    WF_FREE(l->x_m, l->v_mps, l->mode, (void *)l->class_id, (void *)l->group_id, (void *)l->slot);
#define FREE(fld) free(l->always.fld), free(l->window.fld);
    WF_ACCUM_FIELDS(FREE)
#undef FREE
    for (size_t q = 0; q < WF_MAX_GROUPS; q++) free(l->state[q]);
    WF_FREE(g->holds, g->rl, g->fl, g->off, g->first, g->sbase, g->seg, g->berr, g->seen, g->nv, g->left, g->win, g);
    *pg = NULL;
}

/* Bytes on whole cache lines of their own (free() releases them). A block's first slot is a multiple of LINE, so it
 * starts a cache line in every array of the lane, whatever its element's size. */
enum { LINE = 64 };
static void *lines(size_t bytes) { return aligned_alloc(LINE, (bytes + LINE - 1) / LINE * LINE); }

/* The gang's lane: run 0's kernel (scenario, integrator, groups' parameters) over arrays of every run's vehicles,
 * the class, group and member index of each copied once (a ring's vehicles keep them). */
static int lane_build(WfGang *g)
{
    const WfLane *l0 = wf_ring_gang_lane(g->sims[0]);
    size_t n = g->off[g->n_runs];
    WfLane *l = &g->ln;
    *l = (WfLane){.sc = l0->sc, .ig = l0->ig, .ops = &g->ops, .cap = n, .noisy = l0->noisy,
                  .stateful = l0->stateful, .nthreads = 1};
    memcpy(l->class_length_m, l0->class_length_m, sizeof l->class_length_m);
    int ok = (l->x_m = lines(n * sizeof *l->x_m)) && (l->v_mps = lines(n * sizeof *l->v_mps)) &&
             (l->mode = lines(n)) && (l->class_id = lines(n * sizeof *l->class_id)) &&
             (l->group_id = lines(n * sizeof *l->group_id)) &&
             (!l0->slot || (l->slot = lines(n * sizeof *l->slot)));
#define ALLOC(fld)                                                                                                  \
    if (ok && l0->always.fld) ok = (l->always.fld = lines(n * sizeof *l0->always.fld)) != NULL;                    \
    if (ok && l0->window.fld) ok = (l->window.fld = lines(n * sizeof *l0->window.fld)) != NULL;
    WF_ACCUM_FIELDS(ALLOC)
#undef ALLOC
    const WfScenario *sc = l0->sc;
    for (size_t q = 0; ok && q < sc->n_groups; q++) {
        l->params[q] = l0->params[q];
        l->sstride[q] = l0->sstride[q];
        size_t members = 0;
        for (size_t r = 0; r < g->n_runs; r++) {
            g->sbase[r * WF_MAX_GROUPS + q] = members;
            members += g->fl[r]->group_n[q];
        }
        if (l->sstride[q] && members) ok = (l->state[q] = malloc(members * l->sstride[q])) != NULL;
    }
    for (size_t r = 0; ok && r < g->n_runs; r++) {
        const WfFleet *f = g->fl[r];
        size_t o = g->off[r];
        memcpy((uint16_t *)l->class_id + o, f->class_id, f->n * sizeof *f->class_id);
        memcpy((uint16_t *)l->group_id + o, f->group_id, f->n * sizeof *f->group_id);
        for (size_t i = 0; l->slot && i < f->n; i++)
            ((uint32_t *)l->slot)[o + i] = (uint32_t)(g->sbase[r * WF_MAX_GROUPS + f->group_id[i]] + f->slot[i]);
    }
    return ok;
}

/* Whole rings, in run order, into blocks of at most WF_BLOCK vehicles, as few as a greedy fill needs, the rings then
 * spread so that the blocks hold about as many vehicles each (the blocks are shared out to the threads in halves:
 * 64 rings of 22 give the two threads 32 each, the greedy fill 33 and 31), unless that overfills a block. Each
 * block starts at a multiple of LINE slots (the blocks of two threads share no cache line). */
static void pack(WfGang *g)
{
    size_t n_runs = g->n_runs, total = 0, in_block = 0;
    for (size_t r = 0; r < n_runs; r++) {
        g->nv[r] = g->rl[r]->cap;
        if (!r || in_block + g->nv[r] > WF_BLOCK) g->first[g->n_blocks++] = r, in_block = 0;
        in_block += g->nv[r], total += g->nv[r];
    }
    g->first[g->n_blocks] = n_runs;
    /* block j's first ring: the ring boundary nearest j x total / n_blocks vehicles */
    size_t *even = g->off, r = 0, cum = 0, ok = 1; /* off is filled below: scratch until then */
    even[0] = 0;
    for (size_t j = 1; j < g->n_blocks; j++) {
        double target = (double)j * (double)total / (double)g->n_blocks;
        while (r < n_runs && (double)(cum + g->nv[r]) <= target) cum += g->nv[r++];
        if (r < n_runs && (double)(cum + g->nv[r]) - target < target - (double)cum) cum += g->nv[r++];
        even[j] = r;
        ok &= r > even[j - 1];
    }
    even[g->n_blocks] = n_runs;
    for (size_t j = 0; ok && j < g->n_blocks; j++) {
        size_t n = 0;
        for (size_t q = even[j]; q < even[j + 1]; q++) n += g->nv[q];
        ok &= even[j + 1] > even[j] && n <= WF_BLOCK;
    }
    if (ok) memcpy(g->first, even, (g->n_blocks + 1) * sizeof *even);
    for (size_t j = 0, slot = 0; j < g->n_blocks; j++) {
        slot = (slot + LINE - 1) / LINE * LINE;
        for (size_t q = g->first[j]; q < g->first[j + 1]; q++) g->off[q] = slot, slot += g->nv[q];
        g->off[n_runs] = slot;
    }
}

int wf_gang_create(WfSim *const *sims, size_t n_runs, WfGang **out, WfError *err)
{
    *out = NULL;
    if (n_runs < 2) return 0;
    const WfLane *l0 = wf_ring_gang_lane(sims[0]);
    if (!l0) return 0;
    for (size_t r = 0; r < n_runs; r++)
        if (!same_kernel(l0, wf_ring_gang_lane(sims[r]))) return 0;
    WfGang *g = calloc(1, sizeof *g);
    if (!g) return wf_err(err, WF_ESYS, "out of memory");
    g->sims = sims, g->n_runs = n_runs;
    int ok = (g->holds = calloc(n_runs, 1)) && (g->rl = malloc(n_runs * sizeof *g->rl)) &&
             (g->fl = malloc(n_runs * sizeof *g->fl)) && (g->off = malloc((n_runs + 1) * sizeof *g->off)) &&
             (g->first = malloc((n_runs + 1) * sizeof *g->first)) &&
             (g->sbase = calloc(n_runs * WF_MAX_GROUPS, sizeof *g->sbase)) &&
             (g->seg = malloc(n_runs * sizeof *g->seg)) && (g->berr = malloc(n_runs * sizeof *g->berr)) &&
             (g->seen = malloc(n_runs * sizeof *g->seen)) && (g->nv = malloc(n_runs * sizeof *g->nv)) &&
             (g->left = malloc(n_runs * sizeof *g->left)) && (g->win = malloc(n_runs));
    for (size_t r = 0; ok && r < n_runs; r++) {
        g->seen[r] = ULONG_MAX;
        g->rl[r] = wf_ring_gang_lane(sims[r]), g->fl[r] = wf_ring_fleet(sims[r]);
        wf_sim_sync(sims[r]); /* what another gang held: its copy in is this one's first */
    }
    if (ok) pack(g);
    for (size_t r = 0; ok && r < n_runs; r++) {
        const WfScenario *sc = wf_sim_scenario(sims[r]);
        g->seg[r] = (WfSeg){g->off[r], g->nv[r], sc->road.length_m, sc->seed, 0};
    }
    if (!ok || !lane_build(g)) {
        wf_gang_destroy(&g);
        return wf_err(err, WF_ESYS, "out of memory for %zu rings side by side", n_runs);
    }
    *out = g;
    return 0;
}

int wf_gang_ready(WfGang *g, long k)
{
    /* The runs' own counters are written by the threads that step them: read only when a run changed (its epoch)
     * or its known plain steps ran out, so that a call does not fetch a cache line of every run from the other
     * core. */
    for (size_t r = 0; r < g->n_runs; r++) {
        WfSim *sim = g->sims[r];
        if (g->seen[r] == sim->epoch && g->left[r] >= k) continue;
        int w = 0;
        g->left[r] = wf_sim_gang_plain(sim, &w);
        g->win[r] = (uint8_t)w;
        if (g->left[r] < k) return 0;
    }
    /* one statistics window for all: the blocks step with it open or closed */
    for (size_t r = 1; r < g->n_runs; r++)
        if (g->win[r] != g->win[0]) return 0;
    g->in_window = g->win[0];
    for (size_t r = 0; r < g->n_runs; r++) g->left[r] -= k;
    return 1;
}

/* Run r after its steps: its `after` hook. */
static void after(WfGang *g, size_t r)
{
    if (!g->errs[r].code && g->h && g->h->after) g->h->after(g->h->ctx, r, &g->errs[r]);
}

/* Some ring of block j's runs r0 .. r1 failed to settle step s of the call: each such ring ends with its error
 * after the s steps before (as the step loop ends a run), the others keep step s and take the rest one by one.
 * skip[r - r0]: run r is not stepped in this call. */
static void block_fault(WfGang *g, size_t r0, size_t r1, long s, const uint8_t *skip)
{
    for (size_t r = r0; r < r1; r++) {
        WfSim *sim = g->sims[r];
        if (skip[r - r0]) continue;
        move_run(g, r, 0, 1);
        if (g->errs[r].code) {
            wf_sim_gang_done(sim, s);
            wf_sim_gang_fail(sim, g->errs[r].code, &g->errs[r]);
            continue;
        }
        wf_sim_gang_done(sim, s + 1);
        if (s + 1 < g->k) wf_sim_step_untimed(sim, g->k - s - 1, &g->errs[r]);
        after(g, r);
    }
}

/* The first error of runs r0 .. r1 - 1 (0: none): the block's report, so that the caller need not read every run's
 * error from the other core. */
static int first_error(const WfGang *g, size_t r0, size_t r1)
{
    for (size_t r = r0; r < r1; r++)
        if (g->errs[r].code) return g->errs[r].code;
    return 0;
}

/* Block j's rings: before, in, k steps, out, after. A ring whose step flagged an overlap or a fault is settled at
 * once on its own arrays (the repair moves its vehicles), as ring_step settles it. A ring whose `before` failed is
 * stepped in the gang's arrays with the others but not taken out (its state stays as it was). What a thread writes
 * per run of its blocks stays in its blocks' cache lines (the flags here on its stack, its runs' errors cleared
 * here): two threads writing neighbouring flags of one line cost more than the rings' steps. */
static int step_block(void *ctx, size_t j, WfError *unused)
{
    (void)unused;
    WfGang *g = ctx;
    size_t r0 = g->first[j], r1 = g->first[j + 1];
    int edge[WF_BLOCK];
    uint8_t skip[WF_BLOCK];
    for (size_t r = r0; r < r1; r++) {
        g->errs[r].code = 0, g->errs[r].msg[0] = '\0';
        skip[r - r0] = g->h && g->h->before && g->h->before(g->h->ctx, r, &g->errs[r]);
        g->seg[r].step = wf_sim_steps_done(g->sims[r]);
        if (skip[r - r0]) {
            wf_sim_sync(g->sims[r]); /* the gang's copy steps with the block: what it held goes back first */
            g->seen[r] = ULONG_MAX;  /* and will not be the ring's */
        }
        move_run(g, r, 1, 0);
    }
    for (long s = 0; s < g->k; s++) {
        int fl = wf_lane_gang_block(&g->ln, g->seg + r0, r1 - r0, g->in_window, NULL, edge);
        int bad = 0;
        for (size_t r = r0; r < r1; r++) {
            int f = fl | edge[r - r0];
            g->seg[r].step++;
            if (skip[r - r0]) continue;
            if (f) move_run(g, r, 0, 1);
            if (f || s + 1 == g->k) bad |= wf_ring_gang_settle(g->sims[r], g->seg[r].step - 1, f, &g->errs[r]) != 0;
            if (f) move_run(g, r, 1, 1);
        }
        if (bad) {
            block_fault(g, r0, r1, s, skip);
            return first_error(g, r0, r1);
        }
    }
    for (size_t r = r0; r < r1; r++) {
        if (skip[r - r0]) continue;
        move_run(g, r, 0, 0);
        wf_sim_gang_done(g->sims[r], g->k);
    }
    if (g->h && g->h->after_block) g->h->after_block(g->h->ctx, r0, r1);
    for (size_t r = r0; r < r1; r++)
        if (!skip[r - r0]) after(g, r);
    return first_error(g, r0, r1);
}

int wf_gang_step(WfGang *g, long k, int threads, const WfGangHooks *h, WfError *errs)
{
    g->k = k, g->errs = errs, g->h = h;
    /* the blocks in run order, each reporting its runs' first error */
    return wf_runs_each(g->n_blocks, threads, step_block, g, g->berr);
}
