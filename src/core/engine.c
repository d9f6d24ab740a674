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
#include "core/par.h"
#include "core/simd.h"

#define PAR_MIN 4096 /* vehicles below which loops run on one thread */
#define EBLOCK  512  /* energy evaluation gather block */
#define IBLOCK  1024 /* integration block */
#define FBLOCK  256  /* fused-step block, and the noise block (changing it changes the draws) */
/* A record taken by the fused step sums the same blocks as one taken by the multi-pass step (src/observe/stats.c). */
_Static_assert(FBLOCK == WF_STATS_BLOCK, "fused blocks and statistics blocks must coincide");

struct WfSim {
    const WfScenario   *sc; /* borrowed */
    WfFleet            *f;
    const WfIntegrator *ig;
    long     n_steps, out_every, traj_every, warm_steps, steps_done;
    int64_t  overlaps;
    int      nthreads;
    WfStatsBlock *stat_blocks; /* one record's partial sums, block by block */
    int      noisy;         /* some driver group has acceleration noise */
    double  *noise;         /* multi-pass step: each vehicle's standard normal draw for the step; else NULL */
    WfOde   *ode;           /* SUNDIALS integrator, or NULL for a fixed-step scheme */
    double  *xold, *vold, *fuel_step, *vplus; /* ODE path only */
    int      repaired;      /* the last step repaired an overlap */
    double   phase_s[WF_N_PHASES]; /* wall time per phase */
    double  *bound_x, *bound_v;    /* fused step: each chunk's first vehicle at the step's start */
    int     *chunk_flags;          /* fused step: FUSED_* flags raised by each thread's chunk */
    double   checkpoint_every_s;
    long     fault_vehicle;         /* first vehicle with a non-finite state, or -1 */
    struct {                       /* scalars of the state, packed for wf_sim_state */
        int64_t steps_done, overlaps, n_sd, repaired, window_open;
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
    free(s->stat_blocks);
    free(s->chunk_flags);
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
    /* Corridors have their own engine (src/core/corridor.c): refuse rather than simulate a ring of nominal vehicles. */
    if (sc->corridor)
        return wf_err(err, WF_EINPUT, "%s: road.type corridor runs with `wavefuel run` (src/core/corridor.c); the ring "
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
    s->stat_blocks = malloc(wf_stats_scratch_blocks(s->f->n) * sizeof *s->stat_blocks);
    for (size_t g = 0; g < sc->n_groups; g++) s->noisy |= sc->groups[g].noise_mps2 > 0.0;
    int need_noise = s->noisy && s->f->multipass;
    if (need_noise) s->noise = malloc((s->f->n + 1) * sizeof(double));
    s->bound_x = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    s->bound_v = malloc(((size_t)s->nthreads + 1) * sizeof(double));
    s->chunk_flags = calloc((size_t)s->nthreads + 1, sizeof(int));
    if (!s->stat_blocks || (need_noise && !s->noise) || !s->bound_x || !s->bound_v || !s->chunk_flags) {
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

/* Phase 1: acceleration noise. Vehicles are drawn in blocks of FBLOCK (the fused step's blocks): block b's
 * normals at a step come from one Philox stream keyed (seed, b, step) through GSL's ziggurat, so the fused and
 * the multi-pass step see the same draws whatever thread runs the block. */
static void phase_noise(WfSim *s, long step)
{
    if (!s->noise) return;
    size_t n = s->f->n, nblk = (n + FBLOCK - 1) / FBLOCK;
    double *z = s->noise;
    uint64_t seed = s->sc->seed;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, nblk, z, seed, step)",
    for (size_t b = 0; b < nblk; b++) {
        size_t lo = b * FBLOCK, m = n - lo < FBLOCK ? n - lo : FBLOCK;
        wf_rng_normal_block(seed, WF_RNG_NOISE_BLOCK, b, (uint64_t)step, m, z + lo);
    });
}

/* Phase 2: inputs at the step's start (gap to the leader, leader speed, grade) and the acceleration, driver
 * group by driver group (no branching on model names in the loop). */
/* What the engine adds to a model's acceleration: noise, the group's limits, optionally the class's feasible
 * a_max, and the speed limit. Shared by the multi-pass and the fused step so both give the same bits. */
static inline double accel_post(const WfScenario *sc, const WfDriverGroup *grp, const WfVehicleClass *vc,
                                double ai, double vi, double thi, double zi)
{
    double dmax = grp->decel_max_mps2, vlim = sc->road.speed_limit_mps;
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

static inline uint32_t *grade_cache(const WfFleet *f, size_t i) { return f->grade_seg ? &f->grade_seg[i] : NULL; }

static void phase_accel(WfSim *s, const double *x, const double *v)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    const WfRoad *road = &sc->road;
    size_t n = f->n;
    double L = road->length_m;
    const double *z = s->noise;
    double *gap = f->gap_m, *vl = f->v_lead_mps, *th = f->theta_rad, *a = f->a_mps2;
    const uint16_t *cid = f->class_id;
    for (size_t g = 0; g < f->n_groups; g++) {
        const WfDriverGroup *grp = &sc->groups[g];
        const uint32_t *mem = f->group_member[g];
        const unsigned char *params = f->group_params[g], *state = f->group_state[g];
        size_t cnt = f->group_n[g], psz = f->group_param_stride[g], ssz = grp->model->state_size;
        WF_PAR_FOR(cnt >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, L, road, x, v, gap, vl, th, f, cnt, mem, params, state, psz, ssz, grp, cid, a, sc, z)",
        for (size_t k = 0; k < cnt; k++) {
            size_t i = mem[k];
            /* The leader of the last vehicle is vehicle 0, one lap ahead. */
            size_t lead = i + 1 < n ? i + 1 : 0;
            double xl = x[lead] + (i + 1 < n ? 0.0 : L);
            double gi = xl - wf_fleet_length(f, lead) - x[i], vi = v[i], vli = v[lead];
            double thi = wf_road_grade(road, x[i], grade_cache(f, i));
            gap[i] = gi, vl[i] = vli, th[i] = thi;
            double am = grp->model->accel(params + k * psz, ssz ? state + k * ssz : NULL, gi, vi, vli);
            a[i] = accel_post(sc, grp, &sc->classes[cid[i]].vc, am, vi, thi, z ? z[i] : 0.0);
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
 * then the statistics that need the new state (stops). Distances and passages follow from the positions (see
 * WfFleet). With a SUNDIALS integrator the fuel of the step is its exact integral (quadrature) instead of the
 * left-point rule. */
static inline void stats_before(WfFleet *f, const WfScenario *sc, size_t i, double vi, double ai,
                                double fuel_rate_gps, uint8_t flag, int in_window, int left_point_fuel)
{
    uint8_t mode = f->mode[i];
    int braking = ai < -sc->hard_brake_mps2;
    if (in_window) {
        if (left_point_fuel) f->fuel_g[i] += fuel_rate_gps * sc->dt_s;
        f->stopped_steps[i] += vi < sc->v_stop_mps;
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

static inline void stats_after(WfFleet *f, const WfScenario *sc, size_t i, int in_window)
{
    double vi = f->v_mps[i];
    uint8_t mode = f->mode[i];
    if ((mode & WF_MODE_MOVING) && vi < sc->v_stop_mps) {
        mode &= (uint8_t)~WF_MODE_MOVING;
        if (in_window) f->stops[i]++;
    } else if (!(mode & WF_MODE_MOVING) && vi > sc->v_go_mps) {
        mode |= WF_MODE_MOVING;
    }
    f->mode[i] = mode;
}

enum { FUSED_OVERLAP = 1, FUSED_FAULT = 2 };

/* stats_before and stats_after over one block of the fused step, with the same arithmetic per vehicle, written
 * without control flow (bitwise & and | on comparison results, NaN checks by arithmetic) so that the compiler
 * vectorises them; the per-vehicle forms, with their && and ||, do not. */
static inline __attribute__((always_inline)) int stats_before_block(WfFleet *f, const WfScenario *sc, size_t lo, size_t m, const double *restrict v,
                              const double *restrict a, const double *restrict fr, const uint8_t *restrict fl,
                              int in_window)
{
    double dt = sc->dt_s, v_stop = sc->v_stop_mps, hard = -sc->hard_brake_mps2;
    uint8_t *restrict mode = f->mode + lo;
    if (in_window) {
        double *restrict fuel = f->fuel_g + lo, *restrict sv = f->sum_v + lo, *restrict sv2 = f->sum_v2 + lo;
        double *restrict sa = f->sum_a + lo, *restrict sa2 = f->sum_a2 + lo;
        uint32_t *restrict stopped = f->stopped_steps + lo, *restrict infeasible = f->infeasible_steps + lo;
        uint32_t *restrict hb = f->hard_brakes + lo;
#pragma omp simd
        for (size_t k = 0; k < m; k++) {
            fuel[k] += fr[k] * dt;
            stopped[k] += (uint32_t)(v[k] < v_stop);
            sv[k] += v[k];
            sv2[k] += v[k] * v[k];
            sa[k] += a[k];
            sa2[k] += a[k] * a[k];
            infeasible[k] += (uint32_t)(fl[k] == 1);
            hb[k] += (uint32_t)((a[k] < hard) & !(mode[k] & WF_MODE_BRAKING));
        }
    }
    /* x - x is 0 for a finite x and NaN (!= 0) otherwise. */
    int nonfinite = 0;
    for (size_t k = 0; k < m; k++) {
        mode[k] = (uint8_t)((mode[k] & ~WF_MODE_BRAKING) | (a[k] < hard) * WF_MODE_BRAKING);
        nonfinite |= (a[k] - a[k] != 0.0) | (fr[k] - fr[k] != 0.0);
    }
    if (!nonfinite) return 0;
    /* Rare: mark the vehicles (the step then ends in a numerical-fault error naming the first). */
    for (size_t k = 0; k < m; k++)
        if (!isfinite(a[k]) || !isfinite(fr[k])) mode[k] |= WF_MODE_FAULT;
    return FUSED_FAULT;
}

/* lead_len[k]: the length of vehicle k's leader. Returns FUSED_* flags: overlaps inside the block (its last
 * vehicle's is checked once every block has moved) and non-finite states. */
static inline __attribute__((always_inline)) int stats_after_block(WfFleet *f, const WfScenario *sc, size_t lo, size_t m, const double *restrict lead_len,
                             int in_window)
{
    const double *restrict x = f->x_m + lo, *restrict v = f->v_mps + lo;
    uint8_t *restrict mode = f->mode + lo;
    uint32_t *restrict stops = f->stops + lo;
    double v_stop = sc->v_stop_mps, v_go = sc->v_go_mps;
    uint32_t counting = in_window != 0;
    int bad = 0, over = 0;
    for (size_t k = 0; k < m; k++) {
        int moving = mode[k] & WF_MODE_MOVING, stop = moving & (v[k] < v_stop), go = !moving & (v[k] > v_go);
        stops[k] += counting & (uint32_t)stop;
        mode[k] = (uint8_t)((mode[k] & ~WF_MODE_MOVING) | ((moving & !stop) | go) * WF_MODE_MOVING);
    }
    /* x - x is 0 for a finite x and NaN (!= 0) otherwise; integer OR reductions vectorise without reassociating
     * any floating-point sum. */
    for (size_t k = 0; k < m; k++) bad |= (x[k] - x[k] != 0.0) | (v[k] - v[k] != 0.0);
    for (size_t k = 0; k + 1 < m; k++) over |= x[k + 1] - lead_len[k] - x[k] < 0.0;
    return (over ? FUSED_OVERLAP : 0) | (bad ? FUSED_FAULT : 0);
}

static void phase_advance(WfSim *s, int in_window)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    size_t n = f->n, nblk = (n + IBLOCK - 1) / IBLOCK;
    double dt = sc->dt_s;
    const WfIntegrator *ig = s->ig;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(f, sc, nblk, n, dt, ig, in_window)",
    for (size_t b = 0; b < nblk; b++) {
        size_t lo = b * IBLOCK, m = n - lo < IBLOCK ? n - lo : IBLOCK;
        for (size_t k = 0; k < m; k++)
            stats_before(f, sc, lo + k, f->v_mps[lo + k], f->a_mps2[lo + k], f->fuel_rate_gps[lo + k], f->flag[lo + k],
                         in_window, 1);
        ig->step(m, dt, f->x_m + lo, f->v_mps + lo, f->a_mps2 + lo);
        for (size_t k = 0; k < m; k++) stats_after(f, sc, lo + k, in_window);
    });
}

/* Accelerations of the cnt vehicles of driver group g listed (ring order) in one block, from their inputs in
 * the gathered arrays: the model's block kernel when it has one, else accel() per vehicle; then accel_post. The
 * members of a group inside a block have consecutive slots, so their parameters and states are contiguous. */
/* accel_post over a group's vehicles in a block, step by step over the arrays (each step a loop without control
 * flow, so it vectorises): the same operations in the same order per vehicle, so the same bits. */
static inline __attribute__((always_inline)) void accel_post_block(const WfScenario *sc, const WfDriverGroup *grp,
                                                                   size_t cnt, const double *restrict v,
                                                                   const double *restrict th, const double *restrict z,
                                                                   const uint16_t *restrict cls, double *restrict a)
{
    double amax = grp->accel_max_mps2, dmax = grp->decel_max_mps2, noise = grp->noise_mps2;
    double vlim = sc->road.speed_limit_mps, dt = sc->dt_s;
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
    if (isfinite(vlim)) {
#pragma omp simd
        for (size_t j = 0; j < cnt; j++) {
            double to_limit = (vlim - v[j]) / dt, floor_a = to_limit > -dmax ? to_limit : -dmax;
            a[j] = a[j] > to_limit ? floor_a : a[j];
        }
    }
}

static inline __attribute__((always_inline)) void accel_group(const WfSim *s, size_t g, size_t first, size_t cnt,
                                                              const double *gap, const double *v, const double *vl,
                                                              const double *th, const double *z, const uint16_t *cls,
                                                              double *a)
{
    const WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    const WfDriverGroup *grp = &sc->groups[g];
    const WfCfModel *m = grp->model;
    size_t psz = f->group_param_stride[g], ssz = m->state_size;
    const unsigned char *params = f->group_params[g] + wf_fleet_slot(f, first) * psz;
    const unsigned char *state = ssz ? f->group_state[g] + wf_fleet_slot(f, first) * ssz : NULL;
    if (m->accel_block && !ssz) {
        m->accel_block(params, psz, cnt, gap, v, vl, a);
    } else {
        for (size_t j = 0; j < cnt; j++) a[j] = m->accel(params + j * psz, ssz ? state + j * ssz : NULL, gap[j], v[j], vl[j]);
    }
    accel_post_block(sc, grp, cnt, v, th, z, cls, a);
}

/* One block of the fused step (see step_fused). last_in_chunk: the block's last leader is (xs, vs). rec: this
 * step is recorded, so the block's partial sums of the record go there. advance: 0 for the record of the final
 * instant (inputs and record only, no step). Returns FUSED_* flags seen inside the block after the step. */
WF_SIMD_CLONES
static int fused_block(WfSim *s, size_t lo, size_t m, int last_in_chunk, double xs, double vs, long step,
                       int in_window, WfStatsBlock *rec, int advance)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    const WfRoad *road = &sc->road;
    double a[FBLOCK], th[FBLOCK], fr[FBLOCK], gap[FBLOCK], vl[FBLOCK], z[FBLOCK], ll[FBLOCK];
    double gg[FBLOCK], gv[FBLOCK], gl[FBLOCK], gt[FBLOCK], gz[FBLOCK], ga[FBLOCK];
    uint8_t fl[FBLOCK], gfl[FBLOCK];
    uint16_t gc[FBLOCK];
    uint32_t idx[FBLOCK];
    size_t n = f->n;
    double *x = f->x_m + lo, *v = f->v_mps + lo;
    const uint16_t *cid = f->class_id + lo, *gid = f->group_id + lo;
    const double *clen = f->class_length_m;
    if (s->noisy) wf_rng_normal_block(sc->seed, WF_RNG_NOISE_BLOCK, lo / FBLOCK, (uint64_t)step, m, z);
    for (size_t k = 0; k + 1 < m; k++) {
        ll[k] = clen[cid[k + 1]];
        gap[k] = x[k + 1] - ll[k] - x[k];
        vl[k] = v[k + 1];
    }
    {
        /* The block's last vehicle: its leader starts the next block, or the next chunk (saved), or is vehicle 0
         * one lap ahead (saved too: the last vehicle is always last in its chunk). */
        size_t k = m - 1, lead = lo + m < n ? lo + m : 0;
        double xl = last_in_chunk ? xs : x[m];
        vl[k] = last_in_chunk ? vs : v[m];
        gap[k] = xl - clen[f->class_id[lead]] - x[k];
    }
    if (road->n_grade)
        for (size_t k = 0; k < m; k++) th[k] = wf_road_grade(road, x[k], &f->grade_seg[lo + k]);
    else
        memset(th, 0, m * sizeof *th);
    if (f->n_groups == 1) {
        accel_group(s, 0, lo, m, gap, v, vl, th, z, cid, a);
    } else {
        for (size_t g = 0; g < f->n_groups; g++) {
            size_t cnt = 0;
            for (size_t k = 0; k < m; k++)
                if (gid[k] == g) idx[cnt++] = (uint32_t)k;
            if (!cnt) continue;
            for (size_t j = 0; j < cnt; j++) {
                size_t k = idx[j];
                gg[j] = gap[k], gv[j] = v[k], gl[j] = vl[k], gt[j] = th[k], gz[j] = s->noisy ? z[k] : 0.0, gc[j] = cid[k];
            }
            accel_group(s, g, lo + idx[0], cnt, gg, gv, gl, gt, gz, gc, ga);
            for (size_t j = 0; j < cnt; j++) a[idx[j]] = ga[j];
        }
    }
    if (f->n_classes == 1) {
        const WfVehicleClass *vc = &sc->classes[0].vc;
        vc->model->eval(vc->params, m, v, a, th, 0, fr, fl);
    } else {
        for (size_t c = 0; c < f->n_classes; c++) {
            size_t cnt = 0;
            for (size_t k = 0; k < m; k++)
                if (cid[k] == c) idx[cnt++] = (uint32_t)k;
            if (!cnt) continue;
            for (size_t j = 0; j < cnt; j++) gv[j] = v[idx[j]], ga[j] = a[idx[j]], gt[j] = th[idx[j]];
            const WfVehicleClass *vc = &sc->classes[c].vc;
            vc->model->eval(vc->params, cnt, gv, ga, gt, 0, gg, gfl);
            for (size_t j = 0; j < cnt; j++) fr[idx[j]] = gg[j], fl[idx[j]] = gfl[j];
        }
    }
    if (rec) wf_stats_block(m, v, gap, fr, cid, f->n_classes, sc, rec);
    if (!advance) return 0;
    if (s->stateful) {
        for (size_t k = 0; k < m; k++) {
            size_t i = lo + k, g = gid[k];
            const WfCfModel *cm = sc->groups[g].model;
            if (!cm->state_size || !cm->update_state) continue;
            cm->update_state(f->group_params[g] + wf_fleet_slot(f, i) * f->group_param_stride[g],
                             f->group_state[g] + wf_fleet_slot(f, i) * cm->state_size, gap[k], v[k], vl[k], sc->dt_s);
        }
    }
    int flags = stats_before_block(f, sc, lo, m, v, a, fr, fl, in_window);
    s->ig->step(m, sc->dt_s, x, v, a);
    return flags | stats_after_block(f, sc, lo, m, ll, in_window);
}

/* A whole fixed-step time step in one pass over the vehicles: per block of FBLOCK vehicles, noise, inputs,
 * accelerations, fuel, controller memory, the record's partial sums (rec != NULL), statistics and integration,
 * with the block's intermediate values in local arrays instead of fleet-wide ones (far less memory traffic and
 * memory at large N). Positions and speeds are updated in place. That is race-free and order-free because every
 * vehicle reads only its leader's values from the step's start: within a thread's chunk, vehicle i's leader
 * i + 1 is updated after i; the leader of a chunk's last vehicle is the first vehicle of the next chunk (of chunk
 * 0 for the last vehicle, one lap ahead), whose old position and speed are saved before any update. Same
 * arithmetic as the multi-pass step (the same inline functions), so a vehicle's result does not depend on which
 * path or thread ran it. advance = 0 takes the record only. Returns the FUSED_* flags of all blocks, including
 * overlaps across block boundaries. */
/* Overlap of block b's last vehicle with its leader (the next block's first, or vehicle 0 one lap ahead), once both
 * have moved. */
static int block_edge_overlap(const WfFleet *f, double L, size_t b)
{
    size_t n = f->n, i = (b + 1) * FBLOCK - 1 < n ? (b + 1) * FBLOCK - 1 : n - 1, lead = i + 1 < n ? i + 1 : 0;
    double xl = f->x_m[lead] + (lead ? 0.0 : L);
    return n > 1 && xl - wf_fleet_length(f, lead) - f->x_m[i] < 0.0 ? FUSED_OVERLAP : 0;
}

static int step_fused(WfSim *s, long step, int in_window, WfStatsBlock *rec, int advance)
{
    WfFleet *f = s->f;
    const WfScenario *sc = s->sc;
    size_t n = f->n, nblk = (n + FBLOCK - 1) / FBLOCK;
    double L = sc->road.length_m;
    int nth = n >= PAR_MIN ? s->nthreads : 1;
    if ((size_t)nth > nblk) nth = (int)nblk;
    double *bx = s->bound_x, *bv = s->bound_v;
    int flags = 0, *cf = s->chunk_flags;
    if (nth == 1) {
        /* Small fleets: no OpenMP region at all (even a one-thread region costs runtime calls every step). */
        bx[0] = f->x_m[0];
        bv[0] = f->v_mps[0];
        for (size_t b = 0; b < nblk; b++) {
            size_t lo = b * FBLOCK, m = n - lo < FBLOCK ? n - lo : FBLOCK;
            flags |= fused_block(s, lo, m, lo + m == n, bx[0] + L, bv[0], step, in_window, rec ? rec + b : NULL,
                                 advance);
            if (advance && b > 0) flags |= block_edge_overlap(f, L, b - 1);
        }
        if (advance) flags |= block_edge_overlap(f, L, nblk - 1);
        return advance ? flags : 0;
    }
#pragma omp parallel num_threads(nth) default(none) shared(s, f, sc, n, nblk, bx, bv, step, in_window, rec, advance, cf, L)
    {
        /* The team may be smaller than asked (nested inside a sweep worker, or a thread limit): chunk by the
         * team actually running. */
        int t = thread_id(), nt = team_size(), fl = 0;
        size_t b0 = nblk * (size_t)t / (size_t)nt, b1 = nblk * (size_t)(t + 1) / (size_t)nt;
        size_t lo_t = b0 * FBLOCK, hi_t = b1 * FBLOCK < n ? b1 * FBLOCK : n;
        bx[t] = f->x_m[lo_t];
        bv[t] = f->v_mps[lo_t];
#pragma omp barrier
        /* Leader of this chunk's last vehicle: the next chunk's first, saved (plus one lap after the last). */
        int tn = t + 1 < nt ? t + 1 : 0;
        double xs = bx[tn] + (t + 1 < nt ? 0.0 : L), vs = bv[tn];
        for (size_t b = b0; b < b1; b++) {
            size_t lo = b * FBLOCK, m = n - lo < FBLOCK ? n - lo : FBLOCK;
            fl |= fused_block(s, lo, m, lo + m == hi_t, xs, vs, step, in_window, rec ? rec + b : NULL, advance);
            /* The previous block's edge, while both blocks are in cache. */
            if (advance && b > b0) fl |= block_edge_overlap(f, L, b - 1);
        }
        /* The chunk's last edge needs the next chunk moved. */
#pragma omp barrier
        if (advance && b1 > b0) fl |= block_edge_overlap(f, L, b1 - 1);
        cf[t] = fl;
    }
    for (int t = 0; t < nth; t++) flags |= cf[t];
    return advance ? flags : 0;
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
        stats_before(f, sc, i, f->v_mps[i], f->a_mps2[i], f->fuel_rate_gps[i], f->flag[i], in_window, 0);
    });
    int rc = wf_ode_advance(s->ode, t_next, f->x_m, f->v_mps, fs, err);
    if (rc) return rc;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(f, sc, n, fs, in_window)",
    for (size_t i = 0; i < n; i++) {
        if (in_window) f->fuel_g[i] += fs[i];
        stats_after(f, sc, i, in_window);
    });
    return 0;
}

/* Phase 5: no gap may be negative. A vehicle that would overlap its leader (noise, or a model that brakes
 * too late) is put at gap 0 behind it and stopped; each such event is counted. Rare, so it is found in
 * parallel and repaired serially, going backwards so a repaired leader is seen by its follower. */
static long phase_overlaps(WfSim *s)
{
    WfFleet *f = s->f;
    size_t n = f->n;
    double L = s->sc->road.length_m;
    const double *x = f->x_m, *v = f->v_mps;
    const uint8_t *mode = f->mode;
    long bad = 0, nonfinite = 0;
    WF_PAR_FOR(n >= PAR_MIN, "omp parallel for schedule(static) default(none) shared(n, x, v, f, L, mode) reduction(+ : bad, nonfinite)",
    for (size_t i = 0; i < n; i++) {
        size_t lead = i + 1 < n ? i + 1 : 0;
        double xl = x[lead] + (i + 1 < n ? 0.0 : L);
        bad += xl - wf_fleet_length(f, lead) - x[i] < 0.0;
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
            if (xl - wf_fleet_length(f, lead) - f->x_m[j] < 0.0) {
                /* Distance and passages follow the repaired position (they are taken from positions). */
                f->x_m[j] = xl - wf_fleet_length(f, lead);
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
        size_t cnt = f->group_n[g], psz = f->group_param_stride[g], ssz = m->state_size;
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
        if (step == s->warm_steps && !s->f->window_open) wf_fleet_open_window(s->f);
        int in_window = step >= s->warm_steps, records = step % s->out_every == 0;
        /* The fused step unless the fleet-wide per-step arrays are needed now: SUNDIALS integrators (every step),
         * trajectories (their steps only), or time.fused_step off. Both paths give the same bits. */
        int traj_step = sc->trajectories && step % s->traj_every == 0;
        if (!s->ode && sc->fused_step && !traj_step) {
            /* Every step in one pass, records included; the final instant is recorded without a step. */
            size_t nblk = (s->f->n + FBLOCK - 1) / FBLOCK;
            int flags = step_fused(s, step, in_window, records ? s->stat_blocks : NULL, step < s->n_steps);
            LAP(WF_PHASE_FUSED);
            if (records) {
                wf_stats_combine(s->stat_blocks, nblk, s->f->n_classes, sc, t, s->overlaps, &row);
                if (in_window) s->sd_sum += row.v[WF_TS_SD_V], s->n_sd++;
                LAP(WF_PHASE_STATISTICS);
                if (out && out->record && (rc = out->record(out->ctx, s, &row, err))) break;
                LAP(WF_PHASE_OUTPUT);
            }
            if (step == s->n_steps) break;
            s->repaired = flags ? phase_overlaps(s) > 0 : 0;
            LAP(WF_PHASE_INTEGRATION);
        } else {
            phase_noise(s, step);
            phase_accel(s, s->f->x_m, s->f->v_mps);
            LAP(WF_PHASE_CAR_FOLLOWING);
            phase_energy(s, s->f->v_mps, s->f->a_mps2);
            LAP(WF_PHASE_ENERGY);
            if (records) {
                wf_stats_record(s->f, sc, t, s->overlaps, s->stat_blocks, &row);
                if (in_window) s->sd_sum += row.v[WF_TS_SD_V], s->n_sd++;
                LAP(WF_PHASE_STATISTICS);
                if (out && out->record && (rc = out->record(out->ctx, s, &row, err))) break;
                LAP(WF_PHASE_OUTPUT);
            }
            if (sc->trajectories && step % s->traj_every == 0 && out && out->trajectory &&
                (rc = out->trajectory(out->ctx, s, t, err)))
                break;
            LAP(WF_PHASE_OUTPUT);
            if (step == s->n_steps) break;
            if (s->ode) {
                /* The right-hand side jumps where the noise or the controller memory changes, and the state
                 * jumps at an overlap repair: restart the solver there rather than integrate across the
                 * discontinuity. */
                if (step > 0 && (s->noisy || s->stateful || s->repaired) &&
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
            s->repaired = phase_overlaps(s) > 0;
            LAP(WF_PHASE_INTEGRATION);
        }
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
    s->ck.window_open = f->window_open;
#define VAR(nm, ptr, bytes)                                               \
    do {                                                                  \
        if (k < max) vars[k] = (WfStateVar){(nm), (void *)(ptr), (bytes)}; \
        k++;                                                              \
    } while (0)
    VAR("scalars", &s->ck, sizeof s->ck);
    VAR("x", f->x_m, n * sizeof *f->x_m);
    VAR("v", f->v_mps, n * sizeof *f->v_mps);
    if (f->grade_seg) VAR("grade_seg", f->grade_seg, n * sizeof *f->grade_seg); /* NULL on a flat road */
    VAR("x_start", f->x_start_m, n * sizeof *f->x_start_m);
    VAR("fuel", f->fuel_g, n * sizeof *f->fuel_g);
    VAR("stopped_steps", f->stopped_steps, n * sizeof *f->stopped_steps);
    VAR("sum_v", f->sum_v, n * sizeof *f->sum_v);
    VAR("sum_v2", f->sum_v2, n * sizeof *f->sum_v2);
    VAR("sum_a", f->sum_a, n * sizeof *f->sum_a);
    VAR("sum_a2", f->sum_a2, n * sizeof *f->sum_a2);
    VAR("stops", f->stops, n * sizeof *f->stops);
    VAR("hard_brakes", f->hard_brakes, n * sizeof *f->hard_brakes);
    VAR("infeasible_steps", f->infeasible_steps, n * sizeof *f->infeasible_steps);
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
    s->f->window_open = (int)s->ck.window_open;
    /* A SUNDIALS solver restarts from the restored state (as after a noise change): exact with noise or
     * controller memory, where the uninterrupted run restarts at every step too; within tolerance otherwise. */
    if (s->ode) {
        WfError e = {0};
        wf_ode_reinit(s->ode, (double)s->steps_done * s->sc->dt_s, s->f->x_m, s->f->v_mps, &e);
    }
}
