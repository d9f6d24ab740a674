/* The threads of a run's steps, chosen by timing them (governor.h). */
#include "core/governor.h"

#include <limits.h>

#include "util/clock.h"

enum { WF_GOV_PROBE_PART = 16, WF_GOV_BACKOFF_MAX = 64, WF_GOV_FIRST = 8 };

/* How much more work per second a probe must do to switch: 20 %. Beside busy processes a probe's rate is a gamble:
 * a short probe of one thread measured 7-9e7 vehicle-steps/s where whole runs on one thread gave 6.4e7 (a ring of
 * 10^5 vehicles), and at 5 % the run lost the 1.1-1.2 times one thread's rate that two threads keep there over
 * windows of 64 steps; a ring of 10^4 vehicles, where two threads are 2.5 times slower, went back to them after
 * lucky probes. Where a count really wins (two threads on a quiet machine, one thread where two meet at barriers
 * every few milliseconds) it wins by far more. */
#define WF_GOV_GAIN 1.20

static long probe_steps(const WfGovernor *g)
{
    long p = g->interval / WF_GOV_PROBE_PART;
    return p > 0 ? p : 1;
}

/* Whether every thread of the chosen count ran all the time since its stretch began (the process's CPU time at least
 * 90 % of threads x wall time): a thread that waits for a core, or at a barrier for one that waits, runs less. */
static int cores_free(const WfGovernor *g)
{
    double wall_s = g->wall_now() - g->mark_wall_s, cpu_s = g->cpu_now() - g->mark_cpu_s;
    return wall_s > 0.0 && cpu_s >= 0.9 * (double)g->now * wall_s;
}

static void mark(WfGovernor *g) { g->mark_wall_s = g->wall_now(), g->mark_cpu_s = g->cpu_now(); }

/* The steps of the probe that begins: probe_steps, or as many as last probe_s at the rate of the chosen count's
 * stretch that just ended, at least one. */
static long probe_len(const WfGovernor *g, double probe_s)
{
    long p = probe_steps(g);
    if (g->steps[0] > 0 && g->wall_s[0] > 0.0) {
        double fit = probe_s * (double)g->steps[0] / g->wall_s[0];
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
                      .settle = settle > 0 ? settle : 0, .wall_now = wf_wall_now, .cpu_now = wf_cpu_now};
    /* the first call too, whatever settle: the team starts cold (a ring of 10^5 vehicles beside two busy processes
     * took its first 8 steps on two threads at half the rate of the steps after them, and lost its first probe) */
    g->unsettled = g->settle > 0 ? g->settle : 1;
    /* the first probe soon: on a busy machine a step on all threads can take a hundred times one thread's */
    g->left = WF_GOV_FIRST < 2 * probe_steps(g) ? WF_GOV_FIRST : 2 * probe_steps(g);
}

int wf_governor_threads(const WfGovernor *g) { return g->now; }

long wf_governor_probe_left(const WfGovernor *g) { return g->probing && g->left > 0 ? g->left : LONG_MAX; }

void wf_governor_done(WfGovernor *g, double wall_s, double work, long steps)
{
    if (!g->every) return;
    if (g->unsettled > 0) {
        if (--g->unsettled == 0 && !g->probing) mark(g); /* the chosen count's stretch is timed from here */
        return;
    }
    int p = g->probing;
    g->wall_s[p] += wall_s, g->work[p] += work, g->steps[p] += steps;
    int alarm = !p && slow_chunk(g, wall_s, work, steps);
    if (alarm) g->alarms++, g->left = 1; /* the load changed: probe now */
    /* a probe whose steps so far took twice as long as the chosen count's has lost */
    int lost = p && g->steps[0] && g->wall_s[1] > 2.0 * (double)g->steps[1] * g->wall_s[0] / (double)g->steps[0];
    if ((g->left -= steps) > 0 && !lost) return;
    int other = g->now == 1 ? g->n_max : 1;
    if (!p) { /* the chosen count's stretch is over: probe the other, briefly when its threads had their cores */
        int brief = !alarm && cores_free(g);
        g->short_probes += brief;
        g->probing = 1, g->now = other, g->probes++, g->unsettled = g->settle;
        g->left = probe_len(g, brief ? WF_GOV_PROBE_IDLE_S : WF_GOV_PROBE_S);
        return;
    }
    /* the probe is over: switch when it did WF_GOV_GAIN times the work per second
     * (work1 / wall1 > gain work0 / wall0) */
    int probe_won = !lost && g->work[1] * g->wall_s[0] > WF_GOV_GAIN * g->work[0] * g->wall_s[1];
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
    if (!g->unsettled) mark(g);
}
