/* Drive cycles: one vehicle follows a speed trace (CSV `time_s,speed_mps`, any sample rate, uneven steps
 * allowed). Acceleration is the forward difference a[i] = (v[i+1] - v[i]) / dt_i (0 at the last sample),
 * fuel is sum_i f(v[i], a[i], theta) dt_i and distance sum_i v[i] dt_i, with dt_i = t[i+1] - t[i] and
 * dt = 0 at the last sample, so both sums cover exactly the cycle's duration t[n-1] - t[0]. */
#ifndef WAVEFUEL_CYCLE_H
#define WAVEFUEL_CYCLE_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/err.h"
#include "wavefuel/vehicle.h"

typedef struct WfCycle {
    char    name[64];    /* file stem: "udds" */
    char    path[1024];  /* file it was read from ("" for cycles built from arrays) */
    size_t  n;           /* samples, >= 2 */
    double *t_s;         /* owned; strictly increasing, s */
    double *v_mps;       /* owned; >= 0, m/s */
    double *dt_s;        /* owned; t[i+1] - t[i], 0 at the last sample, s */
    double *a_mps2;      /* owned; forward difference, 0 at the last sample, m/s^2 */
} WfCycle;

/* Read a speed trace. Header optional (if present: `time_s,speed_mps`); at least 2 samples; time strictly
 * increasing; speeds finite and >= 0. Errors name file, line and field. Ownership: the arrays of *c are owned by
 * *c (the struct is the caller's) until wf_cycle_free(); on failure nothing is left to free. */
int wf_cycle_load(const char *path, WfCycle *c, WfError *err);
/* Same checks on arrays (copied: the caller keeps t_s and v_mps); `name` labels the cycle. *c as for
 * wf_cycle_load. */
int wf_cycle_from_arrays(const char *name, size_t n, const double *t_s, const double *v_mps, WfCycle *c,
                         WfError *err);
void wf_cycle_free(WfCycle *c);
/* t[n-1] - t[0], s. */
double wf_cycle_duration_s(const WfCycle *c);
/* sum_i v[i] dt_i, m (left Riemann sum; equals the trapezoid rule when the first and last speeds are 0 and
 * the steps are even, as in the regulatory cycles). */
double wf_cycle_distance_m(const WfCycle *c);

/* The data directory holding cycles/NAME.csv: `dir` when given (not NULL or ""), else `default_dir` (may be NULL)
 * when it exists. `wavefuel cycle` gives --cycles, else $WAVEFUEL_DATA, with dir_from naming which ("--cycles",
 * "$WAVEFUEL_DATA") for the error message, and the default PREFIX/../shared/data for PREFIX/bin/wavefuel (shared/
 * next to the repository). *found = 0 (and out = "") when none is given and the default does not exist. Errors:
 * a given directory that does not exist (WF_EINPUT). The library reads no environment variable here. */
int wf_cycle_data_dir(const char *dir, const char *dir_from, const char *default_dir, char *out, size_t len,
                      int *found, WfError *err);
/* A CYCLE argument: a path (contains '/' or ends in .csv) is used as is; a name ("udds") is
 * DATA_DIR/cycles/NAME.csv. Unknown names list the cycles present. data_dir may be "" (none found). */
int wf_cycle_resolve(const char *name_or_path, const char *data_dir, char *out, size_t len, WfError *err);

/* One run of a class over a cycle at a constant grade. */
typedef struct WfCycleRun {
    double   theta_rad;
    int      project;        /* the value used (the caller resolves the model's default) */
    size_t   n;              /* samples */
    double  *fuel_gps;       /* owned; fuel rate at each sample, g/s */
    uint8_t *flag;           /* owned; WF_FEASIBLE, WF_INFEASIBLE_ACCEL... at each sample */
    double   fuel_g;         /* sum fuel_gps[i] dt_i, g */
    double   distance_m;     /* sum v[i] dt_i, m */
    double   duration_s;
    double   infeasible_s;   /* sum of dt_i over flagged samples, s */
    size_t   n_infeasible;   /* flagged samples */
    size_t   n_outside;      /* evaluations clamped to a table's edge (0 for explicit models) */
    double   l_per_100km, mpg;
} WfCycleRun;

/* Evaluate the class's model along the cycle. Deterministic (sums in sample order). *r is owned by the
 * caller: wf_cycle_run_free. Errors: out of memory. */
int wf_cycle_run(const WfCycle *c, const WfVehicleClass *vc, double theta_rad, int project, WfCycleRun *r,
                 WfError *err);
void wf_cycle_run_free(WfCycleRun *r);

/* The paper's validation protocol for a duty: the cycles (names resolved in DATA_DIR/cycles) and the grades
 * (-0.03 ... 0.03 rad for light duty, -0.02 ... 0.02 for heavy duty, 0.01 steps, computed as k / 100).
 * HHDDT high speed is part of the paper's heavy-duty set but no public 1 Hz file exists: it is not listed. */
const char *const *wf_protocol_cycles(WfDuty duty, size_t *n);
size_t wf_protocol_grades(WfDuty duty, double *theta_rad, size_t cap);

/* HDF5 output of cycle runs (src/io/cycle_out.c): PATH.partial renamed on commit, refuses to overwrite an
 * existing file unless force. Each run goes to the group /CLASS/CYCLE/theta_<+0.0000>/MODEL with the time
 * series (t, v, a, fuel, power, flag) and the totals as scalars; see docs/cycles.md. */
typedef struct WfCycleOut WfCycleOut;
/* *out is the caller's (NULL on failure) until wf_cycle_out_commit() or wf_cycle_out_abandon(), which free it and
 * set *out to NULL; command_line is copied into the file. */
int wf_cycle_out_create(const char *path, int force, const char *command_line, WfCycleOut **out, WfError *err);
int wf_cycle_out_run(WfCycleOut *o, const WfVehicleClass *vc, const WfCycle *c, const WfCycleRun *r, WfError *err);
/* Protocol summary of one class at /CLASS/summary: cycle names (+ "ALL"), grades, model names, fuel_g per
 * model as [n_cycles + 1, n_grades] (last row: all cycles combined), and rel_diff (same shape) when not NULL.
 * fuel_g is laid out [model][cycle (ALL last)][grade]. */
int wf_cycle_out_summary(WfCycleOut *o, const char *class_name, size_t n_cycles, const char *const *cycles,
                         size_t n_grades, const double *grades_rad, size_t n_models, const char *const *models,
                         const double *fuel_g, const double *rel_diff, WfError *err);
int wf_cycle_out_commit(WfCycleOut **o, WfError *err);
/* Close and delete the partial file (nothing is left half-written). */
void wf_cycle_out_abandon(WfCycleOut **o);

#endif
