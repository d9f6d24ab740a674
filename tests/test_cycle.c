/* Drive cycles: synthetic traces against fuel and distance computed here from the model's formulas (issue 3's
 * ten steps, written again below), the shipped cycles against the published durations and distances of the
 * sources table, input errors, cycle names, and the validation protocol run through `wavefuel cycle
 * --protocol` with tabulated classes sampled from each shipped explicit class (fuel within 0.5 %). */
#include <dirent.h>
#include <hdf5.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "wavefuel/cycle.h"
#include "wavefuel/spline.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/vehicle.h"
#include "wf_test.h"

static char tmpdir[256];
static const char *data_dir = WF_REPO_DIR "/../shared/data";

static const char *tpath(const char *name)
{
    static char buf[8][512];
    static int k;
    k = (k + 1) % 8;
    snprintf(buf[k], sizeof buf[k], "%s/%s", tmpdir, name);
    return buf[k];
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        exit(1);
    }
    fputs(text, f);
    fclose(f);
}

static int have_data(void)
{
    char p[600];
    snprintf(p, sizeof p, "%s/cycles/udds.csv", data_dir);
    return access(p, R_OK) == 0;
}

/* The explicit model from issue 3's evaluation order, in plain if/else (project off). */
static double ref_fuel(const WfCirclesParams *p, int heavy, double v, double a, double th)
{
    v = v > 0 ? v : 0;
    double P = p->p0 + p->p1 * v + p->p2 * v * v;
    double Q = p->q0 + p->q1 * (v > 1e-12 ? v : 1e-12);
    double ap = a > -P / (2 * Q) ? a : -P / (2 * Q);
    double f = p->c0 + p->c1 * v + p->c2 * v * v + p->c3 * v * v * v + p->p0 * a + p->p1 * a * v + p->p2 * a * v * v +
               p->q0 * ap * ap + p->q1 * ap * ap * v + p->z0 * th + p->z1 * th * v + p->z2 * th * v * v;
    if (heavy) {
        double lb = p->h0 + p->h1 * v;
        if (f < lb) f = lb;
    } else {
        double lb = v <= p->v_c ? p->beta : 0.0;
        if (f < lb) f = lb;
        if (v > p->v_c && a <= p->a0 + p->a1 * v + p->a2 * th + p->a3 * v * v + p->a4 * v * th) f = 0;
    }
    if (v < 0.1 && fabs(a) < 0.01) f = p->f_idle;
    return f;
}

static double ref_a_max(const WfCirclesParams *p, double v, double th)
{
    double vs = v > 1e-12 ? v : 1e-12;
    double lim = p->b2 / vs - p->b3 * v * v;
    double gr = p->b5 + p->b6 * v;
    return (p->b1 < lim ? p->b1 : lim) - (p->b4 < gr ? p->b4 : gr) * th;
}

/* ---- Synthetic cycles ------------------------------------------------------------------------------------ */

static void test_constant_speed(void)
{
    WfVehicleClass *all = NULL;
    size_t n = 0;
    WfError err = {0};
    CHECK(wf_vehicle_list(&all, &n, &err) == 0 && n >= 6, "%s (%zu classes)", err.msg, n);
    /* Uneven steps on purpose: t = 0, 0.5, 1.7, 2, 4.5, 10 s. */
    const double t[] = {0, 0.5, 1.7, 2.0, 4.5, 10.0};
    const double T = 10.0;
    const double speeds[] = {0.0, 3.0, 5.07, 12.0, 25.0, 33.0};
    const double grades[] = {-0.03, 0.0, 0.02};
    int checked = 0, n_circles = 0;
    size_t n_schemes;
    const WfCycleScheme *schemes = wf_cycle_schemes(&n_schemes);
    for (size_t c = 0; c < n; c++) {
        if (all[c].model != &wf_energy_circles) continue;
        n_circles++;
        const WfCirclesParams *p = all[c].params;
        int heavy = all[c].duty == WF_DUTY_HEAVY;
        double density = (heavy ? 3217.0 : 2839.0) / 3.785411784; /* g/L: the release's g per US gallon */
        for (size_t s = 0; s < sizeof speeds / sizeof speeds[0]; s++)
            for (size_t g = 0; g < 3; g++) {
              for (size_t k = 0; k < n_schemes; k++) {
                double v[6];
                for (int i = 0; i < 6; i++) v[i] = speeds[s];
                WfCycle cy;
                WfCycleSamples smp;
                WfCycleRun r;
                CHECK(wf_cycle_from_arrays("const", 6, t, v, &cy, &err) == 0, "%s", err.msg);
                /* Every scheme: a spline through equal speeds is that speed (not-a-knot reproduces cubics). */
                CHECK(wf_cycle_samples(&cy, &schemes[k], &smp, &err) == 0, "%s", err.msg);
                CHECK(wf_cycle_run(&cy, &smp, &all[c], grades[g], 0, &r, &err) == 0, "%s", err.msg);
                for (size_t i = 0; i < smp.n; i++) CHECK(fabs(smp.a_mps2[i]) < 1e-12, "%s: a[%zu] = %g",
                                                         schemes[k].name, i, smp.a_mps2[i]);
                double f = ref_fuel(p, heavy, speeds[s], 0.0, grades[g]);
                CHECK_REL(r.fuel_g, f * T, 1e-12);
                CHECK_REL(r.distance_m, speeds[s] * T, 1e-12);
                CHECK(r.duration_s == T, "duration %g", r.duration_s);
                /* a = 0 is infeasible exactly when a_max(v, theta) < 0 (a steep grade for a truck). */
                double share = ref_a_max(p, speeds[s], grades[g]) < 0 ? 1.0 : 0.0;
                CHECK_ABS(r.infeasible_s, share * T, 1e-12);
                if (speeds[s] > 0 && f > 0) {
                    double litres = f * T / density;
                    CHECK_REL(r.l_per_100km, litres / (speeds[s] * T / 1e5), 1e-12);
                    CHECK_REL(r.mpg, (speeds[s] * T / 1609.344) / (litres / 3.785411784), 1e-12);
                }
                wf_cycle_run_free(&r);
                wf_cycle_samples_free(&smp);
                wf_cycle_free(&cy);
                checked++;
              }
            }
    }
    /* Every CIRCLES class the search path lists (the shipped six, and any class added to vehicles/ or
     * $WAVEFUEL_VEHICLES: tests/t_inventory.sh adds one) x 6 speeds x 3 grades x every scheme. */
    CHECK(n_circles >= 1 && checked == n_circles * 6 * 3 * (int)n_schemes, "ran %d synthetic cycles for %d classes",
          checked, n_circles);
    for (size_t c = 0; c < n; c++) wf_vehicle_free(&all[c]);
    free(all);
}

static void test_forward_difference(void)
{
    /* t = 0, 1, 3, 3.5, 6; v = 0, 2, 2, 5, 1: a = 2, 0, 6, -1.6, 0 (last); dt = 1, 2, 0.5, 2.5, 0. */
    const double t[] = {0, 1, 3, 3.5, 6}, v[] = {0, 2, 2, 5, 1};
    const double a_want[] = {2, 0, 6, -1.6, 0}, dt_want[] = {1, 2, 0.5, 2.5, 0};
    WfError err = {0};
    WfCycle cy;
    CHECK(wf_cycle_from_arrays("ramp", 5, t, v, &cy, &err) == 0, "%s", err.msg);
    for (int i = 0; i < 5; i++) {
        CHECK_ABS(cy.a_mps2[i], a_want[i], 1e-15);
        CHECK(cy.dt_s[i] == dt_want[i], "dt[%d]", i);
    }
    CHECK(wf_cycle_distance_m(&cy) == 0 * 1 + 2 * 2 + 2 * 0.5 + 5 * 2.5, "distance %.17g", wf_cycle_distance_m(&cy));
    WfVehicleClass vc;
    CHECK(wf_vehicle_find("midsize_pickup", &vc, &err) == 0, "%s", err.msg);
    WfCycleRun r;
    WfCycleSamples smp;
    CHECK(wf_cycle_samples(&cy, wf_cycle_scheme_find("first-order", &err), &smp, &err) == 0, "%s", err.msg);
    CHECK(wf_cycle_run(&cy, &smp, &vc, 0.01, 0, &r, &err) == 0, "%s", err.msg);
    double want = 0, infeasible = 0;
    for (int i = 0; i < 5; i++) {
        want += ref_fuel(vc.params, 0, v[i], a_want[i], 0.01) * dt_want[i];
        if (a_want[i] > ref_a_max(vc.params, v[i], 0.01)) infeasible += dt_want[i];
    }
    CHECK_REL(r.fuel_g, want, 1e-12);
    CHECK(infeasible == 0.5 && r.infeasible_s == infeasible, "6 m/s^2 at 2 m/s is infeasible for 0.5 s (got %g)",
          r.infeasible_s);
    wf_cycle_run_free(&r);
    wf_cycle_samples_free(&smp);
    wf_vehicle_free(&vc);
    wf_cycle_free(&cy);
}

/* ---- The not-a-knot spline and the schemes ---------------------------------------------------------------- */

/* A not-a-knot spline reproduces any cubic exactly (its two end conditions hold for it), 3 knots the parabola and
 * 2 the line: values and derivatives against the polynomials, on uneven knots and between them. */
static void test_spline_reproduces_polynomials(void)
{
    const double x[] = {-1.0, 0.3, 0.7, 2.0, 2.2, 4.5, 5.0};
    const double coef[3][4] = {{1.5, -2.0, 0.0, 0.0}, {0.5, 1.0, -0.75, 0.0}, {2.0, -1.0, 0.5, 0.25}};
    const size_t knots[3] = {2, 3, 7}; /* line, parabola, cubic */
    WfError err = {0};
    for (int k = 0; k < 3; k++) {
        const double *c = coef[k];
        double y[7];
        for (size_t i = 0; i < knots[k]; i++) y[i] = c[0] + x[i] * (c[1] + x[i] * (c[2] + x[i] * c[3]));
        WfSpline sp;
        CHECK(wf_spline_fit(knots[k], x, y, &sp, &err) == 0, "%s", err.msg);
        size_t hint = 0;
        for (double t = x[0]; t <= x[knots[k] - 1]; t += 0.01) {
            hint = wf_spline_interval(&sp, t, hint);
            double dy, v = wf_spline_eval(&sp, hint, t, &dy);
            double want = c[0] + t * (c[1] + t * (c[2] + t * c[3])), dwant = c[1] + t * (2 * c[2] + 3 * t * c[3]);
            CHECK_ABS(v, want, 1e-12);
            CHECK_ABS(dy, dwant, 1e-11);
        }
        wf_spline_free(&sp);
    }
    const double bad_x[] = {0.0, 1.0, 1.0};
    WfSpline sp;
    CHECK(wf_spline_fit(3, bad_x, coef[0], &sp, &err) == WF_EINPUT && strstr(err.msg, "x[2] = 1 after 1"), "%s",
          err.msg);
}

/* The scheme table: names unique and found, unknown names list them; the release scheme's samples on a trace with
 * uneven steps and a duration that is not a whole number of 0.1 s: 10 Hz times plus the end, trapezoid weights
 * summing to the duration, central differences of its speeds; the speed is 0 between two zero samples. */
static void test_scheme_table(void)
{
    size_t n;
    const WfCycleScheme *sc = wf_cycle_schemes(&n);
    WfError err = {0};
    for (size_t i = 0; i < n; i++) {
        CHECK(wf_cycle_scheme_find(sc[i].name, &err) == &sc[i], "%s", sc[i].name);
        for (size_t j = 0; j < i; j++) CHECK(strcmp(sc[i].name, sc[j].name), "scheme %s twice", sc[i].name);
    }
    CHECK(wf_cycle_scheme_find("central", &err) == NULL && err.code == WF_EINPUT && strstr(err.msg, sc[0].name) &&
              strstr(err.msg, sc[n - 1].name),
          "%s", err.msg);
    const double t[] = {0.0, 0.7, 1.9, 3.0, 4.0, 5.25}, v[] = {2.0, 3.0, 0.0, 0.0, 1.0, 4.0};
    WfCycle cy;
    WfCycleSamples s;
    CHECK(wf_cycle_from_arrays("uneven", 6, t, v, &cy, &err) == 0, "%s", err.msg);
    CHECK(wf_cycle_samples(&cy, wf_cycle_scheme_find("release", &err), &s, &err) == 0, "%s", err.msg);
    CHECK(s.n == 54 && s.t_s[52] == 5.2 && s.t_s[53] == 5.25, "%zu samples, ends %g %g", s.n, s.t_s[s.n - 2],
          s.t_s[s.n - 1]);
    double w = 0;
    for (size_t i = 0; i < s.n; i++) {
        w += s.w_s[i];
        if (s.t_s[i] > 1.9 && s.t_s[i] < 3.0) CHECK(s.v_mps[i] == 0.0, "standing still at %g s: %g", s.t_s[i],
                                                     s.v_mps[i]);
        CHECK(s.v_mps[i] >= 0.0, "v(%g) = %g", s.t_s[i], s.v_mps[i]);
        size_t hi = i + 1 < s.n ? i + 1 : i, lo = i ? i - 1 : 0;
        CHECK(s.a_mps2[i] == (s.v_mps[hi] - s.v_mps[lo]) / (s.t_s[hi] - s.t_s[lo]), "a at %g", s.t_s[i]);
    }
    CHECK_REL(w, 5.25, 1e-14);
    CHECK(s.v_mps[0] == 2.0 && s.v_mps[7] == 3.0 && fabs(s.v_mps[s.n - 1] - 4.0) < 1e-14, "knot values");
    wf_cycle_samples_free(&s);
    wf_cycle_free(&cy);
}

/* ---- The shipped cycles against the sources table ------------------------------------------------------- */

static void test_shipped_cycles(void)
{
    if (!have_data()) {
        printf("SKIP test_shipped_cycles: no %s/cycles\n", data_dir);
        return;
    }
    /* Published duration (s) and distance (m) as in the sources table (EPA, UNECE GTR 15, CARB/WVU; miles
     * times 1609.344), and the table's own trapezoid distance of each file. HHDDT65 has no official figure:
     * its 10 Hz source's 26.605 mi stands in. */
    static const struct {
        const char *name;
        double      duration_s, published_m, readme_m;
    } ref[] = {
        {"udds", 1369, 7.45 * 1609.344, 11990.2},
        {"hwfet", 765, 10.26 * 1609.344, 16506.5},
        {"us06", 600, 8.01 * 1609.344, 12887.6},
        {"wltc3", 1800, 23266, 23266.3},
        {"hhddt_cruise", 2083, 23.1 * 1609.344, 37131.8},
        {"hhddt_transient", 668, 2.85 * 1609.344, 4573.7},
        {"hhddt_h65", 1900, 26.605 * 1609.344, 42837.3},
    };
    for (size_t i = 0; i < sizeof ref / sizeof ref[0]; i++) {
        char path[600];
        WfError err = {0};
        WfCycle cy;
        CHECK(wf_cycle_resolve(ref[i].name, data_dir, path, sizeof path, &err) == 0, "%s", err.msg);
        if (wf_cycle_load(path, &cy, &err)) {
            CHECK(0, "%s", err.msg);
            continue;
        }
        double d = wf_cycle_distance_m(&cy), trap = 0;
        for (size_t k = 0; k + 1 < cy.n; k++)
            trap += 0.5 * (cy.v_mps[k] + cy.v_mps[k + 1]) * (cy.t_s[k + 1] - cy.t_s[k]);
        CHECK_REL(wf_cycle_duration_s(&cy), ref[i].duration_s, 0.005);
        CHECK_REL(d, ref[i].published_m, 0.005);
        /* sum v dt equals the trapezoid rule here: even steps and zero speed at both ends. */
        CHECK(cy.v_mps[0] == 0 && cy.v_mps[cy.n - 1] == 0, "%s starts and ends at rest", ref[i].name);
        CHECK_REL(d, trap, 1e-12);
        CHECK_ABS(d, ref[i].readme_m, 0.05 + 1e-9);
        printf("  %-16s %5.0f s  %9.1f m  (published %9.1f m, %+.3f %%)\n", ref[i].name, wf_cycle_duration_s(&cy), d,
               ref[i].published_m, 100 * (d / ref[i].published_m - 1));
        wf_cycle_free(&cy);
    }
    char path[600];
    WfError err = {0};
    CHECK(wf_cycle_resolve("hhddt_high", data_dir, path, sizeof path, &err) == WF_EINPUT &&
              strstr(err.msg, "hhddt_cruise") && strstr(err.msg, "not found"),
          "HHDDT high speed is absent, the message lists what exists: %s", err.msg);
}

/* ---- Input errors and names -------------------------------------------------------------------------------- */

static void expect_cycle_error(const char *name, const char *text, const char *want)
{
    write_text(tpath(name), text);
    WfError err = {0};
    WfCycle cy;
    int rc = wf_cycle_load(tpath(name), &cy, &err);
    CHECK(rc == WF_EINPUT && strstr(err.msg, want) && strstr(err.msg, name), "%s: rc %d: %s", name, rc, err.msg);
    CHECK(cy.t_s == NULL, "%s: nothing allocated on failure", name);
}

static void test_cycle_errors(void)
{
    expect_cycle_error("back.csv", "time_s,speed_mps\n0,0\n1,1\n1,2\n", ":4: field 1 (time_s) must increase strictly");
    expect_cycle_error("neg.csv", "0,0\n1,-0.5\n2,0\n", ":2: field 2 (speed_mps) must be in [0, 150] m/s");
    expect_cycle_error("fast.csv", "0,0\n1,1e308\n2,0\n", ":2: field 2 (speed_mps) must be in [0, 150] m/s");
    expect_cycle_error("one.csv", "time_s,speed_mps\n0,0\n", "at least 2 samples");
    expect_cycle_error("hdr.csv", "t,v\n0,0\n1,0\n", "header column 1 is 't', expected 'time_s'");
    expect_cycle_error("nan.csv", "0,0\n1,nan\n", ":2: field 2 (speed_mps): expected a finite number");
    /* A header is optional; uneven steps are fine. */
    write_text(tpath("ok.csv"), "# comment\n0,0\n0.1,1\n2.6,1\n");
    WfError err = {0};
    WfCycle cy;
    CHECK(wf_cycle_load(tpath("ok.csv"), &cy, &err) == 0 && cy.n == 3 && !strcmp(cy.name, "ok"), "%s", err.msg);
    wf_cycle_free(&cy);
}

static void test_names_and_dirs(void)
{
    char out[700];
    WfError err = {0};
    int found;
    CHECK(wf_cycle_resolve("x/y.csv", "", out, sizeof out, &err) == 0 && !strcmp(out, "x/y.csv"), "path kept");
    CHECK(wf_cycle_resolve("mine.csv", "", out, sizeof out, &err) == 0 && !strcmp(out, "mine.csv"), "a .csv is a path");
    CHECK(wf_cycle_resolve("udds", "", out, sizeof out, &err) == WF_EINPUT && strstr(err.msg, "--cycles"), "%s",
          err.msg);
    char dir[600];
    snprintf(dir, sizeof dir, "%s/data", tmpdir);
    char cdir[700];
    snprintf(cdir, sizeof cdir, "%s/cycles", dir);
    CHECK(mkdir(dir, 0755) == 0 && mkdir(cdir, 0755) == 0, "mkdir");
    char f[800];
    snprintf(f, sizeof f, "%s/flat.csv", cdir);
    write_text(f, "0,10\n60,10\n");
    CHECK(wf_cycle_resolve("flat", dir, out, sizeof out, &err) == 0 && !strcmp(out, f), "%s", err.msg);
    CHECK(wf_cycle_resolve("hill", dir, out, sizeof out, &err) == WF_EINPUT && strstr(err.msg, "(cycles there: flat)"),
          "%s", err.msg);
    /* A given directory wins over the default (the CLI's --cycles over $WAVEFUEL_DATA: tests/t_cycle_cli.sh); a
     * missing one is an error naming where it came from; no default, none found. */
    CHECK(wf_cycle_data_dir(dir, "$WAVEFUEL_DATA", tmpdir, out, sizeof out, &found, &err) == 0 && found &&
              !strcmp(out, dir),
          "given: %s", out);
    CHECK(wf_cycle_data_dir("/nonexistent/dir", "--cycles", tmpdir, out, sizeof out, &found, &err) == WF_EINPUT &&
              strstr(err.msg, "/nonexistent/dir (--cycles)"),
          "%s", err.msg);
    CHECK(wf_cycle_data_dir(NULL, NULL, NULL, out, sizeof out, &found, &err) == 0 && !found && !out[0], "none: %s", out);
    CHECK(wf_cycle_data_dir("", NULL, "/nonexistent/dir", out, sizeof out, &found, &err) == 0 && !found,
          "missing default: %s", out);
    if (have_data()) {
        CHECK(wf_cycle_data_dir(NULL, NULL, data_dir, out, sizeof out, &found, &err) == 0 && found &&
                  strstr(out, "/shared/data"),
              "default: %s", out);
    }
}

static void test_protocol_grids(void)
{
    double g[16];
    size_t n = wf_protocol_grades(WF_DUTY_LIGHT, g, 16), nc;
    CHECK(n == 7 && g[0] == -0.03 && g[3] == 0.0 && g[6] == 0.03 && g[4] == 0.01, "light grades");
    n = wf_protocol_grades(WF_DUTY_HEAVY, g, 16);
    CHECK(n == 5 && g[0] == -0.02 && g[4] == 0.02, "heavy grades");
    const char *const *c = wf_protocol_cycles(WF_DUTY_LIGHT, &nc);
    CHECK(nc == 4 && !strcmp(c[0], "udds") && !strcmp(c[3], "wltc3"), "light cycles");
    c = wf_protocol_cycles(WF_DUTY_HEAVY, &nc);
    CHECK(nc == 3 && !strcmp(c[0], "hhddt_cruise"), "heavy cycles (HHDDT high speed has no public file)");
}

/* The class files of the repository's vehicles/ directory, read here with opendir (not through the library's
 * search path), so that the listing the library returns is checked against the directory. */
static int count_repo_vehicles(void)
{
    DIR *d = opendir(WF_REPO_DIR "/vehicles");
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d))) {
        size_t len = strlen(e->d_name);
        n += len > 5 && !strcmp(e->d_name + len - 5, ".yaml");
    }
    if (d) closedir(d);
    return n;
}

static int in_repo_vehicles(const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/vehicles/%s.yaml", WF_REPO_DIR, name);
    return access(path, R_OK) == 0;
}

/* ---- The protocol with tabulated twins ----------------------------------------------------------------------- */

/* A grid fine where the explicit model is discontinuous: speed every 0.1 m/s plus v_c and v_c + 1 mm/s (the
 * fuel cut and the lower bound switch there), acceleration every 0.005 m/s^2 over [-1.2, 0.1] (where the fuel
 * cut's boundary a_cut(v, theta) lies) and 0.05 elsewhere, and the protocol's grades. Speeds and
 * accelerations cover every sample of the cycles, so nothing is clamped. */
static size_t fill_axis(double *x, size_t n, double lo, double hi, double step, int include_hi)
{
    for (long i = 0;; i++) {
        double v = lo + (double)i * step;
        if (include_hi ? v > hi + 1e-9 : v > hi - 1e-9) break;
        x[n++] = v;
    }
    return n;
}

static int sample_class(const WfVehicleClass *vc, const char *path, WfError *err)
{
    static double v[600], a[800], th[8];
    const WfCirclesParams *p = vc->params;
    int light = vc->duty == WF_DUTY_LIGHT;
    size_t nv = fill_axis(v, 0, 0, light ? 37 : 30.5, 0.1, 1);
    if (light) {
        const double extra[2] = {p->v_c, p->v_c + 0.001};
        for (int j = 0; j < 2; j++) {
            size_t k = 0;
            while (k < nv && v[k] < extra[j] - 1e-9) k++;
            if (k < nv && fabs(v[k] - extra[j]) < 1e-9) continue; /* already a node */
            memmove(v + k + 1, v + k, (nv - k) * sizeof *v);
            v[k] = extra[j];
            nv++;
        }
    }
    size_t na = fill_axis(a, 0, light ? -3.2 : -2.9, -1.2, 0.05, 0);
    na = fill_axis(a, na, -1.2, 0.1, 0.005, 0);
    na = fill_axis(a, na, 0.1, light ? 3.8 : 2.1, 0.05, 1);
    size_t nt = wf_protocol_grades(vc->duty, th, 8);
    size_t n = nv * na * nt;
    double *fuel = malloc(n * sizeof *fuel);
    uint8_t *inf = malloc(n);
    WfTable *t = NULL;
    int rc = (!fuel || !inf) ? wf_err(err, WF_ESYS, "out of memory") : 0;
    for (size_t i = 0; i < nv && !rc; i++)
        for (size_t j = 0; j < na; j++)
            for (size_t k = 0; k < nt; k++) {
                uint8_t fl;
                size_t idx = (i * na + j) * nt + k;
                fuel[idx] = wf_circles_fuel(p, v[i], a[j], th[k], 0, &fl);
                inf[idx] = fl == WF_INFEASIBLE_ACCEL;
            }
    if (!rc) rc = wf_table_from_grid(nv, v, na, a, nt, th, fuel, inf, vc->name, &t, err);
    if (!rc) rc = wf_table_write_h5(t, path, 1, err);
    wf_table_destroy(&t);
    free(fuel);
    free(inf);
    return rc;
}

/* Element `index` (flat) of /CLS/summary/DATASET; dims[] gets its shape (1 or 2 dimensions; dims[1] = 1 for 1). */
static double read_summary(const char *h5, const char *cls, const char *dataset, size_t index, hsize_t dims[2])
{
    char name[256];
    snprintf(name, sizeof name, "/%s/summary/%s", cls, dataset);
    dims[0] = dims[1] = 1;
    hid_t f = H5Fopen(h5, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return NAN;
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    double out = NAN;
    if (d >= 0) {
        hid_t sp = H5Dget_space(d);
        if (H5Sget_simple_extent_ndims(sp) <= 2) {
            H5Sget_simple_extent_dims(sp, dims, NULL);
            double *buf = malloc(dims[0] * dims[1] * sizeof *buf);
            H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
            if (index < dims[0] * dims[1]) out = buf[index];
            free(buf);
        }
        H5Sclose(sp);
        H5Dclose(d);
    }
    H5Fclose(f);
    return out;
}

static double read_rel_diff(const char *h5, const char *cls, size_t row, size_t col, size_t *rows, size_t *cols)
{
    hsize_t dims[2];
    read_summary(h5, cls, "rel_diff", 0, dims);
    *rows = dims[0];
    *cols = dims[1];
    return col < dims[1] ? read_summary(h5, cls, "rel_diff", row * dims[1] + col, dims) : NAN;
}

static double read_h5_f64(const char *h5, const char *cls, const char *dataset, size_t index)
{
    hsize_t dims[2];
    return read_summary(h5, cls, dataset, index, dims);
}

static void test_protocol_tabulated_twins(void)
{
    if (!have_data()) {
        printf("SKIP test_protocol_tabulated_twins: no %s/cycles\n", data_dir);
        return;
    }
    WfVehicleClass *all = NULL;
    size_t n = 0;
    WfError err = {0};
    CHECK(wf_vehicle_list(&all, &n, &err) == 0, "%s", err.msg);
    const char *bin = getenv("WAVEFUEL_BIN");
    char cmd[8192];
    int used = snprintf(cmd, sizeof cmd, "%s%s cycle --protocol --no-project --cycles %s -o %s",
                        bin ? "" : WF_REPO_DIR "/", bin ? bin : "bin/wavefuel", data_dir, tpath("protocol.h5"));
    /* One section per class given, each with (cycles of its duty + ALL) rows of relative differences, one cell per
     * grade of its duty: counted from the protocol's definition for the classes the search path lists. */
    int n_classes = 0, want_rows = 0, want_cells = 0, shipped = 0;
    for (size_t c = 0; c < n; c++) {
        shipped += in_repo_vehicles(all[c].name);
        if (all[c].model != &wf_energy_circles) continue;
        size_t ncy;
        double grades_buf[16];
        wf_protocol_cycles(all[c].duty, &ncy);
        size_t ngr = wf_protocol_grades(all[c].duty, grades_buf, 16);
        want_rows += (int)ncy + 2;
        want_cells += ((int)ncy + 2) * (int)ngr;
        char h5[600];
        snprintf(h5, sizeof h5, "%s/%s.h5", tmpdir, all[c].name);
        CHECK(sample_class(&all[c], h5, &err) == 0, "%s", err.msg);
        used += snprintf(cmd + used, sizeof cmd - (size_t)used, " --class %s --table %s=%s", all[c].name,
                         all[c].name, h5);
        n_classes++;
    }
    CHECK(n_classes >= 1 && shipped == count_repo_vehicles(), "%d CIRCLES classes listed; %d of the %d class files "
          "of vehicles/", n_classes, shipped, count_repo_vehicles());
    FILE *p = popen(cmd, "r");
    CHECK(p != NULL, "popen %s", cmd);
    if (!p) return;
    /* Every "rel. diff" row of the Markdown (per cycle, and the two ALL rows): all within 0.5 %. */
    char line[4096];
    int rows = 0, cells = 0, sections = 0;
    double worst = 0;
    while (fgets(line, sizeof line, p)) {
        if (!strncmp(line, "## ", 3)) sections++;
        char *s = strstr(line, "| rel. diff");
        if (!s) continue;
        rows++;
        s = strchr(s + 1, '|') + 1;
        for (;;) {
            char *end;
            double x = strtod(s, &end);
            if (end == s) break;
            cells++;
            if (fabs(x) > worst) worst = fabs(x);
            CHECK(fabs(x) < 0.5, "relative difference %g %% in: %s", x, line);
            s = strchr(end, '|');
            if (!s) break;
            s++;
        }
    }
    int status = pclose(p);
    CHECK(status == 0, "%s exited with %d", cmd, status);
    CHECK(sections == n_classes, "one section per class (%d sections, %d classes)", sections, n_classes);
    CHECK(rows == want_rows && cells == want_cells, "%d rows, %d cells of relative differences (want %d, %d)", rows,
          cells, want_rows, want_cells);
    printf("  largest |explicit - tabulated| / tabulated over the protocol: %.3f %%\n", worst);
    /* The HDF5 summary holds the same column, and it is (explicit - tabulated) / tabulated of runs made here. */
    for (size_t c = 0; c < n; c++) {
        if (strcmp(all[c].name, "midsize_suv") && strcmp(all[c].name, "class8_tractor")) continue;
        char h5[600];
        snprintf(h5, sizeof h5, "%s/%s.h5", tmpdir, all[c].name);
        WfVehicleClass twin;
        CHECK(wf_tabulated_class(&all[c], h5, &twin, &err) == 0, "%s", err.msg);
        size_t nc;
        const char *const *names = wf_protocol_cycles(all[c].duty, &nc);
        double grades[8];
        size_t ng = wf_protocol_grades(all[c].duty, grades, 8);
        double tot_e[8] = {0}, tot_t[8] = {0}, mean[8] = {0}, total_s = 0;
        size_t n_schemes;
        const WfCycleScheme *dflt = wf_cycle_schemes(&n_schemes); /* the default: the table's first row */
        for (size_t k = 0; k < nc; k++) {
            char path[700];
            WfCycle cy;
            WfCycleSamples smp;
            CHECK(wf_cycle_resolve(names[k], data_dir, path, sizeof path, &err) == 0 &&
                      wf_cycle_load(path, &cy, &err) == 0 && wf_cycle_samples(&cy, dflt, &smp, &err) == 0,
                  "%s", err.msg);
            /* The duration from the file's own first and last times, the weight of the paper's ALL rows. */
            double dur_s = cy.t_s[cy.n - 1] - cy.t_s[0];
            total_s += dur_s;
            for (size_t g = 0; g < ng; g++) {
                WfCycleRun re, rt;
                wf_cycle_run(&cy, &smp, &all[c], grades[g], 0, &re, &err);
                wf_cycle_run(&cy, &smp, &twin, grades[g], 0, &rt, &err);
                size_t rows_h5 = 0, cols_h5 = 0;
                double h5rel = read_rel_diff(tpath("protocol.h5"), all[c].name, k, g, &rows_h5, &cols_h5);
                CHECK(rows_h5 == nc + 1 && cols_h5 == ng, "summary shape %zu x %zu", rows_h5, cols_h5);
                CHECK_REL(h5rel, (re.fuel_g - rt.fuel_g) / rt.fuel_g, 1e-12);
                tot_e[g] += re.fuel_g;
                tot_t[g] += rt.fuel_g;
                mean[g] += dur_s * (re.fuel_g - rt.fuel_g) / rt.fuel_g;
                wf_cycle_run_free(&re);
                wf_cycle_run_free(&rt);
            }
            wf_cycle_samples_free(&smp);
            wf_cycle_free(&cy);
        }
        /* ALL: the duration-weighted mean of the cycles' relative differences (the paper's rule), and apart from it
         * total over total. */
        for (size_t g = 0; g < ng; g++) {
            size_t r1, c1;
            double all_rel = read_rel_diff(tpath("protocol.h5"), all[c].name, nc, g, &r1, &c1);
            CHECK_REL(all_rel, mean[g] / total_s, 1e-12);
            double total_rel = read_h5_f64(tpath("protocol.h5"), all[c].name, "rel_diff_total", g);
            CHECK_REL(total_rel, (tot_e[g] - tot_t[g]) / tot_t[g], 1e-12);
        }
        wf_vehicle_free(&twin);
    }
    for (size_t c = 0; c < n; c++) wf_vehicle_free(&all[c]);
    free(all);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wf_test_cycle_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    RUN(test_constant_speed);
    RUN(test_forward_difference);
    RUN(test_spline_reproduces_polynomials);
    RUN(test_scheme_table);
    RUN(test_shipped_cycles);
    RUN(test_cycle_errors);
    RUN(test_names_and_dirs);
    RUN(test_protocol_grids);
    RUN(test_protocol_tabulated_twins);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_EXIT();
}
