/* The sweep scheduler (sweep.h, wf_sweep_execute): runs pulled one at a time from a queue in table order by worker
 * threads, while one coordinating thread collects finished runs in completion order, reports them to the caller,
 * feeds remote workers (MPI ranks) and saves table snapshots. Runs differ in cost, hence the dynamic queue. */
#include "wavefuel/sweep.h"

#include <stdlib.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "util/clock.h"

/* The state shared by the coordinator (thread 0) and the worker threads. res[] and the queues change only under
 * the lock; a finished row never changes again, so the coordinator reads it unlocked once it has seen it in
 * done[]. */
typedef struct Exec {
    const WfSweep         *sw;
    const WfSweepExecOpts *o;
    WfSweepResult         *res;
    size_t                *todo, next;   /* runs to do (counts.n_todo), in table order; next one to hand out */
    size_t                *done, n_done; /* finished (or interrupted) runs, in order of completion */
    size_t                 n_saved_at;
    int                    local_active; /* worker threads still running */
    int                    abort;        /* a snapshot could not be written: hand out nothing more */
    double                 t0, last_save;
    WfSweepCounts          counts;
    WfSweepTiming          timing;
    WfError                save_err;
#ifdef _OPENMP
    omp_lock_t lock;
#endif
} Exec;

#ifdef _OPENMP
static void lock(Exec *e) { omp_set_lock(&e->lock); }
static void unlock(Exec *e) { omp_unset_lock(&e->lock); }
#else
static void lock(Exec *e) { (void)e; }
static void unlock(Exec *e) { (void)e; }
#endif

static int stopped(const Exec *e) { return e->o->stop && *e->o->stop; }

static int take(void *ctx, size_t *run)
{
    Exec *e = ctx;
    lock(e);
    int got = !stopped(e) && !e->abort && e->next < e->counts.n_todo;
    if (got) *run = e->todo[e->next++];
    unlock(e);
    return got;
}

static void finish(void *ctx, size_t run, const WfSweepResult *r)
{
    Exec *e = ctx;
    lock(e);
    e->res[run] = *r;
    e->done[e->n_done++] = run;
    unlock(e);
}

static int save(Exec *e)
{
    e->timing.wall_s = wf_wall_now() - e->t0;
    lock(e); /* rows being finished meanwhile wait: res[] must not change under the writer */
    WfError err = {0};
    int rc = wf_sweep_table_write(e->o->table_path, e->sw, e->res, &e->timing, &err);
    e->n_saved_at = e->n_done;
    if (rc && !e->abort) e->abort = 1, e->save_err = err;
    unlock(e);
    e->last_save = wf_wall_now();
    return rc;
}

/* Coordinator: report the runs finished since the last call, in completion order; save a snapshot when due. */
static void report(Exec *e)
{
    lock(e);
    size_t upto = e->n_done;
    unlock(e);
    WfSweepCounts *c = &e->counts;
    for (size_t j = c->n_reported; j < upto; j++) {
        size_t k = e->done[j];
        const WfSweepResult *r = &e->res[k];
        c->n_ok += r->status == WF_RUN_OK;
        c->n_failed += r->status == WF_RUN_FAILED;
        c->n_interrupted += r->status == WF_RUN_PENDING;
        c->n_reported = j + 1;
        if (e->o->on_finished) e->o->on_finished(e->o->ctx, k, r, c);
    }
    if (e->o->on_progress) e->o->on_progress(e->o->ctx, c, wf_wall_now() - e->t0);
    if (upto > e->n_saved_at && wf_wall_now() - e->last_save >= e->o->save_every_s) save(e);
}

/* Runs until nothing is left to take; with report_each (no coordinator thread) reports after every run. */
static void worker(Exec *e, int id, int report_each)
{
    WfSweepResult r;
    WfSweepRunOpts ro = e->o->run;
    ro.worker = id;
    size_t k;
    if (e->o->on_thread_start) e->o->on_thread_start(e->o->ctx);
    while (take(e, &k)) {
        wf_sweep_run(e->sw, k, &ro, e->o->stop, &r);
        finish(e, k, &r);
        if (report_each) report(e);
    }
    lock(e);
    e->local_active--;
    unlock(e);
}

/* Thread 0 coordinates (and feeds the remote workers); it sleeps 1 ms between polls. */
static void coordinate(Exec *e)
{
    const WfSweepRemote *rm = e->o->remote;
    for (;;) {
        int remote_busy = rm ? rm->poll(rm->ctx, take, finish, e) : 0;
        report(e);
        lock(e);
        int idle = e->local_active == 0 && remote_busy == 0;
        int nothing_left = stopped(e) || e->abort || e->next == e->counts.n_todo;
        unlock(e);
        if (idle && nothing_left) break;
        wf_sleep_ms(1);
    }
    report(e);
}

/* Without a worker thread (no OpenMP, or the runtime gave one thread): run here, then report. With remote
 * workers this thread only coordinates: a run here would leave their answers waiting for its length. */
static void serial(Exec *e)
{
    e->local_active = e->o->remote == NULL;
    if (e->local_active) worker(e, 0, 1);
    coordinate(e);
}

static void execute(Exec *e)
{
#ifdef _OPENMP
    omp_init_lock(&e->lock);
    int workers = e->o->workers;
#pragma omp parallel num_threads(workers + 1) default(none) shared(e)
    {
#pragma omp master
        {
            e->local_active = omp_get_num_threads() - 1;
            /* The runtime may give fewer threads than asked; remote workers are counted by the caller. */
            if (!e->o->remote) e->timing.workers = e->local_active > 0 ? e->local_active : 1;
        }
#pragma omp barrier
        if (e->local_active == 0)
            serial(e);
        else if (omp_get_thread_num() == 0)
            coordinate(e);
        else
            worker(e, omp_get_thread_num() - 1, 0);
    }
    omp_destroy_lock(&e->lock);
#else
    serial(e);
#endif
}

int wf_sweep_execute(const WfSweep *sw, WfSweepResult *res, const WfSweepExecOpts *o, WfSweepCounts *counts,
                     WfSweepTiming *timing, WfError *err)
{
    Exec e = {.sw = sw, .o = o, .res = res};
    e.todo = calloc(sw->n_runs ? sw->n_runs : 1, sizeof *e.todo);
    e.done = calloc(sw->n_runs ? sw->n_runs : 1, sizeof *e.done);
    int rc = !e.todo || !e.done ? wf_err(err, WF_ESYS, "out of memory for %zu runs", sw->n_runs) : 0;
    for (size_t i = 0; !rc && i < sw->n_runs; i++)
        if (res[i].status == WF_RUN_PENDING) e.todo[e.counts.n_todo++] = i;
    e.timing = (WfSweepTiming){o->mode, o->remote ? o->remote->workers : o->workers, o->run.threads, 0.0};
    e.t0 = e.last_save = wf_wall_now();
    if (!rc && e.counts.n_todo) {
        execute(&e);
        /* The final snapshot, unless one already failed (then the table keeps the last good one). */
        if (e.abort || save(&e)) {
            *err = e.save_err;
            rc = err->code ? err->code : WF_ESYS;
        }
    }
    e.timing.wall_s = wf_wall_now() - e.t0;
    if (counts) *counts = e.counts;
    if (timing) *timing = e.timing;
    free(e.todo);
    free(e.done);
    return rc;
}
