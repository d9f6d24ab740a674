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
