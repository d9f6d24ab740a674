/* The thread governor of corridors (src/core/governor.h, time.thread_check_steps) fed with made-up step times: it
 * starts on all threads, probes one thread soon (after 8 steps) and then every `every` steps for every/16
 * steps, switches when the probe did 5 % more work per second, backs off (doubling the interval, up to 64 times) while
 * probes lose, cuts short a probe whose steps took twice as long as the chosen count's, and never probes with one
 * thread or every = 0; a load that arrives in a stretch ends it after a chunk of WF_GOV_CHUNK steps at under a
 * quarter of the chunk before, an interrupt does not. tests/test_engine_paths.c checks that switching threads every
 * step keeps the bits. */
#include <limits.h>
#include <stdio.h>

#include "core/governor.h"
#include "wf_test.h"

/* The first call after init, on all threads, which the governor does not time (the team starts cold): even a call
 * of 10 s changes nothing of what it counts. */
static void first_call(WfGovernor *g)
{
    long left = g->left;
    wf_governor_done(g, 10.0, 1000.0, 1);
    CHECK(g->steps[0] == 0 && g->wall_s[0] == 0.0 && g->left == left && wf_governor_threads(g) == g->n_max,
          "the first call was timed: %ld steps, %g s, %ld steps left (%ld)", g->steps[0], g->wall_s[0], g->left, left);
}

/* Steps of the governor where a step on n threads takes cost(n) seconds; returns the steps taken on one thread. */
static long drive(WfGovernor *g, long steps, double one_thread_s, double all_threads_s)
{
    long on_one = 0;
    for (long s = 0; s < steps; s++) {
        int n = wf_governor_threads(g);
        on_one += n == 1;
        wf_governor_done(g, n == 1 ? one_thread_s : all_threads_s, 1000.0, 1);
    }
    return on_one;
}

static void test_keeps_the_faster(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 64, 0);
    CHECK(wf_governor_threads(&g) == 2, "starts on %d threads, not all", wf_governor_threads(&g));
    first_call(&g);
    /* two threads faster: the first probe (steps 8..11 on one thread) loses, the interval doubles */
    long one = drive(&g, 12, 2e-3, 1e-3);
    CHECK(one == 4 && g.probes == 1 && g.switches == 0 && g.interval == 128,
          "%ld steps on one thread, %ld probes, %ld switches, interval %ld", one, g.probes, g.switches, g.interval);
    /* one thread 4 % faster: no switch (the margin is 20 %) */
    drive(&g, 128, 1.0e-3, 1.04e-3);
    CHECK(g.switches == 0 && g.interval == 256, "%ld switches at 4 %%, interval %ld", g.switches, g.interval);
    /* a loaded machine: two threads now 8 times slower. The first chunk of WF_GOV_CHUNK such steps, at a fifteenth of
     * the quiet chunk's rate before it, ends the stretch (without it, the interval would: 256 - 16 steps); the probe of
     * one thread (12 steps: WF_GOV_PROBE_S at 16 ms a step, fewer than interval / 16) wins; two threads, probed 8 steps
     * later and again after the interval less a probe, lose both (cut short after a step), so the interval is 256
     * again */
    long to_switch = 0;
    for (long s = 0; s < 256; s++) {
        int n = wf_governor_threads(&g);
        wf_governor_done(&g, n == 1 ? 2e-3 : 16e-3, 1000.0, 1);
        to_switch += !g.switches;
    }
    CHECK(g.switches == 1 && wf_governor_threads(&g) == 1 && g.interval == 256 && g.alarms == 1,
          "after the load: %ld switches, %d threads, interval %ld, %ld alarms", g.switches, wf_governor_threads(&g),
          g.interval, g.alarms);
    CHECK(to_switch == WF_GOV_CHUNK + 11, "switched after %ld loaded steps (a chunk on two threads and the probe's "
          "12, decided at its last)", to_switch);
    /* still loaded, two threads now a hundred times slower: each probe of them is cut short after its first step,
     * and probes come ever more rarely */
    long probes0 = g.probes, slow = 0;
    for (long s = 0; s < 64 * 64 * 8; s++) {
        int n = wf_governor_threads(&g);
        slow += n == 2;
        wf_governor_done(&g, n == 1 ? 2e-3 : 0.2, 1000.0, 1);
    }
    /* probes after 193 steps (the stretch's rest), then at intervals 512, 1024, 2048 and 4096 every interval less
     * a sixteenth plus the probe's step: steps 194, 675, 1636, 3557, then every 3841 steps up to 30444 */
    CHECK(g.interval == 64 * 64 && g.probes - probes0 == 11 && slow == g.probes - probes0 && g.alarms == 1,
          "interval %ld (64 x 64 expected), %ld probes (11: 4 while the interval doubles, then one every 3841 steps), "
          "%ld steps on two threads (one per probe), %ld alarms (1)", g.interval, g.probes - probes0, slow, g.alarms);
    /* the load goes: the next probe of two threads wins and the run goes back to them */
    drive(&g, 64 * 64 * 2, 2e-3, 1e-3);
    CHECK((wf_governor_threads(&g) == 2 || g.probing) && g.switches == 2, "%d threads, %ld switches after the load went",
          wf_governor_threads(&g), g.switches);
}

/* As drive, but the first step on all threads after a step on one costs warm_s (waking the team, moving caches). */
static long drive_warm(WfGovernor *g, long steps, double one_thread_s, double all_threads_s, double warm_s)
{
    long on_all = 0;
    int last = wf_governor_threads(g);
    for (long s = 0; s < steps; s++) {
        int n = wf_governor_threads(g);
        on_all += n > 1;
        wf_governor_done(g, n == 1 ? one_thread_s : n != last ? warm_s : all_threads_s, 1000.0, 1);
        last = n;
    }
    return on_all;
}

/* settle: the first step after a change of the count is not timed (an RL batch's steps last microseconds, and the
 * warm-up of a team would decide alone), and a probe lasts its steps plus that one. */
static void test_settle(void)
{
    long back[2], on_all[2];
    for (long settle = 0; settle < 2; settle++) {
        WfGovernor g;
        wf_governor_init(&g, 2, 64, settle);
        /* loaded: two threads 10 times slower; the run goes to one thread, and each probe of two is cut short */
        drive_warm(&g, 16, 1e-3, 10e-3, 20e-3); /* the first probe, of one thread, wins */
        long probes0 = g.probes;
        on_all[settle] = drive_warm(&g, 1024, 1e-3, 10e-3, 20e-3);
        CHECK(wf_governor_threads(&g) == 1 && g.switches == 1, "settle %ld, loaded: %d threads, %ld switches",
              settle, wf_governor_threads(&g), g.switches);
        on_all[settle] -= (g.probes - probes0) * (1 + settle); /* a step a probe, and the settling one */
        /* the load goes: two threads twice as fast, but the first step after one thread 20 times slower */
        drive_warm(&g, 64 * 64, 1e-3, 0.5e-3, 20e-3);
        back[settle] = g.switches;
    }
    /* the first step of all is a change too (the team starts cold) */
    WfGovernor g;
    wf_governor_init(&g, 2, 64, 1);
    wf_governor_done(&g, 1.0, 1000.0, 1);
    wf_governor_done(&g, 1e-3, 1000.0, 1);
    CHECK(g.steps[0] == 1 && g.wall_s[0] == 1e-3, "the first step timed (%ld steps timed, %g s)", g.steps[0],
          g.wall_s[0]);
    CHECK(on_all[0] == 0 && on_all[1] == 0, "steps on two threads besides the probes' (settle 0, 1): %ld, %ld",
          on_all[0], on_all[1]);
    CHECK(back[1] == 2 && back[0] == 1, "switches after the load went: settle 1 %ld (back to two threads), settle 0 "
          "%ld (every probe of two threads lost by its warm-up)", back[1], back[0]);
}

/* A load that arrives in the middle of a long stretch: after a quiet hour the interval is 64 times `every`, and
 * without the chunks' check the run would keep its two threads, now 30 times slower, until the next probe. */
static void test_load_arrives(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 1024, 0);
    drive(&g, 200000, 2e-3, 1e-3); /* quiet: every probe of one thread loses */
    CHECK(g.interval == 64 * 1024 && g.switches == 0 && wf_governor_threads(&g) == 2 && !g.probing,
          "quiet: interval %ld, %ld switches", g.interval, g.switches);
    long left = g.left, alarms0 = g.alarms;
    CHECK(left > 1000, "the stretch ends in %ld steps: the test needs a long one", left);
    /* one step 100 times slower (an interrupt) moves its chunk's mean by (63 + 100) / 64 < 4: no alarm */
    for (long s = 0; s < 4 * WF_GOV_CHUNK; s++) wf_governor_done(&g, s == 20 ? 100e-3 : 1e-3, 1000.0, 1);
    CHECK(g.alarms == alarms0 && !g.probing && g.left == left - 4 * WF_GOV_CHUNK, "an interrupt raised %ld alarms",
          g.alarms - alarms0);
    /* the load: two threads 30 times slower, one thread twice; an alarm after at most two chunks, then the probe of
     * one thread (the faster count, so never cut short) wins. The probe lasts WF_GOV_PROBE_S at the rate of the chunk
     * that alarmed (a sixteenth of the interval would be 4096 steps; at the quiet rate before, 200) */
    long steps = 0, on_two = 0, probe = 0, expect = 0;
    while (g.switches == 0 && steps < 10000) {
        int n = wf_governor_threads(&g);
        on_two += n == 2;
        wf_governor_done(&g, n == 1 ? 4e-3 : 30e-3, 1000.0, 1);
        steps++;
        if (g.probing && !probe) probe = g.left, expect = (long)(WF_GOV_PROBE_S * (double)g.steps[0] / g.wall_s[0]);
    }
    CHECK(g.switches == 1 && g.alarms == alarms0 + 1 && on_two <= 2 * WF_GOV_CHUNK && steps == on_two + probe &&
              probe == expect && probe >= 1 && probe < 50,
          "switched after %ld loaded steps, %ld of them on two threads (at most two chunks), a probe of %ld steps "
          "(%ld expected), %ld alarms", steps, on_two, probe, expect, g.alarms - alarms0);
}

static void test_never_probes(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 0, 0);
    CHECK(drive(&g, 10000, 1e-3, 9e-3) == 0 && g.probes == 0, "every = 0 probed (%ld)", g.probes);
    wf_governor_init(&g, 1, 64, 0);
    CHECK(drive(&g, 10000, 1e-3, 9e-3) == 10000 && g.probes == 0, "one thread probed (%ld)", g.probes);
}

/* The margin: the other count must be 20 % faster to be chosen, one thread or all. */
static void test_margins(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 64, 0);
    first_call(&g);
    drive(&g, 200, 1.0e-3 / 1.15, 1.0e-3); /* one thread 15 % faster: every probe of it loses */
    CHECK(g.probes >= 2 && g.switches == 0 && wf_governor_threads(&g) == 2, "one thread 15 %% faster: %ld probes, "
          "%ld switches", g.probes, g.switches);
    drive(&g, 2000, 1.0e-3 / 1.25, 1.0e-3); /* 25 % faster: the next probe wins */
    CHECK(g.switches == 1 && wf_governor_threads(&g) == 1, "one thread 25 %% faster: %ld switches, %d threads",
          g.switches, wf_governor_threads(&g));
    drive(&g, 64 * 64 * 2, 1.0e-3, 1.0e-3 / 1.15); /* all threads 15 % faster: not enough */
    CHECK(g.switches == 1 && (wf_governor_threads(&g) == 1 || g.probing), "all threads 15 %% faster: %ld switches, %d "
          "threads", g.switches, wf_governor_threads(&g));
    drive(&g, 64 * 64 * 2, 1.0e-3, 1.0e-3 / 1.25); /* 25 % faster: back to them at the next probe */
    CHECK(g.switches == 2 && (wf_governor_threads(&g) == 2 || g.probing), "all threads 25 %% faster: %ld switches, %d "
          "threads", g.switches, wf_governor_threads(&g));
}

/* A ring of 10^7 vehicles: a step takes 0.1 s on two threads, 0.19 s on one (under twice: not cut short). The probes
 * last WF_GOV_PROBE_S at the chosen count's rate, here two steps, not interval / 16 = 64 of them (6 s longer a probe);
 * wf_governor_probe_left says how many steps of the probe are left (a window is cut there), and nothing outside a
 * probe. */
static void test_probe_time_cap(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 1024, 0);
    first_call(&g);
    CHECK(wf_governor_probe_left(&g) == LONG_MAX, "no probe under way: %ld steps left", wf_governor_probe_left(&g));
    long one = drive(&g, 8, 0.19, 0.1);
    CHECK(one == 0 && g.probing && wf_governor_probe_left(&g) == 2, "after 8 steps: %ld on one thread, probing %d, a "
          "probe of %ld steps (2)", one, g.probing, wf_governor_probe_left(&g));
    one = drive(&g, 2, 0.19, 0.1);
    CHECK(one == 2 && !g.probing && wf_governor_threads(&g) == 2 && wf_governor_probe_left(&g) == LONG_MAX &&
              g.left == 2048 - 128,
          "the probe lost: %d threads next, %ld steps to the next probe (1920)", wf_governor_threads(&g), g.left);
}

/* Made-up clocks: the wall advances as the made-up calls say; the process's CPU time by cpu_per_wall times that. */
static double fake_wall_s, fake_cpu_per_wall;
static double fake_wall(void) { return fake_wall_s; }
static double fake_cpu(void) { return fake_wall_s * fake_cpu_per_wall; }

static long drive_clocked(WfGovernor *g, long steps, double one_thread_s, double all_threads_s)
{
    long on_one = 0;
    for (long s = 0; s < steps; s++) {
        int n = wf_governor_threads(g);
        double t = n == 1 ? one_thread_s : all_threads_s;
        on_one += n == 1;
        fake_wall_s += t;
        wf_governor_done(g, t, 1000.0, 1);
    }
    return on_one;
}

/* The ring of test_probe_time_cap with both threads busy all the time (CPU time 1.95 s per second): the probe is
 * WF_GOV_PROBE_IDLE_S long, a step; with CPU time 1.2 s per second (threads waiting for cores), WF_GOV_PROBE_S, two. */
static void test_brief_probe_when_idle(void)
{
    static const double cpu_per_wall[] = {1.95, 1.2};
    static const long expect[] = {1, 2};
    for (int j = 0; j < 2; j++) {
        WfGovernor g;
        wf_governor_init(&g, 2, 1024, 0);
        g.wall_now = fake_wall, g.cpu_now = fake_cpu;
        fake_wall_s = 100.0, fake_cpu_per_wall = cpu_per_wall[j];
        drive_clocked(&g, 9, 0.19, 0.1); /* the first call (not timed), then 8 */
        CHECK(g.probing && wf_governor_probe_left(&g) == expect[j] && g.short_probes == (j == 0),
              "CPU %.2f s per s: a probe of %ld steps (%ld expected), %ld short", cpu_per_wall[j],
              wf_governor_probe_left(&g), expect[j], g.short_probes);
    }
}

/* A ring's time-blocked windows: one call takes k steps, and the intervals, probes and chunks count steps, not calls.
 * With every = 1024 and windows of 16 steps (8 ms on two threads, so WF_GOV_PROBE_S does not cut the probes): the first
 * probe after the first window (8 steps due), of 64 steps (four windows) that lose, then the next after 2048 - 128
 * steps (120 windows); a load that arrives alarms after one chunk of WF_GOV_CHUNK steps (four windows) at under a
 * quarter of the rate of the four before. */
static void test_windows_count_steps(void)
{
    WfGovernor g;
    wf_governor_init(&g, 2, 1024, 0);
    first_call(&g);
    long on_one = 0;
    for (long w = 0; w < 125; w++) {
        int n = wf_governor_threads(&g);
        on_one += n == 1;
        wf_governor_done(&g, n == 1 ? 16e-3 : 8e-3, 16000.0, 16);
        if (w == 4)
            CHECK(g.probes == 1 && on_one == 4 && g.interval == 2048 && wf_governor_threads(&g) == 2,
                  "after 5 windows: %ld probes, %ld windows on one thread (4), interval %ld (2048)", g.probes, on_one,
                  g.interval);
    }
    CHECK(g.probes == 2 && on_one == 4 && wf_governor_threads(&g) == 1 && g.probing,
          "after 125 windows: %ld probes (the second begins), %ld windows on one thread, %d threads next", g.probes,
          on_one, wf_governor_threads(&g));
    /* the second probe loses too; then the load: two threads 8 times slower */
    for (long w = 0; w < 8; w++) wf_governor_done(&g, wf_governor_threads(&g) == 1 ? 16e-3 : 8e-3, 16000.0, 16);
    long alarms0 = g.alarms, w = 0;
    while (!g.probing && w < 100) wf_governor_done(&g, 64e-3, 16000.0, 16), w++;
    CHECK(g.alarms == alarms0 + 1 && w <= 2 * WF_GOV_CHUNK / 16,
          "the load: an alarm after %ld windows (at most two chunks of %d steps), %ld alarms", w, WF_GOV_CHUNK,
          g.alarms - alarms0);
}

int main(void)
{
    RUN(test_keeps_the_faster);
    RUN(test_settle);
    RUN(test_load_arrives);
    RUN(test_never_probes);
    RUN(test_windows_count_steps);
    RUN(test_probe_time_cap);
    RUN(test_margins);
    RUN(test_brief_probe_when_idle);
    TEST_EXIT();
}
