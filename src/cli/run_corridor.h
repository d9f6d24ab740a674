/* `wavefuel run` for corridor scenarios (road.type: corridor): called by src/cli/cmd_run.c. */
#ifndef WAVEFUEL_CLI_RUN_CORRIDOR_H
#define WAVEFUEL_CLI_RUN_CORRIDOR_H

#include "wavefuel/scenario.h"

/* Simulate the loaded corridor scenario `sc` (borrowed), write its HDF5 result to sc->output_path and, unless
 * quiet, print a progress bar (on a terminal) and the summary. With `resume` (a result path), continue the
 * interrupted run of that result from its checkpoint instead (sc must be the scenario the checkpoint holds).
 * checkpoint_s > 0 saves a checkpoint every that many seconds of wall time. SIGINT/SIGTERM end the run after the
 * current step with a checkpoint and a partial result. Returns the process exit status (0, 1, 2 or 3) after
 * printing any error. */
int wf_cli_run_corridor(const WfScenario *sc, const char *resume, double checkpoint_s, int force, int quiet);

#endif
