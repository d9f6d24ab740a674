/* The ballistic integrator's stop within a step (Treiber & Kanagaraj 2015, Transp. Res. C 50, 39): a vehicle whose
 * speed would turn negative during the step stops where v reaches 0, at x + v^2 / (2|a|), and stays at v = 0; any
 * other vehicle moves x + v dt + a dt^2 / 2, v + a dt. The expected values are the closed forms, computed here per
 * vehicle; the integrator runs on whole arrays (several SIMD lanes and a remainder). Then every integrator of the
 * registry (wf_integrators[], whatever it holds) with a step function must keep speeds >= 0 and positions non-decreasing. */
#include <math.h>
#include <stdlib.h>

#include "wavefuel/integrator.h"
#include "wf_test.h"

#define N 37

/* Speeds, accelerations and steps chosen so that some stop inside the step, some exactly at its end, some keep
 * running, some brake while at rest; dt in {0.1, 0.5, 1, 2.5}. */
static void fill(double *x, double *v, double *a, size_t n, double dt)
{
    for (size_t i = 0; i < n; i++) {
        x[i] = 100.0 * (double)i + 0.25;
        v[i] = (i % 5 == 4) ? 0.0 : 0.5 + 1.7 * (double)(i % 7);
        a[i] = (i % 3 == 0) ? 0.8 - 0.1 * (double)(i % 4) : -(0.3 + 0.9 * (double)(i % 6));
        if (i == 7) a[i] = -v[i] / dt; /* reaches v = 0 exactly at the step's end */
    }
}

static void test_ballistic_stop_position(void)
{
    const WfIntegrator *ig = NULL;
    CHECK(wf_integrator_find("ballistic", &ig, NULL) == 0 && ig, "no ballistic integrator");
    if (!ig) return;
    const double dts[] = {0.1, 0.5, 1.0, 2.5};
    int stopped = 0, running = 0;
    for (size_t d = 0; d < sizeof dts / sizeof dts[0]; d++) {
        double dt = dts[d], x[N], v[N], a[N], x0[N], v0[N];
        fill(x, v, a, N, dt);
        for (size_t i = 0; i < N; i++) x0[i] = x[i], v0[i] = v[i];
        ig->step(N, dt, x, v, a);
        for (size_t i = 0; i < N; i++) {
            if (v0[i] + a[i] * dt < 0.0) {
                stopped++;
                CHECK_REL(x[i], x0[i] + v0[i] * v0[i] / (2.0 * fabs(a[i])), 1e-15);
                CHECK(v[i] == 0.0, "vehicle %zu dt %g: v = %g after stopping", i, dt, v[i]);
            } else {
                running++;
                CHECK_REL(x[i], x0[i] + v0[i] * dt + 0.5 * a[i] * dt * dt, 1e-15);
                CHECK_REL(v[i], v0[i] + a[i] * dt, 1e-15);
            }
        }
    }
    CHECK(stopped > 20 && running > 20, "cases: %d stopping, %d running", stopped, running);
}

/* A hand-worked case: v = 3 m/s, a = -4 m/s^2, dt = 1 s stops after 0.75 s at 9/8 m (not 3 - 2 = 1 m). */
static void test_ballistic_stop_by_hand(void)
{
    const WfIntegrator *ig = NULL;
    if (wf_integrator_find("ballistic", &ig, NULL) != 0 || !ig) {
        CHECK(0, "no ballistic integrator");
        return;
    }
    double x = 10.0, v = 3.0, a = -4.0;
    ig->step(1, 1.0, &x, &v, &a);
    CHECK(x == 11.125 && v == 0.0, "x %.17g v %.17g, want 11.125 and 0", x, v);
}

static void test_every_integrator_keeps_v_nonnegative(void)
{
    size_t count = 0;
    for (size_t k = 0; wf_integrators[k]; k++) {
        const WfIntegrator *ig = wf_integrators[k];
        if (!ig->step) continue; /* an adaptive (SUNDIALS) kind, should the registry hold those too */
        count++;
        double x[N], v[N], a[N], x0[N];
        fill(x, v, a, N, 1.0);
        for (size_t i = 0; i < N; i++) x0[i] = x[i];
        ig->step(N, 1.0, x, v, a);
        for (size_t i = 0; i < N; i++) {
            CHECK(v[i] >= 0.0, "%s: vehicle %zu v = %g", ig->name, i, v[i]);
            CHECK(x[i] >= x0[i], "%s: vehicle %zu moved back %g", ig->name, i, x[i] - x0[i]);
        }
    }
    CHECK(count >= 2, "registry lists %zu fixed-step integrators", count);
}

int main(void)
{
    RUN(test_ballistic_stop_position);
    RUN(test_ballistic_stop_by_hand);
    RUN(test_every_integrator_keeps_v_nonnegative);
    TEST_EXIT();
}
