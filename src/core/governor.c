/* The threads of a run's steps, chosen by timing them (governor.h). */
#include "core/governor.h"

enum { WF_GOV_PROBE_PART = 16, WF_GOV_BACKOFF_MAX = 64 };

static long probe_steps(const WfGovernor *g)
{
    long p = g->interval / WF_GOV_PROBE_PART;
    return p > 0 ? p : 1;
}

void wf_governor_init(WfGovernor *g, int n_max, long every)
{
    *g = (WfGovernor){.n_max = n_max, .now = n_max, .every = n_max > 1 ? every : 0, .interval = every};
    g->left = g->interval - probe_steps(g);
    if (g->left < 1) g->left = 1;
}

int wf_governor_threads(const WfGovernor *g) { return g->now; }

void wf_governor_done(WfGovernor *g, double wall_s, double work)
{
    if (!g->every) return;
    g->wall_s[g->probing] += wall_s, g->work[g->probing] += work;
    if (--g->left > 0) return;
    int other = g->now == 1 ? g->n_max : 1;
    if (!g->probing) { /* the chosen count's stretch is over: probe the other */
        g->probing = 1, g->now = other, g->left = probe_steps(g), g->probes++;
        return;
    }
    /* the probe is over: keep the faster (rates compared as work0 / wall0 < work1 / wall1, without dividing) */
    int probe_won = g->work[1] * g->wall_s[0] > g->work[0] * g->wall_s[1];
    if (probe_won) {
        g->switches++, g->interval = g->every; /* g->now stays the probe's count */
    } else {
        g->now = other;
        if (g->interval < WF_GOV_BACKOFF_MAX * g->every) g->interval *= 2;
    }
    g->probing = 0, g->left = g->interval - probe_steps(g);
    if (g->left < 1) g->left = 1;
    g->wall_s[0] = g->wall_s[1] = g->work[0] = g->work[1] = 0.0;
}
