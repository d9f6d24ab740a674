/* The WfPartition calls with MPI (src/mpi/partition_mpi.h). Messages are bytes; a gather's counts and
 * displacements are kept from creation, so a step allocates nothing. */
#include "mpi/partition_mpi.h"

#include <limits.h>
#include <mpi.h>
#include <stdlib.h>

typedef struct MpiPart {
    MPI_Comm    comm;
    int         rank, size; /* this rank's, kept from creation */
    int        *counts, *displs;
    MPI_Request req[2]; /* the halo exchange in flight: receive, send */
} MpiPart;

static int mpi_fail(int rc, const char *what, WfError *err)
{
    char msg[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, msg, &len);
    return wf_err(err, WF_ESYS, "MPI: %s failed: %s", what, msg);
}

/* The halo exchange: a non-blocking receive from the next rank and send to the previous one. */
static int post_next(void *ctx, const void *send, void *recv, size_t bytes, WfError *err)
{
    MpiPart *m = ctx;
    if (bytes > INT_MAX) return wf_err(err, WF_ESYS, "MPI: a halo of %zu bytes is too large", bytes);
    int rc = MPI_Irecv(recv, (int)bytes, MPI_BYTE, (m->rank + 1) % m->size, 1, m->comm, &m->req[0]);
    if (rc == MPI_SUCCESS)
        rc = MPI_Isend(send, (int)bytes, MPI_BYTE, (m->rank + m->size - 1) % m->size, 1, m->comm, &m->req[1]);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "posting the halo exchange", err);
}

/* The open road's halo: a non-blocking receive from the rank ahead (rank - 1) and send to the rank behind. */
static int post_back(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err)
{
    MpiPart *m = ctx;
    if (send_bytes > INT_MAX || recv_bytes > INT_MAX) return wf_err(err, WF_ESYS, "MPI: a halo is too large");
    int from = m->rank > 0 ? m->rank - 1 : MPI_PROC_NULL, to = m->rank + 1 < m->size ? m->rank + 1 : MPI_PROC_NULL;
    int rc = MPI_Irecv(recv, (int)recv_bytes, MPI_BYTE, from, 5, m->comm, &m->req[0]);
    if (rc == MPI_SUCCESS) rc = MPI_Isend(send, (int)send_bytes, MPI_BYTE, to, 5, m->comm, &m->req[1]);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "posting the halo exchange", err);
}

static int wait_next(void *ctx, WfError *err)
{
    MpiPart *m = ctx;
    int rc = MPI_Waitall(2, m->req, MPI_STATUSES_IGNORE);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "the halo exchange", err);
}

static int or_all(void *ctx, int *flags, WfError *err)
{
    MpiPart *m = ctx;
    int rc = MPI_Allreduce(MPI_IN_PLACE, flags, 1, MPI_INT, MPI_BOR, m->comm);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "the agreement on a step's flags", err);
}

static int sum_u64(void *ctx, uint64_t *v, size_t n, WfError *err)
{
    MpiPart *m = ctx;
    int rc = MPI_Allreduce(MPI_IN_PLACE, v, (int)n, MPI_UINT64_T, MPI_SUM, m->comm);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "a sum of counts", err);
}

static int gather(void *ctx, void *buf, const size_t *off, int root, WfError *err)
{
    MpiPart *m = ctx;
    int rank = m->rank, size = m->size;
    if (off[size] > INT_MAX)
        return wf_err(err, WF_ESYS, "MPI: gathering an array of %zu bytes (more than 2 GiB) is not supported",
                      off[size]);
    for (int r = 0; r < size; r++) m->counts[r] = (int)(off[r + 1] - off[r]), m->displs[r] = (int)off[r];
    unsigned char *b = buf;
    int rc = root < 0 ? MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, b, m->counts, m->displs, MPI_BYTE, m->comm)
                      : MPI_Gatherv(rank == root ? MPI_IN_PLACE : b + off[rank], m->counts[rank], MPI_BYTE, b,
                                    m->counts, m->displs, MPI_BYTE, root, m->comm);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "a gather of the state", err);
}

static int allgather(void *ctx, const void *mine, void *all, size_t bytes, WfError *err)
{
    MpiPart *m = ctx;
    if (bytes > INT_MAX) return wf_err(err, WF_ESYS, "MPI: a record of %zu bytes is too large", bytes);
    int rc = MPI_Allgather(mine, (int)bytes, MPI_BYTE, all, (int)bytes, MPI_BYTE, m->comm);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "the exchange of the ranks' records", err);
}

static int shift(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err)
{
    MpiPart *m = ctx;
    if (send_bytes > INT_MAX || recv_bytes > INT_MAX)
        return wf_err(err, WF_ESYS, "MPI: %zu vehicles' bytes are too many for one message",
                      send_bytes > recv_bytes ? send_bytes : recv_bytes);
    int to = m->rank > 0 ? m->rank - 1 : MPI_PROC_NULL, from = m->rank + 1 < m->size ? m->rank + 1 : MPI_PROC_NULL;
    int rc = MPI_Sendrecv(send, (int)send_bytes, MPI_BYTE, to, 2, recv, (int)recv_bytes, MPI_BYTE, from, 2, m->comm,
                          MPI_STATUS_IGNORE);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "passing vehicles to the rank ahead", err);
}

/* Received from the rank before (rank 0: none), passed to the rank after; the last rank's back to rank 0. */
static int chain(void *ctx, void *buf, size_t bytes, void (*fn)(void *arg, void *buf), void *arg, WfError *err)
{
    MpiPart *m = ctx;
    int rank = m->rank, last = m->size - 1, rc = MPI_SUCCESS;
    if (bytes > INT_MAX) return wf_err(err, WF_ESYS, "MPI: a running sum of %zu bytes is too large", bytes);
    if (rank > 0) rc = MPI_Recv(buf, (int)bytes, MPI_BYTE, rank - 1, 3, m->comm, MPI_STATUS_IGNORE);
    if (rc == MPI_SUCCESS) fn(arg, buf);
    if (rc == MPI_SUCCESS && last > 0) {
        if (rank < last) rc = MPI_Send(buf, (int)bytes, MPI_BYTE, rank + 1, 3, m->comm);
        else rc = MPI_Send(buf, (int)bytes, MPI_BYTE, 0, 4, m->comm);
    }
    if (rc == MPI_SUCCESS && last > 0 && rank == 0)
        rc = MPI_Recv(buf, (int)bytes, MPI_BYTE, last, 4, m->comm, MPI_STATUS_IGNORE);
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "a running sum along the ranks", err);
}

static int sum_f64(void *ctx, double *v, size_t n, WfError *err)
{
    MpiPart *m = ctx;
    int rc = MPI_SUCCESS;
    for (size_t k = 0; rc == MPI_SUCCESS && k < n; k += INT_MAX / 2) {
        size_t c = n - k < INT_MAX / 2 ? n - k : INT_MAX / 2;
        rc = MPI_Allreduce(MPI_IN_PLACE, v + k, (int)c, MPI_DOUBLE, MPI_SUM, m->comm);
    }
    return rc == MPI_SUCCESS ? 0 : mpi_fail(rc, "a sum of the measurement", err);
}

int wf_mpi_partition_init(WfPartition *p, volatile sig_atomic_t *stop_own, WfError *err)
{
    MpiPart *m = calloc(1, sizeof *m);
    *p = (WfPartition){.ctx = m, .post_next = post_next, .wait_next = wait_next, .post_back = post_back, .or_all = or_all,
                       .sum_u64 = sum_u64, .gather = gather, .allgather = allgather, .shift = shift,
                       .chain = chain, .sum_f64 = sum_f64, .stop_own = stop_own};
    if (!m) return wf_err(err, WF_ESYS, "out of memory");
    m->comm = MPI_COMM_WORLD;
    MPI_Comm_rank(m->comm, &p->rank);
    MPI_Comm_size(m->comm, &p->size);
    m->rank = p->rank;
    m->size = p->size;
    m->counts = malloc((size_t)p->size * sizeof *m->counts);
    m->displs = malloc((size_t)p->size * sizeof *m->displs);
    if (m->counts && m->displs) return 0;
    wf_mpi_partition_free(p);
    return wf_err(err, WF_ESYS, "out of memory");
}

void wf_mpi_partition_free(WfPartition *p)
{
    MpiPart *m = p->ctx;
    if (m) free(m->counts), free(m->displs);
    free(m);
    p->ctx = NULL;
}

int wf_mpi_agree_status(int status)
{
    int all = status;
    MPI_Allreduce(&status, &all, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    return all;
}

void wf_mpi_abort(int status)
{
    MPI_Abort(MPI_COMM_WORLD, status);
}
