/* Equilibria for initial conditions: Illinois regula falsi on brackets of monotone functions. */
#include "wavefuel/equilibrium.h"
#include "core/par.h"

#include <math.h>
#include <stdlib.h>

/* Root of g on [lo, hi] with g(lo) < 0 < g(hi) (g increasing). Illinois: halve the weight of the endpoint
 * that stays, so the bracket shrinks from both sides. Stops when the bracket is narrower than abs_tol, stops
 * shrinking in floating point, or after max_it evaluations. */
static double illinois(double (*g)(double, const void *), const void *ctx, double lo, double hi, double glo,
                       double ghi, double abs_tol, int max_it)
{
    int side = 0;
    for (int it = 0; it < max_it && hi - lo > abs_tol; it++) {
        double x = (lo * ghi - hi * glo) / (ghi - glo);
        if (!(x > lo && x < hi)) x = 0.5 * (lo + hi); /* degenerate weights: fall back to bisection */
        if (!(x > lo && x < hi)) break;               /* bracket is two adjacent doubles */
        double gx = g(x, ctx);
        if (gx == 0.0) return x;
        if (gx < 0.0) {
            lo = x, glo = gx;
            if (side == -1) ghi *= 0.5;
            side = -1;
        } else {
            hi = x, ghi = gx;
            if (side == 1) glo *= 0.5;
            side = 1;
        }
        if (hi - lo <= 4.0 * 2.220446049250313e-16 * fmax(fabs(lo), fabs(hi))) break;
    }
    /* The side with g < 0, not the midpoint: for a function that jumps at the root (FollowerStopper's equilibrium
     * gap jumps at v = U) the midpoint may lie on the far side of the jump. */
    return lo;
}

typedef struct GapCtx {
    const WfCfModel *m;
    const void      *params;
    double           v;
} GapCtx;

/* accel(s, v, v) increases with the gap s: negative below the equilibrium gap, positive above. */
static double gap_fn(double s, const void *vctx)
{
    const GapCtx *c = vctx;
    return c->m->accel(c->params, NULL, s, c->v, c->v);
}

double wf_equilibrium_gap(const WfCfModel *m, const void *params, double v, double s_max)
{
    GapCtx c = {m, params, v};
    double ghi = gap_fn(s_max, &c);
    if (ghi < 0.0) return s_max;
    double lo = 0.0, glo = gap_fn(0.0, &c), hi = s_max;
    if (glo >= 0.0) return 0.0;
    if (ghi == 0.0) return s_max;
    /* Brackets span many decades (1 mm to a 10^7 m ring) with accelerations from -10^6 to +1 m/s^2, where
     * regula falsi crawls: shrink geometrically to within a factor 4 first, then Illinois. */
    while (hi > 4.0 * fmax(lo, 1e-3)) {
        double mid = sqrt(fmax(lo, 1e-3) * hi), g = gap_fn(mid, &c);
        if (g == 0.0) return mid;
        if (g < 0.0) lo = mid, glo = g;
        else hi = mid, ghi = g;
    }
    return illinois(gap_fn, &c, lo, hi, glo, ghi, 0.0, 200);
}

typedef struct RingCtx {
    const WfScenario  *sc;
    const WfFleet     *f;
    double            *gap;
    double            *block_sum;
    /* a ring split across processes: this process sums the blocks that start among [lo, hi) */
    const WfPartition *part;
    size_t             lo, hi;
    WfError           *err;
    int                failed;
} RingCtx;

void wf_equilibrium_ring_gaps(const WfScenario *sc, const WfFleet *f, double v, size_t lo, size_t hi, double *gap)
{
    const void *prev = NULL;
    for (size_t i = lo; i < hi; i++) {
        /* Vehicles sharing a parameter block (a group without heterogeneity) share their gap: same inputs, same
         * root, so reusing it changes no bit and saves a root solve per vehicle. */
        const void *p = wf_fleet_params(f, sc, i);
        gap[i] = p == prev ? gap[i - 1] : wf_equilibrium_gap(sc->groups[f->group_id[i]].model, p, v, sc->road.length_m);
        prev = p;
    }
}

/* Fleet length at common speed v minus the ring length: increasing in v. Each vehicle's gap is capped at L
 * (no equilibrium within the ring at this speed counts as "too long"). */
static double ring_fn(double v, const void *vctx)
{
    RingCtx *c = (RingCtx *)vctx; /* the root finders pass it as const; a failed sum over the processes is noted */
    const WfFleet *f = c->f;
    const WfScenario *sc = c->sc;
    size_t n = f->n, nb = (n + WF_EQ_BLOCK - 1) / WF_EQ_BLOCK;
    size_t b_lo = c->part ? (c->lo + WF_EQ_BLOCK - 1) / WF_EQ_BLOCK : 0;
    size_t b_hi = c->part ? (c->hi + WF_EQ_BLOCK - 1) / WF_EQ_BLOCK : nb;
    double *gap = c->gap, *bs = c->block_sum;
    WF_PAR_FOR(n >= 2 * WF_EQ_BLOCK,
               "omp parallel for schedule(dynamic, 1) default(none) shared(n, nb, b_lo, b_hi, f, sc, v, gap, bs)",
    for (size_t b = 0; b < nb; b++) {
        bs[b] = 0.0; /* another process's block: +0 here, its sum there */
        if (b < b_lo || b >= b_hi) continue;
        size_t end = (b + 1) * WF_EQ_BLOCK < n ? (b + 1) * WF_EQ_BLOCK : n;
        wf_equilibrium_ring_gaps(sc, f, v, b * WF_EQ_BLOCK, end, gap);
        double s = 0.0;
        for (size_t i = b * WF_EQ_BLOCK; i < end; i++) s += gap[i] + wf_fleet_length(f, i);
        bs[b] = s;
    });
    if (c->part && !c->failed && c->part->sum_f64(c->part->ctx, bs, nb, c->err)) c->failed = 1;
    double total = 0.0;
    for (size_t b = 0; b < nb; b++) total += bs[b];
    return total - sc->road.length_m;
}

static double equilibrium_ring(RingCtx *c, double v_hi)
{
    size_t nb = (c->f->n + WF_EQ_BLOCK - 1) / WF_EQ_BLOCK;
    double *bs = malloc((nb + 1) * sizeof *bs);
    if (!bs) return NAN;
    c->block_sum = bs;
    double lo = 0.0, hi = v_hi, glo = ring_fn(lo, c), v;
    if (glo >= 0.0) {
        v = 0.0; /* jammed: the caller has checked that the standstill gaps fit */
    } else {
        double ghi = ring_fn(hi, c);
        if (ghi <= 0.0) {
            v = v_hi;
        } else {
            /* Gaps capped at L make the top of the bracket huge and flat: bisect to 1/4096 of it first. */
            for (int it = 0; it < 12; it++) {
                double mid = 0.5 * (lo + hi), g = ring_fn(mid, c);
                if (g < 0.0) lo = mid, glo = g;
                else hi = mid, ghi = g;
            }
            /* The fleet length is a sum of N roots, each exact to ~1 ulp: below 1e-12 m/s the bracket only chases
             * that rounding noise, so stop there (the spare length is shared out by the caller anyway). */
            v = ghi == 0.0 ? hi : illinois(ring_fn, c, lo, hi, glo, ghi, 1e-12, 100);
        }
    }
    if (!c->part) ring_fn(v, c); /* leave the gaps of the chosen speed in gap[] */
    free(bs);
    return c->failed ? NAN : v;
}

double wf_equilibrium_ring(const WfScenario *sc, const WfFleet *f, double v_hi, double *gap)
{
    RingCtx c = {.sc = sc, .f = f, .gap = gap};
    return equilibrium_ring(&c, v_hi);
}

double wf_equilibrium_ring_part(const WfScenario *sc, const WfFleet *f, double v_hi, const WfPartition *part,
                                size_t lo, size_t hi, double *gap, WfError *err)
{
    RingCtx c = {.sc = sc, .f = f, .gap = gap, .part = part, .lo = lo, .hi = hi, .err = err};
    double v = equilibrium_ring(&c, v_hi);
    if (isnan(v) && !c.failed) wf_err(err, WF_ESYS, "out of memory");
    return v;
}
