/* A run of one road, whatever its boundary (src/core/sim.h): the boundary's engine stepped by the one step loop
 * (wf_loop_start, wf_loop_advance, wf_loop_finish), with the outputs, wall time, threads, checkpoints and summary
 * every boundary shares. */
#include "core/sim.h"

#include "wavefuel/corridor.h"
#include "wavefuel/mlp.h"
#include "util/numfmt.h"
#include "util/mem.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* The batch buffers of the mlp groups: as many rows as vehicles a group can have on the road (a ring: its count; a
 * corridor: the vehicle slots of the road). */
static int mlp_alloc(WfSim *s, WfError *err)
{
    const WfScenario *sc = s->sc;
    size_t cap = 0;
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].mlp) {
            size_t n = sc->corridor ? wf_corridor_vehicles(wf_sim_corridor(s))->cap : (size_t)sc->groups[g].count;
            cap = n > cap ? n : cap;
        }
    if (!cap) return 0;
    s->mlp_rows = malloc(cap * WF_MLP_INPUTS * sizeof *s->mlp_rows);
    s->mlp_cmd = malloc(cap * sizeof *s->mlp_cmd);
    return s->mlp_rows && s->mlp_cmd ? 0 : wf_err(err, WF_ESYS, "out of memory for the mlp batch of %zu vehicles", cap);
}

int wf_sim_create(const WfScenario *sc, WfSim **out, WfError *err)
{
    return wf_sim_create_part(sc, NULL, out, err);
}

/* What no road split across processes can be (each boundary refuses more: part_check in engine.c, corridor_part.c). */
static int part_refusals(const WfScenario *sc, WfError *err)
{
    const char *why = wf_scenario_lanes(sc) > 1 ? "road.lanes: a road of several lanes"
                    : sc->adaptive ? "time.integrator: a SUNDIALS integrator (fixed-step integrators only)"
                    : sc->trajectories ? "output.trajectories: trajectories"
                    : !sc->fused_step ? "time.fused_step false: steps in two passes" : NULL;
    if (why) return wf_err(err, WF_EINPUT, "%s: %s cannot be split across processes (docs/mpi.md)", sc->path, why);
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].model->external)
            return wf_err(err, WF_EINPUT, "%s: driver group '%s': model %s takes its commands from outside every step "
                          "and cannot be split across processes (docs/mpi.md)", sc->path, sc->groups[g].name,
                          sc->groups[g].mlp ? "mlp" : sc->groups[g].model->name);
    return 0;
}

int wf_sim_create_part(const WfScenario *sc, WfPartition *part, WfSim **out, WfError *err)
{
    *out = NULL;
    int rc = part ? part_refusals(sc, err) : 0;
    if (rc) return rc;
    WfSim *s = calloc(1, sizeof *s);
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    s->sc = sc;
    s->part = part;
    /* The scenario loader has checked the road section of its boundary: an open road holds a corridor spec. */
    s->b = sc->corridor ? &wf_boundary_open : &wf_boundary_periodic;
#ifdef _OPENMP
    s->nthreads = omp_get_max_threads();
#else
    s->nthreads = 1;
#endif
    rc = s->b->create(s, err);
    if (!rc) rc = mlp_alloc(s, err);
    if (rc) wf_sim_destroy(&s);
    *out = s;
    return rc;
}

void wf_sim_sync(WfSim *s)
{
    if (s->held.fn) s->held.fn(s->held.gang, s->held.r, 0);
}

void wf_sim_destroy(WfSim **ps)
{
    if (!ps || !*ps) return;
    if ((*ps)->held.fn) (*ps)->held.fn((*ps)->held.gang, (*ps)->held.r, 1); /* the gang forgets it */
    if ((*ps)->eng) (*ps)->b->destroy((*ps)->eng);
    WF_FREE((*ps)->mlp_rows, (*ps)->mlp_cmd, *ps);
    *ps = NULL;
}

static int mlp_command(WfSim *s, long step, WfError *err);

static int step_cb(void *ctx, long step, long max_steps, long *steps, WfError *err)
{
    WfSim *s = ctx;
    /* an mlp group's commands are set before every step */
    int rc = s->mlp_rows ? mlp_command(s, step, err) : 0;
    return rc ? rc : s->b->step(s->eng, step, s->mlp_rows ? 1 : max_steps, steps, err);
}

static int checkpoint_cb(void *ctx, WfError *err)
{
    WfSim *s = ctx;
    int rc = s->b->flush ? s->b->flush(s->eng, err) : 0;
    return rc ? rc : s->out->checkpoint(s->out->ctx, s, err);
}

static int close_cb(void *ctx, WfError *err)
{
    WfSim *s = ctx;
    return s->b->close(s->eng, err);
}

static int end_cb(void *ctx, int completed, const char *reason, WfError *err)
{
    WfSim *s = ctx;
    return s->out->end(s->out->ctx, s, completed, reason, err);
}

int wf_sim_begin(WfSim *s, const WfOutput *out, WfError *err)
{
    const WfScenario *sc = s->sc;
    if (s->begun) return wf_err(err, WF_EINPUT, "%s: this run has already begun (a run is stepped once)", sc->path);
    int rc = out && out->begin ? out->begin(out->ctx, s, err) : 0;
    if (rc) return rc;
    s->out = out;
    s->begun = 1;
    s->epoch++;
    s->loop = (WfLoop){.ctx = s, .step = step_cb, .checkpoint = out && out->checkpoint ? checkpoint_cb : NULL,
                       .close = close_cb, .end = out && out->end ? end_cb : NULL, .steps_done = s->steps_done,
                       .wall_s = &s->wall_s, .n_steps = wf_scenario_n_steps(sc), .dt_s = sc->dt_s,
                       .duration_s = sc->duration_s, .checkpoint_every_s = s->checkpoint_every_s};
    wf_loop_start(&s->ls);
    return 0;
}

/* The run's end: a stop, an error or the final instant closes it (summary, output end). */
static int finish(WfSim *s, int rc, WfError *err)
{
    wf_sim_sync(s);
    s->finished = 1;
    return wf_loop_finish(&s->loop, &s->ls, rc, err);
}

static int sim_step(WfSim *s, long n, int timed, WfError *err)
{
    if (!s->begun || s->finished)
        return wf_err(err, WF_EINPUT, "%s: %s", s->sc->path,
                      s->finished ? "the run has ended: no step is left" : "wf_sim_begin first");
    s->loop.wall_s = timed ? &s->wall_s : NULL;
    s->epoch++;
    wf_sim_sync(s);
    int rc = wf_loop_advance(&s->loop, &s->ls, n, err);
    return rc || s->ls.reason || s->ls.at_end ? finish(s, rc, err) : 0;
}

long wf_sim_gang_plain(const WfSim *s, int *in_window)
{
    const WfLoop *lp = &s->loop;
    if (!s->begun || s->finished || s->mlp_rows || lp->progress || lp->stop ||
        (lp->checkpoint && lp->checkpoint_every_s > 0) || s->ls.reason || s->ls.at_end || s->b != &wf_boundary_periodic)
        return 0;
    return wf_ring_gang_plain(s, in_window);
}

void wf_sim_gang_done(WfSim *s, long k) { *s->steps_done += k; }

int wf_sim_gang_fail(WfSim *s, int rc, WfError *err)
{
    s->epoch++;
    return finish(s, rc, err);
}

int wf_sim_step(WfSim *s, long n, WfError *err) { return sim_step(s, n, 1, err); }
int wf_sim_step_untimed(WfSim *s, long n, WfError *err) { return sim_step(s, n, 0, err); }

int wf_sim_finish(WfSim *s, WfError *err)
{
    if (!s->begun || s->finished) return 0;
    s->ls.reason = "stopped by the caller";
    s->epoch++;
    return finish(s, 0, err);
}

int wf_sim_done(const WfSim *s) { return s->finished; }
double wf_sim_time_s(const WfSim *s) { return (double)*s->steps_done * s->sc->dt_s; }

int wf_sim_run(WfSim *s, const WfOutput *out, WfProgressFn progress, void *pctx, volatile sig_atomic_t *stop,
               WfError *err)
{
    int rc = wf_sim_begin(s, out, err);
    if (rc) return rc;
    s->loop.progress = progress, s->loop.pctx = pctx, s->loop.stop = stop;
    return wf_sim_step(s, s->loop.n_steps + 1, err);
}

const WfScenario *wf_sim_scenario(const WfSim *s) { return s->sc; }
int wf_sim_lanes(const WfSim *s, WfLaneObs *out) { return s->b->lanes ? s->b->lanes(s->eng, out) : 0; }
int wf_sim_shares(const WfSim *s, WfShareFn fn, void *ctx, WfError *err)
{
    /* the run itself is not const: rank 0 gathers the other shares into its arrays */
    return s->b->shares ? s->b->shares(s->eng, fn, ctx, err) : 0;
}

int wf_sim_state_pieces(WfSim *s, const WfStateVar *vars, size_t n, WfStatePieceFn fn, void *ctx, WfError *err)
{
    if (s->b->state_pieces) return s->b->state_pieces(s->eng, vars, n, fn, ctx, err);
    int rc = 0;
    for (size_t j = 0; fn && !rc && j < n; j++) rc = fn(ctx, j, 0, vars[j].size, err);
    return rc;
}

int wf_sim_window_stats(const WfSim *s, long *windows, long *redone)
{
    *windows = s->win->windows, *redone = s->win->redone;
    return s->win->k_max;
}
const char *wf_sim_kind(const WfSim *s) { return s->b->kind; }

int wf_sim_thread_stats(const WfSim *s, long *probes, long *switches)
{
    const WfGovernor *g = s->gov;
    *probes = g->probes, *switches = g->switches;
    return g->every > 0;
}
const WfSummary *wf_sim_summary(const WfSim *s) { return &s->summary; }
double wf_sim_wall_s(const WfSim *s) { return s->wall_s; }
long wf_sim_steps_done(const WfSim *s) { return *s->steps_done; }
int wf_sim_threads(const WfSim *s) { return s->nthreads; }
const double *wf_sim_phase_times(const WfSim *s) { return s->phase_s; }
/* Before or during a run stepped in pieces. */
void wf_sim_set_checkpoint_interval(WfSim *s, double wall_s)
{
    s->checkpoint_every_s = s->loop.checkpoint_every_s = wall_s;
    s->epoch++;
}
size_t wf_sim_state(WfSim *s, WfStateVar *vars, size_t max)
{
    wf_sim_sync(s);
    return s->b->state(s->eng, vars, max);
}
int wf_sim_restored(WfSim *s, WfError *err)
{
    s->epoch++;
    /* the restored arrays are the run's: a gang copies them in */
    if (s->held.fn) s->held.fn(s->held.gang, s->held.r, 1);
    return s->b->restored(s->eng, err);
}

/* ---- external controllers (models with `external` set: src/models/cf/external.c) ---- */

/* commands: 1 when the caller sets them (an mlp group computes its own, but is observed). */
static int check_group(const WfSim *s, size_t g, size_t n, size_t want, int commands, WfError *err)
{
    const WfScenario *sc = s->sc;
    if (g >= sc->n_groups)
        return wf_err(err, WF_EINPUT, "%s: no driver group %zu (the scenario has %zu)", sc->path, g, sc->n_groups);
    if (!sc->groups[g].model->external || (commands && sc->groups[g].mlp))
        return wf_err(err, WF_EINPUT, "%s: driver group '%s' (model %s) takes no commands: its model must be external "
                      "or external_speed%s", sc->path, sc->groups[g].name, sc->groups[g].model->name,
                      sc->groups[g].mlp ? " (an mlp group's network sets them at every step)" : "");
    if (n != want)
        return wf_err(err, WF_EINPUT, "%s: driver group '%s' has %zu vehicles on the road, got %zu values", sc->path,
                      sc->groups[g].name, want, n);
    return 0;
}

size_t wf_sim_group_size(const WfSim *s, size_t g)
{
    return g < s->sc->n_groups ? s->b->group(s->eng, g, NULL, NULL) : 0;
}

static void put_command(void *ctx, size_t k, unsigned char *state, double v, double vl, double gap)
{
    (void)v, (void)vl, (void)gap;
    memcpy(state, (const double *)ctx + k, sizeof(double));
}

static void put_state(void *ctx, size_t k, unsigned char *state, double v, double vl, double gap)
{
    (void)v, (void)vl, (void)gap;
    ((unsigned char **)ctx)[k] = state;
}

size_t wf_sim_group_states(WfSim *s, size_t g, unsigned char **out) { return s->b->group(s->eng, g, put_state, out); }

int wf_sim_set_actions(WfSim *s, size_t g, const double *u, size_t n, WfError *err)
{
    int rc = check_group(s, g, n, wf_sim_group_size(s, g), 1, err);
    for (size_t k = 0; !rc && k < n; k++)
        if (isinf(u[k]))
            rc = wf_err(err, WF_EINPUT, "%s: driver group '%s': command %zu is %g (finite, or NaN for none)",
                        s->sc->path, s->sc->groups[g].name, k, u[k]);
    if (!rc) s->b->group(s->eng, g, put_command, (void *)u);
    return rc;
}

static void put_observation(void *ctx, size_t k, unsigned char *state, double v, double vl, double gap)
{
    (void)state;
    double *row = (double *)ctx + 3 * k;
    row[0] = v, row[1] = vl, row[2] = gap;
}

size_t wf_sim_observe_rows(const WfSim *s, size_t g, double *obs)
{
    return s->b->group(s->eng, g, put_observation, obs);
}

int wf_sim_observe(const WfSim *s, size_t g, double *obs, size_t n, WfError *err)
{
    int rc = check_group(s, g, n, wf_sim_group_size(s, g), 0, err);
    if (!rc) s->b->group(s->eng, g, put_observation, obs);
    return rc;
}

/* Before every step: each mlp group's commands from its network, evaluated on the group's observation rows (the
 * inputs of this step) as one batch; set as an external group's commands, so the step, the checkpoints and the
 * observations treat them alike. A command depends only on its vehicle's row: the same bits for any thread count. */
static int mlp_command(WfSim *s, long step, WfError *err)
{
    const WfScenario *sc = s->sc;
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfMlp *net = sc->groups[g].mlp;
        if (!net) continue;
        size_t n = s->b->group(s->eng, g, put_observation, s->mlp_rows);
        wf_mlp_eval(net, s->mlp_rows, n, s->mlp_cmd, s->nthreads);
        for (size_t k = 0; k < n; k++)
            if (!isfinite(s->mlp_cmd[k])) {
                const double *r = s->mlp_rows + WF_MLP_INPUTS * k;
                return wf_err(err, WF_EINPUT, "%s: driver group '%s': the network %s gives %s for its vehicle %zu "
                              "(speed %s m/s, leader speed %s m/s, gap %s m) at t = %s s", sc->path, sc->groups[g].name,
                              wf_mlp_path(net), WF_NUM(s->mlp_cmd[k]), k, WF_NUM(r[0]), WF_NUM(r[1]), WF_NUM(r[2]),
                              WF_NUM((double)step * sc->dt_s));
            }
        s->b->group(s->eng, g, put_command, s->mlp_cmd);
    }
    return 0;
}
