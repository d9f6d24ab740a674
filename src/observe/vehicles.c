/* Per-vehicle statistics of a ring (/vehicles): the columns and each vehicle's value from the fleet's window
 * accumulators. Definitions: docs/metrics.md. */
#include <math.h>

#include "observe/columns.h"
#include "wavefuel/vehicle.h"

enum { V_CLASS, V_GROUP, V_LENGTH, V_DIST, V_FUEL, V_L100, V_MPG, V_STOPS, V_STOPPED, V_MEAN_V, V_VAR_V, V_VAR_A,
       V_HARD, V_INFEAS, V_X, V_V, V_LANE, V_CHANGES, V_CUT_INS };

const WfObsColumn wf_vehicle_columns[WF_VEH_N_COLS] = {
    {{"class_id", "1", "index into /classes"}, WF_COL_I64, 1},
    {{"group_id", "1", "index into /drivers"}, WF_COL_I64, 1},
    {{"length", "m", "vehicle length"}, WF_COL_F64, 1},
    {{"distance", "m", "distance travelled in the statistics window"}, WF_COL_F64, 0},
    {{"fuel", "g", "fuel burnt in the statistics window"}, WF_COL_F64, 0},
    {{"l_per_100km", "L/100km", "fuel economy (volume per distance)"}, WF_COL_F64, 0},
    {{"mpg", "mi/gal", "fuel economy (US miles per US gallon)"}, WF_COL_F64, 0},
    {{"stops", "1", "stops: speed fell below v_stop after exceeding v_go"}, WF_COL_I64, 0},
    {{"time_stopped", "s", "time spent slower than v_stop"}, WF_COL_F64, 0},
    {{"mean_speed", "m/s", "distance / window length"}, WF_COL_F64, 0},
    {{"speed_var", "m^2/s^2", "variance of the vehicle's speed over time (step samples)"}, WF_COL_F64, 0},
    {{"accel_var", "m^2/s^4", "variance of the vehicle's acceleration over time (step samples)"}, WF_COL_F64, 0},
    {{"hard_brakes", "1", "hard-braking events: a fell below -statistics.hard_brake_mps2"}, WF_COL_I64, 0},
    {{"infeasible_steps", "1", "steps whose acceleration exceeded the class a_max"}, WF_COL_I64, 0},
    {{"final_x", "m", "unwrapped position at the end"}, WF_COL_F64, 0},
    {{"final_v", "m/s", "speed at the end"}, WF_COL_F64, 0},
    /* multi-lane rings only (from WF_VEH_N_SINGLE on) */
    {{"final_lane", "1", "lane at the end (0: the rightmost)"}, WF_COL_I64, 0},
    {{"lane_changes", "1", "lane changes made (the whole run)"}, WF_COL_I64, 0},
    {{"cut_ins", "1", "vehicles that changed into the lane right ahead of it (the whole run)"}, WF_COL_I64, 0},
};

/* Population variance over time from the sums of samples and of their squares (clamped at 0: rounding). */
static double time_var(double sum, double sum2, double steps)
{
    return steps > 0 ? fmax(0.0, sum2 / steps - (sum / steps) * (sum / steps)) : 0.0;
}

double wf_vehicle_value(const WfVehicleView *v, size_t col, size_t id)
{
    const WfFleet *f = v->f;
    size_t i = f->pos ? f->pos[id] : id; /* its slot */
    const WfVehicleClass *vc = &v->sc->classes[f->class_id[i]].vc;
    double win_steps = v->window_s / v->sc->dt_s;
    switch (col) {
    case V_CLASS: return f->class_id[i];
    case V_GROUP: return f->group_id[i];
    case V_LENGTH: return wf_fleet_length(f, i);
    case V_DIST: return wf_fleet_distance(f, i);
    case V_FUEL: return f->fuel_g[i];
    case V_L100: return wf_l_per_100km(vc, f->fuel_g[i], wf_fleet_distance(f, i));
    case V_MPG: return wf_mpg(vc, f->fuel_g[i], wf_fleet_distance(f, i));
    case V_STOPS: return f->stops[i];
    case V_STOPPED: return (double)f->stopped_steps[i] * v->sc->dt_s;
    case V_MEAN_V: return v->window_s > 0 ? wf_fleet_distance(f, i) / v->window_s : 0.0;
    case V_VAR_V: return time_var(f->sum_v[i], f->sum_v2[i], win_steps);
    case V_VAR_A: return time_var(f->sum_a[i], f->sum_a2[i], win_steps);
    case V_HARD: return f->hard_brakes[i];
    case V_INFEAS: return f->infeasible_steps[i];
    case V_X: return f->lap_m ? f->x_m[i] + f->lap_m[i] : f->x_m[i];
    case V_LANE: return f->lane[i];
    case V_CHANGES: return f->lane_changes[i];
    case V_CUT_INS: return f->cut_ins[i];
    default: return f->v_mps[i];
    }
}
