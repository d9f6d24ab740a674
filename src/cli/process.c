/* The process-wide settings of the wavefuel programs (bin/wavefuel, bin/wavefuel-mpi). The library changes no
 * process-wide state; the programs decide it here, once: signals, HDF5's exit handler and error printing, and
 * where vehicle classes and drive-cycle data are found (docs/energy.md, docs/cycles.md). */
#include <hdf5.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli/commands.h"
#include "util/path.h"
#include "wavefuel/vehicle.h"

volatile sig_atomic_t wf_cli_stop = 0;

/* The program word of the `wavefuel run` commands printed for the user (wf_cli_program). */
static char program[1024] = "wavefuel";

static void on_stop(int sig) { wf_cli_stop = sig; }

void wf_cli_h5_quiet_thread(void)
{
    /* wavefuel reports every HDF5 failure itself (WfError, naming the file and object); HDF5's own stack dump
     * would only repeat it. A setting of the calling thread in the thread-safe HDF5 library. */
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

/* Where the shipped files are under PREFIX: the repository (PREFIX/vehicles, PREFIX/../shared/data) for
 * bin/wavefuel in a clone, and the layout of `make install` (PREFIX/share/wavefuel/vehicles and .../data). The first
 * that exists is used for data; both are on the class search path (missing directories are skipped). */
static const char *const vehicle_dirs[] = {"vehicles", "share/wavefuel/vehicles"};
static const char *const data_dirs[] = {"../shared/data", "share/wavefuel/data"};

/* PREFIX for PREFIX/bin/wavefuel: the repository for bin/wavefuel. */
static int prefix_dir(char *out, size_t len)
{
    char exe_dir[4096];
    return wf_path_exe_dir(exe_dir, sizeof exe_dir) ? -1 : wf_path_dirname(exe_dir, 1, out, len);
}

/* "$WAVEFUEL_VEHICLES:PREFIX/vehicles:PREFIX/share/wavefuel/vehicles". */
static int set_vehicle_path(WfError *err)
{
    const char *env = getenv("WAVEFUEL_VEHICLES");
    char prefix[4096], path[WF_VEHICLE_PATH_MAX];
    int have_prefix = prefix_dir(prefix, sizeof prefix) == 0;
    int w = snprintf(path, sizeof path, "%s", env ? env : "");
    for (size_t i = 0; have_prefix && i < sizeof vehicle_dirs / sizeof vehicle_dirs[0] && w >= 0; i++)
        if ((size_t)w < sizeof path)
            w += snprintf(path + w, sizeof path - (size_t)w, "%s%s/%s", w ? ":" : "", prefix, vehicle_dirs[i]);
    if (w < 0 || (size_t)w >= sizeof path)
        return wf_err(err, WF_EINPUT, "$WAVEFUEL_VEHICLES is too long (%zu bytes at most)", sizeof path - 64);
    return wf_vehicle_search_path_set(path, err);
}

int wf_cli_data_default(char *out, size_t len)
{
    char prefix[4096];
    if (prefix_dir(prefix, sizeof prefix)) return -1;
    struct stat st;
    for (size_t i = 0; i < sizeof data_dirs / sizeof data_dirs[0]; i++) {
        int w = snprintf(out, len, "%s/%s", prefix, data_dirs[i]);
        if (w < 0 || (size_t)w >= len) return -1;
        if (stat(out, &st) == 0 && S_ISDIR(st.st_mode)) return 0;
    }
    /* None exists: the repository's, which the messages then name as missing. */
    int w = snprintf(out, len, "%s/%s", prefix, data_dirs[0]);
    return w < 0 || (size_t)w >= len ? -1 : 0;
}

const char *wf_cli_program(void) { return program; }

/* The word that runs this program's `wavefuel` as the user invoked it: "wavefuel" when found on PATH (argv0 has no
 * '/'), else argv0's directory + "/wavefuel" ("./bin/wavefuel"; bin/wavefuel-mpi gives bin/wavefuel). */
static void set_program(const char *argv0)
{
    const char *slash = argv0 ? strrchr(argv0, '/') : NULL;
    if (slash && (size_t)(slash - argv0) + sizeof "/wavefuel" <= sizeof program)
        snprintf(program, sizeof program, "%.*s/wavefuel", (int)(slash - argv0), argv0);
}

int wf_cli_process_init(const char *argv0, WfError *err)
{
    set_program(argv0);
    /* A file size limit (ulimit -f) must be a write error the writers report (EFBIG), not a silent kill. */
    signal(SIGXFSZ, SIG_IGN);
    /* Before any other HDF5 call: no HDF5 clean-up at exit (after a failed H5Fclose on a full disk, HDF5 1.10's
     * exit handler closes the file again and crashes). */
    H5dont_atexit();
    wf_cli_h5_quiet_thread();
    return set_vehicle_path(err);
}

void wf_cli_catch_stop(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}
