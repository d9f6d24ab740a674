/* Open corridors: a single-lane road of length L that vehicles enter at x = 0 (an inflow in veh/h, queued when
 * the gap does not allow them in) and leave at x = L, with a non-periodic grade profile, speed-limit and
 * time-headway zones, a free or prescribed-speed downstream boundary, and the measurements traffic engineers
 * read: per-trip results, virtual detectors and Edie's generalized flow, density and speed on a space-time grid.
 * The corridor is the open boundary of the engine's block kernel (src/core/block.c), which the ring shares:
 * the same per-vehicle rules, models, integrators and counter-based random numbers; definitions, keys and units:
 * docs/corridors.md. */
#ifndef WAVEFUEL_CORRIDOR_H
#define WAVEFUEL_CORRIDOR_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/engine.h"
#include "wavefuel/err.h"
#include "wavefuel/rng.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"

struct WfCfgNode;

/* Random streams of the corridor (rng.h reserves WF_RNG_USER and up for such uses). */
enum { WF_RNG_CORRIDOR_ENTRY = WF_RNG_USER + 32, WF_RNG_CORRIDOR_ARRIVAL = WF_RNG_USER + 33 };

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

/* WfCorridorCounts: the vehicle counts of an open road, in wavefuel/summary.h (part of the summary). */

/* One trip. Unfinished trips (vehicles still on the road at the end) have completed = 0 and t_exit_s = NaN. */
typedef struct WfTrip {
    uint64_t serial;
    uint16_t class_id, group_id;
    uint8_t  completed;
    double   t_arrival_s, t_entry_s, t_exit_s, v_entry_mps;
    double   fuel_g, dist_m, time_stopped_s;
    uint32_t stops, hard_brakes, infeasible_steps;
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
    double *dist_m, *time_s, *fuel_g;
    double *grade_mean_rad;           /* [nx] cell mean of theta */
    double *class_dist_m, *class_fuel_g;
} WfEdie;

/* A corridor's summary is the common WfSummary (wavefuel/summary.h): the fields a ring does not have stay 0. */
typedef WfClassSummary WfCorridorClassSummary;
typedef WfSummary WfCorridorSummary;

/* Output sink (HDF5 in src/io/h5corridor.c; tests use their own). Each callback may be NULL and returns 0 or an
 * error code. trips() receives completed trips in blocks as they happen and, at the end, the unfinished ones. */
typedef struct WfCorridorOutput {
    int (*begin)(void *ctx, const WfCorridor *c, WfError *err);
    int (*record)(void *ctx, const WfCorridor *c, const WfCorridorRow *row, WfError *err);
    int (*trajectory)(void *ctx, const WfCorridor *c, double t_s, WfError *err);
    int (*trips)(void *ctx, const WfCorridor *c, const WfTrip *trips, size_t n, WfError *err);
    /* Save everything needed to resume (every checkpoint interval of wall time, and when the run is interrupted):
     * called between steps, after every completed trip so far has gone to trips(); may be NULL. */
    int (*checkpoint)(void *ctx, const WfCorridor *c, WfError *err);
    int (*end)(void *ctx, const WfCorridor *c, int completed, const char *reason, WfError *err);
    void *ctx;
} WfCorridorOutput;

/* Build the engine for a corridor scenario (sc->corridor set; sc is borrowed and must outlive the engine).
 * Everything is allocated here: the vehicle buffer (capacity floor(L / shortest length) + 2, which no order-
 * keeping state can exceed), the entrance queue, trips buffer, detectors and Edie grid. Ownership: *out is the
 * caller's until wf_corridor_destroy(); NULL on failure (nothing to free). */
int  wf_corridor_create(const WfScenario *sc, WfCorridor **out, WfError *err);
void wf_corridor_destroy(WfCorridor **c);
/* Run to the end (from the restored step after wf_corridor_restored), as wf_sim_run: *stop (may be NULL) ends the
 * run after the current step with out->checkpoint, out->end(completed = 0) and WF_EINTR; progress may be NULL. */
int  wf_corridor_run(WfCorridor *c, const WfCorridorOutput *out, WfProgressFn progress, void *pctx,
                     volatile sig_atomic_t *stop, WfError *err);

/* Call out->checkpoint every `wall_s` seconds of wall time (0: only when the run is interrupted). */
void wf_corridor_set_checkpoint_interval(WfCorridor *c, double wall_s);
/* The complete state of a run between two steps as named byte blocks (WfStateVar, engine.h), at most max of
 * them, returning their number (at most WF_MAX_STATE_VARS): the vehicles' slots (positions, speeds, drawn
 * parameters, controller memory, serials, trip and window accumulators), the entrance queue and the drawn
 * candidate at its head, the virtual leader, the counters and totals, the detector and Edie sums and the step,
 * which with the vehicle serials and arrival numbers keys every random draw still to come. Blocks have fixed
 * sizes for a given scenario. After saved bytes are written back into them, wf_corridor_restored() checks
 * them and makes the next wf_corridor_run continue from the saved step. */
size_t wf_corridor_state(WfCorridor *c, WfStateVar *vars, size_t max);
/* WF_EINPUT naming the first inconsistency (a slot, queue or step index out of range, an unknown class or driver
 * group on the road) when the restored blocks cannot be a state of this scenario. */
int    wf_corridor_restored(WfCorridor *c, WfError *err);

const WfScenario         *wf_corridor_scenario(const WfCorridor *c);
const WfCorridorVehicles *wf_corridor_vehicles(const WfCorridor *c);
const WfCorridorCounts   *wf_corridor_counts(const WfCorridor *c);
const WfCorridorSummary  *wf_corridor_summary(const WfCorridor *c); /* valid after wf_corridor_run */
const WfDetectors        *wf_corridor_detectors(const WfCorridor *c);
const WfEdie             *wf_corridor_edie(const WfCorridor *c);
/* Virtual leader (leader and speed outflows): rear-bumper position and speed now; returns 0 for free outflow. */
int    wf_corridor_leader(const WfCorridor *c, double *x_m, double *v_mps);
double wf_corridor_wall_s(const WfCorridor *c);
long   wf_corridor_steps_done(const WfCorridor *c);
int    wf_corridor_threads(const WfCorridor *c);

#endif
