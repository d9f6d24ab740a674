/* Statistics: time-series records at output instants and aggregates over the statistics window, summed in
 * a fixed block order so that any thread count gives the same bits. Definitions: docs/metrics.md. */
#include "wavefuel/stats.h"

#include <math.h>
#include <string.h>

#include "wavefuel/vehicle.h"

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

void wf_stats_block(size_t m, const double *v, const double *gap, const double *fr, const uint16_t *cid,
                    size_t nc, const WfScenario *sc, WfStatsBlock *out)
{
    double v_stop = sc->v_stop_mps, v_wave = sc->wave_speed_mps;
    double sv = 0.0, sg = 0.0, stopped = 0.0, waves = 0.0;
    for (size_t c = 0; c < nc; c++) out->class_fuel_rate_gps[c] = 0.0;
    for (size_t k = 0; k < m; k++) {
        sv += v[k];
        sg += gap[k];
        stopped += v[k] < v_stop;
        out->class_fuel_rate_gps[cid[k]] += fr[k];
        /* A wave starts at a slow vehicle whose follower (k - 1, ring order) is not slow; the block's first
         * vehicle is settled in wf_stats_combine, which knows the previous block's last. */
        waves += k > 0 && (v[k] < v_wave) && !(v[k - 1] < v_wave);
    }
    double mean = sv / (double)m, m2 = 0.0, vmin = INFINITY, vmax = -INFINITY, gmin = INFINITY;
    for (size_t k = 0; k < m; k++) {
        double d = v[k] - mean;
        m2 += d * d;
        vmin = v[k] < vmin ? v[k] : vmin;
        vmax = v[k] > vmax ? v[k] : vmax;
        gmin = gap[k] < gmin ? gap[k] : gmin;
    }
    out->n = (double)m, out->sum_v = sv, out->sum_gap = sg, out->stopped = stopped, out->waves = waves;
    out->m2 = m2, out->vmin = vmin, out->vmax = vmax, out->gmin = gmin;
    out->first_slow = v[0] < v_wave;
    out->last_slow = v[m - 1] < v_wave;
}

void wf_stats_combine(const WfStatsBlock *b, size_t nb, size_t nc, const WfScenario *sc, double t_s,
                      int64_t overlaps, WfTsRow *row)
{
    wf_stats_combine_lanes(b, &nb, 1, nc, sc, t_s, overlaps, row);
}

void wf_stats_fold_begin(WfStatsFold *a)
{
    memset(a, 0, sizeof *a);
    a->vmin = a->gmin = INFINITY, a->vmax = a->lane_vmax = -INFINITY;
}

void wf_stats_fold(WfStatsFold *a, const WfStatsBlock *b, size_t nb, size_t nc)
{
    for (size_t k = 0; k < nb; k++) {
        a->n += b[k].n, a->sv += b[k].sum_v, a->sg += b[k].sum_gap, a->stopped += b[k].stopped;
        a->lane_waves += b[k].waves;
        /* The follower of a block's first vehicle is the previous block's last; the lane's first block's is the
         * lane's last block's, settled in wf_stats_fold_lane_end (the counts are whole numbers: any order gives the
         * same sum). */
        if (a->lane_blocks++) a->lane_waves += b[k].first_slow && !a->last_slow;
        else a->lane_first_slow = b[k].first_slow;
        a->last_slow = b[k].last_slow;
        a->vmin = fmin(a->vmin, b[k].vmin);
        a->lane_vmax = fmax(a->lane_vmax, b[k].vmax);
        a->gmin = fmin(a->gmin, b[k].gmin);
        for (size_t c = 0; c < nc; c++) a->class_fuel_rate_gps[c] += b[k].class_fuel_rate_gps[c];
    }
}

void wf_stats_fold_lane_end(WfStatsFold *a, const WfScenario *sc)
{
    if (a->lane_blocks) a->lane_waves += a->lane_first_slow && !a->last_slow;
    /* Every vehicle of a lane slow: one wave spanning it (no start was found above). */
    a->waves += (a->lane_blocks && a->lane_waves == 0 && a->lane_vmax < sc->wave_speed_mps) ? 1.0 : a->lane_waves;
    a->vmax = fmax(a->vmax, a->lane_vmax);
    a->lane_waves = 0, a->lane_vmax = -INFINITY, a->lane_blocks = 0;
    a->mean = a->sv / a->n;
}

void wf_stats_fold_m2(WfStatsFold *a, const WfStatsBlock *b, size_t nb)
{
    for (size_t k = 0; k < nb; k++) {
        double d = b[k].sum_v / b[k].n - a->mean;
        a->m2 += b[k].m2 + b[k].n * d * d;
    }
}

void wf_stats_fold_row(const WfStatsFold *a, size_t nc, double t_s, int64_t overlaps, WfTsRow *row)
{
    double n = a->n, fuel = 0.0;
    memset(row, 0, sizeof *row);
    for (size_t c = 0; c < nc; c++) row->class_fuel_rate_gps[c] = a->class_fuel_rate_gps[c];
    for (size_t c = 0; c < nc; c++) fuel += row->class_fuel_rate_gps[c];
    row->v[WF_TS_T] = t_s;
    row->v[WF_TS_MEAN_V] = a->mean;
    row->v[WF_TS_SD_V] = sqrt(a->m2 / n);
    row->v[WF_TS_MIN_V] = a->vmin;
    row->v[WF_TS_MAX_V] = a->vmax;
    row->v[WF_TS_FRAC_STOPPED] = a->stopped / n;
    row->v[WF_TS_WAVES] = a->waves;
    row->v[WF_TS_FUEL_RATE] = fuel;
    row->v[WF_TS_MEAN_GAP] = a->sg / n;
    row->v[WF_TS_MIN_GAP] = a->gmin;
    row->v[WF_TS_OVERLAPS] = (double)overlaps;
}

void wf_stats_combine_lanes(const WfStatsBlock *b, const size_t *lane_nb, size_t n_lanes, size_t nc,
                            const WfScenario *sc, double t_s, int64_t overlaps, WfTsRow *row)
{
    WfStatsFold a;
    wf_stats_fold_begin(&a);
    size_t nb = 0;
    for (size_t l = 0; l < n_lanes; nb += lane_nb[l++]) {
        wf_stats_fold(&a, b + nb, lane_nb[l], nc);
        wf_stats_fold_lane_end(&a, sc);
    }
    wf_stats_fold_m2(&a, b, nb);
    wf_stats_fold_row(&a, nc, t_s, overlaps, row);
}

void wf_stats_summary_add(const WfFleet *f, const WfScenario *sc, size_t lo, size_t hi, WfSummarySums *a)
{
    double dt = sc->dt_s, L = sc->road.length_m;
    for (size_t i = lo; i < hi; i++) {
        size_t c = f->class_id[i];
        a->fuel_g[c] += f->fuel_g[i];
        a->dist_m[c] += wf_fleet_distance(f, i);
        a->stops[c] += f->stops[i];
        a->infeasible_steps[c] += f->infeasible_steps[i];
        a->hard_brakes += f->hard_brakes[i];
        a->stopped_s += (double)f->stopped_steps[i] * dt;
        a->laps += (double)wf_fleet_laps(f, L, i);
    }
}

void wf_stats_summary_end(const WfFleet *f, const WfScenario *sc, const WfSummarySums *a, double sd_sum, long n_sd,
                          long window_steps, int64_t overlaps, WfSummary *s)
{
    memset(s, 0, sizeof *s);
    s->window_s = (double)window_steps * sc->dt_s;
    double stops = 0, infeas = 0, litres = 0, gallons = 0, hard = a->hard_brakes, stopped_s = a->stopped_s;
    double laps = a->laps;
    for (size_t c = 0; c < f->n_classes; c++) {
        WfClassSummary *cs = &s->cls[c];
        const WfVehicleClass *vc = &sc->classes[c].vc;
        double cstops = a->stops[c], cinf = a->infeasible_steps[c];
        cs->fuel_g = a->fuel_g[c];
        cs->dist_m = a->dist_m[c];
        cs->count = (long)f->class_n[c];
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
