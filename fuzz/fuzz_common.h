/* Shared by the fuzz targets. wavefuel's loaders read files by path (relative names resolve against the
 * file's directory), so each input is written to a scratch file in a private directory created on first
 * use and removed at normal exit (an input that aborts leaves it behind: the scripts point TMPDIR at a directory
 * they delete). Standard input is pointed at /dev/null so an input naming "-" or /dev/stdin
 * cannot block a fuzzing run. */
#ifndef WAVEFUEL_FUZZ_COMMON_H
#define WAVEFUEL_FUZZ_COMMON_H

#include <dirent.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "wavefuel/err.h"
#include "wavefuel/vehicle.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

enum { FUZZ_MAX_FILES = 64 };
static char fuzz_dir[512];
static char fuzz_dir_file[FUZZ_MAX_FILES][600];
static int  fuzz_n_dir_file;
static int  fuzz_has_data_dir;

static void fuzz_cleanup(void)
{
    for (int i = 0; i < fuzz_n_dir_file; i++) unlink(fuzz_dir_file[i]);
    if (fuzz_has_data_dir) {
        char d[600];
        snprintf(d, sizeof d, "%s/data", fuzz_dir);
        rmdir(d);
    }
    if (fuzz_dir[0]) rmdir(fuzz_dir);
}

/* Path of scratch file `name` (created by fuzz_write). Aborts if the directory cannot be made: a harness that
 * cannot write its input tests nothing. */
static inline const char *fuzz_path(const char *name)
{
    if (!fuzz_dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(fuzz_dir, sizeof fuzz_dir, "%s/wavefuel-fuzz-XXXXXX", tmp && *tmp ? tmp : "/tmp");
        if (!mkdtemp(fuzz_dir)) {
            perror("fuzz: mkdtemp");
            abort();
        }
        if (!freopen("/dev/null", "r", stdin)) abort();
        /* Vehicle classes come from the repository's vehicles/ only (the library has no default search path). */
        WfError e = {0};
        if (wf_vehicle_search_path_set(WF_REPO_DIR "/vehicles", &e)) abort();
        atexit(fuzz_cleanup);
    }
    for (int i = 0; i < fuzz_n_dir_file; i++) {
        const char *slash = strrchr(fuzz_dir_file[i], '/');
        if (strcmp(slash + 1, name) == 0) return fuzz_dir_file[i];
    }
    if (fuzz_n_dir_file == FUZZ_MAX_FILES) abort();
    snprintf(fuzz_dir_file[fuzz_n_dir_file], sizeof fuzz_dir_file[0], "%s/%s", fuzz_dir, name);
    return fuzz_dir_file[fuzz_n_dir_file++];
}

/* Copies the repository's scenarios/data/ (the corridor scenarios' inflow and elevation CSVs) into the scratch
 * directory's data/, so the seeds that name them by relative path load as they do in the tree. */
static inline void fuzz_copy_scenario_data(void)
{
#ifdef WF_REPO_DIR
    if (fuzz_has_data_dir) return;
    char src_dir[600], dst[600], src[1300];
    fuzz_path("fuzz.yaml"); /* creates the scratch directory */
    snprintf(src_dir, sizeof src_dir, "%s/scenarios/data", WF_REPO_DIR);
    snprintf(dst, sizeof dst, "%s/data", fuzz_dir);
    if (mkdir(dst, 0700) != 0) return;
    fuzz_has_data_dir = 1;
    DIR *d = opendir(src_dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d)) && fuzz_n_dir_file < FUZZ_MAX_FILES) {
        if (e->d_name[0] == '.') continue;
        int ws = snprintf(src, sizeof src, "%s/%s", src_dir, e->d_name);
        FILE *in = ws > 0 && (size_t)ws < sizeof src ? fopen(src, "rb") : NULL;
        if (!in) continue;
        int w = snprintf(fuzz_dir_file[fuzz_n_dir_file], sizeof fuzz_dir_file[0], "%s/data/%s", fuzz_dir, e->d_name);
        FILE *out = w > 0 && (size_t)w < sizeof fuzz_dir_file[0] ? fopen(fuzz_dir_file[fuzz_n_dir_file], "wb") : NULL;
        if (out) {
            char buf[4096];
            size_t n;
            while ((n = fread(buf, 1, sizeof buf, in)) > 0) fwrite(buf, 1, n, out);
            fclose(out);
            fuzz_n_dir_file++;
        }
        fclose(in);
    }
    closedir(d);
#endif
}

/* Writes size bytes to scratch file `name` (replacing it); returns its path. */
static inline const char *fuzz_write(const char *name, const uint8_t *data, size_t size)
{
    const char *path = fuzz_path(name);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (fd < 0) {
        perror("fuzz: open scratch file");
        abort();
    }
    size_t done = 0;
    while (done < size) {
        ssize_t w = write(fd, data + done, size - done);
        if (w <= 0) {
            perror("fuzz: write scratch file");
            abort();
        }
        done += (size_t)w;
    }
    close(fd);
    return path;
}

/* With WAVEFUEL_FUZZ_VERBOSE=1 (replay drivers), print each input's outcome: used to check that the seeds
 * reach the success paths, and to read the message a regression input produces. */
static inline void fuzz_note(const char *target, int rc, const WfError *err)
{
    static int verbose = -1;
    if (verbose < 0) {
        const char *v = getenv("WAVEFUEL_FUZZ_VERBOSE");
        verbose = v && *v == '1';
    }
    if (verbose) fprintf(stderr, "%s: %s\n", target, rc ? err->msg : "accepted");
}

/* The error contract every loader must keep for any input: a failure is WF_EINPUT (exit status 2) with a
 * non-empty message, or WF_ESYS only for resource exhaustion. Anything else aborts, so the fuzzer keeps the
 * input that produced it. */
static inline void fuzz_check_error(const char *target, int rc, const WfError *err)
{
    fuzz_note(target, rc, err);
    int ok = (rc == WF_EINPUT || rc == WF_ESYS) && err->code == rc && err->msg[0] != '\0';
    if (ok && rc == WF_ESYS && !strstr(err->msg, "out of memory")) ok = 0;
    if (!ok) {
        fprintf(stderr, "%s: broken error contract: rc=%d code=%d msg='%s'\n", target, rc, err->code, err->msg);
        abort();
    }
}

/* Aborts with a message when an accepted input violates a documented property of the result. */
#define FUZZ_REQUIRE(cond, ...)                                                                                 \
    do {                                                                                                        \
        if (!(cond)) {                                                                                          \
            fprintf(stderr, "property violated: %s: ", #cond);                                                  \
            fprintf(stderr, __VA_ARGS__);                                                                       \
            fputc('\n', stderr);                                                                                \
            abort();                                                                                            \
        }                                                                                                       \
    } while (0)

#endif
