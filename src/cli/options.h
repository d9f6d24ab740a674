/* The one option parser of the wavefuel commands: getopt_long with the same rules everywhere. An unknown option or a
 * missing value is one line naming the option and `wavefuel help CMD` (not the whole help), an option given twice
 * that cannot be repeated and two options that exclude each other (--project --no-project) are refused, and -V /
 * --version prints the version in every command. Each refusal: exit status 2, nothing run. */
#ifndef WAVEFUEL_CLI_OPTIONS_H
#define WAVEFUEL_CLI_OPTIONS_H

#include <getopt.h>
#include <stddef.h>
#include <stdio.h>

enum {
    WF_CLI_OPT_MAX = 32,   /* options of one command, -V and -h included */
    WF_CLI_DONE = -2,      /* -V or the help printed: the command ends with status 0 */
    WF_CLI_USAGE = -3      /* a usage error was printed: the command ends with status 2 */
};

typedef struct WfCliOpts {
    const char          *cmd;        /* as in messages and `wavefuel help CMD`: "run", "table import" */
    const struct option *longopts;   /* the command's table, {0}-terminated; each val a character */
    const char          *shortopts;  /* the command's short options, as for getopt_long */
    const char          *repeatable; /* option values that may be given more than once ("s": --set), may be NULL */
    const char *const   *conflicts;  /* NULL-terminated pairs of option values that exclude each other ("pP"), may be
                                        NULL */
    void               (*help)(FILE *out); /* prints the command's help; if set, -h/--help print it on stdout */
    /* internal state, zeroed by the initialiser */
    struct option        all[WF_CLI_OPT_MAX + 1];
    char                 all_short[2 * WF_CLI_OPT_MAX + 4];
    unsigned char        seen[256];
    int                  started;
} WfCliOpts;

/* Like getopt_long (optind, optarg as usual; optind restarts at 1 on the first call): returns the next option's value,
 * -1 after the last option, WF_CLI_DONE after printing the version (-V, --version) or, if o->help is set, the help
 * (-h, --help, on stdout), or WF_CLI_USAGE after printing "wavefuel CMD: ..." on stderr for an unknown option, a
 * missing value, a repeated option or a conflict. Quiet (no message at all) when `quiet` is set in the command, as
 * for MPI ranks other than 0. */
int wf_cli_getopt(WfCliOpts *o, int argc, char **argv, int quiet);

/* Prints "wavefuel CMD: " and the message (printf-style, no newline needed) on stderr unless quiet; returns 2, the
 * exit status of a usage error. */
int wf_cli_usage(const WfCliOpts *o, int quiet, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* A command's line as one string for provenance: "wavefuel" then argv[0..argc) (the command's words), separated by
 * spaces, into out (len bytes); words that do not fit are left out. */
void wf_cli_join_args(int argc, char **argv, char *out, size_t len);

#endif
