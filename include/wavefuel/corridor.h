/* Open corridors: a road of length L, of one lane or several (docs/lanes.md), that vehicles enter at x = 0 (an
 * inflow in veh/h, queued when the gap does not allow them in) and leave at x = L, with a non-periodic grade
 * profile, speed-limit and
 * time-headway zones, a free or prescribed-speed downstream boundary, and the measurements traffic engineers
 * read: per-trip results, virtual detectors and Edie's generalized flow, density and speed on a space-time grid.
 * The corridor is the open boundary of the engine's block kernel (src/core/block.c), which the ring shares:
 * the same per-vehicle rules, models, integrators and counter-based random numbers; definitions, keys and units:
 * docs/corridors.md. */
#ifndef WAVEFUEL_CORRIDOR_H
#define WAVEFUEL_CORRIDOR_H

#include <stddef.h>
#include <stdint.h>

#include "wavefuel/engine.h"
#include "wavefuel/err.h"
#include "wavefuel/rng.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"

struct WfCfgNode;

/* Random streams of the corridor (rng.h reserves WF_RNG_USER and up for such uses). */
enum { WF_RNG_CORRIDOR_ENTRY = WF_RNG_USER + 32, WF_RNG_CORRIDOR_ARRIVAL = WF_RNG_USER + 33,
       WF_RNG_CORRIDOR_EXIT = WF_RNG_USER + 34 };

/* Class and group shares of a corridor are fractions; the ring loader resolves them against this many
 * vehicles (its counts are not used by the corridor). */
#define WF_CORRIDOR_SHARE_BASE 1000000L
/* Bumper-to-bumper gap of the free-road virtual leader (outflow: free): far enough that every shipped model
 * drives as on an empty road (IDM's interaction term (s* / s)^2 is below 1e-7 at highway speeds). */
#define WF_CORRIDOR_FREE_GAP_M 1e5
#define WF_CORRIDOR_MAX_ZONES 64
#define WF_CORRIDOR_MAX_DETECTORS 256

/* ------------------------------------------------------------------------------------- scenario part */

/* A piecewise-linear function of time: y(t) linear between the points, held at the end values outside them.
 * cum[i] = integral of y from t[0] to t[i]. */
typedef struct WfProfile {
    size_t  n;
    double *t, *y, *cum; /* owned */
} WfProfile;

typedef enum { WF_ARRIVALS_DETERMINISTIC = 0, WF_ARRIVALS_POISSON = 1 } WfArrivals;
typedef enum { WF_OUTFLOW_FREE = 0, WF_OUTFLOW_LEADER = 1, WF_OUTFLOW_SPEED = 2 } WfOutflow;
typedef enum { WF_ZONE_SPEED_LIMIT = 0, WF_ZONE_HEADWAY = 1 } WfZoneType;

typedef struct WfCorridorZone {
    WfZoneType type;
    double     from_m, to_m; /* the zone is [from, to) in front-bumper position */
    double     value;        /* speed limit (m/s), or the headway factor (1) */
    char       key[32];      /* headway zones: the driver-model parameter multiplied ("T_s") */
    unsigned   lane_mask;    /* the lanes it applies to (bit l: lane l); 0: every lane */
} WfCorridorZone;

/* Everything a corridor scenario adds to WfScenario (owned by it: WfScenario.corridor). */
typedef struct WfCorridorSpec {
    /* grade: theta linear between points (grade input) or constant on each segment (elevation input); outside
     * the points: the end values (grade input) or 0 (elevation input: the road is flat beyond the profile) */
    size_t  n_grade;
    double *grade_x_m, *grade_rad; /* owned */
    int     grade_steps;           /* 1: piecewise constant (derived from an elevation profile) */
    double *elev_z_m;              /* owned, elevation input only (for the record) */
    /* inflow */
    WfArrivals arrivals;
    WfProfile  inflow_vph;         /* demand at the entrance, veh/h */
    double     entry_speed_mps;    /* cap on the entry speed; +inf: none */
    double     insert_decel_mps2;  /* an entry may not make the vehicle's model brake harder than this */
    int64_t    max_arrivals;       /* -1: unlimited */
    int        interleaved;        /* fleet.placement interleaved: shares assigned by deficit, not drawn */
    double     lane_share[WF_MAX_LANES]; /* each main lane's share of the demand (corridor.inflow.lane_shares) */
    /* an on-ramp (corridor.on_ramp): a merge lane from ramp_from_m to ramp_to_m, its own demand; it is lane 0 and the
     * road's lanes follow as 1, 2, ... */
    int        has_ramp;
    double     ramp_from_m, ramp_to_m;
    WfProfile  ramp_vph;
    /* where each lane ends (corridor.lane_drops; lanes numbered with the merge lane): +inf for the exit */
    double     lane_end_m[WF_MAX_LANES];
    /* an off-ramp (corridor.off_ramp): it leaves the rightmost main lane (exit_lane: 1 with an on-ramp, else 0) at
     * off_at_m; a share of the vehicles that enter upstream of it take it, changing right within off_approach_m */
    int        has_offramp;
    double     off_at_m, off_share, off_approach_m;
    size_t     exit_lane;
    /* outflow */
    WfOutflow  outflow;
    WfProfile  leader_speed_mps;   /* the virtual leader's speed profile (leader and speed outflows) */
    double     leader_offset_m;    /* the virtual leader starts at x = L + offset (>= 0 from the entrance) */
    /* zones */
    WfCorridorZone zones[WF_CORRIDOR_MAX_ZONES];
    size_t     n_zones;
    double     zone_decel_mps2;    /* drivers brake at this rate to meet a lower limit at a zone's start */
    /* measurement */
    double     det_x_m[WF_CORRIDOR_MAX_DETECTORS];
    size_t     n_det;
    double     det_interval_s;
    double     edie_dx_m, edie_dt_s;
} WfCorridorSpec;

/* Called by the scenario loader (src/scenario/scenario.c) for `road.type: corridor` after the fleet is read: reads
 * road.grade / road.elevation / road.zones and the `corridor` section into a new WfCorridorSpec stored in
 * sc->corridor, and checks what the ring loader read against corridor semantics (fractions, no `initial`,
 * fixed-step integrator). Errors name file, line and key. Ownership: the spec belongs to sc (freed by
 * wf_scenario_destroy); root is only read. */
int  wf_corridor_spec_load(WfScenario *sc, struct WfCfgNode *root, WfError *err);
void wf_corridor_spec_destroy(WfCorridorSpec **spec);

/* y(t) and the integral of y from 0 to t (t >= 0) of a profile. *seg caches the segment (start it at 0). */
double wf_profile_value(const WfProfile *p, double t, size_t *seg);
double wf_profile_integral(const WfProfile *p, double t, size_t *seg);

/* Grade angle (rad) at position x on the corridor's non-periodic profile; *seg caches the segment. */
double wf_corridor_grade(const WfCorridorSpec *cs, double x_m, uint32_t *seg);
/* Mean grade over [a, b] (exact for the piecewise profile), rad. */
double wf_corridor_grade_mean(const WfCorridorSpec *cs, double a_m, double b_m);

/* --------------------------------------------------------------------------------------- engine part */

/* The open boundary's engine, created by wf_sim_create (engine.h) for a corridor scenario: vehicle capacity
 * floor(L / shortest length) + 2 (no order-keeping state can exceed it), the entrance queue, the trips buffer,
 * detectors and Edie grid, all allocated then. */
typedef struct WfCorridor WfCorridor;

/* Vehicles on the road: a circular buffer of fixed capacity (a multiple of the kernel's block), in road order.
 * Logical index k = 0 is the front (most downstream) vehicle, k = n - 1 the last one to enter; vehicle k's leader
 * is k - 1, the front vehicle's the virtual leader. The back vehicle lives in slot `first` and leaders in the
 * following slots: logical k in slot (first + n - 1 - k) mod cap. A vehicle keeps its slot from entry to exit. */
typedef struct WfCorridorVehicles {
    size_t    cap, first, n;
    double   *x_m, *v_mps, *a_mps2;           /* front-bumper position from the entrance, speed, applied accel */
    double   *gap_m, *v_lead_mps, *theta_rad; /* inputs at the step's start */
    double   *fuel_rate_gps;
    uint8_t  *flag;
    double   *length_m;
    uint64_t *serial;                         /* arrival number: 0, 1, 2, ... */
    uint16_t *class_id, *group_id;
    double   *params;                         /* cap x WF_MAX_MODEL_PARAMS doubles: each vehicle's drawn params */
    unsigned char *state;                     /* cap x state stride bytes: controller memory */
} WfCorridorVehicles;

static inline size_t wf_corridor_slot(const WfCorridorVehicles *v, size_t k)
{
    size_t s = v->first + (v->n - 1 - k);
    return s >= v->cap ? s - v->cap : s;
}

/* The lanes of a corridor (road.lanes): lane l's vehicles, as wf_corridor_vehicles gives lane 0's. */
size_t wf_corridor_n_lanes(const struct WfCorridor *c);
const WfCorridorVehicles *wf_corridor_lane(const struct WfCorridor *c, size_t l);

/* WfCorridorCounts: the vehicle counts of an open road, in wavefuel/summary.h (part of the summary). */

/* One trip. Unfinished trips (vehicles still on the road at the end) have completed = 0 and t_exit_s = NaN. */
typedef struct WfTrip {
    uint64_t serial;
    uint16_t class_id, group_id;
    uint8_t  completed;
    double   t_arrival_s, t_entry_s, t_exit_s, v_entry_mps;
    double   fuel_g, dist_m, time_stopped_s;
    uint32_t stops, hard_brakes, infeasible_steps;
    uint8_t  lane;                            /* multi-lane corridors: the lane at the exit (or at the end) */
    uint32_t lane_changes;                    /* ... and the lane changes made */
} WfTrip;

/* Time-series columns of a corridor record (names and units in wf_corridor_columns). Speeds, gaps and their
 * spread are over the vehicles on the road at the instant (NaN when it is empty; gaps over vehicles with a
 * vehicle as leader). */
enum {
    WF_CTS_T, WF_CTS_VEHICLES, WF_CTS_MEAN_V, WF_CTS_SD_V, WF_CTS_MIN_V, WF_CTS_MAX_V, WF_CTS_FRAC_STOPPED,
    WF_CTS_WAVES, WF_CTS_FUEL_RATE, WF_CTS_MEAN_GAP, WF_CTS_MIN_GAP, WF_CTS_OVERLAPS, WF_CTS_ARRIVED,
    WF_CTS_ENTERED, WF_CTS_EXITED, WF_CTS_QUEUED, WF_CTS_DELAYED, WF_CTS_N_COLS
};
extern const WfColumn wf_corridor_columns[WF_CTS_N_COLS];

typedef struct WfCorridorRow {
    double v[WF_CTS_N_COLS];
    double class_fuel_rate_gps[WF_MAX_CLASSES];
} WfCorridorRow;

/* Virtual detectors: per interval and detector, front-bumper passages, the sums of their speeds and inverse
 * speeds (speed of a passage = distance of its step / dt), and the time the point was covered by a body. */
typedef struct WfDetectors {
    size_t   n_det, n_int;
    double   interval_s;
    const double *x_m;     /* borrowed from the spec */
    int64_t *count;        /* [n_int x n_det] */
    double  *sum_v_mps, *sum_inv_v_spm, *occupied_s;
} WfDetectors;

/* Edie's generalized definitions on cells [i dx, (i+1) dx) x [j dt, (j+1) dt): Σ distance travelled and Σ time
 * spent by front bumpers in each cell, and Σ fuel burnt there ([nt x nx], whole run); the class profiles are over
 * the statistics window ([n_classes x nx]). q = dist / (dx dt), k = time / (dx dt), v = q / k. */
typedef struct WfEdie {
    size_t  nx, nt;
    double  dx_m, dt_s;
    /* [lane x t x x]: each lane's cell sums (n_lanes planes of nt x nx; the road's field is their sum) */
    size_t  n_lanes;
    double *dist_m, *time_s, *fuel_g;
    double *grade_mean_rad;           /* [nx] cell mean of theta */
    double *class_dist_m, *class_fuel_g;
} WfEdie;


/* The corridor of a run (wf_sim_corridor, engine.h) and what it measures; borrowed from the run, valid while it
 * lives (the arrays change as it steps). */
const WfCorridorVehicles *wf_corridor_vehicles(const WfCorridor *c);
const WfCorridorCounts   *wf_corridor_counts(const WfCorridor *c);
const WfDetectors        *wf_corridor_detectors(const WfCorridor *c);
const WfEdie             *wf_corridor_edie(const WfCorridor *c);
/* Lane l's Edie cell sums as a WfEdie of one plane (lane < 0: the road's, every lane's summed in lane order into
 * scratch, 3 nt nx doubles, when there are several; borrowed otherwise). */
WfEdie wf_corridor_edie_lane(const WfEdie *e, int lane, double *scratch);

#endif
