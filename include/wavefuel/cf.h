/* Car-following models and automated-vehicle controllers: one WfCfModel per file in src/models/cf/, behind this
 * interface. The engine calls accel() for every vehicle at every step (and every right-hand-side evaluation
 * of an adaptive solver), so accel() must be pure in (params, state, gap, v, v_lead); controllers with memory
 * keep it in a per-vehicle state block that update_state() advances once per completed step. */
#ifndef WAVEFUEL_CF_H
#define WAVEFUEL_CF_H

#include <stddef.h>
#include "wavefuel/err.h"
#include "wavefuel/param.h"

typedef struct WfCfModel {
    const char        *name;       /* as written in scenarios: "idm" */
    const char        *doc;        /* one line: model and reference */
    size_t             param_size; /* bytes of the parameter struct (doubles, described by spec) */
    const WfParamSpec *spec;
    size_t             n_spec;
    /* Cross-field checks on one vehicle's parameters; may be NULL. */
    int (*check)(const void *params, WfError *err);
    /* Acceleration in m/s^2 given the bumper-to-bumper gap to the leader (m, >= 0), own speed and leader's
     * speed (m/s, >= 0). Must return a finite value for every gap >= 0 and speed >= 0 (guard divisions).
     * state is NULL when state_size is 0. */
    double (*accel)(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps);
    /* Per-vehicle memory (0 for memoryless models). init_state() sets it at t = 0; update_state() advances it
     * by one completed step of dt_s with the inputs seen during that step, NULL when the step does not (an external
     * model's command, set only from outside: the kernel then skips the per-vehicle visit). Both NULL when
     * state_size is 0. */
    size_t state_size;
    void (*init_state)(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps);
    void (*update_state)(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps,
                         double dt_s);
    /* Optional block form of accel() for memoryless models: a[k] for n vehicles whose parameter structs are at
     * params + k * param_stride (stride 0: one shared struct), with exactly accel()'s arithmetic, so both forms
     * give the same bits (tests/test_cf.c checks it). Lets the compiler vectorise the common case of one
     * parameter set. NULL: the engine calls accel() per vehicle. */
    void (*accel_block)(const void *params, size_t param_stride, size_t n, const double *gap_m,
                        const double *v_mps, const double *v_lead_mps, double *a_mps2);
    /* 1: the vehicle's command is the first double of its state, set from outside once per step
     * (wf_sim_set_actions, engine.h) */
    int external;
} WfCfModel;

/* NULL-terminated registry of every built-in model. */
extern const WfCfModel *const wf_cf_models[];
/* By name; an unknown name is an error listing the known ones. */
int wf_cf_model_find(const char *name, const WfCfModel **out, WfError *err);

/* Equilibrium speed for a uniform flow at bumper-to-bumper gap s: the v in [0, v_hi] with
 * accel(s, v, v) = 0, found by bisection to machine precision. Every shipped model changes sign once in v at
 * fixed gap (IDM and OVM decrease in v; Gipps's check() enforces a single crossing). Returns 0 when even
 * v = 0 decelerates, v_hi when accel stays positive. */
double wf_cf_equilibrium_speed(const WfCfModel *m, const void *params, double gap_m, double v_hi_mps);

extern const WfCfModel wf_cf_idm;
extern const WfCfModel wf_cf_ovm;
extern const WfCfModel wf_cf_gipps;

#endif
