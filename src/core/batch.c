/* Many runs stepped as one batch (include/wavefuel/engine.h: wf_sims_*; the Python package's VectorEnv): the runs'
 * steps in parallel over runs, each run single-threaded inside the batch, so every run gives the bits it gives
 * alone; and the external groups' observations, commands and all vehicles' speeds of every run as one array each,
 * runs in order. */
#include <string.h>

#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"

int wf_sims_step(WfSim *const *sims, size_t n_sims, long n_steps, int threads, WfError *errs)
{
    if (threads < 1) threads = 1;
    long n = (long)n_sims;
    /* Each iteration touches one run only (its engine, its WfError): race-free. A run's own parallel loops meet
     * a team of one inside this region (nested parallelism is off unless the caller enabled it, and the engine
     * chunks by the team it gets); either way its results do not depend on its thread count (engine.h). Dynamic
     * schedule: runs of different lengths balance; the schedule does not change any run's bits. */
#pragma omp parallel for num_threads(threads) default(none) shared(sims, n, n_steps, errs) schedule(dynamic, 1)
    for (long k = 0; k < n; k++) {
        errs[k].code = 0, errs[k].msg[0] = '\0';
        int rc = wf_sim_step(sims[k], n_steps, &errs[k]);
        if (rc && !errs[k].code) errs[k].code = rc;
    }
    for (size_t k = 0; k < n_sims; k++)
        if (errs[k].code) return errs[k].code;
    return 0;
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

/* Vehicles of a run on the road now. */
static size_t count(const WfSim *sim)
{
    const WfFleet *f = wf_sim_fleet(sim);
    return f ? f->n : wf_corridor_vehicles(wf_sim_corridor(sim))->n;
}

/* Speeds of a run's vehicles in road order (a ring: ring order, vehicle i + 1 leading i; a corridor: front first). */
static void speeds(const WfSim *sim, double *out)
{
    const WfFleet *f = wf_sim_fleet(sim);
    if (f) {
        memcpy(out, f->v_mps, f->n * sizeof *out);
        return;
    }
    const WfCorridorVehicles *vh = wf_corridor_vehicles(wf_sim_corridor(sim));
    for (size_t r = 0; r < vh->n; r++) out[r] = vh->v_mps[wf_corridor_slot(vh, r)];
}

int wf_sims_speeds(WfSim *const *sims, size_t n_sims, double *v_mps, size_t n, WfError *err)
{
    size_t total = 0;
    for (size_t k = 0; k < n_sims; k++) total += count(sims[k]);
    if (total != n)
        return wf_err(err, WF_EINPUT, "speeds: the %zu runs have %zu vehicles on the road, got room for %zu", n_sims,
                      total, n);
    for (size_t k = 0, at = 0; k < n_sims; k++) {
        speeds(sims[k], v_mps + at);
        at += count(sims[k]);
    }
    return 0;
}
