/* The MPI side of `wavefuel sweep` (bin/wavefuel-mpi, `make mpi`; docs/sweeps.md): rank 0 reads the sweep, keeps
 * the table and hands out runs one at a time to the ranks that are free (dynamic: runs differ in cost); every other
 * rank runs what it is sent and returns the result. Results are gathered on rank 0, which alone writes the (serial
 * HDF5) table. Only rank 0's main thread calls MPI (MPI_THREAD_FUNNELED). */
#ifndef WAVEFUEL_SWEEP_MPI_H
#define WAVEFUEL_SWEEP_MPI_H

#include <signal.h>

#include "wavefuel/err.h"
#include "wavefuel/sweep.h"

int wf_mpi_rank(void);
int wf_mpi_size(void);

/* Collective. Rank 0 passes the status of loading its sweep and, when 0, the sweep; the other ranks get it rebuilt
 * from rank 0's texts of the sweep and the base scenario (so they need neither file, only what the scenario itself
 * refers to: vehicle classes, grade files, plugins). Returns the status on every rank (the other ranks then hold
 * no message: rank 0 prints it). */
int wf_mpi_share_sweep(int status, const char *path, WfSweep **sw, WfError *err);

/* Ranks other than 0: run the runs rank 0 sends, return each result, until rank 0 says stop. Waits by polling
 * with 1 ms sleeps rather than in a blocking receive, which would keep a core busy. */
void wf_mpi_serve(const WfSweep *sw, const WfSweepRunOpts *o, volatile sig_atomic_t *stop);

/* Rank 0: the other ranks as a pool of workers, the remote workers of the library's scheduler
 * (WfSweepRemote{wf_mpi_pool_poll, pool}). Created by wf_mpi_pool_create, owned by the caller, released (and the
 * ranks told to stop) by wf_mpi_pool_destroy. */
typedef struct WfMpiPool WfMpiPool;
int  wf_mpi_pool_create(WfMpiPool **p, WfError *err);
/* Non-blocking: collect the results that arrived (finish), send a run (take) to every free rank. `pool` is a
 * WfMpiPool. Returns the number of ranks still running one. */
int  wf_mpi_pool_poll(void *pool, WfSweepTakeFn take, WfSweepFinishFn finish, void *sched);
/* Tell every rank to stop serving (call when poll returns 0 and take gives nothing), and free the pool. */
void wf_mpi_pool_destroy(WfMpiPool **p);

#endif
