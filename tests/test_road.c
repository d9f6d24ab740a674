/* Road grade: the periodic piecewise-linear profile against an independent interpolation, closure checks, and
 * the fuel of a vehicle cruising over a hilly ring against the CIRCLES formulas integrated in the test. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/engine.h"
#include "wavefuel/road.h"
#include "wavefuel/scenario.h"
#include "wf_test.h"

static const double L = 2000;

static void test_grade_interpolation(void)
{
    WfRoad r = {.length_m = L};
    WfError err = {0};
    /* Open profile: climbs 0.5*0.02*300 + 0.5*0.02*400 = 7 m and never comes down: rejected. */
    double pxo[] = {0, 300, 700}, pto[] = {0.0, 0.02, 0.0};
    CHECK(wf_road_set_grade(&r, 3, pxo, pto, "t", &err) == WF_EINPUT && strstr(err.msg, "does not close"), "%s",
          err.msg);
    double pxb[] = {0, 300, 200}, ptb[] = {0, 0, 0};
    CHECK(wf_road_set_grade(&r, 3, pxb, ptb, "t", &err) == WF_EINPUT && strstr(err.msg, "must increase"), "%s",
          err.msg);
    /* Closed: up 0 -> 0.02 -> 0 over [0, 700], flat, down over [1000, 1700], flat again to the wrap. */
    double px4[] = {0, 350, 700, 1000, 1350, 1700}, pt4[] = {0.0, 0.02, 0.0, 0.0, -0.02, 0.0};
    CHECK(wf_road_set_grade(&r, 6, px4, pt4, "t", &err) == 0, "%s", err.msg);
    double worst = 0;
    uint32_t seg = 0;
    /* Monotone positions over several laps with the cache carried along, then random positions (cache stale). */
    for (int k = 0; k < 20000; k++) {
        double x = 0.37 * k - 50.0; /* starts before 0 */
        double got = wf_road_grade(&r, x, &seg);
        double xm = fmod(x, L);
        if (xm < 0) xm += L;
        /* reference for the closed profile */
        double ref = 0;
        size_t n = 6;
        int found = 0;
        for (size_t i = 0; i < n && !found; i++) {
            double x0 = px4[i], x1 = i + 1 < n ? px4[i + 1] : px4[0] + L;
            if (xm >= x0 && xm < x1) ref = pt4[i] + (pt4[(i + 1) % n] - pt4[i]) * (xm - x0) / (x1 - x0), found = 1;
        }
        worst = fmax(worst, fabs(got - ref));
    }
    srand(7);
    for (int k = 0; k < 20000; k++) {
        double x = (double)rand() / RAND_MAX * 10 * L;
        double got = wf_road_grade(&r, x, &seg);
        double xm = fmod(x, L), ref = 0;
        for (size_t i = 0; i < 6; i++) {
            double x0 = px4[i], x1 = i + 1 < 6 ? px4[i + 1] : px4[0] + L;
            if (xm >= x0 && xm < x1) ref = pt4[i] + (pt4[(i + 1) % 6] - pt4[i]) * (xm - x0) / (x1 - x0);
        }
        worst = fmax(worst, fabs(got - ref));
    }
    CHECK(worst < 1e-15, "grade differs from the reference by %.3e rad", worst);
    wf_road_free(&r);
}

/* CIRCLES midsize sedan, typed from the release table (issue 3), a = 0 branch of the model. */
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

static void test_hill_fuel(void)
{
    /* One vehicle alone on the ring (its leader is itself, one lap ahead): at the IDM equilibrium speed for gap
     * L - length it cruises at constant speed whatever the grade (IDM ignores grade), so its fuel over the run is
     * sum_k f(v, 0, theta(x0 + v k dt)) dt, the left-point rule the engine documents, computed here. */
    char dir[] = "/tmp/wf_test_road.XXXXXX", path[128];
    if (!mkdtemp(dir)) return;
    snprintf(path, sizeof path, "%s/hill.yaml", dir);
    FILE *f = fopen(path, "w");
    fputs("road:\n  length_m: 2000\n  grade: {points: [[0, 0.0], [350, 0.02], [700, 0.0], [1000, 0.0], [1350, -0.02],"
          " [1700, 0.0]]}\n"
          "time: {duration_s: 200, dt_s: 0.1, output_interval_s: 1}\n"
          "fleet:\n  vehicles: 1\n  classes: [{class: midsize_sedan, count: 1, length_m: 5}]\n"
          "  drivers: [{model: idm, count: 1, params: {v0_mps: 20}}]\n",
          f);
    fclose(f);
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    int rc = wf_scenario_load(path, NULL, 0, &sc, &err);
    if (!rc) rc = wf_sim_create(sc, &sim, &err);
    double x0 = rc ? 0 : wf_sim_fleet(sim)->x_m[0], v = rc ? 0 : wf_sim_fleet(sim)->v_mps[0];
    if (!rc) rc = wf_sim_run(sim, NULL, NULL, NULL, NULL, &err);
    CHECK(rc == 0, "%s", err.msg);
    if (!rc) {
        double fuel = 0, dt = 0.1, climb_fuel = 0, descent_fuel = 0;
        for (int k = 0; k < 2000; k++) {
            double x = x0 + v * dt * k, xm = fmod(x, 2000.0), th = 0;
            const double gx[] = {0, 350, 700, 1000, 1350, 1700}, gt[] = {0, 0.02, 0, 0, -0.02, 0};
            for (int i = 0; i < 6; i++) {
                double a = gx[i], b = i < 5 ? gx[i + 1] : 2000.0;
                if (xm >= a && xm < b) th = gt[i] + (gt[(i + 1) % 6] - gt[i]) * (xm - a) / (b - a);
            }
            double fk = sedan_fuel_a0(v, th) * dt;
            fuel += fk;
            if (th > 0) climb_fuel += fk;
            if (th < 0) descent_fuel += fk;
        }
        const WfSummary *s = wf_sim_summary(sim);
        printf("  cruise %.6f m/s: fuel %.9f g (formula %.9f g); climb %.3f g vs descent %.3f g\n", v, s->fuel_g, fuel,
               climb_fuel, descent_fuel);
        CHECK_REL(s->fuel_g, fuel, 1e-9);
        CHECK(climb_fuel > 1.3 * descent_fuel, "climbing should cost more fuel than descending");
        CHECK(fabs(wf_sim_fleet(sim)->v_mps[0] - v) < 1e-9, "speed drifted");
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    RUN(test_grade_interpolation);
    RUN(test_hill_fuel);
    TEST_EXIT();
}
