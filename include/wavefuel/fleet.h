/* The fleet: vehicle state and per-vehicle accumulators as structure of arrays in ring order (the leader of
 * vehicle i is i + 1, and of the last one vehicle 0, one lap ahead), the driver groups' drawn parameters and
 * member lists, and the classes' member lists. Built once from a scenario; nothing is allocated afterwards. */
#ifndef WAVEFUEL_FLEET_H
#define WAVEFUEL_FLEET_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/err.h"
#include "wavefuel/partition.h"
#include "wavefuel/scenario.h"

typedef struct WfFleet {
    size_t n;
    /* state: front-bumper position (unwrapped, m), speed (m/s) */
    double *x_m, *v_mps;
    /* per-step values at the step's start: applied acceleration, bumper-to-bumper gap, leader speed, grade,
     * fuel rate, feasibility flag. Fleet-wide only when a step may run as two passes (SUNDIALS integrators,
     * trajectories, fused_step off: f->multipass); NULL otherwise, where the fused step keeps them per block. */
    int      multipass;
    double  *a_mps2, *gap_m, *v_lead_mps, *theta_rad, *fuel_rate_gps;
    uint8_t *flag;
    uint32_t *grade_seg; /* per-vehicle cache for wf_road_grade; NULL on a flat road */
    /* attributes: class, driver group, index within the group (controller state, drawn parameters; NULL when no
     * group has either, see wf_fleet_slot) */
    uint16_t *class_id, *group_id;
    uint32_t *slot;
    double    class_length_m[WF_MAX_CLASSES];
    /* groups: drawn parameters (param_size bytes each; one block with stride 0 when the group has no
     * heterogeneity), controller state, member counts */
    size_t    n_groups;
    size_t    group_n[WF_MAX_GROUPS];
    unsigned char *group_params[WF_MAX_GROUPS];
    size_t    group_param_stride[WF_MAX_GROUPS];
    unsigned char *group_state[WF_MAX_GROUPS];
    /* classes: member counts */
    size_t    n_classes;
    size_t    class_n[WF_MAX_CLASSES];
    /* accumulators over the statistics window (after warm-up). Distance and passages of x = 0 (mod L) follow
     * from the positions and x_start_m, the positions when the window opened. */
    int       window_open;
    double   *x_start_m, *fuel_g, *sum_v, *sum_v2, *sum_a, *sum_a2;
    uint32_t *stopped_steps, *stops, *hard_brakes, *infeasible_steps;
    uint8_t  *mode;      /* bit 0: moving (above v_go since the last stop); bit 1: braking hard; bit 2: fault */
    /* initial equilibrium (for the record; on a multi-lane ring, lane 0's) */
    double    v_init_mps;
    /* lanes (road.lanes): lane l holds the slots from lane_first(l) on, lane_n[l] of them, in ring order (the
     * leader of a lane's last vehicle is its first, one lap ahead). With one lane the arrays below are NULL and the
     * slot of a vehicle is the vehicle. Otherwise vehicles move between slots when they change lanes: id[s] is the
     * vehicle in slot s (its index at the start), pos[v] the slot of vehicle v. */
    size_t    n_lanes, lane_n[WF_MAX_LANES];
    uint8_t  *lane;          /* per slot */
    uint32_t *id, *pos;
    int64_t  *lc_ready_step; /* per slot: the first step at which the vehicle may change lanes again */
    uint32_t *lane_changes, *cut_ins; /* per slot: changes made; vehicles that entered the lane right ahead of it */
    /* per slot: whole laps the vehicle's x_m was moved by to fit a new lane's order; x_m + lap_m is its position
     * continuous in time (what /trajectories/x and /vehicles/final_x report) */
    double   *lap_m;
    /* The vehicles whose state this process holds: all of them, or its share of a ring split across processes
     * (wf_fleet_create_part), where only class_id and group_id are written for every vehicle. */
    size_t    share_lo, share_hi;
} WfFleet;

enum { WF_MODE_MOVING = 1, WF_MODE_BRAKING = 2, WF_MODE_FAULT = 4 };

/* Allocate and initialise a fleet: class and group placement, parameter draws, initial positions and
 * speeds. Fails (WF_EINPUT) when the vehicles do not fit at their standstill gaps, when a drawn parameter set
 * is rejected by its model, or when a perturbation makes vehicles overlap. Ownership: sc is borrowed (the fleet
 * keeps no pointer to it); *out is the caller's until wf_fleet_destroy(); NULL on failure. */
int wf_fleet_create(const WfScenario *sc, WfFleet **out, WfError *err);
/* The same fleet for a ring split across processes (part non-NULL; NULL: wf_fleet_create): this process builds its
 * share (wf_partition_blocks) and what it reads of the vehicles ahead of it (their parameters, its last vehicle's
 * leader). Every array stays indexed by vehicle, but only class_id and group_id are written for every vehicle: the
 * pages of the other arrays outside the share are never taken. The sums along the ring run in ring order across the
 * processes: every value of the share, and every error, is one process's. Collective. Ownership as wf_fleet_create;
 * part is borrowed for the call. */
int wf_fleet_create_part(const WfScenario *sc, const WfPartition *part, WfFleet **out, WfError *err);
/* Open the statistics window now: positions become the reference of distances and passages. */
void wf_fleet_open_window(WfFleet *f);
void wf_fleet_destroy(WfFleet **f);

/* One vehicle's driver-model parameters, drawn as wf_fleet_create() draws them: the group's values times
 * (1 + spread z), z counter-based from (seed, vehicle), redrawn when out of range or rejected by the model.
 * out holds the model's parameter struct (param_size bytes). Used by the corridor, which draws at entry with the
 * vehicle's serial number. Fails (WF_EINPUT) when 1000 draws are all rejected. */
int wf_fleet_draw_params(const WfScenario *sc, size_t group, uint64_t vehicle, double *out, WfError *err);

/* Vehicle i's parameters (wf_fleet_params), also outside this process's share: drawn into buf (the model's
 * param_size bytes) as the build draws them. NULL with err set when the draws fail. */
const void *wf_fleet_params_of(const WfFleet *f, const WfScenario *sc, size_t i, double *buf, WfError *err);

/* Vehicle i's index within its group (0 when no group keeps per-vehicle parameters or state). */
static inline size_t wf_fleet_slot(const WfFleet *f, size_t i) { return f->slot ? f->slot[i] : 0; }

/* Pointer to vehicle i's parameters within its group. */
static inline const void *wf_fleet_params(const WfFleet *f, const WfScenario *sc, size_t i)
{
    (void)sc;
    size_t g = f->group_id[i];
    return f->group_params[g] + wf_fleet_slot(f, i) * f->group_param_stride[g];
}

/* The first slot of lane l. */
static inline size_t wf_fleet_lane_first(const WfFleet *f, size_t l)
{
    size_t s = 0;
    for (size_t k = 0; k < l; k++) s += f->lane_n[k];
    return s;
}

/* Vehicle i's length (m): its class's. */
static inline double wf_fleet_length(const WfFleet *f, size_t i) { return f->class_length_m[f->class_id[i]]; }

/* floor(q) as an integer without the libm call (floor is not inlined on baseline x86-64): truncate, then step
 * down for negative non-integers. |q| stays far below 2^63 (positions / ring length). */
static inline int64_t wf_lap_index(double q)
{
    int64_t k = (int64_t)q;
    return k - (q < (double)k);
}

/* Distance vehicle i travelled in the statistics window (m), and its passages of x = 0 (mod L). */
static inline double wf_fleet_distance(const WfFleet *f, size_t i)
{
    return f->window_open ? f->x_m[i] - f->x_start_m[i] : 0.0;
}
static inline int64_t wf_fleet_laps(const WfFleet *f, double L, size_t i)
{
    return f->window_open ? wf_lap_index(f->x_m[i] / L) - wf_lap_index(f->x_start_m[i] / L) : 0;
}

#endif
