/* `wavefuel table`: import a CIRCLES semi-principled table (CSV) into wavefuel's compressed HDF5 form,
 * describe an imported table, and sample an explicit class on the release's grid (the input of an end-to-end
 * check of `wavefuel fit`). */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"
#include "cli/options.h"
#include "util/clock.h"
#include "util/outpath.h"
#include "wavefuel/fit.h"
#include "wavefuel/tabulated.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: wavefuel table import IN.csv -o OUT.h5 [--force]\n"
            "       wavefuel table info TABLE.h5\n"
            "       wavefuel table sample --class NAME|FILE.yaml -o TABLE.csv|TABLE.h5 [--force]\n\n"
            "import reads a semi-principled model table in the CIRCLES release's format (header\n"
            "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible; m/s, m/s^2, rad, g/s, 0/1; rows in any\n"
            "order), checks that the rows form a complete regular grid (axes may be unevenly spaced) and writes\n"
            "it as compressed HDF5 with the grid, the source file and checksums. OUT.h5 is never overwritten\n"
            "without --force.\n"
            "A vehicle class then names it: `energy_model: tabulated` and `table: OUT.h5` (see docs/cycles.md).\n"
            "info loads a table (checksum verified) and prints its grid.\n"
            "sample evaluates a class's model on the release's grid (speed 0..35 m/s by 0.35, acceleration\n"
            "-4..4 m/s^2 by 0.08, grade -0.03..0.03 rad by 0.003), with projection, as the release's tables are\n"
            "made, and writes the table as release-format CSV (.csv) or as HDF5 (any other name); `wavefuel fit`\n"
            "then fits it back (docs/fit.md).\n");
}

static void describe(const WfTable *t)
{
    printf("grid     %zu speeds [%.15g, %.15g] m/s x %zu accelerations [%.15g, %.15g] m/s^2 x %zu grades "
           "[%.15g, %.15g] rad = %zu points\n",
           t->v.n, t->v.lo, t->v.hi, t->a.n, t->a.lo, t->a.hi, t->theta.n, t->theta.lo, t->theta.hi,
           t->v.n * t->a.n * t->theta.n);
    size_t n = t->v.n * t->a.n * t->theta.n, n_inf = 0;
    for (size_t i = 0; i < n; i++) n_inf += t->infeasible[i] != 0;
    printf("infeasible nodes %zu of %zu\n", n_inf, n);
    printf("source   %s (FNV-1a 64 %016llx)\n", t->source, (unsigned long long)t->source_fnv1a64);
    printf("checksum %016llx\n", (unsigned long long)t->data_fnv1a64);
}

static int cmd_import(int argc, char **argv)
{
    static const struct option opts[] = {{"output", required_argument, 0, 'o'},
                                         {"force", no_argument, 0, 'f'},
                                         {0, 0, 0, 0}};
    const char *out = NULL;
    int force = 0, o;
    WfCliOpts cli = {.cmd = "table import", .longopts = opts, .shortopts = "o:f", .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'o': out = optarg; break;
        case 'f': force = 1; break;
        default: return o == WF_CLI_DONE ? 0 : 2;
        }
    }
    if (argc - optind != 1 || !out) return wf_cli_usage(&cli, 0, "one input CSV and -o OUT.h5 are required");
    WfError err = {0};
    WfTable *t = NULL, *back = NULL;
    const char *input = argv[optind];
    int rc = wf_output_check("-o", out, &input, 1, &err);
    if (!rc) rc = wf_table_read_csv(input, &t, &err);
    if (!rc) rc = wf_table_write_h5(t, out, force, &err);
    /* Read the file back as every user of it will, so a table that imports also loads. */
    double t0 = wf_wall_now();
    if (!rc) rc = wf_table_load_h5(out, &back, &err);
    double load_s = wf_wall_now() - t0;
    if (rc) {
        wf_table_destroy(&t);
        return wf_cli_fail(&err);
    }
    describe(back);
    printf("wrote    %s (loads in %.1f ms)\n", out, 1e3 * load_s);
    wf_table_destroy(&t);
    wf_table_destroy(&back);
    return 0;
}

static int cmd_info(int argc, char **argv)
{
    static const struct option none[] = {{0, 0, 0, 0}};
    WfCliOpts cli = {.cmd = "table info", .longopts = none, .shortopts = "", .help = help};
    int o = wf_cli_getopt(&cli, argc, argv, 0);
    if (o != -1) return o == WF_CLI_DONE ? 0 : 2;
    if (argc - optind != 1) return wf_cli_usage(&cli, 0, "one TABLE.h5 argument");
    WfError err = {0};
    WfTable *t = NULL;
    if (wf_table_load_h5(argv[optind], &t, &err)) return wf_cli_fail(&err);
    describe(t);
    wf_table_destroy(&t);
    return 0;
}

static int cmd_sample(int argc, char **argv)
{
    static const struct option opts[] = {{"class", required_argument, 0, 'c'},
                                         {"output", required_argument, 0, 'o'},
                                         {"force", no_argument, 0, 'f'},
                                         {0, 0, 0, 0}};
    const char *cls = NULL, *out = NULL;
    int force = 0, o;
    WfCliOpts cli = {.cmd = "table sample", .longopts = opts, .shortopts = "c:o:f", .help = help};
    while ((o = wf_cli_getopt(&cli, argc, argv, 0)) != -1) {
        switch (o) {
        case 'c': cls = optarg; break;
        case 'o': out = optarg; break;
        case 'f': force = 1; break;
        default: return o == WF_CLI_DONE ? 0 : 2;
        }
    }
    if (argc != optind || !cls || !out)
        return wf_cli_usage(&cli, 0, "--class NAME and -o TABLE.csv|TABLE.h5 are required");
    WfError err = {0};
    WfVehicleClass vc;
    if (wf_vehicle_find(cls, &vc, &err)) return wf_cli_fail(&err);
    const char *input = vc.path;
    if (wf_output_check("-o", out, &input, 1, &err)) {
        wf_vehicle_free(&vc);
        return wf_cli_fail(&err);
    }
    WfFitGrid g;
    wf_fit_release_grid(&g);
    char source[1200];
    snprintf(source, sizeof source, "wavefuel table sample --class %s (%s), the release's grid", vc.name, vc.path);
    WfTable *t = NULL;
    int rc = wf_fit_sample_class(&vc, &g, source, &t, &err);
    size_t len = strlen(out);
    if (!rc) rc = len > 4 && !strcmp(out + len - 4, ".csv") ? wf_fit_write_table_csv(t, out, force, &err)
                                                            : wf_table_write_h5(t, out, force, &err);
    if (!rc) {
        describe(t);
        printf("wrote    %s\n", out);
    }
    wf_table_destroy(&t);
    wf_vehicle_free(&vc);
    return rc ? wf_cli_fail(&err) : 0;
}

int wf_cmd_table(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        help(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (argv[1][0] == '-') { /* an option before the action: -V, or unknown as in every command */
        static const struct option none[] = {{0, 0, 0, 0}};
        WfCliOpts cli = {.cmd = "table", .longopts = none, .shortopts = ""};
        return wf_cli_getopt(&cli, argc, argv, 0) == WF_CLI_DONE ? 0 : 2;
    }
    if (!strcmp(argv[1], "import")) return cmd_import(argc - 1, argv + 1);
    if (!strcmp(argv[1], "info")) return cmd_info(argc - 1, argv + 1);
    if (!strcmp(argv[1], "sample")) return cmd_sample(argc - 1, argv + 1);
    fprintf(stderr, "wavefuel table: unknown action '%s' (import, info, sample)\n", argv[1]);
    return 2;
}
