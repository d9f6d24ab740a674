/* `wavefuel run` for corridors: run the corridor engine into its HDF5 writer and print the summary table. */
#include "cli/run_corridor.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cli/commands.h"
#include "util/clock.h"
#include "wavefuel/corridor.h"
#include "wavefuel/h5corridor.h"

static void print_summary(const WfCorridor *c, const char *path)
{
    const WfScenario *sc = wf_corridor_scenario(c);
    const WfCorridorSummary *s = wf_corridor_summary(c);
    const WfCorridorCounts *n = &s->counts;
    printf("wavefuel run: %s  (corridor %.6g m, %.6g s simulated, %s dt = %.6g s, %d threads, wall %.3f s)\n", sc->name,
           sc->road.length_m, sc->duration_s, sc->integrator, sc->dt_s, wf_corridor_threads(c), wf_corridor_wall_s(c));
    printf("vehicles: %lld arrived, %lld entered, %lld exited, %lld on the road, %lld queued at the end; %lld entries "
           "delayed (mean wait %.3g s, longest queue %lld)\n",
           (long long)n->arrived, (long long)n->entered, (long long)n->exited, (long long)(n->entered - n->exited),
           (long long)n->queued, (long long)n->delayed, s->mean_queue_delay_s, (long long)n->max_queue);
    printf("statistics window: %.6g s after %.6g s warm-up\n\n", s->window_s, sc->warmup_s);
    const char *names[WF_MAX_CLASSES];
    for (size_t k = 0; k < sc->n_classes; k++) names[k] = sc->classes[k].vc.name;
    wf_summary_print(stdout, s, WF_SUMMARY_CORRIDOR, names, sc->n_classes);
    printf("result: %s\n", path);
}

int wf_cli_run_corridor(const WfScenario *sc, const char *resume, double checkpoint_s, int force, int quiet)
{
    WfError err = {0};
    WfCorridor *c = NULL;
    WfH5Corridor *h5 = NULL;
    WfCorridorOutput ops;
    /* Scenario errors come before the result file exists: nothing is left behind. A resumed run continues the
     * checkpoint's state in the partial file it reopens. */
    int rc = wf_corridor_create(sc, &c, &err);
    if (!rc) rc = resume ? wf_h5corridor_resume(resume, c, &h5, &ops, &err)
                         : wf_h5corridor_create(sc->output_path, force, &h5, &ops, &err);
    if (rc) {
        wf_corridor_destroy(&c);
        return wf_cli_fail(&err);
    }
    if (checkpoint_s > 0) wf_corridor_set_checkpoint_interval(c, checkpoint_s);
    wf_cli_catch_stop();
    double t0 = wf_wall_now();
    int tty = isatty(STDERR_FILENO);
    rc = wf_corridor_run(c, &ops, (!quiet && tty) ? wf_cli_run_progress : NULL, &t0, &wf_cli_stop, &err);
    if (!quiet && tty) fprintf(stderr, "\n");
    int status = 0;
    if (rc) {
        status = wf_cli_fail(&err);
        if (wf_h5corridor_path(h5)[0])
            wf_cli_note_partial(wf_h5corridor_path(h5), sc->output_path,
                                "/meta/timeseries_rows, trip_rows and trajectory_rows");
    } else if (!quiet) {
        print_summary(c, wf_h5corridor_path(h5));
    }
    wf_h5corridor_destroy(&h5);
    wf_corridor_destroy(&c);
    return status;
}
