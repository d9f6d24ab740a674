/* Many runs stepped as one batch (include/wavefuel/engine.h: wf_sims_*; src/core/rl_batch.c, the Python package's
 * VectorEnv): the runs' steps in parallel over runs, each run single-threaded inside the batch, so every run gives
 * the bits it gives alone; and the external groups' observations and commands of every run as one array each, runs
 * in order. */
#include "core/batch.h"

#include "core/par.h"

#include "wavefuel/engine.h"

int wf_runs_each(size_t n_runs, int threads, int (*fn)(void *ctx, size_t k, WfError *err), void *ctx, WfError *errs)
{
    if (threads < 1) threads = 1;
    long n = (long)n_runs;
    /* Each call touches one run only (its engine, its WfError): race-free. A run's own parallel loops meet a team
     * of one inside this region (nested parallelism is off unless the caller enabled it, and the engine chunks by
     * the team it gets); either way its results do not depend on its thread count (engine.h). Static schedule: a
     * thread steps the same runs at every call, so their state stays in its core's cache, and neighbouring runs'
     * outputs (a reward, an observation row: a few bytes each) are written by one thread, not alternately by two.
     * Dynamic schedules (one run, or a quarter of a thread's share, at a time) stepped 64 RL rings 1.6 and 1.3
     * times slower on two threads (bench/README.md, RL environments). The schedule changes no run's bits. */
    WF_PAR_FOR(threads > 1 && n > 1,
               "omp parallel for num_threads(threads) default(none) shared(fn, ctx, n, errs) schedule(static)",
               for (long k = 0; k < n; k++) {
                   errs[k].code = 0, errs[k].msg[0] = '\0';
                   int rc = fn(ctx, (size_t)k, &errs[k]);
                   if (rc && !errs[k].code) errs[k].code = rc;
               });
    for (size_t k = 0; k < n_runs; k++)
        if (errs[k].code) return errs[k].code;
    return 0;
}

typedef struct StepCtx {
    WfSim *const *sims;
    long          n_steps;
} StepCtx;

static int step_run(void *ctx, size_t k, WfError *err)
{
    const StepCtx *c = ctx;
    return wf_sim_step(c->sims[k], c->n_steps, err);
}

int wf_sims_step(WfSim *const *sims, size_t n_sims, long n_steps, int threads, WfError *errs)
{
    StepCtx c = {sims, n_steps};
    return wf_runs_each(n_sims, threads, step_run, &c, errs);
}

/* The group sizes of every run add up to the rows given. */
static int check_rows(WfSim *const *sims, size_t n_sims, const size_t *group, size_t n_rows, const char *what,
                      WfError *err)
{
    size_t total = 0;
    for (size_t k = 0; k < n_sims; k++) total += wf_sim_group_size(sims[k], group[k]);
    if (total != n_rows)
        return wf_err(err, WF_EINPUT, "%s: the groups of the %zu runs have %zu vehicles on the road, got %zu %s",
                      what, n_sims, total, n_rows, n_rows == 1 ? "row" : "rows");
    return 0;
}

int wf_sims_observe(WfSim *const *sims, size_t n_sims, const size_t *group, double *obs, size_t n_rows,
                    WfError *err)
{
    int rc = check_rows(sims, n_sims, group, n_rows, "observe", err);
    for (size_t k = 0, row = 0; !rc && k < n_sims; k++) {
        size_t m = wf_sim_group_size(sims[k], group[k]);
        rc = wf_sim_observe(sims[k], group[k], obs + 3 * row, m, err);
        if (rc) wf_err_prefix(err, "run %zu of the batch: ", k);
        row += m;
    }
    return rc;
}

int wf_sims_set_actions(WfSim *const *sims, size_t n_sims, const size_t *group, const double *actions,
                        size_t n_actions, WfError *err)
{
    int rc = check_rows(sims, n_sims, group, n_actions, "set_actions", err);
    for (size_t k = 0, row = 0; !rc && k < n_sims; k++) {
        size_t m = wf_sim_group_size(sims[k], group[k]);
        rc = wf_sim_set_actions(sims[k], group[k], actions + row, m, err);
        if (rc) wf_err_prefix(err, "run %zu of the batch: ", k);
        row += m;
    }
    return rc;
}
