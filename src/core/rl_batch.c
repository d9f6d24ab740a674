/* Reinforcement-learning steps of a batch of runs (include/wavefuel/rl.h): in parallel over runs, each run's
 * commands, steps, then its observation and reward (fuel of its platoon from the classes' energy models, gap
 * bounds, comfort), every sum over one run's vehicles in road order, so a run's bits do not depend on the batch or
 * the threads. Units: m, m/s, m/s^2, g/s. */
#include "wavefuel/rl.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/batch.h"
#include "core/gang.h"
#include "core/governor.h"
#include "core/sim.h"
#include "util/clock.h"
#include "util/mem.h"
#include "wavefuel/corridor.h"

/* One run's share of the batch's arrays. */
typedef struct RlRun {
    size_t n, m;                          /* vehicles on the road, vehicles of the external group */
    size_t veh, row;                      /* offsets of its vehicles and its group's rows */
    size_t n_scope;                       /* vehicles whose fuel counts */
    size_t cls_off[WF_MAX_CLASSES + 1];   /* its vehicles by class: order[veh + cls_off[c] ..] */
    int    fuel_set;                      /* its fuel rates of this action are computed (gang_fuel) */
} RlRun;

struct WfRlBatch {
    WfSim *const *sims;                   /* borrowed */
    size_t        n_runs, n_veh, n_rows;
    size_t       *group;
    RlRun        *run;
    WfRlReward    rw;
    long          action_steps;
    double        dt_s;                   /* of an action */
    WfGovernor    gov;                    /* the threads of each call, for the threads asked (gov.n_max) */
    WfGang       *gang;                   /* the runs stepped side by side, when they can be (gang.h); NULL */
    long          gang_calls;             /* calls the gang stepped */
    long          gov_every;              /* calls between its probes */
    /* per vehicle, runs one after the other, each in road order */
    double       *v0, *v1, *a, *fuel, *cv, *ca, *cf, *zero;
    uint32_t     *order;                  /* by class within each run (cv, ca, cf are in this order) */
    uint8_t      *scope, *flag;
    /* per row of the groups */
    double       *obs0, *obs1, *a_prev;
    double       *low, *high, *u;         /* the commands' bounds (NULL: none) and the clipped commands */
    unsigned char **cmd;                  /* per row of a batch with a gang: where its command goes (its state) */
};

/* A run's vehicles in road order (a ring: fleet order, vehicle i + 1 leading i; a corridor: front first). */
typedef struct Road {
    const WfFleet            *f;
    const WfCorridorVehicles *vh;
    size_t                    n;
} Road;

static Road road_of(const WfSim *sim)
{
    Road r = {wf_ring_fleet(sim), NULL, 0};
    if (r.f) r.n = r.f->n;
    else r.vh = wf_corridor_vehicles(wf_sim_corridor(sim)), r.n = r.vh->n;
    return r;
}

static size_t slot(const Road *r, size_t i) { return r->f ? i : wf_corridor_slot(r->vh, i); }
static double speed(const Road *r, size_t i) { return (r->f ? r->f->v_mps : r->vh->v_mps)[slot(r, i)]; }
static unsigned cls(const Road *r, size_t i) { return (r->f ? r->f->class_id : r->vh->class_id)[slot(r, i)]; }
static unsigned grp(const Road *r, size_t i) { return (r->f ? r->f->group_id : r->vh->group_id)[slot(r, i)]; }

void wf_rl_batch_destroy(WfRlBatch **pb)
{
    if (!pb || !*pb) return;
    WfRlBatch *b = *pb;
    wf_gang_destroy(&b->gang);
    WF_FREE(b->group, b->run, b->v0, b->v1, b->a, b->fuel, b->cv, b->ca, b->cf, b->zero, b->order, b->scope, b->flag,
            b->obs0, b->obs1, b->a_prev, b->cmd, b->low, b->high, b->u, b);
    *pb = NULL;
}

/* Run k's vehicles: speeds, classes (counting sort into order) and scope. */
static void layout_run(WfRlBatch *b, size_t k)
{
    RlRun *ru = &b->run[k];
    Road r = road_of(b->sims[k]);
    size_t first = r.n; /* the platoon on a corridor: from the front-most vehicle of the group back */
    for (size_t i = 0; i < r.n && first == r.n; i++)
        if (grp(&r, i) == b->group[k]) first = i;
    size_t count[WF_MAX_CLASSES + 1] = {0};
    for (size_t i = 0; i < r.n; i++) {
        b->v0[ru->veh + i] = speed(&r, i);
        b->scope[ru->veh + i] = b->rw.scope_all || r.f || i >= first;
        ru->n_scope += b->scope[ru->veh + i];
        count[cls(&r, i) + 1]++;
    }
    for (size_t c = 0; c < WF_MAX_CLASSES; c++) count[c + 1] += count[c];
    memcpy(ru->cls_off, count, sizeof count);
    for (size_t i = 0; i < r.n; i++) b->order[ru->veh + count[cls(&r, i)]++] = (uint32_t)i;
}

int wf_rl_batch_create(WfSim *const *sims, size_t n_runs, const size_t *group, const WfRlReward *rw,
                       long action_steps, double dt_action_s, WfRlBatch **out, WfError *err)
{
    *out = NULL;
    if (action_steps < 1 || !(dt_action_s > 0.0) || !n_runs)
        return wf_err(err, WF_EINPUT, "rl batch: %zu runs, %ld steps an action of %g s (need >= 1, >= 1, > 0)",
                      n_runs, action_steps, dt_action_s);
    WfRlBatch *b = calloc(1, sizeof *b);
    if (!b) return wf_err(err, WF_ESYS, "out of memory");
    *b = (WfRlBatch){.sims = sims, .n_runs = n_runs, .rw = *rw, .action_steps = action_steps, .dt_s = dt_action_s,
                     .gov_every = WF_RL_THREAD_CHECK};
    b->group = malloc(n_runs * sizeof *b->group);
    b->run = calloc(n_runs, sizeof *b->run);
    int rc = b->group && b->run ? 0 : wf_err(err, WF_ESYS, "out of memory");
    for (size_t k = 0; !rc && k < n_runs; k++) {
        b->group[k] = group[k];
        b->run[k] = (RlRun){.n = road_of(sims[k]).n, .m = wf_sim_group_size(sims[k], group[k]), .veh = b->n_veh,
                            .row = b->n_rows};
        if (!b->run[k].m) rc = wf_err(err, WF_EINPUT, "rl batch: run %zu: group %zu has no vehicle on the road", k,
                                      group[k]);
        b->n_veh += b->run[k].n, b->n_rows += b->run[k].m;
    }
    double **dv[] = {&b->v0, &b->v1, &b->a, &b->fuel, &b->cv, &b->ca, &b->cf, &b->zero};
    for (size_t j = 0; !rc && j < sizeof dv / sizeof *dv; j++)
        if (!(*dv[j] = calloc(b->n_veh, sizeof(double)))) rc = wf_err(err, WF_ESYS, "out of memory");
    double **dr[] = {&b->obs0, &b->obs1, &b->a_prev};
    for (size_t j = 0; !rc && j < sizeof dr / sizeof *dr; j++)
        if (!(*dr[j] = calloc(3 * b->n_rows, sizeof(double)))) rc = wf_err(err, WF_ESYS, "out of memory");
    if (!rc && (!(b->order = calloc(b->n_veh, sizeof *b->order)) || !(b->scope = calloc(b->n_veh, 1)) ||
                !(b->flag = calloc(b->n_veh, 1))))
        rc = wf_err(err, WF_ESYS, "out of memory");
    /* The first observation validates the groups (external, sizes). */
    if (!rc) rc = wf_sims_observe(sims, n_runs, b->group, b->obs0, b->n_rows, err);
    for (size_t k = 0; !rc && k < n_runs; k++) layout_run(b, k);
    if (!rc) rc = wf_gang_create(sims, n_runs, &b->gang, err);
    if (!rc && b->gang && !(b->cmd = malloc(b->n_rows * sizeof *b->cmd))) rc = wf_err(err, WF_ESYS, "out of memory");
    for (size_t k = 0; !rc && b->gang && k < n_runs; k++)
        wf_sim_group_states(sims[k], group[k], b->cmd + b->run[k].row);
    for (size_t j = 0; !rc && j < b->n_rows; j++) b->a_prev[j] = NAN; /* no previous action: no jerk */
    if (rc) wf_rl_batch_destroy(&b);
    *out = b;
    return rc;
}

size_t wf_rl_batch_rows(const WfRlBatch *b) { return b->n_rows; }
double *wf_rl_batch_prev_accel(WfRlBatch *b) { return b->a_prev; }
void wf_rl_batch_observe(const WfRlBatch *b, double *obs) { memcpy(obs, b->obs0, 3 * b->n_rows * sizeof *obs); }

/* Class vc's fuel rates at speeds v (finite: states) and accelerations a on a flat road: its model's flat form when
 * it has one (the same bits as theta = +0), else eval with zeros. */
static void flat_fuel(const WfVehicleClass *vc, size_t n, const double *v, const double *a, const double *zero,
                      double *fuel, uint8_t *flag)
{
    if (vc->model->eval_flat) vc->model->eval_flat(vc->params, n, v, a, fuel, flag);
    else vc->model->eval(vc->params, n, v, a, zero, 0, fuel, flag);
}

/* Every vehicle's fuel rate of run k over the action (its class model at v0 and (v1 - v0) / dt, flat road): the
 * vehicles gathered by class, one array evaluation per class, scattered back (a road of one class: in place). */
static void run_fuel(WfRlBatch *b, size_t k)
{
    const RlRun *ru = &b->run[k];
    const WfScenario *sc = wf_sim_scenario(b->sims[k]);
    size_t o = ru->veh;
    for (size_t i = 0; i < ru->n; i++) b->a[o + i] = (b->v1[o + i] - b->v0[o + i]) / b->dt_s;
    for (size_t c = 0; c < sc->n_classes; c++) {
        size_t lo = ru->cls_off[c], hi = ru->cls_off[c + 1];
        if (lo == hi) continue;
        const WfVehicleClass *vc = &sc->classes[c].vc;
        if (hi - lo == ru->n) { /* one class on the road: in place (an evaluation is element-wise) */
            flat_fuel(vc, ru->n, b->v0 + o, b->a + o, b->zero + o, b->fuel + o, b->flag + o);
            break;
        }
        for (size_t j = lo; j < hi; j++) {
            size_t i = o + b->order[o + j];
            b->cv[o + j] = b->v0[i], b->ca[o + j] = b->a[i];
        }
        flat_fuel(vc, hi - lo, b->cv + o + lo, b->ca + o + lo, b->zero + o + lo, b->cf + o + lo, b->flag + o + lo);
        for (size_t j = lo; j < hi; j++) b->fuel[o + b->order[o + j]] = b->cf[o + j];
    }
}

/* Run k after its steps: speeds, observation, reward and info; the action's end becomes the next one's start. */
static int run_reward(WfRlBatch *b, size_t k, double *reward, double *info, WfError *err)
{
    const RlRun *ru = &b->run[k];
    Road r = road_of(b->sims[k]);
    if (r.n != ru->n)
        return wf_err(err, WF_EINPUT, "%zu vehicles on the road, the batch was made with %zu (vehicles entered or "
                      "left)", r.n, ru->n);
    size_t o = ru->veh;
    if (!ru->fuel_set) {
        if (r.f) memcpy(b->v1 + o, r.f->v_mps, r.n * sizeof *b->v1); /* a ring: road order is fleet order */
        else
            for (size_t i = 0; i < r.n; i++) b->v1[o + i] = speed(&r, i);
        run_fuel(b, k);
    }
    b->run[k].fuel_set = 0;
    double fuel = 0.0, vsum = 0.0;
    const double *fr = b->fuel + o, *v1 = b->v1 + o;
    if (ru->n_scope == r.n) { /* every vehicle in scope (a ring): the same sums without the mask */
#pragma GCC unroll 4
        for (size_t i = 0; i < r.n; i++) fuel += fr[i], vsum += v1[i];
    } else {
        for (size_t i = 0; i < r.n; i++) fuel += b->scope[o + i] ? fr[i] : 0.0, vsum += v1[i];
    }
    double *obs = b->obs1 + 3 * ru->row, *obs0 = b->obs0 + 3 * ru->row, *ap = b->a_prev + ru->row;
    /* a ring's group keeps its vehicles (checked at the batch's creation); a corridor's is checked every call */
    int rc = r.f ? (wf_sim_observe_rows(b->sims[k], b->group[k], obs), 0)
                 : wf_sim_observe(b->sims[k], b->group[k], obs, ru->m, err);
    if (rc) return rc;
    const WfRlReward *w = &b->rw;
    double viol = 0.0, a2 = 0.0, j2 = 0.0;
    for (size_t j = 0; j < ru->m; j++) {
        double gap = obs[3 * j + 2], lo = w->gap_min_m - gap, hi = gap - w->gap_max_m;
        viol += lo > 0.0 ? lo * lo : hi > 0.0 ? hi * hi : 0.0;
        double a = (obs[3 * j] - obs0[3 * j]) / b->dt_s, jerk = isnan(ap[j]) ? 0.0 : (a - ap[j]) / b->dt_s;
        a2 += a * a, j2 += jerk * jerk;
        ap[j] = a;
    }
    double m = (double)ru->m, *in = info + WF_RL_N_INFO * k;
    in[WF_RL_FUEL_RATE_GPS] = ru->n_scope ? fuel / (double)ru->n_scope : 0.0;
    in[WF_RL_MEAN_SPEED_MPS] = vsum / (double)r.n;
    in[WF_RL_T_S] = wf_sim_time_s(b->sims[k]);
    in[WF_RL_FUEL] = -w->w_fuel * in[WF_RL_FUEL_RATE_GPS];
    in[WF_RL_GAP] = -w->w_gap * (viol / m);
    in[WF_RL_COMFORT] = -(w->w_accel * (a2 / m) + w->w_jerk * (j2 / m));
    reward[k] = in[WF_RL_FUEL] + in[WF_RL_GAP] + in[WF_RL_COMFORT];
    memcpy(b->v0 + o, b->v1 + o, r.n * sizeof *b->v0);
    memcpy(obs0, obs, 3 * ru->m * sizeof *obs);
    return 0;
}

typedef struct RlStep {
    WfRlBatch    *b;
    const double *actions;
    double       *reward, *info;
} RlStep;

/* Run k: its commands, its steps, then its observation and reward (one parallel region a step for the whole
 * batch). */
static int step_run(void *ctx, size_t k, WfError *err)
{
    const RlStep *c = ctx;
    const RlRun *ru = &c->b->run[k];
    WfSim *sim = c->b->sims[k];
    c->b->run[k].fuel_set = 0;
    int rc = wf_sim_set_actions(sim, c->b->group[k], c->actions + ru->row, ru->m, err);
    /* not timed one by one: the batch's call is (wf_sim_wall_s leaves these steps out) */
    if (!rc) rc = wf_sim_step_untimed(sim, c->b->action_steps, err);
    if (!rc) rc = run_reward(c->b, k, c->reward, c->info, err);
    if (rc) wf_err_prefix(err, "run %zu of the batch: ", k);
    return rc;
}

/* A run of the gang (gang.h): its commands before its steps, its observation and reward after them. */
static int gang_before(void *ctx, size_t k, WfError *err)
{
    const RlStep *c = ctx;
    const RlRun *ru = &c->b->run[k];
    const double *u = c->actions + ru->row;
    c->b->run[k].fuel_set = 0; /* a run whose steps fail keeps it so until its next call */
    /* the commands into the members' state, where wf_sim_set_actions puts them (a ring's members stay); a refused
     * one through it, for its message */
    for (size_t j = 0; j < ru->m; j++)
        if (isinf(u[j])) {
            int rc = wf_sim_set_actions(c->b->sims[k], c->b->group[k], u, ru->m, err);
            wf_err_prefix(err, "run %zu of the batch: ", k);
            return rc;
        }
    for (size_t j = 0; j < ru->m; j++) memcpy(c->b->cmd[ru->row + j], u + j, sizeof *u);
    return 0;
}

/* The fuel rates of a gang block's runs r0 .. r1 - 1 in one evaluation when every vehicle of them is of class 0 (the
 * gang's runs share their classes), their vehicles consecutive in the batch's arrays: the bits of each run's own
 * (run_fuel's: an evaluation is element-wise). Else each run evaluates its own. */
static void gang_fuel(void *ctx, size_t r0, size_t r1)
{
    const RlStep *c = ctx;
    WfRlBatch *b = c->b;
    for (size_t k = r0; k < r1; k++)
        if (b->run[k].cls_off[1] != b->run[k].n) return;
    size_t lo = b->run[r0].veh, hi = b->run[r1 - 1].veh + b->run[r1 - 1].n;
    for (size_t k = r0; k < r1; k++)
        memcpy(b->v1 + b->run[k].veh, wf_ring_fleet(b->sims[k])->v_mps, b->run[k].n * sizeof *b->v1);
    for (size_t i = lo; i < hi; i++) b->a[i] = (b->v1[i] - b->v0[i]) / b->dt_s;
    flat_fuel(&wf_sim_scenario(b->sims[r0])->classes[0].vc, hi - lo, b->v0 + lo, b->a + lo, b->zero + lo,
              b->fuel + lo, b->flag + lo);
    for (size_t k = r0; k < r1; k++) b->run[k].fuel_set = 1;
}

static int gang_after(void *ctx, size_t k, WfError *err)
{
    const RlStep *c = ctx;
    int rc = run_reward(c->b, k, c->reward, c->info, err);
    if (rc) wf_err_prefix(err, "run %zu of the batch: ", k);
    return rc;
}

int wf_rl_batch_set_bounds(WfRlBatch *b, const double *low, const double *high, WfError *err)
{
    if (!low || !high) {
        free(b->low), free(b->high), free(b->u);
        b->low = b->high = b->u = NULL;
        return 0;
    }
    for (size_t j = 0; j < b->n_rows; j++)
        if (!(low[j] <= high[j]))
            return wf_err(err, WF_EINPUT, "rl batch: command %zu's bounds [%g, %g] (need low <= high, not NaN)", j,
                          low[j], high[j]);
    size_t bytes = b->n_rows * sizeof(double);
    double *lo = malloc(bytes), *hi = malloc(bytes), *u = malloc(bytes);
    if (!lo || !hi || !u) {
        free(lo), free(hi), free(u);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    memcpy(lo, low, bytes);
    memcpy(hi, high, bytes);
    free(b->low), free(b->high), free(b->u);
    b->low = lo, b->high = hi, b->u = u;
    return 0;
}

/* numpy's maximum and minimum of two doubles: a NaN in either gives NaN, a tie gives b. */
static double np_maximum(double a, double b) { return a > b || a != a ? a : b; }
static double np_minimum(double a, double b) { return a < b || a != a ? a : b; }

int wf_rl_batch_call(const WfRlCall *c)
{
    return wf_rl_batch_step(c->b, c->actions, c->threads, c->obs, c->reward, c->info, c->errs);
}

int wf_rl_batch_step(WfRlBatch *b, const double *actions, int threads, double *obs, double *reward, double *info,
                     WfError *errs)
{
    if (b->u) { /* the commands clipped to their bounds */
        for (size_t j = 0; j < b->n_rows; j++) b->u[j] = np_minimum(np_maximum(actions[j], b->low[j]), b->high[j]);
        actions = b->u;
    }
    RlStep c = {b, actions, reward, info};
    if (threads < 1) threads = 1;
    /* A call lasts some 50 us: the first on another thread count is not timed (governor.h, settle). */
    if (b->gov.n_max != threads) wf_governor_init(&b->gov, threads, b->gov_every, 1);
    int nt = wf_governor_threads(&b->gov), rc = 0;
    /* not timed: a call on one run or one thread (nothing to choose) */
    double t0 = threads > 1 && b->n_runs > 1 ? wf_wall_now() : 0.0;
    if (b->gang && wf_gang_ready(b->gang, b->action_steps)) {
        /* one parallel region: each thread sets, steps and rewards the rings of its blocks */
        WfGangHooks h = {gang_before, gang_fuel, gang_after, &c};
        rc = wf_gang_step(b->gang, b->action_steps, nt, &h, errs);
        b->gang_calls++;
    } else {
        rc = wf_runs_each(b->n_runs, nt, step_run, &c, errs);
    }
    if (t0 > 0.0) wf_governor_done(&b->gov, wf_wall_now() - t0, (double)b->n_veh * (double)b->action_steps, 1);
    if (!rc && obs) wf_rl_batch_observe(b, obs);
    return rc;
}

void wf_rl_batch_set_thread_check(WfRlBatch *b, long calls)
{
    b->gov_every = calls > 0 ? calls : 0;
    b->gov.n_max = 0; /* set up again at the next call */
}

long wf_rl_batch_thread_check(const WfRlBatch *b) { return b->gov_every; }
long wf_rl_batch_gang_calls(const WfRlBatch *b) { return b->gang_calls; }

void wf_rl_batch_governor(const WfRlBatch *b, long *probes, long *switches)
{
    if (probes) *probes = b->gov.probes;
    if (switches) *switches = b->gov.switches;
}
