/* One ring road split across processes (docs/mpi.md): what a run needs of its communicator. The library holds no
 * MPI: bin/wavefuel-mpi implements these calls with MPI (src/mpi/partition_mpi.c), and any other transport can.
 *
 * Rank r of size steps a contiguous range of the ring's vehicles, whole blocks of WF_STATS_BLOCK (the same split on
 * every rank: wf_partition_blocks). Every rank builds the whole fleet (the same bits everywhere) and keeps every array
 * whole; it steps only its own range and refreshes the few vehicles ahead of it that it reads from the next rank.
 * Every call below is collective: every rank makes it, in the same order. Each returns 0, or an error code with err
 * set (the run then stops with that error on every rank that saw it). */
#ifndef WAVEFUEL_PARTITION_H
#define WAVEFUEL_PARTITION_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "wavefuel/err.h"

typedef struct WfPartition {
    int   rank, size;
    void *ctx;
    /* `bytes` of send to rank - 1 (rank 0: to size - 1), and as many from rank + 1 (the last rank: from 0) into
     * recv, in two calls so that the rank can step what does not need them meanwhile: post_next starts the exchange
     * and returns without waiting for it; wait_next returns once recv holds the bytes and send may be reused. One
     * exchange at a time; both calls on the thread that initialised the transport. */
    int (*post_next)(void *ctx, const void *send, void *recv, size_t bytes, WfError *err);
    int (*wait_next)(void *ctx, WfError *err);
    /* The bitwise OR of *flags over the ranks, into *flags on every rank. */
    int (*or_all)(void *ctx, int *flags, WfError *err);
    /* The sums of m integers over the ranks, into v on every rank. */
    int (*sum_u64)(void *ctx, uint64_t *v, size_t m, WfError *err);
    /* Bytes [off[r], off[r + 1]) of buf are rank r's (off: size + 1 offsets): afterwards rank `root` holds all of
     * them (root -1: every rank). */
    int (*gather)(void *ctx, void *buf, const size_t *off, int root, WfError *err);
    /* The run's stop: each rank's own flag (the number of the signal that stopped it, 0 while none did), and the
     * flag every rank agrees on at each step (set by the engine: the bitwise OR of the ranks' own, the signal's
     * number when they got the same; the step loop reads it). */
    volatile sig_atomic_t *stop_own, stop_all;
} WfPartition;

/* Rank r's blocks of a ring of n_blocks blocks: [*b0, *b1). */
static inline void wf_partition_blocks(size_t n_blocks, int size, int r, size_t *b0, size_t *b1)
{
    *b0 = n_blocks * (size_t)r / (size_t)size, *b1 = n_blocks * (size_t)(r + 1) / (size_t)size;
}

#endif
