/* A minimal test harness: each test binary registers cases, runs them and prints one line per case
 * ("PASS name" or "FAIL name: reason"); tests/run.sh adds the lines up into "N passed, N failed". */
#ifndef WF_TEST_H
#define WF_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/vehicle.h"

static int wf_test_failed_;      /* failures in the current case */
static int wf_test_fail_total_;  /* failed cases in this binary */
static const char *wf_test_name_;

#define CHECK(cond, ...)                                                                \
    do {                                                                                \
        if (!(cond)) {                                                                  \
            if (wf_test_failed_++ < 5) {                                                \
                fprintf(stdout, "  %s:%d: check failed: %s: ", __FILE__, __LINE__, #cond); \
                fprintf(stdout, __VA_ARGS__);                                           \
                fputc('\n', stdout);                                                    \
            }                                                                           \
        }                                                                               \
    } while (0)

/* |got - want| <= rtol * max(|want|, tiny) */
#define CHECK_REL(got, want, rtol)                                                               \
    do {                                                                                         \
        double g_ = (got), w_ = (want);                                                          \
        double s_ = fabs(w_) > 1e-300 ? fabs(w_) : 1e-300;                                       \
        CHECK(fabs(g_ - w_) <= (rtol) * s_, "got %.17g want %.17g (rel err %.3g, tol %.3g)", g_, w_, \
              fabs(g_ - w_) / s_, (double)(rtol));                                               \
    } while (0)

#define CHECK_ABS(got, want, atol)                                                        \
    do {                                                                                  \
        double g_ = (got), w_ = (want);                                                   \
        CHECK(fabs(g_ - w_) <= (atol), "got %.17g want %.17g (abs err %.3g, tol %.3g)", g_, w_, \
              fabs(g_ - w_), (double)(atol));                                             \
    } while (0)

/* Before the first case: the library has no class search path of its own; tests find the repository's classes
 * by its source path (WF_REPO_DIR, given to test objects by the Makefile). */
static void wf_test_setup_(void)
{
    static int done;
    WfError e = {0};
    if (!done && wf_vehicle_search_path_set(WF_REPO_DIR "/vehicles", &e)) abort();
    done = 1;
}

#define RUN(fn)                                                                   \
    do {                                                                          \
        wf_test_setup_();                                                         \
        wf_test_failed_ = 0;                                                      \
        wf_test_name_ = #fn;                                                      \
        fn();                                                                     \
        if (wf_test_failed_) wf_test_fail_total_++;                               \
        printf("%s %s\n", wf_test_failed_ ? "FAIL" : "PASS", wf_test_name_);      \
        fflush(stdout);                                                           \
    } while (0)

/* A run's record (engine.h: WfRecord) kept in a row struct with members v and class_fuel_rate_gps (WfTsRow,
 * WfCorridorRow): the values, each class's fuel rate, zeros past the classes (rows are compared whole). dst is
 * evaluated more than once. */
#define WF_TEST_KEEP_RECORD(dst, rec, n_classes)                                                   \
    do {                                                                                            \
        memset((dst), 0, sizeof *(dst));                                                            \
        memcpy((dst)->v, (rec)->v, (rec)->n * sizeof *(rec)->v);                                    \
        memcpy((dst)->class_fuel_rate_gps, (rec)->class_fuel_rate_gps, (n_classes) * sizeof(double)); \
    } while (0)

/* Values kept in the order they come: a run's records and trips, compared bit for bit. */
typedef struct WfTestVals {
    double *v;
    size_t  n, cap;
} WfTestVals;

static inline void wf_test_keep(WfTestVals *o, const double *v, size_t n)
{
    if (o->n + n > o->cap) {
        o->cap = 2 * (o->n + n);
        o->v = realloc(o->v, o->cap * sizeof(double));
        if (!o->v) abort();
    }
    memcpy(o->v + o->n, v, n * sizeof(double));
    o->n += n;
}

/* A corridor's trip, field by field. */
static inline void wf_test_keep_trip(WfTestVals *o, const WfTrip *t)
{
    double f[] = {(double)t->serial, t->class_id, t->group_id, t->completed, t->t_arrival_s, t->t_entry_s,
                  t->t_exit_s, t->v_entry_mps, t->fuel_g, t->dist_m, t->time_stopped_s, t->stops,
                  t->hard_brakes, t->infeasible_steps, t->lane, t->lane_changes};
    wf_test_keep(o, f, sizeof f / sizeof f[0]);
}

/* A corridor with every part of the state a time-blocked window or a split across processes touches (tests/
 * test_window.c, tests/test_partition.c): Poisson arrivals above what the road takes (a queue at the entrance), noisy
 * heterogeneous IDM with the feasible clip, a PI-with-saturation controller with memory under a safety filter, two
 * classes, a grade profile, a headway and a speed-limit zone, a prescribed-speed virtual leader that drops (a queue
 * from the exit, and its restarts at each exit), Edie cells of 250 m and detectors at and beside 3000, 4000, 6000,
 * 8000 and 9000 m (the cuts between the segments of 2, 3 and 4 processes). */
#define WF_TEST_CORRIDOR_YAML \
    "seed: 17\n" \
    "road:\n  type: corridor\n  length_m: 12000\n  speed_limit_mps: 30\n" \
    "  grade: {points: [[0, 0], [3000, 0.02], [7000, -0.015], [12000, 0]]}\n" \
    "  zones:\n    - {type: headway, from_m: 2000, to_m: 4000, factor: 1.4}\n" \
    "    - {type: speed_limit, from_m: 9000, to_m: 9500, speed_limit_mps: 9}\n" \
    "time: {duration_s: 900, dt_s: 0.1, output_interval_s: 5.0, warmup_s: 450}\n" \
    "fleet:\n  placement: random\n" \
    "  classes:\n    - {class: midsize_sedan, fraction: 0.75}\n    - {class: class8_tractor, fraction: 0.25}\n" \
    "  drivers:\n" \
    "    - {model: idm, fraction: 0.8, noise_mps2: 0.2, feasible_accel: clip,\n" \
    "       heterogeneity: {spread: {v0_mps: 0.1, T_s: 0.15}}}\n" \
    "    - {model: pi_saturation, fraction: 0.2, class: midsize_sedan, safety: {kind: gipps, gap_min_m: 4}}\n" \
    "corridor:\n  inflow: {flow_vph: 2600, arrivals: poisson}\n" \
    "  outflow: {type: speed, points: [[0, 25], [350, 25], [400, 5], [700, 5], [750, 25]]}\n" \
    "  detectors: {x_m: [1000, 2998, 3000, 3990, 4000, 6000, 6003, 7995, 8000, 9000, 11900], interval_s: 60}\n" \
    "  edie: {dx_m: 250, dt_s: 30}\n"

#define TEST_EXIT() return wf_test_fail_total_ ? 1 : 0

/* A scenario text in a new temporary directory: dir is a mkdtemp template ("/tmp/x_XXXXXX", filled in), path
 * receives dir/s.yaml (size bytes). Returns path, or NULL when the directory cannot be made. wf_test_remove_yaml
 * removes both. */
static inline const char *wf_test_write_yaml(const char *text, char *dir, char *path, size_t size)
{
    if (!mkdtemp(dir)) return NULL;
    snprintf(path, size, "%s/s.yaml", dir);
    FILE *f = fopen(path, "w");
    if (!f) return NULL;
    fputs(text, f);
    fclose(f);
    return path;
}

static inline void wf_test_remove_yaml(const char *dir, const char *path)
{
    unlink(path);
    rmdir(dir);
}

/* The run's complete state, what a checkpoint saves (wf_sim_state), concatenated into a new buffer (the caller frees
 * it; NULL when out of memory), its size in *size. */
static inline unsigned char *wf_test_state_copy(WfSim *sim, size_t *size)
{
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS);
    *size = 0;
    for (size_t k = 0; k < nv; k++) *size += vars[k].size;
    unsigned char *buf = malloc(*size ? *size : 1);
    for (size_t k = 0, off = 0; buf && k < nv; k++) {
        memcpy(buf + off, vars[k].data, vars[k].size);
        off += vars[k].size;
    }
    return buf;
}

#endif
