/* A run of one road, whatever its boundary (src/core/sim.h): the boundary's engine stepped by the one step loop
 * (wf_loop_run), with the outputs, wall time, threads, checkpoints and summary every boundary shares. */
#include "core/sim.h"

#include <stdlib.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/block.h"

int wf_sim_create(const WfScenario *sc, WfSim **out, WfError *err)
{
    *out = NULL;
    WfSim *s = calloc(1, sizeof *s);
    if (!s) return wf_err(err, WF_ESYS, "out of memory");
    s->sc = sc;
    /* The scenario loader has checked the road section of its boundary: an open road holds a corridor spec. */
    s->b = sc->corridor ? &wf_boundary_open : &wf_boundary_periodic;
#ifdef _OPENMP
    s->nthreads = omp_get_max_threads();
#else
    s->nthreads = 1;
#endif
    int rc = s->b->create(s, err);
    if (rc) wf_sim_destroy(&s);
    *out = s;
    return rc;
}

void wf_sim_destroy(WfSim **ps)
{
    if (!ps || !*ps) return;
    if ((*ps)->eng) (*ps)->b->destroy((*ps)->eng);
    free(*ps);
    *ps = NULL;
}

static int step_cb(void *ctx, long step, WfError *err)
{
    WfSim *s = ctx;
    return s->b->step(s->eng, step, err);
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

int wf_sim_run(WfSim *s, const WfOutput *out, WfProgressFn progress, void *pctx, volatile sig_atomic_t *stop,
               WfError *err)
{
    const WfScenario *sc = s->sc;
    int rc = out && out->begin ? out->begin(out->ctx, s, err) : 0;
    if (rc) return rc;
    s->out = out;
    WfLoop lp = {.ctx = s, .step = step_cb, .checkpoint = out && out->checkpoint ? checkpoint_cb : NULL,
                 .close = close_cb, .end = out && out->end ? end_cb : NULL, .steps_done = s->steps_done,
                 .wall_s = &s->wall_s, .n_steps = wf_scenario_n_steps(sc), .dt_s = sc->dt_s,
                 .duration_s = sc->duration_s, .checkpoint_every_s = s->checkpoint_every_s, .progress = progress,
                 .pctx = pctx, .stop = stop};
    return wf_loop_run(&lp, err);
}

const WfScenario *wf_sim_scenario(const WfSim *s) { return s->sc; }
const char *wf_sim_kind(const WfSim *s) { return s->b->kind; }
const WfSummary *wf_sim_summary(const WfSim *s) { return &s->summary; }
double wf_sim_wall_s(const WfSim *s) { return s->wall_s; }
long wf_sim_steps_done(const WfSim *s) { return *s->steps_done; }
int wf_sim_threads(const WfSim *s) { return s->nthreads; }
const double *wf_sim_phase_times(const WfSim *s) { return s->phase_s; }
void wf_sim_set_checkpoint_interval(WfSim *s, double wall_s) { s->checkpoint_every_s = wall_s; }
size_t wf_sim_state(WfSim *s, WfStateVar *vars, size_t max) { return s->b->state(s->eng, vars, max); }
int wf_sim_restored(WfSim *s, WfError *err) { return s->b->restored(s->eng, err); }
