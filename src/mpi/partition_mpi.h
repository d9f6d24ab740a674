/* A ring split across the ranks of MPI_COMM_WORLD (`wavefuel-mpi run`, docs/mpi.md): the calls of a WfPartition
 * (wavefuel/partition.h) made with MPI. Only the main thread calls them (MPI_THREAD_FUNNELED). */
#ifndef WAVEFUEL_PARTITION_MPI_H
#define WAVEFUEL_PARTITION_MPI_H

#include "wavefuel/partition.h"

/* Fill *p for this rank of MPI_COMM_WORLD; stop_own: the rank's signal flag. Owns what it allocates until
 * wf_mpi_partition_free. 0 or WF_ESYS. */
int  wf_mpi_partition_init(WfPartition *p, volatile sig_atomic_t *stop_own, WfError *err);
void wf_mpi_partition_free(WfPartition *p);
/* The maximum of every rank's status, on every rank (a setup step every rank must pass before the run). */
int  wf_mpi_agree_status(int status);
/* Stop every rank now with this exit status (an output error on the rank that writes, mid-run). */
void wf_mpi_abort(int status);

#endif
