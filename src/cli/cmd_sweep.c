/* `wavefuel sweep`: run every run of a sweep file (docs/sweeps.md) into one result table, resuming a table left by
 * an earlier, interrupted or extended, invocation. On one machine runs execute side by side, one per thread (threads
 * go inside the runs only when fewer runs than threads remain); built with -DWF_MPI (bin/wavefuel-mpi, `make mpi`)
 * the runs are handed out across MPI ranks by rank 0 (src/mpi/). Progress on stderr, summary on stdout. */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "cli/commands.h"
#include "wavefuel/sweep.h"
#ifdef WF_MPI
#include "mpi/sweep_mpi.h"
#endif

#define SAVE_EVERY_S 5.0 /* table snapshots while the sweep runs: what a killed sweep can lose */

static void help(FILE *out, const char *prog)
{
    fprintf(out,
            "usage: %s SWEEP.yaml [-o FILE.h5] [--threads N] [--per-run-files DIR] [--force]\n"
            "                      [--retry-failed] [--list] [-q]\n"
            "       mpirun -n K wavefuel-mpi SWEEP.yaml [same options]    (make mpi)\n\n"
            "Runs every run of the sweep (a base scenario with --set overrides: axes of values and seeds, or a list\n"
            "of runs; docs/sweeps.md) and writes one table, a row per run: its parameters, seed, status, error and\n"
            "every summary metric. The table is saved every %.0f s and at the end; a rerun resumes it, skipping the\n"
            "runs it holds as done (ok or failed). A failed run is recorded and the others go on.\n"
            "  -o, --output FILE      result table (default: the sweep's `output`, else output/NAME.h5)\n"
            "  --threads N            threads (default: OMP_NUM_THREADS or all cores): N runs side by side, one thread\n"
            "                         each; with fewer runs than threads left, the threads are shared inside runs.\n"
            "                         wavefuel-mpi: threads inside each run on every rank (default 1)\n"
            "  --per-run-files DIR    also keep each run's full result file, DIR/run_HASH.h5 (named in the table)\n"
            "  --force                start over: replace an existing table instead of resuming it\n"
            "  --retry-failed         run again the runs the table holds as failed\n"
            "  --list                 print each run's `wavefuel run` command, one per line, and run nothing\n"
            "  -q, --quiet            no progress, no summary (failures are still reported)\n"
            "Exit status: 0 every run ok, 1 some run failed (or the table could not be written), 2 bad input,\n"
            "3 interrupted (SIGINT/SIGTERM: runs in progress stop, the table is saved; rerun to continue).\n",
            prog, SAVE_EVERY_S);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void sleep_ms(long ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* The state shared by the coordinator (thread 0: progress, snapshots, MPI) and the worker threads. res[] and the
 * queues change only under the lock; a finished row never changes again, so the coordinator reads it unlocked
 * once it has seen it in done[]. */
typedef struct Exec {
    const WfSweep *sw;
    WfSweepResult *res;
    size_t        *todo, n_todo, next; /* runs to do, in table order; next one to hand out */
    size_t        *done, n_done;       /* finished (or interrupted) runs, in order of completion */
    size_t         n_reported, n_saved_at;
    int            local_active;       /* worker threads still running */
    int            abort;              /* a snapshot could not be written: hand out nothing more */
    WfSweepRunOpts opts;
    const char    *out_path;
    int            quiet, tty;
    double         t0, last_save, last_draw;
    size_t         n_ok, n_failed, n_interrupted, n_reused;
    WfSweepTiming  timing;
    WfError        save_err;
#ifdef _OPENMP
    omp_lock_t     lock;
#endif
#ifdef WF_MPI
    WfMpiPool     *pool;
#endif
} Exec;

static void lock(Exec *e)
{
#ifdef _OPENMP
    omp_set_lock(&e->lock);
#else
    (void)e;
#endif
}

static void unlock(Exec *e)
{
#ifdef _OPENMP
    omp_unset_lock(&e->lock);
#else
    (void)e;
#endif
}

static int take(void *ctx, size_t *run)
{
    Exec *e = ctx;
    lock(e);
    int got = !wf_cli_stop && !e->abort && e->next < e->n_todo;
    if (got) *run = e->todo[e->next++];
    unlock(e);
    return got;
}

static void finish(void *ctx, size_t run, const WfSweepResult *r)
{
    Exec *e = ctx;
    lock(e);
    e->res[run] = *r;
    e->done[e->n_done++] = run;
    unlock(e);
}

/* Runs until nothing is left to take; with report_each (no coordinator thread) reports after every run. */
static void report(Exec *e);
static void worker(Exec *e, int id, int report_each)
{
    WfSweepResult r;
    WfSweepRunOpts o = e->opts;
    o.worker = id;
    size_t k;
    wf_cli_h5_quiet_thread(); /* per-run files are written from this thread */
    while (take(e, &k)) {
        wf_sweep_run(e->sw, k, &o, &wf_cli_stop, &r);
        finish(e, k, &r);
        if (report_each) report(e);
    }
    lock(e);
    e->local_active--;
    unlock(e);
}

static int save(Exec *e)
{
    e->timing.wall_s = now_s() - e->t0;
    lock(e); /* rows being finished meanwhile wait: res[] must not change under the writer */
    WfError err = {0};
    int rc = wf_sweep_table_write(e->out_path, e->sw, e->res, &e->timing, &err);
    e->n_saved_at = e->n_done;
    if (rc && !e->abort) e->abort = 1, e->save_err = err;
    unlock(e);
    e->last_save = now_s();
    return rc;
}

static void draw_bar(Exec *e, int final)
{
    double t = now_s();
    if (!e->tty || e->quiet || (!final && t - e->last_draw < 0.2)) return;
    e->last_draw = t;
    size_t done = e->n_reported, total = e->n_todo;
    double wall = t - e->t0, eta = done ? wall * (double)(total - done) / (double)done : 0.0;
    int width = 30, filled = total ? (int)((double)width * (double)done / (double)total) : width;
    char bar[64];
    for (int i = 0; i < width; i++) bar[i] = i < filled ? '#' : '.';
    bar[width] = '\0';
    fprintf(stderr, "\r[%s] %zu/%zu runs  ok %zu  failed %zu  wall %.1f s  ETA %.0f s   ", bar, done, total, e->n_ok,
            e->n_failed, wall, eta);
    fflush(stderr);
}

/* Coordinator: report the runs finished since the last call, in completion order; save a snapshot when due. */
static void report(Exec *e)
{
    lock(e);
    size_t upto = e->n_done;
    unlock(e);
    for (size_t j = e->n_reported; j < upto; j++) {
        size_t k = e->done[j];
        const WfSweepResult *r = &e->res[k];
        e->n_ok += r->status == WF_RUN_OK;
        e->n_failed += r->status == WF_RUN_FAILED;
        e->n_interrupted += r->status == WF_RUN_PENDING;
        if (r->status == WF_RUN_FAILED) {
            char cmd[8192];
            if (e->tty && !e->quiet) fprintf(stderr, "\n");
            fprintf(stderr, "wavefuel sweep: run %zu failed: %s\n", k, r->error);
            if (!wf_sweep_command(e->sw, k, cmd, sizeof cmd)) fprintf(stderr, "  reproduce: %s\n", cmd);
        } else if (!e->tty && !e->quiet) {
            /* Not a terminal (a log): one line per run. */
            fprintf(stderr, "[%zu/%zu] run %zu %s (%.2f s)\n", j + 1, e->n_todo, k,
                    r->status == WF_RUN_OK ? "ok" : "interrupted", r->wall_s);
        }
    }
    e->n_reported = upto;
    draw_bar(e, 0);
    if (upto > e->n_saved_at && now_s() - e->last_save >= SAVE_EVERY_S) save(e);
}

/* Threads 1..W run, thread 0 coordinates (and, with MPI, feeds the other ranks); it sleeps 1 ms between polls. */
static void coordinate(Exec *e)
{
    for (;;) {
        int remote_busy = 0;
#ifdef WF_MPI
        remote_busy = wf_mpi_pool_poll(e->pool, take, finish, e);
#endif
        report(e);
        lock(e);
        int idle = e->local_active == 0 && remote_busy == 0;
        int nothing_left = wf_cli_stop || e->abort || e->next == e->n_todo;
        unlock(e);
        if (idle && nothing_left) break;
        sleep_ms(1);
    }
    report(e);
}

/* Without OpenMP (or if the runtime gives one thread): run here, then report. With MPI and other ranks, rank 0
 * only coordinates: a run here would leave their answers waiting for its length. */
static void serial(Exec *e)
{
    int run_here = 1;
#ifdef WF_MPI
    run_here = wf_mpi_size() == 1;
#endif
    e->local_active = run_here;
    if (run_here) worker(e, 0, 1);
    coordinate(e);
}

static void execute(Exec *e, int workers)
{
#ifdef _OPENMP
    omp_init_lock(&e->lock);
    /* Nested parallelism only when runs get several threads; otherwise their loops stay on their thread. */
    omp_set_max_active_levels(e->opts.threads > 1 ? 2 : 1);
#pragma omp parallel num_threads(workers + 1) default(none) shared(e)
    {
#pragma omp master
        {
            e->local_active = omp_get_num_threads() - 1;
#ifndef WF_MPI
            e->timing.workers = e->local_active > 0 ? e->local_active : 1; /* the runtime may give fewer threads */
#endif
        }
#pragma omp barrier
        if (e->local_active == 0)
            serial(e);
        else if (omp_get_thread_num() == 0)
            coordinate(e);
        else
#ifdef WF_MPI
            worker(e, 0, 0); /* rank 0's own runs are recorded as rank 0's */
#else
            worker(e, omp_get_thread_num() - 1, 0);
#endif
    }
    omp_destroy_lock(&e->lock);
#else
    (void)workers;
    serial(e);
#endif
}

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static int make_dir(const char *dir, WfError *err)
{
    if (mkdir(dir, 0777) == 0 || errno == EEXIST) return 0;
    return wf_err(err, WF_EINPUT, "--per-run-files %s: cannot create the directory: %s", dir, strerror(errno));
}

typedef struct Options {
    const char *sweep, *out, *per_run_dir;
    long        threads;
    int         force, retry_failed, list, quiet;
} Options;

static int parse_args(int argc, char **argv, Options *o, int rank)
{
    static const struct option opts[] = {{"output", required_argument, 0, 'o'},
                                         {"threads", required_argument, 0, 't'},
                                         {"per-run-files", required_argument, 0, 'p'},
                                         {"force", no_argument, 0, 'f'},
                                         {"retry-failed", no_argument, 0, 'r'},
                                         {"list", no_argument, 0, 'l'},
                                         {"quiet", no_argument, 0, 'q'},
                                         {"help", no_argument, 0, 'h'},
                                         {0, 0, 0, 0}};
    FILE *msg = rank == 0 ? stderr : NULL; /* under MPI only rank 0 speaks */
    int c;
    memset(o, 0, sizeof *o);
    optind = 1;
    opterr = rank == 0;
    while ((c = getopt_long(argc, argv, "o:qh", opts, NULL)) != -1) {
        switch (c) {
        case 'o': o->out = optarg; break;
        case 't':
            if (wf_parse_long(optarg, 1, 4096, &o->threads)) {
                if (msg) fprintf(msg, "wavefuel sweep: --threads expects an integer in [1, 4096] (got '%s')\n", optarg);
                return 2;
            }
            break;
        case 'p': o->per_run_dir = optarg; break;
        case 'f': o->force = 1; break;
        case 'r': o->retry_failed = 1; break;
        case 'l': o->list = 1; break;
        case 'q': o->quiet = 1; break;
        case 'h':
            if (msg) help(stdout, strcmp(argv[0], "sweep") ? argv[0] : "wavefuel sweep");
            return -1;
        default:
            if (msg) help(stderr, strcmp(argv[0], "sweep") ? argv[0] : "wavefuel sweep");
            return 2;
        }
    }
    if (argc - optind != 1) {
        if (msg) fprintf(msg, "wavefuel sweep: expected one SWEEP.yaml (see --help)\n");
        return 2;
    }
    o->sweep = argv[optind];
    return 0;
}

/* Rows to start from: pending everywhere, or the finished rows of an existing table. */
static int prepare_rows(const WfSweep *sw, const Options *o, const char *out, WfSweepResult *res, size_t *n_reused,
                        WfError *err)
{
    char partial[1100];
    snprintf(partial, sizeof partial, "%s.partial", out);
    for (size_t i = 0; i < sw->n_runs; i++) res[i].seed = sw->runs[i].seed;
    *n_reused = 0;
    if (o->force) return 0;
    if (exists(partial))
        return wf_err(err, WF_EINPUT,
                      "%s exists: another sweep is writing this table, or one was killed while saving it; remove it "
                      "(the table itself is intact) or use --force",
                      partial);
    if (!exists(out)) return 0;
    WfSweepSaved saved;
    int rc = wf_sweep_table_read(out, &saved, err);
    if (rc) return wf_err_prefix(err, "cannot resume (use --force to replace it, or -o another file): ");
    rc = wf_sweep_resume(sw, &saved, o->retry_failed, res, n_reused, err);
    wf_sweep_saved_free(&saved);
    if (rc) wf_err_prefix(err, "%s: ", out);
    return rc;
}

int wf_cmd_sweep(int argc, char **argv)
{
    int rank = 0, n_ranks = 1;
    (void)n_ranks; /* used by the OpenMP and MPI builds */
#ifdef WF_MPI
    rank = wf_mpi_rank();
    n_ranks = wf_mpi_size();
#endif
    Options o;
    int status = parse_args(argc, argv, &o, rank);
    if (status) return status < 0 ? 0 : status;
    WfError err = {0};
    WfSweep *sw = NULL;
    int rc = rank == 0 ? wf_sweep_load(o.sweep, &sw, &err) : 0;
#ifdef WF_MPI
    rc = wf_mpi_share_sweep(rc, o.sweep, &sw, &err);
    if (rc) return rank == 0 ? wf_cli_fail(&err) : rc;
#else
    if (rc) return wf_cli_fail(&err);
#endif
    wf_cli_catch_stop();

    /* Threads: on one machine, workers = min(threads, runs to do), each run getting threads / workers of them
     * (1 unless runs are fewer than threads). Under MPI, --threads is per run on every rank (default 1). */
    long threads = o.threads;
#ifdef _OPENMP
    if (!threads) threads = n_ranks > 1 ? 1 : omp_get_max_threads();
#else
    threads = 1;
#endif
    /* Other ranks create it too (their file system may be their own); if they cannot, their runs fail alone. */
    if (o.per_run_dir && make_dir(o.per_run_dir, &err) && rank == 0) {
        wf_sweep_destroy(&sw);
#ifdef WF_MPI
        WfMpiPool *none = NULL;
        if (!wf_mpi_pool_create(&none, &err)) wf_mpi_pool_destroy(&none); /* release the other ranks */
#endif
        return wf_cli_fail(&err);
    }
#ifdef WF_MPI
    if (rank != 0) {
        WfSweepRunOpts ro = {.threads = (int)threads, .per_run_dir = o.per_run_dir, .worker = rank};
        wf_mpi_serve(sw, &ro, &wf_cli_stop);
        wf_sweep_destroy(&sw);
        return 0;
    }
    WfMpiPool *pool = NULL;
    if (wf_mpi_pool_create(&pool, &err)) {
        wf_sweep_destroy(&sw);
        return wf_cli_fail(&err);
    }
#endif
    const char *out = o.out ? o.out : sw->output;
    Exec e;
    memset(&e, 0, sizeof e);
    e.sw = sw;
    e.res = calloc(sw->n_runs, sizeof *e.res);
    e.todo = calloc(sw->n_runs, sizeof *e.todo);
    e.done = calloc(sw->n_runs, sizeof *e.done);
    if (!e.res || !e.todo || !e.done) rc = wf_err(&err, WF_ESYS, "out of memory for %zu runs", sw->n_runs);
    if (!rc && o.list) {
        size_t len = 1 << 16;
        char *cmd = malloc(len);
        for (size_t i = 0; cmd && i < sw->n_runs; i++)
            printf("%s\n", wf_sweep_command(sw, i, cmd, len) ? "# (command too long)" : cmd);
        free(cmd);
        goto done;
    }
    if (!rc) rc = prepare_rows(sw, &o, out, e.res, &e.n_reused, &err);
    if (rc) {
        status = wf_cli_fail(&err);
        goto done;
    }
    for (size_t i = 0; i < sw->n_runs; i++)
        if (e.res[i].status == WF_RUN_PENDING) e.todo[e.n_todo++] = i;
    size_t n_failed_before = 0;
    for (size_t i = 0; i < sw->n_runs; i++) n_failed_before += e.res[i].status == WF_RUN_FAILED;
    if (e.n_todo == 0) {
        if (!o.quiet)
            printf("wavefuel sweep: %s: all %zu runs already done in %s (%zu failed); nothing to run\n", sw->name,
                   sw->n_runs, out, n_failed_before);
        status = n_failed_before ? 1 : 0;
        goto done;
    }
    int workers = 1;
#ifdef WF_MPI
    e.pool = pool;
    e.timing.mode = "mpi";
    workers = n_ranks;
    e.opts.threads = (int)threads;
    int local_workers = 1;
#else
    e.timing.mode = "threads";
    workers = (size_t)threads < e.n_todo ? (int)threads : (int)e.n_todo;
    e.opts.threads = (int)(threads / workers);
    int local_workers = workers;
#endif
    e.opts.per_run_dir = o.per_run_dir;
    e.timing.workers = workers;
    e.timing.threads_per_run = e.opts.threads;
    e.out_path = out;
    e.quiet = o.quiet;
    e.tty = isatty(STDERR_FILENO);
    e.t0 = e.last_save = now_s();
    if (!o.quiet) {
        if (e.n_reused)
            fprintf(stderr, "wavefuel sweep: resuming %s: %zu of %zu runs already done\n", out, e.n_reused,
                    sw->n_runs);
        fprintf(stderr, "wavefuel sweep: %s: %zu runs to do on %d worker%s (%s) x %d thread%s per run\n", sw->name,
                e.n_todo, workers, workers > 1 ? "s" : "", e.timing.mode, e.opts.threads,
                e.opts.threads > 1 ? "s" : "");
    }
    execute(&e, local_workers);
    if (e.tty && !o.quiet) fprintf(stderr, "\n");
    int save_rc = e.abort ? 1 : save(&e);
    if (save_rc) {
        status = wf_cli_fail(&e.save_err);
        goto done;
    }
    double wall = now_s() - e.t0;
    size_t pending = 0, failed = 0;
    for (size_t i = 0; i < sw->n_runs; i++) {
        pending += e.res[i].status == WF_RUN_PENDING;
        failed += e.res[i].status == WF_RUN_FAILED;
    }
    if (!o.quiet) {
        size_t ran = e.n_ok + e.n_failed;
        printf("wavefuel sweep: %s: %zu runs: %zu ok, %zu failed, %zu pending; ran %zu now in %.3f s (%.4g runs/h) "
               "on %d worker%s x %d thread%s\n",
               sw->name, sw->n_runs, sw->n_runs - pending - failed, failed, pending, ran, wall,
               wall > 0 ? 3600.0 * (double)ran / wall : 0.0, e.timing.workers, e.timing.workers > 1 ? "s" : "",
               e.opts.threads,
               e.opts.threads > 1 ? "s" : "");
        printf("result: %s\n", out);
    }
    if (pending) {
        fprintf(stderr, "wavefuel: sweep interrupted: %zu runs pending, saved in %s; run the same command again to "
                "continue\n", pending, out);
        status = 3;
    } else if (failed) {
        fprintf(stderr, "wavefuel: %zu of %zu runs failed (status and error in %s, /runs)\n", failed, sw->n_runs, out);
        status = 1;
    }
done:
#ifdef WF_MPI
    wf_mpi_pool_destroy(&pool);
#endif
    free(e.res);
    free(e.todo);
    free(e.done);
    wf_sweep_destroy(&sw);
    return status;
}
