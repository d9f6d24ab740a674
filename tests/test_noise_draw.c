/* Which draw the acceleration noise uses (docs/scenarios.md, `noise_mps2`): at step k, vehicle i of a ring applies
 * model + sigma * z with z the (i mod 256)-th deviate of wf_rng_normal_block(seed, WF_RNG_NOISE_BLOCK, i / 256, k,
 * ...). The model here is examples/plugins/scripted_accel.c with no segments (it answers 0 during the run), so the
 * acceleration applied is exactly sigma * z (well inside the group's limits). `wavefuel run` on 300 vehicles (two
 * noise blocks, the second partial):
 *  - multi-pass step (a trajectory frame every step): /trajectories/a at frames 0 and 1 = sigma * z(step 0, 1);
 *  - fused step (no trajectories, one step): /vehicles/final_v = v0 + sigma * z(step 0) * dt (the ballistic
 *    update's own arithmetic), v0 = /meta/initial_speed (identical drivers on equal gaps all start at it). */
#include <hdf5.h>
#include <limits.h>
#include <stdlib.h>
#include <unistd.h>

#include "wavefuel/rng.h"
#include "wf_test.h"

#define NV    300
#define SEED  7
#define SIGMA 0.5
#define DT    0.1

static char tmp_dir[] = "/tmp/wf_noise_draw_XXXXXX";

/* Reads a whole float64 dataset into out (up to cap values); returns the count, or 0 on any failure. */
static size_t read_doubles(const char *file, const char *name, double *out, size_t cap)
{
    hid_t f = H5Fopen(file, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return 0;
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    size_t n = 0;
    if (d >= 0) {
        hid_t sp = H5Dget_space(d);
        hssize_t np = H5Sget_simple_extent_npoints(sp);
        if (np > 0 && (size_t)np <= cap && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out) >= 0)
            n = (size_t)np;
        H5Sclose(sp);
        H5Dclose(d);
    }
    H5Fclose(f);
    return n;
}

/* Writes the scenario and runs it; extra: --set assignments. Returns the result path or NULL. */
static const char *run(const char *tag, const char *extra)
{
    static char out[PATH_MAX + 64];
    char scen[PATH_MAX + 64], cwd[PATH_MAX], cmd[4 * PATH_MAX];
    const char *bin = getenv("WAVEFUEL_BIN"), *build = getenv("BUILD");
    if (!getcwd(cwd, sizeof cwd)) return NULL;
    snprintf(scen, sizeof scen, "%s/noise.yaml", tmp_dir);
    FILE *fp = fopen(scen, "w");
    if (!fp) return NULL;
    /* L = 300 * 17 m: the plugin's settled law gives an equilibrium near 10 m/s. */
    fprintf(fp, "name: noise_draw\nseed: %d\nroad: {length_m: 5100}\n"
                "time: {duration_s: 0.2, dt_s: %g, output_interval_s: 0.1}\n"
                "fleet:\n  vehicles: %d\n  classes: [{class: midsize_sedan, fraction: 1.0}]\n"
                "  drivers: [{model: plugin, path: %s/%s/plugins/scripted_accel.so, fraction: 1.0, noise_mps2: %g}]\n",
            SEED, DT, NV, cwd, build && *build ? build : "build", SIGMA);
    fclose(fp);
    snprintf(out, sizeof out, "%s/%s.h5", tmp_dir, tag);
    snprintf(cmd, sizeof cmd, "%s run %s -q -o %s %s", bin && *bin ? bin : "bin/wavefuel", scen, out, extra);
    return system(cmd) == 0 ? out : NULL;
}

/* sigma * z for every vehicle at one step, drawn block by block as docs/scenarios.md describes. */
static void expected_accel(uint64_t step, double *a)
{
    for (size_t lo = 0; lo < NV; lo += 256) {
        size_t m = NV - lo < 256 ? NV - lo : 256;
        wf_rng_normal_block(SEED, WF_RNG_NOISE_BLOCK, lo / 256, step, m, a + lo);
    }
    for (size_t i = 0; i < NV; i++) a[i] = SIGMA * a[i];
}

static void test_noise_multipass_steps_0_and_1(void)
{
    static double traj_a[3 * NV];
    const char *f = run("traj", "--set output.trajectories=true --set output.trajectory_interval_s=0.1");
    CHECK(f, "run failed");
    if (!f) return;
    size_t na = read_doubles(f, "/trajectories/a", traj_a, 3 * NV);
    CHECK(na == 3 * NV, "read %zu values", na);
    double want[NV];
    for (uint64_t step = 0; step < 2; step++) {
        expected_accel(step, want);
        size_t bad = 0;
        for (size_t i = 0; i < NV; i++) bad += traj_a[step * NV + i] != want[i];
        CHECK(bad == 0, "step %lu: %zu of %d accelerations differ from sigma z (vehicle 0: %.17g, want %.17g)",
              (unsigned long)step, bad, NV, traj_a[step * NV], want[0]);
    }
}

static void test_noise_fused_step_0(void)
{
    const char *f = run("fused", "--set time.duration_s=0.1");
    CHECK(f, "run failed");
    if (!f) return;
    double fv[NV], want[NV], v0 = 0.0;
    CHECK(read_doubles(f, "/vehicles/final_v", fv, NV) == NV, "cannot read /vehicles/final_v");
    CHECK(read_doubles(f, "/meta/initial_speed", &v0, 1) == 1 && v0 > 5.0, "initial speed %g", v0);
    expected_accel(0, want);
    size_t bad = 0;
    for (size_t i = 0; i < NV; i++) bad += fv[i] != v0 + want[i] * DT;
    CHECK(bad == 0, "%zu of %d final speeds differ from v0 + sigma z dt (vehicle 0: %.17g, want %.17g)", bad, NV,
          fv[0], v0 + want[0] * DT);
}

int main(void)
{
    if (!mkdtemp(tmp_dir)) {
        printf("FAIL noise_draw_tmpdir\n");
        return 1;
    }
    RUN(test_noise_multipass_steps_0_and_1);
    RUN(test_noise_fused_step_0);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmp_dir);
    if (system(cmd) != 0) printf("  could not remove %s\n", tmp_dir);
    TEST_EXIT();
}
