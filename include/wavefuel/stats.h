/* Statistics: the time-resolved record taken at each output instant and the aggregates over the statistics
 * window (after warm-up). Definitions and units: docs/metrics.md. Every sum runs in a fixed order (blocks of
 * WF_STATS_BLOCK vehicles, then the blocks in order), so results do not depend on the thread count. */
#ifndef WAVEFUEL_STATS_H
#define WAVEFUEL_STATS_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/fleet.h"
#include "wavefuel/scenario.h"
#include "wavefuel/summary.h"

/* Vehicles per statistics block: the block kernel's (src/core/block.c), so a record sums the same blocks in the
 * same order whichever pass takes it. */
#define WF_STATS_BLOCK 256

/* Columns of one time-series record, in order (names and units in wf_ts_columns). */
enum {
    WF_TS_T, WF_TS_MEAN_V, WF_TS_SD_V, WF_TS_MIN_V, WF_TS_MAX_V, WF_TS_FRAC_STOPPED, WF_TS_WAVES,
    WF_TS_FUEL_RATE, WF_TS_MEAN_GAP, WF_TS_MIN_GAP, WF_TS_OVERLAPS, WF_TS_N_COLS
};
typedef struct WfColumn { const char *name, *units, *desc; } WfColumn;
extern const WfColumn wf_ts_columns[WF_TS_N_COLS];

/* One record: the WF_TS_* values, plus the fuel rate of each class (g/s). */
typedef struct WfTsRow {
    double v[WF_TS_N_COLS];
    double class_fuel_rate_gps[WF_MAX_CLASSES];
} WfTsRow;

/* Partial sums of a record over one block of consecutive vehicles (ring order). */
typedef struct WfStatsBlock {
    double n, sum_v, sum_gap, stopped, waves, m2, vmin, vmax, gmin; /* m2: about the block's own mean */
    int    first_slow, last_slow; /* the block's first / last vehicle is slower than wave_speed_mps */
    double class_fuel_rate_gps[WF_MAX_CLASSES];
} WfStatsBlock;

/* The partial sums of m vehicles from their speeds, gaps, fuel rates and classes at the step's start. */
void wf_stats_block(size_t m, const double *v, const double *gap, const double *fuel_rate_gps,
                    const uint16_t *class_id, size_t n_classes, const WfScenario *sc, WfStatsBlock *out);
/* A record from the blocks' partial sums, combined in block order (Chan et al.'s pairwise formula for the
 * second moment about the fleet mean: no cancellation when the spread is tiny). */
void wf_stats_combine(const WfStatsBlock *blocks, size_t n_blocks, size_t n_classes, const WfScenario *sc,
                      double t_s, int64_t overlaps, WfTsRow *row);
/* The same over the lanes of a multi-lane ring, lane after lane: lane l's lane_nb[l] blocks follow lane l - 1's
 * (waves are counted around each lane). */
void wf_stats_combine_lanes(const WfStatsBlock *blocks, const size_t *lane_nb, size_t n_lanes, size_t n_classes,
                            const WfScenario *sc, double t_s, int64_t overlaps, WfTsRow *row);

/* The combination in steps, for blocks held in pieces (a ring split across processes): begin; fold each lane's blocks
 * in order, piece after piece, and end the lane; then the second moments about the mean, piece after piece; then the
 * row. wf_stats_combine_lanes is these over one piece. */
typedef struct WfStatsFold {
    double n, sv, sg, stopped, waves, vmin, vmax, gmin, mean, m2;
    double lane_waves, lane_vmax;
    size_t lane_blocks;
    int    lane_first_slow, last_slow;
    double class_fuel_rate_gps[WF_MAX_CLASSES];
} WfStatsFold;
void wf_stats_fold_begin(WfStatsFold *a);
void wf_stats_fold(WfStatsFold *a, const WfStatsBlock *blocks, size_t n_blocks, size_t n_classes);
void wf_stats_fold_lane_end(WfStatsFold *a, const WfScenario *sc);
void wf_stats_fold_m2(WfStatsFold *a, const WfStatsBlock *blocks, size_t n_blocks);
void wf_stats_fold_row(const WfStatsFold *a, size_t n_classes, double t_s, int64_t overlaps, WfTsRow *row);


/* Aggregates over the statistics window: WfSummary (wavefuel/summary.h). */

/* The summary from the accumulators, in two steps, so that a fleet held in pieces (a ring split across processes)
 * can be summed piece after piece: the sums over vehicles [lo, hi), added in ring order (zero them before the first
 * piece, which starts at vehicle 0), then the summary from them. sd_sum / n_sd is the sum / number of the spatial
 * speed s.d. of the records inside the window; window_steps the number of steps in the window. */
typedef struct WfSummarySums {
    double fuel_g[WF_MAX_CLASSES], dist_m[WF_MAX_CLASSES], stops[WF_MAX_CLASSES], infeasible_steps[WF_MAX_CLASSES];
    double hard_brakes, stopped_s, laps;
} WfSummarySums;
void wf_stats_summary_add(const WfFleet *f, const WfScenario *sc, size_t lo, size_t hi, WfSummarySums *sums);
void wf_stats_summary_end(const WfFleet *f, const WfScenario *sc, const WfSummarySums *sums, double sd_sum, long n_sd,
                          long window_steps, int64_t overlaps, WfSummary *s);

#endif
