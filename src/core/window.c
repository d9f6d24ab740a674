/* Time-blocked stepping of a periodic lane (window.h). */
#include "core/window.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "util/mem.h"

#define B WF_BLOCK

/* One chunk's scratch: the halo (a copy of the k + 1 vehicles ahead of the chunk, stepped as a lane of its own),
 * the traces of the halo's and of each tile's first vehicle, the leads of the tile being stepped, its counts. */
struct WfHalo {
    double   *x_m, *v_mps, *hx, *hv, *tx, *tv;
    uint8_t  *mode;
    uint32_t *grade_seg, *slot, *sslot;
    unsigned char *state[WF_MAX_GROUPS];
    WfLead   *lead;
    WfRoadOps ops;       /* the lane's hooks but its per-step bookkeeping (moved): a halo's steps are not the lane's */
    WfLane    hl;        /* the lane over the halo */
    WfChunkOut co;       /* the chunk's flags and safety counts */
};

size_t wf_window_tile_default(size_t bytes_per_vehicle)
{
    long l2 = sysconf(_SC_LEVEL2_CACHE_SIZE);
    size_t cache = l2 > 0 ? (size_t)l2 : (size_t)256 << 10; /* unknown: a small L2 */
    size_t v = cache / 2 / (bytes_per_vehicle ? bytes_per_vehicle : 1);
    return v < B ? B : v;
}

int wf_window_steps_default(long out_every)
{
    return out_every > 0 && out_every < WF_WINDOW_STEPS / WF_WINDOW_RECORDS ? (int)(WF_WINDOW_RECORDS * out_every)
                                                                         : WF_WINDOW_STEPS;
}

int wf_window_fits(size_t n, size_t b_lo, size_t b_hi, int nthreads, int k)
{
    size_t m = (b_hi * B < n ? b_hi * B : n) - b_lo * B; /* the vehicles stepped */
    return k >= 2 && k + 1 < B && m / B >= 2 * (size_t)wf_lane_threads(m, nthreads);
}

static void halo_free(WfHalo *h)
{
    WF_FREE(h->x_m, h->v_mps, h->hx, h->hv, h->tx, h->tv, h->mode, h->grade_seg, h->slot, h->sslot, h->lead);
    for (size_t g = 0; g < WF_MAX_GROUPS; g++) free(h->state[g]);
}

static int halo_alloc(WfHalo *h, const WfLane *ln, size_t k)
{
    size_t m = k + 1;
    int ok = (h->x_m = malloc(m * sizeof(double))) && (h->v_mps = malloc(m * sizeof(double))) &&
             (h->hx = malloc(k * sizeof(double))) && (h->hv = malloc(k * sizeof(double))) &&
             (h->tx = malloc(k * sizeof(double))) && (h->tv = malloc(k * sizeof(double))) &&
             (h->mode = malloc(m)) && (h->slot = malloc(m * sizeof(uint32_t))) &&
             (h->sslot = malloc(m * sizeof(uint32_t))) && (h->lead = malloc(k * sizeof(WfLead))) &&
             (!ln->grade_seg || (h->grade_seg = malloc(m * sizeof(uint32_t))));
    for (size_t g = 0; ok && g < ln->sc->n_groups; g++)
        if (ln->sstride[g]) ok = (h->state[g] = malloc(m * ln->sstride[g])) != NULL;
    for (size_t j = 0; ok && j < m; j++) h->sslot[j] = (uint32_t)j;
    return ok;
}

void wf_window_destroy(WfWindow *w)
{
    if (w->halo)
        for (size_t c = 0; c < w->n_halos; c++) halo_free(&w->halo[c]);
    WF_FREE(w->halo, w->rec, w->backup);
    memset(w, 0, sizeof *w);
}

int wf_window_create(WfWindow *w, const WfLane *ln, size_t n, size_t b_lo, size_t b_hi, int k_max,
                     size_t tile_vehicles, long out_every, size_t state_bytes, WfError *err)
{
    size_t m = (b_hi * B < n ? b_hi * B : n) - b_lo * B;
    *w = (WfWindow){.k_max = k_max, .tile_blocks = (tile_vehicles + B - 1) / B, .nb = wf_lane_blocks(0, n),
                    .b_lo = b_lo, .b_hi = b_hi, .n = n, .out_every = out_every, .n_halos = SIZE_MAX};
    if (!w->tile_blocks) w->tile_blocks = 1;
    wf_window_threads(w, wf_lane_threads(m, ln->nthreads)); /* the chunks of all the threads: one halo each */
    w->n_halos = w->n_chunks;
    w->rec_rows = (size_t)k_max / (size_t)out_every + 1;
    w->halo = calloc(w->n_chunks, sizeof *w->halo);
    w->rec = malloc(w->rec_rows * w->nb * sizeof *w->rec);
    w->backup = calloc(state_bytes, 1); /* untouched: the caller takes the pages it will use (wf_window_prefault) */
    int ok = w->halo && w->rec && w->backup;
    for (size_t c = 0; ok && c < w->n_chunks; c++) ok = halo_alloc(&w->halo[c], ln, (size_t)k_max);
    if (ok) return 0;
    wf_window_destroy(w);
    return wf_err(err, WF_ESYS, "out of memory for time-blocked stepping (a copy of the state: %zu bytes; "
                  "time.block_steps: 1 steps one step at a time without it)", state_bytes);
}

long wf_window_steps(const WfWindow *w, long step, long max_steps, long n_steps, long warm_steps, long traj_every,
                     long rec_every)
{
    if (!w->k_max || step < w->per_step_until || (rec_every && step % rec_every == 0)) return 1;
    long k = w->k_max < max_steps ? w->k_max : max_steps;
    if (n_steps - step < k) k = n_steps - step;
    if (step < warm_steps && warm_steps - step < k) k = warm_steps - step;
    if (rec_every && rec_every - step % rec_every < k) k = rec_every - step % rec_every;
    if (traj_every) {
        long r = step % traj_every;
        if (!r) return 1;
        if (traj_every - r < k) k = traj_every - r;
    }
    return k;
}

int wf_window_range(WfWindow *w, size_t first, size_t n, int nthreads)
{
    size_t nb = wf_lane_blocks(first, n);
    int nt = wf_lane_threads(n, nthreads);
    if (w->k_max + 1 >= B || nb < 2 * (size_t)nt || !w->n_halos) return 0;
    w->first = first, w->n = n, w->nb = nb, w->b_lo = 0, w->b_hi = nb;
    wf_window_threads(w, nt);
    return 1;
}

void wf_window_threads(WfWindow *w, int nthreads)
{
    size_t span = w->b_hi - w->b_lo, most = (size_t)WF_WINDOW_CHUNKS * (size_t)nthreads;
    size_t nc = span / 2 < most ? span / 2 : most;
    w->nthreads = nthreads;
    w->n_chunks = nc < w->n_halos ? nc : w->n_halos;
}

/* The first slot of logical block j of the window's range (j = nb: block 0, the periodic wrap). */
static size_t block_slot(const WfWindow *w, const WfLane *ln, size_t j)
{
    size_t lo;
    wf_lane_block_at(ln, w->first, w->n, j % w->nb, &lo);
    return lo;
}

/* The slots of blocks [b0, b1) of the range: one run [lo[0], hi[0]), or two when they wrap around the buffer's end.
 * Returns the number of runs. */
static int block_runs(const WfWindow *w, const WfLane *ln, size_t b0, size_t b1, size_t lo[2], size_t hi[2])
{
    size_t l0, l1, m1 = wf_lane_block_at(ln, w->first, w->n, b1 - 1, &l1);
    wf_lane_block_at(ln, w->first, w->n, b0, &l0);
    lo[0] = l0, hi[0] = l1 + m1;
    if (l1 >= l0) return 1;
    hi[0] = ln->cap, lo[1] = 0, hi[1] = l1 + m1;
    return 2;
}

/* The k + 1 vehicles from slot c as they are at the window's start, and a lane over that copy: the same
 * parameters, classes and noise keys (key0), its own memory, modes and grade cache, no accumulators. */
static WfLane halo_take(WfHalo *h, const WfLane *ln, size_t c, size_t k)
{
    WfLane hl = *ln;
    h->ops = *ln->ops;
    h->ops.moved = NULL;
    hl.ops = &h->ops;
    for (size_t j = 0; j <= k; j++) {
        size_t i = c + j, g = ln->group_id[i], idx = ln->slot ? ln->slot[i] : i;
        h->x_m[j] = ln->x_m[i], h->v_mps[j] = ln->v_mps[i], h->mode[j] = ln->mode[i];
        h->slot[j] = (uint32_t)idx;
        if (h->grade_seg) h->grade_seg[j] = ln->grade_seg[i];
        if (ln->sstride[g]) memcpy(h->state[g] + j * ln->sstride[g], ln->state[g] + idx * ln->sstride[g], ln->sstride[g]);
    }
    hl.x_m = h->x_m, hl.v_mps = h->v_mps, hl.mode = h->mode, hl.grade_seg = h->grade_seg;
    hl.class_id = ln->class_id + c, hl.group_id = ln->group_id + c;
    hl.slot = h->slot, hl.sslot = h->sslot, hl.key0 = ln->key0 + c;
    for (size_t g = 0; g < WF_MAX_GROUPS; g++) hl.state[g] = h->state[g];
    hl.cap = k + 1, hl.period_m = 0.0;
    hl.always = hl.window = (WfAccum){0};
    hl.out = (WfLaneValues){0};
    hl.x_old_m = NULL;
    return hl;
}

/* The trace of the halo's first vehicle over k steps (into hx, hv): its leader, the halo's last vehicle, is held at
 * its position at the start; only the vehicles it does not reach in time matter, and none of them is traced. */
static void halo_run(WfHalo *h, WfLane *hl, size_t k, long step0, int in_window)
{
    for (size_t s = 0; s < k; s++)
        h->lead[s] = (WfLead){h->x_m[k] - hl->class_length_m[hl->class_id[k]], h->v_mps[k], 0.0};
    wf_lane_tile(hl, 0, k, 0, 1, step0, (int)k, h->lead, h->hx, h->hv, WF_PASS_FUSED, in_window, NULL, NULL);
}

/* The leads of a tile whose leader is the vehicle in slot c with trace (x, v), shift: a period on the ring's
 * wrap (as block.c's front_lead). */
static void leads_of(const WfLane *ln, size_t c, const double *x, const double *v, double shift, size_t k, WfLead *ld)
{
    double len = ln->class_length_m[ln->class_id[c]];
    for (size_t s = 0; s < k; s++) ld[s] = (WfLead){(shift != 0.0 ? x[s] + shift : x[s]) - len, v[s], 0.0};
}

/* Thread t's share of the state variables that are not per-vehicle arrays, copied into the backup. */
static void backup_share(WfWindow *w, const WfStateVar *vars, size_t n_vars, int t, int nt)
{
    unsigned char *bk = w->backup;
    for (size_t j = 0; j < n_vars; bk += vars[j++].size) {
        if (vars[j].stride) continue;
        size_t a = vars[j].size * (size_t)t / (size_t)nt, b = vars[j].size * (size_t)(t + 1) / (size_t)nt;
        memcpy(bk + a, (unsigned char *)vars[j].data + a, b - a);
    }
}

/* The per-vehicle arrays of blocks [b0, b1) into the backup (restore: back from it), as a tile begins: the copy
 * reads what the tile is about to load anyway. */
static void backup_blocks(WfWindow *w, const WfLane *ln, const WfStateVar *vars, size_t n_vars, size_t b0, size_t b1,
                          int restore)
{
    size_t lo[2], hi[2];
    int runs = block_runs(w, ln, b0, b1, lo, hi);
    unsigned char *bk = w->backup;
    for (size_t j = 0; j < n_vars; bk += vars[j++].size) {
        size_t st = vars[j].stride;
        unsigned char *d = vars[j].data;
        for (int r = 0; st && r < runs; r++) {
            size_t off = lo[r] * st, len = (hi[r] - lo[r]) * st;
            if (restore) memcpy(d + off, bk + off, len);
            else memcpy(bk + off, d + off, len);
        }
    }
}

void wf_window_prefault(WfWindow *w, const WfStateVar *vars, size_t n_vars, int part, int parts)
{
    unsigned char *bk = w->backup;
    size_t lo = w->b_lo * B, hi = w->b_hi * B < w->n ? w->b_hi * B : w->n;
    for (size_t j = 0; bk && j < n_vars; bk += vars[j++].size) {
        size_t st = vars[j].stride;
        if (st) wf_mem_prefault(bk + lo * st, (hi - lo) * st, part, parts);
        else wf_mem_prefault(bk, vars[j].size, part, parts);
    }
}

/* Chunk c: blocks [*b0, *b1). */
static void chunk_at(const WfWindow *w, size_t c, size_t *b0, size_t *b1)
{
    size_t span = w->b_hi - w->b_lo;
    *b0 = w->b_lo + span * c / w->n_chunks, *b1 = w->b_lo + span * (c + 1) / w->n_chunks;
}

/* Chunk c for k steps, tile by tile from the front, after its halo was taken (halo_take). */
static int run_chunk_window(WfWindow *w, WfLane *ln, size_t n, long step0, size_t k, int in_window, int pass,
                            WfStatsBlock *const *recs, const WfStateVar *vars, size_t n_vars, size_t ci)
{
    WfHalo *h = &w->halo[ci];
    size_t nb = w->nb, b0, b1;
    chunk_at(w, ci, &b0, &b1);
    int fl = 0;
    if (w->open_x && b1 == nb) { /* an open front: the vehicle ahead's trace */
        for (size_t s = 0; s < k; s++) h->lead[s] = (WfLead){w->open_x[s] - w->open_len_m, w->open_v[s], 0.0};
    } else {
        halo_run(h, &h->hl, k, step0, in_window);
        leads_of(ln, block_slot(w, ln, b1), h->hx, h->hv, b1 < nb ? 0.0 : ln->period_m, k, h->lead);
    }
    for (size_t e = b1; e > b0;) {
        size_t s0 = e - b0 > w->tile_blocks ? e - w->tile_blocks : b0;
        backup_blocks(w, ln, vars, n_vars, s0, e, 0);
        fl |= wf_lane_tile(ln, w->first, n, s0, e, step0, (int)k, h->lead, h->tx, h->tv, pass, in_window, recs,
                           &h->co);
        /* the tile's front edge after the last step: the tile ahead has finished */
        if (e < b1) fl |= wf_lane_chunk_edge(ln, w->first, n, e, nb);
        leads_of(ln, block_slot(w, ln, s0), h->tx, h->tv, 0.0, k, h->lead);
        e = s0;
    }
    return fl;
}

int wf_window_run(WfWindow *w, WfLane *ln, size_t n, long step0, int k, int in_window, const WfStateVar *vars,
                  size_t n_vars, size_t *n_rows)
{
    WfStatsBlock *recs[B];
    size_t rows = 0, nb = w->nb, nc = w->n_chunks;
    for (int s = 0; s < k; s++)
        recs[s] = (step0 + s) % w->out_every == 0 ? w->rec + nb * rows++ : NULL;
    int nth = w->nthreads, flags = 0, part = w->b_lo > 0 || w->b_hi < nb;
    int pass = WF_PASS_FUSED | WF_PASS_COUNT;
    size_t late = part && w->halo_ready ? 1 : 0; /* the front chunk (the last) waits for the next part's vehicles */
    w->halo_rc = w->front_rc = 0;
    w->end = step0 + k;
#pragma omp parallel num_threads(nth) if (nth > 1) default(none) \
    shared(w, ln, n, step0, k, in_window, vars, n_vars, recs, nb, nc, pass, part, late)
    {
#ifdef _OPENMP
        int t = omp_get_thread_num(), team = omp_get_num_threads();
#else
        int t = 0, team = 1;
#endif
        backup_share(w, vars, n_vars, t, team);
        /* every chunk's halo before any chunk moves (the loop's end is a barrier, after the backup too) */
#pragma omp for schedule(static)
        for (size_t c = 0; c < nc; c++) {
            size_t b0, b1;
            chunk_at(w, c, &b0, &b1);
            memset(&w->halo[c].co, 0, sizeof w->halo[c].co);
            if (c + late < nc && !(w->open_x && b1 == nb))
                w->halo[c].hl = halo_take(&w->halo[c], ln, block_slot(w, ln, b1), (size_t)k);
        }
        /* An open front's vehicles ahead, then the front chunk behind them, on the first thread while the others
         * take the other chunks (nobody waits for them) */
        size_t own = w->front_first ? 1 : 0;
        if (own && t == 0) {
            size_t c = nc - 1, b0, b1;
            if ((w->front_rc = w->front_first(w->front_ctx)) == 0) {
                w->halo[c].co.flags =
                    run_chunk_window(w, ln, n, step0, (size_t)k, in_window, pass, recs, vars, n_vars, c);
            } else {
                chunk_at(w, c, &b0, &b1);
                backup_blocks(w, ln, vars, n_vars, b0, b1, 0); /* for the undo */
            }
        }
        /* Chunks go to whichever thread is free: a thread that the system deschedules holds up one chunk, not a
         * share of the ring. */
#pragma omp for schedule(dynamic, 1) nowait
        for (size_t c = 0; c < nc - late - own; c++)
            w->halo[c].co.flags = run_chunk_window(w, ln, n, step0, (size_t)k, in_window, pass, recs, vars, n_vars, c);
        if (late) {
            /* the thread that posted the exchange (MPI_THREAD_FUNNELED) completes it once its other chunks ran */
#pragma omp master
            {
                size_t c = nc - 1, b0, b1;
                chunk_at(w, c, &b0, &b1);
                if ((w->halo_rc = w->halo_ready(w->halo_ctx)) == 0) {
                    w->halo[c].hl = halo_take(&w->halo[c], ln, block_slot(w, ln, b1), (size_t)k);
                    w->halo[c].co.flags =
                        run_chunk_window(w, ln, n, step0, (size_t)k, in_window, pass, recs, vars, n_vars, c);
                }
            }
        }
#pragma omp barrier
#pragma omp for schedule(static)
        for (size_t c = 0; c < nc; c++) {
            size_t b0, b1;
            chunk_at(w, c, &b0, &b1);
            if (!part || b1 < w->b_hi) w->halo[c].co.flags |= wf_lane_chunk_edge(ln, w->first, n, b1, nb);
        }
        if (w->after) { /* the loop's end was a barrier: every chunk's flags are final */
            int fl = 0;
            for (size_t c = 0; c < nc; c++) fl |= w->halo[c].co.flags;
            w->after(w->after_ctx, t, team, fl);
        }
    }
    for (size_t c = 0; c < nc; c++) flags |= w->halo[c].co.flags;
    *n_rows = rows;
    return flags;
}

void wf_window_back_trace(const WfWindow *w, const double **x_m, const double **v_mps)
{
    /* chunk 0's tiles run from its front to the range's first block: the last one traced the back vehicle */
    *x_m = w->halo[0].tx, *v_mps = w->halo[0].tv;
}

void wf_window_settle(WfWindow *w, WfLane *ln, const WfStateVar *vars, size_t n_vars, int flags)
{
    w->windows++;
    if (flags) w->redone++, w->per_step_until = w->end;
    if (!flags) {
        if (ln->safe)
            for (size_t c = 0; c < w->n_chunks; c++) wf_lane_safety_add(ln, &w->halo[c].co, 1);
        return;
    }
    /* the window's blocks of each per-vehicle array, every other variable whole */
    backup_blocks(w, ln, vars, n_vars, w->b_lo, w->b_hi, 1);
    unsigned char *bk = w->backup;
    for (size_t j = 0; j < n_vars; bk += vars[j++].size)
        if (!vars[j].stride) memcpy(vars[j].data, bk, vars[j].size);
}
