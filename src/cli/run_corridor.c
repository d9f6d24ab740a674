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
    printf("%-16s %7s %6s %11s %9s %9s %9s %9s %9s %9s %9s %9s\n", "class", "entered", "trips", "fuel_g", "dist_km",
           "L/100km", "stops/vkm", "trip_g", "trip_s", "g/km_up", "g/km_dn", "g/km_flat");
    for (size_t k = 0; k < sc->n_classes; k++) {
        const WfCorridorClassSummary *cs = &s->cls[k];
        printf("%-16s %7lld %6lld %11.2f %9.3f %9.3f %9.3f %9.2f %9.1f %9.2f %9.2f %9.2f\n", sc->classes[k].vc.name,
               (long long)cs->entered, (long long)cs->trips, cs->fuel_g, cs->dist_m / 1000, cs->l_per_100km,
               cs->stops_per_vkm, cs->trip_fuel_mean_g, cs->trip_time_mean_s, cs->g_per_km_up, cs->g_per_km_down,
               cs->g_per_km_flat);
    }
    printf("%-16s %7lld %6lld %11.2f %9.3f %9.3f %9.3f %9.2f %9.1f\n\n", "fleet", (long long)n->entered,
           (long long)s->trips, s->fuel_g, s->vkt_km, s->l_per_100km, s->stops_per_vkm, s->mean_trip_fuel_g,
           s->mean_travel_time_s);
    printf("mean speed %.3f m/s | time-avg speed s.d. %.3f m/s | inflow %.1f veh/h | outflow %.1f veh/h | hard brakes "
           "%.3f /vkm | overlaps %lld\n",
           s->mean_speed_mps, s->sd_speed_time_avg_mps, s->inflow_vph, s->outflow_vph, s->hard_brakes_per_vkm,
           (long long)n->overlaps);
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
