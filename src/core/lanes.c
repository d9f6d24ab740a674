/* Lane changes on a multi-lane ring (lanes.h). */
#include "core/lanes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/block.h"
#include "wavefuel/lanechange.h"

int wf_lanes_create(WfLaneChanges *lc, const WfScenario *sc, size_t n, size_t n_lanes, WfError *err)
{
    *lc = (WfLaneChanges){.n = n, .n_lanes = n_lanes};
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfDriverGroup *grp = &sc->groups[g];
        if (!grp->lc) continue;
        lc->active = 1;
        lc->interval_steps[g] = (int64_t)ceil(grp->lc->min_interval_s(grp->lc_params) / sc->dt_s - 1e-9);
    }
    if (!lc->active || n_lanes < 2) return lc->active = 0;
    lc->p_m = malloc(n * sizeof *lc->p_m);
    lc->tgt[0] = malloc(n * sizeof *lc->tgt[0]);
    lc->tgt[1] = malloc(n * sizeof *lc->tgt[1]);
    lc->dir = malloc(n * sizeof *lc->dir);
    lc->adv_mps2 = malloc(n * sizeof *lc->adv_mps2);
    lc->claim = malloc((n + n_lanes) * sizeof *lc->claim);
    lc->perm = malloc(n * sizeof *lc->perm);
    lc->shift_m = malloc(n * sizeof *lc->shift_m);
    lc->scratch = malloc(n * sizeof(double));
    lc->blk = malloc((n / WF_BLOCK + n_lanes + 1) * sizeof *lc->blk);
    if (!lc->p_m || !lc->tgt[0] || !lc->tgt[1] || !lc->dir || !lc->adv_mps2 || !lc->claim || !lc->perm ||
        !lc->shift_m || !lc->scratch || !lc->blk)
        return wf_err(err, WF_ESYS, "out of memory for the lane changes of %zu vehicles", n);
    return 0;
}

void wf_lanes_destroy(WfLaneChanges *lc)
{
    free(lc->p_m);
    free(lc->tgt[0]);
    free(lc->tgt[1]);
    free(lc->dir);
    free(lc->adv_mps2);
    free(lc->claim);
    free(lc->perm);
    free(lc->shift_m);
    free(lc->scratch);
    free(lc->blk);
    *lc = (WfLaneChanges){0};
}

/* The road as the decisions see it. */
typedef struct Road {
    const WfScenario *sc;
    const WfFleet    *f;
    const double     *p;                     /* positions around the ring */
    double            L;
    size_t            first[WF_MAX_LANES];   /* each lane's first slot */
} Road;

/* From position a forward to position b around the ring, in [0, L). */
static inline double fwd(double a, double b, double L)
{
    double d = b - a;
    return d < 0.0 ? d + L : d;
}

static inline double len_of(const Road *r, size_t i) { return r->f->class_length_m[r->f->class_id[i]]; }

/* Vehicle i's car-following acceleration behind a leader at bumper-to-bumper gap gap_m driving at vl_mps: its own
 * model or controller, with its own parameters and memory, before noise and limits. */
static double accel_of(const Road *r, size_t i, double gap_m, double v_mps, double vl_mps)
{
    const WfFleet *f = r->f;
    size_t g = f->group_id[i];
    const WfCfModel *m = r->sc->groups[g].model;
    const void *st = m->state_size ? f->group_state[g] + wf_fleet_slot(f, i) * m->state_size : NULL;
    return m->accel(wf_fleet_params(f, r->sc, i), st, gap_m, v_mps, vl_mps);
}

/* For each vehicle of lane l, the index in lane m of its leader there (the first vehicle at or ahead of its position
 * around the ring): one walk of both lanes in the order of positions. rot: each lane's index of its rearmost
 * position (a lane's slots are its positions in order, rotated). */
static void neighbours(WfLaneChanges *lc, const Road *r, const size_t *rot, size_t l, size_t m, int d)
{
    const WfFleet *f = r->f;
    size_t nl = f->lane_n[l], nm = f->lane_n[m], fl = r->first[l], fm = r->first[m];
    uint32_t *tgt = lc->tgt[d];
    const double *p = r->p;
    if (!nm) {
        for (size_t k = 0; k < nl; k++) tgt[fl + k] = UINT32_MAX;
        return;
    }
    /* q walks lane l from its rearmost vehicle (slot index kl), j counts lane m's vehicles behind it (index km) */
    size_t kl = rot[l], km = rot[m], j = 0;
    for (size_t q = 0; q < nl; q++) {
        double pi = p[fl + kl];
        while (j < nm && p[fm + km] < pi) {
            j++;
            km = km + 1 < nm ? km + 1 : 0;
        }
        tgt[fl + kl] = (uint32_t)(j == nm ? rot[m] : km);
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
static void eval(const Road *r, Batch *bt, int e, size_t cnt)
{
    const WfFleet *f = r->f;
    const WfScenario *sc = r->sc;
    const uint32_t *who = bt->who[e];
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfCfModel *m = sc->groups[g].model;
        size_t c = 0;
        for (size_t j = 0; j < cnt; j++)
            if (f->group_id[who[j]] == g) bt->idx[c++] = (uint32_t)j;
        if (!c) continue;
        if (m->accel_block && !m->state_size && !f->group_param_stride[g]) {
            for (size_t q = 0; q < c; q++) {
                size_t j = bt->idx[q];
                bt->gg[q] = bt->gap[e][j], bt->gv[q] = bt->v[e][j], bt->gl[q] = bt->vl[e][j];
            }
            m->accel_block(f->group_params[g], 0, c, bt->gg, bt->gv, bt->gl, bt->ga);
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

/* The decisions of the m vehicles of lane l from slot i0: each one's side with the larger positive advantage (the
 * right one at a tie), or none. */
static void decide_block(WfLaneChanges *lc, const Road *r, size_t l, size_t i0, size_t m, long step, Batch *bt)
{
    const WfFleet *f = r->f;
    const WfScenario *sc = r->sc;
    const double *x = f->x_m, *v = f->v_mps, *p = r->p, L = r->L;
    size_t fl = r->first[l], nl = f->lane_n[l];
    for (size_t k = 0; k < m; k++) {
        size_t i = i0 + k, kl = i - fl + 1 < nl ? i - fl + 1 : 0, ld = fl + kl;
        lc->dir[i] = 0, lc->adv_mps2[i] = 0.0;
        put(bt, EV_OWN_NOW, k, i, x[ld] + (kl ? 0.0 : L) - len_of(r, ld) - x[i], v[i], v[ld]);
    }
    eval(r, bt, EV_OWN_NOW, m);
    double own_now[WF_BLOCK];
    memcpy(own_now, bt->a[EV_OWN_NOW], m * sizeof *own_now);
    for (int d = 0; d < 2; d++) {
        if ((d == 0 && l == 0) || (d == 1 && l + 1 == f->n_lanes)) continue;
        size_t tl = d ? l + 1 : l - 1, nm = f->lane_n[tl], fm = r->first[tl], c = 0;
        for (size_t k = 0; k < m; k++) {
            size_t i = i0 + k, ki = i - fl;
            const WfDriverGroup *grp = &sc->groups[f->group_id[i]];
            if (!grp->lc || step < f->lc_ready_step[i]) continue;
            double len_i = len_of(r, i);
            bt->cand[c] = (uint32_t)k;
            bt->has_new[c] = nm > 0, bt->has_old[c] = nl >= 2;
            if (!nm) {
                put(bt, EV_OWN_NEW, c, i, L - len_i, v[i], v[i]); /* alone in the lane: it follows itself */
                put(bt, EV_NEW_NOW, c, i, 1.0, 0.0, 0.0), put(bt, EV_NEW_NEW, c, i, 1.0, 0.0, 0.0);
            } else {
                size_t tg = lc->tgt[d][i], g = fm + tg, fo = fm + (tg ? tg - 1 : nm - 1);
                double gap_new = fwd(p[i], p[g], L) - len_of(r, g), gap_fo_new = fwd(p[fo], p[i], L) - len_i;
                if (!(gap_new > 0.0) || !(gap_fo_new > 0.0)) continue; /* no room: unsafe */
                put(bt, EV_OWN_NEW, c, i, gap_new, v[i], v[g]);
                /* the new follower's gap now, as the kernel takes it: its leader is the next slot (a lap ahead at the
                 * lane's wrap) */
                put(bt, EV_NEW_NOW, c, fo, x[g] + (tg ? 0.0 : L) - len_of(r, g) - x[fo], v[fo], v[g]);
                put(bt, EV_NEW_NEW, c, fo, gap_fo_new, v[fo], v[i]);
            }
            if (nl >= 2) {
                size_t ko = ki ? ki - 1 : nl - 1, o = fl + ko, kl = ki + 1 < nl ? ki + 1 : 0, ld = fl + kl;
                put(bt, EV_OLD_NOW, c, o, x[i] + (ki ? 0.0 : L) - len_i - x[o], v[o], v[i]);
                if (nl == 2) put(bt, EV_OLD_NEW, c, o, L - len_of(r, o), v[o], v[o]);
                else put(bt, EV_OLD_NEW, c, o, fwd(p[o], p[ld], L) - len_of(r, ld), v[o], v[ld]);
            } else {
                put(bt, EV_OLD_NOW, c, i, 1.0, 0.0, 0.0), put(bt, EV_OLD_NEW, c, i, 1.0, 0.0, 0.0);
            }
            c++;
        }
        if (!c) continue;
        for (int e = EV_OWN_NEW; e < EV_N; e++) eval(r, bt, e, c);
        for (size_t q = 0; q < c; q++) {
            size_t k = bt->cand[q], i = i0 + k;
            const WfDriverGroup *grp = &sc->groups[f->group_id[i]];
            WfLcCase cs = {own_now[k], bt->a[EV_OWN_NEW][q], bt->a[EV_NEW_NOW][q], bt->a[EV_NEW_NEW][q],
                           bt->a[EV_OLD_NOW][q], bt->a[EV_OLD_NEW][q], bt->has_new[q], bt->has_old[q]};
            double adv = grp->lc->advantage(grp->lc_params, d ? WF_LANE_LEFT : WF_LANE_RIGHT, sc->lane_rule, &cs);
            if (adv > lc->adv_mps2[i]) lc->adv_mps2[i] = adv, lc->dir[i] = (int8_t)(d ? WF_LANE_LEFT : WF_LANE_RIGHT);
        }
    }
}

/* The decisions of the blocks lc->blk[0 .. nblk), shared among the threads of the team that calls it (if any). */
static void decide_all(WfLaneChanges *lc, const Road *r, long step, size_t nblk)
{
    const WfFleet *f = r->f;
    Batch bt;
#pragma omp for schedule(static)
    for (size_t b = 0; b < nblk; b++) {
        size_t i0 = lc->blk[b], l = f->lane[i0], end = r->first[l] + f->lane_n[l];
        decide_block(lc, r, l, i0, end - i0 < WF_BLOCK ? end - i0 : WF_BLOCK, step, &bt);
    }
}

/* One gap per step takes one vehicle: a claim beats another only with a larger advantage (slot order breaks ties). */
static long resolve(WfLaneChanges *lc, const Road *r)
{
    const WfFleet *f = r->f;
    long changes = 0;
    memset(lc->claim, 0, (lc->n + lc->n_lanes) * sizeof *lc->claim);
    for (size_t i = 0; i < lc->n; i++) {
        if (!lc->dir[i]) continue;
        size_t m = (size_t)((long)f->lane[i] + lc->dir[i]), key = r->first[m] + m;
        if (f->lane_n[m]) key += lc->tgt[lc->dir[i] > 0][i];
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

/* Lane m's new order into perm from slot j on (its vehicles that stay, each newcomer right behind the leader it
 * chose; behind the lane's first vehicle is after its last), and the laps each newcomer's position moves by so that
 * positions increase along the lane within one lap. Returns the lane's new count. */
static size_t new_order(WfLaneChanges *lc, const Road *r, size_t m, size_t j)
{
    const WfFleet *f = r->f;
    const double *x = f->x_m, L = r->L;
    size_t nm = f->lane_n[m], fm = r->first[m], start = j;
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

long wf_lanes_change(WfLaneChanges *lc, const WfScenario *sc, WfFleet *f, long step, const WfStateVar *vars,
                     size_t nv, int nthreads, WfLaneCounts *cnt)
{
    if (!lc->active) return 0;
    size_t n = f->n, nlanes = f->n_lanes, rot[WF_MAX_LANES] = {0};
    double L = sc->road.length_m;
    Road r = {sc, f, lc->p_m, L, {0}};
    for (size_t l = 1; l < nlanes; l++) r.first[l] = r.first[l - 1] + f->lane_n[l - 1];
    for (size_t i = 0; i < n; i++) {
        double q = f->x_m[i] - L * (double)wf_lap_index(f->x_m[i] / L);
        lc->p_m[i] = q >= L ? q - L : q < 0.0 ? q + L : q;
    }
    for (size_t l = 0; l < nlanes; l++)
        for (size_t k = 1; k < f->lane_n[l]; k++)
            if (lc->p_m[r.first[l] + k] < lc->p_m[r.first[l] + k - 1]) {
                rot[l] = k;
                break;
            }
    for (size_t l = 0; l < nlanes; l++) {
        if (l > 0) neighbours(lc, &r, rot, l, l - 1, 0);
        if (l + 1 < nlanes) neighbours(lc, &r, rot, l, l + 1, 1);
    }
    /* the decisions, block by block of each lane (blocks of WF_BLOCK slots from each lane's first) */
    size_t nblk = 0;
    for (size_t l = 0; l < nlanes; l++)
        for (size_t k = 0; k < f->lane_n[l]; k += WF_BLOCK) lc->blk[nblk++] = (uint32_t)(r.first[l] + k);
    int nth = wf_lane_threads(n, nthreads);
    if (nth > 1) {
#pragma omp parallel num_threads(nth) default(none) shared(lc, r, step, nblk)
        decide_all(lc, &r, step, nblk);
    } else {
        decide_all(lc, &r, step, nblk);
    }
    long changes = resolve(lc, &r);
    if (!changes) return 0;
    size_t newn[WF_MAX_LANES];
    for (size_t m = 0, j = 0; m < nlanes; m++) j += newn[m] = new_order(lc, &r, m, j);
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
            f->lc_ready_step[j] = step + lc->interval_steps[f->group_id[j]];
            f->lane_changes[j]++;
            cnt->changes++;
            cnt->pair[l - (size_t)(long)d][l]++;
            if (newn[l] < 2) continue;
            f->cut_ins[k ? j - 1 : j + newn[l] - 1]++; /* the vehicle it now leads */
            cnt->cut_ins++;
            cnt->lane_cut_ins[l]++;
        }
    }
    return changes;
}
