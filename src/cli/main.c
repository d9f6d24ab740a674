/* wavefuel: command-line entry point. Only dispatches to a subcommand; each lives in src/cli/. */
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"
#include "wavefuel/version.h"

static const WfCommand commands[] = {
    {"run", "simulate a scenario and write an HDF5 result", wf_cmd_run},
    {"info", "print the summary of a result file", wf_cmd_info},
    {"sweep", "run a sweep or ensemble of runs into one result table (also across MPI ranks)", wf_cmd_sweep},
    {"energy", "evaluate a vehicle class's fuel rate at (v, a, theta) points", wf_cmd_energy},
    {"cycle", "drive a vehicle class over a drive cycle, or run the paper's validation protocol", wf_cmd_cycle},
    {"table", "import a tabulated (semi-principled) energy model: CSV -> HDF5", wf_cmd_table},
    {"fit", "derive an explicit vehicle class model from a tabulated one (model reduction)", wf_cmd_fit},
};
enum { N_COMMANDS = sizeof commands / sizeof commands[0] };

static void usage(FILE *out)
{
    fprintf(out, "wavefuel %s: parallel simulator of traffic energy\n\nusage: wavefuel COMMAND [options]\n\n",
            WF_VERSION);
    for (int i = 0; i < N_COMMANDS; i++) fprintf(out, "  %-8s %s\n", commands[i].name, commands[i].summary);
    fprintf(out, "\n'wavefuel help COMMAND' (or 'wavefuel COMMAND --help') describes each command; -V or --version, "
                 "also after a command, prints the version.\n");
}

/* The command called `name`; NULL after saying that there is none. */
static const WfCommand *find(const char *name)
{
    for (int i = 0; i < N_COMMANDS; i++)
        if (!strcmp(name, commands[i].name)) return &commands[i];
    fprintf(stderr, "wavefuel: unknown command '%s'\n", name);
    usage(stderr);
    return NULL;
}

int main(int argc, char **argv)
{
    WfError err = {0};
    if (wf_cli_process_init(argv[0], &err)) return wf_cli_fail(&err);
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    /* `wavefuel help CMD [ACTION]` is `wavefuel CMD [ACTION] --help`, for every command. */
    if (!strcmp(argv[1], "help") && (argc == 3 || argc == 4)) {
        char help_opt[] = "--help";
        char *args[] = {argv[2], argc == 4 ? argv[3] : help_opt, help_opt, NULL};
        const WfCommand *cmd = find(argv[2]);
        return cmd ? cmd->main(argc - 1, args) : 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version") || !strcmp(argv[1], "-V")) {
        printf("wavefuel %s (%s)\n", WF_VERSION, wf_git_hash());
        return 0;
    }
    const WfCommand *cmd = find(argv[1]);
    return cmd ? cmd->main(argc - 1, argv + 1) : 2;
}
