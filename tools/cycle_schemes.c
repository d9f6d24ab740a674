/* cycle_schemes: how far each cycle scheme's fuel is from a fine integration of the same spline trace (the table
 * of docs/cycles.md). For every class on the search path and every protocol cycle of its duty, at every protocol
 * grade, with projection on (the protocol's default): the reference is the `spline` scheme's row run at 2000 Hz;
 * each scheme of the table is compared with it. The 1000 Hz run bounds the reference's own error.
 *   build/tools/cycle_schemes VEHICLES_DIR DATA_DIR   (make tests builds it; e.g. vehicles ../shared/data)
 * prints Markdown; exit 2 for a bad directory or no classes, 1 on other failures. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/cycle.h"
#include "wavefuel/vehicle.h"

enum { MAX_SCHEMES = 8, MAX_GRADES = 16 };

/* Fuel of class vc on cycle c with scheme sc at grade theta (projection on), g. */
static int fuel_of(const WfCycle *c, const WfCycleScheme *sc, const WfVehicleClass *vc, double theta, double *fuel_g,
                   WfError *err)
{
    WfCycleSamples s;
    WfCycleRun r;
    int rc = wf_cycle_samples(c, sc, &s, err);
    if (rc) return rc;
    rc = wf_cycle_run(c, &s, vc, theta, 1, &r, err);
    if (!rc) *fuel_g = r.fuel_g;
    wf_cycle_run_free(&r);
    wf_cycle_samples_free(&s);
    return rc;
}

/* One row: the reference at 0 rad, and per scheme the relative difference at 0 rad and the largest over grades. */
static int row(const WfCycle *c, const WfVehicleClass *vc, const WfCycleScheme *sc, size_t n_sc,
               const WfCycleScheme *ref, const WfCycleScheme *half, double *ref_err, WfError *err)
{
    double grades[MAX_GRADES], at0[MAX_SCHEMES], worst[MAX_SCHEMES] = {0}, f_ref0 = 0;
    size_t ng = wf_protocol_grades(vc->duty, grades, MAX_GRADES);
    for (size_t g = 0; g < ng; g++) {
        double f_ref, f_half;
        int rc = fuel_of(c, ref, vc, grades[g], &f_ref, err);
        if (!rc) rc = fuel_of(c, half, vc, grades[g], &f_half, err);
        if (rc) return rc;
        if (fabs(f_half - f_ref) / f_ref > *ref_err) *ref_err = fabs(f_half - f_ref) / f_ref;
        if (grades[g] == 0.0) f_ref0 = f_ref;
        for (size_t k = 0; k < n_sc; k++) {
            double f;
            if ((rc = fuel_of(c, &sc[k], vc, grades[g], &f, err))) return rc;
            double rel = (f - f_ref) / f_ref;
            if (grades[g] == 0.0) at0[k] = rel;
            if (fabs(rel) > fabs(worst[k])) worst[k] = rel;
        }
    }
    printf("| %s | %s | %.2f |", vc->name, c->name, f_ref0);
    for (size_t k = 0; k < n_sc; k++) printf(" %+.3f %% | %+.3f %% |", 100 * at0[k], 100 * worst[k]);
    printf("\n");
    return 0;
}

static int table(const char *data_dir, WfError *err)
{
    size_t n_sc;
    const WfCycleScheme *sc = wf_cycle_schemes(&n_sc);
    const WfCycleScheme *spline = wf_cycle_scheme_find("spline", err);
    if (!spline || n_sc > MAX_SCHEMES) return WF_ESYS;
    WfCycleScheme ref = *spline, half = *spline;
    ref.rate_hz = 2000.0;
    half.rate_hz = 1000.0;
    WfVehicleClass *all = NULL;
    size_t n = 0;
    int rc = wf_vehicle_list(&all, &n, err);
    if (!rc && n == 0) rc = wf_err(err, WF_EINPUT, "no vehicle classes found");
    printf("| class | cycle | reference fuel at 0 rad (g) |");
    for (size_t k = 0; k < n_sc; k++) printf(" %s at 0 rad | %s, largest over grades |", sc[k].name, sc[k].name);
    printf("\n|---|---|---:|");
    for (size_t k = 0; k < n_sc; k++) printf("---:|---:|");
    printf("\n");
    double ref_err = 0;
    for (size_t i = 0; i < n && !rc; i++) {
        size_t nc;
        const char *const *names = wf_protocol_cycles(all[i].duty, &nc);
        for (size_t k = 0; k < nc && !rc; k++) {
            char path[4096];
            WfCycle c;
            rc = wf_cycle_resolve(names[k], data_dir, path, sizeof path, err);
            if (!rc) rc = wf_cycle_load(path, &c, err);
            if (rc) break;
            rc = row(&c, &all[i], sc, n_sc, &ref, &half, &ref_err, err);
            wf_cycle_free(&c);
        }
    }
    if (!rc)
        printf("\nReference: the `spline` scheme at %g Hz; largest |%g Hz - %g Hz| / reference over all runs: %.1e.\n",
               ref.rate_hz, half.rate_hz, ref.rate_hz, ref_err);
    for (size_t i = 0; i < n; i++) wf_vehicle_free(&all[i]);
    free(all);
    return rc;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: cycle_schemes VEHICLES_DIR DATA_DIR (the directory holding cycles/NAME.csv)\n");
        return 2;
    }
    WfError err = {0};
    int rc = wf_vehicle_search_path_set(argv[1], &err);
    if (!rc) rc = table(argv[2], &err);
    if (rc) fprintf(stderr, "cycle_schemes: %s\n", err.msg);
    return rc == WF_EINPUT ? 2 : rc ? 1 : 0;
}
