/* Virtual detectors of a corridor (/detectors): the columns, and the flows, mean speeds and occupancy per
 * interval and detector from the sums the engine accumulates (src/core/corridor.c). Definitions:
 * docs/corridors.md. */
#include <math.h>

#include "observe/columns.h"

enum { D_X, D_T0, D_T1, D_COUNT, D_FLOW, D_VT, D_VH, D_OCC };

const WfObsColumn wf_detector_columns[WF_DET_N_COLS] = {
    {{"x", "m", "detector positions"}, WF_COL_F64, 1},
    {{"t_start", "s", "start of each interval"}, WF_COL_F64, 1},
    {{"t_end", "s", "end of each interval"}, WF_COL_F64, 1},
    {{"count", "1", "front-bumper passages [interval x detector] (a passage: x_before <= x_d < x_after)"},
     WF_COL_I64, 0},
    {{"flow", "1/h", "passages per hour [interval x detector]"}, WF_COL_F64, 0},
    {{"speed_time_mean", "m/s", "arithmetic mean speed of the passages (NaN without passages)"}, WF_COL_F64, 0},
    {{"speed_harmonic_mean", "m/s", "harmonic mean speed of the passages (space-mean estimate; NaN without passages)"},
     WF_COL_F64, 0},
    {{"occupancy", "1", "share of the interval during which a vehicle body covered the detector point"},
     WF_COL_F64, 0},
};

size_t wf_detectors_scratch(const WfDetectors *d) { return (d->n_int * d->n_det + d->n_int + 1) * 5; }

void wf_detectors_fields(const WfDetectors *d, const WfScenario *sc, double *scratch, WfObsData *out)
{
    size_t ni = d->n_int, nd = d->n_det, n = ni * nd;
    double *t0 = scratch, *t1 = t0 + ni, *flow = t1 + ni, *vt = flow + n, *vh = vt + n, *occ = vh + n;
    for (size_t j = 0; j < ni; j++) {
        t0[j] = (double)j * d->interval_s;
        t1[j] = fmin((double)(j + 1) * d->interval_s, sc->duration_s);
    }
    for (size_t j = 0; j < ni; j++)
        for (size_t q = 0; q < nd; q++) {
            size_t i = j * nd + q;
            double len = t1[j] - t0[j], cnt = (double)d->count[i];
            flow[i] = cnt / len * 3600.0;
            vt[i] = cnt > 0 ? d->sum_v_mps[i] / cnt : NAN;
            vh[i] = cnt > 0 ? cnt / d->sum_inv_v_spm[i] : NAN;
            occ[i] = d->occupied_s[i] / len;
        }
    out[D_X] = (WfObsData){d->x_m, 1, {nd, 0}};
    out[D_T0] = (WfObsData){t0, 1, {ni, 0}};
    out[D_T1] = (WfObsData){t1, 1, {ni, 0}};
    const void *field[] = {d->count, flow, vt, vh, occ};
    for (size_t c = D_COUNT; c <= D_OCC; c++) out[c] = (WfObsData){field[c - D_COUNT], 2, {ni, nd}};
}
