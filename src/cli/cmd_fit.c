/* `wavefuel fit`: derive an explicit CIRCLES class model from a tabulated one (the paper's model reduction,
 * docs/fit.md), print a report of each step and, with -o, write the vehicle class file. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/commands.h"
#include "cli/options.h"
#include "util/outpath.h"
#include "util/path.h"
#include "util/registry.h"
#include "wavefuel/fit.h"

/* kW per g/s when neither --kw-per-gps nor --like gives one: the CIRCLES release's values (its model files'
 * gs2kW: 42.36 for the gasoline classes, 42.47 for the diesel ones). */
#define KW_PER_GPS_GASOLINE 42.36
#define KW_PER_GPS_DIESEL   42.47

static void help(FILE *out)
{
    fprintf(out,
            "usage: wavefuel fit TABLE [--duty light|heavy|auto] [--pq paper|joint]\n"
            "                      [-o vehicles/NAME.yaml [--force]] [--like CLASS] [--name LABEL]\n"
            "                      [--fuel gasoline|diesel] [--mass-kg M] [--length-m L] [--kw-per-gps K]\n\n"
            "Fits the CIRCLES explicit (physics-like) model to a tabulated model, as Khoudari et al. do:\n"
            "fuel cut (v_c, beta, a0..a4), C(v), P(v), Q(v), Z(v) by non-negative least squares, the\n"
            "feasible-acceleration bound (b1..b6, nonlinear), f_idle; heavy duty (no fuel cut below 35 m/s, or\n"
            "--duty heavy) fits the lower bound h0 + h1 v instead. TABLE is an imported table (.h5, `wavefuel\n"
            "table import`) or a CSV in the release's format. Prints each step's parameters, RMS residual and\n"
            "points used.\n\n"
            "--pq paper (default): the paper's steps, P(v) on a in [-0.3, 0.3] (heavy duty [0, 0.3]) without Q,\n"
            "then Q(v) with P fixed. --pq joint: p0..p2, q0, q1 in one NNLS on a in [0, 3] (recovers the\n"
            "heavy-duty classes' P and Q, which the paper's one-sided heavy-duty range trades against each\n"
            "other).\n\n"
            "-o writes the vehicle class file (never over an existing one without --force). A table holds no\n"
            "mass or length: give --mass-kg and --length-m, or --like CLASS to copy fuel, mass, length, kW per\n"
            "g/s and fuel density from a class (options given explicitly win). Defaults: fuel gasoline for\n"
            "light duty and diesel for heavy; kW per g/s 42.36 (gasoline) or 42.47 (diesel), the release's.\n"
            "Steps, ranges and accuracy: docs/fit.md.\n");
}

static void print_report(const WfTable *t, const char *table_path, const WfFitResult *r)
{
    const WfCirclesParams *p = &r->params;
    printf("table    %s: %zu speeds [%.15g, %.15g] m/s x %zu accelerations [%.15g, %.15g] m/s^2 x %zu grades "
           "[%.15g, %.15g] rad\n",
           table_path, t->v.n, t->v.lo, t->v.hi, t->a.n, t->a.lo, t->a.hi, t->theta.n, t->theta.lo, t->theta.hi);
    printf("source   %s (checksum %016llx)\n", r->table_source, (unsigned long long)r->table_checksum);
    if (r->duty == WF_DUTY_LIGHT)
        printf("duty     light (%s: the fuel rate at a = -3 m/s^2 on flat road reaches 0 at %.6g m/s)\n\n",
               r->duty_detected ? "detected" : "forced", p->v_c);
    else
        printf("duty     heavy (%s%s)\n\n", r->duty_detected ? "detected: " : "forced by --duty",
               r->duty_detected ? "no fuel cut below 35 m/s" : "");
    printf("%-16s %-16s %12s %12s %-7s %15s\n", "step", "parameters", "RMS resid.", "max |resid.|", "unit",
           "points used");
    for (int k = 0; k < WF_FIT_N_STEPS; k++) {
        const WfFitStep *s = &r->step[k];
        if (!s->done) continue;
        char pts[48];
        snprintf(pts, sizeof pts, "%zu of %zu", s->n_used, s->n_points);
        if (isnan(s->rms))
            printf("%-16s %-16s %12s %12s %-7s %15s\n", s->key, s->params, "-", "-", s->unit,
                   k == WF_FIT_STEP_CUT_SPEED ? "1 (bisection)" : "1");
        else
            printf("%-16s %-16s %12.4g %12.4g %-7s %15s\n", s->key, s->params, s->rms, s->max_abs, s->unit, pts);
    }
    printf("\nfitted parameters\n");
    for (size_t k = 0; k < wf_energy_circles.n_spec; k++) {
        const WfParamSpec *sp = &wf_energy_circles.spec[k];
        double x = wf_param_get(p, sp);
        if (isnan(x)) continue;
        printf("  %-6s %-14.8g %s\n", sp->key, x, sp->unit);
    }
    printf("\nfuel rate, fitted model - table, over the %zu points of steps C, %s, Z: RMS %.4g g/s, max %.4g g/s\n",
           r->fuel_n, r->pq == WF_FIT_PQ_JOINT ? "PQ" : "P, Q", r->fuel_rms_gps, r->fuel_max_gps);
}

static int parse_num(const char *opt, const char *s, double *out)
{
    if (wf_parse_double(s, out) != 0) {
        fprintf(stderr, "wavefuel fit: %s expects a number (got '%s')\n", opt, s);
        return 2;
    }
    return 0;
}

/* The index of s in names (NULL-terminated), the value of the option's enum; else a usage error saying what the
 * option takes (`takes`). */
static int parse_choice(const char *opt, const char *s, const char *const *names, const char *takes, int *out)
{
    long i = wf_registry_find((const void *const *)names, WF_REG_STRINGS, s, "", NULL);
    if (i >= 0) {
        *out = (int)i;
        return 0;
    }
    fprintf(stderr, "wavefuel fit: %s must be %s (got '%s')\n", opt, takes, s);
    return 2;
}

/* In the order of their enums (WfFitDuty, WfFitPQ, WfFuelType). */
static const char *const duties[] = {"auto", "light", "heavy", NULL};
static const char *const pqs[] = {"paper", "joint", NULL};
static const char *const fuels[] = {"gasoline", "diesel", NULL};
_Static_assert(WF_FIT_DUTY_LIGHT == 1 && WF_FIT_DUTY_HEAVY == 2 && WF_FIT_PQ_JOINT == 1 && WF_FUEL_DIESEL == 1,
               "the choices' order is their enums'");

typedef struct FitArgs {
    const char *out, *like, *label, *table_path;
    WfFitOptions opt;
    int         force, fuel; /* fuel: a WfFuelType, or -1 when not given */
    double      mass, length, kw; /* NAN when not given */
} FitArgs;

/* Returns 0, -1 after --help (exit status 0) or 2 after a usage error. */
static int parse_args(int argc, char **argv, FitArgs *a)
{
    static const struct option opts[] = {{"duty", required_argument, 0, 'd'},
                                         {"pq", required_argument, 0, 'P'},
                                         {"output", required_argument, 0, 'o'},
                                         {"force", no_argument, 0, 'f'},
                                         {"like", required_argument, 0, 'L'},
                                         {"name", required_argument, 0, 'n'},
                                         {"fuel", required_argument, 0, 'F'},
                                         {"mass-kg", required_argument, 0, 'm'},
                                         {"length-m", required_argument, 0, 'l'},
                                         {"kw-per-gps", required_argument, 0, 'k'},
                                         {0, 0, 0, 0}};
    *a = (FitArgs){.opt = {.duty = WF_FIT_DUTY_AUTO, .pq = WF_FIT_PQ_PAPER},
                   .fuel = -1, .mass = NAN, .length = NAN, .kw = NAN};
    int o, v;
    WfCliOpts cli = {.cmd = "fit", .longopts = opts, .shortopts = "o:f", .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'd':
            if (parse_choice("--duty", optarg, duties, "light, heavy or auto", &v)) return 2;
            a->opt.duty = (WfFitDuty)v;
            break;
        case 'P':
            if (parse_choice("--pq", optarg, pqs, "paper or joint", &v)) return 2;
            a->opt.pq = (WfFitPQ)v;
            break;
        case 'o': a->out = optarg; break;
        case 'f': a->force = 1; break;
        case 'L': a->like = optarg; break;
        case 'n': a->label = optarg; break;
        case 'F':
            if (parse_choice("--fuel", optarg, fuels, "gasoline or diesel", &a->fuel)) return 2;
            break;
        case 'm':
            if (parse_num("--mass-kg", optarg, &a->mass)) return 2;
            break;
        case 'l':
            if (parse_num("--length-m", optarg, &a->length)) return 2;
            break;
        case 'k':
            if (parse_num("--kw-per-gps", optarg, &a->kw)) return 2;
            break;
        default: return o == WF_CLI_DONE ? -1 : 2;
        }
    }
    if (argc - optind != 1)
        return wf_cli_usage(&cli, 0, "one TABLE argument (an imported .h5 table or a release-format CSV)");
    a->table_path = argv[optind];
    return 0;
}

/* Write the fitted class to a->out (metadata from the options, else --like's class `base`, else the fuel's
 * defaults) and read it back as every user of it will, so a class that is written also loads. */
static int write_class(int argc, char **argv, const FitArgs *a, const WfFitResult *r, const WfVehicleClass *base,
                       int have_base, WfError *err)
{
    WfFitClassInfo info = {0};
    int fuel = a->fuel;
    info.fuel = fuel >= 0 ? (WfFuelType)fuel
                : have_base ? base->fuel
                            : (r->duty == WF_DUTY_HEAVY ? WF_FUEL_DIESEL : WF_FUEL_GASOLINE);
    info.mass_kg = !isnan(a->mass) ? a->mass : base->mass_kg;
    info.length_m = !isnan(a->length) ? a->length : base->length_m;
    info.kw_per_gps = !isnan(a->kw) ? a->kw
                      : have_base && (fuel < 0 || (WfFuelType)fuel == base->fuel)
                          ? base->kw_per_gps
                          : (info.fuel == WF_FUEL_DIESEL ? KW_PER_GPS_DIESEL : KW_PER_GPS_GASOLINE);
    /* A density copied from --like only when the fuel is the same and the class set its own (the fuel's
     * default is what the loader gives when none is written). */
    double default_density =
        (base->fuel == WF_FUEL_DIESEL ? WF_DIESEL_G_PER_GAL : WF_GASOLINE_G_PER_GAL) / WF_L_PER_US_GAL;
    info.fuel_density_g_per_l = have_base && info.fuel == base->fuel && base->fuel_density_g_per_l != default_density
                                    ? base->fuel_density_g_per_l
                                    : NAN;
    char stem[256], default_label[600], command[4096];
    snprintf(stem, sizeof stem, "%s", wf_path_base(a->out));
    char *dot = strrchr(stem, '.');
    if (dot) *dot = '\0';
    snprintf(default_label, sizeof default_label, "%s (fitted from %s)", stem, wf_path_base(a->table_path));
    info.label = a->label ? a->label : default_label;
    info.table_path = a->table_path;
    wf_cli_join_args(argc, argv, command, sizeof command);
    info.command = command;
    int rc = wf_fit_write_class(r, &info, a->out, a->force, err);
    WfVehicleClass back;
    if (!rc) rc = wf_vehicle_load(a->out, &back, err);
    if (!rc) {
        printf("wrote    %s (class %s: %s duty, %s, %.6g kg, %.6g m, %.6g kW per g/s)\n", a->out, back.name,
               wf_duty_name(back.duty), wf_fuel_name(back.fuel), back.mass_kg, back.length_m, back.kw_per_gps);
        wf_vehicle_free(&back);
    }
    return rc;
}

int wf_cmd_fit(int argc, char **argv)
{
    FitArgs a;
    int status = parse_args(argc, argv, &a);
    if (status) return status < 0 ? 0 : status;
    const char *table_path = a.table_path;
    WfError err = {0};
    WfVehicleClass base;
    int have_base = 0;
    memset(&base, 0, sizeof base);
    if (a.like) {
        if (wf_vehicle_find(a.like, &base, &err)) return wf_cli_fail(&err);
        have_base = 1;
    }
    /* The class written must not replace the table or the --like class (src/util/outpath.c). */
    if (a.out && wf_output_check("-o", a.out, (const char *[]){table_path, have_base ? base.path : NULL}, 2, &err)) {
        if (have_base) wf_vehicle_free(&base);
        return wf_cli_fail(&err);
    }
    /* Check the metadata before the fit, so a missing option does not cost a fit. */
    if (a.out && !have_base && (isnan(a.mass) || isnan(a.length))) {
        fprintf(stderr, "wavefuel fit: -o needs the vehicle's mass and length, which a table does not hold: give "
                        "--mass-kg and --length-m, or --like CLASS to copy them from a class\n");
        return 2;
    }
    size_t len = strlen(table_path);
    WfTable *t = NULL;
    int rc = len > 4 && !strcmp(table_path + len - 4, ".csv") ? wf_table_read_csv(table_path, &t, &err)
                                                             : wf_table_load_h5(table_path, &t, &err);
    WfFitResult r;
    if (!rc) rc = wf_fit_table(t, &a.opt, &r, &err);
    if (rc) {
        wf_table_destroy(&t);
        if (have_base) wf_vehicle_free(&base);
        return wf_cli_fail(&err);
    }
    print_report(t, table_path, &r);
    wf_table_destroy(&t);
    if (a.out) rc = write_class(argc, argv, &a, &r, &base, have_base, &err);
    if (have_base) wf_vehicle_free(&base);
    return rc ? wf_cli_fail(&err) : 0;
}
