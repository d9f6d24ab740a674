/* Statistics: time-series records at output instants and aggregates over the statistics window, summed in
 * a fixed block order so that any thread count gives the same bits. Definitions: docs/metrics.md. */
#include "wavefuel/stats.h"

#include <math.h>
#include <string.h>

#include "wavefuel/vehicle.h"
#include "par.h"

const WfColumn wf_ts_columns[WF_TS_N_COLS] = {
    {"t", "s", "simulated time of the record"},
    {"mean_speed", "m/s", "mean speed over vehicles"},
    {"sd_speed", "m/s", "spatial standard deviation of speed across vehicles (population, 1/N)"},
    {"min_speed", "m/s", "lowest speed"},
    {"max_speed", "m/s", "highest speed"},
    {"frac_stopped", "1", "fraction of vehicles slower than statistics.v_stop_mps"},
    {"waves", "1", "stop-and-go waves: maximal runs of consecutive vehicles (ring order) slower than "
                   "statistics.wave_speed_mps"},
    {"fuel_rate", "g/s", "fleet fuel rate"},
    {"mean_gap", "m", "mean bumper-to-bumper gap"},
    {"min_gap", "m", "smallest bumper-to-bumper gap"},
    {"overlaps", "1", "overlap events so far (a vehicle stopped behind its leader to keep its gap >= 0)"},
};

size_t wf_stats_scratch_size(size_t n, size_t n_classes)
{
    size_t blocks = (n + WF_STATS_BLOCK - 1) / WF_STATS_BLOCK;
    return blocks * (4 + n_classes) + 1;
}

void wf_stats_record(const WfFleet *f, const WfScenario *sc, double t_s, int64_t overlaps, double *scratch,
                     WfTsRow *row)
{
    size_t n = f->n, nc = f->n_classes, nb = (n + WF_STATS_BLOCK - 1) / WF_STATS_BLOCK, stride = 4 + nc;
    const double *v = f->v_mps, *gap = f->gap_m, *fr = f->fuel_rate_gps;
    const uint16_t *cid = f->class_id;
    double v_stop = sc->v_stop_mps, v_wave = sc->wave_speed_mps;
    /* Pass 1 per block: sum of speeds, of gaps, of fuel rates per class, stopped count, wave starts. */
    WF_PAR_FOR(nb > 1, "omp parallel for schedule(static) default(none) shared(nb, n, nc, stride, scratch, v, gap, fr, cid, v_stop, v_wave)",
    for (size_t b = 0; b < nb; b++) {
        double *out = scratch + b * stride, sv = 0.0, sg = 0.0, stopped = 0.0, waves = 0.0;
        for (size_t c = 0; c < nc; c++) out[4 + c] = 0.0;
        size_t end = (b + 1) * WF_STATS_BLOCK < n ? (b + 1) * WF_STATS_BLOCK : n;
        for (size_t i = b * WF_STATS_BLOCK; i < end; i++) {
            sv += v[i];
            sg += gap[i];
            stopped += v[i] < v_stop;
            out[4 + cid[i]] += fr[i];
            /* A wave starts at a slow vehicle whose follower (i - 1, ring order) is not slow. */
            size_t prev = i ? i - 1 : n - 1;
            waves += (v[i] < v_wave) && !(v[prev] < v_wave);
        }
        out[0] = sv;
        out[1] = sg;
        out[2] = stopped;
        out[3] = waves;
    });
    double sv = 0, sg = 0, stopped = 0, waves = 0;
    memset(row, 0, sizeof *row);
    for (size_t b = 0; b < nb; b++) {
        const double *o = scratch + b * stride;
        sv += o[0], sg += o[1], stopped += o[2], waves += o[3];
        for (size_t c = 0; c < nc; c++) row->class_fuel_rate_gps[c] += o[4 + c];
    }
    double mean = sv / (double)n;
    /* Pass 2: centred second moment (two-pass for accuracy when the spread is tiny), extremes. */
    WF_PAR_FOR(nb > 1, "omp parallel for schedule(static) default(none) shared(nb, n, stride, scratch, v, gap, mean)",
    for (size_t b = 0; b < nb; b++) {
        double m2 = 0.0, vmin = INFINITY, vmax = -INFINITY, gmin = INFINITY;
        size_t end = (b + 1) * WF_STATS_BLOCK < n ? (b + 1) * WF_STATS_BLOCK : n;
        for (size_t i = b * WF_STATS_BLOCK; i < end; i++) {
            double d = v[i] - mean;
            m2 += d * d;
            vmin = v[i] < vmin ? v[i] : vmin;
            vmax = v[i] > vmax ? v[i] : vmax;
            gmin = gap[i] < gmin ? gap[i] : gmin;
        }
        double *out = scratch + b * stride;
        out[0] = m2, out[1] = vmin, out[2] = vmax, out[3] = gmin;
    });
    double m2 = 0, vmin = INFINITY, vmax = -INFINITY, gmin = INFINITY, fuel = 0;
    for (size_t b = 0; b < nb; b++) {
        const double *o = scratch + b * stride;
        m2 += o[0];
        vmin = fmin(vmin, o[1]);
        vmax = fmax(vmax, o[2]);
        gmin = fmin(gmin, o[3]);
    }
    for (size_t c = 0; c < nc; c++) fuel += row->class_fuel_rate_gps[c];
    row->v[WF_TS_T] = t_s;
    row->v[WF_TS_MEAN_V] = mean;
    row->v[WF_TS_SD_V] = sqrt(m2 / (double)n);
    row->v[WF_TS_MIN_V] = vmin;
    row->v[WF_TS_MAX_V] = vmax;
    row->v[WF_TS_FRAC_STOPPED] = stopped / (double)n;
    /* Every vehicle slow: one wave spanning the ring (no start was found above). */
    row->v[WF_TS_WAVES] = (waves == 0 && vmax < v_wave) ? 1.0 : waves;
    row->v[WF_TS_FUEL_RATE] = fuel;
    row->v[WF_TS_MEAN_GAP] = sg / (double)n;
    row->v[WF_TS_MIN_GAP] = gmin;
    row->v[WF_TS_OVERLAPS] = (double)overlaps;
}

void wf_stats_summary(const WfFleet *f, const WfScenario *sc, double sd_sum, long n_sd, long window_steps,
                      int64_t overlaps, WfSummary *s)
{
    memset(s, 0, sizeof *s);
    double dt = sc->dt_s;
    s->window_s = (double)window_steps * dt;
    double stops = 0, hard = 0, infeas = 0, stopped_s = 0, laps = 0, litres = 0, gallons = 0;
    for (size_t c = 0; c < f->n_classes; c++) {
        WfClassSummary *cs = &s->cls[c];
        const WfVehicleClass *vc = &sc->classes[c].vc;
        double cstops = 0, cinf = 0;
        cs->count = (long)f->class_n[c];
        for (size_t k = 0; k < f->class_n[c]; k++) {
            size_t i = f->class_member[c][k];
            cs->fuel_g += f->fuel_g[i];
            cs->dist_m += f->dist_m[i];
            cstops += f->stops[i];
            cinf += f->infeasible_steps[i];
            hard += f->hard_brakes[i];
            stopped_s += f->time_stopped_s[i];
            laps += (double)f->laps[i];
        }
        cs->l_per_100km = wf_l_per_100km(vc, cs->fuel_g, cs->dist_m);
        cs->mpg = wf_mpg(vc, cs->fuel_g, cs->dist_m);
        cs->infeasible_share = cs->count && window_steps ? cinf / ((double)cs->count * (double)window_steps) : 0.0;
        cs->stops_per_vkm = cs->dist_m > 0 ? cstops / (cs->dist_m / 1000.0) : 0.0;
        s->fuel_g += cs->fuel_g;
        s->dist_m += cs->dist_m;
        stops += cstops;
        infeas += cinf;
        litres += cs->fuel_g / vc->fuel_density_g_per_l;
        gallons += cs->fuel_g / vc->fuel_density_g_per_l / WF_L_PER_US_GAL;
    }
    double n = (double)f->n;
    s->vkt_km = s->dist_m / 1000.0;
    s->l_per_100km = s->dist_m > 0 ? litres / (s->dist_m / 1e5) : INFINITY;
    s->mpg = gallons > 0 ? (s->dist_m / WF_M_PER_MILE) / gallons : 0.0;
    s->stops_per_vkm = s->vkt_km > 0 ? stops / s->vkt_km : 0.0;
    s->hard_brakes_per_vkm = s->vkt_km > 0 ? hard / s->vkt_km : 0.0;
    s->mean_speed_mps = s->window_s > 0 ? s->dist_m / (n * s->window_s) : 0.0;
    s->sd_speed_time_avg_mps = n_sd ? sd_sum / (double)n_sd : 0.0;
    s->throughput_vph = s->window_s > 0 ? laps / s->window_s * 3600.0 : 0.0;
    s->infeasible_share = window_steps ? infeas / (n * (double)window_steps) : 0.0;
    s->time_stopped_share = s->window_s > 0 ? stopped_s / (n * s->window_s) : 0.0;
    s->overlaps = overlaps;
}
