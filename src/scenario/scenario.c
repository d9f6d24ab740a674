/* Scenario loading: YAML + --set overrides -> WfScenario, with every key typed, range-checked and named in
 * errors (file:line: path), unknown keys rejected with a suggestion, and cross-field consistency checked. Every
 * section's keys are rows of a table (include/wavefuel/keys.h) read in order by wf_keys_read; this file holds the
 * tables of the top level, road, time, solver, initial, statistics and output, scenario_fleet.c those of the fleet,
 * scenario_corridor.c those of corridors. */
#include "wavefuel/scenario.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scenario/scenario_keys.h"
#include "util/outpath.h"
#include "util/path.h"
#include "wavefuel/cf_plugin.h"
#include "wavefuel/mlp.h"
#include "wavefuel/corridor.h"
#include "wavefuel/integrator.h"
#include "util/numfmt.h"
#include "util/mem.h"

#define where_of wf_scenario_where

const char *wf_scenario_where(const WfCfgNode *n, char *buf, size_t len)
{
    char w[600], p[400];
    snprintf(buf, len, "%s: %s", wf_cfg_where(n, w, sizeof w), wf_cfg_path(n, p, sizeof p));
    return buf;
}

void wf_scenario_destroy(WfScenario **psc)
{
    if (!psc || !*psc) return;
    WfScenario *sc = *psc;
    for (size_t i = 0; i < sc->n_classes; i++) {
        wf_vehicle_free(&sc->classes[i].vc);
        free(sc->classes[i].indices);
    }
    for (size_t i = 0; i < sc->n_groups; i++) {
        free(sc->groups[i].indices);
        wf_cf_plugin_close(&sc->groups[i].plugin);
        wf_mlp_destroy(&sc->groups[i].mlp);
    }
    wf_road_free(&sc->road);
    wf_corridor_spec_destroy(&sc->corridor);
    for (size_t i = 0; i < sc->n_inputs; i++) free(sc->inputs[i]);
    WF_FREE(sc->inputs, sc->text, sc->overrides, sc);
    *psc = NULL;
}

int wf_scenario_lanes(const WfScenario *sc)
{
    return (sc->n_lanes > 1 ? sc->n_lanes : 1) + (sc->corridor && sc->corridor->has_ramp);
}

long wf_scenario_n_steps(const WfScenario *sc) { return lround(sc->duration_s / sc->dt_s); }
long wf_scenario_output_every(const WfScenario *sc) { return lround(sc->output_interval_s / sc->dt_s); }
long wf_scenario_trajectory_every(const WfScenario *sc)
{
    long k = lround(sc->trajectory_interval_s / sc->dt_s);
    return k < 1 ? 1 : k;
}
long wf_scenario_records(const WfScenario *sc, long every) { return wf_scenario_n_steps(sc) / every + 1; }

/* road.grade of a ring: points or a CSV file; wf_road_set_grade checks the values and that the profile closes. */
static int load_grade(WfCfgNode *road, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfScenario *sc = target;
    WfCfgNode *grade = NULL;
    if (wf_cfg_map_opt(road, "grade", &grade, err)) return WF_EINPUT;
    if (!grade) return 0;
    static const WfPairCols cols = {{"x_m", "grade_rad"}, {"m", "rad"}, {0, -0.2}, {1e9, 0.2}, .csv_doc = "a file"};
    double *x = NULL, *th = NULL;
    size_t n = 0;
    char where[2048];
    int rc = wf_scenario_pairs(sc, grade, &cols, &x, &th, &n, where, sizeof where, err);
    /* No points: a flat ring; a CSV file without rows is a mistake. */
    if (!rc && n == 0 && wf_cfg_child(grade, "csv")) rc = wf_err(err, WF_EINPUT, "%s: no rows", where);
    if (!rc) rc = wf_road_set_grade(&sc->road, n, x, th, where, err);
    free(x);
    free(th);
    return rc;
}

/* name: the file stem unless given. It names output/NAME.h5, so it must be a plain file name that fits: refused,
 * not cut or followed out of output/ ("../escape"). */
static int load_name(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfScenario *sc = t;
    const char *s = NULL;
    char stem[1024], w[1024];
    snprintf(stem, sizeof stem, "%s", wf_path_base(sc->path));
    char *dot = strrchr(stem, '.');
    if (dot && dot != stem) *dot = '\0';
    if (wf_cfg_string_opt(root, "name", &s, err)) return WF_EINPUT;
    const char *name = s ? s : stem;
    const char *problem = wf_path_plain_name_problem(name, sizeof sc->name - 1);
    char size[64] = "";
    if (problem && strlen(name) > sizeof sc->name - 1)
        snprintf(size, sizeof size, " (%zu bytes; at most %zu)", strlen(name), sizeof sc->name - 1);
    if (problem && s)
        return wf_err(err, WF_EINPUT, "%s '%.200s' %s%s", where_of(wf_cfg_child(root, "name"), w, sizeof w), s,
                      problem, size);
    if (problem)
        return wf_err(err, WF_EINPUT, "%s: the file's stem '%.200s', the default name, %s%s: set `name:`", sc->path,
                      stem, problem, size);
    memcpy(sc->name, name, strlen(name) + 1); /* fits: checked above */
    return 0;
}

/* road.type: the boundary every later key is read for. */
static int load_road_type(WfCfgNode *road, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfScenario *sc = t;
    int rtype = 0;
    if (wf_cfg_enum_opt(road, "type", row->choices, &rtype, err)) return WF_EINPUT;
    env->on = rtype == 0 ? WF_ON_RING : WF_ON_CORRIDOR;
    /* Corridors: vehicles come from the inflow; class and group fractions resolve against a nominal count. */
    if (env->on == WF_ON_CORRIDOR) sc->n_vehicles = WF_CORRIDOR_SHARE_BASE;
    return 0;
}

/* road.lane_speed_limits_mps: one limit per lane (road.lanes and road.speed_limit_mps are read before it). */
static int load_lane_limits(WfCfgNode *road, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    WfScenario *sc = t;
    WfCfgNode *seq = NULL;
    char w[1024];
    for (int l = 0; l < WF_MAX_LANES; l++) sc->lane_speed_limit_mps[l] = sc->road.speed_limit_mps;
    if (wf_cfg_seq_opt(road, row->key, &seq, err)) return WF_EINPUT;
    if (!seq) return 0;
    /* a corridor's lanes include the on-ramp's merge lane, read later: scenario_corridor.c checks the count */
    if (env->on == WF_ON_RING && seq->n_child != (size_t)sc->n_lanes)
        return wf_err(err, WF_EINPUT, "%s: road.lane_speed_limits_mps lists %zu lanes but road.lanes is %d",
                      where_of(seq, w, sizeof w), seq->n_child, sc->n_lanes);
    if (seq->n_child > WF_MAX_LANES)
        return wf_err(err, WF_EINPUT, "%s: road.lane_speed_limits_mps lists %zu lanes: at most %d",
                      where_of(seq, w, sizeof w), seq->n_child, WF_MAX_LANES);
    if (env->on == WF_ON_CORRIDOR)
        for (size_t l = seq->n_child; l < WF_MAX_LANES; l++) sc->lane_speed_limit_mps[l] = NAN;
    for (size_t l = 0; l < seq->n_child; l++)
        if (wf_cfg_node_double(seq->child[l], row->min, row->max, row->unit, &sc->lane_speed_limit_mps[l], err))
            return WF_EINPUT;
    return 0;
}

static const char *const road_types[] = {"ring", "corridor", NULL};
static const char *const lane_rules[] = {"symmetric", "keep_right", NULL};

static const WfKeySpec ring_grade_rows[] = {
    {.key = "points", .type = WF_KEY_CUSTOM, .on = WF_ON_RING, .flags = WF_KEY_NOREAD,
     .doc_type = "list of `[x_m, grade_rad]`", .doc_default = "flat",
     .doc_range = "x in [0, L) increasing, \\|θ\\| ≤ 0.2 rad", .doc = "piecewise-linear grade angle, periodic on the ring"},
    {.key = "csv", .type = WF_KEY_CUSTOM, .on = WF_ON_RING, .flags = WF_KEY_NOREAD, .doc_type = "path",
     .doc = "same from a CSV with header `x_m,grade_rad` (relative to the scenario file)"},
};
static const WfKeyTable ring_grade_keys = {"road.grade", ring_grade_rows, 2};

static const WfKeySpec road_rows[] = {
    {.key = "type", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_road_type, .choices = road_types,
     .doc = "single-lane ring road; `corridor`: an open road with inflow and outflow, keys in "
            "[corridors.md](corridors.md)"},
    {.key = "length_m", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfScenario, road.length_m), .min = 1, .max = 1e10, .unit = "m", .doc_range = "> 0",
     .doc = "ring length; corridor: L, from the entrance to the exit"},
    {.key = "speed_limit_mps", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfScenario, road.speed_limit_mps), .def = INFINITY, .min = 0.1, .max = 100, .unit = "m/s",
     .doc = "no vehicle accelerates past it (the acceleration is capped at (limit − v)/dt); corridor: the limit "
            "everywhere (zones may lower it)"},
    {.key = "lanes", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, n_lanes),
     .size = sizeof(int), .def = 1, .imin = 1, .imax = WF_MAX_LANES, .doc_range = "1, 2, …, 8",
     .doc = "lanes of the road, numbered from 0 (the rightmost); vehicles change lanes by their group's "
            "`lane_change` model ([lanes.md](lanes.md))"},
    {.key = "lane_rule", .type = WF_KEY_CHOICE, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, lane_rule),
     .choices = lane_rules,
     .doc = "passing rule of the lane-change models: `symmetric` (pass on either side), `keep_right` (MOBIL's "
            "European rules: a bias to the right lane, no regard for the new follower on a change to the right)"},
    {.key = "lane_speed_limits_mps", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_lane_limits,
     .min = 0.1, .max = 100, .unit = "m/s",
     .doc_type = "list of m/s", .doc_default = "`speed_limit_mps` in every lane", .doc_range = "one per lane, [0.1, 100]",
     .doc = "a speed limit per lane (lane 0 first; on a corridor with an on-ramp, its merge lane is lane 0), applied "
            "as `speed_limit_mps` is (a corridor's zones may lower it); lane-change models do not see it (their "
            "accelerations are the car-following models')"},
    {.key = "grade", .type = WF_KEY_CUSTOM, .on = WF_ON_RING, .flags = WF_KEY_FLAT, .hook = load_grade,
     .sub = &ring_grade_keys},
    /* A corridor's grade profile is not periodic and its zones name driver parameters: scenario_corridor.c reads
     * them after the fleet. */
    {.key = "grade", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_LATER | WF_KEY_FLAT,
     .hook = wf_corridor_road_grade, .sub = &wf_corridor_grade_keys},
    {.key = "elevation", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_LATER | WF_KEY_FLAT,
     .hook = wf_corridor_road_elevation, .sub = &wf_corridor_elevation_keys},
    {.key = "zones", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_LATER,
     .hook = wf_corridor_road_zones, .sub = &wf_corridor_zone_keys, .doc_type = "list", .doc_default = "none",
     .doc_range = "≤ 64", .doc = "road features along x, below"},
};
const WfKeyTable wf_road_keys = {"road", road_rows, sizeof road_rows / sizeof *road_rows};

/* time.integrator: any entry of the integrator registry; the adaptive ones are configured by `solver`. */
static int load_integrator(WfCfgNode *time, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfScenario *sc = t;
    const char *integ = "ballistic";
    const WfIntegrator *ig = NULL;
    char w[1024];
    if (wf_cfg_string_opt(time, "integrator", &integ, err)) return WF_EINPUT;
    if (wf_integrator_find(integ, &ig, err)) {
        wf_err_prefix(err, "%s: ", where_of(wf_cfg_child(time, "integrator"), w, sizeof w));
        return WF_EINPUT;
    }
    sc->adaptive = ig->kind == WF_INTEG_ADAPTIVE;
    sc->solver.kind = sc->adaptive ? (WfOdeKind)ig->ode_kind : WF_ODE_RK4;
    snprintf(sc->integrator, sizeof sc->integrator, "%s", integ);
    return 0;
}

/* The step must divide the output interval and the duration: records then fall on steps exactly. */
static int check_time(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)root, (void)row, (void)env;
    WfScenario *sc = t;
    double ratio = sc->output_interval_s / sc->dt_s, nsteps = sc->duration_s / sc->dt_s;
    if (sc->dt_s > sc->output_interval_s || fabs(ratio - round(ratio)) > 1e-9 * ratio)
        return wf_err(err, WF_EINPUT,
                      "%s: time.output_interval_s (%s s) must be a whole multiple of time.dt_s (%s s)", sc->path,
                      WF_NUM(sc->output_interval_s), WF_NUM(sc->dt_s));
    if (fabs(nsteps - round(nsteps)) > 1e-9 * nsteps)
        return wf_err(err, WF_EINPUT, "%s: time.duration_s (%s s) must be a whole multiple of time.dt_s (%s s)",
                      sc->path, WF_NUM(sc->duration_s), WF_NUM(sc->dt_s));
    if (nsteps > 1e12) return wf_err(err, WF_EINPUT, "%s: more than 1e12 steps: reduce duration or raise dt", sc->path);
    if (sc->adaptive && sc->n_lanes > 1)
        return wf_err(err, WF_EINPUT,
                      "%s: time.integrator %s steps single-lane rings (lane changes move vehicles between steps, which "
                      "the adaptive solvers would integrate across): use ballistic or euler with road.lanes = %d",
                      sc->path, sc->integrator, sc->n_lanes);
    if (sc->warmup_s >= sc->duration_s)
        return wf_err(err, WF_EINPUT, "%s: time.warmup_s (%s s) must be shorter than time.duration_s (%s s)",
                      sc->path, WF_NUM(sc->warmup_s), WF_NUM(sc->duration_s));
    return 0;
}

static const WfKeySpec time_rows[] = {
    {.key = "duration_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED,
     .offset = offsetof(WfScenario, duration_s), .min = 1e-6, .max = 1e9, .unit = "s",
     .doc_range = "> 0, a multiple of `dt_s`", .doc = "simulated time"},
    {.key = "dt_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, dt_s), .def = 0.1,
     .min = 1e-6, .max = 10, .unit = "s", .doc_range = "(0, 10]", .doc = "time step"},
    {.key = "output_interval_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfScenario, output_interval_s), .def = 1.0, .min = 1e-6, .max = 1e9, .unit = "s",
     .doc_range = "a multiple of `dt_s`", .doc = "time-series records"},
    {.key = "warmup_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, warmup_s), .def = 0,
     .min = 0, .max = 1e9, .unit = "s", .doc_range = "[0, duration)",
     .doc = "excluded from every statistic of the window"},
    {.key = "integrator", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_integrator,
     .doc_type = "a name of the table below", .doc_default = "`ballistic`",
     .doc = "`ballistic`: x += v dt + a dt²/2, v += a dt, stopping exactly where v reaches 0 (Treiber & Kanagaraj "
            "2015); `euler`: x += v dt, v += a dt, v ≥ 0; `cvode`, `arkode`, `rk4`: SUNDIALS, configured by the "
            "`solver` section below"},
    {.key = "fused_step", .type = WF_KEY_BOOL, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, fused_step), .def = 1,
     .doc = "fixed-step schemes: every step (records included) runs car-following, energy, the record's partial sums, "
            "statistics and integration in one pass per block of 256 vehicles, with the per-step values (gap, leader "
            "speed, grade, acceleration, fuel rate) kept per block instead of fleet-wide (less memory and memory "
            "traffic). Steps that write trajectories take two passes of the same block kernel, the first exporting "
            "those values fleet-wide for the writer (so runs with trajectories hold 49 B more per vehicle), the "
            "second advancing. Results are bit-identical either way (`tests/test_engine_paths.c`: final state, every "
            "record, every accumulator, with and without trajectories). Set false to time the two passes apart in "
            "`/meta/phase_time` (rings; a corridor always takes the fused step, as docs/corridors.md says, and writes "
            "no phase times)"},
    {.key = "block_steps", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, block_steps),
     .size = sizeof(int), .def = 0, .imin = 0, .imax = 200, .doc_default = "0 (ring: 64; corridor: 1)",
     .doc_range = "0, 1, …, 200",
     .doc = "fixed-step schemes on the fused path: steps per time-blocked window. The road is cut into chunks "
            "(8 per thread) that go to whichever thread is free; a chunk is stepped tile by tile, every tile "
            "`block_steps` steps while it stays in cache, following the tile ahead through the trace of its first "
            "vehicle, and the threads meet once per window instead of once per step. A ring's default, 64, is 16 "
            "times the steps between records when records come more often than every 4 steps (the window keeps "
            "each of its records' sums, 0.8 B per vehicle a record). Results are bit-identical to "
            "stepping one step at a time (`tests/test_window.c`); a window in which a vehicle overlaps or a fault "
            "appears is undone and redone one step at a time. A ring copies its state for that (about the run's "
            "memory again). A corridor steps in windows only when asked (0 is 1 there: measured slower on idle "
            "cores, bench/README.md): its front vehicles that may leave and its entrance step one step at a time "
            "around the windowed interior, and the Edie and detector measurement of the window follows it "
            "(docs/corridors.md); it keeps 16 B per slot of its vehicle buffer and step of the window, and copies "
            "every slot's controller memory. 1: one step at a time. Stepped one at a time whatever the value: "
            "roads shorter than 512 vehicles per thread, trajectory steps, the step that opens the statistics "
            "window, runs with a `model: mlp` group, `fused_step: false`, the SUNDIALS integrators; on a corridor "
            "also record steps, groups commanded from outside, several lanes and an off-ramp"},
    {.key = "tile_vehicles", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, tile_vehicles),
     .size = sizeof(long), .def = 0, .imin = 0, .imax = 1000000000L, .doc_default = "0 (from the L2 cache)",
     .doc = "vehicles per tile of a time-blocked window, rounded up to blocks of 256; 0: half the L2 cache of a "
            "core over the bytes of state per vehicle. Results do not depend on it"},
    {.key = "thread_check_steps", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH,
     .offset = offsetof(WfScenario, thread_check_steps), .size = sizeof(long), .def = 1024, .imin = 0,
     .imax = 1000000000L, .doc_range = "0, 1, …",
     .doc = "a run on more than one thread: every `thread_check_steps` steps that threads can share (a ring, or a "
            "corridor's lane, of at least 4096 vehicles) the run times 1/16 of them on the other thread count (one "
            "thread, or all of them): at least one step, at most 0.2 s of steps, 0.02 s when the process's CPU time "
            "showed every thread running all the time. It switches when the other count did 20 % more "
            "vehicle-steps per second of wall time; a probe that loses doubles the interval "
            "(up to 64 times), a switch sets it back, and 64 steps at under a quarter of the rate of the 64 before "
            "them (a load that arrived) probe at once. The first step (or window) is not timed. On a machine whose "
            "cores other processes also use, threads that meet at a barrier wait for whichever thread was "
            "descheduled, and two threads can be several times slower than one. Results do not depend on it (a "
            "step gives the same bits on any number of threads). 0: always all threads"},
};
static const WfKeyTable time_keys = {"time", time_rows, sizeof time_rows / sizeof *time_rows};

/* solver.method: cvode's linear multistep family or arkode's Butcher table; rk4 has none. */
static int load_method(WfCfgNode *sv, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    WfOdeConfig *c = t;
    const char *method = NULL;
    char w[1024];
    snprintf(c->erk_table, sizeof c->erk_table, "ARKODE_DORMAND_PRINCE_7_4_5");
    if (wf_cfg_string_opt(sv, "method", &method, err)) return WF_EINPUT;
    if (method && c->kind == WF_ODE_CVODE) {
        if (strcmp(method, "adams") && strcmp(method, "bdf"))
            return wf_err(err, WF_EINPUT, "%s: solver.method for cvode is 'adams' or 'bdf' (got '%s')",
                          where_of(wf_cfg_child(sv, "method"), w, sizeof w), method);
        c->bdf = !strcmp(method, "bdf");
    } else if (method && c->kind == WF_ODE_ARKODE) {
        snprintf(c->erk_table, sizeof c->erk_table, "%s", method);
    } else if (method) {
        return wf_err(err, WF_EINPUT, "%s: rk4 has no method to choose (it is the classic RK4 tableau)",
                      where_of(wf_cfg_child(sv, "method"), w, sizeof w));
    }
    return 0;
}

static const char *const nvectors[] = {"serial", "openmp", NULL};

static const WfKeySpec solver_rows[] = {
    {.key = "rtol", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, rtol), .def = 1e-6,
     .min = 1e-14, .max = 1e-1, .unit = "1",
     .doc = "relative tolerance: speeds relative to themselves, positions relative to the spacing to the leader "
            "(unwrapped positions grow without bound, so a tolerance relative to them would mean nothing), fuel "
            "relative to the accumulated fuel"},
    {.key = "atol_x_m", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, atol_x_m),
     .def = 1e-6, .min = 1e-14, .max = 10, .unit = "m", .doc = "absolute tolerance of positions"},
    {.key = "atol_v_mps", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, atol_v_mps),
     .def = 1e-6, .min = 1e-14, .max = 10, .unit = "m/s", .doc = "absolute tolerance of speeds"},
    {.key = "atol_fuel_g", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, atol_fuel_g),
     .def = 1e-6, .min = 1e-14, .max = 10, .unit = "g", .doc = "absolute tolerance of the fuel integrals"},
    {.key = "max_step_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, max_step_s),
     .def = 0, .min = 0, .max = 1e6, .unit = "s", .doc_default = "0 (none)",
     .doc = "largest internal step (adaptive methods)"},
    {.key = "max_steps", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, max_steps),
     .size = sizeof(long), .def = 100000, .imin = 1, .imax = 1000000000L, .doc = "internal steps allowed per time step"},
    {.key = "fuel_error_control", .type = WF_KEY_BOOL, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, fuel_errcon),
     .def = 0, .doc = "include the fuel integrals in the local error test"},
    {.key = "nvector", .type = WF_KEY_CHOICE, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, nvector_openmp),
     .choices = nvectors,
     .doc = "`openmp` uses NVECTOR_OPENMP: its norms are floating-point reductions whose order depends on the thread "
            "count, so results are then not bit-identical across thread counts. The right-hand side is parallel with "
            "either"},
    {.key = "method", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_method, .doc_type = "text",
     .doc_default = "`adams` (cvode), `ARKODE_DORMAND_PRINCE_7_4_5` (arkode)",
     .doc = "cvode: `adams` (Adams–Moulton, fixed-point iteration) or `bdf` (BDF, Newton with matrix-free GMRES); "
            "arkode: any explicit Butcher table name of ARKODE (`ARKODE_BOGACKI_SHAMPINE_4_2_3`, "
            "`ARKODE_CASH_KARP_6_4_5`, `ARKODE_VERNER_8_5_6`, ...)"},
    {.key = "rk4_substeps", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfOdeConfig, rk4_substeps),
     .size = sizeof(int), .def = 1, .imin = 1, .imax = 1000000, .doc_range = "≥ 1",
     .doc = "rk4: fixed steps of dt / substeps (classic RK4 tableau)"},
};
static const WfKeyTable solver_keys = {"solver", solver_rows, sizeof solver_rows / sizeof *solver_rows};

/* `solver`: settings of the SUNDIALS integrators. Present only with one of them. */
static int load_solver(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row;
    WfScenario *sc = t;
    WfCfgNode *sv = NULL;
    char w[1024];
    WfOdeKind kind = sc->solver.kind;
    memset(&sc->solver, 0, sizeof sc->solver);
    sc->solver.kind = kind;
    if (wf_cfg_map_opt(root, "solver", &sv, err)) return WF_EINPUT;
    if (sv && !sc->adaptive)
        return wf_err(err, WF_EINPUT, "%s: 'solver' configures cvode, arkode and rk4; time.integrator is '%s'",
                      where_of(sv, w, sizeof w), sc->integrator);
    return wf_keys_read(sv, &solver_keys, WF_KEYS_FIRST, &sc->solver, env, err);
}

_Static_assert(sizeof(WfInitState) == sizeof(int) && sizeof(WfOdeKind) == sizeof(int), "choice fields are ints");

/* No perturbation section: no vehicle is perturbed. */
static int check_perturbation(WfCfgNode *init, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)env, (void)err;
    if (!wf_cfg_child(init, row->key)) ((WfScenario *)t)->perturb_vehicle = -1;
    return 0;
}

static const WfKeySpec perturbation_rows[] = {
    {.key = "vehicle", .type = WF_KEY_INTEGER, .on = WF_ON_RING, .offset = offsetof(WfScenario, perturb_vehicle),
     .size = sizeof(long), .def = 0, .imin = 0, .max_is = WF_BOUND_LAST_VEHICLE, .doc_range = "[0, N)",
     .doc = "vehicle to perturb"},
    {.key = "dx_m", .type = WF_KEY_NUMBER, .on = WF_ON_RING, .offset = offsetof(WfScenario, perturb_dx_m), .def = 0,
     .min = -1e3, .max = 1e3, .unit = "m", .doc = "position offset"},
    {.key = "dv_mps", .type = WF_KEY_NUMBER, .on = WF_ON_RING, .offset = offsetof(WfScenario, perturb_dv_mps),
     .def = 0, .min = -100, .max = 100, .unit = "m/s", .doc = "speed offset (the result must stay ≥ 0)"},
};
static const WfKeyTable perturbation_keys = {"initial.perturbation", perturbation_rows, 3};

static const char *const init_states[] = {"equilibrium", "rest", NULL};

static const WfKeySpec initial_rows[] = {
    {.key = "state", .type = WF_KEY_CHOICE, .on = WF_ON_RING, .offset = offsetof(WfScenario, init_state),
     .choices = init_states,
     .doc = "`equilibrium`: every vehicle at the common speed v* at which each one's model equilibrium gap s_e,i(v*) "
            "fills the ring exactly (Σ s_e,i(v*) + len_i = L, solved by bisection from the models, so identical "
            "drivers get uniform spacing); `rest`: equal gaps, v = 0"},
    {.key = "jitter_m", .type = WF_KEY_NUMBER, .on = WF_ON_RING, .offset = offsetof(WfScenario, jitter_m), .def = 0,
     .min = 0, .max = 1e3, .unit = "m", .doc = "uniform random position offset in [−j, j] per vehicle, by seed"},
    {.key = "perturbation", .type = WF_KEY_SECTION, .on = WF_ON_RING, .flags = WF_KEY_FLAT,
     .sub = &perturbation_keys, .hook = check_perturbation},
};
static const WfKeyTable initial_keys = {"initial", initial_rows, sizeof initial_rows / sizeof *initial_rows};

static int check_statistics(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)root, (void)row, (void)env;
    WfScenario *sc = t;
    if (!(sc->v_go_mps > sc->v_stop_mps))
        return wf_err(err, WF_EINPUT, "%s: statistics.v_go_mps (%s) must exceed statistics.v_stop_mps (%s)",
                      sc->path, WF_NUM(sc->v_go_mps), WF_NUM(sc->v_stop_mps));
    if (isnan(sc->wave_speed_mps)) sc->wave_speed_mps = sc->v_go_mps;
    return 0;
}

static const WfKeySpec statistics_rows[] = {
    {.key = "v_stop_mps", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, v_stop_mps),
     .def = 0.5, .min = 0, .max = 50, .unit = "m/s", .doc = "a stop begins below this speed"},
    {.key = "v_go_mps", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, v_go_mps), .def = 2.0,
     .min = 0, .max = 50, .unit = "m/s", .doc_range = "(v_stop, 50]", .doc = "...after having exceeded this one"},
    {.key = "hard_brake_mps2", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfScenario, hard_brake_mps2), .def = 1.0, .min = 0.01, .max = 20, .unit = "m/s^2",
     .doc = "hard braking: a < −this"},
    {.key = "wave_speed_mps", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, wave_speed_mps),
     .def = NAN, .min = 0, .max = 100, .unit = "m/s", .doc_default = "`v_go_mps`",
     .doc = "vehicles slower than this belong to a wave"},
};
static const WfKeyTable statistics_keys = {"statistics", statistics_rows, 4};

/* Derived defaults of `output`, and trajectory frames on steps. */
static int check_output(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)env;
    WfScenario *sc = t;
    if (!sc->output_path[0])
        snprintf(sc->output_path, sizeof sc->output_path, WF_OUTPUT_DEFAULT_DIR "/%s.h5", sc->name);
    if (isnan(sc->trajectory_interval_s)) sc->trajectory_interval_s = sc->output_interval_s;
    double r2 = sc->trajectory_interval_s / sc->dt_s;
    if (wf_cfg_child(root, row->key) && fabs(r2 - round(r2)) > 1e-9 * r2)
        return wf_err(err, WF_EINPUT, "%s: output.trajectory_interval_s must be a whole multiple of time.dt_s",
                      sc->path);
    return 0;
}

static const WfKeySpec output_rows[] = {
    {.key = "path", .type = WF_KEY_TEXT, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, output_path),
     .size = sizeof(((WfScenario *)0)->output_path), .doc_type = "path", .doc_default = "`output/NAME.h5`",
     .doc = "result file (`-o` overrides)"},
    {.key = "trajectories", .type = WF_KEY_BOOL, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, trajectories),
     .def = 0, .doc = "write `/trajectories` (x, v, a, fuel rate per vehicle)"},
    {.key = "trajectory_interval_s", .type = WF_KEY_NUMBER, .on = WF_ON_BOTH,
     .offset = offsetof(WfScenario, trajectory_interval_s), .def = NAN, .min = 1e-6, .max = 1e9, .unit = "s",
     .doc_default = "`output_interval_s`", .doc_range = "a multiple of `dt_s`", .doc = "trajectory sampling"},
};
static const WfKeyTable output_keys = {"output", output_rows, 3};

/* The corridor section, after everything a ring reads too. */
static int load_corridor(WfCfgNode *root, const WfKeySpec *row, void *t, WfKeyEnv *env, WfError *err)
{
    (void)row, (void)env;
    return wf_corridor_spec_load(t, root, err) ? WF_EINPUT : 0;
}

static const WfKeySpec root_rows[] = {
    {.key = "name", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .hook = load_name, .doc_type = "text",
     .doc_default = "file stem", .doc_range = "a file name, ≤ 127 bytes",
     .doc = "run name; default output `output/NAME.h5`. No `/`, not `.` or `..`, no control characters: refused, "
            "never cut"},
    {.key = "seed", .type = WF_KEY_INTEGER, .on = WF_ON_BOTH, .offset = offsetof(WfScenario, seed),
     .size = sizeof(uint64_t), .def = 1, .imin = 0, .imax = 0x7fffffffffffffffL, .doc_range = "≥ 0",
     .doc = "seed of every random draw (placement, heterogeneity, noise, jitter)"},
    {.key = "road", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED | WF_KEY_NODOC,
     .sub = &wf_road_keys, .need = "a section"},
    {.key = "time", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED | WF_KEY_NODOC,
     .sub = &time_keys, .hook = check_time, .need = "a section"},
    {.key = "solver", .type = WF_KEY_CUSTOM, .on = WF_ON_BOTH, .flags = WF_KEY_NODOC, .hook = load_solver,
     .sub = &solver_keys},
    {.key = "fleet", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_REQUIRED | WF_KEY_NODOC,
     .sub = &wf_fleet_keys, .hook = wf_fleet_check_partition, .need = "a section"},
    {.key = "initial", .type = WF_KEY_SECTION, .on = WF_ON_RING, .flags = WF_KEY_NODOC, .sub = &initial_keys,
     .off_msg = "a corridor starts empty and fills from the inflow: 'initial' applies to rings"},
    {.key = "statistics", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_NODOC, .sub = &statistics_keys,
     .hook = check_statistics},
    {.key = "output", .type = WF_KEY_SECTION, .on = WF_ON_BOTH, .flags = WF_KEY_NODOC, .sub = &output_keys,
     .hook = check_output},
    {.key = "corridor", .type = WF_KEY_CUSTOM, .on = WF_ON_CORRIDOR, .flags = WF_KEY_NODOC, .hook = load_corridor,
     .sub = &wf_corridor_keys},
};
static const WfKeyTable root_keys = {"top", root_rows, sizeof root_rows / sizeof *root_rows};

const WfKeyTable *const wf_key_tables[] = {&root_keys,       &wf_road_keys,    &wf_corridor_zone_keys, &time_keys,
                                           &solver_keys,     &wf_fleet_keys,   &wf_class_keys,         &wf_driver_keys,
                                           &initial_keys,    &statistics_keys, &output_keys,           &wf_corridor_keys,
                                           NULL};

/* The fleet must fit: total length plus each driver group's minimum standstill gap (its equilibrium gap at v = 0 is
 * not model-generic, so the fit check uses the vehicles' lengths; the engine checks gaps >= 0). */
static int check_ring_fits(const WfScenario *sc, WfError *err)
{
    double total_len = 0.0;
    for (size_t c = 0; c < sc->n_classes; c++) total_len += (double)sc->classes[c].count * sc->classes[c].length_m;
    if (total_len >= sc->road.length_m)
        return wf_err(err, WF_EINPUT,
                      "%s: %ld vehicles of total length %.6g m cannot fit on a ring of road.length_m = %s m", sc->path,
                      sc->n_vehicles, total_len, WF_NUM(sc->road.length_m));
    return 0;
}

static int load_tree(WfScenario *sc, WfCfg *cfg, WfError *err)
{
    WfKeyEnv env = {.on = WF_ON_RING, .sc = sc};
    if (wf_keys_read(cfg->root, &root_keys, WF_KEYS_FIRST, sc, &env, err)) return WF_EINPUT;
    if (env.on == WF_ON_RING && check_ring_fits(sc, err)) return WF_EINPUT;
    return wf_cfg_check_unused(cfg, err);
}

static int load_cfg(WfCfg *cfg, const char *path, const char *const *set, size_t n_set, WfScenario **out,
                    WfError *err);

int wf_scenario_load(const char *path, const char *const *set, size_t n_set, WfScenario **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_file(path, &cfg, err);
    return rc ? rc : load_cfg(cfg, path, set, n_set, out, err);
}

int wf_scenario_load_text(const char *path, const char *text, const char *const *set, size_t n_set,
                          WfScenario **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = NULL;
    int rc = wf_cfg_load_string(path, text, strlen(text), &cfg, err);
    return rc ? rc : load_cfg(cfg, path, set, n_set, out, err);
}

int wf_scenario_add_input(WfScenario *sc, const char *path, WfError *err)
{
    char **p = realloc(sc->inputs, (sc->n_inputs + 1) * sizeof *p);
    if (!p) return wf_err(err, WF_ESYS, "out of memory");
    sc->inputs = p;
    if (!(p[sc->n_inputs] = strdup(path))) return wf_err(err, WF_ESYS, "out of memory");
    sc->n_inputs++;
    return 0;
}

/* Takes ownership of cfg. */
static int load_cfg(WfCfg *cfg, const char *path, const char *const *set, size_t n_set, WfScenario **out,
                    WfError *err)
{
    int rc = 0;
    WfScenario *sc = calloc(1, sizeof *sc);
    if (!sc) {
        wf_cfg_destroy(&cfg);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    snprintf(sc->path, sizeof sc->path, "%s", path);
    if ((rc = wf_scenario_add_input(sc, path, err))) goto fail;
    size_t olen = 1;
    for (size_t i = 0; i < n_set; i++) olen += strlen(set[i]) + 1;
    sc->overrides = calloc(olen, 1);
    sc->text = strdup(cfg->text);
    if (!sc->overrides || !sc->text) {
        rc = wf_err(err, WF_ESYS, "out of memory");
        goto fail;
    }
    for (size_t i = 0; i < n_set; i++) {
        strcat(sc->overrides, set[i]);
        strcat(sc->overrides, "\n");
        if ((rc = wf_cfg_set(cfg, set[i], err))) goto fail;
    }
    if ((rc = load_tree(sc, cfg, err))) goto fail;
    wf_cfg_destroy(&cfg);
    *out = sc;
    return 0;
fail:
    wf_cfg_destroy(&cfg);
    wf_scenario_destroy(&sc);
    return rc ? rc : WF_EINPUT;
}
