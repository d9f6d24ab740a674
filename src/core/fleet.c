/* Fleet construction: placement of classes and driver groups around the ring, per-vehicle parameter draws
 * (counter-based, so independent of threads), and the initial state (heterogeneous equilibrium or rest). */
#include "wavefuel/fleet.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/equilibrium.h"
#include "wavefuel/rng.h"
#include "core/block.h"
#include "util/mem.h"

void wf_fleet_destroy(WfFleet **pf)
{
    if (!pf || !*pf) return;
    WfFleet *f = *pf;
    WF_FREE(f->x_m, f->v_mps, f->a_mps2, f->gap_m, f->v_lead_mps, f->theta_rad, f->fuel_rate_gps, f->flag, f->grade_seg,
            f->class_id, f->group_id, f->slot, f->x_start_m, f->fuel_g, f->stopped_steps, f->sum_v, f->sum_v2, f->sum_a,
            f->sum_a2, f->stops, f->hard_brakes, f->infeasible_steps, f->mode, f->lane, f->id, f->pos, f->lc_ready_step,
            f->lane_changes, f->cut_ins, f->lap_m);
    for (size_t g = 0; g < WF_MAX_GROUPS; g++) WF_FREE(f->group_params[g], f->group_state[g]);
    free(f);
    *pf = NULL;
}

/* The partner of slot i in the Fisher-Yates shuffle: a counter-based draw in [0, i]. */
static size_t shuffle_partner(uint64_t seed, uint32_t stream, size_t i)
{
    double u[2];
    wf_rng_uniform2(seed, stream, i, 0, u);
    size_t j = (size_t)(u[0] * (double)(i + 1));
    return j > i ? i : j;
}

/* Category of each vehicle from counts. Interleaved: vehicle i goes to the category furthest behind its
 * proportional share (i+1) count_c / n, which spreads every category evenly. Random: that sequence shuffled
 * (Fisher-Yates) with counter-based draws. Explicit: from the index lists. */
static void place(size_t n, size_t m, const long *count, long *const *indices, WfPlacement how, uint64_t seed,
                  uint32_t stream, uint16_t *cat)
{
    if (how == WF_PLACE_EXPLICIT) {
        for (size_t c = 0; c < m; c++)
            for (long k = 0; k < count[c]; k++) cat[indices[c][k]] = (uint16_t)c;
        return;
    }
    long assigned[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES] = {0};
    for (size_t i = 0; i < n; i++) {
        size_t best = m;
        double best_deficit = -INFINITY;
        for (size_t c = 0; c < m; c++) {
            if (assigned[c] >= count[c]) continue;
            double deficit = (double)(i + 1) * (double)count[c] / (double)n - (double)assigned[c];
            if (deficit > best_deficit) best_deficit = deficit, best = c;
        }
        cat[i] = (uint16_t)best;
        assigned[best]++;
    }
    if (how != WF_PLACE_RANDOM || n < 2) return;
    /* The swaps in order, each partner drawn AHEAD swaps early and its slot prefetched: at 10^7 vehicles the
     * partners' cache misses were nearly all of this function's time (14 % of a one-step run). */
    enum { AHEAD = 32 };
    size_t partner[AHEAD];
    for (size_t k = 0; k < AHEAD && k < n - 1; k++) {
        partner[k] = shuffle_partner(seed, stream, n - 1 - k);
        __builtin_prefetch(&cat[partner[k]], 1);
    }
    for (size_t k = 0; k < n - 1; k++) {
        size_t i = n - 1 - k, j = partner[k % AHEAD];
        if (k + AHEAD < n - 1) {
            size_t *next = &partner[k % AHEAD];
            *next = shuffle_partner(seed, stream, i - AHEAD);
            __builtin_prefetch(&cat[*next], 1);
        }
        uint16_t t = cat[i];
        cat[i] = cat[j];
        cat[j] = t;
    }
}

#define UNPLACED UINT16_MAX

/* place() over the vehicles still UNPLACED in cat (in ring order), for `m` categories numbered from `first`
 * upwards in the result. With every vehicle unplaced this is place() itself, so scenarios without per-group
 * placement or classes keep their layout. `scratch` holds n slots (vehicle list) and n categories. */
static void place_rest(size_t n, size_t m, const long *count, WfPlacement how, uint64_t seed, uint32_t stream,
                       const uint16_t *id_of, uint16_t *cat, uint32_t *free_list, uint16_t *sub)
{
    size_t nf = 0;
    for (size_t i = 0; i < n; i++)
        if (cat[i] == UNPLACED) free_list[nf++] = (uint32_t)i;
    place(nf, m, count, NULL, how, seed, stream, sub);
    for (size_t k = 0; k < nf; k++) cat[free_list[k]] = id_of[sub[k]];
}

/* Driver groups with their own placement, in list order, each among the vehicles no earlier one claimed:
 * explicit takes its indices; interleaved takes k vehicles evenly spaced in ring order among the m free ones,
 * the j-th at free position floor(j m / k) (one group alone: vehicle floor(j n / k)); random takes k of them
 * uniformly by seed (partial Fisher-Yates, counter-based draws keyed by the group). */
static void place_own_groups(const WfScenario *sc, size_t n, uint16_t *gid, uint32_t *free_list)
{
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfDriverGroup *grp = &sc->groups[g];
        if (grp->placement < 0) continue;
        if (grp->placement == WF_PLACE_EXPLICIT) {
            for (size_t k = 0; k < grp->n_indices; k++) gid[grp->indices[k]] = (uint16_t)g;
            continue;
        }
        size_t m = 0, k = (size_t)grp->count;
        for (size_t i = 0; i < n; i++)
            if (gid[i] == UNPLACED) free_list[m++] = (uint32_t)i;
        if (grp->placement == WF_PLACE_INTERLEAVED) {
            for (size_t j = 0; j < k; j++) gid[free_list[j * m / k]] = (uint16_t)g;
            continue;
        }
        for (size_t j = 0; j < k; j++) {
            double u[2];
            wf_rng_uniform2(sc->seed, WF_RNG_PLACEMENT + 0x200 + (uint32_t)g, j, 0, u);
            size_t r = j + (size_t)(u[0] * (double)(m - j));
            if (r >= m) r = m - 1;
            uint32_t t = free_list[j];
            free_list[j] = free_list[r];
            free_list[r] = t;
            gid[free_list[j]] = (uint16_t)g;
        }
    }
}

/* Groups first (their own placements, then the rest by fleet.placement), then classes: vehicles of groups that
 * name a class get it, and the classes' remaining counts are placed by fleet.placement over the others. */
static int place_all(const WfScenario *sc, WfFleet *f, WfError *err)
{
    size_t n = f->n;
    long counts[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    long *idx[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    uint16_t id_of[WF_MAX_GROUPS > WF_MAX_CLASSES ? WF_MAX_GROUPS : WF_MAX_CLASSES];
    if (sc->placement == WF_PLACE_EXPLICIT) {
        /* The loader rejects per-group placement and classes here: every vehicle is listed. */
        for (size_t c = 0; c < sc->n_classes; c++) counts[c] = sc->classes[c].count, idx[c] = sc->classes[c].indices;
        place(n, sc->n_classes, counts, idx, sc->placement, sc->seed, WF_RNG_PLACEMENT, f->class_id);
        for (size_t g = 0; g < sc->n_groups; g++) counts[g] = sc->groups[g].count, idx[g] = sc->groups[g].indices;
        place(n, sc->n_groups, counts, idx, sc->placement, sc->seed, WF_RNG_PLACEMENT + 0x100, f->group_id);
        return 0;
    }
    uint32_t *free_list = malloc((n + 1) * sizeof *free_list);
    uint16_t *sub = malloc((n + 1) * sizeof *sub);
    if (!free_list || !sub) {
        free(free_list);
        free(sub);
        return wf_err(err, WF_ESYS, "out of memory for %zu vehicles", n);
    }
    for (size_t i = 0; i < n; i++) f->group_id[i] = UNPLACED, f->class_id[i] = UNPLACED;
    place_own_groups(sc, n, f->group_id, free_list);
    size_t m = 0;
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].placement < 0) counts[m] = sc->groups[g].count, id_of[m++] = (uint16_t)g;
    place_rest(n, m, counts, sc->placement, sc->seed, WF_RNG_PLACEMENT + 0x100, id_of, f->group_id, free_list, sub);

    for (size_t c = 0; c < sc->n_classes; c++) counts[c] = sc->classes[c].count, id_of[c] = (uint16_t)c;
    for (size_t i = 0; i < n; i++) {
        int c = sc->groups[f->group_id[i]].class_index;
        if (c >= 0) f->class_id[i] = (uint16_t)c, counts[c]--; /* the loader checked counts[c] stays >= 0 */
    }
    place_rest(n, sc->n_classes, counts, sc->placement, sc->seed, WF_RNG_PLACEMENT, id_of, f->class_id, free_list,
               sub);
    free(free_list);
    free(sub);
    return 0;
}

/* The build's errors, in one place: a process of a split ring formats the one its processes agreed on. */
static int err_draws(const WfScenario *sc, const WfDriverGroup *g, size_t vehicle, WfError *err)
{
    return wf_err(err, WF_EINPUT,
                  "%s: driver group '%s': 1000 draws of the heterogeneous parameters for vehicle %zu were all out of "
                  "range or rejected by the model: reduce heterogeneity.spread",
                  sc->path, g->name, vehicle);
}

static int err_overlap(const WfScenario *sc, size_t vehicle, double gap_m, WfError *err)
{
    return wf_err(err, WF_EINPUT,
                  "%s: the initial perturbation or jitter makes vehicle %zu overlap its leader (gap %.6g m)", sc->path,
                  vehicle, gap_m);
}

/* One vehicle's parameters: base values times (1 + spread * z), z a standard normal truncated to |z| <= 2 or
 * a uniform on [-1, 1]; values outside the spec's range or rejected by check() are redrawn (deterministic:
 * attempt number is part of the counter). */
static int draw_params(const WfScenario *sc, const WfDriverGroup *g, size_t vehicle, double *out, WfError *err)
{
    const WfCfModel *m = g->model;
    int any = 0;
    for (size_t k = 0; k < m->n_spec; k++) any |= g->spread[k] > 0.0;
    memcpy(out, g->params, m->param_size);
    if (!any) return 0;
    for (uint64_t attempt = 0; attempt < 1000; attempt++) {
        int ok = 1;
        memcpy(out, g->params, m->param_size);
        for (size_t k = 0; k < m->n_spec && ok; k++) {
            if (g->spread[k] <= 0.0) continue;
            double r[2], z;
            if (g->dist == WF_HET_NORMAL) {
                wf_rng_normal2(sc->seed, WF_RNG_HETERO, vehicle, attempt * 64 + k, r);
                z = r[0];
                if (fabs(z) > 2.0) {
                    ok = 0;
                    break;
                }
            } else {
                wf_rng_uniform2(sc->seed, WF_RNG_HETERO, vehicle, attempt * 64 + k, r);
                z = 2.0 * r[0] - 1.0;
            }
            double *p = wf_param_ptr(out, &m->spec[k]);
            *p *= 1.0 + g->spread[k] * z;
            if (!(*p >= m->spec[k].min && *p <= m->spec[k].max)) ok = 0;
        }
        if (ok && m->check && m->check(out, NULL) != 0) ok = 0;
        if (ok) return 0;
    }
    return err_draws(sc, g, vehicle, err);
}

int wf_fleet_draw_params(const WfScenario *sc, size_t group, uint64_t vehicle, double *out, WfError *err)
{
    return draw_params(sc, &sc->groups[group], (size_t)vehicle, out, err);
}

#define ALLOC(ptr, count)                                                                                   \
    do {                                                                                                    \
        if (!((ptr) = calloc((count) ? (count) : 1, sizeof *(ptr))))                                        \
            return wf_err(err, WF_ESYS, "out of memory for %zu vehicles", f->n);                            \
    } while (0)

/* The per-vehicle arrays. The step's values are fleet-wide only when a step may run as two passes. */
static int fleet_alloc(const WfScenario *sc, WfFleet *f, WfError *err)
{
    size_t n = f->n;
    f->n_lanes = sc->n_lanes > 1 ? (size_t)sc->n_lanes : 1;
    f->lane_n[0] = n;
    for (size_t l = 0; f->n_lanes > 1 && l < f->n_lanes; l++) f->lane_n[l] = (size_t)sc->lane_counts[l];
    if (f->n_lanes > 1) {
        ALLOC(f->lane, n); ALLOC(f->id, n); ALLOC(f->pos, n); ALLOC(f->lc_ready_step, n); ALLOC(f->lane_changes, n);
        ALLOC(f->cut_ins, n); ALLOC(f->lap_m, n);
        for (size_t l = 0, i = 0; l < f->n_lanes; l++)
            for (size_t k = 0; k < f->lane_n[l]; k++, i++) f->lane[i] = (uint8_t)l;
        for (size_t i = 0; i < n; i++) f->id[i] = f->pos[i] = (uint32_t)i;
    }
    f->multipass = sc->adaptive || sc->trajectories || !sc->fused_step;
    ALLOC(f->x_m, n); ALLOC(f->v_mps, n);
    if (f->multipass) {
        ALLOC(f->a_mps2, n); ALLOC(f->gap_m, n); ALLOC(f->v_lead_mps, n); ALLOC(f->theta_rad, n);
        ALLOC(f->fuel_rate_gps, n); ALLOC(f->flag, n);
    }
    if (sc->road.n_grade) ALLOC(f->grade_seg, n);
    ALLOC(f->class_id, n); ALLOC(f->group_id, n);
    int per_vehicle = 0; /* some group keeps per-vehicle parameters or state: vehicles need their slot */
    for (size_t g = 0; g < sc->n_groups; g++) {
        per_vehicle |= sc->groups[g].model->state_size > 0;
        for (size_t k = 0; k < sc->groups[g].model->n_spec; k++) per_vehicle |= sc->groups[g].spread[k] > 0.0;
    }
    if (per_vehicle) ALLOC(f->slot, n);
    ALLOC(f->x_start_m, n); ALLOC(f->fuel_g, n); ALLOC(f->stopped_steps, n); ALLOC(f->sum_v, n); ALLOC(f->sum_v2, n);
    ALLOC(f->sum_a, n); ALLOC(f->sum_a2, n); ALLOC(f->stops, n); ALLOC(f->hard_brakes, n);
    ALLOC(f->infeasible_steps, n); ALLOC(f->mode, n);
    return 0;
}

/* ------------------------------------------------------------------ the vehicles one process builds */

/* All of them, or this process's share of a ring split across processes (wavefuel/partition.h): the vehicles it
 * steps, [lo, hi), and those whose parameters it reads, [hi, reach) (the equilibrium's blocks that start in the
 * share, a window's halo) and [0, wrap) (the last process's halo). Every process places every vehicle's class and
 * group, as one process does; the other per-vehicle arrays are written only where it builds (pages never written
 * take no memory). The sums along the whole ring run in ring order across the processes, so every value is one
 * process's, bit for bit. */
typedef struct Share {
    const WfPartition *part; /* NULL: one process */
    size_t lo, hi, reach, wrap;
} Share;

static int share_holds(const Share *sh, size_t i) { return (i >= sh->lo && i < sh->reach) || i < sh->wrap; }

/* A build error of a split ring: every process takes the one of the lowest vehicle (the one a single process meets
 * first) and formats the same message. */
typedef struct Fault {
    uint64_t vehicle;
    int64_t  kind, group;
    double   gap_m;
} Fault;
enum { FAULT_NONE, FAULT_NOMEM, FAULT_DRAWS, FAULT_OVERLAP };

/* rc: this process's (mine says what failed); the agreed one on every process. Collective when split. */
static int share_agree(const Share *sh, const WfScenario *sc, int rc, Fault mine, WfError *err)
{
    if (!sh->part) return rc;
    const WfPartition *p = sh->part;
    if (!rc) mine.kind = FAULT_NONE;
    Fault *all = malloc((size_t)p->size * sizeof *all), *first = NULL;
    if (!all) return wf_err(err, WF_ESYS, "out of memory");
    int arc = p->allgather(p->ctx, &mine, all, sizeof mine, err);
    for (int r = 0; !arc && r < p->size; r++)
        if (all[r].kind != FAULT_NONE && (!first || all[r].vehicle < first->vehicle)) first = &all[r];
    Fault f = first ? *first : (Fault){0};
    free(all);
    if (arc || !first) return arc;
    if (f.kind == FAULT_DRAWS) return err_draws(sc, &sc->groups[f.group], (size_t)f.vehicle, err);
    if (f.kind == FAULT_OVERLAP) return err_overlap(sc, (size_t)f.vehicle, f.gap_m, err);
    return wf_err(err, WF_ESYS, "out of memory for %zu vehicles", (size_t)sc->n_vehicles);
}

/* A sum along the ring: fn(arg, buf) over each process's share in turn, in ring order (wavefuel/partition.h: chain);
 * with `all`, every process then holds the whole ring's result. One process: fn alone. */
static int share_chain(const Share *sh, void *buf, size_t bytes, void (*fn)(void *, void *), void *arg, int all,
                       WfError *err)
{
    if (!sh->part) {
        fn(arg, buf);
        return 0;
    }
    const WfPartition *p = sh->part;
    int rc = p->chain(p->ctx, buf, bytes, fn, arg, err);
    if (rc || !all) return rc;
    size_t *off = malloc(((size_t)p->size + 1) * sizeof *off);
    if (!off) return wf_err(err, WF_ESYS, "out of memory");
    rc = wf_partition_from(p, buf, 0, 0, bytes, -1, off, err); /* rank 0's result onto every rank */
    free(off);
    return rc;
}

/* Each group's parameter blocks (one copy with stride 0 without heterogeneity: every member has the group's
 * parameters) and controller memory, the members' slots and the parameters drawn for the vehicles built here
 * (*bad: the vehicle whose draws failed). */
static int fleet_groups(const WfScenario *sc, WfFleet *f, const Share *sh, size_t *bad, WfError *err)
{
    for (size_t c = 0; c < sc->n_classes; c++) f->class_length_m[c] = sc->classes[c].length_m;
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfCfModel *m = sc->groups[g].model;
        int het = 0;
        for (size_t k = 0; k < m->n_spec; k++) het |= sc->groups[g].spread[k] > 0.0;
        f->group_param_stride[g] = het ? m->param_size : 0;
        f->group_params[g] = calloc(het ? (size_t)sc->groups[g].count + 1 : 1, m->param_size);
        f->group_state[g] = m->state_size ? calloc((size_t)sc->groups[g].count + 1, m->state_size) : NULL;
        if (!f->group_params[g] || (m->state_size && !f->group_state[g]))
            return wf_err(err, WF_ESYS, "out of memory for %zu vehicles", f->n);
        if (!het) memcpy(f->group_params[g], sc->groups[g].params, m->param_size);
    }
    for (size_t i = 0; i < f->n; i++) {
        size_t c = f->class_id[i], g = f->group_id[i];
        f->class_n[c]++;
        size_t slot = f->group_n[g]++;
        if (!share_holds(sh, i)) continue;
        if (f->slot) f->slot[i] = (uint32_t)slot;
        if (!f->group_param_stride[g]) continue;
        int rc = draw_params(sc, &sc->groups[g], i, (double *)(f->group_params[g] + slot * f->group_param_stride[g]),
                             err);
        if (rc) return *bad = i, rc;
    }
    return 0;
}

/* Bumper-to-bumper gap of vehicle i to its leader (vehicle 0 one lap ahead for the last). */
static double ring_gap(const WfFleet *f, double L, size_t i)
{
    size_t lead = i + 1 < f->n ? i + 1 : 0;
    double xl = f->x_m[lead] + (lead == 0 ? L : 0.0);
    return xl - wf_fleet_length(f, lead) - f->x_m[i];
}

/* The running sums of the build along the ring (share_chain), over a share's vehicles. */
typedef struct RingSums {
    const WfScenario *sc;
    WfFleet          *f;
    const Share      *sh;
    const double     *gap;
} RingSums;

/* buf: the vehicles' lengths and their standstill gaps. */
static void sum_standstill(void *arg, void *buf)
{
    const RingSums *c = arg;
    double *t = buf, jam_i = 0.0;
    const void *prev = NULL;
    for (size_t i = c->sh->lo; i < c->sh->hi; i++) {
        t[0] += wf_fleet_length(c->f, i);
        /* Vehicles sharing a parameter block share their standstill gap: solve once per block. */
        const void *p = wf_fleet_params(c->f, c->sc, i);
        if (p != prev)
            jam_i = wf_equilibrium_gap(c->sc->groups[c->f->group_id[i]].model, p, 0.0, c->sc->road.length_m), prev = p;
        t[1] += jam_i;
    }
}

/* buf: the gaps and lengths. */
static void sum_used(void *arg, void *buf)
{
    const RingSums *c = arg;
    double *t = buf;
    for (size_t i = c->sh->lo; i < c->sh->hi; i++) t[0] += c->gap[i] + wf_fleet_length(c->f, i);
}

/* buf: the position of the share's first vehicle; afterwards, of the next share's first, which is also written
 * (the leader of the share's last vehicle). x_0 = length_0 so vehicle 0's rear bumper sits at 0;
 * x_{i+1} = x_i + gap_i + length_{i+1}. */
static void sum_positions(void *arg, void *buf)
{
    const RingSums *c = arg;
    WfFleet *f = c->f;
    size_t lo = c->sh->lo, hi = c->sh->hi;
    double *t = buf;
    f->x_m[lo] = t[0];
    for (size_t i = lo; i + 1 < hi; i++) f->x_m[i + 1] = f->x_m[i] + c->gap[i] + wf_fleet_length(f, i + 1);
    if (hi < f->n) t[0] = f->x_m[hi] = f->x_m[hi - 1] + c->gap[hi - 1] + wf_fleet_length(f, hi);
}

/* Initial gaps of the share (equilibrium, or equal at rest) into gap, and the initial speed; fails when the
 * vehicles do not fit at their standstill gaps. */
static int initial_gaps(const WfScenario *sc, WfFleet *f, const Share *sh, double *gap, double *v0, WfError *err)
{
    size_t n = f->n;
    double L = sc->road.length_m, fit[2] = {0.0, 0.0}, used = 0.0;
    RingSums c = {sc, f, sh, gap};
    int rc = share_chain(sh, fit, sizeof fit, sum_standstill, &c, 1, err);
    if (rc) return rc;
    double total_len = fit[0], jam = fit[1];
    if (total_len + jam > L)
        return wf_err(err, WF_EINPUT,
                      "%s: %zu vehicles need %.6g m at their standstill gaps (lengths %.6g m + gaps %.6g m) but the "
                      "ring is %.6g m long",
                      sc->path, n, total_len + jam, total_len, jam, L);
    *v0 = 0.0;
    if (sc->init_state != WF_INIT_EQUILIBRIUM) {
        for (size_t i = sh->lo; i < sh->hi; i++) gap[i] = (L - total_len) / (double)n;
        return 0;
    }
    double v_hi = isfinite(sc->road.speed_limit_mps) ? sc->road.speed_limit_mps : 100.0;
    if (!sh->part) {
        *v0 = wf_equilibrium_ring(sc, f, v_hi, gap);
        if (isnan(*v0)) return wf_err(err, WF_ESYS, "out of memory");
    } else {
        *v0 = wf_equilibrium_ring_part(sc, f, v_hi, sh->part, sh->lo, sh->hi, gap, err);
        if (isnan(*v0)) return WF_ESYS;
        wf_equilibrium_ring_gaps(sc, f, *v0, sh->lo, sh->hi, gap);
    }
    if ((rc = share_chain(sh, &used, sizeof used, sum_used, &c, 1, err))) return rc;
    /* Spare length (speed limit reached, or bisection residue) is shared equally. */
    for (size_t i = sh->lo; i < sh->hi; i++) gap[i] += (L - used) / (double)n;
    return 0;
}

/* Positions and speeds from the gaps, jitter and perturbation; modes and controller memory. f: the fleet, or one
 * lane of it, whose first vehicle is vehicle `first` of the fleet (jitter draws and the perturbation name vehicles
 * of the fleet). A share also places its last vehicle's leader. */
static int initial_state(const WfScenario *sc, WfFleet *f, const Share *sh, size_t first, const double *gap,
                         double v0, WfError *err)
{
    size_t n = f->n, lo = sh->lo, hi = sh->hi, lead = hi < n ? hi : 0;
    double L = sc->road.length_m, x0 = wf_fleet_length(f, 0);
    RingSums c = {sc, f, sh, gap};
    int rc = share_chain(sh, &x0, sizeof x0, sum_positions, &c, 0, err);
    if (rc) return rc;
    /* the share's vehicles, and (a share of a split ring) its last one's leader: the next share's first, placed by
     * the chain, or the ring's first */
    size_t outside = lead < lo || lead >= hi;
    if (outside && lead == 0) f->x_m[0] = wf_fleet_length(f, 0);
    long pv = sc->perturb_vehicle >= (long)first && sc->perturb_vehicle < (long)(first + n)
                  ? sc->perturb_vehicle - (long)first : -1;
    for (size_t k = lo; k < hi + outside; k++) {
        size_t i = k < hi ? k : lead;
        f->v_mps[i] = v0;
        if (sc->jitter_m > 0) {
            double u[2];
            wf_rng_uniform2(sc->seed, WF_RNG_JITTER, first + i, 0, u);
            f->x_m[i] += sc->jitter_m * (2.0 * u[0] - 1.0);
        }
        if ((long)i == pv) f->x_m[i] += sc->perturb_dx_m, f->v_mps[i] += sc->perturb_dv_mps;
    }
    if (pv >= 0 && v0 + sc->perturb_dv_mps < 0.0)
        return wf_err(err, WF_EINPUT, "%s: initial.perturbation.dv_mps makes vehicle %ld's speed negative (%.6g m/s)",
                      sc->path, sc->perturb_vehicle, v0 + sc->perturb_dv_mps);
    Fault bad = {.kind = FAULT_OVERLAP};
    for (size_t i = lo; !rc && i < hi; i++)
        if (!(ring_gap(f, L, i) >= 0.0)) bad.vehicle = first + i, bad.gap_m = ring_gap(f, L, i), rc = WF_EINPUT;
    if (rc && !sh->part) return err_overlap(sc, (size_t)bad.vehicle, bad.gap_m, err);
    if ((rc = share_agree(sh, sc, rc, bad, err))) return rc;
    for (size_t i = lo; i < hi; i++) {
        f->mode[i] = f->v_mps[i] > sc->v_go_mps ? WF_MODE_MOVING : 0;
        size_t g = f->group_id[i], lead_i = i + 1 < n ? i + 1 : 0;
        const WfCfModel *m = sc->groups[g].model;
        if (m->state_size && m->init_state)
            m->init_state(wf_fleet_params(f, sc, i), f->group_state[g] + wf_fleet_slot(f, i) * m->state_size,
                          ring_gap(f, L, i), f->v_mps[i], f->v_mps[lead_i]);
    }
    return 0;
}

int wf_fleet_create_part(const WfScenario *sc, const WfPartition *part, WfFleet **out, WfError *err)
{
    *out = NULL;
    WfFleet *f = calloc(1, sizeof *f);
    if (!f) return wf_err(err, WF_ESYS, "out of memory");
    size_t n = f->n = (size_t)sc->n_vehicles;
    f->n_groups = sc->n_groups;
    f->n_classes = sc->n_classes;
    Share sh = {part, 0, n, n, 0};
    if (part) {
        size_t b0, b1;
        wf_partition_blocks(wf_lane_blocks(0, n), part->size, part->rank, &b0, &b1);
        sh.lo = b0 * WF_BLOCK, sh.hi = b1 * WF_BLOCK < n ? b1 * WF_BLOCK : n;
        sh.reach = sh.hi + WF_EQ_BLOCK < n ? sh.hi + WF_EQ_BLOCK : n;
        sh.wrap = sh.hi == n ? WF_BLOCK : 0; /* the last share's halo: the ring's first vehicles */
    }
    f->share_lo = sh.lo, f->share_hi = sh.hi;
    double v0 = 0.0, *gap = NULL;
    size_t bad = 0;
    int rc = fleet_alloc(sc, f, err);
    if (!rc) rc = place_all(sc, f, err);
    /* The gaps: the fleet's array when it has one, else scratch until the first step. */
    if (!rc && !(gap = f->gap_m ? f->gap_m : malloc(f->n * sizeof *gap)))
        rc = wf_err(err, WF_ESYS, "out of memory for %zu vehicles", f->n);
    if (!rc) rc = fleet_groups(sc, f, &sh, &bad, err);
    rc = share_agree(&sh, sc, rc,
                     (Fault){bad, rc == WF_EINPUT ? FAULT_DRAWS : FAULT_NOMEM, f->group_id ? f->group_id[bad] : 0, 0.0},
                     err);
    /* Each lane starts as a single-lane ring of its vehicles would. */
    for (size_t l = 0, first = 0; !rc && l < f->n_lanes; first += f->lane_n[l++]) {
        WfFleet lf = *f;
        lf.n = f->lane_n[l];
        lf.x_m += first, lf.v_mps += first, lf.class_id += first, lf.group_id += first, lf.mode += first;
        if (f->slot) lf.slot += first;
        if (!lf.n) continue;
        Share lsh = part ? sh : (Share){NULL, 0, lf.n, lf.n, 0};
        rc = initial_gaps(sc, &lf, &lsh, gap + first, &v0, err);
        if (!rc) rc = initial_state(sc, &lf, &lsh, first, gap + first, v0, err);
        if (!l) f->v_init_mps = v0;
    }
    if (gap != f->gap_m) free(gap);
    if (rc) {
        wf_fleet_destroy(&f);
        return rc;
    }
    *out = f;
    return 0;
}

int wf_fleet_create(const WfScenario *sc, WfFleet **out, WfError *err)
{
    return wf_fleet_create_part(sc, NULL, out, err);
}

const void *wf_fleet_params_of(const WfFleet *f, const WfScenario *sc, size_t i, double *buf, WfError *err)
{
    size_t g = f->group_id[i];
    if (!f->group_param_stride[g] || (i >= f->share_lo && i < f->share_hi)) return wf_fleet_params(f, sc, i);
    return draw_params(sc, &sc->groups[g], i, buf, err) ? NULL : buf;
}

void wf_fleet_open_window(WfFleet *f)
{
    memcpy(f->x_start_m + f->share_lo, f->x_m + f->share_lo, (f->share_hi - f->share_lo) * sizeof *f->x_m);
    f->window_open = 1;
}
