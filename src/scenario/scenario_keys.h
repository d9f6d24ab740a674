/* Private to src/scenario: the key tables and hooks that the ring loader (scenario.c) and the corridor loader
 * (scenario_corridor.c) share. The road table lists the corridor's road keys (read later, by the corridor
 * loader, once the driver groups are known); the docs read every table through wf_key_tables (keys.h). */
#ifndef WAVEFUEL_SCENARIO_KEYS_H
#define WAVEFUEL_SCENARIO_KEYS_H

#include "wavefuel/config.h"
#include "wavefuel/keys.h"
#include "wavefuel/scenario.h"

/* Appends a copy of `path` to sc->inputs (the files the scenario was read from). WF_ESYS when out of memory. */
int wf_scenario_add_input(WfScenario *sc, const char *path, WfError *err);

/* "file:line: path" of a node, into buf. */
const char *wf_scenario_where(const WfCfgNode *n, char *buf, size_t len);

/* Two columns of numbers (wf_scenario_pairs): their names (a CSV's header), units and ranges. */
typedef struct WfPairCols {
    const char *name[2], *unit[2];
    double      min[2], max[2];
    int         csv_ranges; /* a CSV's values checked too (0: the caller checks them, as a ring's road does) */
    const char *csv_doc;    /* 'csv' in the message when neither or both are given; NULL: "a file with header A,B" */
} WfPairCols;

/* The two columns of `points: [[a, b], ...]` or `csv: FILE` (relative to the scenario file, added to its inputs)
 * of `map`, exactly one of them: points each in the ranges of c, a CSV's rows too with c->csv_ranges. *a and *b are
 * malloc'd (n + 1 values; the caller frees them), NULL on failure. `where` receives the location of what was read
 * for later messages: the points' file:line: path, or the CSV's path. */
int wf_scenario_pairs(WfScenario *sc, WfCfgNode *map, const WfPairCols *c, double **a, double **b, size_t *n,
                      char *where, size_t wlen, WfError *err);

/* road.grade / road.elevation / road.zones of a corridor (WF_KEY_LATER rows of the road table). */
int wf_corridor_road_grade(WfCfgNode *road, const WfKeySpec *row, void *sc, WfKeyEnv *env, WfError *err);
int wf_corridor_road_elevation(WfCfgNode *road, const WfKeySpec *row, void *sc, WfKeyEnv *env, WfError *err);
int wf_corridor_road_zones(WfCfgNode *road, const WfKeySpec *row, void *sc, WfKeyEnv *env, WfError *err);
extern const WfKeyTable wf_corridor_grade_keys, wf_corridor_elevation_keys, wf_corridor_zone_keys;
/* The `corridor` section (top-level row of corridors). */
extern const WfKeyTable wf_corridor_keys;
/* The road table, whose LATER rows the corridor loader reads. */
extern const WfKeyTable wf_road_keys;
/* The fleet section (scenario_fleet.c), the tables of its entries (classes, driver groups) and its check. */
extern const WfKeyTable wf_fleet_keys, wf_class_keys, wf_driver_keys;
int wf_fleet_check_partition(WfCfgNode *root, const WfKeySpec *row, void *sc, WfKeyEnv *env, WfError *err);

#endif
