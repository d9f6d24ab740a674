/* `wavefuel sweep`: run every run of a sweep file (docs/sweeps.md) into one result table, resuming a table left by
 * an earlier, interrupted or extended, invocation. The library's scheduler (wf_sweep_execute) runs them; this file
 * parses options, decides the threads, prints progress on stderr and the summary on stdout. Built with -DWF_MPI
 * (bin/wavefuel-mpi, `make mpi`) the other MPI ranks are the scheduler's remote workers (src/mpi/). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "cli/commands.h"
#include "cli/options.h"
#include "util/clock.h"
#include "util/outpath.h"
#include "util/progress.h"
#include "wavefuel/scenario.h"
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

/* What the callbacks of the scheduler need to print. */
typedef struct Printer {
    const WfSweep *sw;
    int            quiet, tty;
    double         last_draw;
} Printer;

static void on_finished(void *ctx, size_t k, const WfSweepResult *r, const WfSweepCounts *c)
{
    Printer *p = ctx;
    if (r->status == WF_RUN_FAILED) {
        char cmd[8192];
        if (p->tty && !p->quiet) fprintf(stderr, "\n");
        fprintf(stderr, "wavefuel sweep: run %zu failed: %s\n", k, r->error);
        if (!wf_sweep_command(p->sw, k, wf_cli_program(), cmd, sizeof cmd)) fprintf(stderr, "  reproduce: %s\n", cmd);
    } else if (!p->tty && !p->quiet) {
        /* Not a terminal (a log): one line per run. */
        fprintf(stderr, "[%zu/%zu] run %zu %s (%.2f s)\n", c->n_reported, c->n_todo, k,
                r->status == WF_RUN_OK ? "ok" : "interrupted", r->wall_s);
    }
}

static void on_progress(void *ctx, const WfSweepCounts *c, double wall)
{
    Printer *p = ctx;
    double t = wf_wall_now();
    if (!p->tty || p->quiet || t - p->last_draw < 0.2) return;
    p->last_draw = t;
    char bar[WF_PROGRESS_CELLS + 1];
    double eta = wf_progress_bar(c->n_todo ? (double)c->n_reported / (double)c->n_todo : 1.0, wall, bar);
    fprintf(stderr, "\r[%s] %zu/%zu runs  ok %zu  failed %zu  wall %.1f s  ETA %.0f s   ", bar, c->n_reported,
            c->n_todo, c->n_ok, c->n_failed, wall, eta);
    fflush(stderr);
}

static void on_thread_start(void *ctx)
{
    (void)ctx;
    wf_cli_h5_quiet_thread(); /* per-run files are written from the worker threads */
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
    int c;
    memset(o, 0, sizeof *o);
    WfCliOpts cli = {.cmd = "sweep", .longopts = opts, .shortopts = "o:qh"};
    while ((c = wf_cli_getopt(&cli, argc, argv, rank != 0)) != -1) {
        switch (c) {
        case 'o': o->out = optarg; break;
        case 't':
            if (wf_parse_long(optarg, 1, 4096, &o->threads))
                return wf_cli_usage(&cli, rank != 0, "--threads expects an integer in [1, 4096] (got '%s')", optarg);
            break;
        case 'p': o->per_run_dir = optarg; break;
        case 'f': o->force = 1; break;
        case 'r': o->retry_failed = 1; break;
        case 'l': o->list = 1; break;
        case 'q': o->quiet = 1; break;
        case 'h': /* under MPI only rank 0 speaks */
            if (rank == 0) help(stdout, strcmp(argv[0], "sweep") ? argv[0] : "wavefuel sweep");
            return -1;
        default: return c == WF_CLI_DONE ? -1 : 2;
        }
    }
    if (argc - optind != 1) return wf_cli_usage(&cli, rank != 0, "expected one SWEEP.yaml (see --help)");
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

static void list_commands(const WfSweep *sw)
{
    size_t len = 1 << 16;
    char *cmd = malloc(len);
    for (size_t i = 0; cmd && i < sw->n_runs; i++)
        printf("%s\n", wf_sweep_command(sw, i, wf_cli_program(), cmd, len) ? "# (command too long)" : cmd);
    free(cmd);
}

/* Threads: on one machine, workers = min(threads, runs to do), each run getting threads / workers of them (1 unless
 * runs are fewer than threads). Under MPI (n_ranks > 1 or the MPI build), one local worker and --threads per run on
 * every rank (default 1). The runs' team size is this thread's OpenMP setting, which the worker threads inherit:
 * the program, not the library, sets it, with nested parallelism when runs get several threads. */
static void plan_threads(const Options *o, int n_ranks, size_t n_todo, WfSweepExecOpts *x)
{
    long threads = o->threads;
#ifdef _OPENMP
    if (!threads) threads = n_ranks > 1 ? 1 : omp_get_max_threads();
#else
    threads = 1;
#endif
#ifdef WF_MPI
    (void)n_todo;
    x->workers = 1;
    x->run.threads = (int)threads;
#else
    (void)n_ranks;
    x->workers = (size_t)threads < n_todo ? (int)threads : (int)n_todo;
    x->run.threads = (int)(threads / (x->workers > 0 ? x->workers : 1));
#endif
#ifdef _OPENMP
    omp_set_num_threads(x->run.threads);
    omp_set_max_active_levels(x->run.threads > 1 ? 2 : 1);
#endif
}

/* Print the outcome; returns the exit status. */
static int conclude(const WfSweep *sw, const char *out, const WfSweepResult *res, const WfSweepCounts *c,
                    const WfSweepTiming *t, int quiet)
{
    size_t pending = 0, failed = 0;
    for (size_t i = 0; i < sw->n_runs; i++) {
        pending += res[i].status == WF_RUN_PENDING;
        failed += res[i].status == WF_RUN_FAILED;
    }
    if (!quiet) {
        size_t ran = c->n_ok + c->n_failed;
        printf("wavefuel sweep: %s: %zu runs: %zu ok, %zu failed, %zu pending; ran %zu now in %.3f s (%.4g runs/h) "
               "on %d worker%s x %d thread%s\n",
               sw->name, sw->n_runs, sw->n_runs - pending - failed, failed, pending, ran, t->wall_s,
               t->wall_s > 0 ? 3600.0 * (double)ran / t->wall_s : 0.0, t->workers, t->workers > 1 ? "s" : "",
               t->threads_per_run, t->threads_per_run > 1 ? "s" : "");
        printf("result: %s\n", out);
    }
    if (pending) {
        fprintf(stderr, "wavefuel: sweep interrupted: %zu runs pending, saved in %s; run the same command again to "
                "continue\n", pending, out);
        return 3;
    }
    if (failed) {
        fprintf(stderr, "wavefuel: %zu of %zu runs failed (status and error in %s, /runs)\n", failed, sw->n_runs, out);
        return 1;
    }
    return 0;
}

/* Rank 0 (or the only process): resume the table, run what is pending, report. remote: the other MPI ranks. */
static int sweep_main(const WfSweep *sw, const Options *o, int n_ranks, const WfSweepRemote *remote)
{
    const char *out = o->out ? o->out : sw->output;
    WfError err = {0};
    WfSweepResult *res = calloc(sw->n_runs ? sw->n_runs : 1, sizeof *res);
    size_t n_reused = 0, n_todo = 0, n_failed_before = 0;
    int rc = res ? prepare_rows(sw, o, out, res, &n_reused, &err)
                 : wf_err(&err, WF_ESYS, "out of memory for %zu runs", sw->n_runs);
    if (rc) {
        free(res);
        return wf_cli_fail(&err);
    }
    for (size_t i = 0; i < sw->n_runs; i++) {
        n_todo += res[i].status == WF_RUN_PENDING;
        n_failed_before += res[i].status == WF_RUN_FAILED;
    }
    if (n_todo == 0) {
        if (!o->quiet)
            printf("wavefuel sweep: %s: all %zu runs already done in %s (%zu failed); nothing to run\n", sw->name,
                   sw->n_runs, out, n_failed_before);
        free(res);
        return n_failed_before ? 1 : 0;
    }
    Printer pr = {.sw = sw, .quiet = o->quiet, .tty = isatty(STDERR_FILENO)};
    WfSweepExecOpts x = {.table_path = out, .save_every_s = SAVE_EVERY_S, .stop = &wf_cli_stop, .remote = remote,
                         .mode = n_ranks > 0 ? "mpi" : "threads", .on_finished = on_finished, .on_progress = on_progress,
                         .on_thread_start = on_thread_start, .ctx = &pr};
    x.run.per_run_dir = o->per_run_dir;
    plan_threads(o, n_ranks, n_todo, &x);
    int shown_workers = remote ? remote->workers : x.workers;
    if (!o->quiet) {
        if (n_reused)
            fprintf(stderr, "wavefuel sweep: resuming %s: %zu of %zu runs already done\n", out, n_reused, sw->n_runs);
        fprintf(stderr, "wavefuel sweep: %s: %zu runs to do on %d worker%s (%s) x %d thread%s per run\n", sw->name,
                n_todo, shown_workers, shown_workers > 1 ? "s" : "", x.mode, x.run.threads,
                x.run.threads > 1 ? "s" : "");
    }
    WfSweepCounts c;
    WfSweepTiming t;
    rc = wf_sweep_execute(sw, res, &x, &c, &t, &err);
    if (pr.tty && !o->quiet) fprintf(stderr, "\n");
    int status = rc ? wf_cli_fail(&err) : conclude(sw, out, res, &c, &t, o->quiet);
    free(res);
    return status;
}

#ifdef WF_MPI
/* bin/wavefuel-mpi: rank 0 coordinates with the other ranks as remote workers; they run what it sends. */
static int sweep_mpi(WfSweep **sw, const Options *o)
{
    WfError err = {0};
    int rank = wf_mpi_rank(), n_ranks = wf_mpi_size();
    WfMpiPool *pool = NULL;
    int status = 0;
    /* Other ranks create it too (their file system may be their own); if they cannot, their runs fail alone. */
    if (o->per_run_dir && make_dir(o->per_run_dir, &err) && rank == 0) {
        if (!wf_mpi_pool_create(&pool, &err)) wf_mpi_pool_destroy(&pool); /* release the other ranks */
        return wf_cli_fail(&err);
    }
    if (rank != 0) {
        WfSweepExecOpts x = {.run = {.per_run_dir = o->per_run_dir, .worker = rank}};
        plan_threads(o, n_ranks, 1, &x);
        wf_mpi_serve(*sw, &x.run, &wf_cli_stop);
    } else if (wf_mpi_pool_create(&pool, &err)) {
        status = wf_cli_fail(&err);
    } else {
        WfSweepRemote rm = {wf_mpi_pool_poll, pool, n_ranks};
        status = sweep_main(*sw, o, n_ranks, n_ranks > 1 ? &rm : NULL);
        wf_mpi_pool_destroy(&pool);
    }
    return status;
}
#endif

/* Before anything runs: the override keys exist, and the table is neither a directory nor one of the inputs (the
 * sweep file, the base scenario and the files it reads). */
static int check_sweep(const WfSweep *sw, const Options *o, WfError *err)
{
    WfScenario *first = NULL;
    int rc = wf_sweep_check_keys(sw, &first, err);
    WfError ignored = {0}; /* no run loads: the base scenario alone still names the files it reads, when it loads */
    if (!rc && !first) wf_scenario_load_text(sw->scenario_path, sw->scenario_text, NULL, 0, &first, &ignored);
    if (!rc && !o->list) {
        size_t n = first ? first->n_inputs : 0;
        const char **inputs = calloc(n + 2, sizeof *inputs);
        if (!inputs) rc = wf_err(err, WF_ESYS, "out of memory");
        for (size_t i = 0; !rc && i < n; i++) inputs[i] = first->inputs[i];
        if (!rc) {
            inputs[n] = sw->path;
            inputs[n + 1] = sw->scenario_path;
            rc = wf_output_check(o->out ? "-o" : "output", o->out ? o->out : sw->output, inputs, n + 2, err);
        }
        if (!rc && !o->out) rc = wf_output_default_dir(sw->output, err);
        free(inputs);
    }
    wf_scenario_destroy(&first);
    return rc;
}

int wf_cmd_sweep(int argc, char **argv)
{
    int rank = 0;
#ifdef WF_MPI
    rank = wf_mpi_rank();
#endif
    Options o;
    int status = parse_args(argc, argv, &o, rank);
    if (status) return status < 0 ? 0 : status;
    WfError err = {0};
    WfSweep *sw = NULL;
    int rc = rank == 0 ? wf_sweep_load(o.sweep, &sw, &err) : 0;
    if (!rc && rank == 0 && (rc = check_sweep(sw, &o, &err))) wf_sweep_destroy(&sw);
#ifdef WF_MPI
    rc = wf_mpi_share_sweep(rc, o.sweep, &sw, &err);
    if (rc) return rank == 0 ? wf_cli_fail(&err) : rc;
#else
    if (rc) return wf_cli_fail(&err);
#endif
    wf_cli_catch_stop();
    if (o.list && rank == 0) {
        list_commands(sw);
#ifdef WF_MPI
        WfMpiPool *none = NULL;
        if (!wf_mpi_pool_create(&none, &err)) wf_mpi_pool_destroy(&none); /* release the other ranks */
    } else if (o.list) {
        wf_mpi_serve(sw, &(WfSweepRunOpts){.threads = 1}, &wf_cli_stop);
#endif
    } else {
#ifdef WF_MPI
        status = sweep_mpi(&sw, &o);
#else
        status = o.per_run_dir && make_dir(o.per_run_dir, &err) ? wf_cli_fail(&err) : sweep_main(sw, &o, 0, NULL);
#endif
    }
    wf_sweep_destroy(&sw);
    return status;
}
