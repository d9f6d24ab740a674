/* The step loop. Every phase is a loop over vehicles in which iteration i writes only vehicle i's entries
 * and reads values fixed for the phase (the previous phase's arrays), so the OpenMP loops are race-free and
 * the results do not depend on the number of threads. Small fleets run serially (OpenMP overhead dominates). */
#include "wavefuel/engine.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wavefuel/rng.h"
#include "par.h"

#define PAR_MIN 4096 /* vehicles below which loops run on one thread */
#define EBLOCK  512  /* energy evaluation gather block */
#define IBLOCK  1024 /* integration block */
#define FBLOCK  256  /* fused-step block (even: noise pairs stay whole) */

struct WfSim {
    const WfScenario   *sc; /* borrowed */
    WfFleet            *f;
    const WfIntegrator *ig;
    long     n_steps, out_every, traj_every, warm_steps, steps_done;
    int64_t  overlaps;
    int      nthreads;
    double  *stat_scratch;
    double  *noise;         /* standard normal draw of each vehicle for the current step; NULL without noise */
    WfOde   *ode;           /* SUNDIALS integrator, or NULL for a fixed-step scheme */
    double  *xold, *vold, *fuel_step, *vplus; /* ODE path only */
    int      repaired;      /* the last step repaired an overlap */
    double   phase_s[WF_N_PHASES]; /* wall time per phase */
    double  *bound_x, *bound_v;    /* fused step: each chunk's first vehicle at the step's start */
    double   checkpoint_every_s;
    long     fault_vehicle;         /* first vehicle with a non-finite state, or -1 */
    struct {                       /* scalars of the state, packed for wf_sim_state */
        int64_t steps_done, overlaps, n_sd, repaired;
        double  sd_sum;
    } ck;
    int      stateful;      /* some driver model keeps per-vehicle memory */
    double   sd_sum;
    long     n_sd;
    double   wall_s;
    WfSummary summary;
};

static double wall_now(void)
{
#ifdef _OPENMP
    return omp_get_wtime();
#else
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
#endif
}

static int team_size(void)
{
#ifdef _OPENMP
    return omp_get_num_threads();
#else
    return 1;
#endif
}

static int thread_id(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

static int ode_rhs(void *ctx, double t, const double *x, const double *v, double *xdot, double *vdot, double *fuel);

void wf_sim_destroy(WfSim **ps)
{
    if (!ps || !*ps) return;
    WfSim *s = *ps;
    wf_fleet_destroy(&s->f);
    free(s->stat_scratch);
    free(s->noise);
    wf_ode_destroy(&s->ode);
    free(s->xold);
    free(s->vold);
    free(s->bound_x);
    free(s->bound_v);
    free(s->fuel_step);
    free(s->vplus);
    free(s);
    *ps = NULL;
}

int wf_sim_create(const WfScenario *sc, WfSim **out, WfError *err)
{
    *out = NULL;
    /* Corridors have their own engine (src/corridor.c): refuse rather than simulate a ring of nominal vehicles. */
    if (sc->corridor)
        return wf_err(err, WF_EINPUT, "%s: road.type corridor runs with `wavefuel run` (src/corridor.c); the ring "
                      "engine, and so `wavefuel sweep`, does not take corridors yet", sc->path);
    WfSim *s = calloc(1, sizeof *s);
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    s->sc = sc;
    int rc = sc->adaptive ? 0 : wf_integrator_find(sc->integrator, &s->ig, err);
    if (!rc) rc = wf_fleet_create(sc, &s->f, err);
    if (rc) {
        wf_sim_destroy(&s);
        return rc;
    }
    s->n_steps = wf_scenario_n_steps(sc);
    s->out_every = wf_scenario_output_every(sc);
    s->traj_every = wf_scenario_trajectory_every(sc);
    s->warm_steps = (long)ceil(sc->warmup_s / sc->dt_s - 1e-9);
    s->fault_vehicle = -1;
#ifdef _OPENMP
    s->nthreads = omp_get_max_threads();
#else
    s->nthreads = 1;
#endif
    s->stat_scratch = malloc(wf_stats_scratch_size(s->f->n, s->f->n_classes) * sizeof(double));
    int noisy = 0;
    for (size_t g = 0; g < sc->n_groups; g++) noisy |= sc->groups[g].noise_mps2 > 0.0;
    if (noisy) s->noise = malloc((s->f->n + 1) * sizeof(double));
    s->bound_x = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    s->bound_v = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    if (!s->stat_scratch || (noisy && !s->noise) || !s->bound_x || !s->bound_v) {
        wf_sim_destroy(&s);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    for (size_t g = 0; g < sc->n_groups; g++) s->stateful |= sc->groups[g].model->state_size > 0;
    if (sc->adaptive) {
        size_t n = s->f->n;
        WfOdeConfig cfg = sc->solver;
        cfg.fixed_step_s = sc->dt_s / cfg.rk4_substeps;
        s->xold = malloc(n * sizeof(double));
        s->vold = malloc(n * sizeof(double));
        s->fuel_step = malloc(n * sizeof(double));
        s->vplus = malloc(n * sizeof(double));
        if (!s->xold || !s->vold || !s->fuel_step || !s->vplus) rc = wf_err(err, WF_ESYS, "out of memory");
        if (!rc) rc = wf_ode_create(&cfg, n, sc->road.length_m, ode_rhs, s, 0.0, s->f->x_m, s->f->v_mps, &s->ode, err);
        if (rc) {
            wf_sim_destroy(&s);
            return rc;
        }
    }
    *out = s;
    return 0;
}

/* Phase 1: acceleration noise. One Philox draw gives two normals (Box-Muller): vehicles 2p and 2p+1 share the
 * draw keyed by (seed, pair p, step), which halves the cost of the transcendental functions. */
static void phase_noise(WfSim *s, long step)
{
    if (!s->noise) return;
    size_t n = s->f->n, pairs = (n + 1) / 2;
    double *z = s->noise;
    uint64_t seed = s->sc->seed;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, pairs, z, seed, step)",
    for (size_t p = 0; p < pairs; p++) {
        double r[2];
        wf_rng_normal2(seed, WF_RNG_NOISE, p, (uint64_t)step, r);
        z[2 * p] = r[0];
        if (2 * p + 1 < n) z[2 * p + 1] = r[1];
    });
}

/* Phase 2: inputs at the step's start (gap to the leader, leader speed, grade) and the acceleration, driver
 * group by driver group (no branching on model names in the loop). */
/* One vehicle's applied acceleration: model + noise, clipped to the group's limits, optionally to the class's
 * feasible a_max, and to the speed limit. Shared by the multi-pass and the fused step so both give the same bits. */
static inline double accel_one(const WfScenario *sc, const WfDriverGroup *grp, const void *params,
                               const void *state, const WfVehicleClass *vc, double gi, double vi, double vli,
                               double thi, double zi)
{
    double dmax = grp->decel_max_mps2, vlim = sc->road.speed_limit_mps;
    double ai = grp->model->accel(params, state, gi, vi, vli);
    if (grp->noise_mps2 > 0.0) ai += grp->noise_mps2 * zi;
    ai = ai > grp->accel_max_mps2 ? grp->accel_max_mps2 : ai;
    ai = ai < -dmax ? -dmax : ai;
    if (grp->clip_feasible) {
        double am = vc->model->a_max(vc->params, vi, thi);
        ai = ai > am ? am : ai;
    }
    /* Speed limit: never accelerate past it within the step. */
    double to_limit = (vlim - vi) / sc->dt_s;
    return ai > to_limit && isfinite(vlim) ? (to_limit > -dmax ? to_limit : -dmax) : ai;
}

static void phase_accel(WfSim *s, const double *x, const double *v)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    const WfRoad *road = &sc->road;
    size_t n = f->n;
    double L = road->length_m;
    const double *z = s->noise, *len = f->length_m;
    double *gap = f->gap_m, *vl = f->v_lead_mps, *th = f->theta_rad, *a = f->a_mps2;
    uint32_t *seg = f->grade_seg;
    const uint16_t *cid = f->class_id;
    for (size_t g = 0; g < f->n_groups; g++) {
        const WfDriverGroup *grp = &sc->groups[g];
        const uint32_t *mem = f->group_member[g];
        const unsigned char *params = f->group_params[g], *state = f->group_state[g];
        size_t cnt = f->group_n[g], psz = grp->model->param_size, ssz = grp->model->state_size;
        WF_PAR_FOR(cnt >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, L, road, x, len, v, gap, vl, th, seg, cnt, mem, params, state, psz, ssz, grp, cid, a, sc, z)",
        for (size_t k = 0; k < cnt; k++) {
            size_t i = mem[k];
            /* The leader of the last vehicle is vehicle 0, one lap ahead. */
            size_t lead = i + 1 < n ? i + 1 : 0;
            double xl = x[lead] + (i + 1 < n ? 0.0 : L);
            double gi = xl - len[lead] - x[i], vi = v[i], vli = v[lead];
            double thi = wf_road_grade(road, x[i], &seg[i]);
            gap[i] = gi, vl[i] = vli, th[i] = thi;
            a[i] = accel_one(sc, grp, params + k * psz, ssz ? state + k * ssz : NULL, &sc->classes[cid[i]].vc, gi, vi,
                             vli, thi, z ? z[i] : 0.0);
        });
    }
}

/* Phase 3: fuel rate and feasibility flag of every vehicle, class by class through the array kernel. */
static void phase_energy(WfSim *s, const double *v, const double *a)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    for (size_t c = 0; c < f->n_classes; c++) {
        const WfVehicleClass *vc = &sc->classes[c].vc;
        const uint32_t *mem = f->class_member[c];
        size_t cnt = f->class_n[c], nblk = (cnt + EBLOCK - 1) / EBLOCK;
        const double *th = f->theta_rad;
        double *fr = f->fuel_rate_gps;
        uint8_t *flag = f->flag;
        /* Gather buffers on the stack of whichever thread runs the block (16.5 kB): no per-thread indexing, which
         * would break when the engine runs inside another OpenMP team (a sweep worker has a thread number of its
         * own while this loop runs serially in it). */
        WF_PAR_FOR(cnt >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(nblk, cnt, mem, vc, v, a, th, fr, flag)",
        for (size_t b = 0; b < nblk; b++) {
            double bv[EBLOCK], ba[EBLOCK], bt[EBLOCK], bf[EBLOCK];
            uint8_t bfl[EBLOCK];
            size_t lo = b * EBLOCK, m = cnt - lo < EBLOCK ? cnt - lo : EBLOCK;
            for (size_t k = 0; k < m; k++) {
                size_t i = mem[lo + k];
                bv[k] = v[i], ba[k] = a[i], bt[k] = th[i];
            }
            vc->model->eval(vc->params, m, bv, ba, bt, 0, bf, bfl);
            for (size_t k = 0; k < m; k++) {
                size_t i = mem[lo + k];
                fr[i] = bf[k];
                flag[i] = bfl[k];
            }
        });
    }
}

/* Phase 4: statistics over the step (left-point rule: values at the step's start held for dt), integration,
 * then the statistics that need the new state (distance, passages, stops). With a SUNDIALS integrator the fuel
 * of the step is its exact integral (quadrature) instead of the left-point rule. */
static inline void stats_before(WfFleet *f, const WfScenario *sc, size_t i, double ai, double fuel_rate_gps,
                                uint8_t flag, int in_window, int left_point_fuel)
{
    double dt = sc->dt_s, vi = f->v_mps[i];
    uint8_t mode = f->mode[i];
    int braking = ai < -sc->hard_brake_mps2;
    if (in_window) {
        if (left_point_fuel) f->fuel_g[i] += fuel_rate_gps * dt;
        f->time_stopped_s[i] += vi < sc->v_stop_mps ? dt : 0.0;
        f->sum_v[i] += vi;
        f->sum_v2[i] += vi * vi;
        f->sum_a[i] += ai;
        f->sum_a2[i] += ai * ai;
        f->infeasible_steps[i] += flag == 1;
        f->hard_brakes[i] += braking && !(mode & WF_MODE_BRAKING);
    }
    /* A non-finite acceleration or fuel rate would be laundered by the integrator (NaN fails v >= 0 and looks
     * like a stop): flag it so the step ends in a numerical-fault error. */
    int fault = !isfinite(ai) || !isfinite(fuel_rate_gps);
    f->mode[i] = (uint8_t)((mode & ~WF_MODE_BRAKING) | (braking ? WF_MODE_BRAKING : 0) | (fault ? WF_MODE_FAULT : 0));
}

/* floor(q) as an integer without the libm call (floor is not inlined on baseline x86-64): truncate, then step
 * down for negative non-integers. |q| stays far below 2^63 (positions / ring length). */
static inline int64_t lap_index(double q)
{
    int64_t k = (int64_t)q;
    return k - (q < (double)k);
}

static inline void stats_after(WfFleet *f, const WfScenario *sc, size_t i, double xold, int in_window)
{
    double vi = f->v_mps[i], L = sc->road.length_m;
    uint8_t mode = f->mode[i];
    if ((mode & WF_MODE_MOVING) && vi < sc->v_stop_mps) {
        mode &= (uint8_t)~WF_MODE_MOVING;
        if (in_window) f->stops[i]++;
    } else if (!(mode & WF_MODE_MOVING) && vi > sc->v_go_mps) {
        mode |= WF_MODE_MOVING;
    }
    f->mode[i] = mode;
    if (in_window) {
        f->dist_m[i] += f->x_m[i] - xold;
        f->laps[i] += lap_index(f->x_m[i] / L) - lap_index(xold / L);
    }
}

static void phase_advance(WfSim *s, int in_window)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    size_t n = f->n, nblk = (n + IBLOCK - 1) / IBLOCK;
    double dt = sc->dt_s;
    const WfIntegrator *ig = s->ig;
    /* Blocks keep the old positions in cache between the integration and the statistics that need them. */
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(f, sc, nblk, n, dt, ig, in_window)",
    for (size_t b = 0; b < nblk; b++) {
        size_t lo = b * IBLOCK, m = n - lo < IBLOCK ? n - lo : IBLOCK;
        double xold[IBLOCK];
        for (size_t k = 0; k < m; k++) {
            xold[k] = f->x_m[lo + k];
            stats_before(f, sc, lo + k, f->a_mps2[lo + k], f->fuel_rate_gps[lo + k], f->flag[lo + k], in_window, 1);
        }
        ig->step(m, dt, f->x_m + lo, f->v_mps + lo, f->a_mps2 + lo);
        for (size_t k = 0; k < m; k++) stats_after(f, sc, lo + k, xold[k], in_window);
    });
}

/* One block of the fused step (see step_fused). last_in_chunk: the block's last leader is (xs, vs). */
static void fused_block(WfSim *s, size_t lo, size_t m, int last_in_chunk, double xs, double vs, long step,
                        int in_window)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    const WfRoad *road = &sc->road;
    double a[FBLOCK], th[FBLOCK], fr[FBLOCK], gap[FBLOCK], vl[FBLOCK], z[FBLOCK], xold[FBLOCK];
    double gv[FBLOCK], ga[FBLOCK], gt[FBLOCK], gf[FBLOCK];
    uint8_t fl[FBLOCK], gfl[FBLOCK];
    uint32_t idx[FBLOCK];
    double *x = f->x_m + lo, *v = f->v_mps + lo;
    if (s->noise) {
        /* The block starts at an even index, so its pairs are whole: same draws as phase_noise. */
        for (size_t k = 0; k < m; k += 2) {
            double r[2];
            wf_rng_normal2(sc->seed, WF_RNG_NOISE, (lo + k) / 2, (uint64_t)step, r);
            z[k] = r[0];
            if (k + 1 < m) z[k + 1] = r[1];
        }
    }
    for (size_t k = 0; k < m; k++) {
        size_t i = lo + k;
        int edge = last_in_chunk && k + 1 == m;
        double xl = edge ? xs : x[k + 1], vli = edge ? vs : v[k + 1];
        double len_l = f->length_m[i + 1 < f->n ? i + 1 : 0];
        size_t g = f->group_id[i];
        const WfDriverGroup *grp = &sc->groups[g];
        size_t psz = grp->model->param_size, ssz = grp->model->state_size;
        const unsigned char *params = f->group_params[g] + (size_t)f->slot[i] * psz;
        unsigned char *state = ssz ? f->group_state[g] + (size_t)f->slot[i] * ssz : NULL;
        gap[k] = xl - len_l - x[k];
        vl[k] = vli;
        th[k] = wf_road_grade(road, x[k], &f->grade_seg[i]);
        a[k] = accel_one(sc, grp, params, state, &sc->classes[f->class_id[i]].vc, gap[k], v[k], vli, th[k],
                         s->noise ? z[k] : 0.0);
    }
    if (f->n_classes == 1) {
        const WfVehicleClass *vc = &sc->classes[0].vc;
        vc->model->eval(vc->params, m, v, a, th, 0, fr, fl);
    } else {
        for (size_t c = 0; c < f->n_classes; c++) {
            size_t cnt = 0;
            for (size_t k = 0; k < m; k++)
                if (f->class_id[lo + k] == c) idx[cnt++] = (uint32_t)k;
            if (!cnt) continue;
            for (size_t j = 0; j < cnt; j++) gv[j] = v[idx[j]], ga[j] = a[idx[j]], gt[j] = th[idx[j]];
            const WfVehicleClass *vc = &sc->classes[c].vc;
            vc->model->eval(vc->params, cnt, gv, ga, gt, 0, gf, gfl);
            for (size_t j = 0; j < cnt; j++) fr[idx[j]] = gf[j], fl[idx[j]] = gfl[j];
        }
    }
    if (s->stateful) {
        for (size_t k = 0; k < m; k++) {
            size_t i = lo + k, g = f->group_id[i];
            const WfCfModel *cm = sc->groups[g].model;
            if (!cm->state_size || !cm->update_state) continue;
            cm->update_state(f->group_params[g] + (size_t)f->slot[i] * cm->param_size,
                             f->group_state[g] + (size_t)f->slot[i] * cm->state_size, gap[k], v[k], vl[k], sc->dt_s);
        }
    }
    for (size_t k = 0; k < m; k++) {
        xold[k] = x[k];
        stats_before(f, sc, lo + k, a[k], fr[k], fl[k], in_window, 1);
    }
    s->ig->step(m, sc->dt_s, x, v, a);
    for (size_t k = 0; k < m; k++) stats_after(f, sc, lo + k, xold[k], in_window);
}

/* A whole fixed-step time step in one pass over the vehicles, for steps that record nothing: per block of
 * FBLOCK vehicles, noise, inputs, accelerations, fuel, controller memory, statistics and integration, with the
 * block's intermediate values in local arrays instead of fleet-wide ones (far less memory traffic at large N).
 * Positions and speeds are updated in place. That is race-free and order-free because every vehicle reads only
 * its leader's values from the step's start: within a thread's chunk, vehicle i's leader i + 1 is updated after i;
 * the leader of a chunk's last vehicle is the first vehicle of the next chunk (of chunk 0 for the last vehicle,
 * one lap ahead), whose old position and speed are saved before any update. Same arithmetic as the multi-pass
 * step (the same inline functions), so a vehicle's result does not depend on which path or thread ran it. */
static void step_fused(WfSim *s, long step, int in_window)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    size_t n = f->n, nblk = (n + FBLOCK - 1) / FBLOCK;
    int nth = n >= PAR_MIN ? s->nthreads : 1;
    if ((size_t)nth > nblk) nth = (int)nblk;
    double *bx = s->bound_x, *bv = s->bound_v;
    if (nth == 1) {
        /* Small fleets: no OpenMP region at all (even a one-thread region costs runtime calls every step). */
        bx[0] = f->x_m[0];
        bv[0] = f->v_mps[0];
        for (size_t b = 0; b < nblk; b++) {
            size_t lo = b * FBLOCK, m = n - lo < FBLOCK ? n - lo : FBLOCK;
            fused_block(s, lo, m, lo + m == n, bx[0] + sc->road.length_m, bv[0], step, in_window);
        }
        return;
    }
#pragma omp parallel num_threads(nth) default(none) shared(s, f, sc, n, nblk, bx, bv, step, in_window)
    {
        /* The team may be smaller than asked (nested inside a sweep worker, or a thread limit): chunk by the
         * team actually running. */
        int t = thread_id(), nt = team_size();
        size_t b0 = nblk * (size_t)t / (size_t)nt, b1 = nblk * (size_t)(t + 1) / (size_t)nt;
        size_t lo_t = b0 * FBLOCK, hi_t = b1 * FBLOCK < n ? b1 * FBLOCK : n;
        bx[t] = f->x_m[lo_t];
        bv[t] = f->v_mps[lo_t];
#pragma omp barrier
        /* Leader of this chunk's last vehicle: the next chunk's first, saved (plus one lap after the last). */
        int tn = t + 1 < nt ? t + 1 : 0;
        double xs = bx[tn] + (t + 1 < nt ? 0.0 : sc->road.length_m), vs = bv[tn];
        for (size_t b = b0; b < b1; b++) {
            size_t lo = b * FBLOCK, m = n - lo < FBLOCK ? n - lo : FBLOCK;
            fused_block(s, lo, m, lo + m == hi_t, xs, vs, step, in_window);
        }
    }
}

/* The right-hand side for the SUNDIALS integrators: the same car-following phase as the fixed-step schemes,
 * evaluated at (x, v). Speeds never go negative: dx/dt = max(v, 0), and a vehicle at rest that is told to
 * brake stays at rest (dv/dt = 0); the fuel rate uses the acceleration actually applied. Noise and controller
 * memory are held for the current time step (piecewise constant), so the function is pure in (t, x, v). */
static int ode_rhs(void *ctx, double t, const double *x, const double *v, double *xdot, double *vdot, double *fuel)
{
    (void)t;
    WfSim *s = ctx;
    WfFleet *f = s->f;
    size_t n = f->n;
    phase_accel(s, x, v);
    const double *a = f->a_mps2;
    int bad = 0;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, v, a, xdot, vdot) reduction(| : bad)",
    for (size_t i = 0; i < n; i++) {
        double vi = v[i] > 0.0 ? v[i] : 0.0;
        xdot[i] = vi;
        vdot[i] = (v[i] <= 0.0 && a[i] < 0.0) ? 0.0 : a[i];
        bad |= !isfinite(vdot[i]) || !isfinite(x[i]);
    });
    if (bad) return -1; /* a non-finite state is not recoverable by a smaller step */
    if (fuel) {
        /* energy at the clamped speed and applied acceleration: s->vplus / vdot */
        double *vp = s->vplus;
        WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, v, vp)",
        for (size_t i = 0; i < n; i++) vp[i] = v[i] > 0.0 ? v[i] : 0.0;);
        phase_energy(s, vp, vdot);
        memcpy(fuel, f->fuel_rate_gps, n * sizeof *fuel);
    }
    return 0;
}

/* Phase 4 with a SUNDIALS integrator: the solver advances the whole state over the step. */
static int phase_advance_ode(WfSim *s, double t_next, int in_window, WfError *err)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    size_t n = f->n;
    double *xold = s->xold, *vold = s->vold, *fs = s->fuel_step;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(f, sc, n, xold, vold, in_window)",
    for (size_t i = 0; i < n; i++) {
        xold[i] = f->x_m[i];
        vold[i] = f->v_mps[i];
        stats_before(f, sc, i, f->a_mps2[i], f->fuel_rate_gps[i], f->flag[i], in_window, 0);
    });
    int rc = wf_ode_advance(s->ode, t_next, f->x_m, f->v_mps, fs, err);
    if (rc) return rc;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(f, sc, n, xold, fs, in_window)",
    for (size_t i = 0; i < n; i++) {
        if (in_window) f->fuel_g[i] += fs[i];
        stats_after(f, sc, i, xold[i], in_window);
    });
    return 0;
}

/* Phase 5: no gap may be negative. A vehicle that would overlap its leader (noise, or a model that brakes
 * too late) is put at gap 0 behind it and stopped; each such event is counted. Rare, so it is found in
 * parallel and repaired serially, going backwards so a repaired leader is seen by its follower. */
static long phase_overlaps(WfSim *s, int in_window)
{
    WfFleet *f = s->f;
    size_t n = f->n;
    double L = s->sc->road.length_m;
    const double *x = f->x_m, *v = f->v_mps, *len = f->length_m;
    const uint8_t *mode = f->mode;
    long bad = 0, nonfinite = 0;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, v, len, L, mode) reduction(+ : bad, nonfinite)",
    for (size_t i = 0; i < n; i++) {
        size_t lead = i + 1 < n ? i + 1 : 0;
        double xl = x[lead] + (i + 1 < n ? 0.0 : L);
        bad += xl - len[lead] - x[i] < 0.0;
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
    if (!bad || n < 2) return 0;
    long total = 0;
    for (int pass = 0; pass < 3; pass++) {
        long fixed = 0;
        for (size_t j = n; j-- > 0;) {
            size_t lead = j + 1 < n ? j + 1 : 0;
            double xl = f->x_m[lead] + (j + 1 < n ? 0.0 : L);
            if (xl - f->length_m[lead] - f->x_m[j] < 0.0) {
                double x_new = xl - f->length_m[lead];
                /* The step's distance and lap count were taken before the repair: correct them. */
                if (in_window) {
                    f->dist_m[j] += x_new - f->x_m[j];
                    f->laps[j] += lap_index(x_new / L) - lap_index(f->x_m[j] / L);
                }
                f->x_m[j] = x_new;
                f->v_mps[j] = 0.0;
                fixed++;
            }
        }
        s->overlaps += fixed;
        total += fixed;
        if (!fixed) break;
    }
    return total;
}

/* Controllers with memory advance once per step, with the inputs of that step (called after the step's
 * accelerations are computed from the old state, before integration changes the speeds). */
static void phase_controller_state(WfSim *s)
{
    WfFleet *f = s->f;
    for (size_t g = 0; g < f->n_groups; g++) {
        const WfCfModel *m = s->sc->groups[g].model;
        if (!m->state_size || !m->update_state) continue;
        size_t cnt = f->group_n[g], psz = m->param_size, ssz = m->state_size;
        const uint32_t *mem = f->group_member[g];
        const unsigned char *params = f->group_params[g];
        unsigned char *state = f->group_state[g];
        const double *gap = f->gap_m, *vl = f->v_lead_mps, *v = f->v_mps;
        double dt = s->sc->dt_s;
        WF_PAR_FOR(cnt >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(cnt, mem, params, state, psz, ssz, m, gap, vl, v, dt)",
        for (size_t k = 0; k < cnt; k++) {
            size_t i = mem[k];
            m->update_state(params + k * psz, state + k * ssz, gap[i], v[i], vl[i], dt);
        });
    }
}

/* The error of a numerical fault: which vehicle, when, its model and the inputs of the step that failed. */
static int numerical_fault(WfSim *s, long step, WfError *err)
{
    const WfFleet *f = s->f;
    size_t i = (size_t)s->fault_vehicle, n = f->n, lead = i + 1 < n ? i + 1 : 0;
    const WfDriverGroup *g = &s->sc->groups[f->group_id[i]];
    return wf_err(err, WF_ESYS,
                  "numerical fault at t = %.9g s: vehicle %zu (driver group '%s', model %s, class %s): a non-finite "
                  "acceleration, fuel rate or state (now x = %g m, v = %g m/s; leader vehicle %zu at v = %g m/s); "
                  "partial results kept",
                  (double)(step + 1) * s->sc->dt_s, i, g->name, g->model->name, s->sc->classes[f->class_id[i]].vc.name,
                  f->x_m[i], f->v_mps[i], lead, f->v_mps[lead]);
}

int wf_sim_run(WfSim *s, const WfOutput *out, WfProgressFn progress, void *pctx, volatile sig_atomic_t *stop,
               WfError *err)
{
    const WfScenario *sc = s->sc;
    int rc = out && out->begin ? out->begin(out->ctx, s, err) : 0;
    if (rc) return rc;
    double t0 = wall_now(), last_progress = t0;
    const char *reason = NULL;
    WfTsRow row;
    long step;
    double last_ckpt = t0;
    for (step = s->steps_done; step <= s->n_steps; step++) {
        double t = (double)step * sc->dt_s;
        double tp = wall_now(), tq;
#define LAP(ph) (tq = wall_now(), s->phase_s[ph] += tq - tp, tp = tq)
        int records = step % s->out_every == 0 || (sc->trajectories && step % s->traj_every == 0);
        if (!s->ode && sc->fused_step && !records && step < s->n_steps) {
            step_fused(s, step, step >= s->warm_steps);
            LAP(WF_PHASE_FUSED);
            s->repaired = phase_overlaps(s, step >= s->warm_steps) > 0;
            LAP(WF_PHASE_INTEGRATION);
            if (s->fault_vehicle >= 0) {
                rc = numerical_fault(s, step, err);
                break;
            }
            s->steps_done = step + 1;
            if (stop && *stop) {
                reason = *stop == SIGTERM ? "interrupted by SIGTERM" : "interrupted by SIGINT";
                break;
            }
            if (s->checkpoint_every_s > 0 && out && out->checkpoint && wall_now() - last_ckpt >= s->checkpoint_every_s) {
                if ((rc = out->checkpoint(out->ctx, s, err))) break;
                last_ckpt = wall_now();
            }
            continue;
        }
        phase_noise(s, step);
        phase_accel(s, s->f->x_m, s->f->v_mps);
        LAP(WF_PHASE_CAR_FOLLOWING);
        phase_energy(s, s->f->v_mps, s->f->a_mps2);
        LAP(WF_PHASE_ENERGY);
        if (step % s->out_every == 0) {
            wf_stats_record(s->f, sc, t, s->overlaps, s->stat_scratch, &row);
            if (step >= s->warm_steps) s->sd_sum += row.v[WF_TS_SD_V], s->n_sd++;
            LAP(WF_PHASE_STATISTICS);
            if (out && out->record && (rc = out->record(out->ctx, s, &row, err))) break;
            LAP(WF_PHASE_OUTPUT);
        }
        if (sc->trajectories && step % s->traj_every == 0 && out && out->trajectory &&
            (rc = out->trajectory(out->ctx, s, t, err)))
            break;
        LAP(WF_PHASE_OUTPUT);
        if (step == s->n_steps) break;
        int in_window = step >= s->warm_steps;
        if (s->ode) {
            /* The right-hand side jumps where the noise or the controller memory changes, and the state jumps
             * at an overlap repair: restart the solver there rather than integrate across the discontinuity. */
            if (step > 0 && (s->noise || s->stateful || s->repaired) &&
                (rc = wf_ode_reinit(s->ode, t, s->f->x_m, s->f->v_mps, err)))
                break;
            if ((rc = phase_advance_ode(s, t + sc->dt_s, in_window, err))) break;
            if (s->stateful) {
                /* Memory advances with the inputs of the step's start, as in the fixed-step path. */
                phase_accel(s, s->xold, s->vold);
                phase_controller_state(s);
            }
        } else {
            phase_controller_state(s);
            phase_advance(s, in_window);
        }
        LAP(WF_PHASE_INTEGRATION);
        s->repaired = phase_overlaps(s, in_window) > 0;
        LAP(WF_PHASE_INTEGRATION);
        if (s->fault_vehicle >= 0) {
            rc = numerical_fault(s, step, err);
            break;
        }

#undef LAP
        s->steps_done = step + 1;
        if (stop && *stop) {
            reason = *stop == SIGTERM ? "interrupted by SIGTERM" : "interrupted by SIGINT";
            break;
        }
        if (s->checkpoint_every_s > 0 && out && out->checkpoint && wall_now() - last_ckpt >= s->checkpoint_every_s) {
            if ((rc = out->checkpoint(out->ctx, s, err))) break;
            last_ckpt = wall_now();
        }
        if (progress && (step & 63) == 0) {
            double now = wall_now();
            if (now - last_progress >= 0.2) {
                progress(pctx, t + sc->dt_s, sc->duration_s, step + 1, s->n_steps);
                last_progress = now;
            }
        }
    }
    s->wall_s = wall_now() - t0;
    long window = s->steps_done - s->warm_steps;
    wf_stats_summary(s->f, sc, s->sd_sum, s->n_sd, window > 0 ? window : 0, s->overlaps, &s->summary);
    if (rc) {
        if (out && out->end) {
            WfError e2 = {0};
            out->end(out->ctx, s, 0, err->msg, &e2);
        }
        return rc;
    }
    int completed = reason == NULL;
    /* An interrupted run can always be resumed from where it stopped. */
    if (!completed && out && out->checkpoint && (rc = out->checkpoint(out->ctx, s, err))) {
        if (out->end) {
            WfError e2 = {0};
            out->end(out->ctx, s, 0, err->msg, &e2);
        }
        return rc;
    }
    if (out && out->end && (rc = out->end(out->ctx, s, completed, reason ? reason : "", err))) return rc;
    if (!completed) return wf_err(err, WF_EINTR, "%s at t = %.6g s: partial results written", reason,
                                  (double)s->steps_done * sc->dt_s);
    return 0;
}

const WfScenario *wf_sim_scenario(const WfSim *s) { return s->sc; }
const WfFleet *wf_sim_fleet(const WfSim *s) { return s->f; }
const WfSummary *wf_sim_summary(const WfSim *s) { return &s->summary; }
double wf_sim_wall_s(const WfSim *s) { return s->wall_s; }
long wf_sim_steps_done(const WfSim *s) { return s->steps_done; }
int wf_sim_threads(const WfSim *s) { return s->nthreads; }

int wf_sim_ode_stats(const WfSim *s, WfOdeStats *st)
{
    if (!s->ode) return 0;
    wf_ode_stats(s->ode, st);
    return 1;
}

const char *const wf_phase_names[WF_N_PHASES] = {"car_following", "energy", "integration", "statistics", "output",
                                                  "fused_step"};

const double *wf_sim_phase_times(const WfSim *s) { return s->phase_s; }

void wf_sim_set_checkpoint_interval(WfSim *s, double wall_s) { s->checkpoint_every_s = wall_s; }

size_t wf_sim_state(WfSim *s, WfStateVar *vars, size_t max)
{
    WfFleet *f = s->f;
    size_t n = f->n, k = 0;
    s->ck.steps_done = s->steps_done;
    s->ck.overlaps = s->overlaps;
    s->ck.n_sd = s->n_sd;
    s->ck.repaired = s->repaired;
    s->ck.sd_sum = s->sd_sum;
#define VAR(nm, ptr, bytes)                                               \
    do {                                                                  \
        if (k < max) vars[k] = (WfStateVar){(nm), (void *)(ptr), (bytes)}; \
        k++;                                                              \
    } while (0)
    VAR("scalars", &s->ck, sizeof s->ck);
    VAR("x", f->x_m, n * sizeof *f->x_m);
    VAR("v", f->v_mps, n * sizeof *f->v_mps);
    VAR("grade_seg", f->grade_seg, n * sizeof *f->grade_seg);
    VAR("dist", f->dist_m, n * sizeof *f->dist_m);
    VAR("fuel", f->fuel_g, n * sizeof *f->fuel_g);
    VAR("time_stopped", f->time_stopped_s, n * sizeof *f->time_stopped_s);
    VAR("sum_v", f->sum_v, n * sizeof *f->sum_v);
    VAR("sum_v2", f->sum_v2, n * sizeof *f->sum_v2);
    VAR("sum_a", f->sum_a, n * sizeof *f->sum_a);
    VAR("sum_a2", f->sum_a2, n * sizeof *f->sum_a2);
    VAR("stops", f->stops, n * sizeof *f->stops);
    VAR("hard_brakes", f->hard_brakes, n * sizeof *f->hard_brakes);
    VAR("infeasible_steps", f->infeasible_steps, n * sizeof *f->infeasible_steps);
    VAR("laps", f->laps, n * sizeof *f->laps);
    VAR("mode", f->mode, n * sizeof *f->mode);
    static const char *const state_names[WF_MAX_GROUPS] = {"ctrl0", "ctrl1", "ctrl2", "ctrl3", "ctrl4", "ctrl5",
                                                           "ctrl6", "ctrl7", "ctrl8", "ctrl9", "ctrl10", "ctrl11",
                                                           "ctrl12", "ctrl13", "ctrl14", "ctrl15"};
    for (size_t g = 0; g < f->n_groups; g++) {
        size_t ssz = s->sc->groups[g].model->state_size;
        if (ssz) VAR(state_names[g], f->group_state[g], f->group_n[g] * ssz);
    }
#undef VAR
    return k;
}

void wf_sim_restored(WfSim *s)
{
    s->steps_done = (long)s->ck.steps_done;
    s->overlaps = s->ck.overlaps;
    s->n_sd = (long)s->ck.n_sd;
    s->repaired = (int)s->ck.repaired;
    s->sd_sum = s->ck.sd_sum;
    /* A SUNDIALS solver restarts from the restored state (as after a noise change): exact with noise or
     * controller memory, where the uninterrupted run restarts at every step too; within tolerance otherwise. */
    if (s->ode) {
        WfError e = {0};
        wf_ode_reinit(s->ode, (double)s->steps_done * s->sc->dt_s, s->f->x_m, s->f->v_mps, &e);
    }
}
