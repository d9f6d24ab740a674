/* The option parser shared by every command (options.h). */
#include "cli/options.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/version.h"

/* The command's table with -V/--version (and -h/--help if o->help) added; built on the first call. */
static void build(WfCliOpts *o)
{
    size_t n = 0;
    while (o->longopts[n].name && n + 2 < WF_CLI_OPT_MAX) {
        o->all[n] = o->longopts[n];
        n++;
    }
    o->all[n++] = (struct option){"version", no_argument, 0, 'V'};
    if (o->help) o->all[n++] = (struct option){"help", no_argument, 0, 'h'};
    o->all[n] = (struct option){0, 0, 0, 0};
    /* A leading ':' makes getopt report a missing value as ':' and print nothing itself. */
    snprintf(o->all_short, sizeof o->all_short, ":%sV%s", o->shortopts, o->help ? "h" : "");
    o->started = 1;
}

/* "-o/--output" for a value, as the user may have typed it. */
static const char *name_of(const WfCliOpts *o, int val, char *buf, size_t len)
{
    const char *lng = NULL;
    for (size_t i = 0; o->all[i].name; i++)
        if (o->all[i].val == val) lng = o->all[i].name;
    int has_short = val > 0 && val < 256 && val != ':' && strchr(o->shortopts, val);
    if (has_short && lng) snprintf(buf, len, "-%c/--%s", val, lng);
    else if (lng) snprintf(buf, len, "--%s", lng);
    else snprintf(buf, len, "-%c", val);
    return buf;
}

static int usage(const WfCliOpts *o, int quiet, const char *what, const char *opt)
{
    if (!quiet) fprintf(stderr, "wavefuel %s: %s %s (options: wavefuel help %s)\n", o->cmd, what, opt, o->cmd);
    return WF_CLI_USAGE;
}

int wf_cli_getopt(WfCliOpts *o, int argc, char **argv, int quiet)
{
    if (!o->started) {
        build(o);
        optind = 1;
    }
    opterr = 0;
    int c = getopt_long(argc, argv, o->all_short, o->all, NULL);
    char a[96], b[96];
    if (c == -1) return -1;
    const char *arg = optind > 0 && optind <= argc ? argv[optind - 1] : "?";
    if (c == '?') {
        /* A short option inside a cluster ("-qx") is not the whole word: name the character. */
        if (optopt && arg[0] == '-' && arg[1] != '-') snprintf(a, sizeof a, "'-%c'", optopt);
        else snprintf(a, sizeof a, "'%s'", arg);
        return usage(o, quiet, "unknown option", a);
    }
    if (c == ':') return usage(o, quiet, "a value is needed after", name_of(o, optopt ? optopt : '?', a, sizeof a));
    if (c == 'V') {
        if (!quiet) printf("wavefuel %s (%s)\n", WF_VERSION, wf_git_hash());
        return WF_CLI_DONE;
    }
    if (c == 'h' && o->help) {
        if (!quiet) o->help(stdout);
        return WF_CLI_DONE;
    }
    unsigned char u = (unsigned char)c;
    if (o->seen[u] && !(o->repeatable && strchr(o->repeatable, c))) {
        snprintf(b, sizeof b, "%s", name_of(o, c, a, sizeof a));
        return usage(o, quiet, "given twice:", b);
    }
    o->seen[u] = 1;
    for (size_t k = 0; o->conflicts && o->conflicts[k]; k++) {
        const char *pair = o->conflicts[k];
        int other = pair[0] == c ? pair[1] : pair[1] == c ? pair[0] : 0;
        if (other && o->seen[(unsigned char)other]) {
            char both[200];
            snprintf(both, sizeof both, "%s and %s", name_of(o, other, a, sizeof a), name_of(o, c, b, sizeof b));
            return usage(o, quiet, "options that exclude each other:", both);
        }
    }
    return c;
}

int wf_cli_usage(const WfCliOpts *o, int quiet, const char *fmt, ...)
{
    if (quiet) return 2;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "wavefuel %s: ", o->cmd);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return 2;
}

void wf_cli_join_args(int argc, char **argv, char *out, size_t len)
{
    size_t used = 0;
    out[0] = '\0';
    for (int i = -1; i < argc; i++) {
        const char *s = i < 0 ? "wavefuel" : argv[i];
        int w = snprintf(out + used, len - used, "%s%s", used ? " " : "", s);
        if (w < 0 || (size_t)w >= len - used) break;
        used += (size_t)w;
    }
}
