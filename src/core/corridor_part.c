/* A corridor split across processes (src/core/corridor_impl.h, docs/mpi.md). */
#include "core/corridor_impl.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* One road split across processes (wavefuel/partition.h, docs/mpi.md): rank r holds a segment of the road, cut on
 * Edie cell edges (rank 0 the exit's, the last rank the entrance's), and the vehicles whose fronts are on it.
 * Vehicles only move forward, so a vehicle leaves a rank only for the rank ahead and joins it behind all of its
 * vehicles: road order stays whole without a reordering. What needs the whole road is exchanged or summed in road
 * order: the entrance and the virtual leader run on every rank from the ranks' records (the back vehicle, rank 0's
 * exits); a record's sums pass from rank to rank (chain); each Edie cell and detector is measured by its segment's
 * rank, from its own vehicles then those that crossed into the segment (behind them in road order), and a
 * detector also from the vehicle just ahead (whose body may cover it); summed onto every rank at the end, a cell
 * holds its owner's value (the others' are +0). */

/* The first Edie cell past rank r's segment of a road of nx cells split R ways: rank r holds the cells
 * [part_cell(nx, R, r + 1), part_cell(nx, R, r)). */
static size_t part_cell(size_t nx, size_t R, size_t r) { return nx * (R - r) / R; }

/* Rank r's upper cut: the fronts at or beyond it are on the segment ahead (rank 0: none). */
static double part_cut(const WfCorridor *c, int r)
{
    size_t R = (size_t)c->pt.p->size;
    return r <= 0 ? INFINITY : (double)part_cell(c->edie.nx, R, (size_t)r) * c->edie.dx_m;
}

/* Before the corridor's segments are cut: what a split corridor cannot be, beyond what no split road can
 * (wf_sim_create_part). */
int cor_part_check(const WfCorridor *c, const WfPartition *p, WfError *err)
{
    const WfScenario *sc = c->sc;
    if (c->cs->has_offramp)
        return wf_err(err, WF_EINPUT, "%s: corridor.off_ramp: an off-ramp cannot be split across processes "
                      "(docs/mpi.md)", sc->path);
    /* every segment longer than two vehicles and PART_MIN_M: a body never spans one, a step never crosses one */
    double len = 0.0, dx = c->edie.dx_m, least = INFINITY;
    size_t nx = c->edie.nx, R = (size_t)p->size;
    for (size_t k = 0; k < sc->n_classes; k++) len = fmax(len, sc->classes[k].length_m);
    for (size_t r = 0; r < R; r++) {
        size_t lo = part_cell(nx, R, r + 1), hi = part_cell(nx, R, r);
        least = fmin(least, (r == 0 ? c->L : (double)hi * dx) - (double)lo * dx);
    }
    if (nx < R || !(least >= 2.0 * len + PART_MIN_M))
        return wf_err(err, WF_EINPUT, "%s: corridor.edie.dx_m %g m: %zu processes split the road's %zu Edie cells "
                      "into segments as short as %.6g m; each needs at least one cell and %.6g m (two of the longest "
                      "vehicles and %g m): fewer processes or smaller cells (docs/mpi.md)", sc->path, dx, R, nx,
                      nx < R ? 0.0 : least, 2.0 * len + PART_MIN_M, PART_MIN_M);
    return 0;
}

/* A vehicle's state in the order of part_pack: every saved per-slot array, the step's old position, fuel rate
 * and Edie cell (the rank it crosses to measures it), its controller memory. */
#define PACK_ARRAYS(X) SAVED_SLOT_ARRAYS(X) X("", xold, 0) X("", veh.fuel_rate_gps, 0) X("", cell, 0)

int cor_part_init(WfCorridor *c, WfPartition *p, WfError *err)
{
    CorPart *pt = &c->pt;
    CorLane *ln = &c->ln[0];
    size_t R = (size_t)p->size, r = (size_t)p->rank, nx = c->edie.nx, cap = ln->veh.cap;
    pt->p = p;
    pt->i_lo = part_cell(nx, R, r + 1), pt->i_hi = part_cell(nx, R, r);
    pt->cut_lo = r + 1 == R ? -INFINITY : part_cut(c, (int)r + 1);
    pt->cut_hi = part_cut(c, (int)r);
#define SIZE_OF(nm, field, stepped) pt->vbytes += sizeof *ln->field;
    PACK_ARRAYS(SIZE_OF)
#undef SIZE_OF
    pt->vbytes += c->sstride;
    pt->pre = calloc(R, sizeof *pt->pre);
    pt->post = calloc(R, sizeof *pt->post);
    pt->off = calloc(R + 1, sizeof *pt->off);
    pt->out = malloc(cap * pt->vbytes);
    pt->in = malloc(cap * pt->vbytes);
    pt->all = malloc(cap * pt->vbytes);
    /* windows (cor_part_window_*): k + 1 vehicles of halo, at most PART_CROSS_MAX crossing with 2 k + 1 rows each */
    size_t k = c->sc->block_steps > 1 ? (size_t)c->sc->block_steps : 0;
    pt->cross_bytes = pt->vbytes + (2 * k + 1) * sizeof(double);
    pt->halo_out = malloc((k + 1) * pt->vbytes);
    pt->halo_in = malloc((k + 1) * pt->vbytes);
    pt->cross_out = malloc(k ? PART_CROSS_MAX * pt->cross_bytes : 1);
    pt->cross_in = malloc(k ? PART_CROSS_MAX * pt->cross_bytes : 1);
    pt->trace = calloc(2 * k + 1, sizeof *pt->trace);
    pt->wrec = calloc(R, sizeof *pt->wrec);
    if (!pt->pre || !pt->post || !pt->off || !pt->out || !pt->in || !pt->all || !pt->halo_out || !pt->halo_in ||
        !pt->cross_out || !pt->cross_in || !pt->trace || !pt->wrec)
        return wf_err(err, WF_ESYS, "out of memory for a corridor of %zu vehicle slots split across processes", cap);
    ln->lane.after_wanted = 0; /* vehicles crossing in are measured after the step */
    return 0;
}

void cor_part_free(CorPart *pt)
{
    WF_FREE(pt->pre, pt->post, pt->off, pt->out, pt->in, pt->all, pt->halo_out, pt->halo_in, pt->cross_out,
            pt->cross_in, pt->trace, pt->wrec);
}

/* Vehicles [k0, k0 + m) of the road, front first, packed into buf (unpack 0) or from it into their slots. */
static void part_pack(WfCorridor *c, size_t k0, size_t m, unsigned char *buf, int unpack)
{
    CorLane *ln = &c->ln[0];
    for (size_t j = 0; j < m; j++) {
        size_t s = wf_corridor_slot(&ln->veh, k0 + j);
#define PACK(nm, field, stepped)                                                                                    \
    unpack ? memcpy(&ln->field[s], buf, sizeof *ln->field) : memcpy(buf, &ln->field[s], sizeof *ln->field);        \
    buf += sizeof *ln->field;
        PACK_ARRAYS(PACK)
#undef PACK
        if (c->sstride)
            unpack ? memcpy(ln->veh.state + s * c->sstride, buf, c->sstride)
                   : memcpy(buf, ln->veh.state + s * c->sstride, c->sstride);
        buf += c->sstride;
    }
}

/* Every rank's vehicles from the records (pre): the road's count, this rank's road indices and back slot. */
static void part_layout(WfCorridor *c)
{
    CorPart *pt = &c->pt;
    WfCorridorVehicles *vh = &c->ln[0].veh;
    size_t n = 0, before = 0, behind = 0;
    for (int r = 0; r < pt->p->size; r++) {
        n += pt->pre[r].n;
        if (r < pt->p->rank) before += pt->pre[r].n;
        if (r > pt->p->rank) behind += pt->pre[r].n;
    }
    vh->n = n;
    pt->k_lo = before;
    pt->n_own = pt->pre[pt->p->rank].n;
    pt->first_own = (vh->first + behind) % vh->cap;
}

/* The nearest rank ahead of this one that holds vehicles (records rec), or -1. */
static int part_ahead(const CorPart *pt, const PartRec *rec)
{
    int r = pt->p->rank - 1;
    while (r >= 0 && !rec[r].n) r--;
    return r;
}

/* The leader of this rank's front vehicle: the rear vehicle of the nearest rank ahead that holds one, as it was at
 * the step's start, or the road's front leader. */
static WfLead part_front(const WfCorridor *c)
{
    int a = part_ahead(&c->pt, c->pt.pre);
    if (a < 0) return cor_front_leader(c, 0);
    const PartRec *r = &c->pt.pre[a];
    return (WfLead){r->x - r->len, r->v, 0.0};
}

static int part_lane_step(WfCorridor *c, const WfLead *front, long step, int pass, int in_window)
{
    CorPart *pt = &c->pt;
    if (!pt->n_own) return 0;
    return wf_lane_step(&c->ln[0].lane, pt->first_own, pt->n_own, front, step, pass, in_window, NULL);
}

/* A record's two passes in road order: the sums, then the squared deviations from the mean (the chains' steps). */
typedef struct PartM2 {
    RecordSums r;
    double m2;
} PartM2;

static void part_sums(void *arg, void *buf)
{
    const WfCorridor *c = arg;
    cor_record_lanes(c, 0, 1, c->pt.k_lo, c->pt.k_lo + c->pt.n_own, 0, buf);
}

static void part_m2(void *arg, void *buf)
{
    const WfCorridor *c = arg;
    PartM2 *m = buf;
    double mean = m->r.n ? m->r.sv / (double)m->r.n : NAN;
    m->m2 = cor_record_m2(c, 0, c->pt.k_lo, c->pt.k_lo + c->pt.n_own, 0, mean, m->m2);
}

/* The record of a step's start, made on rank 0 from the sums along the ranks. */
static int part_record(WfCorridor *c, double t, int in_window, WfError *err)
{
    WfPartition *p = c->pt.p;
    PartM2 m = {.r = {.vmin = INFINITY, .vmax = -INFINITY, .gmin = INFINITY}};
    int rc = p->chain(p->ctx, &m.r, sizeof m.r, part_sums, c, err);
    if (!rc) rc = p->chain(p->ctx, &m, sizeof m, part_m2, c, err);
    if (rc || p->rank) return rc;
    WfCorridorRow row;
    cor_record_row(c, &m.r, m.m2, t, &row);
    if (in_window && c->ln[0].veh.n) c->st.sd_sum += row.v[WF_CTS_SD_V], c->st.n_sd++;
    const WfOutput *out = c->sim->out;
    WfRecord rec = {row.v, WF_CTS_N_COLS, row.class_fuel_rate_gps};
    return out && out->record ? out->record(out->ctx, c->sim, &rec, err) : 0;
}

/* Rank r's record after the kernel moved its n vehicles, road indices from k0 (PartRec). */
static void part_moved(const WfCorridor *c, int r, size_t k0, size_t n, PartRec *q)
{
    const WfCorridorVehicles *vh = &c->ln[0].veh;
    /* the cut beyond the segment ahead (for rank 1, the exit): crossing it too skips a segment */
    double cut = part_cut(c, r), next = r == 1 ? c->L : part_cut(c, r - 1);
    q->n = n, q->out = q->skip = q->past = 0;
    if (!n) return;
    size_t rear = wf_corridor_slot(vh, k0 + n - 1), s;
    q->x = vh->x_m[rear], q->v = vh->v_mps[rear], q->len = vh->length_m[rear];
    q->x2 = vh->x_m[wf_corridor_slot(vh, k0)];
    for (; q->out < n && vh->x_m[s = wf_corridor_slot(vh, k0 + q->out)] >= cut; q->out++) {
        q->skip |= vh->x_m[s] >= next;
        q->out_x = vh->x_m[s], q->out_v = vh->v_mps[s], q->out_len = vh->length_m[s];
    }
    for (; q->past < n && vh->x_m[s = wf_corridor_slot(vh, k0 + q->past)] >= c->L; q->past++)
        q->past_x = vh->x_m[s], q->past_len = vh->length_m[s];
}

/* After the step: every rank's vehicles and rear vehicle at the next step's start (pre) from the records, as the
 * vehicles crossing the cuts and leaving at the exit change them; the speed outflow's leader restarts behind the last
 * vehicle that left, as rank 0's exits set it (phase_exits). */
static void part_next(WfCorridor *c, double t_end)
{
    CorPart *pt = &c->pt;
    const PartRec *post = pt->post;
    int R = pt->p->size;
    uint64_t exits = post[0].past; /* none of the vehicles crossing into rank 0's segment (part_moved) */
    if (exits && c->cs->outflow == WF_OUTFLOW_SPEED && pt->p->rank) {
        struct CorEntrance *en = &c->st.lane[0];
        size_t seg = en->vl_seg;
        en->vl_xref = post[0].past_x - post[0].past_len;
        en->vl_iref = wf_profile_integral(&c->cs->leader_speed_mps, t_end, &seg);
        en->vl_x = en->vl_xref;
    }
    for (int r = 0; r < R; r++) {
        const PartRec *in = r + 1 < R && post[r + 1].out ? &post[r + 1] : NULL;
        PartRec *q = &pt->pre[r];
        *q = (PartRec){.n = post[r].n - post[r].out + (in ? in->out : 0) - (r ? 0 : exits)};
        if (in) q->x = in->out_x, q->v = in->out_v, q->len = in->out_len;
        else q->x = post[r].x, q->v = post[r].v, q->len = post[r].len;
    }
    part_layout(c);
}

/* The whole road onto every rank (the records' counts), which repairs it as one process does; then every rank's
 * record as its moved vehicles now stand. */
static int part_repair(WfCorridor *c, int in_window, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    WfCorridorVehicles *vh = &c->ln[0].veh;
    size_t k = 0;
    for (int r = 0; r < p->size; k += pt->post[r++].n) pt->off[r] = k * pt->vbytes;
    pt->off[p->size] = k * pt->vbytes;
    part_pack(c, pt->k_lo, pt->n_own, pt->all + pt->k_lo * pt->vbytes, 0);
    int rc = p->gather(p->ctx, pt->all, pt->off, -1, err);
    if (rc) return rc;
    part_pack(c, 0, vh->n, pt->all, 1);
    cor_phase_overlaps(c, &c->ln[0], in_window, vh->n);
    k = 0;
    for (int r = 0; r < p->size; k += pt->post[r++].n) part_moved(c, r, k, pt->post[r].n, &pt->post[r]);
    return 0;
}

/* After the kernel moved this rank's vehicles: every rank's record, flags and stop agreed, the edges between ranks
 * tested as the kernel tests a follower against its leader, overlaps repaired (part_repair), then the vehicles that
 * crossed into the segment ahead passed to it and those that crossed into this one taken from the rank behind. */
static int part_after(WfCorridor *c, int in_window, int kflags, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    CorLane *ln = &c->ln[0];
    int me = p->rank, rc;
    int64_t before = c->st.counts.overlaps;
    PartRec q = {0};
    /* the road's front vehicle behind the virtual leader, by the rank that holds it (a full repair repeats it) */
    if (c->has_vl && pt->n_own && pt->k_lo == 0) {
        cor_phase_overlaps(c, ln, in_window, 1);
        if (c->fault_slot >= 0) kflags |= WF_STEP_FAULT, c->fault_slot = -1;
    }
    part_moved(c, me, pt->k_lo, pt->n_own, &q);
    q.repairs = (uint64_t)(c->st.counts.overlaps - before);
    q.flags = (uint64_t)kflags | (p->stop_own ? (uint64_t)*p->stop_own << PART_STOP_SHIFT : 0);
    if ((rc = p->allgather(p->ctx, &q, pt->post, sizeof q, err))) return rc;
    uint64_t flags = 0, stop = 0, skip = 0;
    for (int r = 0, a = -1; r < p->size; r++) {
        const PartRec *o = &pt->post[r];
        flags |= o->flags & ((1u << PART_STOP_SHIFT) - 1), stop |= o->flags >> PART_STOP_SHIFT, skip |= o->skip;
        if (r != me) c->st.counts.overlaps += (int64_t)o->repairs;
        if (!o->n) continue;
        if (a >= 0 && pt->post[a].x - pt->post[a].len - o->x2 < 0.0) flags |= WF_STEP_OVERLAP;
        a = r;
    }
    p->stop_all = (sig_atomic_t)stop;
    if (skip)
        return wf_err(err, WF_EINPUT, "%s: a vehicle crossed a whole process's segment of the road in one step (at t "
                      "= %.6g s): fewer processes (docs/mpi.md)", c->sc->path,
                      (double)(c->meas_step + 1) * c->sc->dt_s);
    if (flags && ((rc = part_repair(c, in_window, err)) || c->fault_slot >= 0)) return rc;
    size_t out = pt->post[me].out;
    pt->n_in = me + 1 < p->size ? pt->post[me + 1].out : 0;
    part_pack(c, pt->k_lo, out, pt->out, 0);
    rc = p->shift(p->ctx, pt->out, out * pt->vbytes, pt->in, pt->n_in * pt->vbytes, err);
    if (!rc) part_pack(c, pt->k_lo + pt->n_own, pt->n_in, pt->in, 1);
    pt->repaired = flags != 0;
    return rc;
}

/* This rank's Edie cells and detectors from the step: its own vehicles, then those that crossed in (behind them in
 * road order); a detector first from the vehicle just ahead, whose body may cover it (its old and new positions
 * from the records, unless a repair brought the whole road). */
static void part_measure(WfCorridor *c, long step, int in_window)
{
    CorPart *pt = &c->pt;
    CorLane *ln = &c->ln[0];
    int a = part_ahead(pt, pt->post);
    pt->kb = pt->k_lo, pt->ke = pt->k_lo + pt->n_own + pt->n_in;
    if (a >= 0 && c->det.n_det) {
        size_t s = wf_corridor_slot(&ln->veh, pt->k_lo - 1);
        if (!pt->repaired) ln->xold[s] = pt->pre[a].x, ln->veh.x_m[s] = pt->post[a].x;
        ln->cell[s] = UINT32_MAX, ln->veh.fuel_rate_gps[s] = 0.0;
        pt->kb--;
    }
    /* the cells in even ranges over the threads (each cell's sums are the same bits wherever the cuts fall) */
    int nth = wf_lane_threads(pt->ke - pt->kb, wf_governor_threads(&c->gov));
    if (nth <= 1) cor_measure_range(c, ln, step, in_window, pt->i_lo, pt->i_hi, 0, 0);
    else {
#pragma omp parallel num_threads(nth) default(none) shared(c, ln, pt, step, in_window)
        {
#ifdef _OPENMP
            size_t t = (size_t)omp_get_thread_num(), nt = (size_t)omp_get_num_threads(), w = pt->i_hi - pt->i_lo;
#else
            size_t t = 0, nt = 1, w = pt->i_hi - pt->i_lo;
#endif
            cor_measure_range(c, ln, step, in_window, pt->i_lo + w * t / nt, pt->i_lo + w * (t + 1) / nt, 0, 0);
        }
    }
    for (size_t q = 0; q < c->det.n_det; q++)
        if (cor_part_holds(pt, c->det.x_m[q]))
            cor_measure_range(c, ln, step, in_window, 0, 0, q, q + 1);
}

/* One step of a split corridor (step_once's order on one lane). */
int cor_part_step_once(WfCorridor *c, long step, WfError *err)
{
    const WfScenario *sc = c->sc;
    CorPart *pt = &c->pt;
    CorLane *ln = &c->ln[0];
    double t = (double)step * sc->dt_s, t_next = (double)(step + 1) * sc->dt_s;
    int in_window = step >= c->warm_steps, records = step % c->out_every == 0, last = step == c->n_steps, rc, flags;
    if ((rc = cor_arrivals(c, t, err))) return rc;
    size_t n0 = ln->veh.n;
    if ((rc = cor_entrance(c, t, step, err))) return rc;
    pt->pre[pt->p->size - 1].n += ln->veh.n - n0; /* an entry joins the last rank */
    part_layout(c);
    WfLead front = part_front(c);
    cor_lane_exports(c, records || last ? COR_EXPORT_ALL : COR_EXPORT_NONE);
    c->meas_step = step, c->meas_in_window = in_window;
    if (records || last) {
        part_lane_step(c, &front, step, WF_PASS_ACCEL | WF_PASS_ENERGY | (last ? 0 : WF_PASS_COUNT), in_window);
        if (records && (rc = part_record(c, t, in_window, err))) return rc;
        if (last) return WF_LOOP_END;
        flags = part_lane_step(c, &front, step, WF_PASS_ADVANCE, in_window);
    } else {
        flags = part_lane_step(c, &front, step, WF_PASS_FUSED | WF_PASS_COUNT, in_window);
    }
    cor_advance_leader(c, t_next);
    if ((rc = part_after(c, in_window, flags, err))) return rc;
    if (c->fault_slot >= 0) return cor_numerical_fault(c, step, err);
    part_measure(c, step, in_window);
    if (pt->p->rank == 0 && (rc = cor_phase_exits(c, ln, t_next, in_window, pt->n_own + pt->n_in, err))) return rc;
    part_next(c, t_next);
    return 0;
}

/* The whole road onto rank 0 (a checkpoint, the summary): every vehicle into its slot, each Edie cell and detector
 * its owner's (summed over the ranks, the others' at +0), the safety counts summed. */
int cor_part_collect(WfCorridor *c, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    int rc;
    size_t k = 0, nx = c->edie.nx, nc = c->sc->n_classes;
    for (int r = 0; r < p->size; k += pt->pre[r++].n) pt->off[r] = k * pt->vbytes;
    pt->off[p->size] = k * pt->vbytes;
    part_pack(c, pt->k_lo, pt->n_own, pt->all + pt->k_lo * pt->vbytes, 0);
    if ((rc = p->gather(p->ctx, pt->all, pt->off, 0, err))) return rc;
    if (p->rank == 0) part_pack(c, 0, c->ln[0].veh.n, pt->all, 1);
    pt->n_in = 0;
    WfEdie *e = &c->edie;
    for (size_t j = 0; j < e->nt + nc; j++) /* the rows of each field, then the class profiles' */
        for (size_t i = 0; i < nx; i++) {
            if (i >= pt->i_lo && i < pt->i_hi) continue;
            if (j < e->nt) e->dist_m[j * nx + i] = e->time_s[j * nx + i] = e->fuel_g[j * nx + i] = 0.0;
            else e->class_dist_m[(j - e->nt) * nx + i] = e->class_fuel_g[(j - e->nt) * nx + i] = 0.0;
        }
    WfDetectors *d = &c->det;
    for (size_t j = 0; j < d->n_int; j++)
        for (size_t q = 0; q < d->n_det; q++) {
            if (cor_part_holds(pt, d->x_m[q])) continue;
            size_t i = j * d->n_det + q;
            d->count[i] = 0, d->sum_v_mps[i] = d->sum_inv_v_spm[i] = d->occupied_s[i] = 0.0;
        }
    size_t ne = e->nt * nx, nd = d->n_int * d->n_det;
    double *f64[] = {e->dist_m, e->time_s, e->fuel_g, e->class_dist_m, e->class_fuel_g, d->sum_v_mps,
                     d->sum_inv_v_spm, d->occupied_s};
    size_t len[] = {ne, ne, ne, nc * nx, nc * nx, nd, nd, nd};
    for (size_t i = 0; !rc && i < sizeof len / sizeof len[0]; i++)
        rc = len[i] ? p->sum_f64(p->ctx, f64[i], len[i], err) : 0;
    if (!rc && nd) rc = p->sum_u64(p->ctx, (uint64_t *)d->count, nd, err);
    pt->safety_all = c->ln[0].lane.safety;
    if (!rc) rc = p->sum_u64(p->ctx, pt->safety_all.steps, WF_MAX_GROUPS, err);
    if (!rc) rc = p->sum_u64(p->ctx, pt->safety_all.hits, WF_MAX_GROUPS, err);
    return rc;
}

/* After a restore (every rank holds the whole road): every rank's vehicles, those whose fronts are on its segment,
 * and rear vehicle. */
void cor_part_restored(WfCorridor *c)
{
    CorPart *pt = &c->pt;
    const WfCorridorVehicles *vh = &c->ln[0].veh;
    for (int r = 0, k = 0; r < pt->p->size; r++) {
        size_t k1 = (size_t)k, s = 0;
        double lo = r + 1 == pt->p->size ? -INFINITY : part_cut(c, r + 1);
        while (k1 < vh->n && vh->x_m[s = wf_corridor_slot(vh, k1)] >= lo) k1++;
        PartRec *q = &pt->pre[r];
        *q = (PartRec){.n = k1 - (size_t)k};
        if (q->n) s = wf_corridor_slot(vh, k1 - 1), q->x = vh->x_m[s], q->v = vh->v_mps[s], q->len = vh->length_m[s];
        k = (int)k1;
    }
    part_layout(c);
    pt->n_in = 0;
    if (pt->p->rank) c->ln[0].lane.safety = (WfSafetyCount){{0}, {0}}; /* rank 0 holds the restored counts */
}

/* Time-blocked windows of a split corridor (time.block_steps; docs/mpi.md). Within a window each rank steps its own
 * vehicles k steps with the single-process window (corridor_window.c), behind a halo: the k + 1 rearmost vehicles of
 * the rank ahead, sent once at the window's start and stepped again here, so that their rearmost one, the leader of
 * this rank's front vehicle, is exact through the window (information flows one way, a vehicle a step). Vehicles
 * that cross a cut stay with their rank until the window ends; the rank ahead then measures them, step after step,
 * behind its own vehicles: the additions of the per-step path in its order. The entrance runs on the last rank
 * behind the road's back vehicle; every other rank repeats it from that vehicle's trace, so that every rank holds
 * the same queue and draws. The exits run on rank 0, and their virtual leader comes from there. A window in which
 * any rank overlaps, faults, or sees a vehicle move beyond the segment ahead of its own is undone on every rank and
 * stepped one step at a time: the bits of the per-step path, whatever k, ranks and threads. Messages per window:
 * an agreement to start, the halo (non-blocking, overlapped by the threads that step the interior), every rank's
 * record, the back vehicle's trace and the crossing vehicles with their rows. */

/* Before a window: every rank fits one (its own range of vehicles, and the rank ahead holds a halo of k + 1), then
 * the halo exchange is posted: this rank's k + 1 rearmost vehicles to the rank behind, the rank ahead's from it. */
int cor_part_window_begin(WfCorridor *c, int k, int fit, int *go, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    int unfit = !fit, rc = p->or_all(p->ctx, &unfit, err);
    *go = !rc && !unfit;
    if (!*go) return rc;
    size_t h = (size_t)k + 1, last = p->rank + 1 == p->size;
    if (!last) part_pack(c, pt->k_lo + pt->n_own - h, h, pt->halo_out, 0);
    pt->halo_rc = 0, pt->overlaps0 = c->st.counts.overlaps;
    return p->post_back(p->ctx, pt->halo_out, last ? 0 : h * pt->vbytes, pt->halo_in, p->rank ? h * pt->vbytes : 0,
                        err);
}

/* On the window's first thread before the front part: the halo received, into its vehicles' slots. */
int cor_part_window_wait(WfCorridor *c)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    pt->halo_rc = p->wait_next(p->ctx, &pt->halo_err);
    if (!pt->halo_rc && p->rank) part_pack(c, pt->k_lo - c->win.n_halo, c->win.n_halo, pt->halo_in, 1);
    return pt->halo_rc;
}

/* This rank's vehicles at the window's end: its own, less those that left at the exit, with those that entered. */
static size_t part_own_now(const WfCorridor *c)
{
    return c->ln[0].veh.n + c->pt.n_own - c->win.road_n;
}

/* After the window: every rank's record (PartRec) on every rank, and the flags they agree on into c->win.flags: any
 * rank's, or a vehicle beyond the segment ahead of its rank (at the exit, unless on rank 0), or more crossing than
 * the buffers hold (a vehicle that entered among them: its rows begin late). The stop requested too. */
int cor_part_window_agree(WfCorridor *c, int flags, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    CorWindow *cw = &c->win;
    int me = p->rank, rc;
    if (pt->halo_rc) {
        *err = pt->halo_err;
        return pt->halo_rc;
    }
    PartRec q = {0};
    part_moved(c, me, pt->k_lo, part_own_now(c), &q);
    if (q.skip || (me && q.past) || q.out > PART_CROSS_MAX || q.out > pt->n_own) flags |= WF_STEP_OVERLAP;
    q.repairs = (uint64_t)(c->st.counts.overlaps - pt->overlaps0);
    q.flags = (uint64_t)flags | (p->stop_own ? (uint64_t)*p->stop_own << PART_STOP_SHIFT : 0);
    if ((rc = p->allgather(p->ctx, &q, pt->wrec, sizeof q, err))) return rc;
    uint64_t all = 0, stop = 0;
    for (int r = 0; r < p->size; r++)
        all |= pt->wrec[r].flags & ((1u << PART_STOP_SHIFT) - 1), stop |= pt->wrec[r].flags >> PART_STOP_SHIFT;
    p->stop_all = (sig_atomic_t)stop;
    cw->flags = (int)all;
    return 0;
}

/* The rows of the window (positions before each step and after the last, fuel rates) of the vehicle in slot s, into
 * buf or from it (unpack); buf follows a packed vehicle, so it need not be aligned for doubles. */
static void part_rows(WfCorridor *c, size_t s, unsigned char *buf, int unpack)
{
    const CorWindow *cw = &c->win;
    size_t cap = c->ln[0].veh.cap, k = (size_t)cw->k, d = sizeof(double);
    for (size_t j = 0; j < 2 * k + 1; j++, buf += d) {
        double *row = j <= k ? &cw->x[j * cap + s] : &cw->rate[(j - k - 1) * cap + s];
        unpack ? memcpy(row, buf, d) : memcpy(buf, row, d);
    }
}

/* The window stands on every rank: the back vehicle's trace from the last rank, the vehicles that crossed into the
 * segment ahead passed to it with their rows, the measurement of this segment, the entrance repeated behind the
 * trace (every rank but the last), the repairs counted, and every rank's vehicles for the next step (part_next). */
int cor_part_window_end(WfCorridor *c, WfError *err)
{
    CorPart *pt = &c->pt;
    WfPartition *p = pt->p;
    CorWindow *cw = &c->win;
    CorLane *ln = &c->ln[0];
    WfCorridorVehicles *vh = &ln->veh;
    int me = p->rank, R = p->size, last = me + 1 == R, rc;
    size_t k = (size_t)cw->k, cap = vh->cap, own = part_own_now(c);
    double *tr = pt->trace; /* positions at the start of each step and after the last, then speeds */
    if (last) {
        const double *bx, *bv;
        wf_window_back_trace(&cw->w, &bx, &bv);
        memcpy(tr, bx, k * sizeof *tr), memcpy(tr + k + 1, bv, k * sizeof *tr);
        tr[k] = vh->x_m[cw->road_first];
    }
    if ((rc = wf_partition_from(p, tr, R - 1, 0, (2 * k + 1) * sizeof *tr, -1, pt->off, err))) return rc;
    /* the crossing vehicles, front first, each packed with its rows */
    size_t out = pt->wrec[me].out, in = last ? 0 : pt->wrec[me + 1].out;
    for (size_t j = 0; j < out; j++) {
        unsigned char *b = pt->cross_out + j * pt->cross_bytes;
        part_pack(c, pt->k_lo + j, 1, b, 0);
        part_rows(c, wf_corridor_slot(vh, pt->k_lo + j), b + pt->vbytes, 0);
    }
    rc = p->shift(p->ctx, pt->cross_out, out * pt->cross_bytes, pt->cross_in, in * pt->cross_bytes, err);
    if (rc) return rc;
    /* their rows behind this rank's vehicles, and the steps by whose end each had crossed the cut */
    for (size_t j = 0; j < in; j++)
        part_rows(c, (cw->first0 + cap - 1 - j) % cap, pt->cross_in + j * pt->cross_bytes + pt->vbytes, 1);
    for (size_t s = 0; s < k; s++) {
        size_t m = 0;
        while (m < in && cw->x[(s + 1) * cap + (cw->first0 + cap - 1 - m) % cap] >= pt->cut_lo) m++;
        cw->cr[s] = m;
        if (!last) cw->nb[s] = 0;
    }
    int nth = wf_lane_threads(cw->n0 + in, wf_governor_threads(&c->gov));
    if (nth <= 1) cor_window_measure(c, 0, 1);
    else {
#pragma omp parallel num_threads(nth) default(none) shared(c)
        {
#ifdef _OPENMP
            cor_window_measure(c, (size_t)omp_get_thread_num(), (size_t)omp_get_num_threads());
#else
            cor_window_measure(c, 0, 1);
#endif
        }
    }
    /* the crossing vehicles join this rank: behind its own */
    for (size_t j = 0; j < in; j++) part_pack(c, pt->k_lo + own + j, 1, pt->cross_in + j * pt->cross_bytes, 1);
    if (!last) { /* the entrance as the last rank ran it; its vehicles and counts are that rank's */
        WfSafetyCount counted = ln->lane.safety;
        cw->active = 1;
        int fl = cor_window_back(c, cw->step0, cw->k, cw->in_window, tr, tr + k + 1, tr[k], err);
        cw->active = 0;
        ln->lane.safety = counted;
        if (fl) return err->code ? err->code : wf_err(err, WF_ESYS, "the entrance of a window differs between ranks");
    }
    /* A speed outflow's leader restarts behind each vehicle that leaves, on rank 0 in the window; the other ranks'
     * copies, which no vehicle of theirs follows now, take it again at rank 0's next exit (part_next), before any
     * of them can need it (rank 0 holds k + 1 vehicles now). */
    for (int r = 0; r < R; r++) {
        if (r != me) c->st.counts.overlaps += (int64_t)pt->wrec[r].repairs;
        pt->post[r] = pt->wrec[r];
    }
    pt->n_in = 0;
    part_next(c, (double)(cw->step0 + cw->k) * c->sc->dt_s);
    return 0;
}
