/* The wavefuel subcommands. Each returns the process exit status (0 ok, 2 bad input, 1 other failure)
 * after printing its own error message; argv[0] is the subcommand name. */
#ifndef WAVEFUEL_CLI_COMMANDS_H
#define WAVEFUEL_CLI_COMMANDS_H

#include <signal.h>

#include "wavefuel/err.h"

typedef struct WfCommand {
    const char *name;
    const char *summary;
    int (*main)(int argc, char **argv);
} WfCommand;

int wf_cmd_energy(int argc, char **argv);
int wf_cmd_cycle(int argc, char **argv);
int wf_cmd_table(int argc, char **argv);
int wf_cmd_fit(int argc, char **argv);
int wf_cmd_run(int argc, char **argv);
int wf_cmd_info(int argc, char **argv);
int wf_cmd_sweep(int argc, char **argv);

/* Print "wavefuel: <message>" on stderr and return the exit status for the error's code. */
int wf_cli_fail(const WfError *err);
/* After a failed or interrupted run that left `partial`, the partial file of the result `result`: say where it is,
 * that /meta/reason says why and that the row counters `counters` (named as in the message) say how much it holds,
 * and whether a checkpoint (result.ckpt) lets --resume continue it. */
void wf_cli_note_partial(const char *partial, const char *result, const char *counters);

/* Before a run starts: its result path sc->output_path (`given`: the -o argument, NULL when the scenario or the
 * default decides) must not be a directory or one of the scenario's inputs (WF_EINPUT); the default directory
 * output/ is created in the working directory when the path is output/NAME.h5 and it is missing. */
struct WfScenario;
int wf_cli_run_output(const struct WfScenario *sc, const char *given, WfError *err);

/* --resume ARG (src/cli/resume_target.c): ARG is X.h5, X.h5.partial or X.h5.ckpt; result (len bytes) = X.h5. WF_EINPUT
 * naming the file and what it is when it is not a wavefuel result, partial result or checkpoint, when the result is
 * already complete, or when there is no checkpoint to continue from. Reads only. */
int wf_cli_resume_target(const char *arg, char *result, size_t len, WfError *err);

/* Process-wide settings (src/cli/process.c), made by the programs only, never by the library. */
/* Set by SIGINT/SIGTERM once wf_cli_catch_stop() is called: the signal's number; runs poll it and stop. */
extern volatile sig_atomic_t wf_cli_stop;
/* At the start of main, with main's argv[0]: SIGXFSZ ignored, HDF5 without its exit handler and without printing
 * its error stack in this thread (errors are reported through WfError), the vehicle class search path set to
 * "$WAVEFUEL_VEHICLES:PREFIX/vehicles:PREFIX/share/wavefuel/vehicles", PREFIX the parent of the executable's
 * directory (the repository for bin/wavefuel, the installation prefix for an installed one), and the program word
 * of printed commands (wf_cli_program). WF_EINPUT if the search path is too long. */
int wf_cli_process_init(const char *argv0, WfError *err);
/* The default data directory of drive cycles: PREFIX/../shared/data (shared/ next to the repository for
 * bin/wavefuel) or PREFIX/share/wavefuel/data (installed), the first that exists. Returns 0, or -1 if it cannot be
 * formed. */
int wf_cli_data_default(char *out, size_t len);
/* How the user runs `wavefuel`, for the commands printed to be run as printed: "wavefuel" when the program was
 * found on PATH, else its path as invoked with the file name wavefuel ("./bin/wavefuel"). Valid for the process. */
const char *wf_cli_program(void);
/* HDF5's error-stack printing off in the calling thread (per thread in the thread-safe HDF5): every thread of
 * the program that calls HDF5 calls it first. */
void wf_cli_h5_quiet_thread(void);
/* From now on SIGINT and SIGTERM set wf_cli_stop instead of killing the process. */
void wf_cli_catch_stop(void);

/* A WfProgressFn for wf_sim_run: the progress line on stderr (src/cli/progress.c). ctx points
 * to the run's start, a double from wf_wall_now(). */
void wf_cli_run_progress(void *ctx, double t_s, double duration_s, long step, long n_steps);

#endif
