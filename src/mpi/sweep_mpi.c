/* Master/worker distribution of a sweep's runs over MPI ranks (see sweep_mpi.h). Messages: rank 0 sends a run
 * index (int64; -1 = stop) with TAG_RUN; a worker answers with the index and its WfSweepResult as raw bytes with
 * TAG_RESULT, so every rank must be the same build on the same architecture (a homogeneous cluster). */
#include "mpi/sweep_mpi.h"

#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "util/clock.h"
#include "util/mem.h"

enum { TAG_RUN = 1, TAG_RESULT = 2 };

typedef struct ResultMsg {
    int64_t       run;
    WfSweepResult res;
} ResultMsg;

struct WfMpiPool {
    int        size;
    char      *busy; /* per rank: a run is out */
    ResultMsg *msg;  /* receive buffer */
};

int wf_mpi_rank(void)
{
    int r = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
    return r;
}

int wf_mpi_size(void)
{
    int s = 1;
    MPI_Comm_size(MPI_COMM_WORLD, &s);
    return s;
}

/* Broadcast a string from rank 0 (length first); *s is malloc'ed on the other ranks. A rank that cannot allocate
 * aborts the job: leaving the collective would hang every other rank in it. */
static int bcast_text(char **s, int rank)
{
    uint64_t len = rank == 0 ? strlen(*s) : 0;
    if (MPI_Bcast(&len, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD) != MPI_SUCCESS) return -1;
    if (rank != 0 && !(*s = malloc(len + 1))) MPI_Abort(MPI_COMM_WORLD, 1);
    /* Texts are at most 64 MiB (the configuration reader's limit), so an int count is enough. */
    if (MPI_Bcast(*s, (int)len, MPI_CHAR, 0, MPI_COMM_WORLD) != MPI_SUCCESS) return -1;
    (*s)[len] = '\0';
    return 0;
}

int wf_mpi_share_sweep(int status, const char *path, WfSweep **sw, WfError *err)
{
    int rank = wf_mpi_rank();
    int st = status;
    if (MPI_Bcast(&st, 1, MPI_INT, 0, MPI_COMM_WORLD) != MPI_SUCCESS) return wf_err(err, WF_ESYS, "MPI_Bcast failed");
    if (st) return st;
    char *text = rank == 0 ? (*sw)->text : NULL, *scen = rank == 0 ? (*sw)->scenario_text : NULL;
    int rc = bcast_text(&text, rank) || bcast_text(&scen, rank) ? WF_ESYS : 0;
    if (!rc && rank != 0) rc = wf_sweep_load_text(path, text, scen, sw, err);
    if (rank != 0) {
        free(text);
        free(scen);
    }
    /* Every rank must agree before rank 0 hands out runs: a rank that could not rebuild the sweep would never
     * answer. */
    int worst = rc;
    if (MPI_Allreduce(&rc, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD) != MPI_SUCCESS) worst = WF_ESYS;
    if (worst && !rc) {
        if (rank != 0) wf_sweep_destroy(sw);
        return wf_err(err, worst, "MPI: another rank could not rebuild the sweep from rank 0's texts");
    }
    return worst;
}

void wf_mpi_serve(const WfSweep *sw, const WfSweepRunOpts *o, volatile sig_atomic_t *stop)
{
    ResultMsg m;
    for (;;) {
        int64_t run = -1;
        MPI_Request rq;
        int done = 0;
        MPI_Irecv(&run, 1, MPI_INT64_T, 0, TAG_RUN, MPI_COMM_WORLD, &rq);
        while (MPI_Test(&rq, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && !done) wf_sleep_ms(1);
        if (run < 0) break;
        m.run = run;
        if ((size_t)run < sw->n_runs) {
            wf_sweep_run(sw, (size_t)run, o, stop, &m.res);
        } else {
            /* Cannot happen with the same sweep on every rank; answer anyway so rank 0 is never left waiting. */
            memset(&m.res, 0, sizeof m.res);
            m.res.status = WF_RUN_FAILED;
            snprintf(m.res.error, sizeof m.res.error, "rank %d: run index %lld out of range", wf_mpi_rank(),
                     (long long)run);
        }
        MPI_Send(&m, (int)sizeof m, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD);
    }
}

int wf_mpi_pool_create(WfMpiPool **out, WfError *err)
{
    WfMpiPool *p = calloc(1, sizeof *p);
    if (p) p->size = wf_mpi_size();
    if (p) p->busy = calloc((size_t)p->size, 1);
    if (p) p->msg = malloc(sizeof *p->msg);
    if (!p || !p->busy || !p->msg) {
        if (p) free(p->busy), free(p->msg);
        free(p);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    *out = p;
    return 0;
}

int wf_mpi_pool_poll(void *pool, WfSweepTakeFn take, WfSweepFinishFn finish, void *ctx)
{
    WfMpiPool *p = pool;
    for (;;) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_RESULT, MPI_COMM_WORLD, &flag, &st);
        if (!flag) break;
        MPI_Recv(p->msg, (int)sizeof *p->msg, MPI_BYTE, st.MPI_SOURCE, TAG_RESULT, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        p->busy[st.MPI_SOURCE] = 0;
        p->msg->res.worker = st.MPI_SOURCE;
        finish(ctx, (size_t)p->msg->run, &p->msg->res);
    }
    int busy = 0;
    for (int r = 1; r < p->size; r++) {
        size_t run;
        if (!p->busy[r] && take(ctx, &run)) {
            int64_t k = (int64_t)run;
            MPI_Send(&k, 1, MPI_INT64_T, r, TAG_RUN, MPI_COMM_WORLD);
            p->busy[r] = 1;
        }
        busy += p->busy[r];
    }
    return busy;
}

static int take_none(void *ctx, size_t *run)
{
    (void)ctx, (void)run;
    return 0;
}

static void finish_drop(void *ctx, size_t run, const WfSweepResult *res) { (void)ctx, (void)run, (void)res; }

void wf_mpi_pool_destroy(WfMpiPool **pp)
{
    WfMpiPool *p = *pp;
    if (!p) return;
    /* Results still out are received (and dropped): a worker blocked sending a large message would otherwise
     * never read its stop message. */
    while (wf_mpi_pool_poll(p, take_none, finish_drop, NULL) > 0) wf_sleep_ms(1);
    int64_t stop = -1;
    for (int r = 1; r < p->size; r++) MPI_Send(&stop, 1, MPI_INT64_T, r, TAG_RUN, MPI_COMM_WORLD);
    WF_FREE(p->busy, p->msg, p);
    *pp = NULL;
}
