/* Trajectories (/trajectories): the columns of ring frames and corridor points, and how a frame is taken from the
 * engine's arrays. Also the per-class column of the time series, which has no scalar table of its own. */
#include "observe/columns.h"

const WfColumn wf_ts_class_column = {"class_fuel_rate", "g/s", "fuel rate of each class [time x class]"};
const WfColumn wf_corridor_class_column = {"class_fuel_rate", "g/s",
                                           "fuel rate of each class on the road [time x class]"};

/* In the order of the group appended together: the arrays, then the frame times. */
const WfColumn wf_ring_traj_columns[WF_RING_TRAJ_N_COLS] = {
    {"x", "m", "unwrapped front-bumper position [time x vehicle]"},
    {"v", "m/s", "speed [time x vehicle]"},
    {"a", "m/s^2", "acceleration applied from this instant"},
    {"fuel_rate", "g/s", "fuel rate [time x vehicle]"},
    {"t", "s", "time of each frame"},
    {"lane", "1", "lane (0: the rightmost) [time x vehicle]; multi-lane rings only"},
};

const WfColumn wf_corridor_traj_columns[WF_CORRIDOR_TRAJ_N_COLS] = {
    {"t", "s", "time of each point"},
    {"serial", "1", "vehicle (trips/serial) of each point"},
    {"x", "m", "front-bumper position from the entrance"},
    {"v", "m/s", "speed"},
    {"a", "m/s^2", "acceleration applied from this instant"},
    {"fuel_rate", "g/s", "fuel rate"},
    {"lane", "1", "lane (0: the rightmost); multi-lane corridors only"},
};

void wf_ring_traj_frame(const WfFleet *f, const double *t_s, double *frame, const double **cols)
{
    cols[0] = f->x_m, cols[1] = f->v_mps, cols[2] = f->a_mps2, cols[3] = f->fuel_rate_gps, cols[4] = t_s;
    if (!f->pos) return;
    size_t n = f->n;
    double *c[5] = {frame, frame + n, frame + 2 * n, frame + 3 * n, frame + 4 * n};
    for (size_t id = 0; id < n; id++) {
        size_t s = f->pos[id];
        c[0][id] = f->x_m[s] + f->lap_m[s], c[1][id] = f->v_mps[s], c[2][id] = f->a_mps2[s];
        c[3][id] = f->fuel_rate_gps[s];
        c[4][id] = f->lane[s];
    }
    cols[0] = c[0], cols[1] = c[1], cols[2] = c[2], cols[3] = c[3], cols[WF_RING_TRAJ_LANE] = c[4];
}

size_t wf_corridor_traj_frame(const WfCorridorVehicles *const *lanes, size_t n_lanes, double t_s, double *frame,
                              size_t cap, const double **cols)
{
    double *col[WF_CORRIDOR_TRAJ_N_COLS];
    for (size_t k = 0; k < WF_CORRIDOR_TRAJ_N_COLS; k++) cols[k] = col[k] = frame + k * cap;
    size_t j = 0;
    for (size_t l = 0; l < n_lanes; l++) {
        const WfCorridorVehicles *vh = lanes[l];
        for (size_t k = 0; k < vh->n; k++, j++) {
            size_t s = wf_corridor_slot(vh, k);
            col[0][j] = t_s, col[1][j] = (double)vh->serial[s], col[2][j] = vh->x_m[s], col[3][j] = vh->v_mps[s];
            col[4][j] = vh->a_mps2[s], col[5][j] = vh->fuel_rate_gps[s], col[6][j] = (double)l;
        }
    }
    return j;
}
