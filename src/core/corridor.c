/* The corridor: the open boundary of the block kernel (src/core/block.c) on a single-lane road [0, L]. Per step:
 * arrivals join the entrance queue, the queue's head is inserted at x = 0 when the gap allows (docs/corridors.md:
 * insertion rule), the kernel steps the vehicles with the road features at each vehicle's position (grade, speed
 * limit and zone anticipation as a per-vehicle cap, headway zones as per-vehicle parameters), then overlap repair,
 * Edie/detector accumulation and exits at x = L. Vehicles live in a circular buffer of slots in road order (the
 * back at `first`, leaders at higher slots) and never move in memory, so entries and exits touch no other
 * vehicle's data and the kernel sees at most two contiguous runs. Every sum that is written out runs serially in
 * road order. Units: m, s, m/s, m/s^2, g. */
#include "core/corridor_impl.h"

#include <limits.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/rng.h"
#include "observe/columns.h"
#include "core/par.h"
#include "core/simd.h"

const WfColumn wf_corridor_columns[WF_CTS_N_COLS] = {
    {"t", "s", "simulated time of the record"},
    {"vehicles", "1", "vehicles on the road"},
    {"mean_speed", "m/s", "mean speed over the vehicles on the road (NaN when empty)"},
    {"sd_speed", "m/s", "standard deviation of speed across the vehicles on the road (population, 1/N)"},
    {"min_speed", "m/s", "lowest speed on the road"},
    {"max_speed", "m/s", "highest speed on the road"},
    {"frac_stopped", "1", "fraction of the vehicles on the road slower than statistics.v_stop_mps"},
    {"waves", "1", "stop-and-go waves: maximal runs of consecutive vehicles (road order) slower than "
                   "statistics.wave_speed_mps"},
    {"fuel_rate", "g/s", "fuel rate of the vehicles on the road"},
    {"mean_gap", "m", "mean bumper-to-bumper gap of the vehicles that follow a vehicle"},
    {"min_gap", "m", "smallest bumper-to-bumper gap of the vehicles that follow a vehicle"},
    {"overlaps", "1", "overlap repairs so far"},
    {"arrived", "1", "vehicles that have reached the entrance so far (demand)"},
    {"entered", "1", "vehicles inserted at x = 0 so far"},
    {"exited", "1", "vehicles that have left at x = L so far"},
    {"queued", "1", "vehicles waiting at the entrance"},
    {"delayed", "1", "entries so far that waited at least one step"},
};
static void corridor_destroy(void *eng)
{
    WfCorridor *c = eng;
    wf_lanes_destroy(&c->lcs);
    cor_window_free(&c->win);
    cor_part_free(&c->pt);
#define SLOT(nm, field, stepped) c->ln[0].field,
    WF_FREE(SAVED_SLOT_ARRAYS(SLOT) STEP_SLOT_ARRAYS(SLOT) c->ln[0].veh.params, c->ln[0].veh.state, c->queue_t,
            c->det.count, c->det.sum_v_mps, c->det.sum_inv_v_spm, c->det.occupied_s, c->edie.dist_m, c->edie.time_s,
            c->edie.fuel_g, c->edie.grade_mean_rad, c->edie.class_dist_m, c->edie.class_fuel_g, c->bound_x, c->bound_v,
            c->chunks, c->cut_arrays, c->snap.x_m, c->snap.v_mps, c->snap.class_id, c->snap.group_id, c->snap.ready,
            c->snap.slot, c->snap.buf, c->lane_rows, c->coop_cap_mps2, c->coop_slot, c->snap.exiting, c->off_src,
            c->off_dst, c);
#undef SLOT
}

/* ------------------------------------------------------------------------------------------ road */

/* Whether zone z applies to lane l (road.zones[i].lanes). */
static inline int zone_on(const WfCorridorZone *zn, size_t l) { return !zn->lane_mask || (zn->lane_mask >> l & 1u); }

/* Speed limit in lane l at x: the lane's (road.lane_speed_limits_mps, else the road's), lowered by every speed-limit
 * zone of the lane containing x. */
static double limit_at(const WfCorridor *c, size_t l, double x)
{
    double lim = c->sc->lane_speed_limit_mps[l];
    for (size_t z = 0; z < c->cs->n_zones; z++) {
        const WfCorridorZone *zn = &c->cs->zones[z];
        if (zn->type == WF_ZONE_SPEED_LIMIT && x >= zn->from_m && x < zn->to_m && zn->value < lim && zone_on(zn, l))
            lim = zn->value;
    }
    return lim;
}

/* The parameters a vehicle drives with at x: its own, or inside its lane's headway zones a copy with the zones' key
 * multiplied (overlapping zones multiply). buf holds WF_MAX_MODEL_PARAMS doubles. */
static const double *params_at(const void *ctx, size_t group, const double *own, double x, double *buf)
{
    const CorLane *ln = ctx;
    const WfCorridor *c = ln->c;
    const double *p = own;
    for (size_t z = 0; z < c->cs->n_zones; z++) {
        const WfCorridorZone *zn = &c->cs->zones[z];
        int off = c->hw_off[group][z];
        if (zn->type != WF_ZONE_HEADWAY || off < 0 || x < zn->from_m || x >= zn->to_m || !zone_on(zn, ln->index))
            continue;
        if (p == own) {
            memcpy(buf, own, c->sc->groups[group].model->param_size);
            p = buf;
        }
        buf[off] *= zn->value;
    }
    return p;
}

/* ------------------------------------------------------------------------------------------ setup */


/* The vehicle buffer. Capacity: fronts on the road lie in [0, L) and bodies do not overlap, so consecutive fronts
 * are at least the shortest length apart: n <= floor(L / shortest) + 1; one more slot keeps a margin, and the
 * capacity is a multiple of the kernel's block, so that no block wraps around the buffer's end. */
static int alloc_vehicles(WfCorridor *c, WfError *err)
{
    const WfScenario *sc = c->sc;
    double len_min = INFINITY;
    for (size_t k = 0; k < sc->n_classes; k++) len_min = fmin(len_min, sc->classes[k].length_m);
    double capd = floor(c->L / len_min) + 2.0;
    if (capd > 1e8)
        return wf_err(err, WF_EINPUT, "%s: road.length_m %.6g m holds up to %.3g vehicles: too many", sc->path,
                      sc->road.length_m, capd);
    size_t cap = ((size_t)capd + WF_BLOCK - 1) / WF_BLOCK * WF_BLOCK, ssz = 0;
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].model->state_size > ssz) ssz = sc->groups[g].model->state_size;
    c->pstride = WF_MAX_MODEL_PARAMS;
    c->sstride = (ssz + 15) / 16 * 16;
    size_t nl = c->n_lanes;
    CorLane *l0 = &c->ln[0];
    l0->veh.cap = cap;
#define ALLOC_SLOTS(nm, field, stepped) ALLOC(l0->field, nl * cap);
    SAVED_SLOT_ARRAYS(ALLOC_SLOTS) STEP_SLOT_ARRAYS(ALLOC_SLOTS)
#undef ALLOC_SLOTS
    ALLOC(l0->veh.params, nl * cap * c->pstride);
    ALLOC(l0->veh.state, nl * cap * (c->sstride ? c->sstride : 1));
    /* lane l: its slots from l cap on, in every array */
    for (size_t l = 0; l < nl; l++) {
        CorLane *ln = &c->ln[l];
        size_t o = l * cap;
        ln->c = c;
        ln->index = l;
#define VIEW(nm, field, stepped) ln->field = l0->field + o;
        if (l) {
            SAVED_SLOT_ARRAYS(VIEW) STEP_SLOT_ARRAYS(VIEW)
            ln->veh.cap = cap;
            ln->veh.params = l0->veh.params + o * c->pstride;
            ln->veh.state = l0->veh.state + o * c->sstride;
        }
#undef VIEW
    }
    return 0;
}

/* Entrance queue: it never holds more vehicles than arrive in the whole run. Deterministic arrivals: the
 * cumulative demand, plus one; Poisson: its mean plus 12 standard deviations (the chance of more is below 1e-30;
 * should it happen the run stops with an error rather than overwrite the queue). */
static int alloc_entrance(WfCorridor *c, WfError *err)
{
    const WfScenario *sc = c->sc;
    const WfCorridorSpec *cs = c->cs;
    size_t seg = 0;
    double lam = wf_profile_integral(&cs->inflow_vph, sc->duration_s, &seg) / 3600.0;
    if (cs->has_ramp) { /* each lane's queue has room for the larger demand */
        size_t rseg = 0;
        lam = fmax(lam, wf_profile_integral(&cs->ramp_vph, sc->duration_s, &rseg) / 3600.0);
    }
    double qcap = cs->arrivals == WF_ARRIVALS_POISSON ? lam + 12.0 * sqrt(lam) + 32.0 : floor(lam) + 2.0;
    if (cs->max_arrivals >= 0 && (double)cs->max_arrivals + 1.0 < qcap) qcap = (double)cs->max_arrivals + 1.0;
    if (qcap > 2e8)
        return wf_err(err, WF_EINPUT, "%s: corridor.inflow brings %.3g vehicles over the run: too many", sc->path, lam);
    c->q_cap = (size_t)qcap;
    ALLOC(c->queue_t, c->n_lanes * c->q_cap); /* each lane its own part */
    return 0;
}

/* Detectors and Edie grid. Time cells are whole steps; the last cell in x (and in t) may be shorter. */
static int alloc_measure(WfCorridor *c, WfError *err)
{
    const WfScenario *sc = c->sc;
    const WfCorridorSpec *cs = c->cs;
    c->det.n_det = cs->n_det;
    c->det.x_m = cs->det_x_m;
    c->det.interval_s = cs->det_interval_s;
    c->det_every = lround(cs->det_interval_s / sc->dt_s);
    c->det.n_int = cs->n_det ? (size_t)((c->n_steps + c->det_every - 1) / c->det_every) : 0;
    size_t nd = c->det.n_int * c->det.n_det;
    ALLOC(c->det.count, nd); ALLOC(c->det.sum_v_mps, nd); ALLOC(c->det.sum_inv_v_spm, nd); ALLOC(c->det.occupied_s, nd);
    WfEdie *e = &c->edie;
    e->dx_m = cs->edie_dx_m;
    e->dt_s = cs->edie_dt_s;
    c->edie_every = lround(cs->edie_dt_s / sc->dt_s);
    e->nx = (size_t)ceil(c->L / e->dx_m - 1e-9);
    e->nt = (size_t)((c->n_steps + c->edie_every - 1) / c->edie_every);
    if (e->nx < 1) e->nx = 1;
    if (e->nt < 1) e->nt = 1;
    e->n_lanes = c->n_lanes;
    size_t ne = c->n_lanes * e->nx * e->nt; /* a plane per lane */
    ALLOC(e->dist_m, ne); ALLOC(e->time_s, ne); ALLOC(e->fuel_g, ne);
    ALLOC(e->grade_mean_rad, e->nx); ALLOC(e->class_dist_m, e->nx * sc->n_classes);
    ALLOC(e->class_fuel_g, e->nx * sc->n_classes);
    for (size_t i = 0; i < e->nx; i++) {
        double a = (double)i * e->dx_m, b = i + 1 == e->nx ? c->L : (double)(i + 1) * e->dx_m;
        e->grade_mean_rad[i] = wf_corridor_grade_mean(cs, a, b);
    }
    return 0;
}

/* Headway zones (where each group's model keeps the zone's key), the class shares of vehicles whose group fixes no
 * class (so that the overall mix is the classes' fractions), the first arrival (deterministic at cumulative demand
 * 1, Poisson after an exponential draw) and the virtual leader. */
static void init_boundary(WfCorridor *c)
{
    const WfScenario *sc = c->sc;
    const WfCorridorSpec *cs = c->cs;
    for (size_t g = 0; g < sc->n_groups; g++)
        for (size_t z = 0; z < cs->n_zones; z++) {
            const WfCfModel *m = sc->groups[g].model;
            const WfParamSpec *sp =
                cs->zones[z].type == WF_ZONE_HEADWAY ? wf_param_find(m->spec, m->n_spec, cs->zones[z].key) : NULL;
            c->hw_off[g][z] = sp ? (int)(sp->offset / sizeof(double)) : -1;
        }
    double tot = 0.0;
    for (size_t k = 0; k < sc->n_classes; k++) {
        double r = sc->classes[k].fraction;
        for (size_t g = 0; g < sc->n_groups; g++) r -= sc->groups[g].class_index == (int)k ? sc->groups[g].fraction : 0.0;
        c->free_share[k] = r > 0.0 ? r : 0.0;
        tot += c->free_share[k];
    }
    for (size_t k = 0; k < sc->n_classes; k++) c->free_share[k] = tot > 0.0 ? c->free_share[k] / tot : 0.0;
    c->has_vl = cs->outflow != WF_OUTFLOW_FREE;
    for (size_t l = 0; l < c->n_lanes; l++) {
        struct CorEntrance *en = &c->st.lane[l];
        en->next_target = 1.0;
        if (cs->arrivals == WF_ARRIVALS_POISSON) {
            double u[2];
            wf_rng_uniform2(sc->seed, WF_RNG_CORRIDOR_ARRIVAL, lane_key(l, 0), 0, u);
            en->next_target = -log(u[0]);
        }
        if (c->has_vl) {
            en->vl_xref = c->L + cs->leader_offset_m;
            en->vl_iref = 0.0;
            en->vl_x = en->vl_xref;
            en->vl_v = wf_profile_value(&cs->leader_speed_mps, 0.0, &en->vl_seg);
        }
    }
}

static int lane_init(WfCorridor *c, WfError *err);
static int lanes_init(WfCorridor *c, WfError *err);

static int corridor_create(WfSim *sim, WfError *err)
{
    const WfScenario *sc = sim->sc;
    WfCorridor *c = calloc(1, sizeof *c);
    if (!c) return wf_err(err, WF_ESYS, "out of memory");
    sim->eng = c;
    sim->steps_done = &c->st.steps_done;
    sim->win = &c->win.w, sim->gov = &c->gov;
    c->sim = sim;
    c->nthreads = sim->nthreads;
    wf_governor_init(&c->gov, c->nthreads, sc->thread_check_steps, 0);
    c->sc = sc;
    c->cs = sc->corridor;
    c->L = sc->road.length_m;
    c->fault_slot = -1;
    c->n_lanes = (size_t)wf_scenario_lanes(sc);
    for (size_t l = 0; l < c->n_lanes; l++) {
        CorLane *ln = &c->ln[l];
        int ramp = c->cs->has_ramp && l == 0;
        ln->demand = ramp ? &c->cs->ramp_vph : &c->cs->inflow_vph;
        ln->share = ramp ? 1.0 : c->cs->lane_share[l - (size_t)c->cs->has_ramp];
        ln->start_m = ramp ? c->cs->ramp_from_m : 0.0;
        ln->end_m = c->n_lanes > 1 ? c->cs->lane_end_m[l] : INFINITY;
    }
    c->n_steps = wf_scenario_n_steps(sc);
    c->out_every = wf_scenario_output_every(sc);
    c->traj_every = wf_scenario_trajectory_every(sc);
    c->warm_steps = (long)ceil(sc->warmup_s / sc->dt_s - 1e-9);
    int rc = wf_integrator_find(sc->integrator, &c->ig, err);
    if (!rc) rc = alloc_vehicles(c, err);
    /* The back of an empty lane is slot 64 (any slot would do): entries then reach the buffer's end after 65
     * vehicles, so every run longer than that steps a range wrapping around it, as long runs do. */
    for (size_t l = 0; !rc && l < c->n_lanes; l++) c->ln[l].veh.first = 64;
    if (!rc) rc = alloc_entrance(c, err);
    if (!rc) rc = alloc_measure(c, err);
    if (!rc) init_boundary(c);
    if (!rc) rc = lane_init(c, err);
    if (!rc) rc = lanes_init(c, err);
    if (!rc && sim->part && !(rc = cor_part_check(c, sim->part, err))) rc = cor_part_init(c, sim->part, err);
    if (!rc) rc = cor_window_init(c, err);
    return rc;
}

/* --------------------------------------------------------------------------------------- entrance */

/* Category with the largest deficit (i+1) share_c - assigned_c (ties to the earlier one): a deterministic
 * sequence that keeps every category within one vehicle of its share. */
static size_t by_deficit(size_t m, const double *share, const int64_t *assigned, int64_t i)
{
    size_t best = 0;
    double best_d = -INFINITY;
    for (size_t k = 0; k < m; k++) {
        if (!(share[k] > 0.0)) continue;
        double d = (double)(i + 1) * share[k] - (double)assigned[k];
        if (d > best_d) best_d = d, best = k;
    }
    return best;
}

/* Category of a uniform draw u in (0, 1) by cumulative shares; rounding leftovers go to the last non-empty one. */
static size_t by_draw(size_t m, const double *share, double u)
{
    double cum = 0.0;
    size_t last = 0;
    for (size_t k = 0; k < m; k++) {
        if (!(share[k] > 0.0)) continue;
        last = k;
        cum += share[k];
        if (u < cum) return k;
    }
    return last;
}

/* Class, group and parameters of the vehicle at the head of the queue (serial = entered so far), keyed by
 * (seed, serial) so they do not depend on when it gets in. */
static int draw_candidate(WfCorridor *c, size_t l, WfError *err)
{
    const WfScenario *sc = c->sc;
    struct CorEntrance *en = &c->st.lane[l];
    uint64_t serial = lane_key(l, (uint64_t)en->entered);
    double gshare[WF_MAX_GROUPS], u[2];
    for (size_t g = 0; g < sc->n_groups; g++) gshare[g] = sc->groups[g].fraction;
    wf_rng_uniform2(sc->seed, WF_RNG_CORRIDOR_ENTRY, serial, 0, u);
    size_t g = c->cs->interleaved ? by_deficit(sc->n_groups, gshare, en->assigned_group, en->entered)
                                  : by_draw(sc->n_groups, gshare, u[0]);
    en->assigned_group[g]++;
    size_t k;
    if (sc->groups[g].class_index >= 0) {
        k = (size_t)sc->groups[g].class_index;
    } else {
        k = c->cs->interleaved ? by_deficit(sc->n_classes, c->free_share, en->assigned_class, en->n_free_class)
                               : by_draw(sc->n_classes, c->free_share, u[1]);
        en->assigned_class[k]++;
        en->n_free_class++;
    }
    en->cand_group = (uint16_t)g;
    en->cand_class = (uint16_t)k;
    en->cand_len = sc->classes[k].length_m;
    int rc = wf_fleet_draw_params(sc, g, serial, en->cand_params, err);
    if (rc) return rc;
    en->have_cand = 1;
    return 0;
}

/* Arrivals up to time t join the queue: arrival n happens when the cumulative demand Λ(t) = ∫ q dt / 3600
 * reaches its target (n + 1 for deterministic headways; a sum of n + 1 unit exponentials for Poisson arrivals,
 * the time-rescaled Poisson process of rate q(t)). */
int cor_arrivals(WfCorridor *c, double t, WfError *err)
{
    const WfCorridorSpec *cs = c->cs;
    WfCorridorCounts *n = &c->st.counts;
    for (size_t l = 0; l < c->n_lanes; l++) {
        struct CorEntrance *en = &c->st.lane[l];
        /* lane l's demand: its share of the road's (the share of one lane is 1, exactly) */
        double lam = c->ln[l].share * (wf_profile_integral(c->ln[l].demand, t, &en->in_seg) / 3600.0);
        /* A deterministic target is an integer that the demand reaches up to round-off in t = k dt. */
        while (lam + 1e-9 * fmax(1.0, lam) >= en->next_target && (cs->max_arrivals < 0 || n->arrived < cs->max_arrivals)) {
            if ((size_t)en->queued >= c->q_cap)
                return wf_err(err, WF_ESYS, "%s: the entrance queue outgrew its %zu places at t = %.6g s", c->sc->path,
                              c->q_cap, t);
            size_t slot = (en->q_head + (size_t)en->queued) % c->q_cap;
            c->queue_t[l * c->q_cap + slot] = t;
            en->queued++, en->arrived++;
            n->queued++, n->arrived++;
            if (n->queued > n->max_queue) n->max_queue = n->queued;
            if (cs->arrivals == WF_ARRIVALS_POISSON) {
                double u[2];
                wf_rng_uniform2(c->sc->seed, WF_RNG_CORRIDOR_ARRIVAL, lane_key(l, (uint64_t)en->arrived), 0, u);
                en->next_target += -log(u[0]); /* u in (0, 1): finite and positive */
            } else {
                en->next_target += 1.0;
            }
        }
    }
    return 0;
}

/* The equilibrium speed at the far gap of group g's model with parameters p, capped at v_hi: a bisection, computed
 * once for a queue head that waits many steps at the entrance (1 % of a saturated corridor's step). */
static double free_speed(WfCorridor *c, size_t l, size_t g, const double *p, double v_hi)
{
    const WfCfModel *m = c->sc->groups[g].model;
    size_t np = m->param_size / sizeof(double);
    struct CorFree *f = &c->vfree[l];
    if (f->valid && f->group == g && f->v_hi == v_hi && !memcmp(f->params, p, np * sizeof *p)) return f->v_free;
    f->valid = 1, f->group = (uint16_t)g, f->v_hi = v_hi;
    memcpy(f->params, p, np * sizeof *p);
    return f->v_free = wf_cf_equilibrium_speed(m, p, WF_CORRIDOR_FREE_GAP_M, v_hi);
}

/* The back vehicle of lane ln (not empty) at the step's start: inside a window, the interior's back one from its
 * trace; split across processes, the rear vehicle of the last rank that holds any (its record of the step). */
static void back_vehicle(const WfCorridor *c, const CorLane *ln, double *x, double *v, double *len)
{
    const WfCorridorVehicles *vh = &ln->veh;
    for (int r = c->pt.p && !c->win.back_on ? c->pt.p->size - 1 : -1; r >= 0; r--)
        if (c->pt.pre[r].n) {
            *x = c->pt.pre[r].x, *v = c->pt.pre[r].v, *len = c->pt.pre[r].len;
            return;
        }
    size_t last = wf_corridor_slot(vh, vh->n - 1);
    int traced = c->win.back_on && last == c->win.back_slot;
    *x = traced ? c->win.back_x : vh->x_m[last];
    *v = traced ? c->win.back_v : vh->v_mps[last];
    *len = vh->length_m[last];
}

/* Insertion rule (docs/corridors.md): the queue's head enters at x = 0 with the speed v_in = min(entry cap,
 * limit at 0, leader speed, own free speed) when its gap g to the last vehicle's rear (or to the virtual leader) is
 * >= 0 and its own model, at (g, v_in, leader speed), does not brake harder than b =
 * corridor.inflow.insert_decel_mps2: the gap is safe for joining the stream at the stream's speed. The own free
 * speed is the model's equilibrium speed at the far gap of an empty road (where the leader's speed is taken to be
 * that too). At most one vehicle enters per step. */
static int try_insert(WfCorridor *c, size_t l, double t, long step, WfError *err)
{
    CorLane *ln = &c->ln[l];
    struct CorEntrance *en = &c->st.lane[l];
    if (en->queued == 0) return 0;
    WfCorridorVehicles *vh = &ln->veh;
    if (vh->n >= vh->cap) return 0; /* cannot happen while gaps stay >= 0 (see corridor_create) */
    if (!en->have_cand) {
        int rc = draw_candidate(c, l, err);
        if (rc) return rc;
    }
    const WfScenario *sc = c->sc;
    const WfDriverGroup *grp = &sc->groups[en->cand_group];
    double buf[WF_MAX_MODEL_PARAMS];
    double x0 = ln->start_m;
    const double *p = params_at(ln, en->cand_group, en->cand_params, x0, buf);
    double vcap = fmin(c->cs->entry_speed_mps, limit_at(c, l, x0));
    double v_hi = isfinite(vcap) ? vcap : 100.0;
    double gap, vl;
    int free_road = 0, obstacle = 0;
    if (vh->n > 0) {
        double bx, blen;
        back_vehicle(c, ln, &bx, &vl, &blen);
        gap = bx - blen - x0;
    } else if (isfinite(ln->end_m)) {
        gap = ln->end_m - x0, vl = 0.0, obstacle = 1; /* an empty merge lane: its end ahead */
    } else if (c->has_vl) {
        gap = en->vl_x;
        vl = en->vl_v;
    } else {
        gap = WF_CORRIDOR_FREE_GAP_M;
        vl = INFINITY;
        free_road = 1;
    }
    if (!(gap >= 0.0)) return 0;
    /* Never faster than the vehicle's own free speed (its model's equilibrium speed at the far gap), or a driver
     * slower than the stream could never join it; on an empty road the far leader drives at that speed. */
    double vfree = free_speed(c, l, en->cand_group, p, v_hi);
    double vin = fmin(obstacle ? vcap : fmin(vcap, vl), vfree), b = c->cs->insert_decel_mps2;
    if (free_road) vl = vin;
    if (obstacle && !(grp->model->accel(p, NULL, gap, vin, vl) >= -b)) {
        /* toward a lane's end the entry speed is the highest the rule admits (the models brake harder the faster
         * they approach a standing leader): bisection to 1e-9 of it */
        double lo = 0.0, hi = vin;
        for (int it = 0; it < 64 && hi - lo > 1e-9 * vin; it++) {
            double mid = 0.5 * (lo + hi);
            if (grp->model->accel(p, NULL, gap, mid, vl) >= -b) lo = mid;
            else hi = mid;
        }
        vin = lo;
    }
    if (!(grp->model->accel(p, NULL, gap, vin, vl) >= -b)) return 0;

    /* The new back vehicle: the slot behind the back one. */
    vh->first = vh->first ? vh->first - 1 : vh->cap - 1;
    vh->n++;
    size_t s = vh->first;
    vh->x_m[s] = x0;
    vh->v_mps[s] = vin;
    vh->a_mps2[s] = 0.0;
    vh->length_m[s] = en->cand_len;
    vh->serial[s] = lane_key(l, (uint64_t)en->entered);
    vh->class_id[s] = en->cand_class;
    vh->group_id[s] = en->cand_group;
    memcpy(vh->params + s * c->pstride, en->cand_params, grp->model->param_size);
    ln->grade_seg[s] = 0;
    ln->mode[s] = vin > sc->v_go_mps ? WF_MODE_MOVING : 0;
    double ta = c->queue_t[l * c->q_cap + en->q_head];
    en->q_head = (en->q_head + 1) % c->q_cap;
    en->queued--, en->entered++;
    c->st.counts.queued--;
    c->st.counts.entered++;
    c->st.counts.queue_delay_s += t - ta;
    c->st.counts.delayed += t - ta > 0.5 * sc->dt_s;
    c->st.cls_entered[en->cand_class]++;
    if (step >= c->warm_steps) c->st.w_entries++;
    ln->t_arr[s] = ta, ln->t_ent[s] = t, ln->v_ent[s] = vin;
    ln->trip.fuel_g[s] = ln->trip.dist_m[s] = ln->trip.stopped_s[s] = 0.0;
    ln->trip.stops[s] = ln->trip.hard_brakes[s] = ln->trip.infeasible[s] = 0;
    ln->win.fuel_g[s] = ln->win.dist_m[s] = ln->win.stopped_s[s] = 0.0;
    ln->win.steps[s] = ln->win.stops[s] = ln->win.hard_brakes[s] = ln->win.infeasible[s] = 0;
    ln->lane_changes[s] = ln->cut_ins[s] = 0, ln->lc_ready[s] = 0;
    ln->dest[s] = 0;
    if (c->cs->has_offramp && x0 < c->cs->off_at_m) {
        double u[2];
        wf_rng_uniform2(sc->seed, WF_RNG_CORRIDOR_EXIT, vh->serial[s], 0, u);
        ln->dest[s] = u[0] < c->cs->off_share;
    }
    if (grp->model->state_size && grp->model->init_state)
        grp->model->init_state(vh->params + s * c->pstride, vh->state + s * c->sstride, gap, vin, vl);
    en->have_cand = 0;
    return 0;
}

/* Each lane's queue head tries its lane, lane after lane. */
int cor_entrance(WfCorridor *c, double t, long step, WfError *err)
{
    for (size_t l = 0; l < c->n_lanes; l++) {
        int rc = try_insert(c, l, t, step, err);
        if (rc) return rc;
    }
    return 0;
}

/* ------------------------------------------------------------------------------------- the open road */

static void corridor_grade(const void *ctx, uint32_t *seg, size_t m, const double *x, double *th)
{
    const CorLane *ln = ctx;
    const WfCorridor *c = ln->c;
    for (size_t k = 0; k < m; k++) th[k] = wf_corridor_grade(c->cs, x[k], &seg[k]);
}

/* The cap of the acceleration at x: never past the speed limit at x within the step, and at least the braking
 * that meets a lower zone limit ahead at the zone's start: once the deceleration needed, (v^2 - v_zone^2) / (2 d),
 * reaches corridor.zone_decel_mps2, the vehicle brakes at least that hard. */
static int corridor_cap(const void *ctx, size_t lo, size_t m, const double *x, const double *v, double *cap)
{
    const CorLane *ln = ctx;
    const WfCorridor *c = ln->c;
    double dt = c->sc->dt_s;
    for (size_t k = 0; k < m; k++) {
        double cp = INFINITY, vlim = limit_at(c, ln->index, x[k]);
        if (isfinite(vlim)) cp = (vlim - v[k]) / dt;
        for (size_t z = 0; z < c->cs->n_zones; z++) {
            const WfCorridorZone *zn = &c->cs->zones[z];
            if (zn->type != WF_ZONE_SPEED_LIMIT || zn->from_m <= x[k] || zn->value >= v[k] || !zone_on(zn, ln->index))
                continue;
            /* d > 0 here (from > x), so the division is safe. */
            double need = (v[k] * v[k] - zn->value * zn->value) / (2.0 * (zn->from_m - x[k]));
            if (need >= c->cs->zone_decel_mps2 && -need < cp) cp = -need;
        }
        cap[k] = cp;
    }
    if (c->coop_cap_mps2) { /* a driver letting a merging vehicle in (lane_cooperation) */
        const double *cc = c->coop_cap_mps2 + ln->index * ln->veh.cap + lo;
        for (size_t k = 0; k < m; k++) cap[k] = cc[k] < cap[k] ? cc[k] : cap[k];
    }
    return 1;
}

/* The Edie cell of each step that lies inside one cell (the common case), computed as edie_vehicle does (the same
 * division and comparisons), else UINT32_MAX; slots [lo, lo + m). The kernel calls it for each block it advanced
 * (WfRoadOps.moved), on the block's thread; an overlap repair calls it again for the vehicle it moves. A loop without
 * control flow: it vectorises, and takes the division out of the measurement. */
WF_SIMD_CLONES
void cor_cells_of(const WfCorridor *c, const double *restrict xa, const double *restrict xb,
                     uint32_t *restrict cell, size_t m)
{
    /* in doubles until the store (the scenario caps the grid at 5e7 cells, so cell numbers fit in 31 bits): the
     * conversions between 32-bit integers and doubles and the narrowing of the masks cost more than the test */
    double dx = c->edie.dx_m, L = c->L, nxd = (double)c->edie.nx, last = nxd - 1.0;
    for (size_t k = 0; k < m; k++) {
        double a = xa[k], b = xb[k], q = (a > 0.0 ? a : 0.0) / dx;
        double i = q < nxd ? trunc(q) : last; /* (size_t)q, clamped to the last cell */
        double edge = i == last ? L : (i + 1.0) * dx;
        int one = (b > a) & (a >= 0.0) & (b <= L) & !(edge < b);
        /* a standing vehicle: edie_vehicle adds dt and its fuel to the cell of xa (in [0, L)) and no distance; the
         * running sums add its d = +0, which leaves every distance sum (+0 or more) unchanged */
        int still = (b == a) & (a >= 0.0) & (a < L);
        cell[k] = (uint32_t)(int32_t)(one | still ? i : -1.0); /* -1: UINT32_MAX */
    }
}

/* WfRoadOps.moved: the Edie cells of the step; inside a window, the step's movement into its rows. */
static void step_moved(const void *ctx, size_t lo, size_t m, long step)
{
    const CorLane *ln = ctx;
    const WfCorridor *c = ln->c;
    const CorWindow *cw = &c->win;
    if (!cw->active) {
        cor_cells_of(c, ln->xold + lo, ln->veh.x_m + lo, ln->cell + lo, m);
        return;
    }
    /* a vehicle's position before step s is row s: the window's start, its position after the step before, or where
     * it entered (back_part) */
    size_t s = (size_t)(step - cw->step0), cap = ln->veh.cap;
    if (s == 0) memcpy(cw->x + lo, ln->xold + lo, m * sizeof(double));
    memcpy(cw->x + (s + 1) * cap + lo, ln->veh.x_m + lo, m * sizeof(double));
    memcpy(cw->rate + s * cap + lo, ln->veh.fuel_rate_gps + lo, m * sizeof(double));
}

/* Whether drivers may cooperate: several lanes, one of them ending or an off-ramp, and a driver who yields. */
static int coop_possible(const WfCorridor *c)
{
    int ends = 0, yields = 0;
    for (size_t l = 0; c->n_lanes > 1 && l < c->n_lanes; l++) ends |= isfinite(c->ln[l].end_m);
    ends |= c->n_lanes > 1 && c->cs->has_offramp;
    for (size_t g = 0; g < c->sc->n_groups; g++) {
        const WfDriverGroup *grp = &c->sc->groups[g];
        double yield_mps2 = 0.0, range_m;
        if (grp->lc) grp->lc->cooperation(grp->lc_params, &yield_mps2, &range_m);
        yields |= yield_mps2 > 0.0;
    }
    return ends && yields;
}

static void measure_after_step(const void *ctx, int t, int nt);

static int lane_init(WfCorridor *c, WfError *err)
{
    const WfScenario *sc = c->sc;
    size_t nt = (size_t)c->nthreads + 1;
    c->bound_x = calloc(nt, sizeof(double));
    c->bound_v = calloc(nt, sizeof(double));
    c->chunks = calloc(nt, sizeof *c->chunks);
    c->cut_arrays = calloc(3 * nt * c->n_lanes, sizeof(double));
    if (!c->bound_x || !c->bound_v || !c->chunks || !c->cut_arrays) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t l = 0; l < c->n_lanes; l++) {
        double *a = c->cut_arrays + 3 * nt * l;
        c->cuts[l] = (WfCuts){.at = a, .busy_s = a + nt, .blocks = a + 2 * nt};
    }
    if (coop_possible(c)) {
        size_t n = c->n_lanes * c->ln[0].veh.cap;
        ALLOC(c->coop_cap_mps2, n);
        ALLOC(c->coop_slot, n);
        for (size_t k = 0; k < n; k++) c->coop_cap_mps2[k] = INFINITY;
    }
    c->has_cap = c->coop_cap_mps2 != NULL;
    for (size_t l = 0; l < c->n_lanes; l++) c->has_cap |= isfinite(sc->lane_speed_limit_mps[l]);
    for (size_t z = 0; z < c->cs->n_zones; z++) c->has_cap |= c->cs->zones[z].type == WF_ZONE_SPEED_LIMIT;
    c->ops = (WfRoadOps){.grade = c->cs->n_grade ? corridor_grade : NULL, .cap = c->has_cap ? corridor_cap : NULL,
                         .moved = step_moved, .after_step = measure_after_step,
                         .params_at = params_at};
    for (size_t l = 0; l < c->n_lanes; l++) {
        CorLane *cl = &c->ln[l];
        WfCorridorVehicles *vh = &cl->veh;
        WfLane *ln = &cl->lane;
        *ln = (WfLane){.sc = sc, .ig = c->ig, .ops = &c->ops, .ctx = cl, .cap = vh->cap, .x_m = vh->x_m,
                       .v_mps = vh->v_mps, .class_id = vh->class_id, .group_id = vh->group_id,
                       .grade_seg = cl->grade_seg, .mode = cl->mode, .x_old_m = cl->xold, .nthreads = c->nthreads,
                       .bound_x = c->bound_x, .bound_v = c->bound_v, .chunks = c->chunks, .cuts = &c->cuts[l],
                       .key0 = l << 40}; /* lane l's noise from blocks l 2^32: no two lanes share draws */
        /* the measurement inside the lane's step when nothing comes between them: one lane, no virtual leader to
         * advance and check first (step_once, phase_measure) */
        ln->after_wanted = c->n_lanes == 1 && !c->has_vl;
        for (size_t k = 0; k < sc->n_classes; k++) ln->class_length_m[k] = sc->classes[k].length_m;
        for (size_t g = 0; g < sc->n_groups; g++) {
            const WfDriverGroup *grp = &sc->groups[g];
            int het = 0;
            for (size_t k = 0; k < grp->model->n_spec; k++) het |= grp->spread[k] > 0.0;
            ln->params[g] = het ? (const unsigned char *)vh->params : (const unsigned char *)grp->params;
            ln->pstride[g] = het ? c->pstride * sizeof(double) : 0;
            ln->state[g] = vh->state;
            ln->sstride[g] = c->sstride;
            for (size_t z = 0; z < c->cs->n_zones; z++) ln->zoned[g] |= c->hw_off[g][z] >= 0;
            ln->noisy |= grp->noise_mps2 > 0.0;
            ln->stateful |= grp->model->update_state != NULL;
        }
        ln->always = cl->trip;
        ln->window = cl->win;
        wf_lane_safety_init(ln);
    }
    return 0;
}

/* Lane changes: the decisions' scratch for every slot of every lane, and the road's description. */
static int lanes_init(WfCorridor *c, WfError *err)
{
    size_t n = c->n_lanes * c->ln[0].veh.cap, unit = c->pstride * sizeof(double);
    if (c->n_lanes > 1) {
        c->lane_row_len = 3 + c->n_lanes * WF_LANE_N_COLS;
        c->lane_rows_max = (size_t)wf_scenario_records(c->sc, c->out_every);
        ALLOC(c->lane_rows, c->lane_rows_max * c->lane_row_len);
    }
    int rc = wf_lanes_create(&c->lcs, c->sc, n, c->n_lanes, err);
    if (rc) return rc;
    if (c->sstride > unit) unit = c->sstride;
    if (c->lcs.active || c->cs->has_offramp) ALLOC(c->snap.buf, n * unit);
    if (c->cs->has_offramp) {
        ALLOC(c->off_src, c->ln[0].veh.cap);
        ALLOC(c->off_dst, c->ln[0].veh.cap);
    }
    if (!c->lcs.active) return 0;
    ALLOC(c->snap.x_m, n); ALLOC(c->snap.v_mps, n); ALLOC(c->snap.class_id, n); ALLOC(c->snap.group_id, n);
    ALLOC(c->snap.ready, n); ALLOC(c->snap.slot, n); ALLOC(c->snap.exiting, n);
    return 0;
}

/* A corridor vehicle's parameters and controller memory (the road's ctx is the corridor; index i of the road). */
static const void *road_params(const WfLcRoad *r, size_t i)
{
    const WfCorridor *c = r->ctx;
    return c->ln[0].veh.params + (size_t)c->snap.slot[i] * c->pstride;
}
static const void *road_state(const WfLcRoad *r, size_t i)
{
    const WfCorridor *c = r->ctx;
    return c->ln[0].veh.state + (size_t)c->snap.slot[i] * c->sstride;
}

/* The corridor as the lane changes see it at the step's start: each lane's vehicles back to front. */
static void lanes_road(WfCorridor *c, WfLcRoad *r)
{
    const WfScenario *sc = c->sc;
    size_t cap = c->ln[0].veh.cap, i = 0;
    *r = (WfLcRoad){.sc = sc, .L = c->L, .n_lanes = c->n_lanes, .x_m = c->snap.x_m, .p_m = c->snap.x_m,
                    .v_mps = c->snap.v_mps, .class_id = c->snap.class_id, .group_id = c->snap.group_id,
                    .ready_step = c->snap.ready, .class_length_m = c->ln[0].lane.class_length_m,
                    .params = road_params, .state = road_state, .ctx = c};
    for (size_t g = 0; g < sc->n_groups; g++)
        r->group_params[g] = c->ln[0].lane.pstride[g] ? NULL : c->ln[0].lane.params[g];
    for (size_t l = 0; l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        const WfCorridorVehicles *vh = &ln->veh;
        r->first[l] = i, r->count[l] = vh->n, r->front[l] = cor_front_leader(c, l), r->end_m[l] = ln->end_m;
        for (size_t j = 0; j < vh->n; j++, i++) {
            size_t s = vh->first + j < cap ? vh->first + j : vh->first + j - cap; /* back to front */
            c->snap.x_m[i] = vh->x_m[s], c->snap.v_mps[i] = vh->v_mps[s], c->snap.class_id[i] = vh->class_id[s];
            c->snap.group_id[i] = vh->group_id[s], c->snap.ready[i] = ln->lc_ready[s];
            c->snap.exiting[i] = ln->dest[s];
            c->snap.slot[i] = (uint32_t)(l * cap + s);
        }
    }
    r->n = i;
    if (c->cs->has_offramp) {
        r->exiting = c->snap.exiting, r->exit_lane = c->cs->exit_lane;
        r->exit_at_m = c->cs->off_at_m, r->exit_approach_m = c->cs->off_approach_m;
    }
}

/* The lanes' window accumulators in the kernel: all of them, or the step count alone while the trip's stand for the
 * rest (win_is_trip). */
static void window_gates(WfCorridor *c, int win_is_trip)
{
    c->win_is_trip = win_is_trip;
    for (size_t l = 0; l < c->n_lanes; l++)
        c->ln[l].lane.window = win_is_trip ? (WfAccum){.steps = c->ln[l].win.steps} : c->ln[l].win;
}

/* A vehicle that entered with the statistics window open has window totals equal to its trip totals, bit for bit:
 * both start at zero at its entry and get the same additions at every step. Once every vehicle on the road did,
 * the kernel adds to the trip's alone: in perf, the second copy took about a quarter of the fused step's own loops
 * (run_block). It stays so: later vehicles enter with the window open too. A road split across processes keeps both:
 * its vehicles cross to ranks that may not have switched. The front vehicle of each lane is usually the earliest
 * to have entered, so while one from before the window remains the test ends at once. */
static void window_is_trip(WfCorridor *c, long step)
{
    if (c->win_is_trip || c->pt.p || step < c->warm_steps) return;
    double t_open = (double)c->warm_steps * c->sc->dt_s; /* the entrance's t of the window's first step */
    for (size_t l = 0; l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        for (size_t k = 0; k < ln->veh.n; k++)
            if (ln->t_ent[wf_corridor_slot(&ln->veh, k)] < t_open) return;
    }
    window_gates(c, 1);
}

/* Slot s's window totals written out from its trip's while win_is_trip (slot s of lane ln's arrays; lane 0's
 * address every lane's slots): before they are read (cor_finish_vehicle, wf_sim_state) or moved (lanes_move), so
 * that every slot holds what it held when the kernel kept both. */
static void window_total_out(const WfCorridor *c, const CorLane *ln, size_t s)
{
    if (!c->win_is_trip) return;
    ln->win.fuel_g[s] = ln->trip.fuel_g[s], ln->win.dist_m[s] = ln->trip.dist_m[s];
    ln->win.stopped_s[s] = ln->trip.stopped_s[s], ln->win.stops[s] = ln->trip.stops[s];
    ln->win.hard_brakes[s] = ln->trip.hard_brakes[s], ln->win.infeasible[s] = ln->trip.infeasible[s];
}

/* Every per-slot array of the lanes, moved: the k-th vehicle of the new order comes from global slot src[k] and goes
 * to global slot dst[k] (one gather into the scratch, then one scatter). */
static void lanes_move(WfCorridor *c, const uint32_t *src, const uint32_t *dst, size_t n)
{
    unsigned char *buf = c->snap.buf;
    CorLane *l0 = &c->ln[0];
    for (size_t k = 0; c->win_is_trip && k < n; k++) window_total_out(c, l0, src[k]);
#define MOVE_ARRAY(base, unit)                                                                               do {                                                                                                         unsigned char *a_ = (unsigned char *)(base);                                                             size_t u_ = (unit);                                                                                      for (size_t k = 0; k < n; k++) memcpy(buf + k * u_, a_ + (size_t)src[k] * u_, u_);                      for (size_t k = 0; k < n; k++) memcpy(a_ + (size_t)dst[k] * u_, buf + k * u_, u_);                  } while (0)
#define MOVE(nm, field, stepped) MOVE_ARRAY(l0->field, sizeof *l0->field);
    SAVED_SLOT_ARRAYS(MOVE)
#undef MOVE
    MOVE_ARRAY(l0->veh.params, c->pstride * sizeof(double));
    if (c->sstride) MOVE_ARRAY(l0->veh.state, c->sstride);
#undef MOVE_ARRAY
}

/* The step's changes decided on r: each lane rebuilt back to front from the vehicles that stay and, in each gap, the
 * one that entered it (a gap behind vehicle k of the old order, or ahead of the lane's front). A lane's back keeps its
 * slot. */
static void lane_moves(WfCorridor *c, const WfLcRoad *r, long step)
{
    const WfLaneChanges *lc = &c->lcs;
    size_t cap = c->ln[0].veh.cap, j = 0, newn[WF_MAX_LANES];
    uint32_t *src = c->lcs.perm, *dst = (uint32_t *)c->lcs.scratch;
    for (size_t m = 0; m < c->n_lanes; m++) {
        size_t fm = r->first[m], nm = r->count[m], start = j, first = c->ln[m].veh.first;
        const uint32_t *claim = lc->claim + fm + m;
        for (size_t q = 0; q <= nm; q++) {
            if (claim[q]) src[j++] = claim[q] - 1;
            if (q < nm && !lc->dir[fm + q]) src[j++] = (uint32_t)(fm + q);
        }
        newn[m] = j - start;
        for (size_t k = start; k < j; k++) {
            size_t s = first + (k - start) < cap ? first + (k - start) : first + (k - start) - cap;
            dst[k] = (uint32_t)(m * cap + s);
        }
    }
    /* snapshot indices -> global slots, then the move */
    for (size_t k = 0; k < j; k++) src[k] = c->snap.slot[src[k]];
    lanes_move(c, src, dst, j);
    for (size_t m = 0, k = 0; m < c->n_lanes; m++) {
        CorLane *ln = &c->ln[m];
        ln->veh.n = newn[m];
        for (size_t q = 0; q < newn[m]; q++, k++) {
            size_t s = dst[k] - m * cap, from = src[k] / cap;
            if (from == m) continue;
            ln->lc_ready[s] = step + lc->interval_steps[ln->veh.group_id[s]];
            ln->lane_changes[s]++;
            c->lk.total.changes++, c->lk.rec_changes++;
            c->lk.total.pair[from][m]++;
            c->lk.total.group_changes[ln->veh.group_id[s]]++;
            if (!q) continue;
            size_t behind = dst[k - 1] - m * cap; /* the vehicle behind it now */
            ln->cut_ins[behind]++;
            c->lk.total.cut_ins++, c->lk.rec_cut_ins++;
            c->lk.total.lane_cut_ins[m]++;
            c->lk.total.group_cut_ins[ln->veh.group_id[behind]]++;
        }
    }
}

/* The cooperation of the step (wf_lanes_cooperate) on the road after its changes: each yielding driver's bound, by
 * global slot, for corridor_cap. The previous step's bounds are cleared first (none at the final instant). */
static void lane_cooperation(WfCorridor *c, const WfLcRoad *r)
{
    for (size_t k = 0; k < c->n_coop; k++) c->coop_cap_mps2[c->coop_slot[k]] = INFINITY;
    c->n_coop = 0;
    if (!r) return;
    size_t n = wf_lanes_cooperate(&c->lcs, r);
    for (size_t k = 0; k < n; k++) {
        uint32_t s = c->snap.slot[c->lcs.coop_who[k]];
        double a = c->lcs.coop_cap_mps2[k];
        if (c->coop_cap_mps2[s] == INFINITY) c->coop_slot[c->n_coop++] = s;
        if (a < c->coop_cap_mps2[s]) c->coop_cap_mps2[s] = a;
    }
}

/* The lane changes at the start of a step (src/core/lanes.h): decisions from the state, the moves, then the
 * cooperation the new state asks for. */
static void lane_changes(WfCorridor *c, long step)
{
    if (!c->lcs.active) return;
    WfLcRoad r;
    lanes_road(c, &r);
    if (wf_lanes_decide(&c->lcs, &r, step, wf_governor_threads(&c->gov))) {
        lane_moves(c, &r, step);
        if (c->coop_cap_mps2) lanes_road(c, &r);
    }
    if (c->coop_cap_mps2) lane_cooperation(c, &r);
}

/* The step's values go to the per-slot arrays (COR_EXPORT_ALL: steps with a trajectory, which read them before the
 * vehicles move; COR_EXPORT_RECORD: what a record reads after a fused step) or stay in the kernel's blocks; the fuel
 * rate is always kept (Edie and detectors read it). */
void cor_lane_exports(WfCorridor *c, int what)
{
    for (size_t l = 0; l < c->n_lanes; l++) {
        WfCorridorVehicles *vh = &c->ln[l].veh;
        c->ln[l].lane.out = what == COR_EXPORT_ALL ? (WfLaneValues){vh->a_mps2, vh->gap_m, vh->v_lead_mps,
                                                                    vh->theta_rad, vh->fuel_rate_gps, vh->flag, NULL}
                          : what == COR_EXPORT_RECORD
                              ? (WfLaneValues){.gap_m = vh->gap_m, .fuel_rate_gps = vh->fuel_rate_gps,
                                               .v_mps = c->ln[l].v_start}
                              : (WfLaneValues){.fuel_rate_gps = vh->fuel_rate_gps};
    }
}

/* The front vehicle's leader: the virtual leader, or a far one at the vehicle's own speed. */
WfLead cor_front_leader(const WfCorridor *c, size_t l)
{
    const struct CorEntrance *en = &c->st.lane[l];
    if (isfinite(c->ln[l].end_m)) return (WfLead){c->ln[l].end_m, 0.0, 0.0}; /* the lane's end, standing */
    return c->has_vl ? (WfLead){en->vl_x, en->vl_v, 0.0} : (WfLead){0.0, 0.0, WF_CORRIDOR_FREE_GAP_M};
}

/* No gap may be negative: a vehicle that would overlap its leader (or pass the virtual leader) is put at gap 0
 * behind it and stopped, front to back so a repaired leader is seen by its follower; each event is counted. A
 * non-finite state is a numerical fault (the run stops). Checks the `upto` front vehicles (the kernel flags
 * overlaps and faults behind the front). */
void cor_phase_overlaps(WfCorridor *c, CorLane *ln, int in_window, size_t upto)
{
    WfCorridorVehicles *vh = &ln->veh;
    for (size_t k = 0; k < vh->n && k < upto; k++) {
        size_t s = wf_corridor_slot(vh, k);
        if (!isfinite(vh->x_m[s]) || !isfinite(vh->v_mps[s]) || (ln->mode[s] & WF_MODE_FAULT)) {
            c->fault_slot = (long)s, c->fault_lane = (size_t)(ln - c->ln);
            return;
        }
        double limit;
        if (k > 0) {
            size_t p = wf_corridor_slot(vh, k - 1);
            limit = vh->x_m[p] - vh->length_m[p];
        } else if (isfinite(ln->end_m)) {
            limit = ln->end_m;
        } else if (c->has_vl) {
            limit = c->st.lane[ln - c->ln].vl_x;
        } else {
            continue;
        }
        if (vh->x_m[s] > limit) {
            double d = limit - vh->x_m[s];
            ln->trip.dist_m[s] += d;
            if (in_window && !c->win_is_trip) ln->win.dist_m[s] += d;
            vh->x_m[s] = limit;
            vh->v_mps[s] = 0.0;
            c->st.counts.overlaps++;
            step_moved(ln, s, 1, c->meas_step);
        }
    }
}

/* A vehicle's step in Edie's cells [i_lo, i_hi) of row j: distance, time and fuel split in proportion to distance
 * (constant speed within the step). Cells before i_lo are skipped exactly as the full loop would leave them: the
 * loop reaches cell i > the first only through the left edge i dx. Inlined into the measurement: around a call, the
 * loop spilled and reloaded its running sums (every vector register is the caller's to save), a fifth of the
 * measurement's time in perf. */
static inline __attribute__((always_inline)) void edie_vehicle(WfCorridor *c, size_t j, size_t cl, double xa,
                                                               double xb, double fuel, int in_window, size_t i_lo,
                                                               size_t i_hi)
{
    WfEdie *e = &c->edie;
    size_t nx = e->nx;
    double dt = c->sc->dt_s, L = c->L, *cd = e->class_dist_m + cl * nx, *cf = e->class_fuel_g + cl * nx;
    double *erow_d = e->dist_m + j * nx, *erow_t = e->time_s + j * nx, *erow_f = e->fuel_g + j * nx;
    if (xb > xa) {
        double span = xb - xa, lo = xa > 0.0 ? xa : 0.0, hi = xb < L ? xb : L;
        size_t i = (size_t)(lo / e->dx_m);
        if (i >= nx) i = nx - 1; /* round-off at the far end */
        if (i < i_lo) {
            if (!((double)i_lo * e->dx_m < hi)) return;
            i = i_lo, lo = (double)i_lo * e->dx_m;
        }
        for (; i < i_hi && lo < hi; i++) {
            /* The last cell ends at L (it may be shorter than dx). */
            double edge = i + 1 == nx ? L : (double)(i + 1) * e->dx_m;
            double b = edge < hi ? edge : hi, d = b - lo, w = d / span;
            erow_d[i] += d, erow_t[i] += dt * w, erow_f[i] += fuel * w;
            if (in_window) cd[i] += d, cf[i] += fuel * w;
            lo = b;
        }
    } else if (xa >= 0.0 && xa < L) {
        size_t i = (size_t)(xa / e->dx_m);
        if (i >= nx) i = nx - 1;
        if (i < i_lo || i >= i_hi) return;
        erow_t[i] += dt, erow_f[i] += fuel;
        if (in_window) cf[i] += fuel;
    }
}

/* A vehicle's step at detector q: a passage, and the time within the step when the body [x - len, x] covers x_d
 * (x moving linearly from xa to xb). Pairs that add nothing (+0 to a sum >= +0) are skipped. */
static inline void detector_vehicle(WfCorridor *c, size_t jd, size_t q, double xa, double xb, double len)
{
    WfDetectors *dt_ = &c->det;
    double dt = c->sc->dt_s, xd = dt_->x_m[q];
    size_t cell = jd * dt_->n_det + q;
    if (xa <= xd && xd < xb) {
        double v = (xb - xa) / dt; /* > 0: xb > xa */
        dt_->count[cell]++;
        dt_->sum_v_mps[cell] += v;
        dt_->sum_inv_v_spm[cell] += 1.0 / v;
    }
    if (xb > xa) {
        if (!(xd + len - xa > 0.0) || xd - xa >= xb - xa) return; /* t1 <= 0 or t0 >= dt: occupancy 0 */
        double t0 = (xd - xa) / (xb - xa) * dt, t1 = (xd + len - xa) / (xb - xa) * dt;
        t0 = t0 > 0.0 ? t0 : 0.0;
        t1 = t1 < dt ? t1 : dt;
        dt_->occupied_s[cell] += t1 > t0 ? t1 - t0 : 0.0;
    } else if (xa >= xd && xa - len <= xd) {
        dt_->occupied_s[cell] += dt;
    }
}

/* First index k in [lo, hi) whose position pos (x_m or xold, by slot) is below x (or at most x unless strict), by
 * bisection: k runs from the front vehicle backwards, so positions fall along k, before and after the step. */
static size_t first_below(const CorLane *ln, const double *pos, double x, int strict, size_t lo, size_t hi)
{
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        double p = pos[wf_corridor_slot(&ln->veh, mid)];
        if (strict ? p < x : p <= x) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* The vehicles [*k0, *k1) whose step can add to Edie cells [i_lo, i_hi) or detectors [q_lo, q_hi): a step from xa to
 * xb adds only to cells it meets and to detectors within a vehicle length behind xb, so vehicles that start the step
 * beyond the range and the longest length, or end it before the range, add nothing (a 1 m margin covers the
 * rounding of cell indices). Visiting only these, still in road order, gives every sum the same additions in the
 * same order, and lets the threads of the parallel measurement share the vehicles instead of each visiting all. */
void cor_measure_span(const WfCorridor *c, const CorLane *ln, size_t i_lo, size_t i_hi, size_t q_lo,
                         size_t q_hi, size_t *k0, size_t *k1)
{
    const WfScenario *sc = c->sc;
    double x_lo = INFINITY, x_hi = -INFINITY, len = 0.0;
    for (size_t k = 0; k < sc->n_classes; k++) len = sc->classes[k].length_m > len ? sc->classes[k].length_m : len;
    if (i_lo < i_hi) {
        x_lo = (double)i_lo * c->edie.dx_m;
        x_hi = i_hi >= c->edie.nx ? INFINITY : (double)i_hi * c->edie.dx_m;
    }
    for (size_t q = q_lo; q < q_hi; q++) {
        double xd = c->det.x_m[q];
        x_lo = xd < x_lo ? xd : x_lo;
        x_hi = xd + len > x_hi ? xd + len : x_hi;
    }
    /* split, the lane itself (not a window's view of its rows): this rank's vehicles */
    int part = c->pt.p && ln == &c->ln[0];
    size_t kb = part ? c->pt.kb : 0, ke = part ? c->pt.ke : ln->veh.n;
    *k0 = first_below(ln, ln->xold, x_hi + 1.0, 0, kb, ke);
    *k1 = first_below(ln, ln->veh.x_m, x_lo - 1.0, 1, *k0, ke);
}

/* The running sums of one Edie cell of the step's row and of its class profiles are held in registers while
 * consecutive vehicles step inside that cell: each sum gets the same additions in the same order as adding to the
 * cell in memory. The class sums are vectors with a lane per class: a vehicle adds its distance and fuel to its
 * class's lane and +0 to the others, which leaves them unchanged (these sums start at +0 and never become -0), so
 * no branch depends on the class. With nv vectors, vector v holds classes 4 v .. 4 v + 3; packed (nv = 0, at most
 * two classes), one vector holds {distance of class 0, fuel of class 0, distance of class 1, fuel of class 1}. The
 * cell's distance and fuel sums are the two lanes of one vector too: a vehicle's {distance, fuel} is added to them
 * by one instruction and, repeated into four lanes, to the packed class sums. */

static inline void lanes_load(V4 *out, const double *base, size_t nx, size_t i, size_t v, size_t nc)
{
    size_t k = 4 * v;
    *out = (V4){k < nc ? base[k * nx + i] : 0.0, k + 1 < nc ? base[(k + 1) * nx + i] : 0.0,
                k + 2 < nc ? base[(k + 2) * nx + i] : 0.0, k + 3 < nc ? base[(k + 3) * nx + i] : 0.0};
}

static inline void lanes_store(const V4 *x, double *base, size_t nx, size_t i, size_t v, size_t nc)
{
    size_t k = 4 * v;
    if (k < nc) base[k * nx + i] = (*x)[0];
    if (k + 1 < nc) base[(k + 1) * nx + i] = (*x)[1];
    if (k + 2 < nc) base[(k + 2) * nx + i] = (*x)[2];
    if (k + 3 < nc) base[(k + 3) * nx + i] = (*x)[3];
}

/* mk[c][v]: the lanes of class c in vector v (nv = 0: in the packed vector), for classes [0, nc); all clear when
 * !on (outside the statistics window: nothing is added). */
static void lane_masks(M4 mk[][4], size_t nc, int nv, int on)
{
    for (size_t c = 0; c < nc; c++)
        for (int v = 0; v < (nv ? nv : 1); v++)
            for (int j = 0; j < 4; j++)
                mk[c][v][j] = on && (nv ? (size_t)(4 * v + j) == c : (size_t)(j >> 1) == c) ? -1 : 0;
}

/* x into the lanes mask selects of acc; the other lanes get +0. Vectors go by pointer: passing one by value would
 * depend on the target's vector ABI. */
static inline void lane_add(V4 *acc, const M4 *mask, const V4 *x) { *acc += (V4)((M4)*x & *mask); }

/* Edie cells [i_lo, i_hi) and detectors [q_lo, q_hi) from every vehicle's step, in road order, with nv class vectors
 * or packed (nv = 0; a constant at each call: the vectors stay in registers). The common case, a step inside one
 * cell (d = span, w = span / span = 1 exactly), adds the same values as edie_vehicle through the cell's running
 * sums. */
static inline __attribute__((always_inline)) void measure_nv(WfCorridor *c, const CorLane *ln, long step,
                                                             int in_window, size_t i_lo, size_t i_hi, size_t q_lo,
                                                             size_t q_hi, const int nv)
{
    const WfCorridorVehicles *vh = &ln->veh;
    WfEdie *e = &c->edie;
    /* row j of the lane's plane */
    size_t j = ln->index * e->nt + (size_t)(step / c->edie_every), nx = e->nx;
    size_t jd = c->det.n_det ? (size_t)(step / c->det_every) : 0;
    size_t nc = c->sc->n_classes, held = SIZE_MAX; /* the cell whose sums are in registers */
    double dt = c->sc->dt_s, *row_d = e->dist_m + j * nx, *row_t = e->time_s + j * nx, *row_f = e->fuel_g + j * nx;
    double *cdist = e->class_dist_m, *cfuel = e->class_fuel_g;
    const double *xold = ln->xold, *x = vh->x_m, *rate = vh->fuel_rate_gps;
    const uint32_t *cell = ln->cell;
    const uint16_t *cls = vh->class_id;
    double st = 0.0;
    V2 sdf = {0.0, 0.0}; /* the cell's distance and fuel */
    V4 cd0 = {0}, cd1 = {0}, cd2 = {0}, cd3 = {0}, cf0 = {0}, cf1 = {0}, cf2 = {0}, cf3 = {0};
    M4 mk[WF_MAX_CLASSES][4];
    lane_masks(mk, nc, nv, in_window);
#define FLUSH()                                                                                                     \
    do {                                                                                                            \
        if (held == SIZE_MAX) break;                                                                                \
        row_d[held] = sdf[0], row_t[held] = st, row_f[held] = sdf[1];                                               \
        if (nv == 0) {                                                                                              \
            cdist[held] = cd0[0], cfuel[held] = cd0[1];                                                             \
            if (nc > 1) cdist[nx + held] = cd0[2], cfuel[nx + held] = cd0[3];                                       \
        } else {                                                                                                    \
            lanes_store(&cd0, cdist, nx, held, 0, nc), lanes_store(&cf0, cfuel, nx, held, 0, nc);                   \
        }                                                                                                           \
        if (nv > 1) lanes_store(&cd1, cdist, nx, held, 1, nc), lanes_store(&cf1, cfuel, nx, held, 1, nc);           \
        if (nv > 2) lanes_store(&cd2, cdist, nx, held, 2, nc), lanes_store(&cf2, cfuel, nx, held, 2, nc);           \
        if (nv > 2) lanes_store(&cd3, cdist, nx, held, 3, nc), lanes_store(&cf3, cfuel, nx, held, 3, nc);           \
        held = SIZE_MAX;                                                                                            \
    } while (0)
    size_t k0, k1;
    cor_measure_span(c, ln, i_lo, i_hi, q_lo, q_hi, &k0, &k1);
    /* Road order is descending slot order, wrapping from slot 0 to the last: at most two segments of slots
     * [lo, hi) visited from hi - 1 down. Along one segment a cell's one-cell steps are consecutive (positions fall
     * along road order), so each run of them is summed by the tight inner loop. */
    for (size_t k = k0; k < k1;) {
        size_t top = wf_corridor_slot(vh, k) + 1, len = top < k1 - k ? top : k1 - k, lo = top - len, s = top;
        k += len;
        while (s > lo) {
            size_t i = cell[s - 1];
            if (i == UINT32_MAX) {
                FLUSH();
                s--;
                edie_vehicle(c, j, cls[s], xold[s], x[s], rate[s] * dt, in_window, i_lo, i_hi);
                continue;
            }
            if (i < i_lo || i >= i_hi) { /* inside one cell of another thread */
                s--;
                continue;
            }
            if (i != held) {
                FLUSH();
                held = i, sdf = (V2){row_d[i], row_f[i]}, st = row_t[i];
                if (nv == 0)
                    cd0 = (V4){cdist[i], cfuel[i], nc > 1 ? cdist[nx + i] : 0.0, nc > 1 ? cfuel[nx + i] : 0.0};
                else
                    lanes_load(&cd0, cdist, nx, i, 0, nc), lanes_load(&cf0, cfuel, nx, i, 0, nc);
                if (nv > 1) lanes_load(&cd1, cdist, nx, i, 1, nc), lanes_load(&cf1, cfuel, nx, i, 1, nc);
                if (nv > 2) lanes_load(&cd2, cdist, nx, i, 2, nc), lanes_load(&cf2, cfuel, nx, i, 2, nc);
                if (nv > 2) lanes_load(&cd3, cdist, nx, i, 3, nc), lanes_load(&cf3, cfuel, nx, i, 3, nc);
            }
            do {
                s--;
                double d = x[s] - xold[s], fuel = rate[s] * dt;
                V2 df2 = {d, fuel};
                sdf += df2, st += dt;
                const M4 *m4 = mk[cls[s]];
                if (nv == 0) {
                    V4 df = {d, fuel, d, fuel};
                    lane_add(&cd0, m4, &df);
                } else {
                    V4 dv = {d, d, d, d}, fv = {fuel, fuel, fuel, fuel};
                    lane_add(&cd0, m4, &dv), lane_add(&cf0, m4, &fv);
                    if (nv > 1) lane_add(&cd1, m4 + 1, &dv), lane_add(&cf1, m4 + 1, &fv);
                    if (nv > 2) lane_add(&cd2, m4 + 2, &dv), lane_add(&cf2, m4 + 2, &fv);
                    if (nv > 2) lane_add(&cd3, m4 + 3, &dv), lane_add(&cf3, m4 + 3, &fv);
                }
            } while (s > lo && cell[s - 1] == i);
        }
    }
    /* detectors: sums of their own, each in road order */
    for (size_t k = k0, s = k0 < k1 ? wf_corridor_slot(vh, k0) : 0; q_lo < q_hi && k < k1;
         k++, s = s ? s - 1 : vh->cap - 1)
        for (size_t q = q_lo; q < q_hi; q++) detector_vehicle(c, jd, q, xold[s], x[s], vh->length_m[s]);
    FLUSH();
#undef FLUSH
}

WF_SIMD_CLONES
void cor_measure_range(WfCorridor *c, const CorLane *ln, long step, int in_window, size_t i_lo, size_t i_hi,
                          size_t q_lo, size_t q_hi)
{
    size_t nc = c->sc->n_classes;
    if (nc <= 2) measure_nv(c, ln, step, in_window, i_lo, i_hi, q_lo, q_hi, 0);
    else if (nc <= 4) measure_nv(c, ln, step, in_window, i_lo, i_hi, q_lo, q_hi, 1);
    else if (nc <= 8) measure_nv(c, ln, step, in_window, i_lo, i_hi, q_lo, q_hi, 2);
    else measure_nv(c, ln, step, in_window, i_lo, i_hi, q_lo, q_hi, 4);
}

/* The first Edie cell of thread t of nt (0 for t = 0, nx for t = nt): the cell of the vehicle with n t / nt of the
 * lane's n vehicles behind it, so that the threads visit about as many vehicles each however they crowd along the
 * road (a queue at the entrance holds most of them in a few kilometres). A running maximum over t' <= t keeps the
 * cuts in order whatever the positions. */
size_t cor_cell_cut(const WfCorridor *c, const CorLane *ln, size_t t, size_t nt)
{
    size_t n = ln->veh.n, nx = c->edie.nx, cut = 0;
    if (t >= nt) return nx;
    for (size_t u = 1; u <= t && n; u++) {
        double x = ln->veh.x_m[wf_corridor_slot(&ln->veh, n - 1 - n * u / nt)] / c->edie.dx_m;
        size_t i = x > 0.0 ? (x < (double)nx ? (size_t)x : nx) : 0;
        cut = i > cut ? i : cut;
    }
    return cut;
}

/* Thread t of nt's share of the measurement of lane ln: its cells (cell_cut) and detectors. */
static void measure_share(WfCorridor *c, const CorLane *ln, long step, int in_window, size_t t, size_t nt)
{
    size_t nd = c->det.n_det;
    cor_measure_range(c, ln, step, in_window, cor_cell_cut(c, ln, t, nt), cor_cell_cut(c, ln, t + 1, nt), nd * t / nt,
                  nd * (t + 1) / nt);
}

static double record_sums(const WfCorridor *c, size_t l0, size_t l1, int at_start, RecordSums *r);

/* WfRoadOps.after_step: the measurement inside the step's own parallel region, when the step needs no repair and
 * nothing else happens between the step and the measurement (one lane, no virtual leader: step_once); on a record
 * step, the record's sums too (record_row takes them). */
static void measure_after_step(const void *ctx, int t, int nt)
{
    const CorLane *ln = ctx;
    WfCorridor *c = ln->c;
    if (!c->rec_in_step || nt < 2) {
        measure_share(c, ln, c->meas_step, c->meas_in_window, (size_t)t, (size_t)nt);
        return;
    }
    /* a record step: its sums are serial chains in road order, as long as a share of the measurement; the first
     * thread takes them, the others the measurement */
    if (t > 0) {
        measure_share(c, ln, c->meas_step, c->meas_in_window, (size_t)t - 1, (size_t)nt - 1);
        return;
    }
    RecordSums r;
    c->rec_m2 = record_sums(c, 0, c->n_lanes, 1, &r);
    memcpy(c->rec_sums, &r, sizeof r);
    c->rec_summed = 1;
}

/* Edie cells, class profiles and detectors from each vehicle's step (xold -> x over [t, t + dt]). Several vehicles
 * add to one cell, so each cell's sum runs in road order whatever the thread count: on a large road each thread
 * owns a range of cells and of detectors and visits, in road order, the vehicles that can reach them
 * (measure_span); the cells and detectors of each thread are the same bits wherever the cuts fall. A lane whose
 * step already measured (measure_after_step) is skipped. */
static void phase_measure(WfCorridor *c, long step, int in_window)
{
    /* lane after lane: each cell's sums run lane by lane, each lane in road order */
    for (size_t l = 0; l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        if (ln->lane.after_done) continue;
        int nth = wf_lane_threads(ln->veh.n, wf_governor_threads(&c->gov));
        if (nth <= 1) {
            measure_share(c, ln, step, in_window, 0, 1);
            continue;
        }
#pragma omp parallel num_threads(nth) default(none) shared(c, ln, step, in_window)
        {
#ifdef _OPENMP
            size_t t = (size_t)omp_get_thread_num(), nt = (size_t)omp_get_num_threads();
#else
            size_t t = 0, nt = 1;
#endif
            measure_share(c, ln, step, in_window, t, nt);
        }
    }
}

/* Hand the completed trips to the output (before a checkpoint, and when the buffer is full). */
static int flush_trips(void *eng, WfError *err)
{
    WfCorridor *c = eng;
    const WfOutput *out = c->sim->out;
    int rc = 0;
    if (c->n_trips && out && out->trips) rc = out->trips(out->ctx, c->sim, c->trips, c->n_trips, err);
    c->n_trips = 0;
    return rc;
}

/* A vehicle's window totals join its class's; its trip joins the buffer. completed: 1 at x = L, 2 by the off-ramp
 * (not a trip of the road's length: not in the trips' means), 0 still on the road. */
int cor_finish_vehicle(WfCorridor *c, const CorLane *ln, size_t s, double t_exit, int completed, WfError *err)
{
    if (c->n_lanes > 1)
        c->lk.group_vehicle_s[ln->veh.group_id[s]] +=
            (completed ? t_exit : (double)c->st.steps_done * c->sc->dt_s) - ln->t_ent[s];
    const WfCorridorVehicles *vh = &ln->veh;
    window_total_out(c, ln, s);
    size_t cl = vh->class_id[s];
    c->st.cls_fuel[cl] += ln->win.fuel_g[s];
    c->st.cls_dist[cl] += ln->win.dist_m[s];
    c->st.cls_stops[cl] += ln->win.stops[s];
    c->st.cls_infeas[cl] += ln->win.infeasible[s];
    c->st.cls_steps[cl] += ln->win.steps[s];
    c->st.tot_hard += ln->win.hard_brakes[s];
    c->st.tot_stopped_s += ln->win.stopped_s[s];
    if (completed == 1) {
        c->st.trips_done++;
        c->st.sum_trip_time += t_exit - ln->t_ent[s];
        c->st.sum_trip_fuel += ln->trip.fuel_g[s];
        c->st.cls_trips[cl]++;
        c->st.cls_trip_time[cl] += t_exit - ln->t_ent[s];
        c->st.cls_trip_fuel[cl] += ln->trip.fuel_g[s];
    }
    WfTrip *tr = &c->trips[c->n_trips++];
    *tr = (WfTrip){.serial = vh->serial[s], .class_id = vh->class_id[s], .group_id = vh->group_id[s],
                   .completed = (uint8_t)completed, .t_arrival_s = ln->t_arr[s], .t_entry_s = ln->t_ent[s],
                   .t_exit_s = completed ? t_exit : NAN, .v_entry_mps = ln->v_ent[s], .fuel_g = ln->trip.fuel_g[s],
                   .dist_m = ln->trip.dist_m[s], .time_stopped_s = ln->trip.stopped_s[s], .stops = ln->trip.stops[s],
                   .hard_brakes = ln->trip.hard_brakes[s], .infeasible_steps = ln->trip.infeasible[s],
                   .lane = (uint8_t)(ln - c->ln), .lane_changes = ln->lane_changes[s]};
    return c->n_trips == TRIP_BUF ? flush_trips(c, err) : 0;
}

/* The vehicle k places behind lane ln's front leaves by the off-ramp: the vehicles behind it move one slot up (the
 * lane's back with them), so those ahead, which it no longer affects, keep their slots and their noise draws. */
static int offramp_exit(WfCorridor *c, CorLane *ln, size_t k, double t_end, WfError *err)
{
    WfCorridorVehicles *vh = &ln->veh;
    size_t o = ln->index * vh->cap, m = 0;
    int rc = cor_finish_vehicle(c, ln, wf_corridor_slot(vh, k), t_end, 2, err);
    for (size_t j = k + 1; j < vh->n; j++, m++)
        c->off_src[m] = (uint32_t)(o + wf_corridor_slot(vh, j)), c->off_dst[m] = (uint32_t)(o + wf_corridor_slot(vh, j - 1));
    lanes_move(c, c->off_src, c->off_dst, m);
    vh->first = vh->first + 1 < vh->cap ? vh->first + 1 : 0;
    vh->n--;
    c->st.counts.off_ramp++;
    return rc;
}

/* The off-ramp: vehicles bound for it whose front reached it in this step leave by it from the exit lane; in
 * another lane they miss it and drive on. */
static int phase_offramp(WfCorridor *c, double t_end, WfError *err)
{
    double at = c->cs->off_at_m;
    for (size_t l = 0; l < c->n_lanes; l++) {
        CorLane *ln = &c->ln[l];
        WfCorridorVehicles *vh = &ln->veh;
        /* from the front: past the vehicles already beyond it, then those that crossed it in this step */
        size_t k = 0;
        while (k < vh->n && ln->xold[wf_corridor_slot(vh, k)] >= at) k++;
        while (k < vh->n && vh->x_m[wf_corridor_slot(vh, k)] >= at) {
            size_t s = wf_corridor_slot(vh, k);
            if (!ln->dest[s]) {
                k++;
            } else if (l == c->cs->exit_lane) {
                int rc = offramp_exit(c, ln, k, t_end, err);
                if (rc) return rc;
            } else {
                ln->dest[s] = 0;
                c->st.counts.missed_exits++;
                k++;
            }
        }
    }
    return 0;
}

/* Vehicles whose front has reached L leave (front first); with the speed outflow each one becomes the virtual
 * leader: its rear bumper drives on at the prescribed speed. Inside a window their trips and totals wait for its
 * end (its slot keeps them: no entry reaches it within a window). */
int cor_phase_exits(WfCorridor *c, CorLane *ln, double t_end, int in_window, size_t most, WfError *err)
{
    WfCorridorVehicles *vh = &ln->veh;
    CorWindow *cw = &c->win;
    for (; most > 0 && vh->n > 0 && vh->x_m[wf_corridor_slot(vh, 0)] >= c->L; most--) {
        size_t s = wf_corridor_slot(vh, 0);
        int rc = 0;
        if (cw->active)
            cw->exit_slot[cw->n_exits] = (uint32_t)s, cw->exit_t[cw->n_exits++] = t_end;
        else
            rc = cor_finish_vehicle(c, ln, s, t_end, 1, err);
        if (c->cs->outflow == WF_OUTFLOW_SPEED) {
            struct CorEntrance *en = &c->st.lane[ln - c->ln];
            size_t seg = en->vl_seg;
            en->vl_xref = vh->x_m[s] - vh->length_m[s];
            en->vl_iref = wf_profile_integral(&c->cs->leader_speed_mps, t_end, &seg);
            en->vl_x = en->vl_xref;
        }
        vh->n--;
        c->st.counts.exited++;
        if (in_window) c->st.w_exits++;
        if (rc) return rc;
    }
    return 0;
}

/* The virtual leader at time t: x = x_ref + ∫ v (exact for the piecewise-linear profile). */
void cor_advance_leader(WfCorridor *c, double t)
{
    if (!c->has_vl) return;
    const WfProfile *p = &c->cs->leader_speed_mps;
    for (size_t l = 0; l < c->n_lanes; l++) {
        struct CorEntrance *en = &c->st.lane[l];
        en->vl_x = en->vl_xref + (wf_profile_integral(p, t, &en->vl_seg) - en->vl_iref);
        en->vl_v = wf_profile_value(p, t, &en->vl_seg);
    }
}


/* A multi-lane corridor's lanes at a record (/lanes, src/observe/lanes.c): each lane's record (the road's rule over
 * that lane alone), as its columns. */
static void lanes_observe(WfCorridor *c, double t, int at_start)
{
    double *row;
    if (c->n_lanes < 2 || !(row = wf_lane_row(c->lane_rows, c->lane_row_len, c->lane_rows_max, &c->lk.n_rows,
                                              &c->lk.rec_changes, &c->lk.rec_cut_ins, t)))
        return;
    for (size_t l = 0; l < c->n_lanes; l++) {
        WfCorridorRow r;
        cor_record(c, l, l + 1, t, at_start, &r);
        static const int from[] = {WF_CTS_MEAN_V, WF_CTS_SD_V, WF_CTS_WAVES,
                                   WF_CTS_FUEL_RATE, WF_CTS_MEAN_GAP, WF_CTS_FRAC_STOPPED};
        wf_lane_values(r.v, from, r.v[WF_CTS_VEHICLES], c->L, row + l * WF_LANE_N_COLS);
    }
}

/* The lane observers (wf_sim_lanes). */
static int corridor_lanes(const void *eng, WfLaneObs *out)
{
    const WfCorridor *c = eng;
    if (c->n_lanes < 2) return 0;
    *out = (WfLaneObs){.n_lanes = c->n_lanes, .n_rows = (size_t)c->lk.n_rows, .row_len = c->lane_row_len,
                       .rows = c->lane_rows, .pair = &c->lk.total.pair[0][0], .lane_cut_ins = c->lk.total.lane_cut_ins,
                       .group_changes = c->lk.total.group_changes, .group_cut_ins = c->lk.total.group_cut_ins,
                       .lane_vehicle_s = c->lk.total.lane_vehicle_s};
    memcpy(out->group_vehicle_s, c->lk.group_vehicle_s, sizeof out->group_vehicle_s);
    return 1;
}


/* Vehicles [k0, k1) of one lane into the record's sums, front first, with nv class vectors (a constant at each
 * call). Every sum is a
 * register, so the pass runs at the speed of its longest chain of additions instead of a class sum's store and
 * reload per vehicle; the minimum and maximum are fmin(m, x) and fmax(m, x) as glibc gives them (m when equal or
 * when x is NaN), written as comparisons because each call of fmin cost more than the rest of the vehicle. */
static inline __attribute__((always_inline)) void record_lane(const WfScenario *sc, const WfCorridorVehicles *vh,
                                                              const M4 mk[][4], RecordSums *r, size_t k0, size_t k1,
                                                              const int nv)
{
    double sv = r->sv, sg = r->sg, vmin = r->vmin, vmax = r->vmax, gmin = r->gmin;
    double v_stop = sc->v_stop_mps, v_wave = sc->wave_speed_mps;
    size_t stopped = r->stopped, waves = r->waves, n = k1 - k0;
    V4 cf0 = r->cf[0], cf1 = r->cf[1], cf2 = r->cf[2], cf3 = r->cf[3];
    int prev_slow = r->prev_slow;
    for (size_t k = k0, s = n ? wf_corridor_slot(vh, k0) : 0; k < k1; k++, s = s ? s - 1 : vh->cap - 1) {
        double v = vh->v_mps[s], rate = vh->fuel_rate_gps[s];
        const M4 *m4 = mk[vh->class_id[s]];
        sv += v;
        stopped += v < v_stop;
        int slow = v < v_wave;
        waves += slow && !prev_slow;
        prev_slow = slow;
        vmin = v < vmin ? v : vmin, vmax = v > vmax ? v : vmax;
        V4 rv = {rate, rate, rate, rate};
        lane_add(&cf0, m4, &rv);
        if (nv > 1) lane_add(&cf1, m4 + 1, &rv);
        if (nv > 2) lane_add(&cf2, m4 + 2, &rv), lane_add(&cf3, m4 + 3, &rv);
        if (k > 0) {
            double g = vh->gap_m[s];
            sg += g, gmin = g < gmin ? g : gmin;
        }
    }
    r->sv = sv, r->sg = sg, r->vmin = vmin, r->vmax = vmax, r->gmin = gmin, r->stopped = stopped, r->waves = waves;
    r->cf[0] = cf0, r->cf[1] = cf1, r->cf[2] = cf2, r->cf[3] = cf3;
    r->prev_slow = prev_slow;
    r->n += n, r->ngap += n ? n - (k0 == 0) : 0; /* the road's front vehicle follows none */
}

/* Lanes [l0, l1) into the record's sums, each lane's vehicles [k0, k1) (SIZE_MAX: all of them), each lane's waves
 * from its front. */
WF_SIMD_CLONES
void cor_record_lanes(const WfCorridor *c, size_t l0, size_t l1, size_t k0, size_t k1, int at_start, RecordSums *r)
{
    size_t nc = c->sc->n_classes;
    int nv = nc <= 4 ? 1 : nc <= 8 ? 2 : 4;
    M4 mk[WF_MAX_CLASSES][4];
    lane_masks(mk, nc, nv, 1);
    const M4(*masks)[4] = (const M4(*)[4])mk;
    for (size_t l = l0; l < l1; l++) {
        WfCorridorVehicles veh = c->ln[l].veh;
        const WfCorridorVehicles *vh = &veh;
        if (at_start) veh.v_mps = c->ln[l].v_start;
        size_t e = k1 < vh->n ? k1 : vh->n;
        if (k1 == SIZE_MAX) r->prev_slow = 0;
        if (nv == 1) record_lane(c->sc, vh, masks, r, k0, e, 1);
        else if (nv == 2) record_lane(c->sc, vh, masks, r, k0, e, 2);
        else record_lane(c->sc, vh, masks, r, k0, e, 4);
    }
}

/* The sum of (v - mean)^2 over vehicles [k0, k1) of lane l, front first, added to m2. */
double cor_record_m2(const WfCorridor *c, size_t l, size_t k0, size_t k1, int at_start, double mean, double m2)
{
    const WfCorridorVehicles *vh = &c->ln[l].veh;
    const double *v = at_start ? c->ln[l].v_start : vh->v_mps;
    for (size_t k = k0; k < k1 && k < vh->n; k++) {
        double d = v[wf_corridor_slot(vh, k)] - mean;
        m2 += d * d;
    }
    return m2;
}


/* The sums of the record of lanes [l0, l1) into *r, lane after lane, each lane front first; waves and gaps within
 * each lane. Returns the sum of squared deviations from the mean speed. */
static double record_sums(const WfCorridor *c, size_t l0, size_t l1, int at_start, RecordSums *r)
{
    *r = (RecordSums){.vmin = INFINITY, .vmax = -INFINITY, .gmin = INFINITY};
    cor_record_lanes(c, l0, l1, 0, SIZE_MAX, at_start, r);
    double mean = r->n ? r->sv / (double)r->n : NAN, m2 = 0.0;
    for (size_t l = l0; l < l1; l++) m2 = cor_record_m2(c, l, 0, SIZE_MAX, at_start, mean, m2);
    return m2;
}

/* The record of lanes [l0, l1) (the road's: all of them). */
void cor_record(const WfCorridor *c, size_t l0, size_t l1, double t, int at_start, WfCorridorRow *row)
{
    RecordSums r;
    double m2 = record_sums(c, l0, l1, at_start, &r);
    cor_record_row(c, &r, m2, t, row);
}

/* A record's row from its sums (record_lanes) and m2 (record_m2). */
void cor_record_row(const WfCorridor *c, const RecordSums *rs, double m2, double t, WfCorridorRow *row)
{
    const WfScenario *sc = c->sc;
    const RecordSums r = *rs;
    memset(row, 0, sizeof *row);
    for (size_t cl = 0; cl < sc->n_classes; cl++) row->class_fuel_rate_gps[cl] = r.cf[cl / 4][cl % 4];
    size_t n = r.n, ngap = r.ngap;
    double sv = r.sv, sg = r.sg, fuel = 0.0;
    double mean = n ? sv / (double)n : NAN;
    for (size_t cl = 0; cl < sc->n_classes; cl++) fuel += row->class_fuel_rate_gps[cl];
    row->v[WF_CTS_T] = t;
    row->v[WF_CTS_VEHICLES] = (double)n;
    row->v[WF_CTS_MEAN_V] = mean;
    row->v[WF_CTS_SD_V] = n ? sqrt(m2 / (double)n) : NAN;
    row->v[WF_CTS_MIN_V] = n ? r.vmin : NAN;
    row->v[WF_CTS_MAX_V] = n ? r.vmax : NAN;
    row->v[WF_CTS_FRAC_STOPPED] = n ? (double)r.stopped / (double)n : 0.0;
    row->v[WF_CTS_WAVES] = (double)r.waves;
    row->v[WF_CTS_FUEL_RATE] = fuel;
    row->v[WF_CTS_MEAN_GAP] = ngap ? sg / (double)ngap : NAN;
    row->v[WF_CTS_MIN_GAP] = ngap ? r.gmin : NAN;
    row->v[WF_CTS_OVERLAPS] = (double)c->st.counts.overlaps;
    row->v[WF_CTS_ARRIVED] = (double)c->st.counts.arrived;
    row->v[WF_CTS_ENTERED] = (double)c->st.counts.entered;
    row->v[WF_CTS_EXITED] = (double)c->st.counts.exited;
    row->v[WF_CTS_QUEUED] = (double)c->st.counts.queued;
    row->v[WF_CTS_DELAYED] = (double)c->st.counts.delayed;
}

static void summarize(WfCorridor *c)
{
    const WfScenario *sc = c->sc;
    WfSummary *s = &c->sim->summary;
    memset(s, 0, sizeof *s);
    long window = c->st.steps_done - c->warm_steps;
    s->window_s = window > 0 ? (double)window * sc->dt_s : 0.0;
    double litres = 0, gallons = 0, stops = 0, infeas = 0, steps = 0;
    const WfEdie *e = &c->edie;
    for (size_t k = 0; k < sc->n_classes; k++) {
        WfClassSummary *cs = &s->cls[k];
        const WfVehicleClass *vc = &sc->classes[k].vc;
        cs->entered = c->st.cls_entered[k];
        cs->trips = c->st.cls_trips[k];
        cs->fuel_g = c->st.cls_fuel[k];
        cs->dist_m = c->st.cls_dist[k];
        cs->l_per_100km = wf_l_per_100km(vc, cs->fuel_g, cs->dist_m);
        cs->mpg = wf_mpg(vc, cs->fuel_g, cs->dist_m);
        cs->stops_per_vkm = cs->dist_m > 0 ? c->st.cls_stops[k] / (cs->dist_m / 1000.0) : 0.0;
        cs->infeasible_share = c->st.cls_steps[k] > 0 ? c->st.cls_infeas[k] / c->st.cls_steps[k] : 0.0;
        cs->trip_fuel_mean_g = cs->trips ? c->st.cls_trip_fuel[k] / (double)cs->trips : NAN;
        cs->trip_time_mean_s = cs->trips ? c->st.cls_trip_time[k] / (double)cs->trips : NAN;
        double fu = 0, du = 0, fd = 0, dd = 0, ff = 0, df = 0;
        for (size_t i = 0; i < e->nx; i++) {
            double th = e->grade_mean_rad[i], f = e->class_fuel_g[k * e->nx + i], d = e->class_dist_m[k * e->nx + i];
            if (th > 1e-4) fu += f, du += d;
            else if (th < -1e-4) fd += f, dd += d;
            else ff += f, df += d;
        }
        cs->g_per_km_up = du > 0 ? fu / (du / 1000.0) : NAN;
        cs->g_per_km_down = dd > 0 ? fd / (dd / 1000.0) : NAN;
        cs->g_per_km_flat = df > 0 ? ff / (df / 1000.0) : NAN;
        s->fuel_g += cs->fuel_g;
        s->dist_m += cs->dist_m;
        stops += c->st.cls_stops[k];
        infeas += c->st.cls_infeas[k];
        steps += c->st.cls_steps[k];
        litres += cs->fuel_g / vc->fuel_density_g_per_l;
        gallons += cs->fuel_g / vc->fuel_density_g_per_l / WF_L_PER_US_GAL;
    }
    double vht_s = steps * sc->dt_s;
    s->vkt_km = s->dist_m / 1000.0;
    s->vht_h = vht_s / 3600.0;
    s->l_per_100km = s->dist_m > 0 ? litres / (s->dist_m / 1e5) : INFINITY;
    s->mpg = gallons > 0 ? (s->dist_m / WF_M_PER_MILE) / gallons : 0.0;
    s->stops_per_vkm = s->vkt_km > 0 ? stops / s->vkt_km : 0.0;
    s->hard_brakes_per_vkm = s->vkt_km > 0 ? c->st.tot_hard / s->vkt_km : 0.0;
    s->mean_speed_mps = vht_s > 0 ? s->dist_m / vht_s : 0.0;
    s->sd_speed_time_avg_mps = c->st.n_sd ? c->st.sd_sum / (double)c->st.n_sd : NAN;
    s->inflow_vph = s->window_s > 0 ? (double)c->st.w_entries / s->window_s * 3600.0 : 0.0;
    s->outflow_vph = s->window_s > 0 ? (double)c->st.w_exits / s->window_s * 3600.0 : 0.0;
    s->infeasible_share = steps > 0 ? infeas / steps : 0.0;
    s->time_stopped_share = vht_s > 0 ? c->st.tot_stopped_s / vht_s : 0.0;
    s->trips = c->st.trips_done;
    s->mean_travel_time_s = c->st.trips_done ? c->st.sum_trip_time / (double)c->st.trips_done : NAN;
    s->mean_trip_fuel_g = c->st.trips_done ? c->st.sum_trip_fuel / (double)c->st.trips_done : NAN;
    s->mean_queue_delay_s = c->st.counts.entered ? c->st.counts.queue_delay_s / (double)c->st.counts.entered : NAN;
    s->counts = c->st.counts;
    s->on_road = c->st.counts.entered - c->st.counts.exited - c->st.counts.off_ramp;
}

int cor_numerical_fault(const WfCorridor *c, long step, WfError *err)
{
    const WfCorridorVehicles *vh = &c->ln[c->fault_lane].veh;
    size_t s = (size_t)c->fault_slot;
    const WfDriverGroup *g = &c->sc->groups[vh->group_id[s]];
    return wf_err(err, WF_ESYS,
                  "numerical fault at t = %.9g s: vehicle %llu (driver group '%s', model %s, class %s): a non-finite "
                  "acceleration, fuel rate or state (now x = %g m, v = %g m/s); partial results kept",
                  (double)(step + 1) * c->sc->dt_s, (unsigned long long)vh->serial[s], g->name, g->model->name,
                  c->sc->classes[vh->class_id[s]].vc.name, vh->x_m[s], vh->v_mps[s]);
}

/* The record of instant t into *row, from the vehicles' values at the step's start (at_start: a fused step kept the
 * speeds before it moved the vehicles; else they have not moved yet). */
static void record_row(WfCorridor *c, double t, int in_window, int at_start, WfCorridorRow *row)
{
    size_t on_road = 0;
    for (size_t l = 0; l < c->n_lanes; l++) on_road += c->ln[l].veh.n;
    if (c->rec_summed) { /* summed inside the step (measure_after_step) */
        RecordSums r;
        memcpy(&r, c->rec_sums, sizeof r);
        cor_record_row(c, &r, c->rec_m2, t, row);
    } else {
        cor_record(c, 0, c->n_lanes, t, at_start, row);
    }
    lanes_observe(c, t, at_start);
    if (in_window && on_road) c->st.sd_sum += row->v[WF_CTS_SD_V], c->st.n_sd++;
}

static int record_out(WfCorridor *c, const WfCorridorRow *row, WfError *err)
{
    const WfOutput *out = c->sim->out;
    WfRecord rec = {row->v, WF_CTS_N_COLS, row->class_fuel_rate_gps};
    return out && out->record ? out->record(out->ctx, c->sim, &rec, err) : 0;
}

/* The open boundary after the vehicles moved: the virtual leader, overlap repair, Edie and detectors, exits. */
static int boundary_after(WfCorridor *c, long step, int in_window, const int *flags, WfError *err)
{
    size_t nl = c->n_lanes;
    double t_next = (double)(step + 1) * c->sc->dt_s;
    int rc;
    for (size_t l = 0; nl > 1 && l < nl; l++) c->lk.total.lane_vehicle_s[l] += (double)c->ln[l].veh.n * c->sc->dt_s;
    cor_advance_leader(c, t_next);
    for (size_t l = 0; l < nl; l++) {
        CorLane *ln = &c->ln[l];
        cor_phase_overlaps(c, ln, in_window, flags[l] ? ln->veh.n : c->has_vl ? 1 : 0);
        if (c->fault_slot >= 0) return cor_numerical_fault(c, step, err);
    }
    phase_measure(c, step, in_window);
    if (c->cs->has_offramp && (rc = phase_offramp(c, t_next, err))) return rc;
    for (size_t l = 0; l < nl; l++)
        if ((rc = cor_phase_exits(c, &c->ln[l], t_next, in_window, SIZE_MAX, err))) return rc;
    return 0;
}

/* One step: the kernel's pass that computes the step's values, fused with the advance unless a trajectory or the
 * final instant must see them first, then the open boundary (boundary_after). A record is taken between the two
 * passes, or after the fused pass from what it kept (COR_EXPORT_RECORD) and handed to the output once the step is
 * complete, so that the output never sees vehicles moved but not yet repaired or gone (WfOutput.record: they may be
 * one step further). Returns WF_LOOP_END after the final instant (recorded without a step), 0 after a step, or an
 * error code. */
static int step_once(WfCorridor *c, long step, WfError *err)
{
    const WfOutput *out = c->sim->out;
    const WfScenario *sc = c->sc;
    size_t nl = c->n_lanes;
    double t = (double)step * sc->dt_s;
    int in_window = step >= c->warm_steps, records = step % c->out_every == 0, last = step == c->n_steps;
    int traj = sc->trajectories && step % c->traj_every == 0, rc, flags[WF_MAX_LANES] = {0};
    if (c->coop_cap_mps2) lane_cooperation(c, NULL);
    if (nl > 1 && step > 0 && !last) lane_changes(c, step);
    if ((rc = cor_arrivals(c, t, err)) || (rc = cor_entrance(c, t, step, err))) return rc;
    WfLead front[WF_MAX_LANES];
    for (size_t l = 0; l < nl; l++) front[l] = cor_front_leader(c, l);
    int two_pass = traj || last;
    cor_lane_exports(c, two_pass ? COR_EXPORT_ALL : records ? COR_EXPORT_RECORD : COR_EXPORT_NONE);
    c->meas_step = step, c->meas_in_window = in_window; /* for measure_after_step */
    WfCorridorRow row;
    if (two_pass) {
        for (size_t l = 0; l < nl; l++) {
            CorLane *ln = &c->ln[l];
            wf_lane_step(&ln->lane, ln->veh.first, ln->veh.n, &front[l], step,
                         WF_PASS_ACCEL | WF_PASS_ENERGY | (last ? 0 : WF_PASS_COUNT), in_window, NULL);
        }
        if (records) record_row(c, t, in_window, 0, &row);
        if (records && (rc = record_out(c, &row, err))) return rc;
        if (traj && out && out->trajectory && (rc = out->trajectory(out->ctx, c->sim, t, err))) return rc;
        if (last) return WF_LOOP_END;
        for (size_t l = 0; l < nl; l++) {
            CorLane *ln = &c->ln[l];
            flags[l] = wf_lane_step(&ln->lane, ln->veh.first, ln->veh.n, &front[l], step, WF_PASS_ADVANCE, in_window,
                                    NULL);
        }
        return boundary_after(c, step, in_window, flags, err);
    }
    c->rec_in_step = records, c->rec_summed = 0;
    for (size_t l = 0; l < nl; l++) {
        CorLane *ln = &c->ln[l];
        flags[l] = wf_lane_step(&ln->lane, ln->veh.first, ln->veh.n, &front[l], step, WF_PASS_FUSED | WF_PASS_COUNT,
                                in_window, NULL);
    }
    /* before the repairs and exits, which change the counts and the vehicles a record sums */
    if (records) record_row(c, t, in_window, 1, &row);
    c->rec_in_step = c->rec_summed = 0;
    rc = boundary_after(c, step, in_window, flags, err);
    if (!records) return rc;
    if (!rc) return record_out(c, &row, err);
    WfError lost = {0}; /* the step's error is the run's: the row still goes out, as it did before the step */
    record_out(c, &row, &lost);
    return rc;
}

static int corridor_step(void *eng, long step, long max_steps, long *steps, WfError *err)
{
    *steps = 1;
    WfCorridor *c = eng;
    window_is_trip(c, step);
    int nt = wf_governor_threads(&c->gov), parallel = 0, rc = 0, done = 0;
    size_t on_road = 0;
    for (size_t l = 0; l < c->n_lanes; l++) {
        c->ln[l].lane.nthreads = nt, on_road += c->ln[l].veh.n;
        parallel |= wf_lane_threads(c->ln[l].veh.n, c->nthreads) > 1;
    }
    /* only steps that threads could share are timed: a short road steps on one thread whatever the count */
    double t0 = parallel ? wf_wall_now() : 0.0;
    /* records step one at a time here: they read the whole road at the step's start */
    /* a probe cuts windows where it ends, on one process only: split, every rank's windows are the same steps */
    long left = c->pt.p ? LONG_MAX : wf_governor_probe_left(&c->gov);
    long k = wf_window_steps(&c->win.w, step, left < max_steps ? left : max_steps, c->n_steps, c->warm_steps,
                             c->sc->trajectories ? c->traj_every : 0, c->out_every);
    if (k > 1) rc = cor_window(c, step, (int)k, &done, err);
    if (done) *steps = k;
    else if (!rc) rc = c->pt.p ? cor_part_step_once(c, step, err) : step_once(c, step, err);
    if (parallel) wf_governor_done(&c->gov, wf_wall_now() - t0, (double)on_road * (double)*steps, *steps);
    return rc;
}

/* The safety counts of every lane, summed (what the summary and a checkpoint hold); restored, they stay with lane 0. */
static WfSafetyCount *safety_total(WfCorridor *c, int restore)
{
    WfSafetyCount *all = c->pt.p ? &c->pt.safety_all : &c->safety; /* split: every rank's, summed (part_collect) */
    if (restore) {
        for (size_t l = 0; l < c->n_lanes; l++) c->ln[l].lane.safety = l ? (WfSafetyCount){{0}, {0}} : *all;
        return all;
    }
    if (c->pt.p) return all;
    *all = (WfSafetyCount){{0}, {0}};
    for (size_t l = 0; l < c->n_lanes; l++)
        for (size_t g = 0; g < WF_MAX_GROUPS; g++)
            all->steps[g] += c->ln[l].lane.safety.steps[g], all->hits[g] += c->ln[l].lane.safety.hits[g];
    return all;
}

/* Before a checkpoint: the trips handed to the output; split across processes, the whole road onto rank 0. */
static int corridor_flush(void *eng, WfError *err)
{
    WfCorridor *c = eng;
    int rc = c->pt.p ? cor_part_collect(c, err) : 0;
    return rc ? rc : flush_trips(c, err);
}

/* The vehicles still on the road: their window totals count, their trips are reported as unfinished. */
static int corridor_close(void *eng, WfError *err)
{
    WfCorridor *c = eng;
    int rc = c->pt.p ? cor_part_collect(c, err) : 0;
    if (rc || (c->pt.p && c->pt.p->rank)) return rc; /* split across processes: rank 0 alone sums */
    rc = flush_trips(c, err);
    for (size_t l = 0; l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        for (size_t k = 0; !rc && k < ln->veh.n; k++)
            rc = cor_finish_vehicle(c, ln, wf_corridor_slot(&ln->veh, k), NAN, 0, err);
    }
    if (!rc) rc = flush_trips(c, err);
    summarize(c);
    c->sim->summary.lane_changes = c->lk.total.changes, c->sim->summary.cut_ins = c->lk.total.cut_ins;
    WfLane all = c->ln[0].lane;
    all.safety = *safety_total(c, 0);
    wf_lane_safety_summary(&all, &c->sim->summary);
    return rc;
}

const WfCorridor *wf_sim_corridor(const WfSim *sim) { return sim->b == &wf_boundary_open ? sim->eng : NULL; }

const WfCorridorVehicles *wf_corridor_vehicles(const WfCorridor *c) { return &c->ln[0].veh; }
size_t wf_corridor_n_lanes(const WfCorridor *c) { return c->n_lanes; }
const WfCorridorVehicles *wf_corridor_lane(const WfCorridor *c, size_t l) { return &c->ln[l].veh; }
const WfCorridorCounts *wf_corridor_counts(const WfCorridor *c) { return &c->st.counts; }
const WfDetectors *wf_corridor_detectors(const WfCorridor *c) { return &c->det; }
const WfEdie *wf_corridor_edie(const WfCorridor *c) { return &c->edie; }

WfEdie wf_corridor_edie_lane(const WfEdie *e, int lane, double *scratch)
{
    WfEdie v = *e;
    size_t n = e->nx * e->nt;
    v.n_lanes = 1;
    if (lane >= 0) {
        v.dist_m += (size_t)lane * n, v.time_s += (size_t)lane * n, v.fuel_g += (size_t)lane * n;
        return v;
    }
    if (e->n_lanes == 1) return v;
    v.dist_m = scratch, v.time_s = scratch + n, v.fuel_g = scratch + 2 * n;
    for (size_t a = 0; a < n; a++) {
        double d = 0, t = 0, f = 0;
        for (size_t l = 0; l < e->n_lanes; l++) d += e->dist_m[l * n + a], t += e->time_s[l * n + a], f += e->fuel_g[l * n + a];
        v.dist_m[a] = d, v.time_s[a] = t, v.fuel_g[a] = f;
    }
    return v;
}

static size_t corridor_state(void *eng, WfStateVar *vars, size_t max)
{
    WfCorridor *c = eng;
    for (size_t l = 0; c->win_is_trip && l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        for (size_t k = 0; k < ln->veh.n; k++) window_total_out(c, ln, wf_corridor_slot(&ln->veh, k));
    }
    WfCorridorVehicles *vh = &c->ln[0].veh;
    size_t cap = vh->cap, nl = c->n_lanes, k = 0, nd = c->det.n_int * c->det.n_det;
    size_t ne = nl * c->edie.nx * c->edie.nt;
    size_t ncx = c->edie.nx * c->sc->n_classes;
#define VAR(nm, ptr, count)                                                                          \
    do {                                                                                             \
        if (k < max)                                                                                 \
            vars[k] = (WfStateVar){.name = (nm), .data = (void *)(ptr), .size = (size_t)(count) * sizeof *(ptr)}; \
        k++;                                                                                         \
    } while (0)
    VAR("scalars", &c->st, 1);
    /* each lane's buffer indices: lane 0's as "first" and "n", lane l's as "firstL" and "nL" */
    static const char *const firsts[WF_MAX_LANES] = {"first", "first1", "first2", "first3", "first4", "first5",
                                                     "first6", "first7"};
    static const char *const counts[WF_MAX_LANES] = {"n", "n1", "n2", "n3", "n4", "n5", "n6", "n7"};
    for (size_t l = 0; l < nl; l++) {
        VAR(firsts[l], &c->ln[l].veh.first, 1);
        VAR(counts[l], &c->ln[l].veh.n, 1);
    }
#define SAVE_SLOTS(nm, field, stepped) VAR(nm, c->ln[0].field, nl * cap);
    SAVED_SLOT_ARRAYS(SAVE_SLOTS)
#undef SAVE_SLOTS
    VAR("params", vh->params, nl * cap * c->pstride);
    if (c->sstride) VAR("controller_state", vh->state, nl * cap * c->sstride);
    VAR("queue_t", c->queue_t, c->n_lanes * c->q_cap);
    if (nd) {
        VAR("det_count", c->det.count, nd);
        VAR("det_sum_v", c->det.sum_v_mps, nd);
        VAR("det_sum_inv_v", c->det.sum_inv_v_spm, nd);
        VAR("det_occupied", c->det.occupied_s, nd);
    }
    VAR("edie_dist", c->edie.dist_m, ne);
    VAR("edie_time", c->edie.time_s, ne);
    VAR("edie_fuel", c->edie.fuel_g, ne);
    VAR("edie_class_dist", c->edie.class_dist_m, ncx);
    VAR("edie_class_fuel", c->edie.class_fuel_g, ncx);
    if (c->ln[0].lane.safe) VAR("safety", safety_total(c, 0), 1); /* absent without a safety filter */
    if (nl > 1) {
        VAR("lanes", &c->lk, 1);
        VAR("lane_rows", c->lane_rows, c->lane_rows_max * c->lane_row_len);
    }
#undef VAR
    return k;
}

static int corridor_restored(void *eng, WfError *err)
{
    WfCorridor *c = eng;
    const WfScenario *sc = c->sc;
    const CorridorRunState *st = &c->st;
    const WfCorridorCounts *n = &st->counts;
    const char *bad = NULL;
    int64_t on_road = 0;
    for (size_t l = 0; l < c->n_lanes; l++) {
        const WfCorridorVehicles *vh = &c->ln[l].veh;
        if (vh->first >= vh->cap || vh->n > vh->cap) bad = "vehicle buffer indices";
        for (size_t k = 0; !bad && k < vh->n; k++) {
            size_t s = wf_corridor_slot(vh, k);
            if (vh->class_id[s] >= sc->n_classes || vh->group_id[s] >= sc->n_groups) bad = "class or driver group";
        }
        on_road += (int64_t)vh->n;
    }
    if (bad) {
    } else if (st->steps_done < 0 || st->steps_done > c->n_steps) bad = "step";
    else if (n->arrived != n->entered + n->queued || n->entered != n->exited + n->off_ramp + on_road) bad = "counters";
    for (size_t l = 0; !bad && l < c->n_lanes; l++) {
        const struct CorEntrance *en = &st->lane[l];
        if (en->q_head >= c->q_cap || en->queued < 0 || (uint64_t)en->queued > c->q_cap) bad = "entrance queue";
        else if (en->arrived != en->entered + en->queued) bad = "counters";
        else if (en->have_cand && (en->cand_class >= sc->n_classes || en->cand_group >= sc->n_groups)) bad = "candidate";
    }
    if (bad)
        return wf_err(err, WF_EINPUT, "%s: the restored state does not fit this corridor (%s at step %ld)", sc->path,
                      bad, st->steps_done);
    safety_total(c, 1);
    window_gates(c, 0); /* window_is_trip tests the restored road */
    if (c->pt.p) cor_part_restored(c);
    c->fault_slot = -1;
    c->n_trips = 0;
    return 0;
}

/* Group g's vehicles lane after lane, each lane front first; a lane's front vehicle follows the step's front leader
 * (cor_front_leader). */
static size_t corridor_group(void *eng, size_t g, WfGroupVisit fn, void *ctx)
{
    WfCorridor *c = eng;
    size_t k = 0;
    for (size_t l = 0; l < c->n_lanes; l++) {
        const CorLane *ln = &c->ln[l];
        const WfCorridorVehicles *vh = &ln->veh;
        const double *x = vh->x_m, *v = vh->v_mps, *len = ln->lane.class_length_m;
        const uint16_t *gid = vh->group_id;
        size_t n = vh->n, cap = vh->cap, top = vh->first + n; /* road order: slots top - 1 down to first, mod cap */
        if (!fn) { /* a count only (checked before every visit): the slots' groups in at most two runs */
            size_t wrap = top > cap ? top - cap : 0;
            uint16_t g16 = (uint16_t)g; /* g < WF_MAX_GROUPS */
            uint32_t m = 0;
#pragma omp simd reduction(+ : m)
            for (size_t s = vh->first; s < top - wrap; s++) m += gid[s] == g16;
#pragma omp simd reduction(+ : m)
            for (size_t s = 0; s < wrap; s++) m += gid[s] == g16;
            k += m;
            continue;
        }
        WfLead front = cor_front_leader(c, l);
        /* the front vehicle, then each vehicle behind its leader (the slot after it, wrapping) */
        for (size_t r = 0, s = n ? wf_corridor_slot(vh, 0) : 0, p = 0; r < n; r++, p = s, s = s ? s - 1 : cap - 1) {
            if (gid[s] != g) continue;
            double gap, vl;
            if (r > 0) {
                gap = x[p] - len[vh->class_id[p]] - x[s], vl = v[p];
            } else if (front.free_gap_m > 0.0) {
                gap = front.free_gap_m, vl = v[s];
            } else {
                gap = front.rear_m - x[s], vl = front.v_mps;
            }
            fn(ctx, k, vh->state + s * c->sstride, v[s], vl, gap);
            k++;
        }
    }
    return k;
}

const WfBoundary wf_boundary_open = {.kind = "corridor", .create = corridor_create, .destroy = corridor_destroy,
                                     .step = corridor_step, .flush = corridor_flush, .close = corridor_close,
                                     .state = corridor_state, .restored = corridor_restored,
                                     .group = corridor_group, .lanes = corridor_lanes};
