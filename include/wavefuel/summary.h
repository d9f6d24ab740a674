/* The summary of a run: every aggregate over the statistics window (definitions: docs/metrics.md), for rings and
 * corridors alike, and the one table of its fields. Each field is declared once, in wf_summary_fields /
 * wf_summary_class_fields (src/observe/summary.c), with its name, units and meaning on each boundary; the HDF5
 * writers (/summary), `wavefuel info`, the summary `wavefuel run` prints and the sweep table (/metrics,
 * /class_metrics) all read it, so a new field is one struct member and one table line. */
#ifndef WAVEFUEL_SUMMARY_H
#define WAVEFUEL_SUMMARY_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "wavefuel/scenario.h"

/* Vehicle counts of an open road (corridor), as they stand at the end of the run (zero on a ring). */
typedef struct WfCorridorCounts {
    int64_t arrived;      /* vehicles that reached the entrance (the demand) */
    int64_t entered;      /* inserted at x = 0 */
    int64_t exited;       /* left at x = L */
    int64_t queued;       /* waiting at the entrance: arrived - entered */
    int64_t delayed;      /* entries that waited at least one step */
    int64_t max_queue;    /* longest queue seen */
    double  queue_delay_s;/* total waiting time of the entered vehicles */
    int64_t overlaps;     /* overlap repairs (docs/metrics.md) */
    int64_t off_ramp;     /* left by the off-ramp (corridor.off_ramp) */
    int64_t missed_exits; /* bound for the off-ramp, passed it in another lane (and drove on to x = L) */
} WfCorridorCounts;

/* Per class. Fields a boundary does not measure stay 0. */
typedef struct WfClassSummary {
    long    count;                       /* ring: vehicles of the class */
    int64_t entered, trips;              /* corridor: vehicles that entered, completed trips */
    double  fuel_g, dist_m, l_per_100km, mpg, infeasible_share, stops_per_vkm;
    /* corridor: fuel per vehicle-km on cells climbing (mean grade > 1e-4 rad), descending (< -1e-4) and flat,
     * g/km (NaN when the class drove no distance there); means over the class's completed trips */
    double  g_per_km_up, g_per_km_down, g_per_km_flat;
    double  trip_fuel_mean_g, trip_time_mean_s;
} WfClassSummary;

/* Per driver group: its safety filter's counts over the whole run (docs/controllers.md#safety-filters); 0 for a
 * group without one. */
typedef struct WfGroupSummary {
    int64_t safety_steps;         /* vehicle-steps of the group's vehicles */
    int64_t safety_interventions; /* of those, the steps whose acceleration the filter changed */
    double  safety_share;         /* interventions / steps (0 when no step) */
} WfGroupSummary;

typedef struct WfSummary {
    double window_s;                  /* length of the statistics window */
    double fuel_g, dist_m, vkt_km;
    double vht_h;                     /* corridor: vehicle-hours on the road in the window */
    double l_per_100km, mpg;          /* fleet: volume summed over classes with their own densities */
    double stops_per_vkm, hard_brakes_per_vkm;
    double mean_speed_mps;            /* total distance / vehicle-time in the window */
    double sd_speed_time_avg_mps;     /* mean over records in the window of the spatial speed s.d. */
    double throughput_vph;            /* ring: passages of x = 0 per hour */
    double inflow_vph, outflow_vph;   /* corridor: entries and exits per hour in the window */
    double infeasible_share;          /* steps with an infeasible acceleration request / vehicle-steps */
    double time_stopped_share;
    int64_t overlaps;                 /* ring: overlap repairs (a corridor's are in counts) */
    int64_t trips;                    /* corridor: completed trips (whole run) */
    double mean_travel_time_s, mean_trip_fuel_g, mean_queue_delay_s; /* corridor */
    WfCorridorCounts counts;          /* corridor, at the end of the run */
    int64_t on_road;                  /* corridor: vehicles on the road at the end (entered - exited) */
    WfClassSummary cls[WF_MAX_CLASSES];
    /* Written only when some group has a safety filter (WF_SUMMARY_IF_SAFETY): */
    int64_t safety_interventions;     /* sum over the groups */
    int64_t collisions_repaired;      /* 1: the run repaired overlaps (its results include collisions), else 0 */
    WfGroupSummary grp[WF_MAX_GROUPS];
    /* Written only for a ring of several lanes (WF_SUMMARY_IF_LANES), whole run: */
    int64_t lane_changes, cut_ins;
} WfSummary;

/* Which road a summary describes: the index of a field's description. */
typedef enum { WF_SUMMARY_RING = 0, WF_SUMMARY_CORRIDOR = 1, WF_SUMMARY_N_BOUNDARIES = 2 } WfSummaryBoundary;

typedef enum { WF_SUMMARY_F64, WF_SUMMARY_I64, WF_SUMMARY_LONG } WfSummaryType;

/* How `wavefuel run` prints a field: a column of the class table (and of its fleet row) or an item of the line
 * below it. */
typedef struct WfSummaryPrint {
    const char *label;  /* column header or line label; NULL: not printed on this boundary */
    const char *format; /* printf conversion of the value after scaling, e.g. "%12.2f" */
    const char *suffix; /* after the value on the line: its printed unit ("veh/h"); "" for none */
} WfSummaryPrint;

typedef struct WfSummaryField {
    const char   *name;   /* dataset in /summary, column of the sweep table */
    const char   *units;  /* the dataset's units attribute */
    const char   *desc[WF_SUMMARY_N_BOUNDARIES]; /* meaning on each boundary; NULL: not part of its summary */
    WfSummaryType type;
    size_t        offset; /* of the value in WfSummary (fleet fields) or WfClassSummary (class fields) */
    /* The same value for the fleet, for the fleet row of the printed class table: offset in WfSummary, or
     * WF_SUMMARY_SUM (the sum over classes), or WF_SUMMARY_NONE (blank). Fleet fields: unused. */
    size_t        fleet_offset;
    WfSummaryPrint print[WF_SUMMARY_N_BOUNDARIES];
    double        print_mul, print_div; /* printed value = value x mul / div (0: 1); dist_m in km: div 1000 */
    int           sweep_only; /* not in /summary, only a column of the sweep table */
    int           when;       /* WF_SUMMARY_ALWAYS, or WF_SUMMARY_IF_SAFETY (IF_LANES): in /summary, `info`, the
                                 printed summary and Python only for runs with a safety filter (rings of several
                                 lanes); never in the sweep table */
} WfSummaryField;

enum { WF_SUMMARY_ALWAYS = 0, WF_SUMMARY_IF_SAFETY = 1, WF_SUMMARY_IF_LANES = 2, WF_SUMMARY_IF_OFFRAMP = 3 };

#define WF_SUMMARY_SUM  ((size_t)-1)
#define WF_SUMMARY_NONE ((size_t)-2)

extern const WfSummaryField wf_summary_fields[];       /* fleet values: scalars in /summary */
extern const size_t         wf_summary_n_fields;
extern const WfSummaryField wf_summary_class_fields[]; /* per class: arrays over the classes in /summary */
extern const size_t         wf_summary_n_class_fields;
extern const WfSummaryField wf_summary_group_fields[]; /* per driver group (WfGroupSummary): arrays over the groups */
extern const size_t         wf_summary_n_group_fields;

/* Whether a field is a column of the sweep table (its ring meaning; fields of some runs only are not). */
static inline int wf_summary_in_sweep(const WfSummaryField *f)
{
    return f->desc[WF_SUMMARY_RING] && f->when == WF_SUMMARY_ALWAYS;
}
/* Whether a field is part of the summary of a scenario's run (its `when`). */
int wf_summary_field_on(const WfSummaryField *f, const WfScenario *sc);
/* Some driver group of the scenario has a safety filter. */
int wf_scenario_has_safety(const WfScenario *sc);
/* The derived values of the summary's safety fields from its counts: shares, totals, collisions_repaired. */
void wf_summary_safety_totals(WfSummary *s);

/* A field's value as a double (integers converted), from a WfSummary (fleet fields) or a WfClassSummary. */
double wf_summary_value(const void *base, const WfSummaryField *f);

/* The summary table `wavefuel run` prints: the class table with its fleet row, then the line of fleet values.
 * names[k]: class k's name. */
void wf_summary_print(FILE *out, const WfSummary *s, WfSummaryBoundary b, const char *const *names, size_t n_classes,
                      const WfScenario *sc);
/* The lines after it: each safety-filtered group's counts (group fields printed), then, when the run repaired
 * overlaps, a warning that its results include repaired collisions. Prints nothing for a run with neither. */
void wf_summary_print_safety(FILE *out, const WfSummary *s, WfSummaryBoundary b, const WfScenario *sc);
/* That warning, when `repaired` (the summary's overlaps) is positive (`wavefuel run` and `wavefuel info`). */
void wf_summary_warn_repairs(FILE *out, long long repaired);

#endif
