/* `wavefuel energy`: the CIRCLES model (or any class's model) evaluated at CSV points v,a,theta. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/commands.h"
#include "cli/options.h"
#include "wavefuel/csv.h"
#include "wavefuel/domain.h"
#include "wavefuel/vehicle.h"

/* The input columns, in WfPointVar order (domain.h). */
static const char *const columns[WF_N_POINT_VARS] = {"v", "a", "theta"};

static void help(FILE *out)
{
    fprintf(out,
            "usage: wavefuel energy --class NAME|FILE.yaml [--project] [FILE|-]\n"
            "       wavefuel energy --list\n\n"
            "Reads CSV rows v,a,theta (speed m/s, acceleration m/s^2, road grade rad; header optional, blank\n"
            "lines and '#' comments skipped) from FILE or standard input, and writes CSV\n"
            "v,a,theta,fuel_gps,power_kw,flag with 17 significant digits. flag: 0 feasible, 1 acceleration\n"
            "above a_max(v, theta). --project clips a to a_max before evaluating.\n"
            "Classes are found in $WAVEFUEL_VEHICLES (colon-separated), then in PREFIX/vehicles for this program\n"
            "PREFIX/bin/wavefuel (the repository's vehicles/).\n");
    /* The accepted ranges come from the table that `wavefuel cycle` checks too. */
    fprintf(out, "Numbers are decimal;");
    for (int k = 0; k < WF_N_POINT_VARS; k++)
        fprintf(out, " %s in [%g, %g] %s%s", columns[k], wf_point_range[k].min, wf_point_range[k].max,
                wf_point_range[k].unit, k + 1 < WF_N_POINT_VARS ? "," : ".\n");
}

static int list_classes(void)
{
    WfVehicleClass *all = NULL;
    size_t n = 0;
    WfError err = {0};
    if (wf_vehicle_list(&all, &n, &err)) return wf_cli_fail(&err);
    printf("%-16s %-6s %-9s %9s %13s %8s  %s\n", "class", "duty", "fuel", "mass_kg", "paper_mass_kg", "length_m",
           "file");
    for (size_t i = 0; i < n; i++) {
        char paper[32] = "-"; /* only where the paper's Table 1 differs from the release's header */
        if (!isnan(all[i].paper_mass_kg)) snprintf(paper, sizeof paper, "%.0f", all[i].paper_mass_kg);
        printf("%-16s %-6s %-9s %9.0f %13s %8.1f  %s\n", all[i].name, wf_duty_name(all[i].duty),
               wf_fuel_name(all[i].fuel), all[i].mass_kg, paper, all[i].length_m, all[i].path);
        wf_vehicle_free(&all[i]);
    }
    free(all);
    return 0;
}

int wf_cmd_energy(int argc, char **argv)
{
    static const struct option opts[] = {{"class", required_argument, 0, 'c'}, {"project", no_argument, 0, 'p'},
                                         {"list", no_argument, 0, 'l'},         {0, 0, 0, 0}};
    const char *cls = NULL;
    int project = 0, list = 0, o;
    WfCliOpts cli = {.cmd = "energy", .longopts = opts, .shortopts = "c:pl", .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'c': cls = optarg; break;
        case 'p': project = 1; break;
        case 'l': list = 1; break;
        default: return o == WF_CLI_DONE ? 0 : 2;
        }
    }
    if (list) return list_classes();
    if (!cls) return wf_cli_usage(&cli, 0, "--class NAME is required (see --list)");
    if (argc - optind > 1) return wf_cli_usage(&cli, 0, "one input file at most");
    const char *in = optind < argc ? argv[optind] : "-";
    WfError err = {0};
    WfVehicleClass vc;
    if (wf_vehicle_find(cls, &vc, &err)) return wf_cli_fail(&err);
    WfCsv csv;
    /* The columns are the model's point variables in WfPointVar order: v, a, theta. */
    static const WfRange *const ranges[] = {&wf_point_range[WF_POINT_SPEED], &wf_point_range[WF_POINT_ACCEL],
                                            &wf_point_range[WF_POINT_GRADE]};
    if (wf_csv_read(in, 3, columns, &csv, &err) || wf_csv_check_ranges(&csv, in, columns, ranges, &err)) {
        wf_csv_free(&csv); /* zeroed by a failed read: freeing it again is safe */
        wf_vehicle_free(&vc);
        return wf_cli_fail(&err);
    }
    size_t n = csv.n_rows;
    double *cols = malloc((4 * n + 1) * sizeof *cols);
    uint8_t *flag = malloc(n + 1);
    if (!cols || !flag) {
        free(cols);
        free(flag);
        wf_csv_free(&csv);
        wf_vehicle_free(&vc);
        wf_err(&err, WF_ESYS, "out of memory for %zu points", n);
        return wf_cli_fail(&err);
    }
    double *v = cols, *a = cols + n, *th = cols + 2 * n, *fuel = cols + 3 * n;
    for (size_t i = 0; i < n; i++) {
        v[i] = csv.data[3 * i];
        a[i] = csv.data[3 * i + 1];
        th[i] = csv.data[3 * i + 2];
    }
    wf_vehicle_fuel(&vc, n, v, a, th, project, fuel, flag);
    /* Everything is computed before the first byte is written: a bad row prints nothing. */
    printf("v,a,theta,fuel_gps,power_kw,flag\n");
    for (size_t i = 0; i < n; i++)
        printf("%.17g,%.17g,%.17g,%.17g,%.17g,%d\n", v[i], a[i], th[i], fuel[i], fuel[i] * vc.kw_per_gps, flag[i]);
    int rc = fflush(stdout) ? 1 : 0;
    free(cols);
    free(flag);
    wf_csv_free(&csv);
    wf_vehicle_free(&vc);
    if (rc) fprintf(stderr, "wavefuel energy: write error on standard output\n");
    return rc;
}
