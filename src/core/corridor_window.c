/* Time-blocked windows of a corridor (src/core/corridor_impl.h; the windows themselves: src/core/window.c). */
#include "core/corridor_impl.h"

#include "util/mem.h"

enum { FRONT_MAX = 2 * WF_BLOCK }; /* vehicles of a window's front part at most (else one step at a time) */
#define REACH_A_MPS2 10.0     /* the acceleration bounding how far a vehicle may get within a window */

/* Windows of time.block_steps steps (0 or 1: none) when the road is a single lane without an off-ramp whose groups
 * all step by the kernel (no commands from outside). Owns what it allocates until destroy. */
int cor_window_init(WfCorridor *c, WfError *err)
{
    const WfScenario *sc = c->sc;
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    /* Only when asked for: measured on this project's machine (bench/README.md, "Corridor threads under load"), a
     * corridor of 5000 vehicles steps 13-15 % slower in windows on idle cores, its state being in cache anyway, and
     * is not faster beside busy processes. */
    int k = sc->block_steps, ok = k >= 2 && c->n_lanes == 1 && sc->fused_step;
    ok &= !c->cs->has_offramp && !c->coop_cap_mps2;
    for (size_t g = 0; g < sc->n_groups; g++) ok &= !sc->groups[g].model->external;
    size_t cap = ln->veh.cap, nv = 0, bytes = 0;
    if (!ok || cap / WF_BLOCK < 2) return 0;
    size_t na = 0, pst = c->pstride * sizeof(double);
#define SLOT_VAR(nm, field, stepped)                                                                            \
    cw->all[na++] = (WfStateVar){.name = nm, .data = ln->field, .size = cap * sizeof *ln->field,                    \
                                 .stride = sizeof *ln->field};                                                      \
    if (stepped) cw->vars[nv++] = cw->all[na - 1];
    SAVED_SLOT_ARRAYS(SLOT_VAR)
#undef SLOT_VAR
    cw->all[na++] = (WfStateVar){.name = "params", .data = ln->veh.params, .size = cap * pst, .stride = pst};
    if (c->sstride)
        cw->vars[nv++] = cw->all[na++] = (WfStateVar){.name = "controller_state", .data = ln->veh.state,
                                                      .size = cap * c->sstride, .stride = c->sstride};
    for (size_t j = 0; j < nv; j++) bytes += cw->vars[j].size, cw->slot_bytes += cw->vars[j].stride;
    for (size_t j = 0; j < na; j++) cw->all_bytes += cw->all[j].stride;
    cw->n_vars = nv, cw->n_all = na;
    /* a step reads about as many bytes per slot again as it changes (parameters, class, group, step values) */
    size_t tile = sc->tile_vehicles > 0 ? (size_t)sc->tile_vehicles : wf_window_tile_default(2 * cw->slot_bytes);
    int rc = wf_window_create(&cw->w, &ln->lane, cap, 0, cap / WF_BLOCK, k, tile, c->out_every, bytes, err);
    if (rc) return rc;
    wf_mem_prefault(cw->w.backup, bytes, 0, 1); /* every slot may be in a window: the whole copy's pages now */
    ALLOC(cw->x, ((size_t)k + 1) * cap);
    ALLOC(cw->rate, (size_t)k * cap);
    ALLOC(cw->cell, (size_t)c->nthreads * cap);
    ALLOC(cw->nf, (size_t)k);
    ALLOC(cw->nb, (size_t)k);
    ALLOC(cw->cr, (size_t)k);
    ALLOC(cw->fx, (size_t)k);
    ALLOC(cw->fv, (size_t)k);
    ALLOC(cw->exit_slot, (size_t)FRONT_MAX);
    ALLOC(cw->exit_t, (size_t)FRONT_MAX);
    ALLOC(cw->keep, (size_t)k * cw->all_bytes + FRONT_MAX * cw->slot_bytes + sizeof c->st + sizeof ln->lane.safety);
    return 0;
}

void cor_window_free(CorWindow *cw)
{
    wf_window_destroy(&cw->w);
    WF_FREE(cw->x, cw->rate, cw->cell, cw->nf, cw->nb, cw->cr, cw->fx, cw->fv, cw->exit_slot, cw->exit_t, cw->keep);
}

/* The front part of a window of k steps over the n0 vehicles from road index k0: the vehicles from the front that
 * could reach L within it (moving off at their speed with REACH_A_MPS2), one more, whose trace the interior follows
 * (split across processes, behind the first rank: the halo, the rank ahead's rearmost vehicles), and, unless that
 * leaves the interior shorter than two blocks, those behind it in its block of slots, so that the part begins a
 * block: a range that begins inside one draws its block's noise from the block's start again. Should more leave,
 * the window finds it (front_part) and is redone. */
static size_t front_count(const WfCorridor *c, int k, size_t k0, size_t n0, size_t halo)
{
    const WfCorridorVehicles *vh = &c->ln[0].veh;
    double T = (double)k * c->sc->dt_s;
    size_t m = halo;
    for (; !halo && m < n0 && m < WF_BLOCK; m++) {
        size_t s = wf_corridor_slot(vh, k0 + m);
        if (vh->x_m[s] + T * (vh->v_mps[s] + 0.5 * REACH_A_MPS2 * T) < c->L) break;
    }
    m += !halo;
    size_t aligned = m < n0 ? m + wf_corridor_slot(vh, k0 + m - 1) % WF_BLOCK : m;
    return aligned + 2 * WF_BLOCK <= n0 ? aligned : m; /* a short road keeps its interior */
}

/* `count` slots from lo (wrapping at cap) of a per-slot array, into p (restore: from p); returns the next p. */
static unsigned char *keep_run(unsigned char *p, const WfStateVar *v, size_t lo, size_t count, size_t cap, int restore)
{
    size_t st = v->stride, a = count < cap - lo ? count : cap - lo;
    unsigned char *d = v->data;
    if (restore) memcpy(d + lo * st, p, a * st), memcpy(d, p + a * st, (count - a) * st);
    else memcpy(p, d + lo * st, a * st), memcpy(p + a * st, d, (count - a) * st);
    return p + count * st;
}

/* What a window changes outside the interior (window.c keeps that): the scalars, the buffer's indices, the safety
 * counts, the per-slot arrays a step changes of the front part, and every per-slot array of the k slots behind the
 * road's back, where vehicles may enter (restore: put back as the window began, the unused slots too: a checkpoint
 * saves them). */
static void window_keep(WfCorridor *c, int k, int restore)
{
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    size_t cap = ln->veh.cap, nf = cw->n0 - cw->n_int;
    unsigned char *p = cw->keep;
    if (restore) {
        memcpy(&c->st, p, sizeof c->st), memcpy(&ln->lane.safety, p + sizeof c->st, sizeof ln->lane.safety);
        ln->veh.first = cw->road_first, ln->veh.n = cw->road_n;
    } else {
        memcpy(p, &c->st, sizeof c->st), memcpy(p + sizeof c->st, &ln->lane.safety, sizeof ln->lane.safety);
    }
    p += sizeof c->st + sizeof ln->lane.safety;
    for (size_t j = 0; j < cw->n_all; j++)
        p = keep_run(p, &cw->all[j], (cw->road_first + cap - (size_t)k) % cap, (size_t)k, cap, restore);
    for (size_t j = 0; j < cw->n_vars; j++)
        p = keep_run(p, &cw->vars[j], (cw->first0 + cw->n_int) % cap, nf, cap, restore);
}

/* The front part k steps one at a time, as step_once steps it (the virtual leader, the repair at the front, the
 * exits, whose trips wait), the trace of its rearmost vehicle into fx, fv. Behind a halo (n_halo: the rank ahead's
 * k + 1 rearmost vehicles, which that rank steps and counts) the halo steps first, behind the road's front leader,
 * which only its first vehicles feel within k steps: its rearmost one, which leads the rest, is exact through the
 * window (a vehicle reads only its leader at the step's start), and it is neither counted nor repaired here.
 * Returns WF_STEP_* flags: any, and the window is redone one step at a time (an overlap behind the front, a fault,
 * the rearmost vehicle left). */
static int front_part(WfCorridor *c, long step0, int k, int in_window, WfError *err)
{
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    WfCorridorVehicles *vh = &ln->veh;
    size_t cap = vh->cap, rear = (cw->first0 + cw->n_int) % cap, halo = cw->n_halo;
    size_t own = cw->n0 - cw->n_int - halo, hr = (rear + own) % cap, behind = cw->road_n - cw->n0;
    for (int s = 0; s < k; s++) {
        long step = step0 + s;
        double t_next = (double)(step + 1) * c->sc->dt_s;
        size_t nf = vh->n - behind - cw->n_int; /* exits shrink it */
        cw->nf[s] = nf;
        cw->fx[s] = vh->x_m[rear], cw->fv[s] = vh->v_mps[rear];
        WfLead front = cor_front_leader(c, 0);
        c->meas_step = step;
        if (halo) {
            WfLead ahead = {vh->x_m[hr] - vh->length_m[hr], vh->v_mps[hr], 0.0};
            WfSafetyCount counted = ln->lane.safety;
            wf_lane_step(&ln->lane, hr, halo, &front, step, WF_PASS_FUSED | WF_PASS_COUNT, in_window, NULL);
            ln->lane.safety = counted;
            front = ahead, nf = own;
        }
        int fl = nf ? wf_lane_step(&ln->lane, rear, nf, &front, step, WF_PASS_FUSED | WF_PASS_COUNT, in_window, NULL)
                    : 0;
        if (fl) return fl;
        cor_advance_leader(c, t_next);
        if (halo) {
            if (own && vh->x_m[hr] - vh->length_m[hr] - vh->x_m[(hr + cap - 1) % cap] < 0.0) return WF_STEP_OVERLAP;
            continue;
        }
        cor_phase_overlaps(c, ln, in_window, c->has_vl ? 1 : 0);
        if (c->fault_slot >= 0) return WF_STEP_FAULT;
        if (cor_phase_exits(c, ln, t_next, in_window, SIZE_MAX, err) || vh->n <= cw->n_int + behind)
            return WF_STEP_OVERLAP;
    }
    return 0;
}

/* WfWindow.front_first: the front part, on the window's first thread while the others step the interior. */
static int window_front(void *ctx)
{
    WfCorridor *c = ctx;
    CorWindow *cw = &c->win;
    if (c->pt.p && cor_part_window_wait(c)) return WF_STEP_FAULT; /* the halo is in place (cor_part_window_wait) */
    return front_part(c, cw->step0, cw->k, cw->in_window, cw->err);
}

/* The entrance k steps one at a time behind the road's back vehicle as the window began, from its trace (bx, bv:
 * its position and speed at the start of each step; x_end after the last): arrivals, an insertion against that
 * vehicle's state at the step's start, the vehicles that entered stepped behind it. Returns WF_STEP_* flags (an
 * error of the entrance too: redone one step at a time, the error comes at its step). */
int cor_window_back(WfCorridor *c, long step0, int k, int in_window, const double *bx, const double *bv, double x_end,
                    WfError *err)
{
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    WfCorridorVehicles *vh = &ln->veh;
    size_t cap = vh->cap, back = cw->road_first, ahead = (back + cap - 1) % cap;
    double len = ln->lane.class_length_m[vh->class_id[back]];
    for (int s = 0; s < k; s++) {
        long step = step0 + s;
        double t = (double)step * c->sc->dt_s;
        cw->back_on = 1, cw->back_slot = back, cw->back_x = bx[s], cw->back_v = bv[s];
        int rc = cor_arrivals(c, t, err);
        if (!rc) rc = cor_entrance(c, t, step, err);
        cw->back_on = 0;
        if (rc) return WF_STEP_FAULT;
        size_t nb = (back + cap - vh->first) % cap;
        if (nb > (s ? cw->nb[s - 1] : 0)) cw->x[(size_t)s * cap + vh->first] = vh->x_m[vh->first]; /* it entered */
        cw->nb[s] = nb;
        if (!nb) continue;
        WfLead lead = {bx[s] - len, bv[s], 0.0};
        c->meas_step = step;
        int fl = wf_lane_step(&ln->lane, vh->first, nb, &lead, step, WF_PASS_FUSED | WF_PASS_COUNT, in_window, NULL);
        double xl = s + 1 < k ? bx[s + 1] : x_end;
        if (fl || xl - len - vh->x_m[ahead] < 0.0) return fl | WF_STEP_OVERLAP;
    }
    return 0;
}

/* The Edie cells [i_lo, i_hi) and detectors [q_lo, q_hi) of step `step` from the view v of the window's rows: the
 * cells of the vehicles that can reach them (measure_span's), slots ascending in at most two runs, then the sums. */
static void measure_view(WfCorridor *c, CorLane *v, long step, size_t i_lo, size_t i_hi, size_t q_lo, size_t q_hi)
{
    size_t k0, k1;
    cor_measure_span(c, v, i_lo, i_hi, q_lo, q_hi, &k0, &k1);
    for (size_t k = k0; k < k1;) {
        size_t top = wf_corridor_slot(&v->veh, k) + 1, len = top < k1 - k ? top : k1 - k, lo = top - len;
        cor_cells_of(c, v->xold + lo, v->veh.x_m + lo, v->cell + lo, len);
        k += len;
    }
    cor_measure_range(c, v, step, c->win.in_window, i_lo, i_hi, q_lo, q_hi);
}

/* Thread t of nt's share of the window's Edie cells and detectors, step after step, from the rows: each thread owns
 * a range of cells (cut by the vehicles at the first step; split across processes, of this rank's segment's cells,
 * in even ranges) and of detectors for the whole window, so each sum gets its additions in road order within a step
 * and step after step, as in the per-step path. A step's view: the front part's vehicles that did not leave before
 * it (behind a halo only its rearmost vehicle, whose body may cover a detector of this segment; the vehicles ahead
 * of it do not reach the segment), the interior, the vehicles that entered, and those of the rank behind that
 * crossed into the segment by the step's end (cr). */
void cor_window_measure(WfCorridor *c, size_t t, size_t nt)
{
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    const CorPart *pt = &c->pt;
    size_t cap = ln->veh.cap, nd = c->det.n_det, q_lo = nd * t / nt, q_hi = nd * (t + 1) / nt, i_lo = 0, i_hi = 0;
    size_t ahead = cw->n_halo ? cw->n_halo - 1 : 0;
    CorLane v = *ln;
    v.cell = cw->cell + t * cap;
    for (int s = 0; s < cw->k; s++) {
        size_t r = (size_t)s * cap, behind = cw->nb[s] + cw->cr[s];
        v.veh.first = (cw->first0 + cap - behind) % cap, v.veh.n = cw->nf[s] - ahead + cw->n_int + behind;
        v.xold = cw->x + r, v.veh.x_m = cw->x + r + cap, v.veh.fuel_rate_gps = cw->rate + r;
        long step = cw->step0 + s;
        if (!pt->p) {
            if (s == 0) i_lo = cor_cell_cut(c, &v, t, nt), i_hi = cor_cell_cut(c, &v, t + 1, nt);
            measure_view(c, &v, step, i_lo, i_hi, q_lo, q_hi);
            continue;
        }
        size_t w = pt->i_hi - pt->i_lo;
        measure_view(c, &v, step, pt->i_lo + w * t / nt, pt->i_lo + w * (t + 1) / nt, 0, 0);
        for (size_t q = q_lo; q < q_hi; q++)
            if (cor_part_holds(pt, c->det.x_m[q])) measure_view(c, &v, step, 0, 0, q, q + 1);
    }
}

/* WfWindow.after, on each thread of the window's team once the interior has moved: on the first, the interior's
 * front edge against the front part's rearmost vehicle and the entrance; then, when every part stands, the
 * measurement, shared. */
static void window_after(void *ctx, int t, int nt, int flags)
{
    WfCorridor *c = ctx;
    CorWindow *cw = &c->win;
    const WfPartition *p = c->pt.p;
    if (t == 0) {
        const double *x = c->ln[0].veh.x_m;
        size_t cap = c->ln[0].veh.cap, rear = (cw->first0 + cw->n_int) % cap, front = (rear + cap - 1) % cap;
        flags |= cw->w.front_rc;
        if (!flags && x[rear] - cw->w.open_len_m - x[front] < 0.0) flags |= WF_STEP_OVERLAP;
        if (!flags && (!p || p->rank + 1 == p->size)) { /* the entrance's rank */
            const double *bx, *bv;
            wf_window_back_trace(&cw->w, &bx, &bv);
            flags = cor_window_back(c, cw->step0, cw->k, cw->in_window, bx, bv, x[cw->first0], cw->err);
        }
        cw->flags = flags;
    }
#pragma omp barrier
    if (!cw->flags && !p) cor_window_measure(c, (size_t)t, (size_t)nt); /* split: once the ranks agree */
}

/* k steps (2 <= k) in one window, in one parallel region: the front part on its first thread while the others step
 * the interior, then the entrance and the measurement (window_after). *done 0 when the road does not fit one (one
 * step at a time then), or when some step overlapped, faulted or a vehicle behind the front part left: the state is
 * as before, and the steps are taken one at a time (their repairs and errors are the per-step path's). Split across
 * processes, each rank steps its own vehicles behind a halo, and the ranks agree before and after (cor_part_window_*
 * in corridor_part.c). */
int cor_window(WfCorridor *c, long step0, int k, int *done, WfError *err)
{
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    WfCorridorVehicles *vh = &ln->veh;
    const CorPart *pt = &c->pt;
    int rank = pt->p ? pt->p->rank : 0, rc = 0, go = 1;
    size_t halo = rank ? (size_t)k + 1 : 0, rows;
    /* this process's vehicles from road index k0 (the halo first), and its back slot */
    size_t n0 = pt->p ? pt->n_own + halo : vh->n, first0 = pt->p ? pt->first_own : vh->first;
    *done = 0;
    int fit = !rank || pt->pre[rank - 1].n >= halo; /* then k_lo >= halo: the halo's road indices begin at k0 */
    size_t k0 = pt->p && fit ? pt->k_lo - halo : 0;
    size_t nf = fit ? front_count(c, k, k0, n0, halo) : 0;
    /* the rank behind steps this rank's k + 1 rearmost vehicles as its halo: they stay in the interior, whose exits
     * undo the window (front_part), so the halo never holds a vehicle that left */
    size_t tail = pt->p && rank + 1 < pt->p->size ? (size_t)k + 1 : 1;
    fit = fit && nf <= FRONT_MAX && nf + tail <= n0 && vh->n + (size_t)k < vh->cap;
    fit = fit && wf_window_range(&cw->w, first0, n0 - nf, ln->lane.nthreads);
    if (pt->p && (rc = cor_part_window_begin(c, k, fit, &go, err))) return rc;
    if (!fit || !go) return 0;
    cw->first0 = first0, cw->n0 = n0, cw->n_int = n0 - nf, cw->n_halo = halo;
    cw->road_first = vh->first, cw->road_n = vh->n;
    memset(cw->cr, 0, (size_t)k * sizeof *cw->cr);
    cor_lane_exports(c, COR_EXPORT_NONE);
    window_keep(c, k, 0);
    size_t rear = (cw->first0 + cw->n_int) % vh->cap;
    cw->active = 1, cw->step0 = step0, cw->k = k, cw->in_window = step0 >= c->warm_steps, cw->err = err;
    cw->n_exits = 0, cw->flags = 0;
    cw->w.open_x = cw->fx, cw->w.open_v = cw->fv, cw->w.open_len_m = ln->lane.class_length_m[vh->class_id[rear]];
    cw->w.front_first = window_front, cw->w.front_ctx = c, cw->w.after = window_after, cw->w.after_ctx = c;
    wf_window_run(&cw->w, &ln->lane, cw->n_int, step0, k, cw->in_window, cw->vars, cw->n_vars, &rows);
    cw->active = 0;
    if (pt->p) rc = cor_part_window_agree(c, cw->flags, err); /* every rank's flags, on every rank */
    wf_window_settle(&cw->w, &ln->lane, cw->vars, cw->n_vars, cw->flags | (rc != 0));
    if (rc || cw->flags) {
        window_keep(c, k, 1);
        c->fault_slot = -1, cw->n_exits = 0;
        return rc;
    }
    if (pt->p && (rc = cor_part_window_end(c, err))) return rc;
    for (size_t e = 0; !rc && e < cw->n_exits; e++)
        rc = cor_finish_vehicle(c, ln, cw->exit_slot[e], cw->exit_t[e], 1, err);
    *done = 1;
    return rc;
}
