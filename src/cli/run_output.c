/* The result file of `wavefuel run`, settled before the run starts (the ring and corridor runners share it): not
 * one of the run's inputs nor a directory (src/util/outpath.c), and the default output/NAME.h5 usable from any
 * working directory (output/ is created there when missing; docs/output.md). */
#include "cli/commands.h"
#include "util/outpath.h"
#include "wavefuel/scenario.h"

int wf_cli_run_output(const WfScenario *sc, const char *given, WfError *err)
{
    int rc = wf_output_check(given ? "-o" : "output.path", sc->output_path, (const char *const *)sc->inputs,
                             sc->n_inputs, err);
    if (!rc && !given) rc = wf_output_default_dir(sc->output_path, err);
    return rc;
}
