/* Vehicle energy models: fuel rate f(v, a, theta) in g/s, equivalent power in kW and a feasibility flag.
 * Each family (the CIRCLES explicit polynomial first) is one WfEnergyModel: a parameter table and pure
 * kernels over arrays (structure of arrays), safe to call from any thread. */
#ifndef WAVEFUEL_ENERGY_H
#define WAVEFUEL_ENERGY_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/err.h"
#include "wavefuel/param.h"

/* Feasibility flag of one evaluation. */
enum { WF_FEASIBLE = 0, WF_INFEASIBLE_ACCEL = 1, WF_NEGATIVE_SPEED = 2 };

struct WfCfgNode; /* a YAML map (wavefuel/config.h), seen only by the optional load() hook */

typedef struct WfEnergyModel {
    const char        *name;       /* as written in vehicle files: energy_model: circles_polynomial */
    size_t             param_size; /* bytes of the parameter struct */
    const WfParamSpec *spec;
    size_t             n_spec;
    /* Cross-field checks after loading (duty-specific keys...); may be NULL. */
    int (*check)(void *params, WfError *err);
    /* n evaluations. Inputs: v_mps (may be negative), a_mps2, theta_rad (road grade angle).
     * project != 0 clips a to a_max(v, theta) before evaluating fuel. Outputs (each may be NULL
     * except fuel_gps): fuel rate g/s, flag (WF_FEASIBLE...). Pure; no allocation; element-wise: element i's outputs
     * are the same bits whatever the other elements and n (the engine evaluates a block's largest class over the
     * whole block and overwrites the others' results). */
    void (*eval)(const void *params, size_t n, const double *v_mps, const double *a_mps2,
                 const double *theta_rad, int project, double *fuel_gps, uint8_t *flag);
    /* Largest feasible acceleration at speed v and grade theta, m/s^2. */
    double (*a_max)(const void *params, double v_mps, double theta_rad);
    /* Optional members (NULL / 0 for the explicit CIRCLES model). Models whose parameters are data files
     * (the tabulated model) load them here, after the numeric parameters are filled and checked:
     * class_path is the class file (relative paths resolve against its directory), class_map its top-level
     * YAML map (the hook reads and marks its own keys, e.g. `table`). On failure the message names the file. */
    int (*load)(void *params, const char *class_path, struct WfCfgNode *class_map, WfError *err);
    /* Frees what load() allocated; called by wf_vehicle_free() before params is freed. Accepts a params
     * block whose load() failed or never ran. */
    void (*release)(void *params);
    /* How many of these n evaluations fall outside the model's domain and were clamped to its edge (same
     * inputs and project as eval). NULL: the model has no bounded domain (never clamps). Pure. */
    size_t (*n_outside)(const void *params, size_t n, const double *v_mps, const double *a_mps2,
                        const double *theta_rad, int project);
    /* project value callers use when the user did not choose: 1 for the tabulated model (as the release's
     * wrappers), 0 for the explicit one. */
    int project_default;
    /* Optional: n evaluations on a flat road, as eval with theta_rad all +0 and project 0, the same bits for every
     * finite v_mps (the engine's states, which it checks finite every step; a_mps2 any). NULL: callers pass eval an
     * array of zeros. The engine's fused step uses it on roads without grade. */
    void (*eval_flat)(const void *params, size_t n, const double *v_mps, const double *a_mps2, double *fuel_gps,
                      uint8_t *flag);
} WfEnergyModel;

/* The registry: NULL-terminated list of every energy model family. */
extern const WfEnergyModel *const wf_energy_models[];
/* Look a family up by name; unknown names are an error listing the known ones. */
int wf_energy_model_find(const char *name, const WfEnergyModel **out, WfError *err);

/* The CIRCLES v3.1 simplified model (Khoudari et al.), exported so other simulators can link it. */
extern const WfEnergyModel wf_energy_circles;

/* Parameters of the CIRCLES explicit model. Light-duty classes set v_c, beta, a0..a4; heavy-duty classes
 * set h0, h1. Units as in the release: c0 g/s, c1 g/m, c3 g s^2/m^3, p0 g s/m, p1 g s^2/m^2,
 * p2 g s^3/m^3, q0 g s^3/m^2, q1 g s^4/m^3, z0 g/(s rad), z1 g/(m rad), z2 g s/(m^2 rad), b1 m/s^2,
 * b2 m^2/s^2, b3 1/m, b4 b5 m/(s^2 rad), b6 1/(s rad), a0 m/s^2, a1 1/s, a2 m/(s^2 rad), a3 1/m,
 * a4 1/(s rad), h0 g/s, h1 g/m, f_idle and beta g/s, v_c m/s. */
typedef struct WfCirclesParams {
    double f_idle, b1, b2, b3, b4, b5, b6;
    double c0, c1, c2, c3, p0, p1, p2, q0, q1, z0, z1, z2;
    double v_c, beta, a0, a1, a2, a3, a4; /* light duty; NaN when absent */
    double h0, h1;                        /* heavy duty; NaN when absent */
    /* Derived by check(): one branch-free kernel serves both duties. Heavy duty: cut_v = +inf (never
     * cuts), lb_beta = 0. Light duty: lb_h0 = lb_h1 = 0, so the added terms are exact zeros. */
    double cut_v, lb_beta, lb_h0, lb_h1;
} WfCirclesParams;

/* Scalar form of the CIRCLES model (same arithmetic as the array form). Returns fuel g/s; *flag may be
 * NULL. */
double wf_circles_fuel(const WfCirclesParams *p, double v_mps, double a_mps2, double theta_rad, int project,
                       uint8_t *flag);
/* a_max(v, theta) = min(b1, b2/max(v,1e-12) - b3 v^2) - min(b4, b5 + b6 v) theta, m/s^2. */
double wf_circles_a_max(const WfCirclesParams *p, double v_mps, double theta_rad);

#endif
