/* A sweep's override keys checked against the scenario schema before the first run: a misspelled key used to fail
 * every run, one after the other, each after its start-up. */
#include <stdlib.h>
#include <string.h>

#include "util/hash.h"
#include "wavefuel/scenario.h"
#include "wavefuel/sweep.h"

/* The keys a run sets (the text before each '='), hashed in order: runs with the same keys share one check. */
static uint64_t keys_hash(const WfSweepRun *r)
{
    uint64_t h = WF_FNV1A64_INIT;
    for (size_t i = 0; i < r->n_set; i++) {
        const char *eq = strchr(r->set[i], '=');
        h = wf_fnv1a64(h, r->set[i], eq ? (size_t)(eq - r->set[i]) : strlen(r->set[i]));
        h = wf_fnv1a64(h, "\n", 1);
    }
    return h;
}

/* The scenario loader rejects keys nobody read only once every value has been read (config.c, check_unused), and
 * names an override's node by its origin "--set". So a load that succeeds has checked every key, a load that fails
 * with this prefix found one unknown, and any other failure (a bad value of this run) has not reached the check. */
static const char unknown_prefix[] = "--set: unknown key '";

int wf_sweep_check_keys(const WfSweep *sw, WfScenario **first, WfError *err)
{
    if (first) *first = NULL;
    uint64_t *done = calloc(sw->n_runs ? sw->n_runs : 1, sizeof *done); /* key sets checked, n_done of them */
    if (!done) return wf_err(err, WF_ESYS, "out of memory");
    size_t n_done = 0;
    int rc = 0;
    for (size_t i = 0; i < sw->n_runs && !rc; i++) {
        uint64_t h = keys_hash(&sw->runs[i]);
        size_t k = 0;
        while (k < n_done && done[k] != h) k++;
        if (k < n_done) continue;
        WfScenario *sc = NULL;
        WfError probe = {0};
        if (!wf_scenario_load_text(sw->scenario_path, sw->scenario_text, sw->runs[i].set, sw->runs[i].n_set, &sc,
                                   &probe)) {
            done[n_done++] = h;
            if (first && !*first) *first = sc;
            else wf_scenario_destroy(&sc);
        } else if (!strncmp(probe.msg, unknown_prefix, sizeof unknown_prefix - 1)) {
            rc = wf_err(err, WF_EINPUT, "%s: run %zu: %s (the scenario %s has no such key; no run started)", sw->path,
                        i, probe.msg, sw->scenario_path);
        }
        /* else: this run fails alone when it runs; the next run with the same keys checks them. */
    }
    free(done);
    if (rc && first) wf_scenario_destroy(first);
    return rc;
}
