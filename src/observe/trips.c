/* Trips of a corridor (/trips): the columns and each trip's value, one row per vehicle that entered. */
#include "observe/columns.h"

enum { TR_SERIAL, TR_CLASS, TR_GROUP, TR_COMPLETED, TR_ARRIVAL, TR_ENTRY, TR_EXIT, TR_TRAVEL, TR_DELAY, TR_VENTRY,
       TR_FUEL, TR_DIST, TR_STOPS, TR_STOPPED, TR_HARD, TR_INFEAS, TR_LANE, TR_CHANGES };

const WfColumn wf_trip_columns[WF_TRIP_N_COLS] = {
    /* on lane l of a multi-lane corridor: l 2^40 + the lane's arrival number (docs/lanes.md) */
    {"serial", "1", "arrival number of the vehicle (0, 1, ...): the key of its random draws"},
    {"class_id", "1", "index into /classes"},
    {"group_id", "1", "index into /drivers"},
    {"completed", "1", "1: the vehicle reached x = L; 2: it left by the off-ramp (corridor.off_ramp); 0: still on the "
                       "road at the end"},
    {"arrival_time", "s", "time the vehicle reached the entrance (joined the queue)"},
    {"entry_time", "s", "time it was inserted at x = 0"},
    {"exit_time", "s", "time its front reached x = L, or the off-ramp (end of that step; NaN when not completed)"},
    {"travel_time", "s", "exit_time - entry_time (NaN when not completed)"},
    {"queue_delay", "s", "entry_time - arrival_time"},
    {"entry_speed", "m/s", "speed at insertion"},
    {"fuel", "g", "fuel burnt on the road (whole trip, warm-up included)"},
    {"distance", "m", "distance travelled on the road"},
    {"stops", "1", "stops (docs/metrics.md) during the trip"},
    {"time_stopped", "s", "time slower than statistics.v_stop_mps during the trip"},
    {"hard_brakes", "1", "hard-braking events during the trip"},
    {"infeasible_steps", "1", "steps whose requested acceleration exceeded the class a_max"},
    /* multi-lane corridors only (from WF_TRIP_N_SINGLE on) */
    {"lane", "1", "lane at the exit, or at the end when not completed (0: the rightmost)"},
    {"lane_changes", "1", "lane changes during the trip"},
};

double wf_trip_value(const WfTrip *t, size_t col)
{
    switch (col) {
    case TR_SERIAL: return (double)t->serial;
    case TR_CLASS: return t->class_id;
    case TR_GROUP: return t->group_id;
    case TR_COMPLETED: return t->completed;
    case TR_ARRIVAL: return t->t_arrival_s;
    case TR_ENTRY: return t->t_entry_s;
    case TR_EXIT: return t->t_exit_s;
    case TR_TRAVEL: return t->t_exit_s - t->t_entry_s;
    case TR_DELAY: return t->t_entry_s - t->t_arrival_s;
    case TR_VENTRY: return t->v_entry_mps;
    case TR_FUEL: return t->fuel_g;
    case TR_DIST: return t->dist_m;
    case TR_STOPS: return t->stops;
    case TR_STOPPED: return t->time_stopped_s;
    case TR_HARD: return t->hard_brakes;
    case TR_LANE: return t->lane;
    case TR_CHANGES: return t->lane_changes;
    default: return t->infeasible_steps;
    }
}
