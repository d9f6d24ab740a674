/* `wavefuel run`: load a scenario, simulate, write the HDF5 result, print a summary table. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "cli/commands.h"
#include "cli/options.h"
#include "util/clock.h"
#include "wavefuel/checkpoint.h"
#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/h5out.h"
#include "wavefuel/scenario.h"
#include "wavefuel/partition.h"
#ifdef WF_MPI
#include "mpi/partition_mpi.h"
#include "mpi/sweep_mpi.h"
#define PART_FREE(p) wf_mpi_partition_free(p)
#else
#define PART_FREE(p) ((void)(p))
#endif

static void help(FILE *out)
{
#ifdef WF_MPI
    fprintf(out, "mpirun -n R wavefuel-mpi run: `wavefuel run` with one road split across the R processes: a\n"
                 "ring's vehicles in contiguous shares, a corridor in segments of the road; rank 0 writes the same\n"
                 "result file as one process would, bit for bit (docs/mpi.md). Roads of one lane with fixed-step\n"
                 "integrators, without trajectories and without groups commanded from outside; a checkpoint is\n"
                 "saved when a signal stops the run (--checkpoint-every is not offered); --resume takes any number\n"
                 "of processes.\n\n");
#endif
    fprintf(out,
            "usage: wavefuel run SCENARIO.yaml [-o FILE.h5] [--set key.path=value]... [--threads N] [--force] [-q]\n"
            "                    [--checkpoint-every SECONDS]\n"
            "       wavefuel run --resume FILE.h5 [--threads N] [-q] [--checkpoint-every SECONDS]\n\n"
            "Simulates the scenario and writes an HDF5 result (default: output.path of the scenario, else\n"
            "output/NAME.h5). The file is written as FILE.h5.partial and renamed when the run completes; an\n"
            "existing result is never replaced unless --force. SIGINT/SIGTERM stop at the end of the current\n"
            "step and leave FILE.h5.partial with /meta/completed = 0. Keys are documented in docs/scenarios.md.\n"
            "  -o, --output FILE   result file\n"
            "  --set k.path=value  override a scenario value (repeatable), e.g. --set fleet.vehicles=44\n"
            "  --threads N         OpenMP threads (default: OMP_NUM_THREADS or all cores)\n"
            "  --force             replace an existing result file\n"
            "  -q, --quiet         no progress bar or summary\n"
            "  --checkpoint-every S  save the complete state to FILE.h5.ckpt every S seconds of wall time (an\n"
            "                      interrupted run always saves one); rings and corridors\n"
            "  --resume FILE.h5    continue an interrupted run from FILE.h5.ckpt and FILE.h5.partial (the scenario\n"
            "                      comes from the checkpoint); with the fixed-step integrators the result is\n"
            "                      bit-identical to an uninterrupted run. A damaged checkpoint, or one of another\n"
            "                      run, is refused with exit status 2. FILE.h5.partial or FILE.h5.ckpt name\n"
            "                      the same run\n");
}

/* The processes a road is split across (wavefuel-mpi run, docs/mpi.md); 0 in wavefuel run. */
static int run_ranks;

/* The run's first line: what was simulated and how fast; a corridor adds its vehicle counts. */
static void print_header(const WfSim *sim)
{
    const WfScenario *sc = wf_sim_scenario(sim);
    const WfCorridor *c = wf_sim_corridor(sim);
    double wall = wf_sim_wall_s(sim);
    if (!c) {
        size_t n = wf_sim_fleet(sim)->n;
        printf("wavefuel run: %s  (%zu vehicles, %.6g s simulated, %s dt = %.6g s, %d threads", sc->name, n,
               sc->duration_s, sc->integrator, sc->dt_s, wf_sim_threads(sim));
        if (run_ranks) printf(" x %d processes", run_ranks);
        printf(", wall %.3f s, %.3g vehicle-steps/s)\n", wall,
               wall > 0 ? (double)n * (double)wf_sim_steps_done(sim) / wall : 0.0);
        return;
    }
    const WfSummary *s = wf_sim_summary(sim);
    const WfCorridorCounts *n = &s->counts;
    printf("wavefuel run: %s  (corridor %.6g m, %.6g s simulated, %s dt = %.6g s, %d threads", sc->name,
           sc->road.length_m, sc->duration_s, sc->integrator, sc->dt_s, wf_sim_threads(sim));
    if (run_ranks) printf(" x %d processes", run_ranks);
    printf(", wall %.3f s)\n", wall);
    printf("vehicles: %lld arrived, %lld entered, %lld exited, %lld on the road, %lld queued at the end; %lld entries "
           "delayed (mean wait %.3g s, longest queue %lld)\n",
           (long long)n->arrived, (long long)n->entered, (long long)n->exited,
           (long long)(n->entered - n->exited - n->off_ramp),
           (long long)n->queued, (long long)n->delayed, s->mean_queue_delay_s, (long long)n->max_queue);
}

static void print_summary(const WfSim *sim, const char *path)
{
    const WfSummary *s = wf_sim_summary(sim);
    const WfScenario *sc = wf_sim_scenario(sim);
    print_header(sim);
    printf("statistics window: %.6g s after %.6g s warm-up\n\n", s->window_s, sc->warmup_s);
    const char *names[WF_MAX_CLASSES];
    for (size_t c = 0; c < sc->n_classes; c++) names[c] = sc->classes[c].vc.name;
    WfSummaryBoundary b = wf_sim_corridor(sim) ? WF_SUMMARY_CORRIDOR : WF_SUMMARY_RING;
    wf_summary_print(stdout, s, b, names, sc->n_classes, sc);
    wf_summary_print_safety(stdout, s, b, sc);
    printf("result: %s\n", path);
}

typedef struct RunArgs {
    double       ckpt_s;
    const char  *resume, *outpath, *scenario;
    const char **sets; /* owned (the strings are argv's), n_set */
    size_t       n_set;
    int          force, quiet;
    long         threads;
} RunArgs;

/* Returns 0, -1 after --help (exit status 0) or 2 after a usage error; a->sets is to be freed in every case. */
static int parse_args(int argc, char **argv, RunArgs *a)
{
    static const struct option opts[] = {{"output", required_argument, 0, 'o'}, {"set", required_argument, 0, 's'},
                                         {"threads", required_argument, 0, 't'}, {"force", no_argument, 0, 'f'},
                                         {"quiet", no_argument, 0, 'q'},
                                         {"checkpoint-every", required_argument, 0, 'c'},
                                         {"resume", required_argument, 0, 'r'},  {0, 0, 0, 0}};
    int o;
    memset(a, 0, sizeof *a);
    if (!(a->sets = calloc((size_t)argc + 1, sizeof *a->sets))) return 1;
    WfCliOpts cli = {.cmd = "run", .longopts = opts, .shortopts = "o:q", .repeatable = "s", .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'o': a->outpath = optarg; break;
        case 's': a->sets[a->n_set++] = optarg; break;
        case 't':
            if (wf_parse_long(optarg, 1, 4096, &a->threads))
                return wf_cli_usage(&cli, 0, "--threads expects an integer in [1, 4096] (got '%s')", optarg);
            break;
        case 'f': a->force = 1; break;
        case 'c':
            if (wf_parse_double(optarg, &a->ckpt_s) || a->ckpt_s <= 0)
                return wf_cli_usage(&cli, 0, "--checkpoint-every expects a positive number of seconds (got '%s')",
                                    optarg);
            break;
        case 'r': a->resume = optarg; break;
        case 'q': a->quiet = 1; break;
        default: return o == WF_CLI_DONE ? -1 : 2;
        }
    }
    if (a->resume ? (argc != optind || a->n_set || a->outpath || a->force) : argc - optind != 1)
        return wf_cli_usage(&cli, 0, "%s", a->resume ? "--resume takes no scenario, --set, -o or --force: the "
                                                       "checkpoint holds them"
                                                     : "expected one SCENARIO.yaml (see --help)");
    a->scenario = a->resume ? NULL : argv[optind];
    return 0;
}

/* The scenario file with --set overrides, or, with --resume, the checkpoint's copy of the scenario text and
 * overrides (not the file on disk, which may have changed since). */
static int load_scenario(RunArgs *a, WfScenario **sc, WfError *err)
{
    int rc;
    if (a->resume) {
        WfCheckpointInfo ck;
        rc = wf_checkpoint_read_info(a->resume, &ck, err);
        /* One slot per line of the checkpoint's overrides: a->sets was sized for the command line, which a resumed
         * run's overrides may outnumber (a heap overflow before). */
        size_t lines = 1;
        for (const char *p = rc ? "" : ck.overrides; *p; p++) lines += *p == '\n';
        const char **sets = rc ? NULL : realloc(a->sets, (lines + 1) * sizeof *sets);
        if (!rc && !sets) {
            rc = wf_err(err, WF_ESYS, "out of memory");
            wf_checkpoint_info_free(&ck);
        }
        if (sets) a->sets = sets;
        if (!rc) {
            size_t n = 0;
            for (char *line = strtok(ck.overrides, "\n"); line; line = strtok(NULL, "\n")) a->sets[n++] = line;
            rc = wf_scenario_load_text(ck.scenario_path, ck.scenario_text, a->sets, n, sc, err);
            if (!rc) snprintf((*sc)->output_path, sizeof (*sc)->output_path, "%s", a->resume);
            wf_checkpoint_info_free(&ck);
        }
        return rc;
    }
    rc = wf_scenario_load(a->scenario, a->sets, a->n_set, sc, err);
    if (!rc && a->outpath) snprintf((*sc)->output_path, sizeof (*sc)->output_path, "%s", a->outpath);
    return rc;
}

#ifdef WF_MPI
/* wavefuel-mpi run (docs/mpi.md): every rank loads the scenario and builds the road; rank 0 alone writes the result
 * and prints. A setup step that fails on some rank stops every rank before the run; an error of rank 0's writer
 * during the run stops every rank at once (the others would wait for rank 0 at the next exchange). */
static WfOutput writer_ops;   /* rank 0's writer */
static WfH5Out **writer_h5;
static int other_stderr = -1; /* ranks other than 0: their own stderr, for errors of their own */

static int begin_or_abort(void *ctx, const WfSim *sim, WfError *err)
{
    int rc = writer_ops.begin(ctx, sim, err);
    if (rc) {
        int st = wf_cli_fail(err);
        wf_h5out_destroy(writer_h5); /* nothing was written: no file is left */
        wf_mpi_abort(st);
    }
    return 0;
}

static int record_or_abort(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    int rc = writer_ops.record(ctx, sim, rec, err);
    if (rc) wf_mpi_abort(wf_cli_fail(err)); /* the partial file keeps the rows written before */
    return 0;
}

static int trips_or_abort(void *ctx, const WfSim *sim, const struct WfTrip *trips, size_t n, WfError *err)
{
    int rc = writer_ops.trips(ctx, sim, trips, n, err);
    if (rc) wf_mpi_abort(wf_cli_fail(err)); /* a corridor's trips go out during the run too */
    return 0;
}

/* The other ranks save nothing: their shares of a ring's state go to rank 0 as it saves a checkpoint (nothing on a
 * corridor, whose state is gathered onto rank 0 before). */
static int send_state(void *ctx, const WfSim *sim, WfError *err)
{
    (void)ctx;
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state((WfSim *)sim, vars, WF_MAX_STATE_VARS);
    return wf_sim_state_pieces((WfSim *)sim, vars, nv, NULL, NULL, err);
}

/* The other ranks' end: their shares of a ring, to rank 0's writer as it writes the per-vehicle results
 * (wf_sim_shares; nothing on a corridor). */
static int send_shares(void *ctx, const WfSim *sim, int completed, const char *reason, WfError *err)
{
    (void)ctx, (void)completed, (void)reason;
    return wf_sim_shares(sim, NULL, NULL, err);
}

/* Every rank's status agreed; an error that rank 0 did not have is printed by the rank that had it. */
static int agree(int rank, int rc, const WfError *err)
{
    int all = wf_mpi_agree_status(rc), first = wf_mpi_agree_status(rank == 0 ? rc : 0);
    if (rc && rank && !first) dprintf(other_stderr, "wavefuel-mpi (rank %d): %s\n", rank, err->msg);
    return all;
}
#endif

/* The result writer of this run: created, reopened at the checkpoint (--resume) or, on a rank of a split ring other
 * than 0, none (its state restored from the checkpoint). */
static int open_output(const RunArgs *a, WfScenario *sc, WfSim *sim, int rank, WfH5Out **h5, WfOutput *ops,
                       WfError *err)
{
    int rc;
#ifdef WF_MPI
    if (rank) {
        *ops = (WfOutput){.checkpoint = send_state, .end = send_shares};
        return a->resume ? wf_h5out_restore(a->resume, sim, err) : 0;
    }
#else
    (void)rank;
#endif
    rc = a->resume ? wf_h5out_resume(a->resume, sim, h5, ops, err)
                   : wf_h5out_create(sim, sc->output_path, a->force, h5, ops, err);
#ifdef WF_MPI
    if (!rc) {
        writer_ops = *ops, writer_h5 = h5;
        ops->begin = ops->begin ? begin_or_abort : NULL;
        ops->record = ops->record ? record_or_abort : NULL;
        ops->trips = ops->trips ? trips_or_abort : NULL;
    }
#endif
    return rc;
}

int wf_cmd_run(int argc, char **argv)
{
    RunArgs a;
    WfError err = {0};
    int rank = 0;
    WfPartition *pp = NULL;
    volatile sig_atomic_t *stop = &wf_cli_stop;
#ifdef WF_MPI
    static WfPartition part; /* outlives the run, whose loop reads part.stop_all */
    if ((rank = wf_mpi_rank()) != 0 && (other_stderr = dup(STDERR_FILENO)) >= 0 &&
        (!freopen("/dev/null", "w", stderr) || !freopen("/dev/null", "w", stdout)))
        return 1; /* rank 0 says what every rank would */
#endif
    int status = parse_args(argc, argv, &a);
    if (status) {
        free(a.sets);
        return status < 0 ? 0 : status;
    }
#ifdef WF_MPI
    if (a.ckpt_s > 0) {
        fprintf(stderr, "wavefuel-mpi run: --checkpoint-every: a road split across processes saves a checkpoint only "
                        "when a signal stops it (docs/mpi.md)\n");
        free(a.sets);
        return 2;
    }
    run_ranks = wf_mpi_size();
#endif
#ifdef _OPENMP
    if (a.threads) omp_set_num_threads((int)a.threads);
#endif
    char resume_path[1100];
    if (a.resume && wf_cli_resume_target(a.resume, resume_path, sizeof resume_path, &err)) {
        free(a.sets);
        return wf_cli_fail(&err);
    }
    if (a.resume) a.resume = resume_path;
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    WfH5Out *h5 = NULL;
    WfOutput ops;
    int rc = load_scenario(&a, &sc, &err);
    if (!rc && !a.resume && !rank) rc = wf_cli_run_output(sc, a.outpath, &err);
#ifdef WF_MPI
    if (!rc && (rc = wf_mpi_partition_init(&part, &wf_cli_stop, &err)) == 0) pp = &part, stop = &part.stop_all;
#endif
    /* Scenario and fleet errors come before the result file exists: nothing is left behind. A resumed run
     * continues the checkpoint's state in the partial file it reopens. */
    if (!rc) rc = wf_sim_create_part(sc, pp, &sim, &err);
#ifdef WF_MPI
    /* the other ranks read the checkpoint before rank 0 reopens its partial file for writing */
    rc = agree(rank, rc, &err);
    if (!rc) rc = agree(rank, rank ? open_output(&a, sc, sim, rank, &h5, &ops, &err) : 0, &err);
    if (!rc) rc = agree(rank, rank ? 0 : open_output(&a, sc, sim, rank, &h5, &ops, &err), &err);
    if (rc && !err.code) wf_err(&err, rc, "another process of the run failed (its message is above)");
#else
    if (!rc) rc = open_output(&a, sc, sim, rank, &h5, &ops, &err);
#endif
    free(a.sets);
    if (!rc && a.ckpt_s > 0) wf_sim_set_checkpoint_interval(sim, a.ckpt_s);
    if (rc) {
        wf_h5out_destroy(&h5);
        wf_sim_destroy(&sim);
        wf_scenario_destroy(&sc);
        if (pp) PART_FREE(pp);
        return wf_cli_fail(&err);
    }
    wf_cli_catch_stop();
    double t0 = wf_wall_now();
    int tty = isatty(STDERR_FILENO) && !rank;
    rc = wf_sim_run(sim, &ops, (!a.quiet && tty) ? wf_cli_run_progress : NULL, &t0, stop, &err);
    if (!a.quiet && tty) fprintf(stderr, "\n");
    status = 0;
    if (rc) {
        status = wf_cli_fail(&err);
        char counters[200];
        if (h5 && wf_h5out_path(h5)[0])
            wf_cli_note_partial(wf_h5out_path(h5), sc->output_path, wf_h5out_counters(h5, counters, sizeof counters));
    } else if (!a.quiet && !rank) {
        print_summary(sim, wf_h5out_path(h5));
    }
    wf_h5out_destroy(&h5);
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    if (pp) PART_FREE(pp);
    return status;
}
