/* Tabulated energy model: CSV import (grid detection, malformed tables), HDF5 round trip and checksum, and the
 * evaluation semantics compared with an independent trilinear / bilinear interpolation written here, a smooth
 * function sampled on the release's grid (interpolation error bound), the release's 63-row sample, and
 * vehicle classes that name a table. */
#include <hdf5.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "wavefuel/cycle.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/vehicle.h"
#include "wf_test.h"

static char tmpdir[256];

static uint64_t rng_state = 0x9e3779b97f4a7c15ULL;
static double urand(void) /* deterministic uniform [0, 1): tests do not depend on the time */
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(rng_state >> 11) * 0x1.0p-53;
}

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

/* ---- A small uneven grid with arbitrary values, and an independent interpolation of it ---------------- */

enum { NV = 4, NA = 5, NT = 3 };
static const double GV[NV] = {0, 0.5, 1.5, 3};
static const double GA[NA] = {-1, -0.2, 0, 0.7, 2};
static const double GT[NT] = {-0.03, 0, 0.02};
static double GF[NV][NA][NT];
static int GI[NV][NA][NT];

/* Values: arbitrary in [0, 5); infeasible where a is high for the speed and grade (so every column has a
 * feasible node), plus a stray infeasible node to exercise "largest feasible" rather than "first". */
static void make_small(void)
{
    for (int i = 0; i < NV; i++)
        for (int j = 0; j < NA; j++)
            for (int k = 0; k < NT; k++) {
                GF[i][j][k] = 5 * urand();
                GI[i][j][k] = GA[j] > 1.0 - 0.2 * GV[i] - 10 * GT[k];
            }
    GI[1][1][1] = 1; /* infeasible below a feasible node: the column's largest feasible is still higher */
}

/* Writes the small grid in the release's format, rows shuffled. */
static void write_small_csv(const char *path)
{
    int order[NV * NA * NT];
    for (int i = 0; i < NV * NA * NT; i++) order[i] = i;
    for (int i = NV * NA * NT - 1; i > 0; i--) {
        int j = (int)(urand() * (i + 1)), t = order[i];
        order[i] = order[j];
        order[j] = t;
    }
    FILE *f = fopen(path, "w");
    fprintf(f, "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n");
    for (int r = 0; r < NV * NA * NT; r++) {
        int i = order[r] / (NA * NT), j = (order[r] / NT) % NA, k = order[r] % NT;
        fprintf(f, "%.17g,%.17g,%.17g,%.17g,%d\n", GV[i], GA[j], GT[k], GF[i][j][k], GI[i][j][k]);
    }
    fclose(f);
}

/* Linear search for the cell and weight of x on nodes g[0..n-1] (clamped). */
static void cell(const double *g, int n, double x, int *k, double *w)
{
    if (x <= g[0]) {
        *k = 0;
        *w = 0;
        return;
    }
    if (x >= g[n - 1]) {
        *k = n - 2;
        *w = 1;
        return;
    }
    int i = 0;
    while (!(g[i] <= x && x < g[i + 1])) i++;
    *k = i;
    *w = (x - g[i]) / (g[i + 1] - g[i]);
}

/* Trilinear interpolation as the sum over the 8 corners of w_v w_a w_t value. */
static double ref_tri(double vals(int, int, int), double v, double a, double th)
{
    int iv, ia, it;
    double wv, wa, wt, s = 0;
    cell(GV, NV, v, &iv, &wv);
    cell(GA, NA, a, &ia, &wa);
    cell(GT, NT, th, &it, &wt);
    for (int dv = 0; dv < 2; dv++)
        for (int da = 0; da < 2; da++)
            for (int dt = 0; dt < 2; dt++)
                s += (dv ? wv : 1 - wv) * (da ? wa : 1 - wa) * (dt ? wt : 1 - wt) * vals(iv + dv, ia + da, it + dt);
    return s;
}
static double val_fuel(int i, int j, int k) { return GF[i][j][k]; }
static double val_inf(int i, int j, int k) { return GI[i][j][k]; }
static double col_amax(int i, int k)
{
    for (int j = NA - 1; j >= 0; j--)
        if (!GI[i][j][k]) return GA[j];
    return GA[0];
}
static double ref_amax(double v, double th)
{
    int iv, it;
    double wv, wt, s = 0;
    cell(GV, NV, v < 0 ? 0 : v, &iv, &wv);
    cell(GT, NT, th, &it, &wt);
    for (int dv = 0; dv < 2; dv++)
        for (int dt = 0; dt < 2; dt++) s += (dv ? wv : 1 - wv) * (dt ? wt : 1 - wt) * col_amax(iv + dv, it + dt);
    return s;
}

static WfTable *small_table(void)
{
    WfTable *t = NULL;
    WfError err = {0};
    write_small_csv(tpath("small.csv"));
    int rc = wf_table_read_csv(tpath("small.csv"), &t, &err);
    CHECK(rc == 0, "%s", err.msg);
    return t;
}

static void test_nodes_exact(void)
{
    WfTable *t = small_table();
    if (!t) return;
    CHECK(t->v.n == NV && t->a.n == NA && t->theta.n == NT, "grid %zu x %zu x %zu", t->v.n, t->a.n, t->theta.n);
    WfError err = {0};
    CHECK(wf_table_write_h5(t, tpath("small.h5"), 0, &err) == 0, "%s", err.msg);
    WfTable *back = NULL;
    CHECK(wf_table_load_h5(tpath("small.h5"), &back, &err) == 0, "%s", err.msg);
    if (!back) return;
    CHECK(back->data_fnv1a64 == t->data_fnv1a64, "checksums differ after the round trip");
    CHECK(back->source_fnv1a64 == t->source_fnv1a64 && !strcmp(back->source, t->source), "source lost");
    for (int i = 0; i < NV; i++)
        for (int j = 0; j < NA; j++)
            for (int k = 0; k < NT; k++) {
                uint8_t fl;
                int out;
                /* Exact equality: a node's value must come back bit for bit, before and after HDF5. */
                double f1 = wf_table_fuel(t, GV[i], GA[j], GT[k], 0, &fl, &out);
                double f2 = wf_table_fuel(back, GV[i], GA[j], GT[k], 0, NULL, NULL);
                CHECK(f1 == GF[i][j][k] && f2 == GF[i][j][k], "node (%d,%d,%d): %.17g / %.17g want %.17g", i, j, k, f1,
                      f2, GF[i][j][k]);
                CHECK(fl == GI[i][j][k], "node (%d,%d,%d): flag %d want %d", i, j, k, fl, GI[i][j][k]);
                CHECK(out == 0, "a node is inside the grid");
            }
    for (int i = 0; i < NV; i++)
        for (int k = 0; k < NT; k++) CHECK(wf_table_a_max(back, GV[i], GT[k]) == col_amax(i, k), "a_max (%d,%d)", i, k);
    wf_table_destroy(&t);
    wf_table_destroy(&back);
    CHECK(t == NULL && back == NULL, "destroy clears the pointer");
}

static void test_between_nodes(void)
{
    WfTable *t = small_table();
    if (!t) return;
    enum { N = 4000 };
    double v[N], a[N], th[N], fuel[N];
    uint8_t flag[N];
    for (int i = 0; i < N; i++) {
        v[i] = 3 * urand();
        a[i] = -1 + 3 * urand();
        th[i] = -0.03 + 0.05 * urand();
    }
    wf_table_eval(t, N, v, a, th, 0, fuel, flag);
    for (int i = 0; i < N; i++) {
        CHECK_ABS(fuel[i], ref_tri(val_fuel, v[i], a[i], th[i]), 1e-12);
        int want = ref_tri(val_inf, v[i], a[i], th[i]) != 0.0;
        CHECK(flag[i] == want, "point %d: flag %d want %d", i, flag[i], want);
        CHECK_ABS(wf_table_a_max(t, v[i], th[i]), ref_amax(v[i], th[i]), 1e-12);
    }
    /* Projection: a <- min(a, a_max(v, theta)) before the fuel interpolation; the flag keeps the original a. */
    wf_table_eval(t, N, v, a, th, 1, fuel, flag);
    int projected = 0;
    for (int i = 0; i < N; i++) {
        double am = ref_amax(v[i], th[i]), au = a[i] < am ? a[i] : am;
        projected += a[i] > am;
        CHECK_ABS(fuel[i], ref_tri(val_fuel, v[i], au, th[i]), 1e-12);
        CHECK(flag[i] == (ref_tri(val_inf, v[i], a[i], th[i]) != 0.0), "projected point %d: flag", i);
    }
    CHECK(projected > N / 10, "the sample should exercise the projection (%d of %d)", projected, N);
    /* Negative speed: flag 2, evaluated at v = 0. */
    uint8_t fl;
    double f = wf_table_fuel(t, -2.0, 0.3, 0.01, 0, &fl, NULL);
    CHECK(fl == WF_NEGATIVE_SPEED, "flag %d", fl);
    CHECK_ABS(f, ref_tri(val_fuel, 0.0, 0.3, 0.01), 1e-12);
    wf_table_destroy(&t);
}

static void test_outside_clamped_and_counted(void)
{
    WfTable *t = small_table();
    if (!t) return;
    double v[] = {1.0, 7.0, 1.0, 1.0, 1.0, -1.0, 1.0};
    double a[] = {0.3, 0.3, -4.0, 9.0, 0.3, 0.3, 9.0};
    double th[] = {0.01, 0.01, 0.01, 0.01, 0.2, 0.01, 0.01};
    /* clamped coordinates each point is read at (v < 0 is evaluated at 0, which is on this grid) */
    double cv[] = {1.0, 3.0, 1.0, 1.0, 1.0, 0.0, 1.0};
    double ca[] = {0.3, 0.3, -1.0, 2.0, 0.3, 0.3, 2.0};
    double ct[] = {0.01, 0.01, 0.01, 0.01, 0.02, 0.01, 0.01};
    int want_out[] = {0, 1, 1, 1, 1, 0, 1};
    double fuel[7];
    wf_table_eval(t, 7, v, a, th, 0, fuel, NULL);
    int n_want = 0;
    for (int i = 0; i < 7; i++) {
        int out;
        CHECK_ABS(fuel[i], ref_tri(val_fuel, cv[i], ca[i], ct[i]), 1e-12);
        wf_table_fuel(t, v[i], a[i], th[i], 0, NULL, &out);
        CHECK(out == want_out[i], "point %d: outside %d want %d", i, out, want_out[i]);
        n_want += want_out[i];
    }
    CHECK(wf_table_n_outside(t, 7, v, a, th, 0) == (size_t)n_want, "count %zu want %d",
          wf_table_n_outside(t, 7, v, a, th, 0), n_want);
    /* With projection a = 9 becomes a_max (inside the grid): only the speed and grade excursions count. */
    size_t n_proj = wf_table_n_outside(t, 7, v, a, th, 1);
    CHECK(n_proj == 3, "projected count %zu want 3", n_proj);
    wf_table_destroy(&t);
}

/* ---- A smooth function on the release's grid ----------------------------------------------------------- */

/* g(v, a, theta) and bounds of its second derivatives on the grid (v in [0, 30], a in [-4, 4]). */
static double smooth(double v, double a, double th)
{
    return 0.3 + 0.02 * v + 0.0004 * v * v + 0.2 * sin(0.3 * v) + 0.5 * a + 0.1 * a * a + 0.02 * a * v + 3 * th +
           0.4 * th * v + 5 * th * th;
}
static const double G_VV = 0.0008 + 0.2 * 0.09, G_AA = 0.2, G_TT = 10.0;

static void test_smooth_on_release_grid(void)
{
    /* The release's layout: grade fastest (-0.03..0.03 step 0.003), then acceleration from 4 down by 0.08,
     * then speed upward (the sample shows only v = 0; 1 m/s steps here); coordinates in shortest form,
     * fuel with 15 significant digits. */
    const char *path = tpath("smooth.csv");
    FILE *f = fopen(path, "w");
    fprintf(f, "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n");
    int nv = 31, na = 101, nt = 21;
    for (int i = 0; i < nv; i++)
        for (int j = 0; j < na; j++)
            for (int k = 0; k < nt; k++) {
                double v = i, a = (400 - 8 * j) / 100.0, th = (3 * k - 30) / 1000.0;
                fprintf(f, "%.15g,%.15g,%.15g,%.15g,0\n", v, a, th, smooth(v, a, th));
            }
    fclose(f);
    WfError err = {0};
    WfTable *t = NULL;
    CHECK(wf_table_read_csv(path, &t, &err) == 0, "%s", err.msg);
    if (!t) return;
    CHECK(t->v.n == 31 && t->a.n == 101 && t->theta.n == 21, "grid %zu x %zu x %zu", t->v.n, t->a.n, t->theta.n);
    CHECK(t->a.x[0] == -4.0 && t->a.x[100] == 4.0 && t->a.x[51] == 0.08, "acceleration axis ascending");
    /* Trilinear error bound for a C2 function: sum over axes of h^2/8 max|second derivative|. */
    double hv = 1.0, ha = 0.08, ht = 0.003;
    double bound = hv * hv / 8 * G_VV + ha * ha / 8 * G_AA + ht * ht / 8 * G_TT + 1e-13;
    double worst = 0;
    for (int n = 0; n < 20000; n++) {
        double v = 30 * urand(), a = -4 + 8 * urand(), th = -0.03 + 0.06 * urand();
        double e = fabs(wf_table_fuel(t, v, a, th, 0, NULL, NULL) - smooth(v, a, th));
        if (e > worst) worst = e;
    }
    CHECK(worst <= bound, "max error %.3g above the bound %.3g", worst, bound);
    CHECK(worst >= 0.2 * bound, "max error %.3g far below the bound %.3g: the check would be vacuous", worst, bound);
    wf_table_destroy(&t);
}

/* ---- The release's sample ------------------------------------------------------------------------------ */

static void test_sample_file(void)
{
    const char *path = WF_REPO_DIR "/../shared/data/semiprincipled/midsize_suv_head.csv";
    if (access(path, R_OK) != 0) {
        printf("SKIP test_sample_file: %s not present\n", path);
        return;
    }
    WfError err = {0};
    WfTable *t = NULL;
    CHECK(wf_table_read_csv(path, &t, &err) == 0, "%s", err.msg);
    if (!t) return;
    CHECK(t->v.n == 1 && t->a.n == 3 && t->theta.n == 21, "grid %zu x %zu x %zu", t->v.n, t->a.n, t->theta.n);
    /* Every row comes back exactly at its node (the file read here with sscanf, not the CSV reader). */
    FILE *f = fopen(path, "r");
    char line[256];
    int rows = 0;
    if (!fgets(line, sizeof line, f)) line[0] = 0;
    CHECK(!strncmp(line, "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible", 53), "header %s", line);
    while (fgets(line, sizeof line, f)) {
        double v, a, th, fu;
        int inf;
        if (sscanf(line, "%lf,%lf,%lf,%lf,%d", &v, &a, &th, &fu, &inf) != 5) continue;
        rows++;
        uint8_t fl;
        CHECK(wf_table_fuel(t, v, a, th, 0, &fl, NULL) == fu, "row %d", rows);
        CHECK(fl == inf, "row %d flag %d want %d", rows, fl, inf);
    }
    fclose(f);
    CHECK(rows == 63, "rows %d", rows);
    /* Largest feasible acceleration per grade, read off the sample: 4 up to -0.003 rad, 3.92 up to 0.006,
     * 3.84 up to 0.015; none feasible from 0.018 on, where the lowest grid acceleration stands in. */
    for (int k = 0; k < 21; k++) {
        double th = (3 * k - 30) / 1000.0, want = k <= 9 ? 4 : k <= 12 ? 3.92 : 3.84;
        CHECK(wf_table_a_max(t, 0, th) == want, "a_max at %g: %.17g want %g", th, wf_table_a_max(t, 0, th), want);
    }
    /* One speed: any speed reads the v = 0 values and counts as outside the grid. */
    int out;
    CHECK(wf_table_fuel(t, 5.0, 3.92, 0.0, 0, NULL, &out) == wf_table_fuel(t, 0.0, 3.92, 0.0, 0, NULL, NULL) && out,
          "speed clamped to the single node");
    wf_table_destroy(&t);
}

/* ---- Malformed tables ------------------------------------------------------------------------------------ */

static void expect_error(const char *name, const char *text, const char *want1, const char *want2)
{
    const char *path = tpath(name);
    write_text(path, text);
    WfError err = {0};
    WfTable *t = NULL;
    int rc = wf_table_read_csv(path, &t, &err);
    CHECK(rc == WF_EINPUT, "%s: rc %d", name, rc);
    CHECK(t == NULL, "%s: no table on failure", name);
    CHECK(strstr(err.msg, path) != NULL, "%s: message names the file: %s", name, err.msg);
    CHECK(strstr(err.msg, want1) != NULL, "%s: message lacks '%s': %s", name, want1, err.msg);
    CHECK(!want2 || strstr(err.msg, want2) != NULL, "%s: message lacks '%s': %s", name, want2, err.msg);
    wf_table_destroy(&t);
}

#define HDR "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n"
static void test_malformed(void)
{
    expect_error("missing.csv", HDR "0,1,0,1.5,0\n0,1,0.01,1.6,0\n0,0,0,1.1,0\n", "not a regular grid",
                 "no row for Velocity=0, Acceleration=0, Road Grade=0.01");
    /* Irregular: the grade values differ between accelerations, so the points do not lie on one grid. */
    expect_error("irregular.csv", HDR "0,1,0,1.5,0\n0,1,0.01,1.6,0\n0,0,0,1.1,0\n0,0,0.02,1.2,0\n",
                 "not a regular grid", "do not lie on one grid");
    expect_error("header.csv", "Velocity,Acceleration,Grade,Fuel Rate,Infeasible\n0,1,0,1.5,0\n",
                 "header column 3 is 'Grade', expected 'Road Grade'", NULL);
    expect_error("noheader.csv", "0,1,0,1.5,0\n", "first line must be the header", NULL);
    expect_error("nan.csv", HDR "0,1,0,NaN,0\n", ":2:", "finite number");
    expect_error("inf01.csv", HDR "0,1,0,1.5,2\n", ":2:", "Infeasible) must be 0 or 1");
    expect_error("dup.csv", HDR "0,1,0,1.5,0\n0,1,0,1.5,0\n", ":3: duplicate row", "first on line 2");
    expect_error("short.csv", HDR "0,1,0,1.5\n", ":2:", "4 fields, expected 5");
    expect_error("empty.csv", HDR, "no data rows", NULL);
    WfError err = {0};
    WfTable *t = NULL;
    CHECK(wf_table_read_csv(tpath("does_not_exist.csv"), &t, &err) == WF_EINPUT && strstr(err.msg, "cannot open"),
          "%s", err.msg);
}

/* ---- HDF5 form -------------------------------------------------------------------------------------------- */

static void test_h5_checks(void)
{
    WfTable *t = small_table();
    if (!t) return;
    WfError err = {0};
    const char *h5 = tpath("check.h5");
    CHECK(wf_table_write_h5(t, h5, 0, &err) == 0, "%s", err.msg);
    CHECK(wf_table_write_h5(t, h5, 0, &err) == WF_EINPUT && strstr(err.msg, "exists"), "overwrite refused: %s",
          err.msg);
    CHECK(wf_table_write_h5(t, h5, 1, &err) == 0, "--force overwrites: %s", err.msg);
    struct stat st;
    char partial[600];
    snprintf(partial, sizeof partial, "%s.partial", h5);
    CHECK(stat(partial, &st) != 0, "no .partial left behind");
    /* Damage one value in place: the checksum catches it. */
    hid_t fid = H5Fopen(h5, H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t d = H5Dopen2(fid, "fuel_gps", H5P_DEFAULT);
    double vals[NV * NA * NT];
    H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, vals);
    vals[7] += 1e-9;
    H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, vals);
    H5Dclose(d);
    H5Fclose(fid);
    WfTable *back = NULL;
    CHECK(wf_table_load_h5(h5, &back, &err) == WF_EINPUT && strstr(err.msg, "checksum mismatch"), "%s", err.msg);
    CHECK(back == NULL, "no table from a damaged file");
    /* An HDF5 file that is not a table, and a CSV given where HDF5 is expected. */
    fid = H5Fcreate(tpath("other.h5"), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    H5Fclose(fid);
    CHECK(wf_table_load_h5(tpath("other.h5"), &back, &err) == WF_EINPUT && strstr(err.msg, "attribute 'format'"),
          "%s", err.msg);
    CHECK(wf_table_load_h5(tpath("small.csv"), &back, &err) == WF_EINPUT && strstr(err.msg, "not an HDF5 file"),
          "%s", err.msg);
    wf_table_destroy(&t);
}

static void test_from_grid_matches_csv(void)
{
    WfTable *t = small_table();
    if (!t) return;
    uint8_t inf[NV * NA * NT];
    for (int i = 0; i < NV * NA * NT; i++) inf[i] = (uint8_t)GI[i / (NA * NT)][(i / NT) % NA][i % NT];
    WfTable *g = NULL;
    WfError err = {0};
    CHECK(wf_table_from_grid(NV, GV, NA, GA, NT, GT, &GF[0][0][0], inf, "memory", &g, &err) == 0, "%s", err.msg);
    if (g) CHECK(g->data_fnv1a64 == t->data_fnv1a64, "same grid and values, same checksum");
    wf_table_destroy(&g);
    double bad_a[NA] = {-1, 0, 0, 0.7, 2};
    CHECK(wf_table_from_grid(NV, GV, NA, bad_a, NT, GT, &GF[0][0][0], inf, "memory", &g, &err) == WF_EINPUT &&
              strstr(err.msg, "acceleration node 2"),
          "%s", err.msg);
    wf_table_destroy(&t);
}

/* ---- Vehicle classes that name a table -------------------------------------------------------------------- */

static const char *class_text(const char *model, const char *table_line, const char *extra)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "name: Test class\nduty: light\nfuel: gasoline\nmass_kg: 1500\nlength_m: 4.5\nkw_per_gps: 42.36\n"
             "energy_model: %s\n%s%s",
             model, table_line, extra);
    return buf;
}

static void test_vehicle_class(void)
{
    WfTable *t = small_table();
    if (!t) return;
    WfError err = {0};
    char dir[600];
    snprintf(dir, sizeof dir, "%s/tables", tmpdir);
    mkdir(dir, 0755);
    char h5[700];
    snprintf(h5, sizeof h5, "%s/small.h5", dir);
    CHECK(wf_table_write_h5(t, h5, 1, &err) == 0, "%s", err.msg);
    /* Relative to the class file's directory, not to the working directory. */
    write_text(tpath("tab.yaml"), class_text("tabulated", "table: tables/small.h5\n", ""));
    WfVehicleClass vc;
    int rc = wf_vehicle_load(tpath("tab.yaml"), &vc, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        CHECK(vc.model == &wf_energy_tabulated && vc.model->project_default == 1, "model %s", vc.model->name);
        double v[3] = {0.7, 2.2, 9.0}, a[3] = {0.1, 1.9, 0.0}, th[3] = {0.01, -0.02, 0.0}, fuel[3];
        uint8_t flag[3];
        wf_vehicle_fuel(&vc, 3, v, a, th, 1, fuel, flag);
        for (int i = 0; i < 3; i++) {
            uint8_t fl;
            CHECK(fuel[i] == wf_table_fuel(t, v[i], a[i], th[i], 1, &fl, NULL) && flag[i] == fl, "point %d", i);
        }
        CHECK(vc.model->n_outside(vc.params, 3, v, a, th, 1) == 1, "one point beyond the speed range");
        CHECK_ABS(vc.model->a_max(vc.params, 1.0, 0.0), ref_amax(1.0, 0.0), 1e-12);
        wf_vehicle_free(&vc);
    }
    const char *bad_name[] = {"nokey.yaml", "missing.yaml", "csv.yaml", "poly.yaml"};
    const char *bad_want[] = {"table", "cannot open", "wavefuel table import", "unknown key"};
    for (int i = 0; i < 4; i++) {
        /* class_text() returns a static buffer: each file is written before the next text is made. */
        const char *text = i == 0   ? class_text("tabulated", "", "")
                           : i == 1 ? class_text("tabulated", "table: nowhere.h5\n", "")
                           : i == 2 ? class_text("tabulated", "table: tables/x.csv\n", "")
                                    : class_text("tabulated", "table: tables/small.h5\n", "energy:\n  c0: 1\n");
        write_text(tpath(bad_name[i]), text);
        rc = wf_vehicle_load(tpath(bad_name[i]), &vc, &err);
        CHECK(rc == WF_EINPUT && strstr(err.msg, bad_want[i]) && strstr(err.msg, bad_name[i]), "%s: rc %d: %s",
              bad_name[i], rc, err.msg);
    }
    /* Beside an explicit model: the class loads as explicit; the table is its tabulated twin. */
    char text[4096];
    FILE *f = fopen(WF_REPO_DIR "/vehicles/midsize_suv.yaml", "r");
    size_t n = f ? fread(text, 1, sizeof text - 64, f) : 0;
    if (f) fclose(f);
    text[n] = '\0';
    strcat(text, "table: tables/small.h5\n");
    write_text(tpath("suv_beside.yaml"), text);
    rc = wf_vehicle_load(tpath("suv_beside.yaml"), &vc, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        char path[1024];
        CHECK(vc.model == &wf_energy_circles, "explicit model kept");
        CHECK(wf_tabulated_class_table(&vc, path, sizeof path, &err) == 0 && !strcmp(path, h5), "twin path '%s'", path);
        WfVehicleClass twin;
        CHECK(wf_tabulated_class(&vc, path, &twin, &err) == 0, "%s", err.msg);
        CHECK(twin.model == &wf_energy_tabulated && !strcmp(twin.name, "suv_beside") &&
                  twin.kw_per_gps == vc.kw_per_gps && twin.fuel_density_g_per_l == vc.fuel_density_g_per_l,
              "twin keeps the class's identity");
        wf_vehicle_free(&twin);
        wf_vehicle_free(&vc);
    }
    wf_table_destroy(&t);
}

/* ---- Load time of a release-sized table ------------------------------------------------------------------- */

static void test_load_time(void)
{
    /* 81 speeds x 101 accelerations x 21 grades: the size of a release table (about 170 000 rows). */
    size_t nv = 81, na = 101, nt = 21, n = nv * na * nt;
    double v[81], a[101], th[21], *fuel = malloc(n * sizeof *fuel);
    uint8_t *inf = malloc(n);
    for (size_t i = 0; i < nv; i++) v[i] = 0.5 * (double)i;
    for (size_t j = 0; j < na; j++) a[j] = (8.0 * (double)j - 400.0) / 100.0;
    for (size_t k = 0; k < nt; k++) th[k] = (3.0 * (double)k - 30.0) / 1000.0;
    for (size_t i = 0; i < n; i++) {
        fuel[i] = 10 * urand();
        inf[i] = urand() < 0.2;
    }
    WfTable *t = NULL, *back = NULL;
    WfError err = {0};
    CHECK(wf_table_from_grid(nv, v, na, a, nt, th, fuel, inf, "random", &t, &err) == 0, "%s", err.msg);
    CHECK(t && wf_table_write_h5(t, tpath("big.h5"), 1, &err) == 0, "%s", err.msg);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    CHECK(wf_table_load_h5(tpath("big.h5"), &back, &err) == 0, "%s", err.msg);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ms = (double)(t1.tv_sec - t0.tv_sec) * 1e3 + (double)(t1.tv_nsec - t0.tv_nsec) * 1e-6;
    struct stat st;
    stat(tpath("big.h5"), &st);
    printf("  release-sized table (%zu points, %lld bytes of HDF5) loads in %.1f ms\n", n, (long long)st.st_size, ms);
    CHECK(ms < 1000, "load took %.1f ms", ms);
    CHECK(back && back->data_fnv1a64 == t->data_fnv1a64, "round trip");
    wf_table_destroy(&t);
    wf_table_destroy(&back);
    free(fuel);
    free(inf);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wf_test_tabulated_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    make_small();
    RUN(test_nodes_exact);
    RUN(test_between_nodes);
    RUN(test_outside_clamped_and_counted);
    RUN(test_smooth_on_release_grid);
    RUN(test_sample_file);
    RUN(test_malformed);
    RUN(test_h5_checks);
    RUN(test_from_grid_matches_csv);
    RUN(test_vehicle_class);
    RUN(test_load_time);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_EXIT();
}
