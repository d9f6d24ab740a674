/* The lanes of a multi-lane ring (/lanes, docs/output.md): each lane's record at every output instant, the lane
 * changes and cut-ins between records, and the run's counts per lane pair, lane and driver group. */
#include <math.h>

#include "observe/columns.h"

const WfObsColumn wf_lane_columns[WF_LANE_N_COLS] = {
    {{"vehicles", "1", "vehicles in the lane [time x lane]"}, WF_COL_F64, 0},
    {{"density", "veh/km", "vehicles per km of the lane [time x lane]"}, WF_COL_F64, 0},
    {{"flow", "veh/h", "density times mean speed [time x lane]"}, WF_COL_F64, 0},
    {{"mean_speed", "m/s", "mean speed of the lane's vehicles [time x lane]"}, WF_COL_F64, 0},
    {{"sd_speed", "m/s", "speed standard deviation (population) of the lane's vehicles [time x lane]"}, WF_COL_F64, 0},
    {{"waves", "1", "stop-and-go waves around the lane (as /timeseries/waves) [time x lane]"}, WF_COL_F64, 0},
    {{"fuel_rate", "g/s", "fuel rate of the lane's vehicles [time x lane]"}, WF_COL_F64, 0},
    {{"mean_gap", "m", "mean bumper-to-bumper gap in the lane [time x lane]"}, WF_COL_F64, 0},
    {{"frac_stopped", "1", "fraction of the lane's vehicles slower than statistics.v_stop_mps (NaN for an empty lane) "
                           "[time x lane]"}, WF_COL_F64, 0},
};

const WfObsColumn wf_lane_record_columns[WF_LANE_REC_N_COLS] = {
    {{"t", "s", "time of each record"}, WF_COL_F64, 0},
    {{"lane_changes", "1", "lane changes since the previous record [time]"}, WF_COL_F64, 0},
    {{"cut_ins", "1", "lane changes into a gap with a follower (a cut-in ahead of it) since the previous record "
                      "[time]"}, WF_COL_F64, 0},
};

const WfObsColumn wf_lane_count_columns[WF_LANE_CNT_N_COLS] = {
    {{"pair_changes", "1", "lane changes from lane i (row) to lane j (column) over the run [lane x lane]"},
     WF_COL_I64, 0},
    {{"lane_cut_ins", "1", "cut-ins into each lane over the run [lane]"}, WF_COL_I64, 0},
    {{"group_lane_changes", "1", "lane changes made by each driver group's vehicles over the run [group]"},
     WF_COL_I64, 0},
    {{"group_cut_ins", "1", "cut-ins suffered by each driver group's vehicles over the run [group]"}, WF_COL_I64, 0},
    {{"group_cut_in_rate", "1/h", "cut-ins suffered per vehicle-hour by each driver group over the run [group]"},
     WF_COL_F64, 0},
    {{"lane_cut_in_rate", "1/h", "cut-ins into each lane per vehicle-hour spent in it over the run [lane]"}, WF_COL_F64,
     0},
};

double *wf_lane_row(double *rows, size_t len, size_t max, int64_t *n_rows, int64_t *changes, int64_t *cut_ins, double t)
{
    if (*n_rows >= (int64_t)max) return NULL;
    double *row = rows + (size_t)(*n_rows)++ * len;
    row[0] = t, row[1] = (double)*changes, row[2] = (double)*cut_ins;
    *changes = *cut_ins = 0;
    return row + 3;
}

void wf_lane_values(const double *v, const int *from, double n, double length_m, double *out)
{
    static const double empty[] = {NAN, NAN, 0.0, 0.0, NAN, NAN}; /* an empty lane, as /timeseries */
    double k = n / (length_m / 1000.0);
    out[WF_LANE_VEHICLES] = n;
    out[WF_LANE_DENSITY] = k;
    for (int c = WF_LANE_MEAN_V; c < WF_LANE_N_COLS; c++)
        out[c] = n > 0 ? v[from[c - WF_LANE_MEAN_V]] : empty[c - WF_LANE_MEAN_V];
    out[WF_LANE_FLOW] = n > 0 ? k * out[WF_LANE_MEAN_V] * 3.6 : 0.0;
}
