/* Drive cycles: one vehicle follows a speed trace (CSV `time_s,speed_mps`, any sample rate, uneven steps
 * allowed). A scheme (the table wf_cycle_schemes(), docs/cycles.md) turns the trace into quadrature samples
 * (time, speed, acceleration, weight); fuel is sum_i f(v[i], a[i], theta) w_i and distance sum_i v[i] w_i, the
 * weights covering exactly the cycle's duration t[n-1] - t[0]. The `first-order` scheme is the trace's own samples
 * with the forward difference a[i] = (v[i+1] - v[i]) / dt_i and w_i = dt_i (0 at the last sample). */
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

/* Quadrature samples of a cycle: where the model is evaluated and with what weight. */
typedef struct WfCycleScheme WfCycleScheme;
typedef struct WfCycleSamples {
    const WfCycleScheme *scheme; /* borrowed: the table entry that made them */
    size_t  n;                   /* samples, >= 2 */
    /* Owned, one allocation (wf_cycle_samples_free): */
    double *t_s;                 /* increasing, from t[0] to t[n-1] of the cycle, s */
    double *v_mps;               /* >= 0, m/s */
    double *a_mps2;              /* m/s^2 */
    double *w_s;                 /* quadrature weights >= 0, summing to the duration, s */
} WfCycleSamples;

/* A scheme: one row of the table. `sample` fills *s (owned by it until wf_cycle_samples_free; nothing to free on
 * failure) from the cycle at rate_hz (the row's rate; 0 for the trace's own samples). Errors: out of memory. */
struct WfCycleScheme {
    const char *name;        /* as on the command line: "release" */
    const char *summary;     /* one line: the samples, the acceleration, the sum */
    double      rate_hz;     /* resampling rate, 1/s; 0: the trace's own samples */
    int (*sample)(const WfCycle *c, double rate_hz, WfCycleSamples *s, WfError *err);
};

/* The schemes (first the default). The table is static; n gets its length. */
const WfCycleScheme *wf_cycle_schemes(size_t *n);
/* A scheme by name; unknown names are WF_EINPUT listing the known ones. */
const WfCycleScheme *wf_cycle_scheme_find(const char *name, WfError *err);
/* scheme->sample(c, scheme->rate_hz, s, err) with s->scheme set. */
int wf_cycle_samples(const WfCycle *c, const WfCycleScheme *scheme, WfCycleSamples *s, WfError *err);
void wf_cycle_samples_free(WfCycleSamples *s);

/* One run of a class over a cycle at a constant grade. */
typedef struct WfCycleRun {
    const WfCycleSamples *samples; /* borrowed: what the model was evaluated on */
    double   theta_rad;
    int      project;        /* the value used (the caller resolves the model's default) */
    size_t   n;              /* samples (samples->n) */
    double  *fuel_gps;       /* owned; fuel rate at each sample, g/s */
    uint8_t *flag;           /* owned; WF_FEASIBLE, WF_INFEASIBLE_ACCEL... at each sample */
    double   fuel_g;         /* sum fuel_gps[i] w_i, g */
    double   distance_m;     /* sum v[i] w_i, m */
    double   duration_s;
    double   infeasible_s;   /* sum of w_i over flagged samples, s */
    size_t   n_infeasible;   /* flagged samples */
    size_t   n_outside;      /* evaluations clamped to a table's edge (0 for explicit models) */
    double   l_per_100km, mpg;
} WfCycleRun;

/* Evaluate the class's model at the samples s of cycle c (s must outlive *r). Deterministic (sums in sample
 * order). *r is owned by the caller: wf_cycle_run_free. Errors: out of memory. */
int wf_cycle_run(const WfCycle *c, const WfCycleSamples *s, const WfVehicleClass *vc, double theta_rad, int project,
                 WfCycleRun *r, WfError *err);
void wf_cycle_run_free(WfCycleRun *r);

/* The paper's validation protocol for a duty: the cycles (names resolved in DATA_DIR/cycles) and the grades
 * (-0.03 ... 0.03 rad for light duty, -0.02 ... 0.02 for heavy duty, 0.01 steps, computed as k / 100).
 * HHDDT high speed is part of the paper's heavy-duty set but no public 1 Hz file exists: it is not listed. */
const char *const *wf_protocol_cycles(WfDuty duty, size_t *n);
size_t wf_protocol_grades(WfDuty duty, double *theta_rad, size_t cap);

/* HDF5 output of cycle runs (src/io/cycle_out.c): PATH.partial renamed on commit, refuses to overwrite an
 * existing file unless force. Each run goes to the group /CLASS/CYCLE/theta_<+0.0000>/MODEL with the totals as
 * scalars and (single runs) the series at the scheme's samples (t, v, a, weight, fuel, power, flag); see
 * docs/cycles.md. */
typedef struct WfCycleOut WfCycleOut;
/* *out is the caller's (NULL on failure) until wf_cycle_out_commit() or wf_cycle_out_abandon(), which free it and
 * set *out to NULL; command_line is copied into the file. */
int wf_cycle_out_create(const char *path, int force, const char *command_line, WfCycleOut **out, WfError *err);
/* One run: attributes and totals, and with `series` the arrays at its samples (r->samples); the protocol leaves
 * them out (at 100 Hz they would make the file close to 1 GB). */
int wf_cycle_out_run(WfCycleOut *o, const WfVehicleClass *vc, const WfCycle *c, const WfCycleRun *r, int series,
                     WfError *err);
/* Protocol summary of one class at /CLASS/summary: cycle names (+ "ALL"), their durations, grades, model names,
 * fuel_g per model as [n_cycles + 1, n_grades] (last row: the sum over cycles), laid out [model][cycle (ALL
 * last)][grade]; when rel_diff is not NULL, rel_diff of the same shape (last row: the duration-weighted mean of the
 * cycles' rows) and rel_total [n_grades] (total over total). */
int wf_cycle_out_summary(WfCycleOut *o, const char *class_name, size_t n_cycles, const char *const *cycles,
                         const double *durations_s, size_t n_grades, const double *grades_rad, size_t n_models,
                         const char *const *models, const double *fuel_g, const double *rel_diff,
                         const double *rel_total, WfError *err);
int wf_cycle_out_commit(WfCycleOut **o, WfError *err);
/* Close and delete the partial file (nothing is left half-written). */
void wf_cycle_out_abandon(WfCycleOut **o);

#endif
