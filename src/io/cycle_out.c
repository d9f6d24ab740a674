/* HDF5 output of drive-cycle runs (`wavefuel cycle -o`): one group per class / cycle / grade / model with the
 * time series and totals, and a per-class summary for the protocol. Written as PATH.partial and renamed on
 * success (src/io/h5util.h). Units in every dataset's `units` attribute. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/h5util.h"
#include "wavefuel/cycle.h"
#include "wavefuel/tabulated.h"
#include "wavefuel/version.h"

struct WfCycleOut {
    WfH5File *f;
};

int wf_cycle_out_create(const char *path, int force, const char *command_line, WfCycleOut **out, WfError *err)
{
    *out = NULL;
    WfCycleOut *o = calloc(1, sizeof *o);
    if (!o) return wf_err(err, WF_ESYS, "out of memory");
    int rc = wf_h5_create(path, force, &o->f, err);
    if (rc) {
        free(o);
        return rc;
    }
    char created[128];
    snprintf(created, sizeof created, "wavefuel %s (%s)", WF_VERSION, wf_git_hash());
    if ((rc = wf_h5_attr_str(o->f->fid, "created_by", created, err)) ||
        (rc = wf_h5_attr_str(o->f->fid, "command", command_line ? command_line : "", err)) ||
        (rc = wf_h5_attr_str(o->f->fid, "layout",
                             "/CLASS/CYCLE/theta_<grade rad>/MODEL: one run; /CLASS/summary: protocol tables", err))) {
        wf_cycle_out_abandon(&o);
        return rc;
    }
    *out = o;
    return 0;
}

/* Group name of a grade: fixed width and sign, so -0.01 and 0.01 sort and never collide; -0 prints as +0. */
static void grade_group(double theta, char *out, size_t len)
{
    snprintf(out, len, "theta_%+.4f", theta == 0.0 ? 0.0 : theta);
}

/* The series at the scheme's samples. */
static int write_series(hid_t g, const WfVehicleClass *vc, const WfCycleRun *r, WfError *err)
{
    const WfCycleSamples *s = r->samples;
    hsize_t n = s->n;
    double *power = malloc((s->n ? s->n : 1) * sizeof *power);
    if (!power) return wf_err(err, WF_ESYS, "out of memory");
    for (size_t i = 0; i < s->n; i++) power[i] = r->fuel_gps[i] * vc->kw_per_gps;
    int rc = wf_h5_write_f64(g, "time_s", 1, &n, s->t_s, "s", "sample time (the scheme's samples)", err) ||
             wf_h5_write_f64(g, "speed_mps", 1, &n, s->v_mps, "m/s", "cycle speed at the samples", err) ||
             wf_h5_write_f64(g, "accel_mps2", 1, &n, s->a_mps2, "m/s^2", "acceleration as the scheme forms it", err) ||
             wf_h5_write_f64(g, "weight_s", 1, &n, s->w_s, "s", "quadrature weight of each sample", err) ||
             wf_h5_write_f64(g, "fuel_gps", 1, &n, r->fuel_gps, "g/s", "fuel rate", err) ||
             wf_h5_write_f64(g, "power_kw", 1, &n, power, "kW", "equivalent power: fuel rate x kw_per_gps", err) ||
             wf_h5_write_u8(g, "flag", 1, &n, r->flag, "1", "0 feasible, 1 acceleration infeasible, 2 negative speed",
                            err);
    free(power);
    return rc ? WF_ESYS : 0;
}

int wf_cycle_out_run(WfCycleOut *o, const WfVehicleClass *vc, const WfCycle *c, const WfCycleRun *r, int series,
                     WfError *err)
{
    const WfCycleSamples *s = r->samples;
    char gname[512], gg[32];
    grade_group(r->theta_rad, gg, sizeof gg);
    int w = snprintf(gname, sizeof gname, "/%s/%s/%s/%s", vc->name, c->name, gg, vc->model->name);
    if (w < 0 || (size_t)w >= sizeof gname) return wf_err(err, WF_EINPUT, "HDF5 group name too long: %s", gname);
    hid_t g = wf_h5_group(o->f->fid, gname, err);
    if (g < 0) return WF_ESYS;
    const char *table = vc->model == &wf_energy_tabulated
                            ? ((const WfTabulatedParams *)vc->params)->table->source
                            : "";
    int rc = wf_h5_attr_str(g, "class", vc->name, err) || wf_h5_attr_str(g, "class_label", vc->label, err) ||
             wf_h5_attr_str(g, "class_file", vc->path, err) || wf_h5_attr_str(g, "model", vc->model->name, err) ||
             wf_h5_attr_str(g, "table_source", table, err) || wf_h5_attr_str(g, "duty", wf_duty_name(vc->duty), err) ||
             wf_h5_attr_str(g, "fuel", wf_fuel_name(vc->fuel), err) ||
             wf_h5_attr_f64(g, "fuel_density_g_per_l", vc->fuel_density_g_per_l, err) ||
             wf_h5_attr_f64(g, "kw_per_gps", vc->kw_per_gps, err) || wf_h5_attr_str(g, "cycle", c->name, err) ||
             wf_h5_attr_str(g, "cycle_file", c->path, err) || wf_h5_attr_f64(g, "grade_rad", r->theta_rad, err) ||
             wf_h5_attr_i64(g, "project", r->project, err) || wf_h5_attr_str(g, "scheme", s->scheme->name, err) ||
             wf_h5_attr_str(g, "scheme_summary", s->scheme->summary, err) ||
             wf_h5_scalar_i64(g, "n_samples", (int64_t)s->n, "1", "samples the model was evaluated at", err) ||
             (series && write_series(g, vc, r, err)) ||
             wf_h5_scalar_f64(g, "fuel_g", r->fuel_g, "g", "sum fuel_gps[i] weight_s[i]", err) ||
             wf_h5_scalar_f64(g, "distance_m", r->distance_m, "m", "sum speed_mps[i] weight_s[i]", err) ||
             wf_h5_scalar_f64(g, "duration_s", r->duration_s, "s", "last time minus first time", err) ||
             wf_h5_scalar_f64(g, "l_per_100km", r->l_per_100km, "L/100km", "fuel_g / density per distance", err) ||
             wf_h5_scalar_f64(g, "mpg", r->mpg, "mi/gal", "miles per US gallon", err) ||
             wf_h5_scalar_f64(g, "infeasible_share", r->duration_s > 0 ? r->infeasible_s / r->duration_s : 0.0, "1",
                              "share of the cycle's time at samples flagged infeasible", err) ||
             wf_h5_scalar_i64(g, "n_outside_grid", (int64_t)r->n_outside, "1",
                              "evaluations clamped to the table's edge (tabulated models)", err);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

int wf_cycle_out_summary(WfCycleOut *o, const char *class_name, size_t n_cycles, const char *const *cycles,
                         const double *durations_s, size_t n_grades, const double *grades, size_t n_models,
                         const char *const *models, const double *fuel_g, const double *rel_diff,
                         const double *rel_total, WfError *err)
{
    char gname[256];
    int w = snprintf(gname, sizeof gname, "/%s/summary", class_name);
    if (w < 0 || (size_t)w >= sizeof gname) return wf_err(err, WF_EINPUT, "HDF5 group name too long: %s", gname);
    hid_t g = wf_h5_group(o->f->fid, gname, err);
    if (g < 0) return WF_ESYS;
    const char **rows = malloc((n_cycles + 1) * sizeof *rows);
    if (!rows) {
        H5Gclose(g);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    for (size_t i = 0; i < n_cycles; i++) rows[i] = cycles[i];
    rows[n_cycles] = "ALL";
    hsize_t ng = n_grades, nc = n_cycles, dims[2] = {n_cycles + 1, n_grades};
    int rc = wf_h5_write_strings(g, "cycles", n_cycles + 1, rows, "row names of the tables; ALL = all cycles", err) ||
             wf_h5_write_f64(g, "durations_s", 1, &nc, durations_s, "s",
                             "duration of each cycle (the weights of the ALL row of rel_diff)", err) ||
             wf_h5_write_f64(g, "grades_rad", 1, &ng, grades, "rad", "column grades of the tables", err) ||
             wf_h5_write_strings(g, "models", n_models, models, "energy models compared", err);
    for (size_t m = 0; !rc && m < n_models; m++) {
        char name[128];
        snprintf(name, sizeof name, "fuel_g_%s", models[m]);
        rc = wf_h5_write_f64(g, name, 2, dims, fuel_g + m * (n_cycles + 1) * n_grades, "g",
                             "fuel per cycle (rows) and grade (columns); last row ALL = sum over cycles", err);
    }
    if (!rc && rel_diff)
        rc = wf_h5_write_f64(g, "rel_diff", 2, dims, rel_diff, "1",
                             "(explicit - tabulated) / tabulated fuel; last row ALL: the duration-weighted mean of the "
                             "cycles' rows (the paper's rule)", err) ||
             wf_h5_write_f64(g, "rel_diff_total", 1, &ng, rel_total, "1",
                             "all cycles: (total explicit - total tabulated) / total tabulated fuel", err);
    free(rows);
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

int wf_cycle_out_commit(WfCycleOut **po, WfError *err)
{
    WfCycleOut *o = *po;
    *po = NULL;
    if (!o) return 0;
    int rc = wf_h5_commit(&o->f, err);
    free(o);
    return rc;
}

void wf_cycle_out_abandon(WfCycleOut **po)
{
    WfCycleOut *o = *po;
    *po = NULL;
    if (!o) return;
    wf_h5_abandon(&o->f, 1);
    free(o);
}
