/* `wavefuel cycle`: a vehicle class follows a drive cycle (fuel, distance, economy, infeasible time), or the
 * paper's validation protocol (every class on its duty's cycles and grades, every model available for the
 * class, a Markdown table and HDF5). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/commands.h"
#include "cli/options.h"
#include "util/numfmt.h"
#include "util/outpath.h"
#include "util/mem.h"
#include "wavefuel/cycle.h"
#include "wavefuel/domain.h"
#include "wavefuel/tabulated.h"

enum { MAX_TABLES = 64, MAX_GRADES = 16 };

static void help(FILE *out)
{
    fprintf(out,
            "usage: wavefuel cycle --class NAME|FILE.yaml [--grade RAD] [--scheme NAME] [--project|--no-project]\n"
            "                      [--table CLASS=TABLE.h5] [--cycles DIR] [-o FILE.h5 [--force]] CYCLE\n"
            "       wavefuel cycle --protocol [--class NAME]... [--table CLASS=TABLE.h5]... [--cycles DIR]\n"
            "                      [--scheme NAME] [--no-project] [-o FILE.h5 [--force]]\n\n"
            "One vehicle follows a speed trace CYCLE (CSV time_s,speed_mps, any sample rate): a path, or a name\n"
            "such as udds resolved as DIR/cycles/NAME.csv, DIR from --cycles, $WAVEFUEL_DATA, or ../shared/data\n"
            "next to the repository. A scheme turns the trace into samples (speed, acceleration, weight); fuel =\n"
            "sum f(v, a, theta) w and distance = sum v w over them. Reports fuel (g), distance (km), L/100 km,\n"
            "mpg and the share of time at infeasible accelerations.\n\n"
            "Schemes (--scheme NAME, default the first):\n");
    size_t n;
    const WfCycleScheme *sc = wf_cycle_schemes(&n);
    for (size_t i = 0; i < n; i++) fprintf(out, "  %-12s %s\n", sc[i].name, sc[i].summary);
    fprintf(out,
            "\nModels: the class's own model, plus a tabulated one when the class file names `table:` beside its\n"
            "polynomial or --table CLASS=TABLE.h5 is given (an imported table: wavefuel table import).\n"
            "Projection (a <- min(a, a_max)): one run uses each model's default (explicit off, tabulated on)\n"
            "unless --project or --no-project; the protocol projects every model, as the release's script does,\n"
            "unless --no-project.\n\n"
            "--protocol runs the paper's tables: light-duty classes on udds, hwfet, us06, wltc3 at grades\n"
            "-0.03..0.03 rad, heavy-duty classes on hhddt_cruise, hhddt_transient, hhddt_h65 at -0.02..0.02\n"
            "(0.01 steps; HHDDT high speed has no public file). Default classes: all found. Prints Markdown:\n"
            "fuel per cycle and grade, and (explicit - tabulated) / tabulated where both models exist; over all\n"
            "cycles (ALL) both as the duration-weighted mean of the cycles' values (the paper's rule) and as\n"
            "total fuel over total fuel. -o writes every run and the tables to HDF5 (never overwrites without\n"
            "--force). See docs/cycles.md.\n");
}

/* A class and the tabulated twin compared with it (when one is given). */
typedef struct Entry {
    WfVehicleClass cls;
    WfVehicleClass twin;
    int            has_twin;
} Entry;

typedef struct TableArg {
    const char *cls;
    const char *path;
    int         used;
} TableArg;

static void free_entries(Entry *e, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        wf_vehicle_free(&e[i].cls);
        if (e[i].has_twin) wf_vehicle_free(&e[i].twin);
    }
    free(e);
}

/* Attach the tabulated twin: --table CLASS=FILE first, else the class file's own `table:`. */
static int attach_twin(Entry *e, const char *given_as, TableArg *tables, size_t n_tables, WfError *err)
{
    const char *path = NULL;
    for (size_t i = 0; i < n_tables; i++)
        if (!strcmp(tables[i].cls, e->cls.name) || !strcmp(tables[i].cls, given_as)) {
            path = tables[i].path;
            tables[i].used = 1;
        }
    char from_file[4096];
    if (e->cls.model == &wf_energy_tabulated) {
        if (path)
            return wf_err(err, WF_EINPUT, "--table %s: class '%s' is already tabulated (%s)", given_as, e->cls.name,
                          e->cls.path);
        return 0;
    }
    if (!path) {
        int rc = wf_tabulated_class_table(&e->cls, from_file, sizeof from_file, err);
        if (rc) return rc;
        if (!from_file[0]) return 0;
        path = from_file;
    }
    int rc = wf_tabulated_class(&e->cls, path, &e->twin, err);
    if (rc) return rc;
    e->has_twin = 1;
    return 0;
}

static int add_class(Entry **entries, size_t *n, const char *name, TableArg *tables, size_t n_tables, WfError *err)
{
    Entry *p = realloc(*entries, (*n + 1) * sizeof *p);
    if (!p) return wf_err(err, WF_ESYS, "out of memory");
    *entries = p;
    Entry *e = &p[*n];
    memset(e, 0, sizeof *e);
    int rc = wf_vehicle_find(name, &e->cls, err);
    if (rc) return rc;
    for (size_t i = 0; i < *n; i++)
        if (!strcmp(p[i].cls.name, e->cls.name)) {
            wf_vehicle_free(&e->cls);
            return wf_err(err, WF_EINPUT, "class '%s' given twice", name);
        }
    (*n)++; /* counted now, so free_entries releases it whatever happens next */
    return attach_twin(e, name, tables, n_tables, err);
}

static int resolve_project(int choice, const WfVehicleClass *vc)
{
    return choice >= 0 ? choice : vc->model->project_default;
}

static const char *density_note(const WfVehicleClass *vc)
{
    double def = (vc->fuel == WF_FUEL_DIESEL ? WF_DIESEL_G_PER_GAL : WF_GASOLINE_G_PER_GAL) / WF_L_PER_US_GAL;
    return vc->fuel_density_g_per_l == def ? "the CIRCLES release's value" : "set in the class file";
}

/* ------------------------------------------------------------------------------------------------------- */

static int run_single(Entry *e, const char *cycle_arg, const char *data_dir, double theta, int project_choice,
                      const WfCycleScheme *scheme, const char *out_path, int force, const char *cmdline)
{
    WfError err = {0};
    char path[4096];
    WfCycle c;
    WfCycleSamples smp;
    const char *inputs[] = {path, e->cls.path};
    if (wf_cycle_resolve(cycle_arg, data_dir, path, sizeof path, &err) || wf_cycle_load(path, &c, &err))
        return wf_cli_fail(&err);
    if ((out_path && wf_output_check("-o", out_path, inputs, 2, &err)) || wf_cycle_samples(&c, scheme, &smp, &err)) {
        wf_cycle_free(&c);
        return wf_cli_fail(&err);
    }
    const WfVehicleClass *models[2] = {&e->cls, e->has_twin ? &e->twin : NULL};
    size_t n_models = e->has_twin ? 2 : 1;
    WfCycleRun runs[2];
    memset(runs, 0, sizeof runs);
    WfCycleOut *out = NULL;
    int rc = 0;
    for (size_t m = 0; m < n_models && !rc; m++)
        rc = wf_cycle_run(&c, &smp, models[m], theta, resolve_project(project_choice, models[m]), &runs[m], &err);
    if (!rc && out_path) rc = wf_cycle_out_create(out_path, force, cmdline, &out, &err);
    for (size_t m = 0; m < n_models && !rc && out; m++) rc = wf_cycle_out_run(out, models[m], &c, &runs[m], 1, &err);
    if (!rc && out) rc = wf_cycle_out_commit(&out, &err);
    if (!rc) {
        const WfVehicleClass *vc = &e->cls;
        printf("class     %s (%s): %s duty, %s, %s\n", vc->name, vc->label, wf_duty_name(vc->duty),
               wf_fuel_name(vc->fuel), vc->path);
        printf("cycle     %s: %s, %zu samples, %.6g s, %.3f km\n", c.name, c.path, c.n, wf_cycle_duration_s(&c),
               wf_cycle_distance_m(&c) / 1e3);
        printf("scheme    %s: %s; %zu samples\n", scheme->name, scheme->summary, smp.n);
        printf("grade     %.6g rad\n", theta);
        printf("density   %.1f g/L = %.0f g per US gallon (%s)\n", vc->fuel_density_g_per_l,
               vc->fuel_density_g_per_l * WF_L_PER_US_GAL, density_note(vc));
        printf("\n%-20s %-7s %12s %10s %8s %11s %14s\n", "model", "project", "fuel_g", "L/100km", "mpg", "infeasible",
               "outside_grid");
        for (size_t m = 0; m < n_models; m++) {
            const WfCycleRun *r = &runs[m];
            char outside[32] = "-";
            if (models[m]->model->n_outside) snprintf(outside, sizeof outside, "%zu of %zu", r->n_outside, r->n);
            printf("%-20s %-7s %12.3f %10.4f %8.3f %10.2f%% %14s\n", models[m]->model->name,
                   r->project ? "on" : "off", r->fuel_g, r->l_per_100km, r->mpg,
                   r->duration_s > 0 ? 100.0 * r->infeasible_s / r->duration_s : 0.0, outside);
        }
        if (out_path) printf("\nwrote %s\n", out_path);
    }
    wf_cycle_out_abandon(&out);
    for (size_t m = 0; m < n_models; m++) wf_cycle_run_free(&runs[m]);
    wf_cycle_samples_free(&smp);
    wf_cycle_free(&c);
    if (rc) return wf_cli_fail(&err);
    return fflush(stdout) ? 1 : 0;
}

/* ------------------------------------------------------------------------------------------------------- */

enum { MAX_CYCLES = 8 };

/* The protocol's cycles of one duty, loaded and sampled once for every class. */
typedef struct Duty {
    const char *const *names;
    size_t             n;
    int                needed;
    WfCycle            cyc[MAX_CYCLES];
    WfCycleSamples     smp[MAX_CYCLES];
} Duty;

/* Results of one class in the protocol: fuel[model][cycle + ALL][grade] (ALL: the sum), and where a tabulated
 * twin exists rel[cycle + ALL][grade] (ALL: the duration-weighted mean of the cycles' values, the paper's rule)
 * and rel_total[grade] (total fuel over total fuel); the clamped evaluations. */
typedef struct ClassResult {
    size_t  n_cycles, n_grades, n_models;
    double  grades[MAX_GRADES];
    double *fuel;      /* owned */
    double *rel;       /* owned; NULL with one model */
    double *rel_total; /* owned; NULL with one model */
    size_t  n_outside, n_evals_tab;
} ClassResult;

static double *fuel_at(const ClassResult *r, size_t m, size_t c, size_t g)
{
    return &r->fuel[(m * (r->n_cycles + 1) + c) * r->n_grades + g];
}

static void print_rel_row(const char *name, const char *label, const double *rel, size_t n_grades)
{
    printf("| %s | %s |", name, label);
    for (size_t g = 0; g < n_grades; g++) printf(" %+.3f %% |", 100.0 * rel[g]);
    printf("\n");
}

static void print_class_markdown(const Entry *e, const ClassResult *r, const char *const *cycles)
{
    const WfVehicleClass *models[2] = {&e->cls, e->has_twin ? &e->twin : NULL};
    printf("## %s (%s, %s duty, %s)\n\n| cycle | model |", e->cls.name, e->cls.label, wf_duty_name(e->cls.duty),
           wf_fuel_name(e->cls.fuel));
    for (size_t g = 0; g < r->n_grades; g++) printf(" %+.2f |", r->grades[g] == 0.0 ? 0.0 : r->grades[g]);
    printf("\n|---|---|");
    for (size_t g = 0; g < r->n_grades; g++) printf("---:|");
    printf("\n");
    for (size_t c = 0; c <= r->n_cycles; c++) {
        const char *name = c < r->n_cycles ? cycles[c] : "ALL";
        for (size_t m = 0; m < r->n_models; m++) {
            printf("| %s | %s%s |", name, models[m]->model->name, c < r->n_cycles ? "" : " (sum)");
            for (size_t g = 0; g < r->n_grades; g++) printf(" %.2f |", *fuel_at(r, m, c, g));
            printf("\n");
        }
        if (r->rel && c < r->n_cycles) print_rel_row(name, "rel. diff", &r->rel[c * r->n_grades], r->n_grades);
    }
    if (r->rel) {
        print_rel_row("ALL", "rel. diff, duration-weighted mean (paper)", &r->rel[r->n_cycles * r->n_grades],
                      r->n_grades);
        print_rel_row("ALL", "rel. diff, total fuel over total fuel", r->rel_total, r->n_grades);
    }
    if (r->n_evals_tab)
        printf("\nTabulated evaluations clamped to the table's edge: %zu of %zu.\n", r->n_outside, r->n_evals_tab);
    printf("\n");
}

/* Explicit (model 0) relative to the table (model 1) per cycle; ALL as the duration-weighted mean of those (the
 * paper's rule) and as total over total. */
static void relative_differences(ClassResult *r, const Duty *d)
{
    size_t G = r->n_grades, C = r->n_cycles;
    double total_s = 0.0;
    for (size_t c = 0; c < C; c++) total_s += wf_cycle_duration_s(&d->cyc[c]);
    for (size_t g = 0; g < G; g++) {
        double mean = 0.0;
        for (size_t c = 0; c < C; c++) {
            double rel = (*fuel_at(r, 0, c, g) - *fuel_at(r, 1, c, g)) / *fuel_at(r, 1, c, g);
            r->rel[c * G + g] = rel;
            mean += wf_cycle_duration_s(&d->cyc[c]) * rel;
        }
        r->rel[C * G + g] = mean / total_s;
        r->rel_total[g] = (*fuel_at(r, 0, C, g) - *fuel_at(r, 1, C, g)) / *fuel_at(r, 1, C, g);
    }
}

/* Every run of one class: its duty's cycles x grades x models, written to out when given. */
static int run_class(const Entry *e, const Duty *d, int project_choice, WfCycleOut *out, ClassResult *r,
                     WfError *err)
{
    const WfVehicleClass *models[2] = {&e->cls, e->has_twin ? &e->twin : NULL};
    r->n_models = e->has_twin ? 2 : 1;
    r->n_cycles = d->n;
    r->n_grades = wf_protocol_grades(e->cls.duty, r->grades, MAX_GRADES);
    size_t rows = r->n_cycles + 1;
    r->fuel = calloc(r->n_models * rows * r->n_grades, sizeof *r->fuel);
    if (e->has_twin) {
        r->rel = calloc(rows * r->n_grades, sizeof *r->rel);
        r->rel_total = calloc(r->n_grades, sizeof *r->rel_total);
    }
    if (!r->fuel || (e->has_twin && (!r->rel || !r->rel_total))) return wf_err(err, WF_ESYS, "out of memory");
    int rc = 0;
    for (size_t c = 0; c < r->n_cycles && !rc; c++)
        for (size_t g = 0; g < r->n_grades && !rc; g++)
            for (size_t m = 0; m < r->n_models && !rc; m++) {
                WfCycleRun run;
                /* The release's script projects every model (flag_project = true): so does the protocol. */
                rc = wf_cycle_run(&d->cyc[c], &d->smp[c], models[m], r->grades[g],
                                  project_choice >= 0 ? project_choice : 1, &run, err);
                if (rc) break;
                *fuel_at(r, m, c, g) = run.fuel_g;
                *fuel_at(r, m, r->n_cycles, g) += run.fuel_g; /* ALL: cycles added in a fixed order */
                if (models[m]->model->n_outside) {
                    r->n_outside += run.n_outside;
                    r->n_evals_tab += run.n;
                }
                if (out) rc = wf_cycle_out_run(out, models[m], &d->cyc[c], &run, 0, err);
                wf_cycle_run_free(&run);
            }
    if (!rc && r->rel) relative_differences(r, d);
    if (!rc && out) {
        const char *mnames[2] = {models[0]->model->name, r->n_models > 1 ? models[1]->model->name : NULL};
        double dur[MAX_CYCLES];
        for (size_t c = 0; c < r->n_cycles; c++) dur[c] = wf_cycle_duration_s(&d->cyc[c]);
        rc = wf_cycle_out_summary(out, e->cls.name, r->n_cycles, d->names, dur, r->n_grades, r->grades, r->n_models,
                                  mnames, r->fuel, r->rel, r->rel_total, err);
    }
    return rc;
}

/* Every cycle of the duties present, loaded and sampled before anything runs or is written: a missing file is
 * reported before any work. */
static int load_duties(Duty duty[2], const Entry *entries, size_t n_entries, const char *data_dir,
                       const WfCycleScheme *scheme, WfError *err)
{
    WfDuty which[2] = {WF_DUTY_LIGHT, WF_DUTY_HEAVY};
    for (int d = 0; d < 2; d++) {
        duty[d].names = wf_protocol_cycles(which[d], &duty[d].n);
        if (duty[d].n > MAX_CYCLES) return wf_err(err, WF_ESYS, "protocol: %zu cycles, room for %d", duty[d].n, MAX_CYCLES);
        for (size_t i = 0; i < n_entries; i++) duty[d].needed |= entries[i].cls.duty == which[d];
    }
    for (int d = 0; d < 2; d++)
        for (size_t k = 0; k < duty[d].n && duty[d].needed; k++) {
            char path[4096];
            int rc = wf_cycle_resolve(duty[d].names[k], data_dir, path, sizeof path, err);
            if (!rc) rc = wf_cycle_load(path, &duty[d].cyc[k], err);
            if (!rc && (rc = wf_cycle_samples(&duty[d].cyc[k], scheme, &duty[d].smp[k], err)))
                wf_cycle_free(&duty[d].cyc[k]);
            if (rc) return rc;
        }
    return 0;
}

static void free_duties(Duty duty[2])
{
    for (int d = 0; d < 2; d++)
        for (size_t k = 0; k < duty[d].n; k++) {
            wf_cycle_samples_free(&duty[d].smp[k]);
            wf_cycle_free(&duty[d].cyc[k]);
        }
}

static void print_protocol(const Entry *entries, size_t n_entries, const ClassResult *res, const Duty duty[2],
                           const char *data_dir, int project_choice, const WfCycleScheme *scheme, const char *out_path)
{
    printf("# wavefuel cycle --protocol\n\n");
    printf("Fuel in g per drive cycle (rows) and road grade in rad (columns). rel. diff = (explicit - tabulated) / "
           "tabulated. ALL: fuel summed over the cycles; rel. diff both as the duration-weighted mean of the cycles' "
           "values (the paper's ALL rows) and as total fuel over total fuel. Scheme %s: %s. Projection: %s. "
           "Cycles from %s/cycles. HHDDT high speed is not run: no public 1 Hz file exists (docs/cycles.md).\n\n",
           scheme->name, scheme->summary,
           project_choice == 0 ? "off for every model (--no-project)"
                               : "on for every model (as the release's script)",
           data_dir);
    for (size_t i = 0; i < n_entries; i++)
        print_class_markdown(&entries[i], &res[i], duty[entries[i].cls.duty == WF_DUTY_HEAVY].names);
    if (out_path) printf("Wrote %s.\n", out_path);
}

static int run_protocol(Entry *entries, size_t n_entries, const char *data_dir, int project_choice,
                        const WfCycleScheme *scheme, const char *out_path, int force, const char *cmdline)
{
    WfError err = {0};
    Duty duty[2];
    memset(duty, 0, sizeof duty);
    ClassResult *res = calloc(n_entries ? n_entries : 1, sizeof *res);
    WfCycleOut *out = NULL;
    if (!res) {
        wf_err(&err, WF_ESYS, "out of memory");
        return wf_cli_fail(&err);
    }
    int rc = load_duties(duty, entries, n_entries, data_dir, scheme, &err);
    if (!rc && out_path) rc = wf_cycle_out_create(out_path, force, cmdline, &out, &err);
    for (size_t i = 0; i < n_entries && !rc; i++)
        rc = run_class(&entries[i], &duty[entries[i].cls.duty == WF_DUTY_HEAVY], project_choice, out, &res[i], &err);
    if (!rc && out) rc = wf_cycle_out_commit(&out, &err);
    /* Everything ran: only now is the report printed, so a failure prints nothing half-done. */
    if (!rc) print_protocol(entries, n_entries, res, duty, data_dir, project_choice, scheme, out_path);
    wf_cycle_out_abandon(&out);
    for (size_t i = 0; i < n_entries; i++) WF_FREE(res[i].fuel, res[i].rel, res[i].rel_total);
    free(res);
    free_duties(duty);
    if (rc) return wf_cli_fail(&err);
    return fflush(stdout) ? 1 : 0;
}

/* ------------------------------------------------------------------------------------------------------- */

/* The classes to drive: the --class ones, else every class on the search path; each --table must name one. */
static int load_entries(const char *const *classes, size_t n_classes, TableArg *tables, size_t n_tables,
                        Entry **out, size_t *n_out, WfError *err)
{
    Entry *entries = NULL;
    size_t n_entries = 0;
    int rc = 0;
    if (n_classes) {
        for (size_t i = 0; i < n_classes && !rc; i++)
            rc = add_class(&entries, &n_entries, classes[i], tables, n_tables, err);
    } else {
        WfVehicleClass *all = NULL;
        size_t n_all = 0;
        rc = wf_vehicle_list(&all, &n_all, err);
        for (size_t i = 0; i < n_all; i++) {
            if (!rc) rc = add_class(&entries, &n_entries, all[i].path, tables, n_tables, err);
            wf_vehicle_free(&all[i]);
        }
        free(all);
        if (!rc && n_entries == 0) rc = wf_err(err, WF_EINPUT, "no vehicle classes found");
    }
    for (size_t i = 0; i < n_tables && !rc; i++)
        if (!tables[i].used)
            rc = wf_err(err, WF_EINPUT, "--table %s=%s: no class '%s' in this run", tables[i].cls, tables[i].path,
                        tables[i].cls);
    *out = entries;
    *n_out = n_entries;
    return rc;
}

int wf_cmd_cycle(int argc, char **argv)
{
    static const struct option opts[] = {{"class", required_argument, 0, 'c'},  {"grade", required_argument, 0, 'g'},
                                         {"project", no_argument, 0, 'p'},      {"no-project", no_argument, 0, 'P'},
                                         {"output", required_argument, 0, 'o'}, {"force", no_argument, 0, 'f'},
                                         {"cycles", required_argument, 0, 'd'}, {"protocol", no_argument, 0, 'R'},
                                         {"table", required_argument, 0, 't'},  {"scheme", required_argument, 0, 's'},
                                         {0, 0, 0, 0}};
    const char *classes[64], *out_path = NULL, *cycles_dir = NULL, *grade_arg = NULL, *scheme_arg = NULL;
    size_t n_classes = 0, n_tables = 0;
    TableArg tables[MAX_TABLES];
    int project = -1, force = 0, protocol = 0, o;
    char cmdline[4096];
    wf_cli_join_args(argc, argv, cmdline, sizeof cmdline);
    static const char *const conflicts[] = {"pP", NULL};
    WfCliOpts cli = {.cmd = "cycle", .longopts = opts, .shortopts = "c:g:o:f", .repeatable = "ct",
                     .conflicts = conflicts, .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'c':
            if (n_classes == sizeof classes / sizeof classes[0])
                return wf_cli_usage(&cli, 0, "too many --class options");
            classes[n_classes++] = optarg;
            break;
        case 'g': grade_arg = optarg; break;
        case 'p': project = 1; break;
        case 'P': project = 0; break;
        case 'o': out_path = optarg; break;
        case 'f': force = 1; break;
        case 'd': cycles_dir = optarg; break;
        case 'R': protocol = 1; break;
        case 's': scheme_arg = optarg; break;
        case 't': {
            char *eq = strchr(optarg, '=');
            if (!eq || eq == optarg || !eq[1] || n_tables == MAX_TABLES)
                return wf_cli_usage(&cli, 0, "--table expects CLASS=TABLE.h5 (got '%s')", optarg);
            *eq = '\0';
            tables[n_tables++] = (TableArg){optarg, eq + 1, 0};
            break;
        }
        default: return o == WF_CLI_DONE ? 0 : 2;
        }
    }
    double theta = 0.0;
    if (grade_arg) {
        if (protocol) return wf_cli_usage(&cli, 0, "--grade does not apply to --protocol (it runs the paper's grades)");
        const WfRange *g = &wf_point_range[WF_POINT_GRADE]; /* the grades `wavefuel energy` accepts too */
        if (wf_parse_double(grade_arg, &theta) || !(theta >= g->min && theta <= g->max))
            return wf_cli_usage(&cli, 0, "--grade expects a road grade angle in [%s, %s] %s (got '%s')",
                                WF_NUM(g->min), WF_NUM(g->max), g->unit, grade_arg);
        if (theta == 0.0) theta = 0.0; /* -0 and 0 are the same grade: one group name in HDF5 */
    }
    if (protocol && optind != argc)
        return wf_cli_usage(&cli, 0, "--protocol takes no CYCLE argument (it runs the paper's cycles)");
    if (!protocol && (n_classes != 1 || argc - optind != 1))
        return wf_cli_usage(&cli, 0, "give one --class NAME and one CYCLE (or --protocol); see --help");
    WfError err = {0};
    size_t n_schemes;
    const WfCycleScheme *scheme = scheme_arg ? wf_cycle_scheme_find(scheme_arg, &err) : wf_cycle_schemes(&n_schemes);
    if (!scheme) return wf_cli_fail(&err);
    char data_dir[4096];
    int found = 0;
    char dflt[4096];
    int have_dflt = wf_cli_data_default(dflt, sizeof dflt) == 0;
    const char *env = getenv("WAVEFUEL_DATA"), *given = cycles_dir ? cycles_dir : env && *env ? env : NULL;
    if (wf_cycle_data_dir(given, cycles_dir ? "--cycles" : "$WAVEFUEL_DATA", have_dflt ? dflt : NULL, data_dir,
                          sizeof data_dir, &found, &err))
        return wf_cli_fail(&err);
    Entry *entries = NULL;
    size_t n_entries = 0;
    int rc = load_entries(classes, n_classes, tables, n_tables, &entries, &n_entries, &err);
    /* The protocol's inputs are the classes (the cycles are the data directory's): the result must not replace one. */
    for (size_t i = 0; !rc && protocol && out_path && i < n_entries; i++)
        rc = wf_output_check("-o", out_path, (const char *[]){entries[i].cls.path}, 1, &err);
    if (rc) {
        free_entries(entries, n_entries);
        return wf_cli_fail(&err);
    }
    int status = protocol ? run_protocol(entries, n_entries, data_dir, project, scheme, out_path, force, cmdline)
                          : run_single(&entries[0], argv[optind], data_dir, theta, project, scheme, out_path, force,
                                       cmdline);
    free_entries(entries, n_entries);
    return status;
}
