/* Lane changes on a multi-lane ring (lanes.h). */
#include "core/lanes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/block.h"
#include "core/par.h"
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
    if (!lc->p_m || !lc->tgt[0] || !lc->tgt[1] || !lc->dir || !lc->adv_mps2 || !lc->claim || !lc->perm ||
        !lc->shift_m || !lc->scratch)
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
    if (!nm) {
        for (size_t k = 0; k < nl; k++) tgt[fl + k] = UINT32_MAX;
        return;
    }
    for (size_t q = 0, j = 0; q < nl; q++) {
        size_t i = fl + (rot[l] + q) % nl;
        while (j < nm && r->p[fm + (rot[m] + j) % nm] < r->p[i]) j++;
        tgt[i] = (uint32_t)((rot[m] + (j == nm ? 0 : j)) % nm);
    }
}

/* The advantage of vehicle i (slot k of lane l, own acceleration own_now) moving in direction d (0 right, 1 left). */
static double advantage(const WfLaneChanges *lc, const Road *r, size_t i, size_t l, size_t k, int d, double own_now)
{
    const WfFleet *f = r->f;
    const WfDriverGroup *grp = &r->sc->groups[f->group_id[i]];
    const double *x = f->x_m, *v = f->v_mps, *p = r->p, L = r->L;
    size_t m = d ? l + 1 : l - 1, nm = f->lane_n[m], nl = f->lane_n[l], fl = r->first[l];
    double len_i = len_of(r, i);
    WfLcCase c = {.own_now = own_now};
    if (!nm) {
        c.own_new = accel_of(r, i, L - len_i, v[i], v[i]); /* alone in the lane: it follows itself a lap ahead */
    } else {
        size_t tg = lc->tgt[d][i], g = r->first[m] + tg, fo = r->first[m] + (tg ? tg - 1 : nm - 1);
        double gap_new = fwd(p[i], p[g], L) - len_of(r, g), gap_fo_new = fwd(p[fo], p[i], L) - len_i;
        if (!(gap_new > 0.0) || !(gap_fo_new > 0.0)) return -INFINITY;
        /* the new follower's gap now, as the kernel takes it: its leader is the next slot, a lap ahead at the wrap */
        double gap_fo_now = x[g] + (tg ? 0.0 : L) - len_of(r, g) - x[fo];
        c.own_new = accel_of(r, i, gap_new, v[i], v[g]);
        c.has_new = 1;
        c.new_now = accel_of(r, fo, gap_fo_now, v[fo], v[g]);
        c.new_new = accel_of(r, fo, gap_fo_new, v[fo], v[i]);
    }
    if (nl >= 2) {
        size_t ko = k ? k - 1 : nl - 1, o = fl + ko, kl = k + 1 < nl ? k + 1 : 0, ld = fl + kl;
        c.has_old = 1;
        c.old_now = accel_of(r, o, x[i] + (k ? 0.0 : L) - len_i - x[o], v[o], v[i]);
        c.old_new = nl == 2 ? accel_of(r, o, L - len_of(r, o), v[o], v[o])
                            : accel_of(r, o, fwd(p[o], p[ld], L) - len_of(r, ld), v[o], v[ld]);
    }
    return grp->lc->advantage(grp->lc_params, d ? WF_LANE_LEFT : WF_LANE_RIGHT, r->sc->lane_rule, &c);
}

/* Vehicle i's choice: the side with the larger positive advantage (the right one at a tie), or none. */
static void decide(WfLaneChanges *lc, const Road *r, size_t i, long step)
{
    const WfFleet *f = r->f;
    const WfDriverGroup *grp = &r->sc->groups[f->group_id[i]];
    lc->dir[i] = 0;
    if (!grp->lc || step < f->lc_ready_step[i]) return;
    size_t l = f->lane[i], fl = r->first[l], nl = f->lane_n[l], k = i - fl, kl = k + 1 < nl ? k + 1 : 0;
    double own_now = accel_of(r, i, f->x_m[fl + kl] + (kl ? 0.0 : r->L) - len_of(r, fl + kl) - f->x_m[i], f->v_mps[i],
                              f->v_mps[fl + kl]);
    double best = 0.0;
    for (int d = 0; d < 2; d++) {
        if ((d == 0 && l == 0) || (d == 1 && l + 1 == f->n_lanes)) continue;
        double a = advantage(lc, r, i, l, k, d, own_now);
        if (a > best) best = a, lc->dir[i] = (int8_t)(d ? WF_LANE_LEFT : WF_LANE_RIGHT);
    }
    lc->adv_mps2[i] = best;
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
    int nth = wf_lane_threads(n, nthreads);
    WF_PAR_FOR(nth > 1, "omp parallel for schedule(static) num_threads(nth) default(none) shared(lc, r, n, step)",
               for (size_t i = 0; i < n; i++) decide(lc, &r, i, step););
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
