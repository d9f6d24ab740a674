/* The observers' column tables: every dataset group a result file holds from per-vehicle or per-record data
 * declares its columns here once (name, units, description, type, and whether the values are known when the file
 * is created or only at the end), next to the code that computes them (src/observe/vehicles.c, trips.c,
 * trajectories.c, detectors.c, edie.c; the time series' columns: wf_ts_columns in stats.c and
 * wf_corridor_columns in src/core/corridor.c). The HDF5 writer (src/io/h5result.c) loops over these tables, and
 * tests/t_units_docs.sh compares what it writes with docs/output.md. Internal to wavefuel (not installed). */
#ifndef WAVEFUEL_OBSERVE_COLUMNS_H
#define WAVEFUEL_OBSERVE_COLUMNS_H

#include <stddef.h>

#include "wavefuel/corridor.h"
#include "wavefuel/fleet.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"

typedef enum { WF_COL_F64 = 0, WF_COL_I64 = 1 } WfColType;
/* A column of an observer: at_start 1 when its values are known when the file is created (written once then),
 * 0 when they are results allocated at the start and written at the end. */
typedef struct WfObsColumn {
    WfColumn  col;
    WfColType type;
    int       at_start;
} WfObsColumn;
/* The values of one column of a gridded observer (detectors, Edie): rank 1 or 2, dims in rows x columns; data is
 * double or int64_t as the column's type says (borrowed). */
typedef struct WfObsData {
    const void *data;
    int         rank;
    size_t      dims[2];
} WfObsData;

/* ---- /timeseries: the per-class column that follows the scalar columns of a record */
extern const WfColumn wf_ts_class_column;       /* ring */
extern const WfColumn wf_corridor_class_column; /* corridor */

/* ---- /vehicles (ring): one value per vehicle */
enum { WF_VEH_N_COLS = 19, WF_VEH_N_SINGLE = 16 }; /* the columns from WF_VEH_N_SINGLE on: multi-lane rings */
extern const WfObsColumn wf_vehicle_columns[WF_VEH_N_COLS];
/* What the per-vehicle values are computed from (borrowed). */
typedef struct WfVehicleView {
    const WfFleet    *f;
    const WfScenario *sc;
    double            window_s;   /* length of the statistics window */
} WfVehicleView;
/* Value of column `col` of vehicle `id` (its index at the start; integers as exact doubles). */
double wf_vehicle_value(const WfVehicleView *v, size_t col, size_t id);

/* ---- /lanes (multi-lane rings): per record and lane, per record, and the run's counts (src/observe/lanes.c) */
enum { WF_LANE_VEHICLES, WF_LANE_DENSITY, WF_LANE_FLOW, WF_LANE_MEAN_V, WF_LANE_SD_V, WF_LANE_WAVES,
       WF_LANE_FUEL_RATE, WF_LANE_MEAN_GAP, WF_LANE_FRAC_STOPPED, WF_LANE_N_COLS };
enum { WF_LANE_REC_N_COLS = 3, WF_LANE_CNT_N_COLS = 6 };
extern const WfObsColumn wf_lane_columns[WF_LANE_N_COLS];
extern const WfObsColumn wf_lane_record_columns[WF_LANE_REC_N_COLS];
extern const WfObsColumn wf_lane_count_columns[WF_LANE_CNT_N_COLS];
/* A lane's columns from its record and its n vehicles on a road of length_m: v a record row of either boundary
 * (/timeseries), from[c] where it holds lane column WF_LANE_MEAN_V + c (mean speed, its s.d., waves, fuel rate,
 * mean gap, fraction stopped). */
void wf_lane_values(const double *v, const int *from, double n, double length_m, double *out);
/* The next /lanes row of a record at t in rows (max rows of len values, *n_rows taken): t, then the lane changes and
 * cut-ins since the last record, which restart at 0. Returns where the lanes' columns go, or NULL when rows are full. */
double *wf_lane_row(double *rows, size_t len, size_t max, int64_t *n_rows, int64_t *changes, int64_t *cut_ins, double t);

/* ---- /trips (corridor): one row per trip, float64 (integers are exact below 2^53) */
enum { WF_TRIP_N_COLS = 18, WF_TRIP_N_SINGLE = 16 }; /* the columns from WF_TRIP_N_SINGLE on: multi-lane roads */
extern const WfColumn wf_trip_columns[WF_TRIP_N_COLS];
double wf_trip_value(const WfTrip *t, size_t col);

/* ---- /trajectories: ring frames [time x vehicle] (the arrays, then the frame times); corridor points, one row
 * per vehicle on the road per frame */
enum { WF_RING_TRAJ_N_COLS = 6, WF_CORRIDOR_TRAJ_N_COLS = 7, WF_CORRIDOR_TRAJ_SINGLE = 6 };
enum { WF_RING_TRAJ_LANE = 5 }; /* the ring's lane column: multi-lane rings only */
extern const WfColumn wf_ring_traj_columns[WF_RING_TRAJ_N_COLS];
extern const WfColumn wf_corridor_traj_columns[WF_CORRIDOR_TRAJ_N_COLS];
/* The ring's frame at time t: the columns' arrays (the fleet's, borrowed; &t for the time). A multi-lane ring's
 * vehicles move between slots: its columns are gathered vehicle by vehicle into frame (5 n doubles). */
void wf_ring_traj_frame(const WfFleet *f, const double *t_s, double *frame, const double **cols);
/* The corridor's frame at time t_s, lane after lane, each in road order (front first), into frame
 * (WF_CORRIDOR_TRAJ_N_COLS columns of cap values each; cap >= the vehicles on the road); cols receives the columns'
 * starts (the lane column: multi-lane roads). Returns the points. */
size_t wf_corridor_traj_frame(const WfCorridorVehicles *const *lanes, size_t n_lanes, double t_s, double *frame,
                              size_t cap, const double **cols);

/* ---- /detectors (corridor) */
enum { WF_DET_N_COLS = 8 };
extern const WfObsColumn wf_detector_columns[WF_DET_N_COLS];
/* Doubles of scratch wf_detectors_fields needs. */
size_t wf_detectors_scratch(const WfDetectors *d);
/* Every column's values (intervals, flows, mean speeds, occupancy) from the detectors' sums, into out[k] for
 * column k; derived values live in scratch, the others are borrowed from d. */
void wf_detectors_fields(const WfDetectors *d, const WfScenario *sc, double *scratch, WfObsData *out);

/* ---- /edie (corridor) */
enum { WF_EDIE_N_COLS = 15 };
extern const WfObsColumn wf_edie_columns[WF_EDIE_N_COLS];
/* Columns of /edie indexed [t x x] (they carry an `axes` attribute). */
int    wf_edie_is_field(size_t col);
size_t wf_edie_scratch(const WfEdie *e, size_t n_classes);
/* Every column's values (cell edges and centres, Edie's q, k, v, the fuel field, per-class fuel per km) into
 * out[k] for column k; derived values live in scratch, the others are borrowed from e. */
void wf_edie_fields(const WfEdie *e, const WfScenario *sc, double *scratch, WfObsData *out);

#endif
