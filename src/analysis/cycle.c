/* Drive cycles: loading a speed trace, forward-difference acceleration, the fuel and distance sums of one run over
 * a scheme's samples (cycle_scheme.c), the data directory and the paper's protocol grid (cycles and grades per
 * duty). Units: s, m/s, m/s^2, rad, g/s, g, m. */
#include "wavefuel/cycle.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "wavefuel/csv.h"
#include "wavefuel/domain.h"
#include "util/numfmt.h"
#include "util/mem.h"

void wf_cycle_free(WfCycle *c)
{
    if (!c) return;
    WF_FREE(c->t_s, c->v_mps, c->dt_s, c->a_mps2);
    c->t_s = c->v_mps = c->dt_s = c->a_mps2 = NULL;
    c->n = 0;
}

/* Checks and derives dt and a from t and v already stored in c; lines[] (may be NULL) names rows. */
static int derive(WfCycle *c, const char *shown, const int *lines, WfError *err)
{
    size_t n = c->n;
    if (n < 2) return wf_err(err, WF_EINPUT, "%s: a cycle needs at least 2 samples (got %zu)", shown, n);
    for (size_t i = 0; i < n; i++) {
        int line = lines ? lines[i] : (int)i + 1;
        if (!isfinite(c->t_s[i]) || !isfinite(c->v_mps[i]))
            return wf_err(err, WF_EINPUT, "%s:%d: time and speed must be finite", shown, line);
        /* The speeds `wavefuel energy` accepts too (domain.h); the bound keeps distances and accelerations finite. */
        const WfRange *speed = &wf_point_range[WF_POINT_SPEED];
        if (!(c->v_mps[i] >= speed->min && c->v_mps[i] <= speed->max)) {
            char where[1200];
            snprintf(where, sizeof where, "%s:%d: field 2 (speed_mps)", shown, line);
            return wf_range_check(speed, c->v_mps[i], where, err);
        }
        if (i > 0 && !(c->t_s[i] > c->t_s[i - 1]))
            return wf_err(err, WF_EINPUT, "%s:%d: field 1 (time_s) must increase strictly (%s after %s)", shown,
                          line, WF_NUM(c->t_s[i]), WF_NUM(c->t_s[i - 1]));
    }
    for (size_t i = 0; i + 1 < n; i++) {
        c->dt_s[i] = c->t_s[i + 1] - c->t_s[i];
        c->a_mps2[i] = (c->v_mps[i + 1] - c->v_mps[i]) / c->dt_s[i]; /* dt > 0: checked above */
    }
    /* The last sample has no forward difference and closes the cycle: it contributes no time. */
    c->dt_s[n - 1] = 0.0;
    c->a_mps2[n - 1] = 0.0;
    return 0;
}

static int alloc_cycle(WfCycle *c, size_t n, WfError *err)
{
    c->n = n;
    size_t m = n ? n : 1;
    c->t_s = malloc(m * sizeof *c->t_s);
    c->v_mps = malloc(m * sizeof *c->v_mps);
    c->dt_s = malloc(m * sizeof *c->dt_s);
    c->a_mps2 = malloc(m * sizeof *c->a_mps2);
    if (!c->t_s || !c->v_mps || !c->dt_s || !c->a_mps2) {
        wf_cycle_free(c);
        return wf_err(err, WF_ESYS, "out of memory for a cycle of %zu samples", n);
    }
    return 0;
}

static void stem_of(const char *path, char *out, size_t len)
{
    const char *base = strrchr(path, '/');
    snprintf(out, len, "%s", base ? base + 1 : path);
    char *dot = strrchr(out, '.');
    if (dot && dot != out) *dot = '\0';
}

int wf_cycle_load(const char *path, WfCycle *c, WfError *err)
{
    memset(c, 0, sizeof *c);
    static const char *const names[] = {"time_s", "speed_mps"};
    WfCsv csv;
    int rc = wf_csv_read(path, 2, names, &csv, err);
    if (rc) return rc;
    if ((rc = alloc_cycle(c, csv.n_rows, err))) {
        wf_csv_free(&csv);
        return rc;
    }
    for (size_t i = 0; i < csv.n_rows; i++) {
        c->t_s[i] = csv.data[2 * i];
        c->v_mps[i] = csv.data[2 * i + 1];
    }
    rc = derive(c, path, csv.line, err);
    wf_csv_free(&csv);
    if (rc) {
        wf_cycle_free(c);
        return rc;
    }
    snprintf(c->path, sizeof c->path, "%s", path);
    stem_of(path, c->name, sizeof c->name);
    return 0;
}

int wf_cycle_from_arrays(const char *name, size_t n, const double *t_s, const double *v_mps, WfCycle *c,
                         WfError *err)
{
    memset(c, 0, sizeof *c);
    int rc = alloc_cycle(c, n, err);
    if (rc) return rc;
    if (n) {
        memcpy(c->t_s, t_s, n * sizeof *t_s);
        memcpy(c->v_mps, v_mps, n * sizeof *v_mps);
    }
    if ((rc = derive(c, name, NULL, err))) {
        wf_cycle_free(c);
        return rc;
    }
    snprintf(c->name, sizeof c->name, "%s", name);
    return 0;
}

double wf_cycle_duration_s(const WfCycle *c) { return c->n ? c->t_s[c->n - 1] - c->t_s[0] : 0.0; }

double wf_cycle_distance_m(const WfCycle *c)
{
    double d = 0.0;
    for (size_t i = 0; i < c->n; i++) d += c->v_mps[i] * c->dt_s[i];
    return d;
}

/* ---------------------------------------------------------------------------------------------------------
 * Data directory and cycle names */

static int is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

int wf_cycle_data_dir(const char *dir, const char *dir_from, const char *default_dir, char *out, size_t len,
                      int *found, WfError *err)
{
    *found = 0;
    out[0] = '\0';
    const char *show = dir && *dir ? dir : NULL;
    char real[PATH_MAX];
    if (show && !is_dir(show))
        return wf_err(err, WF_EINPUT, "data directory %s (%s) does not exist", show, dir_from ? dir_from : "given");
    if (!show) {
        if (!default_dir || !is_dir(default_dir)) return 0;
        show = realpath(default_dir, real) ? real : default_dir;
    }
    int w = snprintf(out, len, "%s", show);
    if (w < 0 || (size_t)w >= len) return wf_err(err, WF_EINPUT, "data directory path too long: %s", show);
    *found = 1;
    return 0;
}

int wf_cycle_resolve(const char *arg, const char *data_dir, char *out, size_t len, WfError *err)
{
    size_t alen = strlen(arg);
    int w;
    if (strchr(arg, '/') || (alen > 4 && !strcmp(arg + alen - 4, ".csv"))) {
        w = snprintf(out, len, "%s", arg);
        if (w < 0 || (size_t)w >= len) return wf_err(err, WF_EINPUT, "cycle path too long: %s", arg);
        return 0;
    }
    if (!data_dir || !data_dir[0])
        return wf_err(err, WF_EINPUT,
                      "cycle '%s' is a name but there is no data directory: give --cycles DIR or set WAVEFUEL_DATA "
                      "(DIR/cycles/%s.csv), or give the CSV's path",
                      arg, arg);
    w = snprintf(out, len, "%s/cycles/%s.csv", data_dir, arg);
    if (w < 0 || (size_t)w >= len)
        return wf_err(err, WF_EINPUT, "cycle path too long: %s/cycles/%s.csv", data_dir, arg);
    if (access(out, R_OK) == 0) return 0;
    /* Unknown name: list what the directory holds. */
    char known[1024] = "", cdir[PATH_MAX + 16];
    size_t used = 0;
    snprintf(cdir, sizeof cdir, "%s/cycles", data_dir);
    DIR *d = opendir(cdir);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            size_t l = strlen(e->d_name);
            if (l < 5 || strcmp(e->d_name + l - 4, ".csv")) continue;
            int k = snprintf(known + used, sizeof known - used, "%s%.*s", used ? ", " : "", (int)(l - 4), e->d_name);
            if (k > 0 && (size_t)k < sizeof known - used) used += (size_t)k;
        }
        closedir(d);
    }
    return wf_err(err, WF_EINPUT, "cycle '%s' not found: no %s (cycles there: %s)", arg, out, used ? known : "none");
}

/* ---------------------------------------------------------------------------------------------------------
 * Runs */

void wf_cycle_run_free(WfCycleRun *r)
{
    if (!r) return;
    free(r->fuel_gps);
    free(r->flag);
    r->fuel_gps = NULL;
    r->flag = NULL;
}

int wf_cycle_run(const WfCycle *c, const WfCycleSamples *s, const WfVehicleClass *vc, double theta_rad, int project,
                 WfCycleRun *r, WfError *err)
{
    memset(r, 0, sizeof *r);
    size_t n = s->n;
    double *theta = malloc(n * sizeof *theta);
    r->fuel_gps = malloc(n * sizeof *r->fuel_gps);
    r->flag = malloc(n);
    if (!theta || !r->fuel_gps || !r->flag) {
        free(theta);
        wf_cycle_run_free(r);
        return wf_err(err, WF_ESYS, "out of memory for a run of %zu samples", n);
    }
    for (size_t i = 0; i < n; i++) theta[i] = theta_rad;
    r->samples = s;
    r->theta_rad = theta_rad;
    r->project = project;
    r->n = n;
    wf_vehicle_fuel(vc, n, s->v_mps, s->a_mps2, theta, project, r->fuel_gps, r->flag);
    if (vc->model->n_outside) r->n_outside = vc->model->n_outside(vc->params, n, s->v_mps, s->a_mps2, theta, project);
    free(theta);
    /* Sums in sample order: the same cycle gives the same bits on any machine and thread count. */
    for (size_t i = 0; i < n; i++) {
        r->fuel_g += r->fuel_gps[i] * s->w_s[i];
        r->distance_m += s->v_mps[i] * s->w_s[i];
        if (r->flag[i] != WF_FEASIBLE) {
            r->infeasible_s += s->w_s[i];
            r->n_infeasible++;
        }
    }
    r->duration_s = wf_cycle_duration_s(c);
    r->l_per_100km = wf_l_per_100km(vc, r->fuel_g, r->distance_m);
    r->mpg = wf_mpg(vc, r->fuel_g, r->distance_m);
    return 0;
}

/* ---------------------------------------------------------------------------------------------------------
 * The paper's protocol */

const char *const *wf_protocol_cycles(WfDuty duty, size_t *n)
{
    static const char *const light[] = {"udds", "hwfet", "us06", "wltc3"};
    /* The paper also runs HHDDT high speed; no public 1 Hz copy was found (see docs/cycles.md). */
    static const char *const heavy[] = {"hhddt_cruise", "hhddt_transient", "hhddt_h65"};
    *n = duty == WF_DUTY_HEAVY ? sizeof heavy / sizeof heavy[0] : sizeof light / sizeof light[0];
    return duty == WF_DUTY_HEAVY ? heavy : light;
}

size_t wf_protocol_grades(WfDuty duty, double *theta, size_t cap)
{
    int k_max = duty == WF_DUTY_HEAVY ? 2 : 3;
    size_t n = 0;
    /* k / 100 rather than a running sum, so every grade is the closest double to its decimal. */
    for (int k = -k_max; k <= k_max && n < cap; k++) theta[n++] = (double)k / 100.0;
    return n;
}
