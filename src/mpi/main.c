/* wavefuel-mpi: `wavefuel sweep` across MPI ranks (`mpirun -n K bin/wavefuel-mpi SWEEP.yaml [options]`; options as
 * for `wavefuel sweep`, docs/sweeps.md), and one ring split across them (`mpirun -n K bin/wavefuel-mpi run
 * SCENARIO.yaml [options]`; options as for `wavefuel run`, docs/mpi.md). Only prolog and epilog: MPI is initialised
 * for funneled threads (each rank's main thread alone calls MPI, outside its OpenMP regions). */
#include <mpi.h>
#include <stdio.h>
#include <string.h>

#include "cli/commands.h"

int main(int argc, char **argv)
{
    int provided = 0;
    WfError err = {0};
    if (wf_cli_process_init(argv[0], &err)) return wf_cli_fail(&err); /* as in src/cli/main.c */
    if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fprintf(stderr, "wavefuel-mpi: MPI_Init_thread failed\n");
        return 1;
    }
    int status;
    if (provided < MPI_THREAD_FUNNELED) {
        fprintf(stderr, "wavefuel-mpi: the MPI library does not support MPI_THREAD_FUNNELED\n");
        status = 1;
    } else {
        status = argc > 1 && !strcmp(argv[1], "run") ? wf_cmd_run(argc - 1, argv + 1) : wf_cmd_sweep(argc, argv);
    }
    MPI_Finalize();
    return status;
}
