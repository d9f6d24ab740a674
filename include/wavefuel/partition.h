/* One road split across processes (docs/mpi.md): what a run needs of its communicator. The library holds no MPI:
 * bin/wavefuel-mpi implements these calls with MPI (src/mpi/partition_mpi.c), and any other transport can. A ring: rank
 * r of size steps a contiguous range of the ring's vehicles, whole blocks of WF_STATS_BLOCK (the same split on every
 * rank: wf_partition_blocks). Every rank builds only its own range of the fleet (wf_fleet_create_part: the same bits as
 * one process) in arrays indexed by vehicle, steps it and refreshes the few vehicles ahead of it that it reads from the
 * next rank. A corridor: rank r owns a segment of the road (rank 0 the exit's, the last rank the entrance's) and the
 * vehicles on it, which pass to the rank ahead as they cross into its segment (src/core/corridor_part.c). Every call
 * below is collective: every rank makes it, in the same order. Each returns 0, or an error code with err set (the run
 * then stops with that error on every rank that saw it). */
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
    /* The other way on an open road, completed by wait_next as well: send_bytes of send to rank + 1 (the last rank
     * sends nothing), recv_bytes from rank - 1 into recv (rank 0 receives nothing). */
    int (*post_back)(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err);
    /* The bitwise OR of *flags over the ranks, into *flags on every rank. */
    int (*or_all)(void *ctx, int *flags, WfError *err);
    /* The sums of m integers over the ranks, into v on every rank. */
    int (*sum_u64)(void *ctx, uint64_t *v, size_t m, WfError *err);
    /* Bytes [off[r], off[r + 1]) of buf are rank r's (off: size + 1 offsets): afterwards rank `root` holds all of
     * them (root -1: every rank). */
    int (*gather)(void *ctx, void *buf, const size_t *off, int root, WfError *err);
    /* Each rank's `bytes` of mine into all + r bytes, on every rank. */
    int (*allgather)(void *ctx, const void *mine, void *all, size_t bytes, WfError *err);
    /* send_bytes of send to rank - 1 (rank 0 sends nothing) and recv_bytes from rank + 1 into recv (the last rank
     * receives nothing): each rank passes on to the rank ahead of it on an open road. */
    int (*shift)(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err);
    /* The ranks in turn: rank 0 calls fn(arg, buf) and passes buf to rank 1, which calls fn on what it received and
     * passes it on, and so on; the last rank's buf comes back to rank 0. A sum that must run in rank order. */
    int (*chain)(void *ctx, void *buf, size_t bytes, void (*fn)(void *arg, void *buf), void *arg, WfError *err);
    /* The sums of m doubles over the ranks, into v on every rank (where at most one rank holds a value other than
     * +0, the sum is that value bit for bit). */
    int (*sum_f64)(void *ctx, double *v, size_t m, WfError *err);
    /* The run's stop: each rank's own flag (the number of the signal that stopped it, 0 while none did), and the
     * flag every rank agrees on at each step (set by the engine: the bitwise OR of the ranks' own, the signal's
     * number when they got the same; the step loop reads it). */
    volatile sig_atomic_t *stop_own, stop_all;
} WfPartition;

/* Bytes [lo, hi) of buf, which rank r holds, onto rank `root` (-1: every rank): a gather in which no other rank
 * holds any. off: room for size + 1 offsets. Collective. */
static inline int wf_partition_from(const WfPartition *p, void *buf, int r, size_t lo, size_t hi, int root, size_t *off,
                                    WfError *err)
{
    for (int q = 0; q <= p->size; q++) off[q] = q <= r ? lo : hi;
    return p->gather(p->ctx, buf, off, root, err);
}

/* Rank r's blocks of a ring of n_blocks blocks: [*b0, *b1). */
static inline void wf_partition_blocks(size_t n_blocks, int size, int r, size_t *b0, size_t *b1)
{
    *b0 = n_blocks * (size_t)r / (size_t)size, *b1 = n_blocks * (size_t)(r + 1) / (size_t)size;
}

#endif
