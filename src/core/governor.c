/* The threads of a run's steps, chosen by timing them (governor.h). */
#include "core/governor.h"

#include <limits.h>

enum { WF_GOV_PROBE_PART = 16, WF_GOV_BACKOFF_MAX = 64, WF_GOV_FIRST = 8 };

static long probe_steps(const WfGovernor *g)
{
    long p = g->interval / WF_GOV_PROBE_PART;
    return p > 0 ? p : 1;
}

/* The steps of the probe that begins: probe_steps, or as many as last WF_GOV_PROBE_S at the rate of the chosen
 * count's stretch that just ended, at least one. */
static long probe_len(const WfGovernor *g)
{
    long p = probe_steps(g);
    if (g->steps[0] > 0 && g->wall_s[0] > 0.0) {
        double fit = WF_GOV_PROBE_S * (double)g->steps[0] / g->wall_s[0];
        if (fit < (double)p) p = fit >= 1.0 ? (long)fit : 1;
    }
    return p;
}

/* Whether the chosen count's last WF_GOV_CHUNK steps, this one included, did less than a quarter of the work per
 * second of the WF_GOV_CHUNK steps of it before them (on this count since the last switch; none yet: no). Chunks hold
 * the chosen count's steps only, across the probes between them. */
static int slow_chunk(WfGovernor *g, double wall_s, double work, long steps)
{
    g->chunk_wall_s += wall_s, g->chunk_work += work, g->chunk_steps += steps;
    if (g->chunk_steps < WF_GOV_CHUNK) return 0;
    /* chunk_work / chunk_wall_s < ref_work / ref_wall_s / 4, without dividing */
    int slow = g->ref_work > 0.0 && 4.0 * g->chunk_work * g->ref_wall_s < g->ref_work * g->chunk_wall_s;
    g->ref_wall_s = g->chunk_wall_s, g->ref_work = g->chunk_work; /* a load that stays alarms once */
    /* the probe then measures itself against this chunk, not against the quiet steps of the stretch before it */
    if (slow) g->wall_s[0] = g->chunk_wall_s, g->work[0] = g->chunk_work, g->steps[0] = g->chunk_steps;
    g->chunk_wall_s = g->chunk_work = 0.0, g->chunk_steps = 0;
    return slow;
}

void wf_governor_init(WfGovernor *g, int n_max, long every, long settle)
{
    *g = (WfGovernor){.n_max = n_max, .now = n_max, .every = n_max > 1 ? every : 0, .interval = every,
                      .settle = settle > 0 ? settle : 0};
    g->unsettled = g->settle; /* the first steps too: the team starts cold */
    /* the first probe soon: on a busy machine a step on all threads can take a hundred times one thread's */
    g->left = WF_GOV_FIRST < 2 * probe_steps(g) ? WF_GOV_FIRST : 2 * probe_steps(g);
}

int wf_governor_threads(const WfGovernor *g) { return g->now; }

long wf_governor_steps_left(const WfGovernor *g) { return g->every && g->left > 0 ? g->left : LONG_MAX; }

void wf_governor_done(WfGovernor *g, double wall_s, double work, long steps)
{
    if (!g->every) return;
    if (g->unsettled > 0) {
        g->unsettled--;
        return;
    }
    int p = g->probing;
    g->wall_s[p] += wall_s, g->work[p] += work, g->steps[p] += steps;
    if (!p && slow_chunk(g, wall_s, work, steps)) g->alarms++, g->left = 1; /* the load changed: probe now */
    /* a probe whose steps so far took twice as long as the chosen count's has lost */
    int lost = p && g->steps[0] && g->wall_s[1] > 2.0 * (double)g->steps[1] * g->wall_s[0] / (double)g->steps[0];
    if ((g->left -= steps) > 0 && !lost) return;
    int other = g->now == 1 ? g->n_max : 1;
    if (!p) { /* the chosen count's stretch is over: probe the other */
        g->probing = 1, g->now = other, g->left = probe_len(g), g->probes++, g->unsettled = g->settle;
        return;
    }
    /* the probe is over: switch when it did 5 % more work per second (work1 / wall1 > 1.05 work0 / wall0) */
    int probe_won = !lost && g->work[1] * g->wall_s[0] > 1.05 * g->work[0] * g->wall_s[1];
    if (probe_won) {
        g->switches++, g->interval = g->every; /* g->now stays the probe's count */
        g->chunk_wall_s = g->chunk_work = g->ref_wall_s = g->ref_work = 0.0, g->chunk_steps = 0;
    } else {
        g->now = other, g->unsettled = g->settle;
        if (g->interval < WF_GOV_BACKOFF_MAX * g->every) g->interval *= 2;
    }
    /* after a switch the new count is checked soon, as at the start: a probe can win by chance on a busy machine */
    g->probing = 0, g->left = probe_won ? 2 * probe_steps(g) : g->interval - probe_steps(g);
    if (g->left < 1) g->left = 1;
    g->wall_s[0] = g->wall_s[1] = g->work[0] = g->work[1] = 0.0;
    g->steps[0] = g->steps[1] = 0;
}
