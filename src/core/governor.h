/* How many threads a run's steps take, chosen by timing them (time.thread_check_steps, docs/scenarios.md). Results
 * never depend on it: a step gives the same bits on any number of threads. What it guards against: on a machine
 * whose cores other processes also use, a step that meets its threads at a barrier waits for whichever thread the
 * system has descheduled, and two threads can be several times slower than one.
 *
 * The run steps on its chosen count (at first all its threads); every `interval` steps (after 8 steps at the start,
 * and twice `probe` steps after a switch, when the switch may have won by chance) it times `probe` steps
 * (interval / 16, at least one, fewer when they would last over WF_GOV_PROBE_S, or WF_GOV_PROBE_IDLE_S when the
 * threads had their cores) on the other count (one thread, or all of them) and switches when the probe did at
 * least 20 % more vehicle-steps per second of wall time (governor.c: WF_GOV_GAIN). A probe that loses doubles the
 * interval (up to 64 times `every`), so a steady machine pays for few probes; a switch sets it back to `every`. A
 * probe is cut short as soon as its steps so far took twice as long as the chosen count's: on a loaded machine a
 * step whose thread was descheduled can take a hundred times longer, and a whole probe of them would cost more than
 * it could save.
 *
 * A load that arrives while the chosen count runs ends its stretch at once: the chosen count's steps are timed in
 * chunks of WF_GOV_CHUNK, and a chunk at less than a quarter of the rate of the chunk before it (a process started
 * beside the run, say) starts the probe now instead of after the interval, which after a quiet hour is 64 times
 * `every` (65 536 steps, minutes of steps ten to a hundred times slower), and the probe is measured against that
 * chunk. A load that stays alarms once (the slow chunk becomes the reference); one slow step among a chunk's (an
 * interrupt) does not unless it took some 190 times the others. (Chunks of 16 at half the rate alarmed some 30 times
 * in 50 000 steps of an idle but noisy VM, each alarm a probe of one thread that cost more than it could save.)
 *
 * `settle` calls after every change of the count are taken on the new count but neither timed nor counted: where a
 * call lasts microseconds (a batch of RL environments), the first one on another count wakes the team's threads and
 * moves half the state to another core's cache, and alone it lost every probe of two threads on an idle machine. A
 * corridor's steps and a ring's windows last milliseconds: 0 there, so that a probe on a loaded machine costs one
 * slow call, not two. The run's first call is never timed (the team starts cold).
 *
 * Rings (src/core/engine.c), corridors (src/core/corridor.c) and RL batches (src/core/rl_batch.c) use it. Rings of
 * 10^4 and 10^5 vehicles on this project's 2-vCPU machine beside two busy processes ran on two threads at 0.13-0.90
 * and 0.67-1.07 of one thread's rate before they had one, 0.77-0.98 and 1.06-1.24 with it and windows of 64 steps
 * (runs of 1e8 vehicle-steps; 10^4 in runs ten times longer: 0.23-0.99 before, 0.96-1.05 with it; bench/README.md,
 * "Session 23"). */
#ifndef WAVEFUEL_CORE_GOVERNOR_H
#define WAVEFUEL_CORE_GOVERNOR_H

enum { WF_GOV_CHUNK = 64 }; /* steps of the chosen count timed together, each chunk against the one before */
/* s: a probe lasts no longer at the chosen count's rate (fewer steps than interval / 16 when those would); a step of
 * a ring of 10^7 vehicles takes 0.06 s on two threads, and 64 steps of it on one thread would cost seconds. Beside
 * busy processes, windows of one count vary twofold in rate: a probe needs tenths of a second. */
#define WF_GOV_PROBE_S 0.2
/* s: the same when the stretch before the probe had every thread running all the time (the process's CPU time at
 * least 90 % of threads x wall time): cores to spare, one thread loses by far, and a long probe would only cost (a
 * ring of 10^6 vehicles: 35 steps on one thread, 0.15 s, in a run of 160 steps that took 0.9 s) */
#define WF_GOV_PROBE_IDLE_S 0.02

typedef struct WfGovernor {
    int    n_max, now;          /* the run's threads; the threads of the next step */
    long   every, interval;     /* steps between probes: the base (0: never probe) and the current */
    long   left;                /* steps left in this stretch (the chosen count's, or the probe's) */
    int    probing;             /* the stretch is a probe */
    double wall_s[2], work[2];  /* wall time and vehicle-steps of the chosen count's stretch [0] and the probe [1] */
    long   steps[2];            /* and their steps */
    long   settle, unsettled;   /* steps not timed after a change of the count; those still to come */
    double chunk_wall_s, chunk_work; /* the chosen count's last steps, up to WF_GOV_CHUNK of them */
    double ref_wall_s, ref_work;     /* its WF_GOV_CHUNK steps before them (0: none since the last switch) */
    long   chunk_steps;
    long   probes, switches;    /* what it did (tests, benchmarks) */
    long   alarms;              /* stretches ended early by a slow chunk */
    long   short_probes;        /* probes kept short: every thread of the stretch before had its core */
    double (*wall_now)(void), (*cpu_now)(void); /* the clocks (util/clock.h; tests replace them) */
    double mark_wall_s, mark_cpu_s;             /* both as the chosen count's stretch began */
} WfGovernor;

/* n_max threads; every: time.thread_check_steps (0: always n_max); settle: calls not timed after a change. */
void wf_governor_init(WfGovernor *g, int n_max, long every, long settle);
/* The threads the next step takes. */
int  wf_governor_threads(const WfGovernor *g);
/* The steps left in the probe under way (LONG_MAX when none is): a time-blocked window should take no more, so that
 * a probe of a long road lasts WF_GOV_PROBE_S, not a whole window on the slower count. The chosen count's stretches
 * take whole windows: short ones meet the threads more often per step, and beside busy processes, where each meeting
 * waits for a descheduled thread, windows of 8 steps ran at half the rate of windows of 64 and lost every first
 * probe. */
long wf_governor_probe_left(const WfGovernor *g);
/* After a call that took `steps` steps on wf_governor_threads' count (a time-blocked window takes several): its
 * wall time (s) and its work (vehicle-steps). Intervals, probes and chunks count steps; `settle` counts calls. */
void wf_governor_done(WfGovernor *g, double wall_s, double work, long steps);

#endif
