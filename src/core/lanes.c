/* Lane changes of a multi-lane road (lanes.h). */
#include "core/lanes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/block.h"
#include "core/par.h"
#include "util/mem.h"
#include "wavefuel/lanechange.h"

int wf_lanes_create(WfLaneChanges *lc, const WfScenario *sc, size_t n, size_t n_lanes, WfError *err)
{
    *lc = (WfLaneChanges){.n = n, .n_lanes = n_lanes};
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfDriverGroup *grp = &sc->groups[g];
        if (!grp->lc) continue;
        lc->active = 1;
        lc->interval_steps[g] = (int64_t)ceil(grp->lc->min_interval_s(grp->lc_params) / sc->dt_s - 1e-9);
        double yield_mps2, range_m;
        grp->lc->cooperation(grp->lc_params, &yield_mps2, &range_m);
        lc->coop |= yield_mps2 > 0.0;
    }
    if (!lc->active || n_lanes < 2) return lc->active = 0;
    size_t nb = n / WF_BLOCK + n_lanes + 1;
    int ok = (lc->p_m = malloc(n * sizeof *lc->p_m)) && (lc->tgt[0] = malloc(n * sizeof *lc->tgt[0])) &&
             (lc->tgt[1] = malloc(n * sizeof *lc->tgt[1])) && (lc->dir = malloc(n * sizeof *lc->dir)) &&
             (lc->adv_mps2 = malloc(n * sizeof *lc->adv_mps2)) &&
             (lc->claim = malloc((n + n_lanes) * sizeof *lc->claim)) && (lc->perm = malloc(n * sizeof *lc->perm)) &&
             (lc->shift_m = malloc(n * sizeof *lc->shift_m)) && (lc->scratch = malloc(n * sizeof(double))) &&
             (lc->blk = malloc(nb * sizeof *lc->blk)) && (lc->blkl = malloc(nb * sizeof *lc->blkl)) &&
             (lc->coop_who = malloc(2 * n * sizeof *lc->coop_who)) &&
             (lc->coop_cap_mps2 = malloc(2 * n * sizeof *lc->coop_cap_mps2));
    if (!ok) return wf_err(err, WF_ESYS, "out of memory for the lane changes of %zu vehicles", n);
    return 0;
}

void wf_lanes_destroy(WfLaneChanges *lc)
{
    WF_FREE(lc->p_m, lc->tgt[0], lc->tgt[1], lc->dir, lc->adv_mps2, lc->claim, lc->perm, lc->shift_m, lc->scratch,
            lc->blk, lc->blkl, lc->coop_who, lc->coop_cap_mps2);
    *lc = (WfLaneChanges){0};
}

/* ------------------------------------------------------------------------------------------- the decisions */

/* From position a forward to position b (around the ring: in [0, L); on an open road b >= a here). */
static inline double fwd(double a, double b, double L)
{
    double d = b - a;
    return d < 0.0 ? d + L : d;
}

static inline double len_of(const WfLcRoad *r, size_t i) { return r->class_length_m[r->class_id[i]]; }

/* Vehicle i's car-following acceleration behind a leader at bumper-to-bumper gap gap_m driving at vl_mps: its own
 * model or controller, with its own parameters and memory, before noise and limits. */
static double accel_of(const WfLcRoad *r, size_t i, double gap_m, double v_mps, double vl_mps)
{
    const WfCfModel *m = r->sc->groups[r->group_id[i]].model;
    const void *st = m->state_size && r->state ? r->state(r, i) : NULL;
    return m->accel(r->params(r, i), st, gap_m, v_mps, vl_mps);
}

/* For each vehicle of lane l, the index in lane m of its leader there (the first vehicle at or ahead of its position;
 * on a ring around it, on an open road count[m] when none is ahead): one walk of both lanes in the order of
 * positions (a lane's indices are its positions in order, rotated by rot on a ring). */
static void neighbours(WfLaneChanges *lc, const WfLcRoad *r, size_t l, size_t m, int d)
{
    size_t nl = r->count[l], nm = r->count[m], fl = r->first[l], fm = r->first[m];
    uint32_t *tgt = lc->tgt[d];
    const double *p = r->p_m;
    if (!nm) {
        for (size_t k = 0; k < nl; k++) tgt[fl + k] = 0;
        return;
    }
    /* q walks lane l from its rearmost vehicle (index kl), j counts lane m's vehicles behind it (index km) */
    size_t kl = r->rot[l], km = r->rot[m], j = 0;
    for (size_t q = 0; q < nl; q++) {
        double pi = p[fl + kl];
        while (j < nm && p[fm + km] < pi) {
            j++;
            km = km + 1 < nm ? km + 1 : 0;
        }
        tgt[fl + kl] = (uint32_t)(j < nm ? km : r->periodic ? r->rot[m] : nm);
        kl = kl + 1 < nl ? kl + 1 : 0;
    }
}

/* The accelerations a change concerns, for a batch of vehicles at once (WfLcCase's six, each a list of who, gap,
 * own speed, leader speed). */
enum { EV_OWN_NOW, EV_OWN_NEW, EV_NEW_NOW, EV_NEW_NEW, EV_OLD_NOW, EV_OLD_NEW, EV_N };
typedef struct Batch {
    uint32_t who[EV_N][WF_BLOCK];
    double   gap[EV_N][WF_BLOCK], v[EV_N][WF_BLOCK], vl[EV_N][WF_BLOCK], a[EV_N][WF_BLOCK];
    uint32_t cand[WF_BLOCK];       /* the changer of each case */
    uint8_t  has_new[WF_BLOCK], has_old[WF_BLOCK];
    uint32_t idx[WF_BLOCK];
    double   gg[WF_BLOCK], gv[WF_BLOCK], gl[WF_BLOCK], ga[WF_BLOCK];
} Batch;

/* Car-following accelerations a[j] of vehicles who[j] (their own model or controller, parameters and memory, before
 * noise and limits): group by group, through the model's block form when the group shares one parameter set and
 * keeps no memory (the same arithmetic as accel(), so the same bits), else accel() per vehicle. */
static void eval(const WfLcRoad *r, Batch *bt, int e, size_t cnt)
{
    const WfScenario *sc = r->sc;
    const uint32_t *who = bt->who[e];
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfCfModel *m = sc->groups[g].model;
        size_t c = 0;
        for (size_t j = 0; j < cnt; j++)
            if (r->group_id[who[j]] == g) bt->idx[c++] = (uint32_t)j;
        if (!c) continue;
        if (m->accel_block && !m->state_size && r->group_params[g]) {
            for (size_t q = 0; q < c; q++) {
                size_t j = bt->idx[q];
                bt->gg[q] = bt->gap[e][j], bt->gv[q] = bt->v[e][j], bt->gl[q] = bt->vl[e][j];
            }
            m->accel_block(r->group_params[g], 0, c, bt->gg, bt->gv, bt->gl, bt->ga);
            for (size_t q = 0; q < c; q++) bt->a[e][bt->idx[q]] = bt->ga[q];
            continue;
        }
        for (size_t q = 0; q < c; q++) {
            size_t j = bt->idx[q];
            bt->a[e][j] = accel_of(r, who[j], bt->gap[e][j], bt->v[e][j], bt->vl[e][j]);
        }
    }
}

static inline void put(Batch *bt, int e, size_t c, size_t who, double gap, double v, double vl)
{
    bt->who[e][c] = (uint32_t)who, bt->gap[e][c] = gap, bt->v[e][c] = v, bt->vl[e][c] = vl;
}

/* Vehicle i's (index k of its lane, first fl, count nl) leader inside its lane as an acceleration's inputs: its gap
 * and the leader's speed; the lane's last follows its first one lap ahead on a ring, the lane's front leader on an
 * open road. */
static void lane_lead(const WfLcRoad *r, size_t l, size_t i, double *gap, double *vl)
{
    size_t fl = r->first[l], nl = r->count[l], kl = i - fl + 1 < nl ? i - fl + 1 : 0, ld = fl + kl;
    const double *x = r->x_m;
    if (kl || r->periodic) {
        *gap = x[ld] + (kl ? 0.0 : r->L) - len_of(r, ld) - x[i], *vl = r->v_mps[ld];
    } else if (r->front[l].free_gap_m > 0.0) {
        *gap = r->front[l].free_gap_m, *vl = r->v_mps[i];
    } else {
        *gap = r->front[l].rear_m - x[i], *vl = r->front[l].v_mps;
    }
}

/* Vehicle i's gap and leader's speed behind the front leader of lane m (an open road's lane it would lead). */
static void front_lead(const WfLcRoad *r, size_t m, size_t i, double *gap, double *vl)
{
    if (r->front[m].free_gap_m > 0.0) *gap = r->front[m].free_gap_m, *vl = r->v_mps[i];
    else *gap = r->front[m].rear_m - r->x_m[i], *vl = r->front[m].v_mps;
}

/* Vehicle i's case for a change into lane m in direction d, as the c-th of the batch; 0: no room (unsafe). */
static int put_case(const WfLaneChanges *lc, const WfLcRoad *r, Batch *bt, size_t c, size_t i, size_t l, size_t m,
                    int d)
{
    const double *x = r->x_m, *v = r->v_mps, *p = r->p_m, L = r->L;
    size_t nm = r->count[m], fm = r->first[m], nl = r->count[l], fl = r->first[l], ki = i - fl, tg = lc->tgt[d][i];
    double len_i = len_of(r, i), gap, vl;
    bt->has_new[c] = 0, bt->has_old[c] = 0;
    put(bt, EV_NEW_NOW, c, i, 1.0, 0.0, 0.0), put(bt, EV_NEW_NEW, c, i, 1.0, 0.0, 0.0);
    put(bt, EV_OLD_NOW, c, i, 1.0, 0.0, 0.0), put(bt, EV_OLD_NEW, c, i, 1.0, 0.0, 0.0);
    if (!nm && r->periodic) {
        put(bt, EV_OWN_NEW, c, i, L - len_i, v[i], v[i]); /* alone in the lane: it follows itself */
    } else if (tg == nm) {
        front_lead(r, m, i, &gap, &vl); /* ahead of the lane's front (or an empty lane) */
        if (!(gap > 0.0)) return 0;
        put(bt, EV_OWN_NEW, c, i, gap, v[i], vl);
    } else {
        size_t g = fm + tg;
        double gap_new = fwd(p[i], p[g], L) - len_of(r, g);
        if (!(gap_new > 0.0)) return 0;
        put(bt, EV_OWN_NEW, c, i, gap_new, v[i], v[g]);
    }
    if (nm && (tg || r->periodic)) { /* the new follower: the one behind that gap */
        size_t fo = fm + (tg ? tg - 1 : nm - 1);
        double gap_fo_new = fwd(p[fo], p[i], L) - len_i;
        if (!(gap_fo_new > 0.0)) return 0;
        lane_lead(r, m, fo, &gap, &vl);
        bt->has_new[c] = 1;
        put(bt, EV_NEW_NOW, c, fo, gap, v[fo], vl);
        put(bt, EV_NEW_NEW, c, fo, gap_fo_new, v[fo], v[i]);
    }
    if (nl >= 2 && (ki || r->periodic)) { /* the old follower: behind it now, behind its leader after */
        size_t ko = ki ? ki - 1 : nl - 1, o = fl + ko, kl = ki + 1 < nl ? ki + 1 : 0, ld = fl + kl;
        bt->has_old[c] = 1;
        put(bt, EV_OLD_NOW, c, o, x[i] + (ki ? 0.0 : L) - len_i - x[o], v[o], v[i]);
        if (r->periodic && nl == 2) put(bt, EV_OLD_NEW, c, o, L - len_of(r, o), v[o], v[o]);
        else if (kl || r->periodic) put(bt, EV_OLD_NEW, c, o, fwd(p[o], p[ld], L) - len_of(r, ld), v[o], v[ld]);
        else front_lead(r, l, o, &gap, &vl), put(bt, EV_OLD_NEW, c, o, gap, v[o], vl);
    }
    return 1;
}

/* Whether vehicle i, bound for the off-ramp, is on its approach (where it keeps to its way there). */
static inline int approaching(const WfLcRoad *r, size_t i)
{
    return r->exiting && r->exiting[i] && r->x_m[i] >= r->exit_at_m - r->exit_approach_m && r->x_m[i] < r->exit_at_m;
}

/* Whether vehicle i (of a group with a lane-change model) must leave lane l: the lane ends within its driver's merge
 * range. */
static int must_leave(const WfLcRoad *r, size_t l, size_t i)
{
    const WfDriverGroup *grp = &r->sc->groups[r->group_id[i]];
    double yield_mps2, range_m;
    if (!isfinite(r->end_m[l])) return 0;
    grp->lc->cooperation(grp->lc_params, &yield_mps2, &range_m);
    return r->end_m[l] - r->x_m[i] <= range_m;
}

/* The rule vehicle i of lane l changes by: mandatory when it must leave its lane or is on the off-ramp's approach;
 * else the road's. */
static int rule_of(const WfLcRoad *r, size_t l, size_t i)
{
    return approaching(r, i) || must_leave(r, l, i) ? WF_LANE_RULE_MANDATORY : r->sc->lane_rule;
}

/* The decisions of the m vehicles of lane l from index i0: each one's side with the larger positive advantage (the
 * right one at a tie), or none. */
static void decide_block(WfLaneChanges *lc, const WfLcRoad *r, size_t l, size_t i0, size_t m, long step, Batch *bt)
{
    const WfScenario *sc = r->sc;
    for (size_t k = 0; k < m; k++) {
        size_t i = i0 + k;
        double gap, vl;
        lc->dir[i] = 0, lc->adv_mps2[i] = 0.0;
        lane_lead(r, l, i, &gap, &vl);
        put(bt, EV_OWN_NOW, k, i, gap, r->v_mps[i], vl);
    }
    eval(r, bt, EV_OWN_NOW, m);
    double own_now[WF_BLOCK];
    memcpy(own_now, bt->a[EV_OWN_NOW], m * sizeof *own_now);
    for (int d = 0; d < 2; d++) {
        if ((d == 0 && l == 0) || (d == 1 && l + 1 == r->n_lanes)) continue;
        size_t tl = d ? l + 1 : l - 1, c = 0;
        if (isfinite(r->end_m[tl])) continue; /* a lane that ends takes nobody */
        for (size_t k = 0; k < m; k++) {
            size_t i = i0 + k;
            if (!sc->groups[r->group_id[i]].lc || step < r->ready_step[i]) continue;
            /* on the approach: toward the exit lane only (from above it or from a merge lane below), then hold it */
            if (approaching(r, i) && (l == r->exit_lane || (l > r->exit_lane) != (d == 0))) continue;
            bt->cand[c] = (uint32_t)k;
            c += (size_t)put_case(lc, r, bt, c, i, l, tl, d);
        }
        if (!c) continue;
        for (int e = EV_OWN_NEW; e < EV_N; e++) eval(r, bt, e, c);
        for (size_t q = 0; q < c; q++) {
            size_t k = bt->cand[q], i = i0 + k;
            const WfDriverGroup *grp = &sc->groups[r->group_id[i]];
            WfLcCase cs = {own_now[k], bt->a[EV_OWN_NEW][q], bt->a[EV_NEW_NOW][q], bt->a[EV_NEW_NEW][q],
                           bt->a[EV_OLD_NOW][q], bt->a[EV_OLD_NEW][q], bt->has_new[q], bt->has_old[q]};
            double adv = grp->lc->advantage(grp->lc_params, d ? WF_LANE_LEFT : WF_LANE_RIGHT, rule_of(r, l, i), &cs);
            if (adv > lc->adv_mps2[i]) lc->adv_mps2[i] = adv, lc->dir[i] = (int8_t)(d ? WF_LANE_LEFT : WF_LANE_RIGHT);
        }
    }
}

/* The decisions of the blocks lc->blk[0 .. nblk), shared among the threads of the team that calls it (if any). */
static void decide_all(WfLaneChanges *lc, const WfLcRoad *r, long step, size_t nblk, const uint8_t *lane_of_blk)
{
    Batch bt;
#pragma omp for schedule(static)
    for (size_t b = 0; b < nblk; b++) {
        size_t i0 = lc->blk[b], l = lane_of_blk[b], end = r->first[l] + r->count[l];
        decide_block(lc, r, l, i0, end - i0 < WF_BLOCK ? end - i0 : WF_BLOCK, step, &bt);
    }
}

/* One gap per step takes one vehicle: a claim beats another only with a larger advantage (index order breaks
 * ties). */
static long resolve(WfLaneChanges *lc, const WfLcRoad *r)
{
    long changes = 0;
    memset(lc->claim, 0, (r->n + r->n_lanes) * sizeof *lc->claim);
    for (size_t l = 0; l < r->n_lanes; l++)
        for (size_t i = r->first[l]; i < r->first[l] + r->count[l]; i++) {
            if (!lc->dir[i]) continue;
            size_t m = (size_t)((long)l + lc->dir[i]), key = r->first[m] + m + lc->tgt[lc->dir[i] > 0][i];
            uint32_t c = lc->claim[key];
            if (c && !(lc->adv_mps2[i] > lc->adv_mps2[c - 1])) {
                lc->dir[i] = 0;
                continue;
            }
            if (c) lc->dir[c - 1] = 0, changes--;
            lc->claim[key] = (uint32_t)(i + 1);
            changes++;
        }
    return changes;
}

long wf_lanes_decide(WfLaneChanges *lc, const WfLcRoad *r, long step, int nthreads)
{
    if (!lc->active) return 0;
    size_t nlanes = r->n_lanes, nblk = 0, npair = 2 * nlanes;
    /* each lane's walk beside the lane to its right (d 0) and to its left (d 1): independent of one another */
    int nthp = wf_lane_threads(r->n, nthreads);
    WF_PAR_FOR(nthp > 1, "omp parallel for schedule(dynamic, 1) num_threads(nthp) default(none) shared(lc, r, nlanes, npair)",
    for (size_t q = 0; q < npair; q++) {
        size_t l = q / 2;
        int d = (int)(q % 2);
        if (d == 0 && l > 0) neighbours(lc, r, l, l - 1, 0);
        if (d == 1 && l + 1 < nlanes) neighbours(lc, r, l, l + 1, 1);
    });
    /* the decisions, block by block of each lane (blocks of WF_BLOCK vehicles from each lane's first) */
    for (size_t l = 0; l < nlanes; l++)
        for (size_t k = 0; k < r->count[l]; k += WF_BLOCK)
            lc->blk[nblk] = (uint32_t)(r->first[l] + k), lc->blkl[nblk++] = (uint8_t)l;
    int nth = wf_lane_threads(r->n, nthreads);
    if (nth > 1) {
#pragma omp parallel num_threads(nth) default(none) shared(lc, r, step, nblk)
        decide_all(lc, r, step, nblk, lc->blkl);
    } else {
        decide_all(lc, r, step, nblk, lc->blkl);
    }
    return resolve(lc, r);
}

/* ------------------------------------------------------------------------------------------- cooperation */

/* Whether vehicle i of lane l asks the vehicles of lane m to let it in: it is on the off-ramp's approach and m lies
 * toward the exit lane, or it must leave a lane that ends, within its driver's merge range of the end. */
static int asks(const WfLcRoad *r, size_t l, size_t m, size_t i)
{
    if (!r->sc->groups[r->group_id[i]].lc) return 0;
    if (approaching(r, i)) return l > r->exit_lane ? m < l : l < r->exit_lane && m > l;
    return must_leave(r, l, i);
}

/* The askers of lane l toward lane m: each one's follower there (the last of lane m behind it, one walk of both
 * lanes in the order of positions), and whether that follower yields. */
static size_t cooperate_pair(WfLaneChanges *lc, const WfLcRoad *r, size_t l, size_t m, size_t nc)
{
    const WfScenario *sc = r->sc;
    const double *x = r->x_m, *v = r->v_mps;
    size_t fm = r->first[m], nm = r->count[m], j = 0;
    for (size_t i = r->first[l]; i < r->first[l] + r->count[l]; i++) {
        if (!asks(r, l, m, i)) continue;
        while (j < nm && x[fm + j] < x[i]) j++;
        if (!j) continue;
        size_t f = fm + j - 1;
        const WfDriverGroup *gf = &sc->groups[r->group_id[f]];
        double yield_mps2, range_m;
        if (!gf->lc) continue;
        gf->lc->cooperation(gf->lc_params, &yield_mps2, &range_m);
        double gap = x[i] - len_of(r, i) - x[f];
        if (!(yield_mps2 > 0.0) || !(gap > 0.0)) continue;
        double a = accel_of(r, f, gap, v[f], v[i]);
        if (!(a >= -yield_mps2)) continue;
        lc->coop_who[nc] = (uint32_t)f, lc->coop_cap_mps2[nc++] = a;
    }
    return nc;
}

size_t wf_lanes_cooperate(WfLaneChanges *lc, const WfLcRoad *r)
{
    size_t nc = 0;
    if (!lc->active || !lc->coop) return 0;
    for (size_t l = 0; l < r->n_lanes; l++) {
        int ends = isfinite(r->end_m[l]), exits = r->exiting && l != r->exit_lane;
        if (!r->count[l] || !(ends || exits)) continue;
        if (l > 0 && !isfinite(r->end_m[l - 1])) nc = cooperate_pair(lc, r, l, l - 1, nc);
        if (l + 1 < r->n_lanes && !isfinite(r->end_m[l + 1])) nc = cooperate_pair(lc, r, l, l + 1, nc);
    }
    return nc;
}

/* ------------------------------------------------------------------------------------------------ the ring */

/* A ring vehicle's parameters and controller memory (the road's ctx is the fleet). */
static const void *ring_params(const WfLcRoad *r, size_t i) { return wf_fleet_params(r->ctx, r->sc, i); }
static const void *ring_state(const WfLcRoad *r, size_t i)
{
    const WfFleet *f = r->ctx;
    size_t g = f->group_id[i];
    return f->group_state[g] + wf_fleet_slot(f, i) * r->sc->groups[g].model->state_size;
}

void wf_lanes_ring_road(WfLaneChanges *lc, const WfScenario *sc, const WfFleet *f, WfLcRoad *r)
{
    size_t n = f->n;
    double L = sc->road.length_m;
    *r = (WfLcRoad){.sc = sc, .periodic = 1, .L = L, .n = n, .n_lanes = f->n_lanes, .x_m = f->x_m, .p_m = lc->p_m,
                    .v_mps = f->v_mps, .class_id = f->class_id, .group_id = f->group_id,
                    .ready_step = f->lc_ready_step, .class_length_m = f->class_length_m, .params = ring_params,
                    .state = ring_state, .ctx = f};
    for (size_t g = 0; g < f->n_groups; g++) r->group_params[g] = f->group_param_stride[g] ? NULL : f->group_params[g];
    for (size_t l = 0; l < WF_MAX_LANES; l++) r->end_m[l] = INFINITY;
    for (size_t l = 0, first = 0; l < f->n_lanes; first += f->lane_n[l++]) r->first[l] = first, r->count[l] = f->lane_n[l];
    const double *x = f->x_m;
    double *p = lc->p_m;
    WF_PAR_FOR(n >= WF_PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, p, L)",
    for (size_t i = 0; i < n; i++) {
        double q = x[i] - L * (double)wf_lap_index(x[i] / L);
        p[i] = q >= L ? q - L : q < 0.0 ? q + L : q;
    });
    for (size_t l = 0; l < f->n_lanes; l++)
        for (size_t k = 1; k < f->lane_n[l]; k++)
            if (lc->p_m[r->first[l] + k] < lc->p_m[r->first[l] + k - 1]) {
                r->rot[l] = k;
                break;
            }
}

/* Ring lane m's new order into perm from slot j on (its vehicles that stay, each newcomer right behind the leader it
 * chose; behind the lane's first vehicle is after its last), and the laps each newcomer's position moves by so that
 * positions increase along the lane within one lap. Returns the lane's new count. */
static size_t new_order(WfLaneChanges *lc, const WfLcRoad *r, size_t m, size_t j)
{
    const double *x = r->x_m, L = r->L;
    size_t nm = r->count[m], fm = r->first[m], start = j;
    const uint32_t *claim = lc->claim + fm + m;
    if (nm && !lc->dir[fm]) lc->perm[j++] = (uint32_t)fm;
    for (size_t k = 1; k < nm; k++) {
        if (claim[k]) lc->perm[j++] = claim[k] - 1;
        if (!lc->dir[fm + k]) lc->perm[j++] = (uint32_t)(fm + k);
    }
    if (claim[0]) lc->perm[j++] = claim[0] - 1;
    /* positions: stayers keep theirs; a newcomer takes the one of its lap that lies after the vehicle before it
     * (or, before the first stayer, before the vehicle after it) */
    size_t q = start;
    while (q < j && lc->dir[lc->perm[q]]) q++;
    if (q == j) q = start;
    for (size_t s = start; s < j; s++) lc->shift_m[s] = 0.0;
    for (size_t s = q + 1; s < j; s++) {
        double xprev = x[lc->perm[s - 1]] - lc->shift_m[s - 1], xs = x[lc->perm[s]];
        if (lc->dir[lc->perm[s]]) lc->shift_m[s] = L * (double)wf_lap_index((xs - xprev) / L);
    }
    for (size_t s = q; s-- > start;) {
        double xnext = x[lc->perm[s + 1]] - lc->shift_m[s + 1], xs = x[lc->perm[s]];
        lc->shift_m[s] = L * (double)(wf_lap_index((xs - xnext) / L) + 1);
    }
    return j - start;
}

/* Every per-vehicle array into its new slots. */
static void permute(WfLaneChanges *lc, const WfStateVar *vars, size_t nv)
{
    size_t n = lc->n;
    const uint32_t *perm = lc->perm;
    for (size_t k = 0; k < nv; k++) {
        size_t st = vars[k].stride;
        if (!st) continue;
        unsigned char *a = vars[k].data, *s = lc->scratch;
        switch (st) {
        case 8: for (size_t j = 0; j < n; j++) memcpy(s + 8 * j, a + 8 * (size_t)perm[j], 8); break;
        case 4: for (size_t j = 0; j < n; j++) memcpy(s + 4 * j, a + 4 * (size_t)perm[j], 4); break;
        case 2: for (size_t j = 0; j < n; j++) memcpy(s + 2 * j, a + 2 * (size_t)perm[j], 2); break;
        default: for (size_t j = 0; j < n; j++) memcpy(s + st * j, a + st * (size_t)perm[j], st); break;
        }
        memcpy(a, s, n * st);
    }
}

void wf_lanes_apply_ring(WfLaneChanges *lc, const WfLcRoad *r, WfFleet *f, long step, const WfStateVar *vars,
                         size_t nv, WfLaneCounts *cnt)
{
    size_t nlanes = f->n_lanes, newn[WF_MAX_LANES];
    for (size_t m = 0, j = 0; m < nlanes; m++) j += newn[m] = new_order(lc, r, m, j);
    permute(lc, vars, nv);
    for (size_t l = 0, j = 0; l < nlanes; l++) {
        f->lane_n[l] = newn[l];
        for (size_t k = 0; k < newn[l]; k++, j++) {
            f->lane[j] = (uint8_t)l;
            f->pos[f->id[j]] = (uint32_t)j;
            int8_t d = lc->dir[lc->perm[j]];
            if (!d) continue;
            f->x_m[j] -= lc->shift_m[j];
            f->x_start_m[j] -= lc->shift_m[j];
            f->lap_m[j] += lc->shift_m[j];
            f->lc_ready_step[j] = step + lc->interval_steps[f->group_id[j]];
            f->lane_changes[j]++;
            cnt->changes++;
            cnt->pair[l - (size_t)(long)d][l]++;
            cnt->group_changes[f->group_id[j]]++;
            if (newn[l] < 2) continue;
            size_t behind = k ? j - 1 : j + newn[l] - 1; /* the vehicle it now leads */
            f->cut_ins[behind]++;
            cnt->cut_ins++;
            cnt->lane_cut_ins[l]++;
            cnt->group_cut_ins[f->group_id[behind]]++;
        }
    }
}
