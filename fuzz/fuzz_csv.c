/* Fuzz target: the numeric CSV reader and every table built on it. The first input byte selects the reader,
 * the rest is the file:
 *   0  grade profile    x_m,grade_rad        -> wf_road_set_grade on a 1000 m ring, then the grade lookup
 *   1  energy queries   v,a,theta            -> the midsize_sedan class evaluated at every row
 *   2  drive cycle      time_s,speed_mps     -> wf_cycle_load
 *   3  tabulated model  Velocity,...,Infeasible (5 columns) -> wf_table_read_csv, then evaluation
 *   4  raw reader, no header names, 1 + (second byte mod 5) columns
 *   5  corridor inflow profile  time_s,flow_vph  -> a corridor scenario naming it (corridor.inflow.csv)
 *   6  corridor elevation       x_m,z_m          -> a corridor scenario naming it (road.elevation.csv)
 * Accepted tables must satisfy what each reader documents (checked below). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_common.h"
#include "wavefuel/corridor.h"
#include "wavefuel/csv.h"
#include "wavefuel/cycle.h"
#include "wavefuel/road.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/vehicle.h"

static void check_rows(const WfCsv *t, size_t n_cols)
{
    FUZZ_REQUIRE(t->n_cols == n_cols, "n_cols %zu", t->n_cols);
    for (size_t r = 0; r < t->n_rows; r++) {
        FUZZ_REQUIRE(t->line[r] >= 1 && (r == 0 || t->line[r] > t->line[r - 1]), "row %zu line %d", r, t->line[r]);
        for (size_t c = 0; c < n_cols; c++)
            FUZZ_REQUIRE(isfinite(t->data[r * n_cols + c]), "row %zu col %zu not finite", r, c);
    }
}

static void grade(const char *path)
{
    static const char *const names[] = {"x_m", "grade_rad"};
    WfCsv t;
    WfError err = {0};
    int rc = wf_csv_read(path, 2, names, &t, &err);
    if (rc) {
        fuzz_check_error("csv grade", rc, &err);
        return;
    }
    check_rows(&t, 2);
    WfRoad road = {.length_m = 1000.0, .speed_limit_mps = INFINITY};
    double *x = malloc((t.n_rows + 1) * sizeof *x), *th = malloc((t.n_rows + 1) * sizeof *th);
    FUZZ_REQUIRE(x && th, "out of memory");
    for (size_t i = 0; i < t.n_rows; i++) x[i] = t.data[2 * i], th[i] = t.data[2 * i + 1];
    rc = wf_road_set_grade(&road, t.n_rows, x, th, path, &err);
    if (rc) {
        fuzz_check_error("road grade", rc, &err);
    } else {
        fuzz_note("road grade", 0, &err);
        /* Interpolation between accepted points never leaves [-0.2, 0.2] rad, at any unwrapped position. */
        uint32_t seg = 0;
        for (int k = -50; k <= 50; k++) {
            double xq = 1000.0 * k / 13.0;
            double g = wf_road_grade(&road, xq, &seg);
            FUZZ_REQUIRE(isfinite(g) && fabs(g) <= 0.2 + 1e-12, "grade(%g) = %g", xq, g);
        }
        seg = 7; /* a stale cache entry must be corrected */
        FUZZ_REQUIRE(isfinite(wf_road_grade(&road, 1e9 + 0.5, &seg)), "grade far down the road");
    }
    wf_road_free(&road);
    free(x);
    free(th);
    wf_csv_free(&t);
}

static void energy(const char *path)
{
    static WfVehicleClass vc;
    static int loaded;
    if (!loaded) {
        WfError e = {0};
        if (wf_vehicle_find("midsize_sedan", &vc, &e)) {
            fprintf(stderr, "fuzz_csv: %s\n", e.msg);
            abort();
        }
        loaded = 1;
    }
    static const char *const names[] = {"v", "a", "theta"};
    WfCsv t;
    WfError err = {0};
    int rc = wf_csv_read(path, 3, names, &t, &err);
    if (rc) {
        fuzz_check_error("csv energy", rc, &err);
        return;
    }
    fuzz_note("csv energy", 0, &err);
    check_rows(&t, 3);
    size_t n = t.n_rows;
    double *col = malloc((4 * n + 1) * sizeof *col);
    uint8_t *flag = malloc(n + 1);
    FUZZ_REQUIRE(col && flag, "out of memory");
    for (size_t i = 0; i < n; i++)
        col[i] = t.data[3 * i], col[n + i] = t.data[3 * i + 1], col[2 * n + i] = t.data[3 * i + 2];
    wf_vehicle_fuel(&vc, n, col, col + n, col + 2 * n, 0, col + 3 * n, flag);
    for (size_t i = 0; i < n; i++) {
        FUZZ_REQUIRE(flag[i] <= WF_NEGATIVE_SPEED, "flag %d", flag[i]);
        /* Inside a physical envelope the model's rate is finite (outside it, cubic terms may overflow). */
        if (fabs(col[i]) <= 100 && fabs(col[n + i]) <= 20 && fabs(col[2 * n + i]) <= 0.5)
            FUZZ_REQUIRE(isfinite(col[3 * n + i]), "fuel not finite at row %zu", i);
    }
    free(col);
    free(flag);
    wf_csv_free(&t);
}

static void cycle(const char *path)
{
    WfCycle c;
    WfError err = {0};
    int rc = wf_cycle_load(path, &c, &err);
    if (rc) {
        fuzz_check_error("cycle", rc, &err);
        return;
    }
    fuzz_note("cycle", 0, &err);
    FUZZ_REQUIRE(c.n >= 2, "cycle of %zu samples", c.n);
    for (size_t i = 0; i < c.n; i++) {
        FUZZ_REQUIRE(isfinite(c.t_s[i]) && (i == 0 || c.t_s[i] > c.t_s[i - 1]), "t[%zu] = %g", i, c.t_s[i]);
        FUZZ_REQUIRE(isfinite(c.v_mps[i]) && c.v_mps[i] >= 0, "v[%zu] = %g", i, c.v_mps[i]);
        FUZZ_REQUIRE(isfinite(c.dt_s[i]) && c.dt_s[i] >= 0, "dt[%zu] = %g", i, c.dt_s[i]);
        FUZZ_REQUIRE(isfinite(c.a_mps2[i]), "a[%zu] = %g (t %g, v %g)", i, c.a_mps2[i], c.t_s[i], c.v_mps[i]);
    }
    FUZZ_REQUIRE(isfinite(wf_cycle_duration_s(&c)) && isfinite(wf_cycle_distance_m(&c)), "duration or distance");
    wf_cycle_free(&c);
}

static void table(const char *path)
{
    WfTable *t = NULL;
    WfError err = {0};
    int rc = wf_table_read_csv(path, &t, &err);
    if (rc) {
        fuzz_check_error("table", rc, &err);
        FUZZ_REQUIRE(t == NULL, "failed import returned a table");
        return;
    }
    fuzz_note("table", 0, &err);
    FUZZ_REQUIRE(t && t->v.n >= 1 && t->a.n >= 1 && t->theta.n >= 1, "empty axis");
    /* Clamped trilinear interpolation of finite nodes is finite everywhere, on the grid and far outside it. */
    const double probe[] = {-1e300, -5, -0.05, 0, 0.01, 3, 17.5, 1e300};
    for (size_t i = 0; i < 8; i++)
        for (size_t j = 0; j < 8; j++)
            for (size_t k = 0; k < 8; k++) {
                uint8_t fl;
                int outside = 0;
                double f = wf_table_fuel(t, probe[i], probe[j], probe[k], (int)((i + j + k) & 1), &fl, &outside);
                FUZZ_REQUIRE(isfinite(f) && fl <= WF_NEGATIVE_SPEED, "table(%g, %g, %g) = %g", probe[i], probe[j],
                             probe[k], f);
                FUZZ_REQUIRE(isfinite(wf_table_a_max(t, probe[i], probe[k])), "table a_max");
            }
    wf_table_destroy(&t);
}

static void raw(const char *path, size_t n_cols)
{
    WfCsv t;
    WfError err = {0};
    int rc = wf_csv_read(path, n_cols, NULL, &t, &err);
    if (rc) {
        fuzz_check_error("csv raw", rc, &err);
        return;
    }
    fuzz_note("csv raw", 0, &err);
    check_rows(&t, n_cols);
    wf_csv_free(&t);
}

/* A corridor scenario whose inflow (elevation = 0) or elevation profile (elevation = 1) is the fuzzed CSV, read
 * by the scenario loader's own CSV path (relative to the scenario file). */
static void corridor_profile(int elevation)
{
    static const char inflow_yaml[] =
        "road: {type: corridor, length_m: 10000}\n"
        "time: {duration_s: 10}\n"
        "fleet:\n  classes: [{class: midsize_sedan, fraction: 1}]\n  drivers: [{model: idm, fraction: 1}]\n"
        "corridor:\n  inflow: {csv: fuzz.csv, arrivals: poisson}\n";
    static const char elevation_yaml[] =
        "road: {type: corridor, length_m: 10000, elevation: {csv: fuzz.csv}}\n"
        "time: {duration_s: 10}\n"
        "fleet:\n  classes: [{class: midsize_sedan, fraction: 1}]\n  drivers: [{model: idm, fraction: 1}]\n"
        "corridor:\n  inflow: {flow_vph: 1200}\n";
    const char *yaml = elevation ? elevation_yaml : inflow_yaml;
    const char *path = fuzz_write("corridor.yaml", (const uint8_t *)yaml, strlen(yaml));
    WfScenario *sc = NULL;
    WfError err = {0};
    int rc = wf_scenario_load(path, NULL, 0, &sc, &err);
    if (rc) {
        fuzz_check_error(elevation ? "corridor elevation" : "corridor inflow", rc, &err);
        return;
    }
    fuzz_note(elevation ? "corridor elevation" : "corridor inflow", 0, &err);
    const WfCorridorSpec *cs = sc->corridor;
    FUZZ_REQUIRE(cs != NULL, "not a corridor");
    for (size_t i = 0; i < cs->n_grade; i++) {
        FUZZ_REQUIRE(cs->grade_x_m[i] >= 0 && cs->grade_x_m[i] <= 10000, "grade x %g", cs->grade_x_m[i]);
        FUZZ_REQUIRE(i == 0 || cs->grade_x_m[i] > cs->grade_x_m[i - 1], "grade x not increasing at %zu", i);
        FUZZ_REQUIRE(fabs(cs->grade_rad[i]) <= 0.2, "grade %g rad", cs->grade_rad[i]);
    }
    const WfProfile *p = &cs->inflow_vph;
    FUZZ_REQUIRE(p->n >= 1, "empty inflow profile");
    for (size_t i = 0; i < p->n; i++) {
        FUZZ_REQUIRE(isfinite(p->t[i]) && (i == 0 || p->t[i] > p->t[i - 1]), "inflow t[%zu] = %g", i, p->t[i]);
        FUZZ_REQUIRE(isfinite(p->y[i]) && p->y[i] >= 0, "inflow[%zu] = %g veh/h", i, p->y[i]);
        FUZZ_REQUIRE(isfinite(p->cum[i]), "inflow integral[%zu] = %g", i, p->cum[i]);
    }
    wf_scenario_destroy(&sc);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    int mode = data[0] % 7;
    const char *path = fuzz_write("fuzz.csv", data + 1, size - 1);
    switch (mode) {
    case 0: grade(path); break;
    case 1: energy(path); break;
    case 2: cycle(path); break;
    case 3: table(path); break;
    case 4: raw(path, 1 + (size > 1 ? data[1] % 5 : 0)); break;
    case 5: corridor_profile(0); break;
    default: corridor_profile(1); break;
    }
    return 0;
}
