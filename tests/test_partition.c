/* A road split across processes (include/wavefuel/partition.h, docs/mpi.md) gives the bits of one process, without
 * MPI: R "ranks" are threads of this program, each with its own run of the same scenario, and the partition's
 * collective calls are made through shared memory and a barrier. Rank 0's records, its whole state after the run
 * (every per-vehicle array, controller memory, safety counts: what a checkpoint saves) and its summary equal those of
 * one process, for 2 and 3 ranks, windows of 16 steps and single steps, on a noisy graded ring with controllers and
 * a safety filter, and on a ring whose overlaps force repairs and redone windows; a stop requested by one rank stops
 * every rank at the same step. A corridor split into 2 and 3 segments gives one process's records, trips, state
 * (with every Edie cell and detector) and summary, with detectors at and beside the cuts and overlaps repaired
 * across them. tests/t_mpi.sh runs the same with MPI where it is installed. */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/corridor.h"
#include "wavefuel/engine.h"
#include "wavefuel/partition.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

enum { MAX_RANKS = 4, MAX_ROWS = 400 };

/* tests/test_window.c's ring: graded, three classes, speed limit, noisy heterogeneous IDM, PI with saturation under
 * a safety filter, FollowerStopper (9000 vehicles: 36 blocks, so that two ranks step with two threads each). */
static const char *ring_yaml =
    "seed: 11\n"
    "road:\n  length_m: 180000\n  speed_limit_mps: 24\n"
    "  grade: {points: [[0, 0.0], [60000, 0.02], [90000, 0.0], [135000, -0.02]]}\n"
    "time: {duration_s: 12, dt_s: 0.1, output_interval_s: 0.1, warmup_s: 3.3}\n"
    "fleet:\n  vehicles: 9000\n  placement: random\n"
    "  classes:\n    - {class: midsize_sedan, fraction: 0.5}\n    - {class: midsize_suv, fraction: 0.3}\n"
    "    - {class: class8_tractor, fraction: 0.2}\n"
    "  drivers:\n"
    "    - {model: idm, fraction: 0.6, noise_mps2: 0.3, feasible_accel: clip,\n"
    "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
    "    - {model: follower_stopper, fraction: 0.3}\n"
    "    - {model: pi_saturation, fraction: 0.1, safety: {kind: gipps, gap_min_m: 6}}\n"
    "initial: {state: equilibrium, jitter_m: 0.5}\n";

/* Noise far beyond what the brakes absorb: overlaps in many windows (as in tests/test_window.c), and at every edge
 * between the shares of 2 and 3 ranks (12 blocks: vehicles 1023, 1535 and 2047 are the last of a share; 2999's
 * leader is vehicle 0 across the ring's wrap) a driver with stronger noise still. */
static const char *overlap_yaml =
    "seed: 7\nroad: {length_m: 36000}\ntime: {duration_s: 20, dt_s: 0.1, output_interval_s: 0.5}\n"
    "fleet:\n  vehicles: 3000\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
    "  drivers:\n    - {model: idm, count: 2996, noise_mps2: 5, decel_max_mps2: 0.5}\n"
    "    - {model: idm, noise_mps2: 9, decel_max_mps2: 0.2, placement: explicit,\n"
    "       indices: [1023, 1535, 2047, 2999]}\n"
    "initial: {state: equilibrium}\n";

/* A corridor (wf_test.h) with detectors at and beside the cuts between the segments of 2 and 3 ranks (Edie cells of
 * 250 m: cuts at 6000 m, and at 4000 and 8000 m). */
static const char *corridor_yaml = WF_TEST_CORRIDOR_YAML;

/* Noise far beyond what the brakes absorb, in queues behind three slow zones that start past the cuts between the
 * segments (3000 m; 2000 and 4000 m) and a virtual leader that slows to 3 m/s: overlaps repaired along the road, some
 * between the ranks' vehicles alone in their step, and slow runs (waves) across the cuts. */
static const char *corridor_overlap_yaml =
    "seed: 5\nroad:\n  type: corridor\n  length_m: 6000\n  zones:\n"
    "    - {type: speed_limit, from_m: 2150, to_m: 2600, speed_limit_mps: 8}\n"
    "    - {type: speed_limit, from_m: 3150, to_m: 3600, speed_limit_mps: 5}\n"
    "    - {type: speed_limit, from_m: 4150, to_m: 4600, speed_limit_mps: 3}\n"
    "time: {duration_s: 600, dt_s: 0.1, output_interval_s: 2.0}\n"
    "fleet:\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
    "  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]\n"
    "corridor:\n  inflow: {flow_vph: 3000}\n"
    "  outflow: {type: speed, points: [[0, 20], [200, 20], [260, 3], [600, 3]]}\n"
    "  detectors: {x_m: [1995, 3000, 4001], interval_s: 30}\n  edie: {dx_m: 500, dt_s: 20}\n";

/* Vehicles far apart behind a prescribed-speed leader: the exit's segment is often empty, so the front vehicle
 * follows the leader from another rank, and the leader restarts behind each vehicle that leaves (rank 0's exits). */
static const char *corridor_sparse_yaml =
    "seed: 9\nroad: {type: corridor, length_m: 6000}\n"
    "time: {duration_s: 1200, dt_s: 0.1, output_interval_s: 3.0}\n"
    "fleet:\n  classes: [{class: midsize_sedan, fraction: 1}]\n"
    "  drivers: [{model: idm, fraction: 1, noise_mps2: 0.3}]\n"
    "corridor:\n  inflow: {flow_vph: 45}\n"
    "  outflow: {type: speed, points: [[0, 22], [600, 18], [1200, 22]]}\n"
    "  detectors: {x_m: [1999, 3000, 4000], interval_s: 60}\n  edie: {dx_m: 500, dt_s: 30}\n";

/* A queue behind a prescribed-speed leader that slows to 4 m/s, filling the road from the exit (Edie cells of 500 m:
 * cuts at 12 000 m; 8000 and 16 000 m), long enough by 1000 s for every rank's vehicles to step in windows of 16
 * behind the halo of the rank ahead, with vehicles crossing the cuts and leaving at the exit inside windows; noisy
 * heterogeneous IDM with PI with saturation under a safety filter, two classes, a grade, detectors at and beside the
 * cuts. */
static const char *corridor_window_yaml =
    "seed: 21\nroad:\n  type: corridor\n  length_m: 24000\n  speed_limit_mps: 14\n"
    "  grade: {points: [[0, 0], [9000, 0.01], [15000, -0.01], [24000, 0]]}\n"
    "time: {duration_s: 1800, dt_s: 0.1, output_interval_s: 10.0, warmup_s: 600}\n"
    "fleet:\n  classes:\n    - {class: midsize_sedan, fraction: 0.8}\n    - {class: class8_tractor, fraction: 0.2}\n"
    "  drivers:\n"
    "    - {model: idm, fraction: 0.85, noise_mps2: 0.2, heterogeneity: {spread: {v0_mps: 0.1, T_s: 0.15}}}\n"
    "    - {model: pi_saturation, fraction: 0.15, class: midsize_sedan, safety: {kind: gipps, gap_min_m: 4}}\n"
    "corridor:\n  inflow: {flow_vph: 3000, arrivals: poisson}\n"
    "  outflow: {type: speed, points: [[0, 14], [100, 14], [200, 4], [1800, 4]]}\n"
    "  detectors: {x_m: [3000, 7990, 8000, 11998, 12000, 12004, 16000, 16010, 20000], interval_s: 60}\n"
    "  edie: {dx_m: 500, dt_s: 60}\n";

/* What a run leaves: its records (and a corridor's trips) as doubles, its state after the run (rank 0: gathered a
 * share at a time), its summary, its steps. */
typedef struct Out {
    WfTestVals vals;
    size_t n_rows, n_trips;
    unsigned char *state;
    size_t state_size;
    WfSummary summary;
    long steps, windows, redone;
    int rc;
    const WfFleet *f;         /* a ring's fleet */
    double *x_end, *fuel_end; /* rank 0: its vehicles' positions and fuel at the end, n_end of each */
    size_t n_end;
} Out;

static int keep_row(void *ctx, const WfSim *sim, const WfRecord *rec, WfError *err)
{
    (void)err;
    Out *o = ctx;
    wf_test_keep(&o->vals, rec->v, rec->n);
    wf_test_keep(&o->vals, rec->class_fuel_rate_gps, wf_sim_scenario(sim)->n_classes);
    o->n_rows++;
    return 0;
}

static int keep_trips(void *ctx, const WfSim *sim, const WfTrip *trips, size_t n, WfError *err)
{
    (void)sim, (void)err;
    Out *o = ctx;
    for (size_t k = 0; k < n; k++) wf_test_keep_trip(&o->vals, &trips[k]);
    o->n_trips += n;
    return 0;
}

/* ------------------------------------------------------------------ the partition in shared memory */

typedef struct Shared {
    int size;
    pthread_barrier_t bar;
    const void *ptr[MAX_RANKS];
    int flag[MAX_RANKS];
    long stop_after[MAX_RANKS]; /* a rank raises its own stop at its n-th exchange (0: never) */
    unsigned char chain[4096];  /* what a chain passes on */
} Shared;

typedef struct Rank {
    Shared *sh;
    int rank;
    long exchanges;
    void *recv; /* the exchange posted: bytes from rank `from` (-1: none) */
    size_t bytes;
    int from;
    volatile sig_atomic_t own_stop;
} Rank;

/* The exchange posted: this rank's send buffer published (every rank reaches the barrier before any reads); waited:
 * the next rank's copied, and no buffer reused before every rank has copied. Steps in between overlap it, as MPI's
 * do. */
static int post_next(void *ctx, const void *send, void *recv, size_t bytes, WfError *err)
{
    (void)err;
    Rank *r = ctx;
    if (++r->exchanges == r->sh->stop_after[r->rank]) r->own_stop = 1;
    r->sh->ptr[r->rank] = send;
    r->recv = recv, r->bytes = bytes, r->from = (r->rank + 1) % r->sh->size;
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int post_back(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err)
{
    (void)err, (void)send_bytes;
    Rank *r = ctx;
    r->sh->ptr[r->rank] = send;
    r->recv = recv, r->bytes = recv_bytes, r->from = r->rank - 1;
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int wait_next(void *ctx, WfError *err)
{
    (void)err;
    Rank *r = ctx;
    if (r->from >= 0) memcpy(r->recv, r->sh->ptr[r->from], r->bytes);
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int or_all(void *ctx, int *flags, WfError *err)
{
    (void)err;
    Rank *r = ctx;
    r->sh->flag[r->rank] = *flags;
    pthread_barrier_wait(&r->sh->bar);
    int all = 0;
    for (int k = 0; k < r->sh->size; k++) all |= r->sh->flag[k];
    pthread_barrier_wait(&r->sh->bar);
    *flags = all;
    return 0;
}

static int sum_u64(void *ctx, uint64_t *v, size_t m, WfError *err)
{
    Rank *r = ctx;
    uint64_t *sum = calloc(m ? m : 1, sizeof *sum);
    if (!sum) return wf_err(err, WF_ESYS, "out of memory");
    r->sh->ptr[r->rank] = v;
    pthread_barrier_wait(&r->sh->bar);
    for (int k = 0; k < r->sh->size; k++)
        for (size_t j = 0; j < m; j++) sum[j] += ((const uint64_t *)r->sh->ptr[k])[j];
    pthread_barrier_wait(&r->sh->bar);
    memcpy(v, sum, m * sizeof *v);
    free(sum);
    return 0;
}

static int gather(void *ctx, void *buf, const size_t *off, int root, WfError *err)
{
    (void)err;
    Rank *r = ctx;
    r->sh->ptr[r->rank] = buf;
    pthread_barrier_wait(&r->sh->bar);
    if (root < 0 || root == r->rank)
        for (int k = 0; k < r->sh->size; k++)
            if (k != r->rank)
                memcpy((unsigned char *)buf + off[k], (const unsigned char *)r->sh->ptr[k] + off[k], off[k + 1] - off[k]);
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int allgather(void *ctx, const void *mine, void *all, size_t bytes, WfError *err)
{
    (void)err;
    Rank *r = ctx;
    r->sh->ptr[r->rank] = mine;
    pthread_barrier_wait(&r->sh->bar);
    for (int k = 0; k < r->sh->size; k++) memcpy((unsigned char *)all + (size_t)k * bytes, r->sh->ptr[k], bytes);
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int shift(void *ctx, const void *send, size_t send_bytes, void *recv, size_t recv_bytes, WfError *err)
{
    (void)err, (void)send_bytes;
    Rank *r = ctx;
    r->sh->ptr[r->rank] = send;
    pthread_barrier_wait(&r->sh->bar);
    if (r->rank + 1 < r->sh->size) memcpy(recv, r->sh->ptr[r->rank + 1], recv_bytes);
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

/* The ranks in turn, one per round between barriers; the last rank's buffer back to rank 0. */
static int chain(void *ctx, void *buf, size_t bytes, void (*fn)(void *arg, void *buf), void *arg, WfError *err)
{
    Rank *r = ctx;
    if (bytes > sizeof r->sh->chain) return wf_err(err, WF_ESYS, "test transport: a chain of %zu bytes", bytes);
    for (int k = 0; k < r->sh->size; k++) {
        if (k == r->rank) {
            if (k) memcpy(buf, r->sh->chain, bytes);
            fn(arg, buf);
            memcpy(r->sh->chain, buf, bytes);
        }
        pthread_barrier_wait(&r->sh->bar);
    }
    if (r->rank == 0) memcpy(buf, r->sh->chain, bytes);
    pthread_barrier_wait(&r->sh->bar);
    return 0;
}

static int sum_f64(void *ctx, double *v, size_t m, WfError *err)
{
    Rank *r = ctx;
    double *sum = calloc(m ? m : 1, sizeof *sum);
    if (!sum) return wf_err(err, WF_ESYS, "out of memory");
    r->sh->ptr[r->rank] = v;
    pthread_barrier_wait(&r->sh->bar);
    for (int k = 0; k < r->sh->size; k++)
        for (size_t j = 0; j < m; j++) sum[j] += ((const double *)r->sh->ptr[k])[j];
    pthread_barrier_wait(&r->sh->bar);
    memcpy(v, sum, m * sizeof *v);
    free(sum);
    return 0;
}

/* ------------------------------------------------------------------ runs */

typedef struct Job {
    const char *path;
    const char *set[3];
    size_t n_set;
    int threads;
    Shared *sh;   /* NULL: one process */
    int rank;
    Out *out;
} Job;

/* The state after the run as a checkpoint takes it (wf_sim_state_pieces: a split ring's shares of a block come to
 * rank 0 one at a time), concatenated on rank 0; every rank takes part. */
typedef struct Pieces {
    unsigned char    *buf;
    const size_t     *off;
    const WfStateVar *vars;
} Pieces;

static int copy_piece(void *ctx, size_t j, size_t lo, size_t hi, WfError *err)
{
    (void)err;
    const Pieces *p = ctx;
    memcpy(p->buf + p->off[j] + lo, (const unsigned char *)p->vars[j].data + lo, hi - lo);
    return 0;
}

static void state_on_rank0(WfSim *sim, int rank, Out *o)
{
    WfStateVar vars[WF_MAX_STATE_VARS];
    size_t nv = wf_sim_state(sim, vars, WF_MAX_STATE_VARS), off[WF_MAX_STATE_VARS + 1] = {0};
    for (size_t k = 0; k < nv; k++) off[k + 1] = off[k] + vars[k].size;
    o->state_size = off[nv];
    Pieces p = {rank ? NULL : calloc(off[nv] ? off[nv] : 1, 1), off, vars};
    WfError err = {0};
    if (wf_sim_state_pieces(sim, vars, nv, p.buf ? copy_piece : NULL, &p, &err))
        printf("  rank %d: %s\n", rank, err.msg);
    o->state = p.buf;
}

/* A ring's positions and fuel at the end as the result writer takes them (wf_sim_shares: a share at a time on
 * rank 0); nothing for a corridor. */
static int copy_share(void *ctx, size_t lo, size_t hi, WfError *err)
{
    (void)err;
    Out *o = ctx;
    memcpy(o->x_end + lo, o->f->x_m + lo, (hi - lo) * sizeof *o->x_end);
    memcpy(o->fuel_end + lo, o->f->fuel_g + lo, (hi - lo) * sizeof *o->fuel_end);
    return 0;
}

static void ends_on_rank0(WfSim *sim, int rank, Out *o)
{
    o->f = wf_sim_fleet(sim);
    if (!o->f) return;
    o->n_end = o->f->n;
    if (!rank) o->x_end = calloc(o->n_end, sizeof *o->x_end), o->fuel_end = calloc(o->n_end, sizeof *o->fuel_end);
    WfError err = {0};
    if (wf_sim_shares(sim, rank ? NULL : copy_share, o, &err)) printf("  rank %d: %s\n", rank, err.msg);
}

static void *job_main(void *arg)
{
    Job *j = arg;
    Out *o = j->out;
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
#ifdef _OPENMP
    omp_set_num_threads(j->threads);
#endif
    Rank rk = {.sh = j->sh, .rank = j->rank};
    WfPartition part = {.rank = j->rank, .size = j->sh ? j->sh->size : 1, .ctx = &rk, .post_next = post_next,
                        .wait_next = wait_next, .post_back = post_back, .or_all = or_all, .sum_u64 = sum_u64,
                        .gather = gather,
                        .allgather = allgather, .shift = shift, .chain = chain, .sum_f64 = sum_f64,
                        .stop_own = &rk.own_stop};
    WfOutput out = {.record = keep_row, .trips = keep_trips, .ctx = o};
    memset(o, 0, sizeof *o);
    o->rc = wf_scenario_load(j->path, j->set, j->n_set, &sc, &err);
    if (!o->rc) o->rc = wf_sim_create_part(sc, j->sh ? &part : NULL, &sim, &err);
    if (!o->rc) o->rc = wf_sim_run(sim, &out, NULL, NULL, j->sh ? &part.stop_all : NULL, &err);
    if (o->rc && o->rc != WF_EINTR) printf("  rank %d: %s\n", j->rank, err.msg);
    if (sim) {
        state_on_rank0(sim, j->rank, o);
        ends_on_rank0(sim, j->rank, o);
        o->summary = *wf_sim_summary(sim);
        o->steps = wf_sim_steps_done(sim);
        wf_sim_window_stats(sim, &o->windows, &o->redone);
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    return NULL;
}

/* Ranks 0..size-1 of the split run into out[0..size-1]; rank stop_rank raises its own stop at its stop_after-th
 * exchange with the next rank. */
static void run_split(const char *path, const char *const *set, size_t n_set, int size, int threads, int stop_rank,
                      long stop_after, Out *out)
{
    Shared sh = {.size = size};
    pthread_barrier_init(&sh.bar, NULL, (unsigned)size);
    Job jobs[MAX_RANKS];
    pthread_t th[MAX_RANKS];
    for (int r = 0; r < size; r++) {
        sh.stop_after[r] = r == stop_rank ? stop_after : 0;
        jobs[r] = (Job){.path = path, .n_set = n_set, .threads = threads, .sh = &sh, .rank = r, .out = &out[r]};
        for (size_t k = 0; k < n_set; k++) jobs[r].set[k] = set[k];
        pthread_create(&th[r], NULL, job_main, &jobs[r]);
    }
    for (int r = 0; r < size; r++) pthread_join(th[r], NULL);
    pthread_barrier_destroy(&sh.bar);
}

static void run_one(const char *path, const char *const *set, size_t n_set, Out *out)
{
    Job j = {.path = path, .n_set = n_set, .threads = 1, .out = out};
    for (size_t k = 0; k < n_set; k++) j.set[k] = set[k];
    job_main(&j);
}

static void out_free(Out *o, int n)
{
    for (int k = 0; k < n; k++) {
        free(o[k].state), free(o[k].vals.v), free(o[k].x_end), free(o[k].fuel_end);
        o[k].state = NULL, o[k].vals = (WfTestVals){0}, o[k].x_end = o[k].fuel_end = NULL;
    }
}

static void compare(const Out *o, const Out *ref, const char *what)
{
    CHECK(o->rc == 0 && ref->rc == 0, "%s: a run failed (%d, %d)", what, o->rc, ref->rc);
    CHECK(o->n_rows == ref->n_rows && o->n_rows > 0 && o->n_trips == ref->n_trips,
          "%s: %zu records and %zu trips, one process %zu and %zu", what, o->n_rows, o->n_trips, ref->n_rows,
          ref->n_trips);
    size_t first = 0, n = o->vals.n, nr = ref->vals.n;
    while (first < n && first < nr && !memcmp(&o->vals.v[first], &ref->vals.v[first], sizeof(double))) first++;
    CHECK(n == nr && first == n, "%s: records and trips differ from value %zu of %zu (%.17g, one process %.17g)", what,
          first, nr, first < n ? o->vals.v[first] : NAN, first < nr ? ref->vals.v[first] : NAN);
    CHECK(o->state_size == ref->state_size && memcmp(o->state, ref->state, o->state_size) == 0,
          "%s: the state after the run (accumulators, modes, controller memory, safety counts) differs", what);
    CHECK(memcmp(&o->summary, &ref->summary, sizeof o->summary) == 0, "%s: the summary differs", what);
    int ends_same = o->n_end == ref->n_end &&
                    (!o->n_end || (!memcmp(o->x_end, ref->x_end, o->n_end * sizeof *o->x_end) &&
                                   !memcmp(o->fuel_end, ref->fuel_end, o->n_end * sizeof *o->fuel_end)));
    CHECK(ends_same, "%s: the positions or fuel handed to the result writer a share at a time differ", what);
}

/* Every split against one process, windows of 16 and single steps. */
static void split_equals_one(const char *yaml, const char *name, int need_redone)
{
    char dir[] = "/tmp/wf_part_XXXXXX", path[64];
    if (!wf_test_write_yaml(yaml, dir, path, sizeof path)) return;
    static const char *k16[] = {"time.block_steps=16"}, *k1[] = {"time.block_steps=1"};
    const char *const *sets[] = {k16, k1};
    Out *ref = calloc(1, sizeof *ref), *out = calloc(MAX_RANKS, sizeof *out);
    run_one(path, k1, 1, ref);
    long windows = 0, redone = 0;
    for (int size = 2; size <= 3; size++)
        for (int v = 0; v < 2; v++)
            for (int threads = 1; threads <= (size == 2 && v == 0 ? 2 : 1); threads++) {
                char what[128];
                snprintf(what, sizeof what, "%s, %d ranks, %s, %d threads", name, size, sets[v][0], threads);
                run_split(path, sets[v], 1, size, threads, -1, 0, out);
                compare(&out[0], ref, what);
                windows += out[0].windows, redone += out[0].redone;
                for (int r = 1; r < size; r++)
                    CHECK(out[r].rc == 0 && out[r].steps == ref->steps && out[r].windows == out[0].windows,
                          "%s: rank %d took %ld steps and %ld windows, rank 0 %ld and %ld", what, r, out[r].steps,
                          out[r].windows, out[0].steps, out[0].windows);
                out_free(out, size);
            }
    printf("  %s: %ld windows over the split runs, %ld redone; %zu records\n", name, windows, redone, ref->n_rows);
    CHECK(windows > 0, "%s: no split run took a window", name);
    if (need_redone) CHECK(redone > 0, "%s: no window was redone: the repair path was not exercised", name);
    out_free(ref, 1);
    free(ref), free(out);
    wf_test_remove_yaml(dir, path);
}

/* A corridor split 2 and 3 ways (1 and 2 threads) against one process stepped one step at a time: every record,
 * trip, the whole state after the run (vehicles, Edie cells, detectors, counters, controller memory, safety counts)
 * and the summary. set[0], when n_set > 0: the split runs' time.block_steps, and windows must then be taken, the same
 * number on every rank (and some redone where overlaps are needed); the others: keys for every run. */
static void corridor_split_equals_one(const char *yaml, const char *name, int need_overlaps, const char *const *set,
                                      size_t n_set)
{
    char dir[] = "/tmp/wf_part_XXXXXX", path[64];
    if (!wf_test_write_yaml(yaml, dir, path, sizeof path)) return;
    Out *ref = calloc(1, sizeof *ref), *out = calloc(MAX_RANKS, sizeof *out);
    const char *block = n_set ? set[0] : NULL;
    long windows = 0, redone = 0;
    run_one(path, set + 1, n_set > 1 ? n_set - 1 : 0, ref);
    for (int size = 2; size <= 3; size++)
        for (int threads = 1; threads <= (size == 2 ? 2 : 1); threads++) {
            char what[160];
            snprintf(what, sizeof what, "%s, %d ranks, %d threads%s%s", name, size, threads, block ? ", " : "",
                     block ? block : "");
            run_split(path, set, n_set, size, threads, -1, 0, out);
            compare(&out[0], ref, what);
            windows += out[0].windows, redone += out[0].redone;
            for (int r = 1; r < size; r++)
                CHECK(out[r].rc == 0 && out[r].steps == ref->steps && out[r].windows == out[0].windows,
                      "%s: rank %d took %ld steps and %ld windows, rank 0 %ld and %ld", what, r, out[r].steps,
                      out[r].windows, out[0].steps, out[0].windows);
            out_free(out, size);
        }
    printf("  %s: %zu records, %zu trips, %lld overlaps repaired; %ld windows over the split runs, %ld redone\n", name,
           ref->n_rows, ref->n_trips, (long long)ref->summary.counts.overlaps, windows, redone);
    if (block) CHECK(windows > 0, "%s: no split run took a window", name);
    if (block && need_overlaps) CHECK(redone > 0, "%s: no window was redone: the undo was not exercised", name);
    CHECK(ref->n_trips > 10, "%s: only %zu trips", name, ref->n_trips);
    if (need_overlaps) CHECK(ref->summary.counts.overlaps > 0, "%s: no overlap was repaired", name);
    out_free(ref, 1);
    free(ref), free(out);
    wf_test_remove_yaml(dir, path);
}

static void test_corridor(void) { corridor_split_equals_one(corridor_yaml, "corridor", 0, NULL, 0); }
static void test_corridor_sparse(void)
{
    corridor_split_equals_one(corridor_sparse_yaml, "sparse corridor", 0, NULL, 0);
}
static void test_corridor_overlaps(void)
{
    corridor_split_equals_one(corridor_overlap_yaml, "overlapping corridor", 1, NULL, 0);
}
/* Windows across the ranks; then with noise beyond what the brakes absorb, so that windows overlap and are undone on
 * every rank. */
static void test_corridor_windows(void)
{
    static const char *k16[] = {"time.block_steps=16"};
    static const char *noisy[] = {"time.block_steps=16", "fleet.drivers[0].noise_mps2=3",
                                  "fleet.drivers[0].decel_max_mps2=0.6"};
    corridor_split_equals_one(corridor_window_yaml, "corridor in windows", 0, k16, 1);
    corridor_split_equals_one(corridor_window_yaml, "overlapping corridor in windows", 1, noisy, 3);
}

static void test_noisy_ring_with_controllers(void) { split_equals_one(ring_yaml, "graded ring, controllers", 0); }
static void test_overlaps_repaired(void) { split_equals_one(overlap_yaml, "overlapping ring", 1); }

/* One rank's stop request (raised in the middle of a window's exchanges) stops every rank after the same step. */
static void test_stop_on_one_rank(void)
{
    char dir[] = "/tmp/wf_part_XXXXXX", path[64];
    if (!wf_test_write_yaml(ring_yaml, dir, path, sizeof path)) return;
    Out *out = calloc(MAX_RANKS, sizeof *out);
    run_split(path, NULL, 0, 3, 1, 2, 9, out);
    for (int r = 0; r < 3; r++)
        CHECK(out[r].rc == WF_EINTR && out[r].steps == out[0].steps && out[r].steps > 0 && out[r].steps < 120,
              "rank %d: status %d, stopped after %ld steps, rank 0 after %ld (of 120)", r, out[r].rc, out[r].steps,
              out[0].steps);
    printf("  a stop raised by rank 2 at its 9th exchange: every rank stopped after %ld steps\n", out[0].steps);
    out_free(out, 3);
    free(out);
    wf_test_remove_yaml(dir, path);
}

int main(void)
{
    RUN(test_noisy_ring_with_controllers);
    RUN(test_overlaps_repaired);
    RUN(test_stop_on_one_rank);
    RUN(test_corridor);
    RUN(test_corridor_overlaps);
    RUN(test_corridor_sparse);
    RUN(test_corridor_windows);
    TEST_EXIT();
}
