/* The fleet: vehicle state and per-vehicle accumulators as structure of arrays in ring order (the leader of
 * vehicle i is i + 1, and of the last one vehicle 0, one lap ahead), the driver groups' drawn parameters and
 * member lists, and the classes' member lists. Built once from a scenario; nothing is allocated afterwards. */
#ifndef WAVEFUEL_FLEET_H
#define WAVEFUEL_FLEET_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/err.h"
#include "wavefuel/scenario.h"

typedef struct WfFleet {
    size_t n;
    /* state: front-bumper position (unwrapped, m), speed (m/s), acceleration applied in the last step */
    double *x_m, *v_mps, *a_mps2;
    /* per-step values at the step's start: bumper-to-bumper gap, leader speed, grade, fuel rate, flag */
    double  *gap_m, *v_lead_mps, *theta_rad, *fuel_rate_gps;
    uint8_t *flag;
    uint32_t *grade_seg; /* per-vehicle cache for wf_road_grade */
    /* attributes */
    double   *length_m;
    uint16_t *class_id, *group_id;
    uint32_t *slot;      /* index of the vehicle within its group (parameters, state) */
    /* groups: members in ring order, drawn parameters (param_size bytes each), controller state */
    size_t    n_groups;
    uint32_t *group_member[WF_MAX_GROUPS];
    size_t    group_n[WF_MAX_GROUPS];
    unsigned char *group_params[WF_MAX_GROUPS];
    unsigned char *group_state[WF_MAX_GROUPS];
    /* classes: members in ring order */
    size_t    n_classes;
    uint32_t *class_member[WF_MAX_CLASSES];
    size_t    class_n[WF_MAX_CLASSES];
    /* accumulators over the statistics window (after warm-up) */
    double   *dist_m, *fuel_g, *time_stopped_s, *sum_v, *sum_v2, *sum_a, *sum_a2;
    uint32_t *stops, *hard_brakes, *infeasible_steps;
    int64_t  *laps;      /* passages of the reference point x = 0 (mod L) */
    uint8_t  *mode;      /* bit 0: moving (above v_go since the last stop); bit 1: braking hard; bit 2: fault */
    /* initial equilibrium (for the record) */
    double    v_init_mps;
} WfFleet;

enum { WF_MODE_MOVING = 1, WF_MODE_BRAKING = 2, WF_MODE_FAULT = 4 };

/* Allocate and initialise a fleet: class and group placement, parameter draws, initial positions and
 * speeds. Fails (WF_EINPUT) when the vehicles do not fit at their standstill gaps, when a drawn parameter set
 * is rejected by its model, or when a perturbation makes vehicles overlap. */
int wf_fleet_create(const WfScenario *sc, WfFleet **out, WfError *err);
void wf_fleet_destroy(WfFleet **f);

/* One vehicle's driver-model parameters, drawn as wf_fleet_create() draws them: the group's values times
 * (1 + spread z), z counter-based from (seed, vehicle), redrawn when out of range or rejected by the model.
 * out holds the model's parameter struct (param_size bytes). Used by the corridor, which draws at entry with the
 * vehicle's serial number. Fails (WF_EINPUT) when 1000 draws are all rejected. */
int wf_fleet_draw_params(const WfScenario *sc, size_t group, uint64_t vehicle, double *out, WfError *err);

/* Pointer to vehicle i's parameters / state within its group. */
static inline const void *wf_fleet_params(const WfFleet *f, const WfScenario *sc, size_t i)
{
    size_t g = f->group_id[i];
    return f->group_params[g] + (size_t)f->slot[i] * sc->groups[g].model->param_size;
}

#endif
