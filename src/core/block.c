/* The block kernel (block.h). Every per-vehicle rule exists once, in block form: loops over a block's arrays
 * without control flow where they are hot, so they vectorise. A vehicle's arithmetic does not depend on which
 * pass, block split or thread runs it, so fused and multi-pass steps and any thread count give the same bits. */
#include "core/block.h"

#include <math.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/fleet.h"
#include "wavefuel/rng.h"
#include "core/noise.h"
#include "core/par.h"
#include "core/select.h"
#include "core/simd.h"
#include "util/clock.h"

#define B WF_BLOCK
#define AI static inline __attribute__((always_inline))

void wf_loop_start(WfLoopState *st)
{
    double now = wf_wall_now();
    *st = (WfLoopState){.last_progress = now, .last_ckpt = now};
}

int wf_loop_advance(const WfLoop *lp, WfLoopState *st, long n, WfError *err)
{
    double t0 = lp->wall_s ? wf_wall_now() : 0.0;
    int rc = 0;
    for (long k = 0; k < n && !st->at_end && !st->reason;) {
        long step = *lp->steps_done, done = 1;
        if ((rc = lp->step(lp->ctx, step, n - k, &done, err))) {
            if (rc == WF_LOOP_END) st->at_end = 1, rc = 0;
            break;
        }
        *lp->steps_done = step + done;
        k += done;
        if (lp->stop && *lp->stop) {
            st->reason = *lp->stop == SIGTERM ? "interrupted by SIGTERM" : "interrupted by SIGINT";
            break;
        }
        if (lp->checkpoint_every_s > 0 && lp->checkpoint && wf_wall_now() - st->last_ckpt >= lp->checkpoint_every_s) {
            if ((rc = lp->checkpoint(lp->ctx, err))) break;
            st->last_ckpt = wf_wall_now();
        }
        /* the clock is read when the steps done cross a multiple of 64 */
        if (lp->progress && (step + done - 1) / 64 * 64 >= step && wf_wall_now() - st->last_progress >= 0.2) {
            lp->progress(lp->pctx, (double)(step + done) * lp->dt_s, lp->duration_s, step + done, lp->n_steps);
            st->last_progress = wf_wall_now();
        }
    }
    if (lp->wall_s) *lp->wall_s += wf_wall_now() - t0;
    return rc;
}

int wf_loop_finish(const WfLoop *lp, WfLoopState *st, int rc, WfError *err)
{
    const char *reason = st->reason;
    /* The checkpoint comes before the close, which may change the totals (a corridor closes the trips of the
     * vehicles still on the road, which a resumed run drops). */
    if (!rc && reason && lp->checkpoint) rc = lp->checkpoint(lp->ctx, err);
    WfError e2 = {0};
    int rc2 = lp->close(lp->ctx, rc ? &e2 : err);
    if (!rc && rc2) rc = rc2;
    if (rc) {
        if (lp->end) lp->end(lp->ctx, 0, err->msg, &e2);
        return rc;
    }
    if (lp->end && (rc = lp->end(lp->ctx, reason == NULL, reason ? reason : "", err))) return rc;
    if (reason)
        return wf_err(err, WF_EINTR, "%s at t = %.6g s: partial results written", reason,
                      (double)*lp->steps_done * lp->dt_s);
    return 0;
}

static inline size_t idx_of(const WfLane *ln, size_t i) { return ln->slot ? ln->slot[i] : i; }
static inline size_t sidx_of(const WfLane *ln, size_t i) { return ln->sslot ? ln->sslot[i] : idx_of(ln, i); }

/* A block's values of the step, kept locally by the fused step. */
typedef struct Blk {
    double a[B], th[B], fr[B], gap[B], vl[B], ll[B]; /* ll[k]: the length of vehicle k + 1 (the leader's) */
    uint8_t fl[B];
} Blk;

/* What the engine adds to a model's acceleration: noise, the group's limits, optionally the class's feasible
 * a_max, and the cap (speed limits: never past the limit within the step, nor into a lower limit ahead too fast). */
AI void post_rule(const WfScenario *sc, const WfDriverGroup *grp, size_t cnt, const double *restrict v,
                  const double *restrict th, const double *restrict z, const double *restrict cap,
                  const uint16_t *restrict cls, double *restrict a)
{
    double amax = grp->accel_max_mps2, dmax = grp->decel_max_mps2, noise = grp->noise_mps2;
    if (noise > 0.0) {
#pragma omp simd
        for (size_t j = 0; j < cnt; j++) a[j] += noise * z[j];
    }
#pragma omp simd
    for (size_t j = 0; j < cnt; j++) {
        double ai = a[j] > amax ? amax : a[j];
        a[j] = ai < -dmax ? -dmax : ai;
    }
    if (grp->clip_feasible) {
        for (size_t j = 0; j < cnt; j++) {
            const WfVehicleClass *vc = &sc->classes[cls[j]].vc;
            double am = vc->model->a_max(vc->params, v[j], th[j]);
            a[j] = a[j] > am ? am : a[j];
        }
    }
    if (cap) {
#pragma omp simd
        for (size_t j = 0; j < cnt; j++) {
            double floor_a = cap[j] > -dmax ? cap[j] : -dmax;
            a[j] = a[j] > cap[j] ? floor_a : a[j];
        }
    }
}

/* The group's safety filter, the last rule: a' = a > bound ? max(bound, -decel_max) : a, on the step's inputs (gap,
 * own and leader speed). Returns the vehicles whose acceleration it lowered (an integer sum: vectorises without
 * reassociating anything written out). */
AI size_t safety_rule(const WfDriverGroup *grp, double dt, size_t cnt, const double *gap, const double *v,
                      const double *vl, double *restrict a)
{
    double lim[B], dmax = grp->decel_max_mps2;
    size_t hits = 0;
    grp->safety->bound(grp->safety_params, dt, cnt, gap, v, vl, lim);
#pragma omp simd reduction(+ : hits)
    for (size_t j = 0; j < cnt; j++) {
        double floor_a = lim[j] > -dmax ? lim[j] : -dmax;
        double ai = a[j] > lim[j] ? floor_a : a[j];
        hits += (size_t)(ai < a[j]);
        a[j] = ai;
    }
    return hits;
}

/* The parameters of the vehicle in slot i of group g (its zone's copy in buf when the group is zoned). */
static inline const void *params_of(const WfLane *ln, size_t g, size_t i, double x, double *buf)
{
    const void *p = ln->params[g] + idx_of(ln, i) * ln->pstride[g];
    return ln->zoned[g] ? ln->ops->params_at(ln->ctx, g, p, x, buf) : p;
}

/* Accelerations of the cnt vehicles of group g in a block (slots lo + k[j], or lo + j when k is NULL) from their
 * gathered inputs: the model's block kernel when the parameters are one shared block or consecutive, else accel()
 * per vehicle; then the post-rule and the group's safety filter (counted into co when co is not NULL). */
AI void accel_group(const WfLane *ln, size_t g, size_t lo, const uint32_t *k, size_t cnt, const double *x,
                    const double *gap, const double *v, const double *vl, const double *th, const double *z,
                    const double *cap, const uint16_t *cls, double *a, WfChunkOut *co)
{
    const WfDriverGroup *grp = &ln->sc->groups[g];
    const WfCfModel *m = grp->model;
    size_t psz = ln->pstride[g], ssz = ln->sstride[g];
    size_t i0 = lo + (k ? k[0] : 0), i1 = lo + (k ? k[cnt - 1] : cnt - 1), s0 = idx_of(ln, i0);
    if (m->accel_block && !m->state_size && !ln->zoned[g] && (!psz || idx_of(ln, i1) - s0 == cnt - 1)) {
        m->accel_block(ln->params[g] + s0 * psz, psz, cnt, gap, v, vl, a);
    } else {
        double buf[WF_MAX_MODEL_PARAMS];
        for (size_t j = 0; j < cnt; j++) {
            size_t i = lo + (k ? k[j] : j);
            const void *st = m->state_size ? ln->state[g] + sidx_of(ln, i) * ssz : NULL;
            a[j] = m->accel(params_of(ln, g, i, x[i - lo], buf), st, gap[j], v[j], vl[j]);
        }
    }
    post_rule(ln->sc, grp, cnt, v, th, z, cap, cls, a);
    if (grp->safety) {
        size_t hits = safety_rule(grp, ln->sc->dt_s, cnt, gap, v, vl, a);
        if (co) co->safety_hits[g] += hits, co->safety_steps[g] += cnt;
    }
}

/* Class c's fuel rates and flags of n points: on a flat road (th NULL) through its model's flat form when it has
 * one, else with the grades th (a flat road's: zeros). */
AI void energy_eval(const WfScenario *sc, size_t c, size_t n, const double *v, const double *a, const double *th,
                    const double *zeros, double *fr, uint8_t *fl)
{
    const WfVehicleClass *vc = &sc->classes[c].vc;
    if (!th && vc->model->eval_flat) vc->model->eval_flat(vc->params, n, v, a, fr, fl);
    else vc->model->eval(vc->params, n, v, a, th ? th : zeros, 0, fr, fl);
}

/* th: the grades, or NULL on a flat road (zeros: n zeros for the models without a flat form). */
AI void energy_block(const WfLane *ln, size_t lo, size_t n, const double *v, const double *a, const double *th,
                    const double *zeros, double *fr, uint8_t *fl)
{
    const WfScenario *sc = ln->sc;
    const uint16_t *cid = ln->class_id + lo;
    if (sc->n_classes == 1) {
        energy_eval(sc, 0, n, v, a, th, zeros, fr, fl);
        return;
    }
    double gv[B], ga[B], gt[B], gf[B];
    uint8_t gfl[B];
    uint32_t idx[B];
    for (size_t b0 = 0; b0 < n; b0 += B) {
        size_t m = n - b0 < B ? n - b0 : B, count[WF_MAX_CLASSES] = {0}, major = 0;
        /* class by class, a vector compare and sum: a histogram (count[cid[k]]++) chains each increment through
         * memory, some 5 cycles a vehicle (perf: 7 % of a corridor's step) */
        for (size_t c = 0; c < sc->n_classes; c++) {
            const uint16_t c16 = (uint16_t)c, *cb = cid + b0;
            uint32_t s = 0;
#pragma omp simd reduction(+ : s)
            for (size_t k = 0; k < m; k++) s += cb[k] == c16;
            count[c] = s;
        }
        for (size_t c = 1; c < sc->n_classes; c++) major = count[c] > count[major] ? c : major;
        /* The block's largest class over the whole block, in place, then each other class gathered and written
         * over its vehicles: the fewest gathers. A vehicle's fuel rate does not depend on the others evaluated with
         * it (an energy model's eval is element-wise), so the bits are those of evaluating each class alone. */
        energy_eval(sc, major, m, v + b0, a + b0, th ? th + b0 : NULL, zeros, fr + b0, fl + b0);
        for (size_t c = 0; c < sc->n_classes; c++) {
            if (c == major || !count[c]) continue;
            size_t cnt = wf_select_eq16(cid + b0, m, (uint16_t)c, (uint32_t)b0, idx);
            for (size_t j = 0; j < cnt; j++) gv[j] = v[idx[j]], ga[j] = a[idx[j]];
            for (size_t j = 0; th && j < cnt; j++) gt[j] = th[idx[j]];
            energy_eval(sc, c, cnt, gv, ga, th ? gt : NULL, zeros, gf, gfl);
            for (size_t j = 0; j < cnt; j++) fr[idx[j]] = gf[j], fl[idx[j]] = gfl[j];
        }
    }
}

void wf_lane_energy(const WfLane *ln, size_t lo, size_t n, const double *v, const double *a, const double *th,
                    double *fr, uint8_t *fl)
{
    energy_block(ln, lo, n, v, a, th, NULL, fr, fl);
}

/* Whether group g's accelerations can be computed over a whole block in place, its vehicles and the others alike
 * (the others' then overwritten): its model's block kernel on one shared parameter set, element-wise, with no
 * memory, zones or safety counts that would see the others. */
static inline int whole_block(const WfLane *ln, size_t g)
{
    const WfDriverGroup *grp = &ln->sc->groups[g];
    const WfCfModel *m = grp->model;
    return m->accel_block && !m->state_size && !ln->zoned[g] && !ln->pstride[g] && !grp->safety;
}

/* Accelerations of a block, group by group; co: see accel_group. The block's largest group over the whole block in
 * place when it can be (whole_block), each other group gathered, computed and scattered over its vehicles: with a
 * few automated vehicles among humans, the humans are not copied. Each vehicle's acceleration is computed from its
 * own inputs alone, so the bits are those of every group gathered. */
AI void accel_block(const WfLane *ln, size_t lo, size_t m, const double *x, const double *v, const double *z,
                    const double *cap, Blk *b, WfChunkOut *co)
{
    const WfScenario *sc = ln->sc;
    const uint16_t *cid = ln->class_id + lo, *gid = ln->group_id + lo;
    if (sc->n_groups == 1) {
        accel_group(ln, 0, lo, NULL, m, x, b->gap, v, b->vl, b->th, z, cap, cid, b->a, co);
        return;
    }
    size_t count[WF_MAX_GROUPS], major = 0;
    for (size_t g = 0; g < sc->n_groups; g++) {
        const uint16_t g16 = (uint16_t)g;
        uint32_t c = 0;
#pragma omp simd reduction(+ : c)
        for (size_t k = 0; k < m; k++) c += gid[k] == g16;
        count[g] = c;
        major = count[g] > count[major] ? g : major;
    }
    int in_place = whole_block(ln, major);
    if (in_place) accel_group(ln, major, lo, NULL, m, x, b->gap, v, b->vl, b->th, z, cap, cid, b->a, co);
    double gg[B], gv[B], gl[B], gt[B], gz[B], gc[B], ga[B];
    uint16_t gcl[B];
    uint32_t idx[B];
    for (size_t g = 0; g < sc->n_groups; g++) {
        if (!count[g] || (in_place && g == major)) continue;
        size_t cnt = wf_select_eq16(gid, m, (uint16_t)g, 0, idx);
        for (size_t j = 0; j < cnt; j++) {
            size_t k = idx[j];
            gg[j] = b->gap[k], gv[j] = v[k], gl[j] = b->vl[k], gt[j] = b->th[k], gcl[j] = cid[k];
            gz[j] = ln->noisy ? z[k] : 0.0;
            gc[j] = cap ? cap[k] : 0.0;
        }
        accel_group(ln, g, lo, idx, cnt, x, gg, gv, gl, gt, gz, cap ? gc : NULL, gcl, ga, co);
        for (size_t j = 0; j < cnt; j++) b->a[idx[j]] = ga[j];
    }
}

/* The acceleration noise of slots [lo, lo + m) at a step: slot i's draw is deviate i mod B of the counter-based
 * stream keyed (seed, block i / B, step) (wf_rng_normal_block), whatever thread runs it and wherever the range
 * begins: a vehicle keeps its slot, so its draws depend only on the state. */
static void lane_noise(uint64_t seed, size_t lo, size_t m, long step, double *z)
{
    size_t off = lo % B;
    if (!off) {
        wf_rng_normal_block(seed, WF_RNG_NOISE_BLOCK, lo / B, (uint64_t)step, m, z);
        return;
    }
    double all[B];
    wf_rng_normal_block(seed, WF_RNG_NOISE_BLOCK, lo / B, (uint64_t)step, off + m, all);
    memcpy(z, all + off, m * sizeof *z);
}

/* The noise of the rings sg[0 .. ns) of a gang block, ring after ring: ring r's is lane_noise's of its slots 0 ..
 * n - 1 alone (its block 0, its seed and step), drawn for all at once. */
static void seg_noise(const WfSeg *sg, size_t ns, double *z)
{
    uint64_t seed[B], step[B];
    size_t n[B];
    for (size_t r = 0; r < ns; r++) seed[r] = sg[r].seed, step[r] = (uint64_t)sg[r].step, n[r] = sg[r].n;
    wf_rng_normal_rings(ns, seed, WF_RNG_NOISE_BLOCK, 0, step, n, z);
}

/* ll[k] = the length of vehicle k + 1's class, k < pairs: a select per class over the block (exact), which
 * vectorises where a lookup by 16-bit class number cannot (gcc 12 emits no gather: 4 instructions a vehicle). */
AI void leader_lengths(const WfLane *ln, const uint16_t *restrict cid, size_t pairs, double *restrict ll)
{
    const double *len = ln->class_length_m;
    size_t nc = ln->sc->n_classes;
    double l0 = len[0], l1 = nc > 1 ? len[1] : l0;
    for (size_t k = 0; k < pairs; k++) ll[k] = cid[k + 1] == 1 ? l1 : l0;
    for (size_t c = 2; c < nc; c++) {
        double lc = len[c];
        uint16_t c16 = (uint16_t)c;
        for (size_t k = 0; k < pairs; k++) ll[k] = cid[k + 1] == c16 ? lc : ll[k];
    }
}

/* Inputs at the step's start, accelerations and (WF_PASS_ENERGY) fuel rates of the block in slots [lo, lo + m);
 * its last vehicle's leader is ld; co: where a counting pass counts the safety filters' interventions, or NULL. */
AI void inputs_block(const WfLane *ln, size_t lo, size_t m, const WfLead *ld, long step, int pass,
                     WfStatsBlock *rec, Blk *b, WfChunkOut *co, const WfSeg *sg, size_t ns)
{
    const WfScenario *sc = ln->sc;
    const double *x = ln->x_m + lo, *v = ln->v_mps + lo;
    const uint16_t *cid = ln->class_id + lo;
    double z[B], cap[B];
    if (ln->noisy && !sg) lane_noise(sc->seed, ln->key0 + lo, m, step, z);
    /* rings side by side (wf_lane_gang_block): each ring's draws are those of its block 0 at its step */
    if (ln->noisy && sg) seg_noise(sg, ns, z + (sg[0].lo - lo));
    size_t pairs = m ? m - 1 : 0;
    leader_lengths(ln, cid, pairs, b->ll);
    for (size_t k = 0; k + 1 < m; k++) {
        b->gap[k] = x[k + 1] - b->ll[k] - x[k];
        b->vl[k] = v[k + 1];
    }
    /* Side by side, the last vehicle of each ring but the block's last follows its ring's first one lap ahead
     * (front_lead's expression), and is not its neighbour's follower: a leader length of -inf leaves that pair out
     * of the block's overlap count (stats_after; wf_lane_gang_block checks each ring's own edge). */
    for (size_t r = 0; r + 1 < ns; r++) {
        size_t k = sg[r].lo + sg[r].n - 1 - lo, f = sg[r].lo - lo;
        double rear = (x[f] + sg[r].period_m) - ln->class_length_m[cid[f]];
        b->gap[k] = rear - x[k];
        b->vl[k] = v[f];
        b->ll[k] = -INFINITY;
    }
    if (ld->free_gap_m > 0.0) {
        b->gap[m - 1] = ld->free_gap_m;
        b->vl[m - 1] = v[m - 1];
    } else {
        b->gap[m - 1] = ld->rear_m - x[m - 1];
        b->vl[m - 1] = ld->v_mps;
    }
    if (ln->ops->grade)
        ln->ops->grade(ln->ctx, ln->grade_seg + lo, m, x, b->th);
    else
        memset(b->th, 0, m * sizeof *b->th);
    int capped = ln->ops->cap && ln->ops->cap(ln->ctx, lo, m, x, v, cap);
    accel_block(ln, lo, m, x, v, z, capped ? cap : NULL, b, co);
    if (pass & WF_PASS_ENERGY) {
        /* a flat road's b->th are the zeros of the models without a flat form */
        energy_block(ln, lo, m, v, b->a, ln->ops->grade ? b->th : NULL, b->th, b->fr, b->fl);
        if (rec) wf_stats_block(m, v, b->gap, b->fr, cid, sc->n_classes, sc, rec);
    }
}

/* The speed and acceleration moments of one gate over a block (one loop: v and a loaded once for the four). */
AI void accum_moments(const WfAccum *ac, size_t lo, size_t m, const double *restrict v, const double *restrict a)
{
    if (!ac || !ac->sum_v) return;
    double *restrict s1 = ac->sum_v + lo, *restrict s2 = ac->sum_v2 + lo;
    double *restrict a1 = ac->sum_a + lo, *restrict a2 = ac->sum_a2 + lo;
#pragma omp simd
    for (size_t k = 0; k < m; k++) {
        s1[k] += v[k];
        s2[k] += v[k] * v[k];
        a1[k] += a[k];
        a2[k] += a[k] * a[k];
    }
}

/* Adds expr (a value of vehicle k) to array f of gate g1 and, when g2 is not NULL, of gate g2 (the statistics
 * window) over the caller's block (slots lo + k, k < m), computing it once for both: each array gets the value it
 * would get alone. */
#define GATES_ADD(g1, g2, T, f, expr)                                                                               \
    do {                                                                                                            \
        T *p1_ = (g1)->f ? (g1)->f + lo : NULL, *p2_ = (g2) && (g2)->f ? (g2)->f + lo : NULL;                        \
        if (p1_ && p2_) {                                                                                           \
            T *restrict q1_ = p1_, *restrict q2_ = p2_;                                                             \
            _Pragma("omp simd") for (size_t k = 0; k < m; k++) {                                                    \
                T u_ = (expr);                                                                                      \
                q1_[k] += u_;                                                                                       \
                q2_[k] += u_;                                                                                       \
            }                                                                                                       \
        } else if (p1_ || p2_) {                                                                                    \
            T *restrict q_ = p1_ ? p1_ : p2_;                                                                       \
            _Pragma("omp simd") for (size_t k = 0; k < m; k++) q_[k] += (expr);                                     \
        }                                                                                                           \
    } while (0)

/* Left-point accumulation over a block into gate g1 and, when g2 is not NULL, gate g2; onset: 1 where hard braking
 * begins. */
AI void accum_before(const WfAccum *g1, const WfAccum *g2, const WfScenario *sc, size_t lo, size_t m,
                     const double *restrict v, const double *restrict a, const double *restrict fr,
                     const uint8_t *restrict fl, const uint8_t *restrict onset, int with_fuel)
{
    double dt = sc->dt_s, v_stop = sc->v_stop_mps;
    if (with_fuel) GATES_ADD(g1, g2, double, fuel_g, fr[k] * dt);
    GATES_ADD(g1, g2, double, stopped_s, v[k] < v_stop ? dt : 0.0);
    accum_moments(g1, lo, m, v, a);
    accum_moments(g2, lo, m, v, a);
    GATES_ADD(g1, g2, uint32_t, stopped_steps, (uint32_t)(v[k] < v_stop));
    GATES_ADD(g1, g2, uint32_t, infeasible, (uint32_t)(fl[k] == WF_INFEASIBLE_ACCEL));
    GATES_ADD(g1, g2, uint32_t, hard_brakes, (uint32_t)onset[k]);
    GATES_ADD(g1, g2, uint32_t, steps, 1u);
}

/* Whether p[k] and q[k] are finite for every k < m: x - x is +0 for a finite x and NaN otherwise, so the sum of
 * them all is +0 or NaN in whatever order the vector lanes add it (the integer-flag form of this test cost 3
 * instructions a vehicle). */
AI int finite_all(size_t m, const double *restrict p, const double *restrict q)
{
    double s = 0.0;
#pragma omp simd reduction(+ : s)
    for (size_t k = 0; k < m; k++) s += (p[k] - p[k]) + (q[k] - q[k]);
    return s == 0.0;
}

/* Statistics of the step from its start (accumulators, onset of hard braking, faults). */
AI int stats_before(WfLane *ln, size_t lo, size_t m, const double *restrict v, const double *restrict a,
                    const double *restrict fr, const uint8_t *restrict fl, int in_window, int with_fuel)
{
    uint8_t *restrict mode = ln->mode + lo, onset[B];
    double hard = -ln->sc->hard_brake_mps2;
    /* the onsets of hard braking (braking harder than hard_brake_mps2 now, not at the step before) and the new
     * braking bits, in one loop of bytes */
    for (size_t k = 0; k < m; k++) {
        uint8_t md = mode[k], br = (uint8_t)(a[k] < hard);
        onset[k] = (uint8_t)(br & !(md & WF_MODE_BRAKING));
        mode[k] = (uint8_t)((md & ~WF_MODE_BRAKING) | br * WF_MODE_BRAKING);
    }
    accum_before(&ln->always, in_window ? &ln->window : NULL, ln->sc, lo, m, v, a, fr, fl, onset, with_fuel);
    if (finite_all(m, a, fr)) return 0;
    /* Rare: mark the vehicles (the step then ends in a numerical-fault error naming the first). */
    for (size_t k = 0; k < m; k++)
        if (!isfinite(a[k]) || !isfinite(fr[k])) mode[k] |= WF_MODE_FAULT;
    return WF_STEP_FAULT;
}

AI void accum_after(const WfAccum *g1, const WfAccum *g2, size_t lo, size_t m, const double *restrict x,
                    const double *restrict xo, const uint8_t *restrict stop)
{
    GATES_ADD(g1, g2, uint32_t, stops, stop[k]);
    GATES_ADD(g1, g2, double, dist_m, x[k] - xo[k]);
}

/* Statistics of the new state: stops (hysteresis between v_stop and v_go), distances from xo, overlaps inside the
 * block (its last vehicle's is checked once every block has moved) and non-finite states. lead_len[k]: the length of
 * vehicle k + 1, as the step's inputs took it (NULL: looked up). */
AI int stats_after(WfLane *ln, size_t lo, size_t m, const double *restrict xo, const double *lead_len, int in_window)
{
    const WfScenario *sc = ln->sc;
    const double *restrict x = ln->x_m + lo, *restrict v = ln->v_mps + lo;
    const uint16_t *cid = ln->class_id + lo;
    uint8_t *restrict mode = ln->mode + lo;
    uint8_t stop[B];
    double v_stop = sc->v_stop_mps, v_go = sc->v_go_mps, ll[B];
    /* The hysteresis in bytes (the moving bit is bit 0), one vectorised loop: a moving vehicle stops below v_stop, a
     * stopped one moves again above v_go. */
    _Static_assert(WF_MODE_MOVING == 1, "the stop hysteresis below takes the moving bit as bit 0");
    for (size_t k = 0; k < m; k++) {
        uint8_t sl = (uint8_t)(v[k] < v_stop), fa = (uint8_t)(v[k] > v_go);
        uint8_t md = mode[k], moving = md & 1u, st = moving & sl, go = (uint8_t)(moving ^ 1u) & fa;
        stop[k] = st;
        mode[k] = (uint8_t)((md & ~1u) | (moving ^ st) | go);
    }
    accum_after(&ln->always, in_window ? &ln->window : NULL, lo, m, x, xo, stop);
    if (!lead_len) {
        leader_lengths(ln, cid, m ? m - 1 : 0, ll);
        lead_len = ll;
    }
    /* a count of overlaps in doubles (0 and 1 added in any order give the same exact sum), and finite_all's test of
     * the new positions and speeds in the same loop (x loaded once) */
    double over = 0.0, nonfinite = 0.0;
    size_t pairs = m ? m - 1 : 0;
#pragma omp simd reduction(+ : over, nonfinite)
    for (size_t k = 0; k < pairs; k++) {
        over += x[k + 1] - lead_len[k] - x[k] < 0.0 ? 1.0 : 0.0;
        nonfinite += (x[k] - x[k]) + (v[k] - v[k]);
    }
    if (m) nonfinite += (x[m - 1] - x[m - 1]) + (v[m - 1] - v[m - 1]);
    return (over > 0.0 ? WF_STEP_OVERLAP : 0) | (nonfinite == 0.0 ? 0 : WF_STEP_FAULT);
}

void wf_lane_controllers(WfLane *ln, size_t lo, size_t n, const double *v)
{
    const WfScenario *sc = ln->sc;
    for (size_t k = 0; k < n; k++) {
        size_t i = lo + k, g = ln->group_id[i];
        const WfCfModel *cm = sc->groups[g].model;
        if (!cm->state_size || !cm->update_state) continue;
        double buf[WF_MAX_MODEL_PARAMS];
        cm->update_state(params_of(ln, g, i, ln->x_m[i], buf), ln->state[g] + sidx_of(ln, i) * ln->sstride[g],
                         ln->out.gap_m[i], v[k], ln->out.v_lead_mps[i], sc->dt_s);
    }
}

/* Controller memory (with the step's inputs), statistics, integration of the block. */
AI int advance_block(WfLane *ln, size_t lo, size_t m, const double *a, const double *gap, const double *vl,
                     const double *fr, const uint8_t *fl, const double *lead_len, int in_window)
{
    const WfScenario *sc = ln->sc;
    double *x = ln->x_m + lo, *v = ln->v_mps + lo, xo[B];
    if (ln->stateful) {
        for (size_t k = 0; k < m; k++) {
            size_t i = lo + k, g = ln->group_id[i];
            const WfCfModel *cm = sc->groups[g].model;
            if (!cm->state_size || !cm->update_state) continue;
            double buf[WF_MAX_MODEL_PARAMS];
            cm->update_state(params_of(ln, g, i, x[k], buf), ln->state[g] + sidx_of(ln, i) * ln->sstride[g], gap[k],
                             v[k], vl[k], sc->dt_s);
        }
    }
    int flags = stats_before(ln, lo, m, v, a, fr, fl, in_window, 1);
    memcpy(xo, x, m * sizeof *x);
    if (ln->x_old_m) memcpy(ln->x_old_m + lo, x, m * sizeof *x);
    ln->ig->step(m, sc->dt_s, x, v, a);
    return flags | stats_after(ln, lo, m, xo, lead_len, in_window);
}

/* A fused pass without its energy evaluation when nothing would read the fuel rates: no record, no export, no
 * accumulator of fuel or of infeasible requests (every step's gate, or the statistics window's while it is open):
 * a ring outside its statistics window between records (an RL environment's whole run). The fault test then sees
 * zero fuel rates: a fuel model's non-finite value can end a run only where the run keeps it. */
AI int energy_pass(const WfLane *ln, int pass, int in_window, const WfStatsBlock *rec, Blk *b, size_t m)
{
    if ((pass & WF_PASS_FUSED) != WF_PASS_FUSED || rec || ln->out.fuel_rate_gps || ln->out.flag ||
        ln->always.fuel_g || ln->always.infeasible || (in_window && (ln->window.fuel_g || ln->window.infeasible)))
        return pass;
    memset(b->fr, 0, m * sizeof *b->fr);
    memset(b->fl, 0, m * sizeof *b->fl);
    return pass & ~WF_PASS_ENERGY;
}

/* One block of a pass: slots [lo, lo + m), its last vehicle's leader ld, rec its record's partial sums or NULL, co
 * the chunk's safety counts (NULL: not a counting pass). */
WF_SIMD_CLONES
static int run_block(WfLane *ln, size_t lo, size_t m, const WfLead *ld, long step, int pass, int in_window,
                     WfStatsBlock *rec, WfChunkOut *co)
{
    Blk b;
    if (!(pass & WF_PASS_ACCEL))
        return advance_block(ln, lo, m, ln->out.a_mps2 + lo, ln->out.gap_m + lo, ln->out.v_lead_mps + lo, ln->out.fuel_rate_gps + lo,
                             ln->out.flag + lo, NULL, in_window);
    pass = energy_pass(ln, pass, in_window, rec, &b, m);
    inputs_block(ln, lo, m, ld, step, pass, rec, &b, co, NULL, 0);
    if (ln->out.a_mps2) memcpy(ln->out.a_mps2 + lo, b.a, m * sizeof *b.a);
    if (ln->out.gap_m) memcpy(ln->out.gap_m + lo, b.gap, m * sizeof *b.gap);
    if (ln->out.v_lead_mps) memcpy(ln->out.v_lead_mps + lo, b.vl, m * sizeof *b.vl);
    if (ln->out.theta_rad) memcpy(ln->out.theta_rad + lo, b.th, m * sizeof *b.th);
    if ((pass & WF_PASS_ENERGY) && ln->out.fuel_rate_gps) memcpy(ln->out.fuel_rate_gps + lo, b.fr, m * sizeof *b.fr);
    if ((pass & WF_PASS_ENERGY) && ln->out.flag) memcpy(ln->out.flag + lo, b.fl, m * sizeof *b.fl);
    if (!(pass & WF_PASS_ADVANCE)) return 0;
    if (ln->out.v_mps) memcpy(ln->out.v_mps + lo, ln->v_mps + lo, m * sizeof *ln->v_mps);
    return advance_block(ln, lo, m, b.a, b.gap, b.vl, b.fr, b.fl, b.ll, in_window);
}

void wf_lane_stats_before(WfLane *ln, size_t lo, size_t n, int in_window)
{
    for (size_t b0 = 0; b0 < n; b0 += B) {
        size_t i = lo + b0, m = n - b0 < B ? n - b0 : B;
        stats_before(ln, i, m, ln->v_mps + i, ln->out.a_mps2 + i, ln->out.fuel_rate_gps + i, ln->out.flag + i, in_window, 0);
    }
}

void wf_lane_stats_after(WfLane *ln, size_t lo, size_t n, int in_window)
{
    for (size_t b0 = 0; b0 < n; b0 += B) {
        size_t i = lo + b0, m = n - b0 < B ? n - b0 : B;
        stats_after(ln, i, m, ln->x_old_m + i, NULL, in_window);
    }
}


size_t wf_lane_blocks(size_t first, size_t n) { return n ? (n + first % B + B - 1) / B : 0; }

size_t wf_lane_block_at(const WfLane *ln, size_t first, size_t n, size_t j, size_t *lo)
{
    size_t off = first % B, s = j ? j * B - off : 0, e = (j + 1) * B - off;
    if (e > n) e = n;
    *lo = (first + s) % ln->cap;
    return e - s;
}

/* The leader of the range's front vehicle: the back one (saved at x0, v0) one period ahead, or the open front. */
static WfLead front_lead(const WfLane *ln, size_t first, double x0, double v0, const WfLead *front)
{
    if (!(ln->period_m > 0.0)) return *front;
    return (WfLead){(x0 + ln->period_m) - ln->class_length_m[ln->class_id[first]], v0, 0.0};
}

/* Overlap of the vehicle in slot i with the one in slot l (both moved); shift: l's position offset (a period). */
static int edge_overlap(const WfLane *ln, size_t i, size_t l, double shift)
{
    double xl = ln->x_m[l] + shift;
    return xl - ln->class_length_m[ln->class_id[l]] - ln->x_m[i] < 0.0 ? WF_STEP_OVERLAP : 0;
}

int wf_lane_tile(WfLane *ln, size_t first, size_t n, size_t b0, size_t b1, long step0, int k, const WfLead *lead,
                 double *tx, double *tv, int pass, int in_window, WfStatsBlock *const *recs, WfChunkOut *co)
{
    int fl = 0;
    size_t lo0, last = 0;
    wf_lane_block_at(ln, first, n, b0, &lo0);
    for (int s = 0; s < k; s++) {
        if (tx) tx[s] = ln->x_m[lo0], tv[s] = ln->v_mps[lo0];
        size_t prev_last = 0;
        for (size_t b = b0; b < b1; b++) {
            size_t lo, m = wf_lane_block_at(ln, first, n, b, &lo), nx = (lo + m) % ln->cap;
            WfLead ld = b + 1 == b1 ? lead[s]
                                    : (WfLead){ln->x_m[nx] - ln->class_length_m[ln->class_id[nx]], ln->v_mps[nx], 0.0};
            fl |= run_block(ln, lo, m, &ld, step0 + s, pass, in_window, recs && recs[s] ? recs[s] + b : NULL, co);
            if ((pass & WF_PASS_ADVANCE) && ln->ops->moved) ln->ops->moved(ln->ctx, lo, m, step0 + s);
            /* The previous block's edge, while both blocks are in cache. */
            if ((pass & WF_PASS_ADVANCE) && b > b0) fl |= edge_overlap(ln, prev_last, lo, 0.0);
            prev_last = last = lo + m - 1;
        }
        /* The front edge against the leader at the next step's start (it is a vehicle when k > 1). */
        if ((pass & WF_PASS_ADVANCE) && s + 1 < k && lead[s + 1].rear_m - ln->x_m[last] < 0.0) fl |= WF_STEP_OVERLAP;
    }
    return fl;
}

/* Blocks [b0, b1) of one chunk for one step; (xs, vs): the chunk's last leader, saved before any update; co: see
 * run_block. */
static int run_chunk(WfLane *ln, size_t first, size_t n, size_t b0, size_t b1, size_t nb, double xs, double vs,
                     const WfLead *front, long step, int pass, int in_window, WfStatsBlock *rec, WfChunkOut *co)
{
    size_t lo, m = wf_lane_block_at(ln, first, n, b1 - 1, &lo), nx = (lo + m) % ln->cap;
    WfLead ld = b1 == nb ? front_lead(ln, first, xs, vs, front)
                         : (WfLead){xs - ln->class_length_m[ln->class_id[nx]], vs, 0.0};
    return wf_lane_tile(ln, first, n, b0, b1, step, 1, &ld, NULL, NULL, pass, in_window, &rec, co);
}

/* Rings side by side: the inputs with each ring's own noise and leaders, the fused advance of the whole block. */
WF_SIMD_CLONES
static int gang_block(WfLane *ln, const WfSeg *sg, size_t ns, int in_window, WfChunkOut *co)
{
    Blk b;
    const WfSeg *l = &sg[ns - 1];
    size_t lo = sg[0].lo, m = l->lo + l->n - lo;
    WfLead ld = {(ln->x_m[l->lo] + l->period_m) - ln->class_length_m[ln->class_id[l->lo]], ln->v_mps[l->lo], 0.0};
    int pass = energy_pass(ln, WF_PASS_FUSED | WF_PASS_COUNT, in_window, NULL, &b, m);
    inputs_block(ln, lo, m, &ld, 0, pass, NULL, &b, co, sg, ns);
    return advance_block(ln, lo, m, b.a, b.gap, b.vl, b.fr, b.fl, b.ll, in_window);
}

int wf_lane_gang_block(WfLane *ln, const WfSeg *sg, size_t ns, int in_window, WfChunkOut *co, int *edge)
{
    int fl = gang_block(ln, sg, ns, in_window, co);
    for (size_t r = 0; r < ns; r++)
        edge[r] = sg[r].n > 1 ? edge_overlap(ln, sg[r].lo + sg[r].n - 1, sg[r].lo, sg[r].period_m) : 0;
    return fl;
}

int wf_lane_chunk_edge(const WfLane *ln, size_t first, size_t n, size_t b1, size_t nb)
{
    size_t lo, m = wf_lane_block_at(ln, first, n, b1 - 1, &lo), last = lo + m - 1;
    if (b1 < nb) return edge_overlap(ln, last, (last + 1) % ln->cap, 0.0);
    return ln->period_m > 0.0 && n > 1 ? edge_overlap(ln, last, first, ln->period_m) : 0;
}

void wf_lane_safety_init(WfLane *ln)
{
    ln->safe = 0;
    for (size_t g = 0; g < ln->sc->n_groups; g++) ln->safe |= ln->sc->groups[g].safety != NULL;
    memset(&ln->safety, 0, sizeof ln->safety);
}

void wf_lane_safety_summary(const WfLane *ln, WfSummary *s)
{
    for (size_t g = 0; g < WF_MAX_GROUPS; g++) {
        s->grp[g].safety_steps = (int64_t)ln->safety.steps[g];
        s->grp[g].safety_interventions = (int64_t)ln->safety.hits[g];
    }
    wf_summary_safety_totals(s);
}

void wf_lane_safety_add(WfLane *ln, const WfChunkOut *cf, int nth)
{
    for (int t = 0; t < nth; t++)
        for (size_t g = 0; g < ln->sc->n_groups; g++) {
            ln->safety.steps[g] += cf[t].safety_steps[g];
            ln->safety.hits[g] += cf[t].safety_hits[g];
        }
}

/* Where chunk t of nt of blocks [bb0, bb1) begins (t = nt: bb1): an even split, or the lane's cuts when the team is
 * the one they were made for. */
static size_t chunk_begin(const WfLane *ln, size_t bb0, size_t bb1, int t, int nt)
{
    size_t span = bb1 - bb0;
    if (!ln->cuts || nt != ln->nthreads || ln->cuts->at[nt] != 1.0) return bb0 + span * (size_t)t / (size_t)nt;
    size_t b = bb0 + (size_t)((double)span * ln->cuts->at[t] + 0.5);
    return b < bb1 ? b : bb1;
}

/* The first vehicle of each of the nt chunks of blocks [bb0, bb1), at the step's start, into bound_x/bound_v. */
static void chunk_firsts(WfLane *ln, size_t first, size_t n, size_t bb0, size_t bb1, int nt)
{
    for (int t = 0; t < nt; t++) {
        size_t b0 = chunk_begin(ln, bb0, bb1, t, nt), b1 = chunk_begin(ln, bb0, bb1, t + 1, nt), lo = 0;
        if (b1 > b0) wf_lane_block_at(ln, first, n, b0, &lo);
        ln->bound_x[t] = ln->x_m[lo], ln->bound_v[t] = ln->v_mps[lo];
    }
}

/* After a fused step on the lane's nthreads, with each chunk's blocks and wall time: every WF_CUT_STEPS such steps
 * the cuts move halfway towards those that would have given the chunks equal wall times at their measured blocks
 * per second. Summing over many steps keeps a step whose thread was descheduled from moving them, and keeps them
 * from swinging a block back and forth between cores every step (a block moved loses its cache). */
static void chunk_rebalance(WfLane *ln, const WfChunkOut *cf, int nt)
{
    WfCuts *c = ln->cuts;
    for (int t = 0; t < nt; t++) c->busy_s[t] += cf[t].busy_s, c->blocks[t] += (double)cf[t].blocks;
    if (++c->steps < WF_CUT_STEPS) return;
    double sum = 0.0;
    int ok = 1;
    for (int t = 0; t < nt; t++) {
        ok &= c->blocks[t] > 0.0 && c->busy_s[t] > 0.0;
        sum += ok ? c->blocks[t] / c->busy_s[t] : 0.0;
    }
    if (c->at[nt] != 1.0 || !ok) /* first cuts, cuts made for another team, or a chunk without blocks: even */
        for (int t = 0; t <= nt; t++) c->at[t] = (double)t / nt;
    double at = 0.0;
    for (int t = 0; ok && t + 1 < nt; t++) {
        at += c->blocks[t] / c->busy_s[t] / sum;
        c->at[t + 1] += 0.5 * (at - c->at[t + 1]);
    }
    for (int t = 0; t < nt; t++) c->busy_s[t] = c->blocks[t] = 0.0;
    c->steps = 0;
}

/* Positions and speeds are updated in place. Race-free and order-free because every vehicle reads only its
 * leader's values from the step's start: within a chunk, vehicle i's leader i + 1 is updated after i; the leader
 * of a chunk's last vehicle is the next chunk's first (or the periodic back vehicle), saved before any update. A
 * part's last leader (block bb1 % nb's first vehicle) is not stepped here: the caller keeps it as it is at the
 * step's start, and checks the part's front edge once it has moved. */
int wf_lane_step_part(WfLane *ln, size_t first, size_t n, size_t bb0, size_t bb1, const WfLead *front, long step,
                      int pass, int in_window, WfStatsBlock *rec)
{
    ln->after_done = 0;
    if (!n) return 0;
    size_t nb = wf_lane_blocks(first, n), lo_f;
    int part = bb0 > 0 || bb1 < nb;
    int nth = wf_lane_threads(n, ln->nthreads);
    if ((size_t)nth > bb1 - bb0) nth = (int)(bb1 - bb0);
    int adv = (pass & WF_PASS_ADVANCE) != 0, count = (pass & WF_PASS_COUNT) && ln->safe, flags = 0;
    WfChunkOut *cf = ln->chunks;
    double *bx = ln->bound_x, *bv = ln->bound_v;
    int after = adv && ln->after_wanted && ln->ops->after_step;
    /* fused steps time their chunks for the cuts; other passes cost differently along the road and only use them */
    int balance = ln->cuts && (pass & WF_PASS_FUSED) == WF_PASS_FUSED;
    wf_lane_block_at(ln, first, n, bb1 % nb, &lo_f); /* the front chunk's leader (the ring's back vehicle when whole) */
    for (int t = 0; t < nth; t++) {
        cf[t].flags = 0, cf[t].edge = 0;
        if (count) memset(cf[t].safety_steps, 0, sizeof cf[t].safety_steps), memset(cf[t].safety_hits, 0, sizeof cf[t].safety_hits);
    }
    if (nth <= 1) {
        /* Small roads: no OpenMP region at all (even a one-thread region costs runtime calls every step). */
        flags = run_chunk(ln, first, n, bb0, bb1, nb, ln->x_m[lo_f], ln->v_mps[lo_f], front, step, pass, in_window,
                          rec, count ? cf : NULL);
        if (count) wf_lane_safety_add(ln, cf, 1);
        return adv && !part ? flags | wf_lane_chunk_edge(ln, first, n, nb, nb) : adv ? flags : 0;
    }
    double xf = ln->x_m[lo_f], vf = ln->v_mps[lo_f];
    int team = 0; /* the team that ran */
    /* Each chunk's first vehicle at the step's start, read before the team starts, so that the team needs no barrier
     * for it (a smaller team than asked, nested or limited, reads its own after one). */
    chunk_firsts(ln, first, n, bb0, bb1, nth);
#pragma omp parallel num_threads(nth) default(none) shared(ln, first, n, nb, bb0, bb1, part, bx, bv, xf, vf, front, step, pass, in_window, rec, adv, cf, count, after, nth, balance, team)
    {
        /* The team may be smaller than asked (nested inside a sweep worker, or a thread limit): chunk by the team
         * actually running. */
#ifdef _OPENMP
        int t = omp_get_thread_num(), nt = omp_get_num_threads();
#else
        int t = 0, nt = 1;
#endif
        size_t b0 = chunk_begin(ln, bb0, bb1, t, nt), b1 = chunk_begin(ln, bb0, bb1, t + 1, nt);
        if (nt != nth) {
#pragma omp single
            chunk_firsts(ln, first, n, bb0, bb1, nt);
        }
        /* Leader of this chunk's last vehicle: the next chunk's first, saved (the front chunk's: the part's leader,
         * saved before the team started). */
        double xs = t + 1 < nt ? bx[t + 1] : xf, vs = t + 1 < nt ? bv[t + 1] : vf;
        double t0 = balance ? wf_wall_now() : 0.0;
        int fl = b1 > b0 ? run_chunk(ln, first, n, b0, b1, nb, xs, vs, front, step, pass, in_window, rec,
                                     count ? &cf[t] : NULL) : 0;
        cf[t].flags = fl, cf[t].edge = 0, cf[t].busy_s = balance ? wf_wall_now() - t0 : 0.0;
        cf[t].blocks = b1 - b0;
        if (t == 0) team = nt;
#pragma omp barrier
        if (adv && b1 > b0 && !(part && b1 == bb1)) cf[t].edge = wf_lane_chunk_edge(ln, first, n, b1, nb);
        if (after) {
            /* The boundary's work unless the step must be repaired first: every thread finds the same answer from
             * every chunk's flags and front edge, so no second barrier is needed (edges are checked here again,
             * reading positions nobody writes any more). */
            int any = 0;
            for (int u = 0; u < nt; u++) {
                size_t e = chunk_begin(ln, bb0, bb1, u + 1, nt);
                any |= cf[u].flags;
                if (e > chunk_begin(ln, bb0, bb1, u, nt) && !(part && e == bb1))
                    any |= wf_lane_chunk_edge(ln, first, n, e, nb);
            }
            if (!any) ln->ops->after_step(ln->ctx, t, nt);
        }
    }
    for (int t = 0; t < nth; t++) flags |= cf[t].flags | cf[t].edge;
    if (balance && team == ln->nthreads) chunk_rebalance(ln, cf, team);
    ln->after_done = after && !flags;
    if (count) wf_lane_safety_add(ln, cf, nth);
    return adv ? flags : 0;
}

int wf_lane_step(WfLane *ln, size_t first, size_t n, const WfLead *front, long step, int pass, int in_window,
                 WfStatsBlock *rec)
{
    return wf_lane_step_part(ln, first, n, 0, n ? wf_lane_blocks(first, n) : 0, front, step, pass, in_window, rec);
}
