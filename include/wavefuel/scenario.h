/* Scenarios: a YAML file (plus --set overrides) turned into a plain, validated struct. The engine reads
 * only this struct; it never sees text. Every key, with its unit, default, range and boundary, is a row of a key
 * table (include/wavefuel/keys.h) that the loader reads and docs/scenarios.md and docs/corridors.md show. */
#ifndef WAVEFUEL_SCENARIO_H
#define WAVEFUEL_SCENARIO_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/cf.h"
#include "wavefuel/err.h"
#include "wavefuel/ode.h"
#include "wavefuel/road.h"
#include "wavefuel/safety.h"
#include "wavefuel/lanechange.h"
#include "wavefuel/vehicle.h"

#define WF_MAX_CLASSES      16
#define WF_MAX_GROUPS       16
#define WF_MAX_LANES        8  /* lanes of a road (road.lanes) */
#define WF_MAX_MODEL_PARAMS 32 /* doubles in one model's parameter struct */

typedef enum { WF_PLACE_RANDOM = 0, WF_PLACE_INTERLEAVED = 1, WF_PLACE_EXPLICIT = 2 } WfPlacement;
typedef enum { WF_HET_NORMAL = 0, WF_HET_UNIFORM = 1 } WfHetDist;
typedef enum { WF_INIT_EQUILIBRIUM = 0, WF_INIT_REST = 1 } WfInitState;

typedef struct WfClassShare {
    WfVehicleClass vc;         /* owned (wf_vehicle_free) */
    double         fraction;   /* of the fleet; NaN when count is given */
    long           count;      /* resolved vehicle count */
    double         length_m;   /* vehicle length for this class (class default unless overridden) */
    long          *indices;    /* owned; explicit placement only */
    size_t         n_indices;
} WfClassShare;

typedef struct WfDriverGroup {
    char             name[64];
    const WfCfModel *model;                          /* borrowed registry entry */
    double           params[WF_MAX_MODEL_PARAMS];    /* the model's parameter struct (all doubles) */
    double           spread[WF_MAX_MODEL_PARAMS];    /* relative spread of each spec entry; 0 = none */
    WfHetDist        dist;
    double           fraction;
    long             count;
    double           noise_mps2;         /* std of additive white acceleration noise */
    double           accel_max_mps2;     /* comfortable acceleration limit */
    double           decel_max_mps2;     /* emergency deceleration limit (positive number) */
    int              clip_feasible;      /* 1: also a <= a_max(v, theta) of the vehicle's class */
    long            *indices;            /* owned; explicit placement only */
    size_t           n_indices;
    /* Placement of this group alone (automated vehicles): -1 = with the other groups by fleet.placement;
     * otherwise a WfPlacement, applied before the groups placed by fleet.placement (src/core/fleet.c). */
    int              placement;
    int              class_index;        /* -1: any; else index into classes[]: all its vehicles are that class */
    struct WfCfPluginLib *plugin;        /* owned: the library of a `model: plugin` group (model points into
                                            it); NULL for built-in models */
    struct WfMlp         *mlp;           /* owned: the network of a `model: mlp` group (model points into it);
                                            NULL otherwise */
    const WfSafetyKind *safety;          /* borrowed registry entry: the group's safety filter; NULL: none */
    double           safety_params[WF_MAX_SAFETY_PARAMS]; /* the filter's parameter struct (all doubles) */
    /* borrowed registry entry: the group's lane-change model on a multi-lane road; NULL: never changes lanes */
    const WfLaneChangeModel *lc;
    double           lc_params[WF_MAX_LC_PARAMS]; /* the model's parameter struct (all doubles) */
} WfDriverGroup;

typedef struct WfScenario {
    char    path[1024];
    char   *text;            /* owned: the scenario file verbatim */
    char   *overrides;       /* owned: the --set assignments, one per line */
    char    name[128];
    WfRoad  road;
    double  duration_s, dt_s, output_interval_s, warmup_s;
    char    integrator[32];
    int     adaptive;             /* 1: a SUNDIALS integrator (cvode, arkode, rk4) configured by `solver` */
    WfOdeConfig solver;
    int     fused_step;           /* 1: steps that record nothing run in one fused pass (same results, faster) */
    int     block_steps;          /* ring: steps per time-blocked window (0: the default, 1: one step at a time) */
    long    tile_vehicles;        /* ring: vehicles per tile of a window (0: from the cache size) */
    long    thread_check_steps;   /* corridor: steps between timings of the other thread count (0: never) */
    uint64_t seed;
    long    n_vehicles;
    /* lanes (road.lanes, 1 to WF_MAX_LANES), their passing rule (WF_LANE_RULE_*) and each lane's vehicles at the
     * start (fleet.lane_counts; lane 0 is the rightmost and holds vehicles 0 .. lane_counts[0] - 1 of the
     * placement, lane 1 the next ones, ...) */
    int     n_lanes, lane_rule;
    long    lane_counts[WF_MAX_LANES];
    double  lane_speed_limit_mps[WF_MAX_LANES]; /* road.lane_speed_limits_mps (default: the road's; +inf: none) */
    WfPlacement placement;
    WfClassShare  classes[WF_MAX_CLASSES];
    size_t        n_classes;
    WfDriverGroup groups[WF_MAX_GROUPS];
    size_t        n_groups;
    WfInitState init_state;
    long    perturb_vehicle;      /* -1: none */
    double  perturb_dx_m, perturb_dv_mps;
    double  jitter_m;             /* uniform random position jitter half-width */
    /* statistics thresholds */
    double  v_stop_mps, v_go_mps, hard_brake_mps2, wave_speed_mps;
    /* output */
    char    output_path[1024];
    int     trajectories;
    double  trajectory_interval_s;
    /* road.type corridor: the corridor-only keys (include/wavefuel/corridor.h); owned. NULL for a ring. */
    struct WfCorridorSpec *corridor;
    /* Every file the scenario was read from, as opened: the scenario, class files and their tables, profile CSVs,
     * controller plug-ins, network files. A run refuses to write its result over any of them. Owned (the array and
     * strings). */
    char  **inputs;
    size_t  n_inputs;
} WfScenario;

/* Load, apply `n_set` overrides ("key.path=value"), validate. On error nothing is allocated. Ownership: *out is
 * the caller's until wf_scenario_destroy() and holds copies of everything (path, set and the file's text);
 * the vehicle classes it loaded, the plug-ins it opened and the networks it read live as long as it does. */
int wf_scenario_load(const char *path, const char *const *set, size_t n_set, WfScenario **out, WfError *err);
/* Same from the scenario's text (a resumed run uses the text saved in its checkpoint); `path` is used in messages
 * and to resolve relative paths (grade CSV, class files). */
int wf_scenario_load_text(const char *path, const char *text, const char *const *set, size_t n_set,
                          WfScenario **out, WfError *err);
void wf_scenario_destroy(WfScenario **sc);

/* Lanes of the road: road.lanes, and a corridor's merge lane (corridor.on_ramp) when it has one. */
int wf_scenario_lanes(const WfScenario *sc);

/* Number of steps and output records implied by the time section. */
long wf_scenario_n_steps(const WfScenario *sc);
long wf_scenario_output_every(const WfScenario *sc); /* steps between output records */
long wf_scenario_trajectory_every(const WfScenario *sc); /* steps between trajectory frames (>= 1) */
/* Records written at the steps 0, every, 2 every, ... up to n_steps: n_steps / every + 1. */
long wf_scenario_records(const WfScenario *sc, long every);

#endif
