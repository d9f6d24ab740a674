/* Open corridors (src/core/corridor.c, src/scenario/scenario_corridor.c) against references derived here: conservation of
 * vehicles at every record and in the trips, detectors and Edie sums; the free-flow stationary state of IDM solved
 * in closed form with the CIRCLES fuel rate re-typed from issue 3; Edie flow and density on the model's
 * equilibrium Q(k) (free branch, a headway zone, and a congested branch behind a prescribed downstream speed);
 * the fuel of one vehicle cruising over a symmetric hill (grade points and an elevation CSV) against the formulas
 * summed and integrated over the profile; entries and exits that leave earlier vehicles' results bit-identical;
 * scenario errors. Scenarios are written to a temporary directory and run through the public API with an
 * in-memory output. */
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/corridor.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

static char tmp_dir[64];

/* ------------------------------------------------------------------------------------------ harness */

typedef struct Rec {
    WfCorridorRow *rows;
    size_t         n, cap;
    WfTrip        *trips;
    size_t         n_trips, cap_trips;
    long           bad;      /* invariant violations seen at records */
    double         L;
    int            check;    /* check the invariants at every record */
} Rec;

static int rec_row(void *ctx, const WfSim *c, const WfRecord *rec, WfError *err)
{
    Rec *r = ctx;
    if (r->n == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 1024;
        WfCorridorRow *p = realloc(r->rows, cap * sizeof *p);
        if (!p) return wf_err(err, WF_ESYS, "test: out of memory");
        r->rows = p, r->cap = cap;
    }
    WfCorridorRow *row = &r->rows[r->n++];
    WF_TEST_KEEP_RECORD(row, rec, wf_sim_scenario(c)->n_classes);
    if (!r->check) return 0;
    /* Conservation and road order, recomputed from the vehicles as the output sees them: at the record's instant or
     * one step further (WfOutput.record), never half-way through a step. The record's own counts against the trips:
     * trips_vs_rows. */
    const WfCorridorVehicles *vh = wf_corridor_vehicles(wf_sim_corridor(c));
    const WfCorridorCounts *k = wf_corridor_counts(wf_sim_corridor(c));
    double t = row->v[WF_CTS_T];
    long bad = 0;
    bad += k->entered != k->exited + (int64_t)vh->n;
    bad += k->arrived != k->entered + k->queued;
    bad += row->v[WF_CTS_ENTERED] != row->v[WF_CTS_EXITED] + row->v[WF_CTS_VEHICLES];
    bad += row->v[WF_CTS_ARRIVED] != row->v[WF_CTS_ENTERED] + row->v[WF_CTS_QUEUED];
    for (size_t i = 0; i < vh->n; i++) {
        size_t s = wf_corridor_slot(vh, i);
        bad += !(vh->x_m[s] >= 0.0 && vh->x_m[s] < r->L) || !(vh->v_mps[s] >= 0.0);
        if (i) {
            size_t p = wf_corridor_slot(vh, i - 1);
            bad += !(vh->x_m[p] - vh->length_m[p] - vh->x_m[s] >= 0.0); /* gap >= 0: order kept */
            bad += vh->serial[p] + 1 != vh->serial[s];                  /* FIFO: serials consecutive */
        }
    }
    if (bad && r->bad < 3) printf("  t = %g: %ld invariant violations\n", t, bad);
    r->bad += bad;
    return 0;
}

/* Records whose vehicles on the road, entries and exits differ from the trips': a vehicle is on the road at instant
 * t when it entered at t or before and had not yet reached L (t_exit > t; an exit's time lies within its step). */
static long trips_vs_rows(const Rec *r)
{
    long bad = 0;
    for (size_t j = 0; j < r->n; j++) {
        double t = r->rows[j].v[WF_CTS_T] + 1e-9, on = 0, entered = 0, exited = 0;
        for (size_t i = 0; i < r->n_trips; i++) {
            const WfTrip *p = &r->trips[i];
            int in = p->t_entry_s <= t, out = p->completed && p->t_exit_s <= t;
            entered += in, exited += out, on += in && !out;
        }
        bad += r->rows[j].v[WF_CTS_VEHICLES] != on || r->rows[j].v[WF_CTS_ENTERED] != entered ||
               r->rows[j].v[WF_CTS_EXITED] != exited;
    }
    return bad;
}

static int rec_trips(void *ctx, const WfSim *c, const WfTrip *t, size_t n, WfError *err)
{
    (void)c;
    Rec *r = ctx;
    if (r->n_trips + n > r->cap_trips) {
        size_t cap = r->cap_trips ? 2 * r->cap_trips : 1024;
        while (cap < r->n_trips + n) cap *= 2;
        WfTrip *p = realloc(r->trips, cap * sizeof *p);
        if (!p) return wf_err(err, WF_ESYS, "test: out of memory");
        r->trips = p, r->cap_trips = cap;
    }
    memcpy(r->trips + r->n_trips, t, n * sizeof *t);
    r->n_trips += n;
    return 0;
}

static void rec_free(Rec *r)
{
    free(r->rows);
    free(r->trips);
    memset(r, 0, sizeof *r);
}

static int write_file(const char *name, const char *text, char *path, size_t len)
{
    snprintf(path, len, "%s/%s", tmp_dir, name);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL, "cannot write %s", path);
    if (!fp) return -1;
    fputs(text, fp);
    CHECK(fclose(fp) == 0, "cannot close %s", path);
    return 0;
}

static WfScenario *load_text(const char *name, const char *text)
{
    char path[256];
    if (write_file(name, text, path, sizeof path)) return NULL;
    WfScenario *sc = NULL;
    WfError err = {0};
    int rc = wf_scenario_load(path, NULL, 0, &sc, &err);
    CHECK(rc == 0, "scenario %s: %s", name, err.msg);
    return rc ? NULL : sc;
}

/* Run a corridor; returns the engine (caller destroys) or NULL after a failed CHECK. */
static WfSim *run_corridor(const WfScenario *sc, Rec *rec)
{
    WfSim *c = NULL;
    WfError err = {0};
    rec->L = sc->road.length_m;
    int rc = wf_sim_create(sc, &c, &err);
    CHECK(rc == 0, "wf_sim_create: %s", err.msg);
    if (rc) return NULL;
    WfOutput out = {.record = rec_row, .trips = rec_trips, .ctx = rec};
    rc = wf_sim_run(c, &out, NULL, NULL, NULL, &err);
    CHECK(rc == 0, "wf_sim_run: %s", err.msg);
    if (rc) wf_sim_destroy(&c);
    return c;
}

static int by_serial(const void *a, const void *b)
{
    uint64_t x = ((const WfTrip *)a)->serial, y = ((const WfTrip *)b)->serial;
    return (x > y) - (x < y);
}

/* ------------------------------------------------------------------------------------ references */

/* IDM (Treiber et al. 2000) uniform flow: s_e(v) = (s0 + v T) / sqrt(1 - (v/v0)^4); the speed for a gap by
 * bisection (s_e grows from s0 at v = 0 to infinity at v0). */
typedef struct Idm {
    double v0, T, s0, a, b;
} Idm;

static double idm_se(const Idm *p, double v) { return (p->s0 + v * p->T) / sqrt(1.0 - pow(v / p->v0, 4.0)); }

static double idm_v_of_gap(const Idm *p, double gap)
{
    double lo = 0.0, hi = p->v0;
    if (gap <= p->s0) return 0.0;
    for (int it = 0; it < 2000; it++) {
        double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (idm_se(p, mid) < gap) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* Stationary flow q (veh/s) of vehicles of length len: the speed with s_e(v) + len = v / q, on the free branch
 * (the larger root: v / q - len - s_e(v) changes sign from + to - between the capacity speed and v0). */
static double idm_v_of_flow_free(const Idm *p, double q, double len)
{
    double lo = 0.0, hi = p->v0, best = 0.0, vbest = 0.0;
    /* the capacity speed maximises v / (s_e(v) + len): a coarse scan then bisection above it */
    for (int i = 1; i < 3000; i++) {
        double v = p->v0 * i / 3000.0, f = v / (idm_se(p, v) + len);
        if (f > best) best = f, vbest = v;
    }
    lo = vbest;
    for (int it = 0; it < 2000; it++) {
        double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (mid / q - len - idm_se(p, mid) > 0.0) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* The model's fundamental diagram: Q(k) = k v_e(1/k - len), veh/s from veh/m. */
static double idm_Q(const Idm *p, double k, double len) { return k * idm_v_of_gap(p, 1.0 / k - len); }

/* CIRCLES midsize sedan, typed from the release table (issue 3); the a = 0 branch of the model. */
static double sedan_fuel_a0(double v, double th)
{
    const double c0 = 0.19829, c1 = 0.021122, c2 = 0, c3 = 2.7801e-05, z0 = 2.5227, z1 = 0.76464, z2 = 0.0060213;
    const double q0 = 0, q1 = 0.050556, p0 = 0.23956, p1 = 0.0080592, p2 = 0.0027737;
    const double vc = 5.07, beta = 0.1271, a0 = -0.15742, a1 = -0.00037876, a2 = -9.1124, a3 = -0.00022957,
                 a4 = -0.011559;
    double P = p0 + p1 * v + p2 * v * v, Q = q0 + q1 * v, ap = fmax(0.0, -P / (2 * Q));
    double f = c0 + c1 * v + c2 * v * v + c3 * v * v * v + q0 * ap * ap + q1 * ap * ap * v + z0 * th + z1 * th * v +
               z2 * th * v * v;
    f = fmax(f, v <= vc ? beta : 0.0);
    if (v > vc && 0.0 <= a0 + a1 * v + a2 * th + a3 * v * v + a4 * v * th) f = 0.0;
    return f;
}

/* Edie over a union of cells: Σ distance / Σ area and Σ time / Σ area (veh/s, veh/m). */
static void edie_region(const WfEdie *e, double L, double T, double x0, double x1, double t0, double t1, double *q,
                        double *k)
{
    double d = 0, tt = 0, area = 0;
    for (size_t j = 0; j < e->nt; j++) {
        double ta = (double)j * e->dt_s, tb = fmin((double)(j + 1) * e->dt_s, T);
        if (ta < t0 - 1e-9 || tb > t1 + 1e-9) continue;
        for (size_t i = 0; i < e->nx; i++) {
            double xa = (double)i * e->dx_m, xb = i + 1 == e->nx ? L : (double)(i + 1) * e->dx_m;
            if (xa < x0 - 1e-9 || xb > x1 + 1e-9) continue;
            d += e->dist_m[j * e->nx + i];
            tt += e->time_s[j * e->nx + i];
            area += (xb - xa) * (tb - ta);
        }
    }
    *q = d / area;
    *k = tt / area;
}

/* ------------------------------------------------------------------------------ 1. conservation */

static const char *conservation_yaml(const char *inflow_csv)
{
    static char yaml[4096];
    snprintf(yaml, sizeof yaml,
             "seed: 11\n"
             "road:\n"
             "  type: corridor\n"
             "  length_m: 3000\n"
             "  zones:\n"
             "    - {type: headway, from_m: 1000, to_m: 1400, factor: 1.4}\n"
             "    - {type: speed_limit, from_m: 2200, to_m: 2500, speed_limit_mps: 7}\n"
             "time: {duration_s: 900, dt_s: 0.1, output_interval_s: 1, warmup_s: 0}\n"
             "fleet:\n"
             "  classes: [{class: midsize_sedan, fraction: 0.8}, {class: class8_tractor, fraction: 0.2}]\n"
             "  drivers:\n"
             "    - {name: calm, model: idm, fraction: 0.6, noise_mps2: 0.3,\n"
             "       params: {v0_mps: 30, T_s: 1.4, s0_m: 2, a_mps2: 1.0, b_mps2: 1.5},\n"
             "       heterogeneity: {spread: {T_s: 0.15, v0_mps: 0.1}}}\n"
             "    - {name: brisk, model: idm, fraction: 0.4, noise_mps2: 0.3,\n"
             "       params: {v0_mps: 32, T_s: 1.0, s0_m: 2, a_mps2: 1.4, b_mps2: 2.0}}\n"
             "corridor:\n"
             "  inflow: {csv: %s, arrivals: poisson}\n"
             "  detectors: {x_m: [10, 1500, 2900], interval_s: 60}\n"
             "  edie: {dx_m: 100, dt_s: 30}\n",
             inflow_csv);
    return yaml;
}

static void test_conservation(void)
{
    char p1[256], p2[256];
    /* Demand rises above what the speed-limit zone passes, then falls: a queue forms at the entrance and drains.
     * Run B's demand differs only after t = 400 s. */
    if (write_file("inflow_a.csv", "time_s,flow_vph\n0,1000\n200,2600\n600,2600\n700,400\n", p1, sizeof p1) ||
        write_file("inflow_b.csv", "time_s,flow_vph\n0,1000\n200,2600\n400,2600\n401,100\n", p2, sizeof p2))
        return;
    WfScenario *sa = load_text("cons_a.yaml", conservation_yaml("inflow_a.csv"));
    WfScenario *sb = load_text("cons_b.yaml", conservation_yaml("inflow_b.csv"));
    Rec ra = {.check = 1}, rb = {0};
    WfSim *ca = sa ? run_corridor(sa, &ra) : NULL;
    WfSim *cb = sb ? run_corridor(sb, &rb) : NULL;
    if (ca && cb) {
        const WfSummary *s = wf_sim_summary(ca);
        const WfCorridorCounts *k = &s->counts;
        double max_q = 0;
        for (size_t i = 0; i < ra.n; i++) max_q = fmax(max_q, ra.rows[i].v[WF_CTS_QUEUED]);
        CHECK(ra.n == 901, "%zu records", ra.n);
        CHECK(ra.bad == 0, "%ld invariant violations at records", ra.bad);
        CHECK(k->delayed > 50 && max_q > 10, "the scenario must queue entries (delayed %lld, longest queue %g)",
              (long long)k->delayed, max_q);
        CHECK(k->arrived == k->entered + k->queued && k->entered == k->exited + (int64_t)wf_corridor_vehicles(wf_sim_corridor(ca))->n,
              "final counts: arrived %lld entered %lld exited %lld queued %lld", (long long)k->arrived,
              (long long)k->entered, (long long)k->exited, (long long)k->queued);
        /* Every entered vehicle has exactly one trip; completed ones are the exits. */
        qsort(ra.trips, ra.n_trips, sizeof *ra.trips, by_serial);
        CHECK(ra.n_trips == (size_t)k->entered, "%zu trips for %lld entries", ra.n_trips, (long long)k->entered);
        long done = 0, bad = 0, delayed = 0;
        double delay = 0, fuel = 0, dist = 0, det_pass[3] = {0, 0, 0}, time_lo = 0;
        const double xd[3] = {10, 1500, 2900};
        for (size_t i = 0; i < ra.n_trips; i++) {
            const WfTrip *t = &ra.trips[i];
            bad += t->serial != i;
            bad += !(t->t_entry_s >= t->t_arrival_s) || (t->completed && !(t->t_exit_s > t->t_entry_s));
            done += t->completed;
            delay += t->t_entry_s - t->t_arrival_s;
            delayed += t->t_entry_s - t->t_arrival_s > 0.05;
            fuel += t->fuel_g;
            /* A trip covers [0, L] when completed, [0, its final position] otherwise (positions never decrease). */
            double reach = t->completed ? 3000.0 : t->dist_m;
            dist += reach;
            for (int q = 0; q < 3; q++) det_pass[q] += reach > xd[q];
            time_lo += (t->completed ? t->t_exit_s : 900.0) - t->t_entry_s;
        }
        CHECK(bad == 0, "%ld trips out of order or with inconsistent times", bad);
        long off = trips_vs_rows(&ra);
        CHECK(off == 0, "%ld of %zu records count other vehicles on the road, entries or exits than the trips", off,
              ra.n);
        CHECK(done == k->exited, "%ld completed trips, %lld exits", done, (long long)k->exited);
        CHECK(delayed == k->delayed, "%ld trips waited, counter says %lld", delayed, (long long)k->delayed);
        CHECK_REL(delay, k->queue_delay_s, 1e-9);
        CHECK_REL(fuel, s->fuel_g, 1e-9); /* no warm-up: the window is the whole run */
        /* Edie: Σ distance is every trip's distance inside [0, L]; Σ time differs from the trips' time on the road
         * only by the part of each exit step spent beyond L (< dt per exit). */
        const WfEdie *e = wf_corridor_edie(wf_sim_corridor(ca));
        double ed = 0, et = 0;
        for (size_t i = 0; i < e->nx * e->nt; i++) ed += e->dist_m[i], et += e->time_s[i];
        CHECK_REL(ed, dist, 1e-9);
        CHECK(et <= time_lo + 1e-6 && et >= time_lo - 0.1 * (double)k->exited - 1e-6,
              "Edie time %.9g s, trips %.9g s, %lld exits", et, time_lo, (long long)k->exited);
        /* Detectors: every passage counted once. */
        const WfDetectors *d = wf_corridor_detectors(wf_sim_corridor(ca));
        for (size_t q = 0; q < 3; q++) {
            int64_t cnt = 0;
            for (size_t j = 0; j < d->n_int; j++) cnt += d->count[j * d->n_det + q];
            CHECK((double)cnt == det_pass[q], "detector at %g m: %lld passages, trips say %.0f", xd[q], (long long)cnt,
                  det_pass[q]);
        }
        /* Vehicles that arrived before the demands differ have bit-identical trips in both runs: entries behind
         * them and exits ahead of them never touched their state. */
        qsort(rb.trips, rb.n_trips, sizeof *rb.trips, by_serial);
        size_t same = 0, n400 = 0;
        for (size_t i = 0; i < ra.n_trips && ra.trips[i].t_arrival_s < 400.0; i++) n400++;
        for (size_t i = 0; i < n400 && i < rb.n_trips; i++) same += memcmp(&ra.trips[i], &rb.trips[i], sizeof(WfTrip)) == 0;
        CHECK(n400 > 100 && same == n400, "%zu of %zu early trips identical", same, n400);
        CHECK(rb.n_trips < ra.n_trips, "run B (less demand) should have fewer trips (%zu vs %zu)", rb.n_trips,
              ra.n_trips);
        printf("  conservation: %zu records, %lld arrived, %lld entered (%lld delayed, longest queue %.0f), %lld exited, "
               "%lld overlaps; %zu early trips bit-identical under a different later demand\n",
               ra.n, (long long)k->arrived, (long long)k->entered, (long long)k->delayed, max_q, (long long)k->exited,
               (long long)k->overlaps, same);
    }
    wf_sim_destroy(&ca);
    wf_sim_destroy(&cb);
    rec_free(&ra);
    rec_free(&rb);
    wf_scenario_destroy(&sa);
    wf_scenario_destroy(&sb);
}

/* ------------------------------------------------------------------------------------ 2. free flow */

static const Idm IDM_FF = {30.0, 1.0, 2.0, 1.0, 1.5};
#define FF_LEN 5.0
#define FF_Q_VPH 720.0 /* one vehicle every 5 s: well below the capacity (~2600 veh/h) */

/* One run of the free-flow corridor: 720 veh/h of identical IDM sedans on a flat 4 km road. outflow_speed < 0:
 * free outflow; otherwise vehicles that leave drive on at that speed (the road continues in the same state). */
static WfSim *free_flow_run(const char *name, double outflow_speed, WfScenario **sc, Rec *rec)
{
    char yaml[2048], outflow[128] = "";
    if (outflow_speed >= 0) snprintf(outflow, sizeof outflow, "  outflow: {type: speed, speed_mps: %.17g}\n", outflow_speed);
    snprintf(yaml, sizeof yaml,
             "road: {type: corridor, length_m: 4000}\n"
             "time: {duration_s: 800, dt_s: 0.1, output_interval_s: 1}\n"
             "fleet:\n"
             "  classes: [{class: midsize_sedan, fraction: 1, length_m: %.17g}]\n"
             "  drivers: [{model: idm, fraction: 1, params: {v0_mps: %.17g, T_s: %.17g, s0_m: %.17g, a_mps2: %.17g,"
             " b_mps2: %.17g, delta: 4}}]\n"
             "corridor:\n"
             "  inflow: {flow_vph: %.17g}\n"
             "%s"
             "  detectors: {x_m: [2000, 3500], interval_s: 100}\n"
             "  edie: {dx_m: 100, dt_s: 100}\n",
             FF_LEN, IDM_FF.v0, IDM_FF.T, IDM_FF.s0, IDM_FF.a, IDM_FF.b, FF_Q_VPH, outflow);
    *sc = load_text(name, yaml);
    rec->check = 1;
    return *sc ? run_corridor(*sc, rec) : NULL;
}

/* Trips after the entry transient (the first vehicles follow a leader at the free speed): entry at v*, travel time
 * L / v* to within a step, fuel f(v*, 0, 0) x travel time; no stops. Returns the number of trips checked. */
static size_t check_stationary_trips(const Rec *rec, double vs, double fs, double fuel_tol, double *worst_v,
                                     double *worst_tt, double *worst_fuel)
{
    const double L = 4000, dt = 0.1;
    size_t checked = 0;
    *worst_v = *worst_tt = *worst_fuel = 0;
    for (size_t i = 0; i < rec->n_trips; i++) {
        const WfTrip *t = &rec->trips[i];
        CHECK(t->stops == 0, "trip %llu stopped %u times", (unsigned long long)t->serial, t->stops);
        if (!t->completed || t->serial < 20) continue;
        double tt = t->t_exit_s - t->t_entry_s;
        *worst_v = fmax(*worst_v, fabs(t->v_entry_mps - vs) / vs);
        *worst_tt = fmax(*worst_tt, fabs(tt - L / vs));
        *worst_fuel = fmax(*worst_fuel, fabs(t->fuel_g - fs * tt) / (fs * tt));
        checked++;
    }
    CHECK(checked >= 60, "only %zu stationary trips", checked);
    CHECK(*worst_v < 1e-6, "entry speed off v* by %.3g (relative)", *worst_v);
    CHECK(*worst_tt <= dt + 1e-9, "travel time off L / v* by %.3g s", *worst_tt);
    CHECK(*worst_fuel < fuel_tol, "trip fuel off f(v*) x travel time by %.3g (relative, tolerance %.2g)", *worst_fuel,
          fuel_tol);
    return checked;
}

static void test_free_flow(void)
{
    const double h = 3600.0 / FF_Q_VPH, L = 4000, T = 800;
    double vs = idm_v_of_flow_free(&IDM_FF, 1.0 / h, FF_LEN), fs = sedan_fuel_a0(vs, 0.0);
    CHECK(fabs(idm_se(&IDM_FF, vs) + FF_LEN - vs * h) < 1e-9, "stationary speed %.17g not solved", vs);
    /* Free outflow: the vehicle nearest the exit sees an empty road once its leader has left and speeds up over
     * its last gap (~140 m) before leaving, so trips are compared with a 1 % tolerance, and the exact stationary
     * values are checked away from the ends: Edie fuel per vehicle-second and per metre in the interior, and the
     * detectors. */
    WfScenario *sc = NULL;
    Rec rec = {0};
    WfSim *c = free_flow_run("free.yaml", -1.0, &sc, &rec);
    if (c) {
        const WfSummary *s = wf_sim_summary(c);
        CHECK(rec.bad == 0, "%ld invariant violations", rec.bad);
        CHECK(s->counts.delayed == 0 && s->counts.max_queue <= 1, "free flow must not queue (delayed %lld)",
              (long long)s->counts.delayed);
        CHECK(s->stops_per_vkm == 0.0, "stops in free flow: %g /vkm", s->stops_per_vkm);
        double wv, wt, wf;
        size_t n = check_stationary_trips(&rec, vs, fs, 0.01, &wv, &wt, &wf);
        const WfEdie *e = wf_corridor_edie(wf_sim_corridor(c));
        double fuel = 0, time = 0, dist = 0;
        for (size_t j = 3; j < e->nt; j++)
            for (size_t i = 5; i < 35; i++) {
                size_t a = j * e->nx + i;
                fuel += e->fuel_g[a], time += e->time_s[a], dist += e->dist_m[a];
            }
        CHECK_REL(fuel / time, fs, 1e-6);
        CHECK_REL(fuel / dist, fs / vs, 1e-6);
        const WfDetectors *d = wf_corridor_detectors(wf_sim_corridor(c));
        for (size_t j = 4; j < d->n_int; j++)
            for (size_t q = 0; q < d->n_det; q++) {
                size_t i = j * d->n_det + q;
                CHECK(d->count[i] == 20, "interval %zu detector %zu: %lld passages, expected 20", j, q,
                      (long long)d->count[i]);
                CHECK_REL(d->sum_v_mps[i] / (double)d->count[i], vs, 1e-6);
                CHECK_REL(d->occupied_s[i] / d->interval_s, FF_LEN / (vs * h), 1e-6);
            }
        printf("  free flow %.0f veh/h: v* = %.9f m/s (closed form), f(v*) = %.9f g/s; free outflow: %zu trips after the "
               "entry transient: entry speed within %.2g, travel time within %.3g s, fuel within %.2g of f(v*) x travel "
               "time (exit effect); interior Edie fuel %.9f g/s per vehicle\n",
               FF_Q_VPH, vs, fs, n, wv, wt, wf, fuel / time);
    }
    wf_sim_destroy(&c);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
    /* The road continuing downstream in the same state (vehicles that leave drive on at v*): every trip after the
     * entry transient is stationary from entrance to exit. */
    c = free_flow_run("free_out.yaml", vs, &sc, &rec);
    if (c) {
        double wv, wt, wf;
        size_t n = check_stationary_trips(&rec, vs, fs, 1e-6, &wv, &wt, &wf);
        CHECK(wf_sim_summary(c)->counts.delayed == 0, "delayed entries");
        printf("  free flow, downstream at v*: %zu trips: entry speed within %.2g, travel time within %.3g s, fuel "
               "within %.2g (relative) of f(v*) x travel time\n", n, wv, wt, wf);
    }
    (void)L, (void)T;
    wf_sim_destroy(&c);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

/* ------------------------------------------------------------------------------- 3. fundamental diagram */

/* Free branch at 1440 veh/h with a headway zone (T x 1.5 on [2000, 3000) m, below its capacity of ~1790 veh/h):
 * upstream, inside and downstream of the zone the Edie (q, k) must lie on IDM's Q(k) for the T in force there, and
 * k must be the equilibrium density of that flow (11 % higher in the zone). */
static void test_fundamental_diagram_free(void)
{
    const double L = 4000, T = 900, qv = 1440;
    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "road: {type: corridor, length_m: %.17g, zones: [{type: headway, from_m: 2000, to_m: 3000, factor: 1.5}]}\n"
             "time: {duration_s: %.17g, dt_s: 0.1, output_interval_s: 10}\n"
             "fleet:\n"
             "  classes: [{class: midsize_sedan, fraction: 1, length_m: %.17g}]\n"
             "  drivers: [{model: idm, fraction: 1, params: {v0_mps: %.17g, T_s: %.17g, s0_m: %.17g, a_mps2: %.17g,"
             " b_mps2: %.17g}}]\n"
             "corridor: {inflow: {flow_vph: %.17g}, edie: {dx_m: 100, dt_s: 50}}\n",
             L, T, FF_LEN, IDM_FF.v0, IDM_FF.T, IDM_FF.s0, IDM_FF.a, IDM_FF.b, qv);
    WfScenario *sc = load_text("fd_free.yaml", yaml);
    Rec rec = {0};
    WfSim *c = sc ? run_corridor(sc, &rec) : NULL;
    if (c) {
        const WfEdie *e = wf_corridor_edie(wf_sim_corridor(c));
        Idm zone = IDM_FF;
        zone.T *= 1.5;
        struct { const char *name; double x0, x1; const Idm *p; } reg[3] = {
            {"upstream", 600, 1600, &IDM_FF}, {"in the zone", 2300, 2900, &zone}, {"downstream", 3400, 4000, &IDM_FF}};
        double kk[3];
        for (int r = 0; r < 3; r++) {
            double q, k;
            edie_region(e, L, T, reg[r].x0, reg[r].x1, 400, T, &q, &k);
            double Qk = idm_Q(reg[r].p, k, FF_LEN), ke = (qv / 3600) / idm_v_of_flow_free(reg[r].p, qv / 3600, FF_LEN);
            kk[r] = k;
            CHECK(fabs(q - Qk) <= 0.02 * Qk, "%s: Edie q = %.6g veh/h, model Q(k = %.6g veh/km) = %.6g veh/h", reg[r].name,
                  q * 3600, k * 1000, Qk * 3600);
            CHECK(fabs(q * 3600 - qv) <= 0.01 * qv, "%s: Edie q = %.6g veh/h, inflow %.0f veh/h", reg[r].name, q * 3600,
                  qv);
            CHECK(fabs(k - ke) <= 0.02 * ke, "%s: Edie k = %.6g veh/km, equilibrium density of the flow %.6g veh/km",
                  reg[r].name, k * 1000, ke * 1000);
            printf("  FD free branch %-12s Edie q %8.3f veh/h, k %7.4f veh/km (equilibrium %7.4f); model Q(k) %8.3f veh/h "
                   "(rel. diff %.2g)\n", reg[r].name, q * 3600, k * 1000, ke * 1000, Qk * 3600, (q - Qk) / Qk);
        }
        CHECK(kk[1] > 1.05 * kk[0], "the headway zone must be denser (k %.4g vs %.4g veh/km)", kk[1] * 1000, kk[0] * 1000);
    }
    wf_sim_destroy(&c);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

/* Congested branch: demand above what leaves behind a downstream speed boundary (vehicles that leave drive on at
 * v_out), so a queue fills the road; Edie (q, k) over its stationary part must lie on Q(k), at the spacing of v_out.
 * IDM with a larger maximum acceleration keeps this state string-stable (no stop-and-go to spoil homogeneity). */
static const Idm IDM_CG = {30.0, 1.0, 2.0, 2.5, 2.0};

static void test_fundamental_diagram_congested(void)
{
    const double L = 2000, T = 2400, v_out = 12.0, t0 = 1600;
    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "road: {type: corridor, length_m: %.17g}\n"
             "time: {duration_s: %.17g, dt_s: 0.1, output_interval_s: 10}\n"
             "fleet:\n"
             "  classes: [{class: midsize_sedan, fraction: 1, length_m: %.17g}]\n"
             "  drivers: [{model: idm, fraction: 1, params: {v0_mps: %.17g, T_s: %.17g, s0_m: %.17g, a_mps2: %.17g,"
             " b_mps2: %.17g}}]\n"
             "corridor:\n"
             "  inflow: {flow_vph: 3000}\n"
             "  outflow: {type: speed, speed_mps: %.17g}\n"
             "  edie: {dx_m: 100, dt_s: 50}\n",
             L, T, FF_LEN, IDM_CG.v0, IDM_CG.T, IDM_CG.s0, IDM_CG.a, IDM_CG.b, v_out);
    WfScenario *sc = load_text("fd_cong.yaml", yaml);
    Rec rec = {0};
    WfSim *c = sc ? run_corridor(sc, &rec) : NULL;
    if (c) {
        const WfEdie *e = wf_corridor_edie(wf_sim_corridor(c));
        double q, k;
        edie_region(e, L, T, 200, 1800, t0, T, &q, &k);
        double Qk = idm_Q(&IDM_CG, k, FF_LEN), k_out = 1.0 / (idm_se(&IDM_CG, v_out) + FF_LEN);
        CHECK(fabs(q - Qk) <= 0.02 * Qk, "Edie q = %.6g veh/h, model Q(k = %.6g veh/km) = %.6g veh/h", q * 3600, k * 1000,
              Qk * 3600);
        CHECK(fabs(k - k_out) <= 0.02 * k_out, "Edie k = %.6g veh/km, equilibrium density at v_out %.6g veh/km",
              k * 1000, k_out * 1000);
        double vmin = INFINITY, vmax = 0;
        for (size_t j = 0; j < e->nt; j++)
            for (size_t i = 2; i < 18; i++)
                if ((double)j * e->dt_s >= t0) {
                    double v = e->dist_m[j * e->nx + i] / e->time_s[j * e->nx + i];
                    vmin = fmin(vmin, v), vmax = fmax(vmax, v);
                }
        CHECK(vmax - vmin < 0.05 * v_out, "not homogeneous: cell speeds %.4g .. %.4g m/s", vmin, vmax);
        CHECK(wf_corridor_counts(wf_sim_corridor(c))->queued > 100, "the demand must exceed the discharge (queue %lld)",
              (long long)wf_corridor_counts(wf_sim_corridor(c))->queued);
        printf("  FD congested (v_out %.0f m/s): Edie q %8.3f veh/h, k %7.4f veh/km (equilibrium at v_out %7.4f); model "
               "Q(k) %8.3f veh/h (rel. diff %.2g); cell speeds %.4f..%.4f m/s\n",
               v_out, q * 3600, k * 1000, k_out * 1000, Qk * 3600, (q - Qk) / Qk, vmin, vmax);
    }
    wf_sim_destroy(&c);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

/* ----------------------------------------------------------------------------------------- 4. grade */

/* theta of the test's hill: piecewise linear through the points (grade input), or from an elevation profile. */
static const double HX[] = {0, 600, 900, 1200, 1500, 1800, 2100, 2400, 3000};
static const double HT[] = {0, 0, 0.04, 0.04, 0, -0.04, -0.04, 0, 0};
static const double EX[] = {0, 600, 1200, 1500, 2100, 3000};
static const double EZ[] = {0, 0, 18, 18, 0, 0};

static double hill_theta(int elevation, double x)
{
    if (elevation) {
        for (int i = 0; i < 5; i++)
            if (x >= EX[i] && x < EX[i + 1]) return atan((EZ[i + 1] - EZ[i]) / (EX[i + 1] - EX[i]));
        return 0.0;
    }
    for (int i = 0; i < 8; i++)
        if (x >= HX[i] && x < HX[i + 1]) return HT[i] + (HT[i + 1] - HT[i]) * (x - HX[i]) / (HX[i + 1] - HX[i]);
    return 0.0;
}

/* One sedan at the road's 20 m/s speed limit (IDM wants 30: the limit holds it at exactly 20, a = 0), over a
 * symmetric hill. Its trip fuel is the left-point sum of f(20, 0, theta(x_k)) dt over x_k = 2 k m, computed here,
 * and within 1e-3 of the integral of f(20, 0, theta(x)) / 20 over the profile (Simpson, 3e5 panels); climbing
 * cells cost more per km than descending ones, as the class profile reports. */
static void grade_case(int elevation)
{
    const double L = 3000, v = 20, dt = 0.1;
    char yaml[2048], csv[256];
    const char *grade = "grade: {points: [[0, 0], [600, 0], [900, 0.04], [1200, 0.04], [1500, 0], [1800, -0.04], "
                        "[2100, -0.04], [2400, 0], [3000, 0]]}";
    if (elevation && write_file("hill_z.csv", "x_m,z_m\n0,0\n600,0\n1200,18\n1500,18\n2100,0\n3000,0\n", csv, sizeof csv))
        return;
    snprintf(yaml, sizeof yaml,
             "road: {type: corridor, length_m: %.17g, speed_limit_mps: %.17g, %s}\n"
             "time: {duration_s: 200, dt_s: %.17g, output_interval_s: 1}\n"
             "fleet:\n"
             "  classes: [{class: midsize_sedan, fraction: 1}]\n"
             "  drivers: [{model: idm, fraction: 1, params: {v0_mps: 30}}]\n"
             "corridor: {inflow: {flow_vph: 3600, vehicles: 1}, edie: {dx_m: 100, dt_s: 10}}\n",
             L, v, elevation ? "elevation: {csv: hill_z.csv}" : grade, dt);
    WfScenario *sc = load_text(elevation ? "hill_z.yaml" : "hill.yaml", yaml);
    Rec rec = {0};
    WfSim *c = sc ? run_corridor(sc, &rec) : NULL;
    if (c) {
        CHECK(rec.n_trips == 1 && rec.trips[0].completed, "expected one completed trip (%zu)", rec.n_trips);
        const WfTrip *t = rec.n_trips ? &rec.trips[0] : NULL;
        double sum = 0, cell_f[30] = {0}, cell_th[30];
        long steps = lround(L / (v * dt));
        for (long k = 0; k < steps; k++) {
            double fk = sedan_fuel_a0(v, hill_theta(elevation, 2.0 * (double)k)) * dt;
            sum += fk;
            cell_f[(2 * k) / 100] += fk;
        }
        /* Simpson's rule on 3e5 panels (kinks and the fuel-cut jump cost ~1e-7 relative). */
        const long np = 300000;
        double integ = 0, hx = L / (double)np;
        for (long i = 0; i <= np; i++) {
            double w = (i == 0 || i == np) ? 1 : (i % 2 ? 4 : 2);
            integ += w * sedan_fuel_a0(v, hill_theta(elevation, (double)i * hx));
        }
        integ *= hx / 3.0 / v;
        /* Cell mean grades (analytic integrals of the profiles, by fine midpoint sums: exact for steps and linear
         * pieces whose breakpoints fall on cell edges, which all of them do). */
        double fu = 0, fd = 0;
        int nu = 0, nd = 0;
        for (int i = 0; i < 30; i++) {
            double s = 0;
            for (int m = 0; m < 1000; m++) s += hill_theta(elevation, 100.0 * i + 0.1 * (m + 0.5));
            cell_th[i] = s / 1000;
            if (cell_th[i] > 1e-4) fu += cell_f[i], nu++;
            else if (cell_th[i] < -1e-4) fd += cell_f[i], nd++;
        }
        const WfSummary *s = wf_sim_summary(c);
        if (t) {
            CHECK_REL(t->fuel_g, sum, 1e-9);
            CHECK(fabs(t->fuel_g - integ) <= 1e-3 * integ, "trip fuel %.9g g, integral over the profile %.9g g",
                  t->fuel_g, integ);
            CHECK_REL(t->t_exit_s - t->t_entry_s, L / v, 1e-9);
        }
        CHECK_REL(s->cls[0].g_per_km_up, fu / (nu * 0.1), 1e-9);
        CHECK_REL(s->cls[0].g_per_km_down, fd / (nd * 0.1), 1e-9);
        CHECK(s->cls[0].g_per_km_up > 2.0 * s->cls[0].g_per_km_down, "climbing %.4g g/km vs descending %.4g g/km",
              s->cls[0].g_per_km_up, s->cls[0].g_per_km_down);
        printf("  hill (%s): trip fuel %.9f g; left-point sum of the formula %.9f g; integral over the profile %.9f g "
               "(rel. diff %.2g); climbing %.3f g/km, descending %.3f g/km, flat %.3f g/km\n",
               elevation ? "elevation CSV" : "grade points", t ? t->fuel_g : NAN, sum, integ,
               t ? (t->fuel_g - integ) / integ : NAN, s->cls[0].g_per_km_up, s->cls[0].g_per_km_down,
               s->cls[0].g_per_km_flat);
    }
    wf_sim_destroy(&c);
    rec_free(&rec);
    wf_scenario_destroy(&sc);
}

static void test_grade(void)
{
    grade_case(0);
    grade_case(1);
}

/* ------------------------------------------------------------------------- 5. state save and restore */

/* A run stopped at a record time by its own output (as SIGTERM stops it), its state blocks copied at the
 * checkpoint the engine then requests, and a second engine built from the same scenario that gets the copied bytes
 * and runs on: its records and trips must continue the first run's exactly, and every result of the two together
 * must be the bytes of an uninterrupted run. The scenario exercises what the CLI test (tests/t_corridor_resume.sh)
 * does not: interleaved placement, a time-varying deterministic demand that stops after a number of vehicles, a
 * leader outflow starting inside the road, ACC and a PI controller with memory. */
typedef struct Snap {
    Rec            rec;
    double         stop_at_s;
    volatile sig_atomic_t stop;
    int            taken;       /* checkpoints requested */
    size_t         rows, trips; /* records and trips output when the last one was taken */
    WfStateVar     vars[WF_MAX_STATE_VARS];
    unsigned char *bytes[WF_MAX_STATE_VARS];
    size_t         n_vars;
} Snap;

static int snap_row(void *ctx, const WfSim *c, const WfRecord *rec, WfError *err)
{
    Snap *sn = ctx;
    if (rec->v[WF_CTS_T] >= sn->stop_at_s) sn->stop = SIGTERM;
    return rec_row(&sn->rec, c, rec, err);
}

static int snap_trips(void *ctx, const WfSim *c, const WfTrip *t, size_t n, WfError *err)
{
    return rec_trips(&((Snap *)ctx)->rec, c, t, n, err);
}

static int snap_checkpoint(void *ctx, const WfSim *c, WfError *err)
{
    Snap *sn = ctx;
    sn->n_vars = wf_sim_state((WfSim *)c, sn->vars, WF_MAX_STATE_VARS);
    for (size_t i = 0; i < sn->n_vars; i++) {
        if (!sn->bytes[i]) sn->bytes[i] = malloc(sn->vars[i].size + 1); /* block sizes are fixed for a corridor */
        if (!sn->bytes[i]) return wf_err(err, WF_ESYS, "test: out of memory");
        memcpy(sn->bytes[i], sn->vars[i].data, sn->vars[i].size);
    }
    sn->taken++;
    sn->rows = sn->rec.n;
    sn->trips = sn->rec.n_trips;
    return 0;
}

static void test_state_restore(void)
{
    WfScenario *sc = load_text("restore.yaml",
                               "seed: 5\n"
                               "road:\n"
                               "  type: corridor\n"
                               "  length_m: 2000\n"
                               "  speed_limit_mps: 30\n"
                               "  grade: {points: [[0, 0.01], [1000, -0.01], [2000, 0.01]]}\n"
                               "  zones: [{type: speed_limit, from_m: 1200, to_m: 1400, speed_limit_mps: 10},\n"
                               "          {type: headway, from_m: 300, to_m: 700, factor: 1.3}]\n"
                               "time: {duration_s: 1200, dt_s: 0.1, output_interval_s: 1, warmup_s: 100}\n"
                               "fleet:\n"
                               "  placement: interleaved\n"
                               "  classes: [{class: midsize_sedan, fraction: 0.6},\n"
                               "            {class: midsize_suv, fraction: 0.2},\n"
                               "            {class: class8_tractor, fraction: 0.2}]\n"
                               "  drivers:\n"
                               "    - {name: human, model: idm, fraction: 0.6, noise_mps2: 0.3,\n"
                               "       params: {v0_mps: 28, T_s: 1.3, s0_m: 2, a_mps2: 1.0, b_mps2: 1.5},\n"
                               "       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}\n"
                               "    - {name: acc, model: acc, fraction: 0.2}\n"
                               "    - {name: pi, model: pi_saturation, fraction: 0.2, class: midsize_sedan}\n"
                               "corridor:\n"
                               "  inflow: {points: [[0, 900], [300, 2400], [900, 600]], vehicles: 400}\n"
                               "  outflow: {type: leader, points: [[0, 20], [500, 6], [700, 20]], offset_m: -300}\n"
                               "  detectors: {x_m: [100, 1300, 1900], interval_s: 60}\n"
                               "  edie: {dx_m: 100, dt_s: 30}\n");
    if (!sc) return;
    Rec ra = {0};
    WfSim *ca = run_corridor(sc, &ra), *cb = NULL, *cc = NULL;
    WfError err = {0};
    Snap sn = {.stop_at_s = 517.0};
    Rec rc_ = {0};
    int rc = wf_sim_create(sc, &cb, &err);
    CHECK(rc == 0, "create: %s", err.msg);
    if (ca && !rc) {
        WfOutput ob = {.record = snap_row, .trips = snap_trips, .checkpoint = snap_checkpoint, .ctx = &sn};
        wf_sim_set_checkpoint_interval(cb, 1e-9); /* every step: the last one taken is the interruption's */
        rc = wf_sim_run(cb, &ob, NULL, NULL, &sn.stop, &err);
        CHECK(rc == WF_EINTR, "the stopped run: rc %d (%s)", rc, err.msg);
        CHECK(sn.taken > 100 && sn.rows == 518, "checkpoints %d, records %zu at the last", sn.taken, sn.rows);
        rc = wf_sim_create(sc, &cc, &err);
        CHECK(rc == 0, "create: %s", err.msg);
    }
    if (ca && cc && sn.taken) {
        WfStateVar v[WF_MAX_STATE_VARS];
        size_t nv = wf_sim_state(cc, v, WF_MAX_STATE_VARS);
        CHECK(nv == sn.n_vars && nv <= WF_MAX_STATE_VARS, "%zu blocks, %zu saved", nv, sn.n_vars);
        for (size_t i = 0; i < nv && i < sn.n_vars; i++) {
            CHECK(v[i].size == sn.vars[i].size && !strcmp(v[i].name, sn.vars[i].name), "block %zu differs", i);
            if (v[i].size == sn.vars[i].size) memcpy(v[i].data, sn.bytes[i], v[i].size);
        }
        /* A state that cannot belong to this corridor is refused; the saved one is accepted. */
        size_t first = wf_corridor_vehicles(wf_sim_corridor(cc))->first;
        for (size_t i = 0; i < nv; i++)
            if (!strcmp(v[i].name, "first")) *(size_t *)v[i].data = wf_corridor_vehicles(wf_sim_corridor(cc))->cap;
        rc = wf_sim_restored(cc, &err);
        CHECK(rc == WF_EINPUT && strstr(err.msg, "vehicle buffer indices"), "bad state: rc %d '%s'", rc, err.msg);
        for (size_t i = 0; i < nv; i++)
            if (!strcmp(v[i].name, "first")) *(size_t *)v[i].data = first;
        rc = wf_sim_restored(cc, &err);
        CHECK(rc == 0, "restored: %s", err.msg);
        WfOutput oc = {.record = rec_row, .trips = rec_trips, .ctx = &rc_};
        rc = rc ? rc : wf_sim_run(cc, &oc, NULL, NULL, NULL, &err);
        CHECK(rc == 0, "the resumed run: %s", err.msg);
    }
    if (ca && cc && !rc) {
        const WfCorridorCounts *k = wf_corridor_counts(wf_sim_corridor(ca));
        CHECK(sn.rows + rc_.n == ra.n, "records: %zu before, %zu after, %zu uninterrupted", sn.rows, rc_.n, ra.n);
        CHECK(sn.trips + rc_.n_trips == ra.n_trips, "trips: %zu + %zu, %zu uninterrupted", sn.trips, rc_.n_trips,
              ra.n_trips);
        CHECK(sn.trips > 50 && k->delayed > 20 && k->arrived == 400 && k->overlaps > 0,
              "the run must have trips before the stop (%zu), delayed entries (%lld), every arrival (%lld), overlaps "
              "(%lld)", sn.trips, (long long)k->delayed, (long long)k->arrived, (long long)k->overlaps);
        size_t same_rows = 0, same_trips = 0;
        for (size_t i = 0; i < ra.n && i < sn.rows + rc_.n; i++) {
            const WfCorridorRow *r = i < sn.rows ? &sn.rec.rows[i] : &rc_.rows[i - sn.rows];
            same_rows += !memcmp(r, &ra.rows[i], sizeof *r);
        }
        for (size_t i = 0; i < ra.n_trips && i < sn.trips + rc_.n_trips; i++) {
            const WfTrip *t = i < sn.trips ? &sn.rec.trips[i] : &rc_.trips[i - sn.trips];
            same_trips += !memcmp(t, &ra.trips[i], sizeof *t);
        }
        CHECK(same_rows == ra.n && same_trips == ra.n_trips, "%zu of %zu records, %zu of %zu trips identical",
              same_rows, ra.n, same_trips, ra.n_trips);
        const WfEdie *ea = wf_corridor_edie(wf_sim_corridor(ca)), *ec = wf_corridor_edie(wf_sim_corridor(cc));
        const WfDetectors *da = wf_corridor_detectors(wf_sim_corridor(ca)), *dc = wf_corridor_detectors(wf_sim_corridor(cc));
        size_t ne = ea->nx * ea->nt, nd = da->n_int * da->n_det;
        CHECK(!memcmp(ea->dist_m, ec->dist_m, ne * 8) && !memcmp(ea->time_s, ec->time_s, ne * 8) &&
                  !memcmp(ea->fuel_g, ec->fuel_g, ne * 8) &&
                  !memcmp(ea->class_fuel_g, ec->class_fuel_g, 3 * ea->nx * 8) &&
                  !memcmp(ea->class_dist_m, ec->class_dist_m, 3 * ea->nx * 8),
              "Edie sums differ");
        CHECK(!memcmp(da->count, dc->count, nd * 8) && !memcmp(da->occupied_s, dc->occupied_s, nd * 8) &&
                  !memcmp(da->sum_inv_v_spm, dc->sum_inv_v_spm, nd * 8),
              "detector sums differ");
        CHECK(!memcmp(wf_sim_summary(ca), wf_sim_summary(cc), sizeof(WfSummary)), "summaries differ");
        printf("  state restore: stopped at t = %.0f s after %d checkpoints (%zu blocks), %zu records and %zu trips "
               "identical to the uninterrupted run\n",
               sn.stop_at_s + 0.1, sn.taken, sn.n_vars, same_rows, same_trips);
    }
    for (size_t i = 0; i < WF_MAX_STATE_VARS; i++) free(sn.bytes[i]);
    wf_sim_destroy(&ca);
    wf_sim_destroy(&cb);
    wf_sim_destroy(&cc);
    wf_scenario_destroy(&sc);
    rec_free(&ra);
    rec_free(&sn.rec);
    rec_free(&rc_);
}

/* --------------------------------------------------------------------------------- 6. scenario errors */

static void expect_error(const char *name, const char *yaml, const char *needle)
{
    char path[256];
    if (write_file(name, yaml, path, sizeof path)) return;
    WfScenario *sc = NULL;
    WfError err = {0};
    int rc = wf_scenario_load(path, NULL, 0, &sc, &err);
    CHECK(rc == WF_EINPUT && strstr(err.msg, needle), "%s: rc %d, message '%s' (expected '%s')", name, rc, err.msg,
          needle);
    wf_scenario_destroy(&sc);
}

static void test_scenario_errors(void)
{
    const char *head = "road: {type: corridor, length_m: 1000}\n"
                       "time: {duration_s: 100}\n"
                       "fleet: {classes: [{class: midsize_sedan, fraction: 1}], drivers: [{model: idm, fraction: 1}]}\n";
    char y[1024];
    snprintf(y, sizeof y, "%scorridor: {inflow: {flow_vph: 1000, flow: 3}}\n", head);
    expect_error("e1.yaml", y, "unknown key 'corridor.inflow.flow'");
    snprintf(y, sizeof y, "%scorridor: {detectors: {x_m: [10]}}\n", head);
    expect_error("e2.yaml", y, "missing key 'inflow'");
    snprintf(y, sizeof y, "%scorridor: {inflow: {flow_vph: 1000}, outflow: {type: leader, speed_mps: 5, offset_m: -2000}}\n",
             head);
    expect_error("e3.yaml", y, "offset_m");
    snprintf(y, sizeof y, "%scorridor: {inflow: {flow_vph: 1000}, edie: {dt_s: 0.25}}\n", head);
    expect_error("e4.yaml", y, "whole multiple of time.dt_s");
    expect_error("e5.yaml",
                 "road: {type: corridor, length_m: 1000}\ntime: {duration_s: 100}\n"
                 "fleet: {vehicles: 10, classes: [{class: midsize_sedan, fraction: 1}], drivers: [{model: idm, fraction: 1}]}\n"
                 "corridor: {inflow: {flow_vph: 1000}}\n",
                 "no fixed fleet size");
    expect_error("e6.yaml",
                 "road: {type: corridor, length_m: 1000, zones: [{type: headway, from_m: 0, to_m: 100, factor: 2}]}\n"
                 "time: {duration_s: 100}\n"
                 "fleet: {classes: [{class: midsize_sedan, fraction: 1}], drivers: [{model: ovm, fraction: 1}]}\n"
                 "corridor: {inflow: {flow_vph: 1000}}\n",
                 "no driver group's model has a parameter 'T_s'");
    expect_error("e7.yaml",
                 "road: {type: corridor, length_m: 1000, grade: {points: [[0, 0], [500, 0.3]]}}\n"
                 "time: {duration_s: 100}\n"
                 "fleet: {classes: [{class: midsize_sedan, fraction: 1}], drivers: [{model: idm, fraction: 1}]}\n"
                 "corridor: {inflow: {flow_vph: 1000}}\n",
                 "[-0.2, 0.2]");
    snprintf(y, sizeof y, "%sinitial: {state: rest}\ncorridor: {inflow: {flow_vph: 1000}}\n", head);
    expect_error("e8.yaml", y, "starts empty");
}

/* A state block of the snapshot by name (NULL: none), and its bytes into *size when size is not NULL. */
static const void *snap_block(const Snap *sn, const char *name, size_t *size)
{
    for (size_t i = 0; i < sn->n_vars; i++)
        if (!strcmp(sn->vars[i].name, name)) {
            if (size) *size = sn->vars[i].size;
            return sn->bytes[i];
        }
    return NULL;
}

/* The window totals a state lists (what a checkpoint saves), vehicle by vehicle, against the trip totals: with the
 * statistics window open from the first step they are equal; with a warm-up, a vehicle that entered before its end
 * has burned less fuel in the window than on its trip, and one that entered after has the same totals. (Once every
 * vehicle on the road entered with the window open, the engine keeps the trip totals alone.) */
static void test_window_totals(void)
{
    static const char *const pairs[][2] = {{"trip_fuel", "w_fuel"},   {"trip_dist", "w_dist"},
                                           {"trip_stopped", "w_stopped"}};
    static const char *const counts[][2] = {{"trip_stops", "w_stops"}, {"trip_hard", "w_hard"},
                                            {"trip_infeasible", "w_infeasible"}};
    for (int warm = 0; warm < 2; warm++) {
        char y[1024];
        snprintf(y, sizeof y,
                 "seed: 9\n"
                 "road: {type: corridor, length_m: 3000}\n"
                 "time: {duration_s: 300, dt_s: 0.1, output_interval_s: 1, warmup_s: %d}\n"
                 "fleet:\n"
                 "  classes: [{class: midsize_sedan, fraction: 0.7}, {class: class8_tractor, fraction: 0.3}]\n"
                 "  drivers: [{model: idm, fraction: 1.0, noise_mps2: 0.3,\n"
                 "             params: {v0_mps: 28, T_s: 1.2, s0_m: 2, a_mps2: 1.0, b_mps2: 1.5}}]\n"
                 "corridor: {inflow: {flow_vph: 1500}}\n",
                 warm ? 100 : 0);
        WfScenario *sc = load_text(warm ? "wt_warm.yaml" : "wt_open.yaml", y);
        if (!sc) return;
        WfSim *c = NULL;
        WfError err = {0};
        Snap sn = {.stop_at_s = 150.0};
        int rc = wf_sim_create(sc, &c, &err);
        CHECK(rc == 0, "create: %s", err.msg);
        if (!rc) {
            WfOutput out = {.record = snap_row, .trips = snap_trips, .checkpoint = snap_checkpoint, .ctx = &sn};
            wf_sim_set_checkpoint_interval(c, 1e-9); /* every step: the last one is the interruption's */
            rc = wf_sim_run(c, &out, NULL, NULL, &sn.stop, &err);
            CHECK(rc == WF_EINTR && sn.taken > 0, "the stopped run: rc %d (%s), %d checkpoints", rc, err.msg,
                  sn.taken);
        }
        size_t cap = 0;
        const size_t *n = snap_block(&sn, "n", NULL), *first = snap_block(&sn, "first", NULL);
        const double *t_ent = snap_block(&sn, "t_entry", &cap);
        cap /= sizeof(double);
        CHECK(rc == WF_EINTR && n && first && t_ent && cap, "state blocks n, first and t_entry");
        size_t same = 0, before = 0, less = 0, n_veh = rc == WF_EINTR && n && first && t_ent && cap ? *n : 0;
        for (size_t k = 0; k < n_veh; k++) {
            size_t slot = (*first + *n - 1 - k) % cap;
            int all_same = 1;
            for (size_t q = 0; q < 3; q++) {
                const double *a = snap_block(&sn, pairs[q][0], NULL), *b = snap_block(&sn, pairs[q][1], NULL);
                all_same &= a && b && a[slot] == b[slot];
            }
            for (size_t q = 0; q < 3; q++) {
                const uint32_t *a = snap_block(&sn, counts[q][0], NULL), *b = snap_block(&sn, counts[q][1], NULL);
                all_same &= a && b && a[slot] == b[slot];
            }
            const double *tf = snap_block(&sn, "trip_fuel", NULL), *wf = snap_block(&sn, "w_fuel", NULL);
            if (warm && t_ent[slot] < 100.0) before++, less += tf && wf && wf[slot] < tf[slot];
            else same += all_same;
        }
        CHECK(n_veh > 40 && same == n_veh - before, "%s: %zu of %zu vehicles with window totals equal to the trip's",
              warm ? "warm-up 100 s" : "no warm-up", same, n_veh - before);
        CHECK(!warm || (before > 10 && less == before),
              "warm-up 100 s: %zu of %zu vehicles that entered before it with less window fuel than trip fuel", less,
              before);
        for (size_t i = 0; i < WF_MAX_STATE_VARS; i++) free(sn.bytes[i]);
        rec_free(&sn.rec);
        wf_sim_destroy(&c);
        wf_scenario_destroy(&sc);
    }
}

/* ---------------------------------------------------------------------------------------------- main */

static void remove_tmp_dir(void)
{
    static const char *const names[] = {"inflow_a.csv", "inflow_b.csv", "cons_a.yaml", "cons_b.yaml", "free.yaml", "free_out.yaml",
                                        "fd_free.yaml", "fd_cong.yaml", "hill.yaml", "hill_z.yaml", "hill_z.csv",
                                        "e1.yaml", "e2.yaml", "e3.yaml", "e4.yaml", "e5.yaml", "e6.yaml", "e7.yaml",
                                        "e8.yaml", "restore.yaml", "wt_open.yaml", "wt_warm.yaml"};
    char path[256];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", tmp_dir, names[i]);
        unlink(path);
    }
    rmdir(tmp_dir);
}

int main(void)
{
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/wf_corridor_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
        printf("FAIL setup: mkdtemp: cannot create a temporary directory\n");
        return 1;
    }
    RUN(test_conservation);
    RUN(test_free_flow);
    RUN(test_fundamental_diagram_free);
    RUN(test_fundamental_diagram_congested);
    RUN(test_grade);
    RUN(test_state_restore);
    RUN(test_window_totals);
    RUN(test_scenario_errors);
    remove_tmp_dir();
    TEST_EXIT();
}
