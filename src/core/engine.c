/* The ring: the periodic boundary of the block kernel (src/core/block.c). The leader of the last vehicle is vehicle
 * 0 one lap ahead; the road's features are its periodic grade and one speed limit. Each step is one pass of the
 * kernel (the fused step) or, when the step's values must be seen before the state moves (SUNDIALS integrators,
 * trajectories, time.fused_step off), a pass that exports them and a pass that advances; both give the same bits. */
#include "wavefuel/engine.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/block.h"
#include "core/lanes.h"
#include "core/par.h"
#include "core/sim.h"
#include "core/window.h"
#include "observe/columns.h"
#include "util/mem.h"

typedef struct WfRing {
    WfSim              *sim;  /* the run this engine is the boundary of (outputs, threads, summary) */
    const WfScenario   *sc;   /* borrowed */
    WfFleet            *f;
    const WfIntegrator *ig;
    WfLane   lane;          /* the fleet as the kernel sees it */
    WfRoadOps ops;
    long     n_steps, out_every, traj_every, warm_steps, steps_done, cur_step;
    int64_t  overlaps;
    int      nthreads;
    WfStatsBlock *stat_blocks; /* one record's partial sums, block by block */
    int      noisy;         /* some driver group has acceleration noise */
    WfOde   *ode;           /* SUNDIALS integrator, or NULL for a fixed-step scheme */
    double  *xold, *vold, *fuel_step, *vplus; /* ODE path only */
    int      repaired;      /* the last step repaired an overlap */
    double   phase_s[WF_N_PHASES]; /* wall time per phase */
    double  *bound_x, *bound_v;    /* each chunk's first vehicle at the step's start */
    WfChunkOut *chunks;            /* what each thread's chunk reports */
    long     fault_vehicle;         /* first vehicle with a non-finite state, or -1 */
    struct {                       /* scalars of the state, packed for wf_sim_state */
        int64_t steps_done, overlaps, n_sd, repaired, window_open;
        double  sd_sum;
    } ck;
    int      stateful;      /* some driver model keeps per-vehicle memory */
    double   sd_sum;
    long     n_sd;
    WfWindow win;           /* time-blocked stepping (win.k_max 0: one step at a time) */
    int      win_threads;   /* the threads a window may take (win.nthreads as created) */
    WfGovernor gov;         /* the threads of each step or window (governor.h): at most nthreads */
    /* a multi-lane ring (f->n_lanes > 1): each lane as the kernel sees it (lane_views), its record blocks, the
     * lane changes' scratch and what they did (totals, and since the last record) */
    WfLane   lanes[WF_MAX_LANES];
    size_t   lane_nb[WF_MAX_LANES];
    /* each lane is stepped by one thread, the lanes side by side (a lane's chunk report and bounds are its own) */
    WfChunkOut lane_chunk[WF_MAX_LANES];
    double   lane_bx[WF_MAX_LANES], lane_bv[WF_MAX_LANES];
    WfLaneChanges lcs;
    struct RingLaneCtx {           /* what the road's hooks see of each lane (WfLane.ctx) */
        const struct WfRing *s;
        double speed_limit_mps;
    } lane_ctx[WF_MAX_LANES];
    struct {
        WfLaneCounts total;
        int64_t  rec_changes, rec_cut_ins, n_rows; /* since the last record; records kept */
        uint64_t lane_n[WF_MAX_LANES];
    } lk;
    double  *lane_rows;     /* per record: t, changes, cut-ins, then lane after lane the WF_LANE_* columns */
    size_t   lane_row_len, lane_rows_max;
    /* The blocks stepped here: [0, nb), or this rank's part of a ring split across processes (part non-NULL:
     * the section "a ring split across processes" below) */
    size_t   b_lo, b_hi;
    WfPartition *part;
    size_t  *off;           /* part: size + 1 byte offsets of a gather */
    size_t  *group_before;  /* part: [g * (size + 1) + r]: vehicles of group g ahead of rank r's first (slots) */
    unsigned char *halo_out, *halo_in; /* part: packed vehicles, halo_vbytes each */
    size_t   halo_vbytes, halo_m; /* halo_m: vehicles of the exchange in flight */
    WfError *halo_err;            /* where a window's wait for the exchange reports (part_halo_ready) */
    WfSafetyCount safety_all; /* part: the counts of every rank (what checkpoints save) */
    /* A single-lane ring's vehicles keep their indices: those of each group whose commands come from outside
     * (external, mlp), in ring order, [member_off[g], member_off[g + 1]) of members; NULL when no group is such or
     * the ring has lanes (ring_group then scans the fleet). Visited every step or action: a scan of a 22-vehicle
     * ring for its one automated vehicle was 6 % of an RL action. */
    uint32_t *members;
    size_t    member_off[WF_MAX_GROUPS + 1];
} WfRing;

static int ode_rhs(void *ctx, double t, const double *x, const double *v, double *xdot, double *vdot, double *fuel);
static size_t ring_state(void *eng, WfStateVar *vars, size_t max);

static void ring_destroy(void *eng)
{
    WfRing *s = eng;
    wf_fleet_destroy(&s->f);
    wf_window_destroy(&s->win);
    wf_lanes_destroy(&s->lcs);
    wf_ode_destroy(&s->ode);
    WF_FREE(s->lane_rows, s->stat_blocks, s->chunks, s->xold, s->vold, s->bound_x, s->bound_v, s->fuel_step, s->vplus,
            s->off, s->group_before, s->halo_out, s->halo_in, s->members, s);
}

/* ------------------------------------------------------------------------------------- the ring's road */

static void ring_grade(const void *ctx, uint32_t *seg, size_t m, const double *x, double *th)
{
    const WfRing *s = ((const struct RingLaneCtx *)ctx)->s;
    for (size_t k = 0; k < m; k++) th[k] = wf_road_grade(&s->sc->road, x[k], &seg[k]);
}

/* The lane's speed limit: never accelerate past it within the step. */
static int ring_cap(const void *ctx, size_t lo, size_t m, const double *x, const double *v, double *cap)
{
    (void)lo, (void)x;
    const struct RingLaneCtx *lc = ctx;
    double vlim = lc->speed_limit_mps, dt = lc->s->sc->dt_s;
    if (!isfinite(vlim)) return 0;
#pragma omp simd
    for (size_t k = 0; k < m; k++) cap[k] = (vlim - v[k]) / dt;
    return 1;
}

/* The fleet as the kernel sees it: every array borrowed from the fleet. */
static void lane_init(WfRing *s)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    int capped = 0;
    for (size_t l = 0; l < f->n_lanes; l++) {
        s->lane_ctx[l] = (struct RingLaneCtx){s, f->n_lanes > 1 ? sc->lane_speed_limit_mps[l] : sc->road.speed_limit_mps};
        capped |= isfinite(s->lane_ctx[l].speed_limit_mps);
    }
    s->ops = (WfRoadOps){.grade = sc->road.n_grade ? ring_grade : NULL, .cap = capped ? ring_cap : NULL};
    WfLane *ln = &s->lane;
    *ln = (WfLane){.sc = sc, .ig = s->ig, .ops = &s->ops, .ctx = &s->lane_ctx[0], .cap = f->n, .period_m = sc->road.length_m,
                   .x_m = f->x_m, .v_mps = f->v_mps, .class_id = f->class_id, .group_id = f->group_id,
                   .slot = f->slot, .grade_seg = f->grade_seg, .mode = f->mode, .x_old_m = s->xold,
                   .noisy = s->noisy, .stateful = 0, .nthreads = s->nthreads, .bound_x = s->bound_x,
                   .bound_v = s->bound_v, .chunks = s->chunks};
    for (size_t k = 0; k < sc->n_classes; k++) ln->class_length_m[k] = sc->classes[k].length_m;
    for (size_t g = 0; g < f->n_groups; g++) {
        ln->stateful |= sc->groups[g].model->update_state != NULL;
        ln->params[g] = f->group_params[g];
        ln->pstride[g] = f->group_param_stride[g];
        ln->state[g] = f->group_state[g];
        ln->sstride[g] = sc->groups[g].model->state_size;
    }
    ln->window = (WfAccum){.fuel_g = f->fuel_g, .sum_v = f->sum_v, .sum_v2 = f->sum_v2, .sum_a = f->sum_a,
                           .sum_a2 = f->sum_a2, .stopped_steps = f->stopped_steps, .stops = f->stops,
                           .hard_brakes = f->hard_brakes, .infeasible = f->infeasible_steps};
    wf_lane_safety_init(ln);
}

/* Each lane of a multi-lane ring as the kernel sees it: the ring's lane with every per-slot array from the lane's
 * first slot, a ring of its own; its noise from blocks numbered from l * 2^32 (slot keys from l * 2^40), so that
 * no two lanes share draws. Rebuilt whenever the lanes' counts or the exports change. */
static void lane_views(WfRing *s)
{
    const WfFleet *f = s->f;
#define OFF(p) ((p) ? (p) + first : (p))
    for (size_t l = 0, first = 0; f->n_lanes > 1 && l < f->n_lanes; first += f->lane_n[l++]) {
        WfLane *v = &s->lanes[l];
        WfSafetyCount keep = v->safety;
        const WfLane *a = &s->lane;
        *v = *a;
        v->cap = f->lane_n[l];
        v->x_m = OFF(a->x_m), v->v_mps = OFF(a->v_mps), v->class_id = OFF(a->class_id);
        v->group_id = OFF(a->group_id), v->slot = OFF(a->slot), v->sslot = OFF(a->sslot);
        v->grade_seg = OFF(a->grade_seg), v->mode = OFF(a->mode), v->x_old_m = OFF(a->x_old_m);
        WfAccum *ac[2] = {&v->always, &v->window};
#define SHIFT(fld) ac[q]->fld = OFF(ac[q]->fld);
        for (int q = 0; q < 2; q++) {
            WF_ACCUM_FIELDS(SHIFT)
        }
#undef SHIFT
        WfLaneValues *o = &v->out;
        *o = (WfLaneValues){OFF(o->a_mps2), OFF(o->gap_m), OFF(o->v_lead_mps), OFF(o->theta_rad),
                            OFF(o->fuel_rate_gps), OFF(o->flag), OFF(o->v_mps)};
        v->key0 = (size_t)l << 40;
        v->ctx = &s->lane_ctx[l];
        v->nthreads = 1, v->chunks = &s->lane_chunk[l], v->bound_x = &s->lane_bx[l], v->bound_v = &s->lane_bv[l];
        v->safety = keep;
    }
#undef OFF
}

/* The step's values go to the fleet's arrays (steps in two passes) or stay in the kernel's blocks (fused). */
static void lane_exports(WfRing *s, int on)
{
    WfFleet *f = s->f;
    s->lane.out = on ? (WfLaneValues){f->a_mps2, f->gap_m, f->v_lead_mps, f->theta_rad, f->fuel_rate_gps, f->flag, NULL}
                     : (WfLaneValues){0};
    lane_views(s);
}

/* One pass of a step over the ring: its one lane, or each lane of a multi-lane ring as a ring of its own, the
 * record's partial sums lane after lane (s->lane_nb: each lane's blocks). Returns the WF_STEP_* flags. */
static int lanes_step(WfRing *s, long step, int pass, int in_window, WfStatsBlock *rec)
{
    const WfFleet *f = s->f;
    if (f->n_lanes < 2) {
        s->lane_nb[0] = wf_lane_blocks(0, f->n);
        return wf_lane_step(&s->lane, 0, f->n, NULL, step, pass, in_window, rec);
    }
    int flags = 0;
    size_t nl = f->n_lanes, off[WF_MAX_LANES];
    for (size_t l = 0, o = 0; l < nl; o += s->lane_nb[l++]) {
        s->lane_nb[l] = s->lanes[l].cap ? wf_lane_blocks(0, s->lanes[l].cap) : 0;
        off[l] = o;
    }
    /* the lanes side by side, each on one thread: the same bits as one after the other (a lane's step does not
     * depend on the threads) */
    int nth = wf_lane_threads(f->n, s->lane.nthreads);
    if ((size_t)nth > nl) nth = (int)nl;
    WF_PAR_FOR(nth > 1, "omp parallel for schedule(dynamic, 1) num_threads(nth) default(none) shared(s, nl, off, step, pass, in_window, rec) reduction(| : flags)",
    for (size_t l = 0; l < nl; l++) {
        WfLane *v = &s->lanes[l];
        if (v->cap) flags |= wf_lane_step(v, 0, v->cap, NULL, step, pass, in_window, rec ? rec + off[l] : NULL);
    });
    return flags;
}

/* The record of the step's start from the partial sums lanes_step left, lane after lane. */
static void lanes_record(const WfRing *s, const WfStatsBlock *rec, double t, WfTsRow *row)
{
    wf_stats_combine_lanes(rec, s->lane_nb, s->f->n_lanes, s->f->n_classes, s->sc, t, s->overlaps, row);
}

static int ode_init(WfRing *s, WfError *err)
{
    const WfScenario *sc = s->sc;
    size_t n = s->f->n;
    WfOdeConfig cfg = sc->solver;
    cfg.fixed_step_s = sc->dt_s / cfg.rk4_substeps;
    if (!((s->xold = malloc(n * sizeof(double))) && (s->vold = malloc(n * sizeof(double))) &&
          (s->fuel_step = malloc(n * sizeof(double))) && (s->vplus = malloc(n * sizeof(double)))))
        return wf_err(err, WF_ESYS, "out of memory");
    return wf_ode_create(&cfg, n, sc->road.length_m, ode_rhs, s, 0.0, s->f->x_m, s->f->v_mps, &s->ode, err);
}

static int part_halo_ready(void *ctx);

/* Time-blocked stepping (src/core/window.h) for fixed-step schemes on the fused path, when the ring is long enough
 * for the threads: time.block_steps steps per window (0: wf_window_steps_default; 1: none), tiles of time.tile_vehicles
 * (0: from the cache size and the bytes of state per vehicle); split across processes, each window's halo travels
 * while the window's interior steps (part_halo_ready). */
static int window_init(WfRing *s, WfError *err)
{
    const WfScenario *sc = s->sc;
    int k = sc->block_steps ? sc->block_steps : wf_window_steps_default(s->out_every);
    size_t n = s->f->n;
    if (s->ode || !sc->fused_step || s->f->n_lanes > 1 || !wf_window_fits(n, s->b_lo, s->b_hi, s->nthreads, k))
        return 0;
    /* split across processes, every rank steps windows or none does (each rank's answer, for the same threads) */
    for (int r = 0; s->part && r < s->part->size; r++) {
        size_t b0, b1;
        wf_partition_blocks(wf_lane_blocks(0, n), s->part->size, r, &b0, &b1);
        if (!wf_window_fits(n, b0, b1, s->nthreads, k)) return 0;
    }
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = ring_state(s, vars, WF_MAX_STATE_VARS), bytes = 0;
    for (size_t j = 0; j < nv; j++) bytes += vars[j].size;
    size_t tile = sc->tile_vehicles > 0 ? (size_t)sc->tile_vehicles : wf_window_tile_default(bytes / n);
    int rc = wf_window_create(&s->win, &s->lane, n, s->b_lo, s->b_hi, k, tile, s->out_every, bytes, err);
    s->lane_nb[0] = s->win.nb; /* a window's records: lanes_record */
    if (!rc && s->part && s->part->size > 1) s->win.halo_ready = part_halo_ready, s->win.halo_ctx = s;
    return rc;
}

/* ------------------------------------------------------------------ a ring split across processes */

/* This rank steps the blocks [b_lo, b_hi) of the ring (wavefuel/partition.h, docs/mpi.md): every array is indexed by
 * vehicle on every rank, but only this part's entries are built and current (wf_fleet_create_part). What the part reads
 * of the next part (its first vehicle, the leader of this part's last; its first k + 1 vehicles, which a window's halo
 * steps again) arrives in messages and is written into the same arrays. Sums over the ring (a record, the summary)
 * run along the ranks in ring order; the end's per-vehicle results and a checkpoint come to rank 0 a share at a time;
 * overlaps are repaired share after share; only a numerical fault gathers the whole ring (positions, speeds, modes)
 * onto every rank. Each step or window ends with one agreement of every rank on its flags and on a stop, so all ranks
 * repair, redo or stop at the same step. */
enum { WF_PART_STOP_SHIFT = 8 }; /* the agreed word: WF_STEP_* flags below, the stop's signal number above */

static void part_range(const WfRing *s, int r, size_t *lo, size_t *hi)
{
    size_t n = s->f->n, b0, b1;
    wf_partition_blocks(wf_lane_blocks(0, n), s->part->size, r, &b0, &b1);
    *lo = b0 * WF_BLOCK, *hi = b1 * WF_BLOCK < n ? b1 * WF_BLOCK : n;
}

/* The slot of the next part's first vehicle (the ring's vehicle 0 after the last part). */
static size_t part_ahead(const WfRing *s)
{
    return s->b_hi < wf_lane_blocks(0, s->f->n) ? s->b_hi * WF_BLOCK : 0;
}

/* Before the fleet is built: what a split ring cannot be, beyond what no split road can (wf_sim_create_part). */
static int part_check(const WfScenario *sc, const WfPartition *p, WfError *err)
{
    size_t n = (size_t)sc->n_vehicles;
    size_t nb = wf_lane_blocks(0, n);
    if (nb < 2 * (size_t)p->size)
        return wf_err(err, WF_EINPUT, "%s: fleet.vehicles %zu: %d processes need at least %zu vehicles (two blocks of "
                      "%d per process)", sc->path, n, p->size, (size_t)(2 * p->size - 1) * WF_BLOCK + 1, WF_BLOCK);
    return 0;
}

static int part_init(WfRing *s, WfPartition *p, WfError *err)
{
    const WfScenario *sc = s->sc;
    const WfFleet *f = s->f;
    s->part = p;
    wf_partition_blocks(wf_lane_blocks(0, f->n), p->size, p->rank, &s->b_lo, &s->b_hi);
    size_t ns = (size_t)p->size + 1, most_state = 0;
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].model->state_size > most_state) most_state = sc->groups[g].model->state_size;
    /* a packed vehicle: x, v, mode, grade cache, controller memory */
    s->halo_vbytes = 2 * sizeof(double) + 1 + (f->grade_seg ? sizeof(uint32_t) : 0) + most_state;
    s->off = malloc(ns * sizeof *s->off);
    s->group_before = calloc(sc->n_groups * ns, sizeof *s->group_before);
    s->halo_out = malloc(WF_BLOCK * s->halo_vbytes);
    s->halo_in = malloc(WF_BLOCK * s->halo_vbytes);
    if (!s->off || !s->group_before || !s->halo_out || !s->halo_in) return wf_err(err, WF_ESYS, "out of memory");
    for (int r = 1; r <= p->size; r++) {
        size_t lo, hi, lo_prev;
        part_range(s, r - 1, &lo_prev, &hi);
        lo = r < p->size ? hi : f->n;
        for (size_t g = 0; g < sc->n_groups; g++) s->group_before[g * ns + (size_t)r] = s->group_before[g * ns + (size_t)r - 1];
        for (size_t i = lo_prev; i < lo; i++) s->group_before[f->group_id[i] * ns + (size_t)r]++;
    }
    return 0;
}

/* Vehicles [c, c + m) packed (to 0) or unpacked (1), halo_vbytes each. */
static void part_pack(WfRing *s, size_t c, size_t m, unsigned char *buf, int unpack)
{
    WfFleet *f = s->f;
    for (size_t j = 0; j < m; j++, buf += s->halo_vbytes) {
        size_t i = c + j, g = f->group_id[i], ssz = s->sc->groups[g].model->state_size;
        struct { void *p; size_t n; } item[] = {
            {&f->x_m[i], sizeof(double)}, {&f->v_mps[i], sizeof(double)}, {&f->mode[i], 1},
            {f->grade_seg ? &f->grade_seg[i] : NULL, sizeof(uint32_t)},
            {ssz ? f->group_state[g] + wf_fleet_slot(f, i) * ssz : NULL, ssz}};
        unsigned char *q = buf;
        for (size_t k = 0; k < sizeof item / sizeof item[0]; k++) {
            if (!item[k].p) continue;
            if (unpack)
                memcpy(item[k].p, q, item[k].n);
            else
                memcpy(q, item[k].p, item[k].n);
            q += item[k].n;
        }
    }
}

/* The next part's first m vehicles, as they are now, into this rank's arrays (m = 1: its first vehicle): part_post
 * sends this part's first m and returns at once, part_wait completes the exchange and unpacks what came;
 * part_refresh does both. */
static int part_post(WfRing *s, size_t m, WfError *err)
{
    WfPartition *p = s->part;
    size_t lo, hi;
    part_range(s, p->rank, &lo, &hi);
    part_pack(s, lo, m, s->halo_out, 0);
    s->halo_m = m;
    return p->post_next(p->ctx, s->halo_out, s->halo_in, m * s->halo_vbytes, err);
}

static int part_wait(WfRing *s, WfError *err)
{
    int rc = s->part->wait_next(s->part->ctx, err);
    if (!rc) part_pack(s, part_ahead(s), s->halo_m, s->halo_in, 1);
    return rc;
}

static int part_refresh(WfRing *s, size_t m, WfError *err)
{
    int rc = part_post(s, m, err);
    return rc ? rc : part_wait(s, err);
}

/* WfWindow.halo_ready: a window's halo exchange, posted before the window, completed after its interior chunks. */
static int part_halo_ready(void *ctx)
{
    WfRing *s = ctx;
    return part_wait(s, s->halo_err);
}

/* After this part moved: its front edge against the next part's first vehicle (moved too), then every rank's
 * flags and stop agreed; p->stop_all is what the step loop reads. */
static int part_agree(WfRing *s, int adv, int *flags, WfError *err)
{
    WfPartition *p = s->part;
    int rc = adv ? part_refresh(s, 1, err) : 0;
    if (rc) return rc;
    if (adv) *flags |= wf_lane_chunk_edge(&s->lane, 0, s->f->n, s->b_hi, wf_lane_blocks(0, s->f->n));
    int x = *flags | (p->stop_own ? (int)*p->stop_own << WF_PART_STOP_SHIFT : 0);
    if ((rc = p->or_all(p->ctx, &x, err))) return rc;
    p->stop_all = x >> WF_PART_STOP_SHIFT;
    *flags = x & ((1 << WF_PART_STOP_SHIFT) - 1);
    return 0;
}

/* buf: an array of stride bytes per vehicle (root -1: onto every rank). */
static int part_gather(WfRing *s, void *buf, size_t stride, int root, WfError *err)
{
    WfPartition *p = s->part;
    for (int r = 0; r < p->size; r++) {
        size_t lo, hi;
        part_range(s, r, &lo, &hi);
        s->off[r] = lo * stride;
    }
    s->off[p->size] = s->f->n * stride;
    return p->gather(p->ctx, buf, s->off, root, err);
}

/* WfPartition.chain over this rank's blocks of a record (part_record). */
struct PartFold {
    const WfRing       *s;
    const WfStatsBlock *rec;
    int                 m2;
};
static void part_fold(void *arg, void *buf)
{
    const struct PartFold *pf = arg;
    size_t nb = pf->s->b_hi - pf->s->b_lo;
    const WfStatsBlock *b = pf->rec + pf->s->b_lo;
    if (pf->m2) wf_stats_fold_m2(buf, b, nb);
    else wf_stats_fold(buf, b, nb, pf->s->f->n_classes);
}

/* A record of a ring split across processes from each rank's block sums (rec, indexed by block), combined as one
 * process combines them (wf_stats_combine): the sums run from rank 0 to the last rank in block order and back, then
 * the second moments about the mean the same way, 2R messages of 240 bytes instead of every block onto rank 0.
 * Every rank calls this; rank 0 alone gets the row. */
static int part_record(WfRing *s, const WfStatsBlock *rec, double t, WfTsRow *row, WfError *err)
{
    WfPartition *p = s->part;
    WfStatsFold a;
    wf_stats_fold_begin(&a);
    struct PartFold pf = {s, rec, 0};
    int rc = p->chain(p->ctx, &a, sizeof a, part_fold, &pf, err);
    if (!rc && !p->rank) wf_stats_fold_lane_end(&a, s->sc); /* the mean, which the second pass carries */
    pf.m2 = 1;
    if (!rc) rc = p->chain(p->ctx, &a, sizeof a, part_fold, &pf, err);
    if (!rc && !p->rank) wf_stats_fold_row(&a, s->f->n_classes, t, s->overlaps, row);
    return rc;
}

/* After a numerical fault, which phase_overlaps finds as one process does: positions, speeds and modes onto every
 * rank. */
static int part_gather_motion(WfRing *s, WfError *err)
{
    WfFleet *f = s->f;
    int rc = part_gather(s, f->x_m, sizeof *f->x_m, -1, err);
    if (!rc) rc = part_gather(s, f->v_mps, sizeof *f->v_mps, -1, err);
    if (!rc) rc = part_gather(s, f->mode, sizeof *f->mode, -1, err);
    return rc;
}

/* The safety counts of every rank, into safety_all on every rank (what the summary and a checkpoint read). */
static int part_safety(WfRing *s, WfError *err)
{
    WfPartition *p = s->part;
    s->safety_all = s->lane.safety;
    int rc = p->sum_u64(p->ctx, s->safety_all.steps, WF_MAX_GROUPS, err);
    return rc ? rc : p->sum_u64(p->ctx, s->safety_all.hits, WF_MAX_GROUPS, err);
}

/* WfPartition.chain: the summary's sums over this rank's share, after those of the ranks behind it. */
static void part_summary_add(void *arg, void *buf)
{
    const WfRing *s = arg;
    wf_stats_summary_add(s->f, s->sc, s->f->share_lo, s->f->share_hi, buf);
}

/* Bytes [*lo, *hi) of state block v held by rank r: its share of a per-vehicle array, or its members' run of a
 * group's controller memory (part_init: group_before). */
static void part_block_range(const WfRing *s, const WfStateVar *v, int r, size_t *lo, size_t *hi)
{
    if (v->stride) {
        part_range(s, r, lo, hi);
        *lo *= v->stride, *hi *= v->stride;
        return;
    }
    size_t ns = (size_t)s->part->size + 1;
    for (size_t g = 0; g < s->f->n_groups; g++)
        if (s->f->group_state[g] == v->data) {
            size_t ssz = s->sc->groups[g].model->state_size;
            *lo = s->group_before[g * ns + (size_t)r] * ssz, *hi = s->group_before[g * ns + (size_t)r + 1] * ssz;
            return;
        }
    *lo = *hi = 0;
}

/* Rank r's bytes [lo, hi) of block v onto rank 0 (every rank calls this; nothing moves for rank 0's own). */
static int part_gather_piece(WfRing *s, const WfStateVar *v, int r, size_t lo, size_t hi, WfError *err)
{
    return r ? wf_partition_from(s->part, v->data, r, lo, hi, 0, s->off, err) : 0;
}

/* WfBoundary.state_pieces (wf_sim_state_pieces): a split ring's blocks held in shares come to rank 0 one share at a
 * time, each handed to fn and its pages given back (but rank 0's own). */
static int ring_state_pieces(void *eng, const WfStateVar *vars, size_t nv, WfStatePieceFn fn, void *ctx, WfError *err)
{
    WfRing *s = eng;
    WfPartition *p = s->part;
    int rc = 0, frc = 0;
    for (size_t j = 0; !rc && j < nv; j++) {
        if (!p || !vars[j].partial) {
            if (fn && !frc && (!p || !p->rank)) frc = fn(ctx, j, 0, vars[j].size, err);
            continue;
        }
        for (int r = 0; !rc && r < p->size; r++) {
            size_t lo, hi;
            part_block_range(s, &vars[j], r, &lo, &hi);
            if ((rc = part_gather_piece(s, &vars[j], r, lo, hi, err)) || p->rank) continue;
            if (fn && !frc) frc = fn(ctx, j, lo, hi, err);
            if (r) wf_mem_release((char *)vars[j].data + lo, hi - lo);
        }
    }
    return rc ? rc : frc;
}

/* The ring's vehicles a share at a time on rank 0, in ring order (WfBoundary.shares): each other rank's share is
 * gathered into rank 0's arrays, handed to fn (rank 0 only) and its pages given back, so that rank 0 never holds
 * more than its own share and one other. Every rank calls this; an error of fn skips fn for the later shares but
 * not the gathers, which every rank makes. One process: fn over the whole ring. */
static int ring_shares(void *eng, WfShareFn fn, void *ctx, WfError *err)
{
    WfRing *s = eng;
    WfPartition *p = s->part;
    if (!p) return fn ? fn(ctx, 0, s->f->n, err) : 0;
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = ring_state(s, vars, WF_MAX_STATE_VARS);
    int rc = 0, frc = 0;
    for (int r = 0; !rc && r < p->size; r++) {
        size_t lo, hi;
        part_range(s, r, &lo, &hi);
        for (size_t j = 0; !rc && j < nv; j++)
            if (vars[j].stride)
                rc = part_gather_piece(s, &vars[j], r, lo * vars[j].stride, hi * vars[j].stride, err);
        if (rc || p->rank) continue;
        if (fn && !frc) frc = fn(ctx, lo, hi, err);
        for (size_t j = 0; r && j < nv; j++)
            if (vars[j].stride) wf_mem_release((char *)vars[j].data + lo * vars[j].stride, (hi - lo) * vars[j].stride);
    }
    return rc ? rc : frc;
}

/* One pass of a step over this part (src/core/block.c: wf_lane_step_part), its leader refreshed first; *flags:
 * every rank's. */
static int part_step(WfRing *s, long step, int pass, int in_window, WfStatsBlock *rec, int *flags, WfError *err)
{
    int rc = part_refresh(s, 1, err);
    if (rc) return rc;
    s->lane_nb[0] = wf_lane_blocks(0, s->f->n); /* the record's blocks (lanes_record) */
    *flags = wf_lane_step_part(&s->lane, 0, s->f->n, s->b_lo, s->b_hi, NULL, step, pass, in_window, rec);
    return part_agree(s, (pass & WF_PASS_ADVANCE) != 0, flags, err);
}

/* The members of the groups commanded from outside (WfRing.members); 0 or an error. */
static int members_init(WfRing *s, WfError *err)
{
    const WfFleet *f = s->f;
    size_t total = 0;
    for (size_t g = 0; g < f->n_groups; g++) {
        s->member_off[g] = total;
        total += s->sc->groups[g].model->external ? f->group_n[g] : 0;
    }
    s->member_off[f->n_groups] = total;
    if (!total || f->n_lanes > 1) return 0;
    if (!(s->members = malloc(total * sizeof *s->members))) return wf_err(err, WF_ESYS, "out of memory");
    size_t fill[WF_MAX_GROUPS];
    memcpy(fill, s->member_off, f->n_groups * sizeof *fill);
    for (size_t i = 0; i < f->n; i++)
        if (s->sc->groups[f->group_id[i]].model->external) s->members[fill[f->group_id[i]]++] = (uint32_t)i;
    return 0;
}

/* The pages of the per-vehicle state this process steps (and of its windows' copy), taken at creation rather than
 * by the step loop (util/mem.h): the sums are first touched by `+=`, which would map the zero page and fault again
 * on the write. Only this process's share of a ring split across processes (docs/mpi.md, Memory). A share of fewer
 * than WF_PAR_MIN vehicles (arrays of at most 32 kB: a few pages) is left to the step, without the system calls (an
 * RL environment's ring is created every episode). */
static void prefault_share(WfRing *s)
{
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t n = s->f->n, lo = s->b_lo * WF_BLOCK, hi = s->b_hi * WF_BLOCK < n ? s->b_hi * WF_BLOCK : n;
    if (hi - lo < WF_PAR_MIN) return;
    size_t nv = ring_state(s, vars, WF_MAX_STATE_VARS);
    if (nv > WF_MAX_STATE_VARS) nv = WF_MAX_STATE_VARS;
    int nt = wf_lane_threads(hi - lo, s->nthreads); /* the kernel clears new pages: split between the threads */
    WF_PAR_FOR(nt > 1, "omp parallel for schedule(static, 1) num_threads(nt) default(none) shared(s, vars, nv, lo, hi, nt)",
    for (int t = 0; t < nt; t++) {
        for (size_t j = 0; j < nv; j++)
            if (vars[j].stride)
                wf_mem_prefault((char *)vars[j].data + lo * vars[j].stride, (hi - lo) * vars[j].stride, t, nt);
        if (s->win.backup) wf_window_prefault(&s->win, vars, nv, t, nt);
    });
}

static int ring_create(WfSim *sim, WfError *err)
{
    const WfScenario *sc = sim->sc;
    WfRing *s = calloc(1, sizeof *s);
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    sim->eng = s;
    sim->steps_done = &s->steps_done;
    sim->win = &s->win, sim->gov = &s->gov;
    sim->phase_s = s->phase_s;
    s->sim = sim;
    s->sc = sc;
    s->nthreads = sim->nthreads;
    int rc = sc->adaptive ? 0 : wf_integrator_find(sc->integrator, &s->ig, err);
    if (!rc && sim->part) rc = part_check(sc, sim->part, err);
    if (!rc) rc = wf_fleet_create_part(sc, sim->part, &s->f, err);
    if (rc) return rc;
    s->n_steps = wf_scenario_n_steps(sc);
    s->out_every = wf_scenario_output_every(sc);
    s->traj_every = wf_scenario_trajectory_every(sc);
    s->warm_steps = (long)ceil(sc->warmup_s / sc->dt_s - 1e-9);
    s->fault_vehicle = -1;
    s->stat_blocks = malloc((wf_lane_blocks(0, s->f->n) + s->f->n_lanes + 1) * sizeof *s->stat_blocks);
    for (size_t g = 0; g < sc->n_groups; g++) s->noisy |= sc->groups[g].noise_mps2 > 0.0;
    for (size_t g = 0; g < sc->n_groups; g++) s->stateful |= sc->groups[g].model->state_size > 0;
    s->bound_x = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    s->bound_v = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    s->chunks = calloc((size_t)s->nthreads + 1, sizeof *s->chunks);
    if (!s->stat_blocks || !s->bound_x || !s->bound_v || !s->chunks)
        rc = wf_err(err, WF_ESYS, "out of memory");
    if (!rc && sc->adaptive) rc = ode_init(s, err);
    if (!rc) rc = wf_lanes_create(&s->lcs, sc, s->f->n, s->f->n_lanes, err);
    if (!rc && s->f->n_lanes > 1) {
        s->lane_row_len = 3 + s->f->n_lanes * WF_LANE_N_COLS;
        s->lane_rows_max = (size_t)wf_scenario_records(sc, s->out_every);
        if (!(s->lane_rows = calloc(s->lane_rows_max * s->lane_row_len, sizeof *s->lane_rows)))
            rc = wf_err(err, WF_ESYS, "out of memory for the lane records");
    }
    s->b_hi = wf_lane_blocks(0, s->f->n);
    if (!rc && sim->part) rc = part_init(s, sim->part, err);
    if (!rc) lane_init(s);
    if (!rc) lane_views(s);
    if (!rc) rc = window_init(s, err);
    s->win_threads = s->win.nthreads;
    /* only rings that threads can share are timed: a shorter one steps on one thread whatever the count */
    int shared = wf_lane_threads((s->b_hi - s->b_lo) * WF_BLOCK, s->nthreads) > 1;
    wf_governor_init(&s->gov, shared ? s->nthreads : 1, sc->thread_check_steps, 0);
    if (!rc) rc = members_init(s, err);
    if (!rc) prefault_share(s);
    return rc;
}

/* ------------------------------------------------------------------------------------------- the step */

/* The right-hand side for the SUNDIALS integrators: the kernel's acceleration at (x, v). Speeds never go negative:
 * dx/dt = max(v, 0), and a vehicle at rest that is told to brake stays at rest (dv/dt = 0); the fuel rate uses the
 * acceleration actually applied. Noise and controller memory are held for the current time step (piecewise
 * constant), so the function is pure in (t, x, v). */
static int ode_rhs(void *ctx, double t, const double *x, const double *v, double *xdot, double *vdot, double *fuel)
{
    (void)t;
    WfRing *s = ctx;
    WfFleet *f = s->f;
    WfLane *ln = &s->lane;
    size_t n = f->n;
    ln->x_m = (double *)x, ln->v_mps = (double *)v;
    wf_lane_step(ln, 0, n, NULL, s->cur_step, WF_PASS_ACCEL, 0, NULL);
    ln->x_m = f->x_m, ln->v_mps = f->v_mps;
    const double *a = ln->out.a_mps2;
    int bad = 0;
    WF_PAR_FOR(n >= WF_PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, v, a, xdot, vdot) reduction(| : bad)",
    for (size_t i = 0; i < n; i++) {
        double vi = v[i] > 0.0 ? v[i] : 0.0;
        xdot[i] = vi;
        vdot[i] = (v[i] <= 0.0 && a[i] < 0.0) ? 0.0 : a[i];
        bad |= !isfinite(vdot[i]) || !isfinite(x[i]);
    });
    if (bad) return -1; /* a non-finite state is not recoverable by a smaller step */
    if (fuel) {
        /* energy at the clamped speed and applied acceleration */
        double *vp = s->vplus;
        for (size_t i = 0; i < n; i++) vp[i] = v[i] > 0.0 ? v[i] : 0.0;
        wf_lane_energy(ln, 0, n, vp, vdot, f->theta_rad, f->fuel_rate_gps, f->flag);
        memcpy(fuel, f->fuel_rate_gps, n * sizeof *fuel);
    }
    return 0;
}

/* The advance with a SUNDIALS integrator: the solver moves the whole state over the step; the fuel of the step is
 * its exact integral (quadrature) instead of the left-point rule. The right-hand side jumps where the noise or the
 * controller memory changes, and the state jumps at an overlap repair: the solver restarts there rather than
 * integrate across the discontinuity. */
static int advance_ode(WfRing *s, long step, int in_window, WfError *err)
{
    WfFleet *f = s->f;
    WfLane *ln = &s->lane;
    size_t n = f->n;
    double t = (double)step * s->sc->dt_s;
    int rc = 0;
    if (step > 0 && (s->noisy || s->stateful || s->repaired) && (rc = wf_ode_reinit(s->ode, t, f->x_m, f->v_mps, err)))
        return rc;
    memcpy(s->xold, f->x_m, n * sizeof *f->x_m);
    memcpy(s->vold, f->v_mps, n * sizeof *f->v_mps);
    wf_lane_stats_before(ln, 0, n, in_window);
    if ((rc = wf_ode_advance(s->ode, t + s->sc->dt_s, f->x_m, f->v_mps, s->fuel_step, err))) return rc;
    for (size_t i = 0; in_window && i < n; i++) f->fuel_g[i] += s->fuel_step[i];
    wf_lane_stats_after(ln, 0, n, in_window);
    if (s->stateful) {
        /* Memory advances with the inputs of the step's start (gaps and leader speeds at xold, vold). */
        ln->x_m = s->xold, ln->v_mps = s->vold;
        wf_lane_step(ln, 0, n, NULL, step, WF_PASS_ACCEL, 0, NULL);
        ln->x_m = f->x_m, ln->v_mps = f->v_mps;
        wf_lane_controllers(ln, 0, n, f->v_mps);
    }
    return 0;
}

/* After a step that flagged: the first vehicle with a non-finite state (s->fault_vehicle), or the overlaps repaired
 * lane by lane from the front (a vehicle overlapping its leader is put right behind it, at rest). */
static long phase_overlaps(WfRing *s)
{
    WfFleet *f = s->f;
    size_t n = f->n;
    double L = s->sc->road.length_m;
    const double *x = f->x_m, *v = f->v_mps;
    const uint8_t *mode = f->mode;
    long bad = 0, nonfinite = 0;
    WF_PAR_FOR(n >= WF_PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, v, f, L, mode) reduction(+ : bad, nonfinite)",
    for (size_t i = 0; i < n; i++) {
        double lap;
        size_t lead = wf_lanes_leader(f, L, i, &lap);
        bad += x[lead] + lap - wf_fleet_length(f, lead) - x[i] < 0.0;
        nonfinite += !isfinite(x[i]) || !isfinite(v[i]) || (mode[i] & WF_MODE_FAULT);
    });
    /* A non-finite state, acceleration or fuel rate is a numerical fault: the run stops (see wf_sim_run). */
    if (nonfinite) {
        for (size_t i = 0; i < n; i++)
            if (!isfinite(x[i]) || !isfinite(v[i]) || (mode[i] & WF_MODE_FAULT)) {
                s->fault_vehicle = (long)i;
                break;
            }
        return 0;
    }
    if (!bad) return 0;
    long total = 0;
    for (size_t l = 0, first = 0; l < f->n_lanes; first += f->lane_n[l++]) {
        size_t nl = f->lane_n[l];
        for (int pass = 0; nl >= 2 && pass < 3; pass++) {
            long fixed = 0;
            for (size_t j = first + nl; j-- > first;) {
                double lap;
                size_t lead = wf_lanes_leader(f, L, j, &lap);
                double xl = f->x_m[lead] + lap;
                if (xl - wf_fleet_length(f, lead) - f->x_m[j] < 0.0) {
                    /* Distance and passages follow the repaired position (they are taken from positions). */
                    f->x_m[j] = xl - wf_fleet_length(f, lead);
                    f->v_mps[j] = 0.0;
                    fixed++;
                }
            }
            s->overlaps += fixed;
            total += fixed;
            if (!fixed) break;
        }
    }
    return total;
}

/* One backward sweep of the overlap repair over this rank's share (part_overlaps): *lead_x, the position of its last
 * vehicle's leader (lap included) as the share ahead left it, becomes its first vehicle's. */
static long part_sweep(WfRing *s, double *lead_x)
{
    WfFleet *f = s->f;
    size_t lo = f->share_lo, hi = f->share_hi;
    long fixed = 0;
    for (size_t j = hi; j-- > lo;) {
        size_t lead = j + 1 < f->n ? j + 1 : 0;
        double xl = j + 1 < hi ? f->x_m[lead] + 0.0 : *lead_x;
        if (xl - wf_fleet_length(f, lead) - f->x_m[j] < 0.0) {
            f->x_m[j] = xl - wf_fleet_length(f, lead);
            f->v_mps[j] = 0.0;
            fixed++;
        }
    }
    *lead_x = f->x_m[lo];
    return fixed;
}

/* phase_overlaps for a ring split across processes, without the whole ring on any rank: the same sweeps from the
 * ring's last vehicle to its first, each share after the share ahead of it (from the last rank to rank 0, one message
 * of 8 bytes a rank), the last rank's last vehicle behind vehicle 0 as the sweep found it; the fixes of each sweep
 * summed over the ranks. A numerical fault anywhere gathers the whole ring's motion first, as before, so that
 * phase_overlaps names the vehicle as one process does. Every rank calls this. */
static int part_overlaps(WfRing *s, long *repaired, WfError *err)
{
    WfPartition *p = s->part;
    WfFleet *f = s->f;
    size_t n = f->n, lo = f->share_lo, hi = f->share_hi;
    double L = s->sc->road.length_m;
    uint64_t flags[2] = {0, 0}; /* vehicles with a non-finite state, overlapping vehicles */
    for (size_t i = lo; i < hi; i++) {
        flags[0] += !isfinite(f->x_m[i]) || !isfinite(f->v_mps[i]) || (f->mode[i] & WF_MODE_FAULT);
        size_t lead = i + 1 < n ? i + 1 : 0; /* the next share's first as it moved (part_agree) */
        flags[1] += f->x_m[lead] + (lead ? 0.0 : L) - wf_fleet_length(f, lead) - f->x_m[i] < 0.0;
    }
    int rc = p->sum_u64(p->ctx, flags, 2, err);
    if (rc) return rc;
    if (flags[0]) {
        if (!(rc = part_gather_motion(s, err))) *repaired = phase_overlaps(s);
        return rc;
    }
    *repaired = 0;
    for (int pass = 0; flags[1] && pass < 3; pass++) {
        /* vehicle 0 as rank 0 has it */
        if ((rc = wf_partition_from(p, f->x_m, 0, 0, sizeof *f->x_m, -1, s->off, err))) return rc;
        double lead_x = f->x_m[0] + L, got = 0.0;
        uint64_t fixed[1] = {0};
        if (p->rank == p->size - 1) fixed[0] = (uint64_t)part_sweep(s, &lead_x);
        for (int k = p->size - 1; k > 0; k--) { /* the share of rank k hands its first vehicle to rank k - 1 */
            if ((rc = p->shift(p->ctx, &lead_x, sizeof lead_x, &got, sizeof got, err))) return rc;
            if (p->rank == k - 1) lead_x = got, fixed[0] = (uint64_t)part_sweep(s, &lead_x);
        }
        if ((rc = p->sum_u64(p->ctx, fixed, 1, err))) return rc;
        s->overlaps += (int64_t)fixed[0];
        *repaired += (long)fixed[0];
        if (!fixed[0]) break;
    }
    return 0;
}

/* The error of a numerical fault: which vehicle, when, its model and the inputs of the step that failed. */
static int numerical_fault(WfRing *s, long step, WfError *err)
{
    const WfFleet *f = s->f;
    double lap;
    size_t i = (size_t)s->fault_vehicle, lead = wf_lanes_leader(f, s->sc->road.length_m, i, &lap);
    const WfDriverGroup *g = &s->sc->groups[f->group_id[i]];
    return wf_err(err, WF_ESYS,
                  "numerical fault at t = %.9g s: vehicle %zu (driver group '%s', model %s, class %s): a non-finite "
                  "acceleration, fuel rate or state (now x = %g m, v = %g m/s; leader vehicle %zu at v = %g m/s); "
                  "partial results kept",
                  (double)(step + 1) * s->sc->dt_s, f->id ? (size_t)f->id[i] : i, g->name, g->model->name, s->sc->classes[f->class_id[i]].vc.name,
                  f->x_m[i], f->v_mps[i], f->id ? (size_t)f->id[lead] : lead, f->v_mps[lead]);
}


/* The phases' wall times go to the result file alone: a run without one (Python, RL environments stepping one step
 * per call) does not read the clock for them, which costs some 30 ns a read on a VM, 3 % of a 22-vehicle ring's
 * step. */
static double phase_start(const WfRing *s) { return s->sim->out ? wf_wall_now() : 0.0; }

static void lap(WfRing *s, int phase, double *tp)
{
    if (!s->sim->out) return;
    double tq = wf_wall_now();
    s->phase_s[phase] += tq - *tp;
    *tp = tq;
}

/* A multi-lane ring's lanes at a record (/lanes): each lane's record from its own blocks. */
static void lanes_observe(WfRing *s, const WfStatsBlock *rec, double t)
{
    const WfFleet *f = s->f;
    double *row;
    if (f->n_lanes < 2 || !(row = wf_lane_row(s->lane_rows, s->lane_row_len, s->lane_rows_max, &s->lk.n_rows,
                                              &s->lk.rec_changes, &s->lk.rec_cut_ins, t)))
        return;
    for (size_t l = 0; l < f->n_lanes; l++) {
        WfTsRow lr;
        if (s->lane_nb[l]) wf_stats_combine(rec, s->lane_nb[l], f->n_classes, s->sc, t, s->overlaps, &lr);
        static const int from[] = {WF_TS_MEAN_V, WF_TS_SD_V, WF_TS_WAVES,
                                   WF_TS_FUEL_RATE, WF_TS_MEAN_GAP, WF_TS_FRAC_STOPPED};
        wf_lane_values(lr.v, from, (double)f->lane_n[l], s->sc->road.length_m, row + l * WF_LANE_N_COLS);
        rec += s->lane_nb[l];
    }
}

/* The record of instant t from its statistics blocks (each lane's: s->lane_nb): split across processes, gathered
 * onto rank 0, which alone records; its /lanes row, the time-averaged s.d.'s sum, the output. */
static int ring_record(WfRing *s, const WfStatsBlock *blocks, double t, int in_window, double *tp, WfError *err)
{
    WfTsRow row;
    int rc = s->part ? part_record(s, blocks, t, &row, err) : 0;
    if (rc || (s->part && s->part->rank)) return rc;
    if (!s->part) lanes_record(s, blocks, t, &row);
    lanes_observe(s, blocks, t);
    if (in_window) s->sd_sum += row.v[WF_TS_SD_V], s->n_sd++;
    lap(s, WF_PHASE_STATISTICS, tp);
    WfRecord rec = {row.v, WF_TS_N_COLS, row.class_fuel_rate_gps};
    const WfOutput *out = s->sim->out;
    if (out && out->record && (rc = out->record(out->ctx, s->sim, &rec, err))) return rc;
    lap(s, WF_PHASE_OUTPUT, tp);
    return 0;
}

/* k steps in one window; *done 0 when some step overlapped or faulted: the state is as before, the steps are then
 * taken one at a time (their repairs and errors are the per-step path's). Records in step order. */
static int ring_window(WfRing *s, long step, long k, int *done, WfError *err)
{
    const WfScenario *sc = s->sc;
    size_t nb = s->win.nb, rows, j = 0;
    int in_window = step >= s->warm_steps, rc = 0;
    double tp = phase_start(s);
    if (step == s->warm_steps && !s->f->window_open) wf_fleet_open_window(s->f);
    lane_exports(s, 0);
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = ring_state(s, vars, WF_MAX_STATE_VARS);
    /* split across processes, the next part's first k + 1 vehicles travel while this part's interior steps */
    if (s->part && (rc = s->win.halo_ready ? part_post(s, (size_t)k + 1, err) : part_refresh(s, (size_t)k + 1, err)))
        return rc;
    s->halo_err = err;
    int flags = wf_window_run(&s->win, &s->lane, s->f->n, step, (int)k, in_window, vars, nv, &rows);
    if (s->win.halo_rc) return s->win.halo_rc;
    if (s->part && (rc = part_agree(s, 1, &flags, err))) return rc;
    wf_window_settle(&s->win, &s->lane, vars, nv, flags);
    lap(s, WF_PHASE_FUSED, &tp);
    if ((*done = !flags) == 0) return 0;
    s->repaired = 0;
    for (long q = step; q < step + k && j < rows && !rc; q++)
        if (q % s->out_every == 0) rc = ring_record(s, s->win.rec + nb * j++, (double)q * sc->dt_s, in_window, &tp, err);
    return rc;
}

/* The lane changes at the start of a step of a multi-lane ring (src/core/lanes.h), every per-vehicle array of the
 * state moving with its vehicle. */
static void lane_changes(WfRing *s, long step)
{
    if (!s->lcs.active) return;
    WfLcRoad r;
    wf_lanes_ring_road(&s->lcs, s->sc, s->f, &r);
    if (!wf_lanes_decide(&s->lcs, &r, step, s->lane.nthreads)) return;
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = ring_state(s, vars, WF_MAX_STATE_VARS);
    int64_t cut0 = s->lk.total.cut_ins, ch0 = s->lk.total.changes;
    wf_lanes_apply_ring(&s->lcs, &r, s->f, step, vars, nv, &s->lk.total);
    lane_views(s);
    s->lk.rec_changes += s->lk.total.changes - ch0, s->lk.rec_cut_ins += s->lk.total.cut_ins - cut0;
}

/* A window of steps (ring_window) when one fits before max_steps, else one step: the pass that computes the step's
 * values (and, fused, advances), the record and the trajectory at the step's start, then the advance when it is a
 * pass of its own, and the overlap repair. *steps: the steps taken. Returns WF_LOOP_END after the final instant
 * (recorded without a step), 0 after the steps, or an error code. */
static int ring_advance(WfRing *s, long step, long max_steps, long *steps, WfError *err)
{
    long k = wf_window_steps(&s->win, step, max_steps, s->n_steps, s->warm_steps,
                             s->sc->trajectories ? s->traj_every : 0, 0);
    *steps = 1;
    if (k > 1) {
        int done, rc = ring_window(s, step, k, &done, err);
        if (rc || done) {
            *steps = k;
            return rc;
        }
    }
    const WfOutput *out = s->sim->out;
    const WfScenario *sc = s->sc;
    int in_window = step >= s->warm_steps, records = step % s->out_every == 0, last = step == s->n_steps, rc = 0;
    int traj = sc->trajectories && step % s->traj_every == 0, fused = !s->ode && sc->fused_step && !traj;
    double t = (double)step * sc->dt_s, tp = phase_start(s);
    if (step == s->warm_steps && !s->f->window_open) wf_fleet_open_window(s->f);
    if (s->f->n_lanes > 1 && step > 0 && !last) lane_changes(s, step);
    lane_exports(s, !fused);
    s->cur_step = step;
    int pass = (fused && !last ? WF_PASS_FUSED : WF_PASS_ACCEL | WF_PASS_ENERGY) | (last ? 0 : WF_PASS_COUNT);
    int flags;
    if (s->part && (rc = part_step(s, step, pass, in_window, records ? s->stat_blocks : NULL, &flags, err))) return rc;
    if (!s->part) flags = lanes_step(s, step, pass, in_window, records ? s->stat_blocks : NULL);
    lap(s, fused ? WF_PHASE_FUSED : WF_PHASE_CAR_FOLLOWING, &tp);
    if (records && (rc = ring_record(s, s->stat_blocks, t, in_window, &tp, err))) return rc;
    if (traj && out && out->trajectory) {
        if ((rc = out->trajectory(out->ctx, s->sim, t, err))) return rc;
        lap(s, WF_PHASE_OUTPUT, &tp);
    }
    if (last) return WF_LOOP_END;
    for (size_t l = 0; s->f->n_lanes > 1 && l < s->f->n_lanes; l++)
        s->lk.total.lane_vehicle_s[l] += (double)s->f->lane_n[l] * sc->dt_s;
    if (s->ode) {
        if ((rc = advance_ode(s, step, in_window, err))) return rc;
        flags = WF_STEP_OVERLAP; /* the solver's state is checked in full */
    } else if (!fused) {
        flags = lanes_step(s, step, WF_PASS_ADVANCE, in_window, NULL);
    }
    long fixed = 0;
    if (flags && s->part && (rc = part_overlaps(s, &fixed, err))) return rc;
    if (flags && !s->part) fixed = phase_overlaps(s);
    s->repaired = fixed > 0;
    /* A fused step without an overlap did its integration in its one pass: no clock read (a small ring's step
     * costs a few of them: RL environments step many). */
    if (!fused || flags) lap(s, WF_PHASE_INTEGRATION, &tp);
    if (s->fault_vehicle >= 0) return numerical_fault(s, step, err);
    return 0;
}

/* ring_advance on the threads the governor chose (the same bits on any count), timed for it. */
static int ring_step(void *eng, long step, long max_steps, long *steps, WfError *err)
{
    WfRing *s = eng;
    int nt = wf_governor_threads(&s->gov);
    s->lane.nthreads = nt;
    if (s->win.k_max) wf_window_threads(&s->win, nt < s->win_threads ? nt : s->win_threads);
    /* a probe cuts windows where it ends, on one process only: split across processes every rank steps windows of
     * the same steps (their halos and agreements pair up), whatever each one's threads */
    long left = s->part ? LONG_MAX : wf_governor_probe_left(&s->gov);
    if (left < max_steps) max_steps = left;
    double t0 = s->gov.every ? wf_wall_now() : 0.0;
    int rc = ring_advance(s, step, max_steps, steps, err);
    if (t0 > 0.0 && !rc)
        wf_governor_done(&s->gov, wf_wall_now() - t0, (double)s->f->n * (double)*steps, *steps);
    return rc;
}

/* A multi-lane ring's safety counts: each lane's, summed into the ring's lane (what the summary and the checkpoint
 * read); restored, they stay with lane 0's view. */
static void lanes_safety(WfRing *s, int restore)
{
    if (s->f->n_lanes < 2) return;
    WfSafetyCount *all = &s->lane.safety;
    if (restore) {
        for (size_t l = 0; l < s->f->n_lanes; l++) s->lanes[l].safety = l ? (WfSafetyCount){{0}, {0}} : *all;
        return;
    }
    *all = (WfSafetyCount){{0}, {0}};
    for (size_t l = 0; l < s->f->n_lanes; l++)
        for (size_t g = 0; g < WF_MAX_GROUPS; g++)
            all->steps[g] += s->lanes[l].safety.steps[g], all->hits[g] += s->lanes[l].safety.hits[g];
}

/* Before a checkpoint of a ring split across processes: every rank's safety counts (the checkpoint's per-vehicle
 * blocks and controller memory come to rank 0 a share at a time: ring_state_pieces). */
static int ring_flush(void *eng, WfError *err)
{
    WfRing *s = eng;
    return s->part ? part_safety(s, err) : 0;
}

/* The run's totals (also after an interruption or an error). Split across processes, the vehicles' sums run along
 * the ranks in ring order and rank 0 alone makes the summary; no rank gathers the state (ring_shares does, a
 * share at a time, for the result's per-vehicle datasets). */
static int ring_close(void *eng, WfError *err)
{
    WfRing *s = eng;
    lanes_safety(s, 0);
    WfSummarySums sums;
    memset(&sums, 0, sizeof sums);
    int rc = s->part ? part_safety(s, err) : 0;
    if (!rc && s->part) rc = s->part->chain(s->part->ctx, &sums, sizeof sums, part_summary_add, s, err);
    if (rc || (s->part && s->part->rank)) return rc;
    if (!s->part) wf_stats_summary_add(s->f, s->sc, 0, s->f->n, &sums);
    long window = s->steps_done - s->warm_steps;
    wf_stats_summary_end(s->f, s->sc, &sums, s->sd_sum, s->n_sd, window > 0 ? window : 0, s->overlaps,
                         &s->sim->summary);
    WfLane all = s->lane;
    if (s->part) all.safety = s->safety_all;
    wf_lane_safety_summary(&all, &s->sim->summary);
    s->sim->summary.lane_changes = s->lk.total.changes, s->sim->summary.cut_ins = s->lk.total.cut_ins;
    return 0;
}

const WfFleet *wf_ring_fleet(const WfSim *sim)
{
    return sim->b == &wf_boundary_periodic ? ((const WfRing *)sim->eng)->f : NULL;
}

const WfFleet *wf_sim_fleet(const WfSim *sim)
{
    wf_sim_sync((WfSim *)sim); /* the arrays' values as a step leaves them (the run itself is not const) */
    return wf_ring_fleet(sim);
}

/* The lane observers (wf_sim_lanes); every vehicle was on the ring the whole time run so far. */
static int ring_lanes(const void *eng, WfLaneObs *out)
{
    const WfRing *s = eng;
    if (s->f->n_lanes < 2) return 0;
    *out = (WfLaneObs){.n_lanes = s->f->n_lanes, .n_rows = (size_t)s->lk.n_rows, .row_len = s->lane_row_len,
                       .rows = s->lane_rows, .pair = &s->lk.total.pair[0][0], .lane_cut_ins = s->lk.total.lane_cut_ins,
                       .group_changes = s->lk.total.group_changes, .group_cut_ins = s->lk.total.group_cut_ins,
                       .lane_vehicle_s = s->lk.total.lane_vehicle_s};
    for (size_t g = 0; g < s->f->n_groups; g++)
        out->group_vehicle_s[g] = (double)s->f->group_n[g] * ((double)s->steps_done * s->sc->dt_s);
    return 1;
}

int wf_sim_ode_stats(const WfSim *sim, WfOdeStats *st)
{
    const WfRing *s = sim->b == &wf_boundary_periodic ? sim->eng : NULL;
    if (!s || !s->ode) return 0;
    wf_ode_stats(s->ode, st);
    return 1;
}

const char *const wf_phase_names[WF_N_PHASES] = {"car_following", "energy", "integration", "statistics", "output",
                                                  "fused_step"};

static size_t ring_state(void *eng, WfStateVar *vars, size_t max)
{
    WfRing *s = eng;
    WfFleet *f = s->f;
    size_t n = f->n, k = 0;
    s->ck.steps_done = s->steps_done;
    s->ck.overlaps = s->overlaps;
    s->ck.n_sd = s->n_sd;
    s->ck.repaired = s->repaired;
    s->ck.sd_sum = s->sd_sum;
    s->ck.window_open = f->window_open;
    for (size_t l = 0; l < f->n_lanes; l++) s->lk.lane_n[l] = f->lane_n[l];
    lanes_safety(s, 0);
#define VAR(nm, ptr, bytes)                                                  \
    do {                                                                     \
        if (k < max) vars[k] = (WfStateVar){.name = (nm), .data = (void *)(ptr), .size = (bytes)}; \
        k++;                                                                 \
    } while (0)
    /* a per-vehicle array: time-blocked windows copy it tile by tile; split across processes, this rank's share is
     * its part */
#define VEH(nm, ptr)                                                                                      \
    do {                                                                                                 \
        if (k < max) vars[k] = (WfStateVar){(nm), (void *)(ptr), n * sizeof *(ptr), sizeof *(ptr), s->part != NULL, \
                                            f->share_lo * sizeof *(ptr), f->share_hi * sizeof *(ptr)};           \
        k++;                                                                                             \
    } while (0)
    VAR("scalars", &s->ck, sizeof s->ck);
    VEH("x", f->x_m);
    VEH("v", f->v_mps);
    if (f->grade_seg) VEH("grade_seg", f->grade_seg); /* NULL on a flat road */
    VEH("x_start", f->x_start_m);
    VEH("fuel", f->fuel_g);
    VEH("stopped_steps", f->stopped_steps);
    VEH("sum_v", f->sum_v);
    VEH("sum_v2", f->sum_v2);
    VEH("sum_a", f->sum_a);
    VEH("sum_a2", f->sum_a2);
    VEH("stops", f->stops);
    VEH("hard_brakes", f->hard_brakes);
    VEH("infeasible_steps", f->infeasible_steps);
    VEH("mode", f->mode);
    if (f->n_lanes > 1) { /* vehicles move between slots: what they are moves with them */
        VAR("lanes", &s->lk, sizeof s->lk);
        VAR("lane_rows", s->lane_rows, s->lane_rows_max * s->lane_row_len * sizeof *s->lane_rows);
        VEH("class", f->class_id);
        VEH("group", f->group_id);
        if (f->slot) VEH("slot", f->slot);
        VEH("lane", f->lane);
        VEH("id", f->id);
        VEH("lc_ready_step", f->lc_ready_step);
        VEH("lane_changes", f->lane_changes);
        VEH("cut_ins", f->cut_ins);
        VEH("lap", f->lap_m);
    }
    /* absent without a safety filter; split across processes, every rank's (part_safety) */
    if (s->lane.safe) VAR("safety", s->part ? &s->safety_all : &s->lane.safety, sizeof s->lane.safety);
    static const char *const state_names[WF_MAX_GROUPS] = {"ctrl0", "ctrl1", "ctrl2", "ctrl3", "ctrl4", "ctrl5",
                                                           "ctrl6", "ctrl7", "ctrl8", "ctrl9", "ctrl10", "ctrl11",
                                                           "ctrl12", "ctrl13", "ctrl14", "ctrl15"};
    for (size_t g = 0; g < f->n_groups; g++) {
        size_t ssz = s->sc->groups[g].model->state_size, ns = s->part ? (size_t)s->part->size + 1 : 0;
        if (ssz) VAR(state_names[g], f->group_state[g], f->group_n[g] * ssz);
        if (ssz && s->part && k <= max) /* this rank's members: a run of the group's (part_init) */
            vars[k - 1].partial = 1, vars[k - 1].lo = s->group_before[g * ns + (size_t)s->part->rank] * ssz,
            vars[k - 1].hi = s->group_before[g * ns + (size_t)s->part->rank + 1] * ssz;
    }
#undef VAR
#undef VEH
    return k;
}

static int ring_restored(void *eng, WfError *err)
{
    WfRing *s = eng;
    s->steps_done = (long)s->ck.steps_done;
    s->overlaps = s->ck.overlaps;
    s->n_sd = (long)s->ck.n_sd;
    s->repaired = (int)s->ck.repaired;
    s->sd_sum = s->ck.sd_sum;
    s->f->window_open = (int)s->ck.window_open;
    if (s->part) s->lane.safety = s->part->rank ? (WfSafetyCount){{0}, {0}} : s->safety_all; /* summed at the end */
    WfFleet *f = s->f;
    if (f->n_lanes > 1) {
        size_t total = 0;
        for (size_t l = 0; l < f->n_lanes; l++) total += f->lane_n[l] = (size_t)s->lk.lane_n[l];
        if (total != f->n) return wf_err(err, WF_EINPUT, "checkpoint: the lanes hold %zu vehicles, not %zu", total, f->n);
        for (size_t j = 0; j < f->n; j++) {
            if (f->id[j] >= f->n) return wf_err(err, WF_EINPUT, "checkpoint: slot %zu holds vehicle %u of %zu", j,
                                                (unsigned)f->id[j], f->n);
            f->pos[f->id[j]] = (uint32_t)j;
        }
        lane_views(s);
        lanes_safety(s, 1);
    }
    /* A SUNDIALS solver restarts from the restored state (as after a noise change): exact with noise or
     * controller memory, where the uninterrupted run restarts at every step too; within tolerance otherwise. */
    if (s->ode) {
        WfError e = {0};
        wf_ode_reinit(s->ode, (double)s->steps_done * s->sc->dt_s, s->f->x_m, s->f->v_mps, &e);
    }
    return 0;
}

/* ------------------------------------------------------------- rings stepped side by side (src/core/gang.c) */

WfLane *wf_ring_gang_lane(WfSim *sim)
{
    if (sim->b != &wf_boundary_periodic) return NULL;
    WfRing *s = sim->eng;
    return s->ode || s->part || s->f->n_lanes > 1 ? NULL : &s->lane;
}

/* Steps from `step` before the next multiple of `every` (0 when step is one). */
static long until_due(long step, long every) { return (step + every - 1) / every * every - step; }

long wf_ring_gang_plain(const WfSim *sim, int *in_window)
{
    const WfRing *s = sim->eng;
    long step = s->steps_done, k = s->n_steps - step, rec = until_due(step, s->out_every);
    *in_window = step >= s->warm_steps;
    /* the statistics window open for all of the steps, or closed for all (the step that opens it is ring_step's) */
    if (!wf_ring_gang_lane((WfSim *)sim) || !s->sc->fused_step || (*in_window && !s->f->window_open) ||
        s->fault_vehicle >= 0)
        return 0;
    if (!*in_window) k = s->warm_steps - step < k ? s->warm_steps - step : k;
    k = rec < k ? rec : k;
    if (s->sc->trajectories) {
        long tr = until_due(step, s->traj_every);
        k = tr < k ? tr : k;
    }
    return k > 0 ? k : 0;
}

int wf_ring_gang_settle(WfSim *sim, long step, int flags, WfError *err)
{
    WfRing *s = sim->eng;
    s->cur_step = step;
    s->repaired = flags ? phase_overlaps(s) > 0 : 0;
    return s->fault_vehicle >= 0 ? numerical_fault(s, step, err) : 0;
}

/* Vehicle i of group g, the k-th in ring order: its inputs of the next step to fn. */
static void group_visit(const WfRing *s, size_t g, size_t k, size_t i, WfGroupVisit fn, void *ctx)
{
    const WfFleet *f = s->f;
    double lap;
    size_t l = wf_lanes_leader(f, s->sc->road.length_m, i, &lap), ssz = s->sc->groups[g].model->state_size;
    double gap = (f->x_m[l] + lap) - s->lane.class_length_m[f->class_id[l]] - f->x_m[i];
    fn(ctx, k, f->group_state[g] + wf_fleet_slot(f, i) * ssz, f->v_mps[i], f->v_mps[l], gap);
}

/* Group g's vehicles in ring order (its member list, or a scan of the fleet); the last vehicle's leader is vehicle 0
 * one lap ahead (block.c: front_lead). */
static size_t ring_group(void *eng, size_t g, WfGroupVisit fn, void *ctx)
{
    const WfRing *s = eng;
    const WfFleet *f = s->f;
    if (!fn) return f->group_n[g]; /* a count only: a ring's groups keep their members */
    size_t k = 0;
    if (s->members && s->member_off[g + 1] > s->member_off[g]) {
        for (size_t j = s->member_off[g]; j < s->member_off[g + 1]; j++) group_visit(s, g, k++, s->members[j], fn, ctx);
        return k;
    }
    for (size_t i = 0; i < f->n; i++)
        if (f->group_id[i] == g) group_visit(s, g, k++, i, fn, ctx);
    return k;
}

const WfBoundary wf_boundary_periodic = {.kind = "ring", .create = ring_create, .destroy = ring_destroy,
                                         .step = ring_step, .flush = ring_flush, .close = ring_close, .state = ring_state,
                                         .restored = ring_restored, .group = ring_group, .lanes = ring_lanes,
                                         .shares = ring_shares,
                                         .state_pieces = ring_state_pieces};
