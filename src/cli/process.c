/* The process-wide settings of the wavefuel programs (bin/wavefuel, bin/wavefuel-mpi). The library changes no
 * process-wide state; the programs decide it here, once: signals, HDF5's exit handler and error printing. */
#include <hdf5.h>
#include <signal.h>
#include <string.h>

#include "cli/commands.h"

volatile sig_atomic_t wf_cli_stop = 0;

static void on_stop(int sig) { wf_cli_stop = sig; }

void wf_cli_h5_quiet_thread(void)
{
    /* wavefuel reports every HDF5 failure itself (WfError, naming the file and object); HDF5's own stack dump
     * would only repeat it. A setting of the calling thread in the thread-safe HDF5 library. */
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

void wf_cli_process_init(void)
{
    /* A file size limit (ulimit -f) must be a write error the writers report (EFBIG), not a silent kill. */
    signal(SIGXFSZ, SIG_IGN);
    /* Before any other HDF5 call: no HDF5 clean-up at exit (after a failed H5Fclose on a full disk, HDF5 1.10's
     * exit handler closes the file again and crashes). */
    H5dont_atexit();
    wf_cli_h5_quiet_thread();
}

void wf_cli_catch_stop(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}
