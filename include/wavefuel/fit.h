/* Model reduction (Khoudari et al., "Reducing Detailed Vehicle Energy Dynamics to Physics-Like Models",
 * section "Simplified Model with Desirable Physics-like Properties"): fit the CIRCLES explicit model
 * (wavefuel/energy.h, WfCirclesParams) to a tabulated model evaluated with the release's semantics
 * (wavefuel/tabulated.h, project on), step by step as docs/fit.md describes; write the result as a vehicle
 * class file; and the reverse, sample an explicit class on the release's grid. Units: v m/s, a m/s^2,
 * theta rad, fuel g/s; each parameter's unit is in WfCirclesParams. */
#ifndef WAVEFUEL_FIT_H
#define WAVEFUEL_FIT_H

#include <stddef.h>
#include <stdint.h>

#include "wavefuel/energy.h"
#include "wavefuel/err.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/vehicle.h"

typedef enum { WF_FIT_DUTY_AUTO = 0, WF_FIT_DUTY_LIGHT = 1, WF_FIT_DUTY_HEAVY = 2 } WfFitDuty;

/* How P(v) and Q(v) are fitted. WF_FIT_PQ_PAPER (the default): the paper's steps 3 and 4, P on a in [-0.3, 0.3]
 * (heavy duty [0, 0.3]) without Q, then Q with P fixed; on a one-sided range P absorbs part of Q (the shipped
 * class 8 comes back as p0 0.160 for 0.205). WF_FIT_PQ_JOINT: p0..p2, q0, q1 in one NNLS of P a + Q a^2 to
 * f(v, a, 0) - C(v) on a in [0, 3], where a+ = a and the model is linear in all five: recovers the shipped
 * classes, heavy duty included, to the polynomial tolerance (docs/fit.md). */
typedef enum { WF_FIT_PQ_PAPER = 0, WF_FIT_PQ_JOINT = 1 } WfFitPQ;

/* Choices of a fit; zero-initialised = the paper's pipeline with the duty detected. */
typedef struct WfFitOptions {
    WfFitDuty duty;
    WfFitPQ   pq;
} WfFitOptions;

/* The fit's fixed ranges (the paper's): speeds [0, 35] m/s for every polynomial step, the fuel-cut speed
 * searched over [0, WF_FIT_V_MAX]; heavy duty is detected when that search reaches the top. */
#define WF_FIT_V_MAX 35.0

/* One step of the pipeline, as printed by `wavefuel fit` and written to the class file. */
enum {
    WF_FIT_STEP_CUT_SPEED = 0, /* 1a. v_c (bisection) and beta (light duty); heavy: the detection */
    WF_FIT_STEP_CUT_ACCEL,     /* 1b. a0..a4: least squares on the zero-fuel accelerations (light duty) */
    WF_FIT_STEP_C,             /* 2.  c0..c3 >= 0 */
    WF_FIT_STEP_P,             /* 3.  p0..p2 >= 0 (WF_FIT_PQ_JOINT: p0..p2, q0, q1 together, key "PQ") */
    WF_FIT_STEP_Q,             /* 4.  q0, q1 >= 0 (not done with WF_FIT_PQ_JOINT) */
    WF_FIT_STEP_Z,             /* 5.  z0..z2 >= 0 */
    WF_FIT_STEP_AMAX_FLAT,     /* 6a. b1..b3 (nonlinear) */
    WF_FIT_STEP_AMAX_GRADE,    /* 6b. b4..b6 (nonlinear) */
    WF_FIT_STEP_IDLE,          /* 7.  f_idle */
    WF_FIT_STEP_LOWER_BOUND,   /* heavy duty: h0, h1 >= 0 */
    WF_FIT_N_STEPS
};

typedef struct WfFitStep {
    const char *key;      /* class-file key: "fuel_cut_accel", "C", ... */
    const char *params;   /* "a0 a1 a2 a3 a4" */
    const char *target;   /* what was fitted to what, one line */
    const char *unit;     /* unit of the residual */
    int         done;     /* 0: the step does not apply to this duty */
    size_t      n_points; /* grid points of the step */
    size_t      n_used;   /* points that passed its filter (feasible, not fuel-cut, ...) */
    double      rms;      /* RMS residual over the used points (model - target), NaN when not defined */
    double      max_abs;  /* largest |residual| */
} WfFitStep;

typedef struct WfFitResult {
    WfCirclesParams params;     /* every fitted parameter, checked (derived fields filled): ready for
                                 * wf_circles_fuel(). Light duty: v_c, beta, a0..a4 set, h0/h1 NaN;
                                 * heavy duty the reverse. */
    WfDuty          duty;
    WfFitPQ         pq;            /* how P and Q were fitted */
    int             duty_detected; /* 1: chosen by the v_c search (auto), 0: forced by the caller */
    WfFitStep       step[WF_FIT_N_STEPS];
    double          fuel_rms_gps;  /* fitted model (no projection) - table, over the points of steps 2-5 */
    double          fuel_max_gps;  /* largest |difference| over those points */
    size_t          fuel_n;        /* how many points */
    char            table_source[1024]; /* the table's source (CSV as imported, or what sampled it) */
    uint64_t        table_checksum;     /* the table's data checksum (wf_table_checksum) */
} WfFitResult;

/* Run the whole pipeline on a table with the options *opt (NULL: the paper's steps, duty detected). The table
 * is read only; its grid (any spacing) must span v [0, 35] m/s, a [-3, 3] m/s^2 and theta [-0.03, 0.03] rad,
 * the ranges the steps read (the release's does). Fails (WF_EINPUT) when it does not, when a step has too few
 * usable points or points that do not determine its coefficients (the message names the step), or when light
 * duty is forced on a table with no fuel cut below WF_FIT_V_MAX; WF_ESYS when a nonlinear fit does not converge
 * or memory runs out. *out is filled on success only. Single-threaded; deterministic. */
int wf_fit_table(const WfTable *t, const WfFitOptions *opt, WfFitResult *out, WfError *err);

/* The metadata a class file needs that a table does not hold. */
typedef struct WfFitClassInfo {
    const char *label;       /* `name:` (human name) */
    WfFuelType  fuel;
    double      mass_kg;     /* 100..100000 */
    double      length_m;    /* 1..30 */
    double      kw_per_gps;  /* 1..100 */
    double      fuel_density_g_per_l; /* NaN: the fuel's default (not written) */
    const char *table_path;  /* the table file, recorded as provenance (may be NULL) */
    const char *command;     /* the command line, recorded as provenance (may be NULL) */
} WfFitClassInfo;

/* Write a vehicle class file (vehicles/NAME.yaml format, energy_model: circles_polynomial) with every
 * fitted parameter and its unit, the residuals of each step and the table it came from (under `source:`,
 * which the loader keeps as documentation). Parameters are written with 17 significant digits, so the
 * loaded class evaluates exactly as r->params. Written as PATH.partial and renamed; an existing PATH is
 * never replaced unless force (WF_EINPUT "exists"). */
int wf_fit_write_class(const WfFitResult *r, const WfFitClassInfo *info, const char *path, int force,
                       WfError *err);

/* A grid: n nodes per axis, ascending. */
typedef struct WfFitGrid {
    size_t nv, na, nt;
    double v_mps[256], a_mps2[256], theta_rad[64];
} WfFitGrid;

/* The grid of the CIRCLES release's tables (CIRCLES-consortium/CIRCLES-ENERGY-MODELS @ 8dd3c42): speed 0 to
 * 35 m/s by 0.35 (101 values), acceleration -4 to 4 m/s^2 by 0.08 (101), grade -0.03 to 0.03 rad by 0.003
 * (21): 214 221 nodes. Each node is the double nearest its decimal value (k * 35 / 100 and so on), as a
 * CSV reader of the release's files gets it. */
void wf_fit_release_grid(WfFitGrid *g);

/* Sample a class's model on a grid as the release's tables are made: at each node the fuel rate with
 * projection (an infeasible node holds the value at the largest feasible acceleration, the saturated value
 * the release's tables show) and Infeasible = (flag == 1). `source` labels the table. *out is owned by the
 * caller (wf_table_destroy). */
int wf_fit_sample_class(const WfVehicleClass *vc, const WfFitGrid *g, const char *source, WfTable **out,
                        WfError *err);

/* Write a table as CSV in the release's format: header `Velocity,Acceleration,Road Grade,Fuel Rate,
 * Infeasible`, grade fastest, then acceleration from the highest down, then speed upward; coordinates and
 * fuel with 15 significant digits (%.15g: the shortest form for the release's grid). Written as
 * PATH.partial and renamed; an existing PATH is never replaced unless force. */
int wf_fit_write_table_csv(const WfTable *t, const char *path, int force, WfError *err);

#endif
