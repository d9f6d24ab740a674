/* /lanes of a road of several lanes (docs/output.md, docs/lanes.md): the records of src/observe/lanes.c,
 * allocated for every record and NaN where none was kept (an interrupted run), and the run's counts per lane pair,
 * lane and driver group. Shared by the ring's and the corridor's writers. */
#include <math.h>
#include <stdlib.h>

#include "io/h5result.h"

int wf_h5_write_lanes(hid_t fid, const WfSim *sim, WfH5Pass pass, WfError *err)
{
    WfLaneObs lo;
    if (!wf_sim_lanes(sim, &lo)) return 0;
    const WfScenario *sc = wf_sim_scenario(sim);
    size_t nr = (size_t)wf_scenario_records(sc, wf_scenario_output_every(sc)), nl = lo.n_lanes, ng = sc->n_groups;
    hid_t g = wf_h5_group_pass(fid, "lanes", pass, err);
    if (g < 0) return WF_ESYS;
    double *d = malloc((nr * nl + nl * nl + ng + 1) * sizeof *d);
    int rc = !d ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t c = 0; !rc && c < WF_LANE_REC_N_COLS + WF_LANE_N_COLS; c++) {
        int per_lane = c >= WF_LANE_REC_N_COLS;
        size_t w = per_lane ? nl : 1, off = per_lane ? 3 + (c - WF_LANE_REC_N_COLS) : c;
        size_t step = per_lane ? WF_LANE_N_COLS : 1;
        for (size_t i = 0; i < nr; i++)
            for (size_t l = 0; l < w; l++) d[i * w + l] = i < lo.n_rows ? lo.rows[i * lo.row_len + off + l * step] : NAN;
        WfObsData data = {d, per_lane ? 2 : 1, {nr, per_lane ? nl : 0}};
        rc = wf_h5_put_columns(g, per_lane ? &wf_lane_columns[c - WF_LANE_REC_N_COLS] : &wf_lane_record_columns[c],
                               &data, 1, pass, err);
    }
    /* the run's counts: lane pairs, cut-ins per lane, per driver group, and each group's cut-ins per vehicle-hour */
    int64_t *k = (int64_t *)d;
    double rate[WF_MAX_GROUPS], lrate[WF_MAX_LANES];
    for (size_t q = 0; q < ng; q++)
        rate[q] = lo.group_vehicle_s[q] > 0 ? (double)lo.group_cut_ins[q] / (lo.group_vehicle_s[q] / 3600.0) : 0.0;
    for (size_t q = 0; q < nl; q++)
        lrate[q] = lo.lane_vehicle_s[q] > 0 ? (double)lo.lane_cut_ins[q] / (lo.lane_vehicle_s[q] / 3600.0) : 0.0;
    for (size_t i = 0; i < nl; i++)
        for (size_t j = 0; j < nl; j++) k[i * nl + j] = lo.pair[i * WF_MAX_LANES + j];
    WfObsData cnt[WF_LANE_CNT_N_COLS] = {{k, 2, {nl, nl}}, {lo.lane_cut_ins, 1, {nl, 0}}, {lo.group_changes, 1, {ng, 0}},
                                         {lo.group_cut_ins, 1, {ng, 0}}, {rate, 1, {ng, 0}}, {lrate, 1, {nl, 0}}};
    for (size_t c = 0; !rc && c < WF_LANE_CNT_N_COLS; c++)
        rc = wf_h5_put_columns(g, &wf_lane_count_columns[c], &cnt[c], 1, pass, err);
    free(d);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}
