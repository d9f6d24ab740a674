/* Sweeps (src/sweep/sweep.c, src/io/h5sweep.c): the expansion of a sweep file into runs against the product written out by
 * hand in the test, range values, `with` and `points`, explicit runs, error messages, shell quoting of the printed
 * command; each run's summary against the same scenario loaded and simulated directly (bitwise); a failed run
 * recorded while the others complete; the table written and read back bit for bit; resume matching. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "wavefuel/engine.h"
#include "wavefuel/scenario.h"
#include "wavefuel/sweep.h"
#include "wf_test.h"

#define TINY WF_REPO_DIR "/tests/data/tiny_ring.yaml"

static WfSweep *load(const char *text, WfError *err)
{
    WfSweep *sw = NULL;
    memset(err, 0, sizeof *err);
    if (wf_sweep_load_text("t/sweep.yaml", text, "name: x\n", &sw, err)) return NULL;
    return sw;
}

/* The runs of two axes and two seeds, in the documented order (first axis outermost, seeds innermost), built here
 * by nested loops and compared with the expansion. */
static void test_product_order(void)
{
    WfError err;
    WfSweep *sw = load("scenario: base.yaml\n"
                       "set: {time: {duration_s: 30}, output.trajectories: false}\n"
                       "axes:\n"
                       "  - {key: fleet.vehicles, values: [18, 22]}\n"
                       "  - key: fleet.drivers[0].noise_mps2\n"
                       "    range: {start: 0.1, stop: 0.3, step: 0.1}\n"
                       "seeds: [7, 9]\n",
                       &err);
    CHECK(sw != NULL, "%s", err.msg);
    if (!sw) return;
    CHECK(!strcmp(sw->scenario_path, "t/base.yaml"), "scenario resolved against the sweep's directory: %s",
          sw->scenario_path);
    CHECK(!strcmp(sw->output, "output/sweep.h5") && !strcmp(sw->name, "sweep"), "%s %s", sw->name, sw->output);
    CHECK(sw->n_runs == 12 && sw->n_axes == 2, "%zu runs, %zu axes", sw->n_runs, sw->n_axes);
    const char *veh[] = {"18", "22"}, *noise[] = {"0.1", "0.2", "0.3"};
    int seeds[] = {7, 9};
    size_t r = 0;
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 3; b++)
            for (int s = 0; s < 2 && r < sw->n_runs; s++, r++) {
                char want[5][64];
                snprintf(want[0], 64, "time.duration_s=30");
                snprintf(want[1], 64, "output.trajectories=false");
                snprintf(want[2], 64, "fleet.vehicles=%s", veh[a]);
                snprintf(want[3], 64, "fleet.drivers[0].noise_mps2=%s", noise[b]);
                snprintf(want[4], 64, "seed=%d", seeds[s]);
                const WfSweepRun *run = &sw->runs[r];
                CHECK(run->n_set == 5, "run %zu: %zu assignments", r, run->n_set);
                for (size_t k = 0; k < 5 && k < run->n_set; k++)
                    CHECK(!strcmp(run->set[k], want[k]), "run %zu: '%s', want '%s'", r, run->set[k], want[k]);
                CHECK(run->seed == seeds[s], "run %zu: seed %lld", r, (long long)run->seed);
                CHECK(!strcmp(run->value[0], veh[a]) && !strcmp(run->value[1], noise[b]), "run %zu: values %s %s", r,
                      run->value[0], run->value[1]);
            }
    CHECK(!strcmp(sw->axes[0].name, "vehicles") && !strcmp(sw->axes[1].name, "noise_mps2"), "names %s %s",
          sw->axes[0].name, sw->axes[1].name);
    CHECK(!strcmp(sw->axes[0].units, "1") && !strcmp(sw->axes[1].units, "m/s^2"), "units %s %s", sw->axes[0].units,
          sw->axes[1].units);
    CHECK(sw->axes[0].numeric && sw->axes[1].numeric, "numeric axes");
    char *ov = NULL;
    CHECK(wf_sweep_overrides(sw, 11, &ov, &err) == 0, "%s", err.msg);
    CHECK(ov && !strcmp(ov, "time.duration_s=30\noutput.trajectories=false\nfleet.vehicles=22\n"
                            "fleet.drivers[0].noise_mps2=0.3\nseed=9\n"),
          "overrides: %s", ov);
    free(ov);
    wf_sweep_destroy(&sw);
    CHECK(sw == NULL, "destroy clears the pointer");

    /* A range whose stop is reached up to rounding ((1 - 0) / 0.1 = 9.99...), and a descending one. */
    sw = load("scenario: b.yaml\naxes:\n  - {key: a_mps2, range: {start: 0, stop: 1, step: 0.1}}\n"
              "  - {key: road.length_m, range: {start: 300, stop: 200, step: -50}}\n",
              &err);
    CHECK(sw && sw->n_runs == 33, "%s", sw ? "" : err.msg);
    if (sw) {
        CHECK(!strcmp(sw->runs[3 * 3].value[0], "0.3"), "0.1 steps print as 0.3, got %s", sw->runs[9].value[0]);
        CHECK(!strcmp(sw->runs[32].value[0], "1") && !strcmp(sw->runs[32].value[1], "200"), "%s %s",
              sw->runs[32].value[0], sw->runs[32].value[1]);
        CHECK(sw->runs[0].seed == -1 && sw->runs[0].n_set == 2, "no seeds: no seed override");
        CHECK(!strcmp(sw->axes[1].units, "m"), "units %s", sw->axes[1].units);
    }
    wf_sweep_destroy(&sw);
}

static void test_with_points_and_runs(void)
{
    WfError err;
    WfSweep *sw = load("scenario: b.yaml\nname: pen\noutput: o.h5\n"
                       "axes:\n"
                       "  - name: ctl\n"
                       "    points:\n"
                       "      - {value: fs, set: {\"fleet.drivers[1].model\": follower_stopper, "
                       "\"fleet.drivers[1].params.U_mps\": 2.9}}\n"
                       "      - {value: acc, set: {\"fleet.drivers[1].model\": acc}}\n"
                       "  - key: fleet.drivers[1].count\n"
                       "    name: avs\n"
                       "    values: [0, 2]\n"
                       "    with: {\"fleet.drivers[0].count\": [22, 20]}\n"
                       "seeds: 2\n",
                       &err);
    CHECK(sw != NULL, "%s", err.msg);
    if (!sw) return;
    CHECK(sw->n_runs == 8 && !strcmp(sw->output, "o.h5") && !strcmp(sw->name, "pen"), "%zu %s", sw->n_runs,
          sw->output);
    const WfSweepRun *r = &sw->runs[3]; /* fs, avs = 2, seed 2 */
    const char *want[] = {"fleet.drivers[1].model=follower_stopper", "fleet.drivers[1].params.U_mps=2.9",
                          "fleet.drivers[1].count=2", "fleet.drivers[0].count=20", "seed=2"};
    CHECK(r->n_set == 5, "%zu", r->n_set);
    for (size_t k = 0; k < 5 && k < r->n_set; k++) CHECK(!strcmp(r->set[k], want[k]), "%s", r->set[k]);
    CHECK(sw->runs[7].n_set == 4 && !strcmp(sw->runs[7].value[0], "acc"), "acc point has one assignment");
    CHECK(!sw->axes[0].numeric && sw->axes[0].units[0] == '\0', "text axis");
    CHECK(!strcmp(sw->axes[0].keys, "fleet.drivers[1].model,fleet.drivers[1].params.U_mps"), "%s", sw->axes[0].keys);
    CHECK(!strcmp(sw->axes[1].keys, "fleet.drivers[1].count,fleet.drivers[0].count"), "%s", sw->axes[1].keys);
    wf_sweep_destroy(&sw);

    /* Explicit runs: one column per distinct key, unset where a run does not give it; seeds multiply them. */
    sw = load("scenario: b.yaml\nruns:\n  - {fleet.vehicles: 20}\n  - {fleet.vehicles: 24, road.length_m: 300}\n"
              "  - {time: {dt_s: 0.05}}\nseeds: [3]\n",
              &err);
    CHECK(sw && sw->n_runs == 3 && sw->n_axes == 3, "%s", sw ? "" : err.msg);
    if (sw) {
        CHECK(!strcmp(sw->axes[0].name, "fleet.vehicles") && !strcmp(sw->axes[2].name, "time.dt_s"), "%s %s",
              sw->axes[0].name, sw->axes[2].name);
        CHECK(sw->runs[0].value[1] == NULL && !strcmp(sw->runs[1].value[1], "300"), "unset value is NULL");
        CHECK(sw->runs[2].n_set == 2 && !strcmp(sw->runs[2].set[1], "seed=3"), "%s", sw->runs[2].set[0]);
        CHECK(!strcmp(sw->axes[2].units, "s"), "%s", sw->axes[2].units);
    }
    wf_sweep_destroy(&sw);
}

static void test_parse_errors(void)
{
    static const struct { const char *text, *want; } cases[] = {
        {"axes: []\n", "missing key 'scenario'"},
        {"scenario: b.yaml\nseed: 3\n", "unknown key 'seed' (did you mean 'seeds'?)"},
        {"scenario: b.yaml\naxes:\n  - {key: a, values: [1]}\nruns:\n  - {a: 1}\n", "not both"},
        {"scenario: b.yaml\naxes:\n  - {key: a, values: []}\n", "no values"},
        {"scenario: b.yaml\naxes:\n  - {key: a, values: [1], range: {start: 0, stop: 1, step: 1}}\n", "not both"},
        {"scenario: b.yaml\naxes:\n  - {key: a, valeus: [1]}\n", "unknown key 'axes[0].valeus' (did you mean 'values'?)"},
        {"scenario: b.yaml\naxes:\n  - {values: [1]}\n", "missing key 'key'"},
        {"scenario: b.yaml\naxes:\n  - {name: p, key: a, points: [{value: x, set: {a: 1}}]}\n", "has no `key`"},
        {"scenario: b.yaml\naxes:\n  - {key: a, range: {start: 0, stop: 1, step: -1}}\n", "cannot go from"},
        {"scenario: b.yaml\naxes:\n  - {key: a, range: {start: 0, stop: 1, step: 0}}\n", "cannot go from"},
        {"scenario: b.yaml\naxes:\n  - {key: a, range: {start: 0, stop: 1e9, step: 1}}\n", "more than 100000"},
        {"scenario: b.yaml\naxes:\n  - {key: a, values: [1, 2], with: {b: [1]}}\n", "list of 2 values"},
        {"scenario: b.yaml\naxes:\n  - {key: x.a, values: [1]}\n  - {key: y.a, values: [2]}\n",
         "two axes are named 'a'"},
        {"scenario: b.yaml\naxes:\n  - {key: a, values: [[1, 2]]}\n", "sweep.yaml:3: axes[0].values[0]"},
        {"scenario: b.yaml\naxes:\n  - {points: [{value: x, set: {a: 1}}]}\n", "missing key 'name'"},
        {"scenario: b.yaml\naxes:\n  - {name: p, points: [{value: x}]}\n", "missing key 'set'"},
        {"scenario: b.yaml\nset: {\"a=b\": 1}\n", "may not contain '='"},
        {"scenario: b.yaml\nseeds: 0\n", "seeds"},
        {"scenario: b.yaml\nseeds: [1, -2]\n", "seeds[1]"},
        {"scenario: b.yaml\nruns: []\n", "`runs` is empty"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        WfError err;
        WfSweep *sw = load(cases[i].text, &err);
        CHECK(sw == NULL && err.code == WF_EINPUT, "case %zu accepted", i);
        CHECK(strstr(err.msg, cases[i].want) != NULL, "case %zu: '%s' lacks '%s'", i, err.msg, cases[i].want);
        CHECK(strncmp(err.msg, "t/sweep.yaml", 12) == 0, "case %zu: no file name: %s", i, err.msg);
        wf_sweep_destroy(&sw);
    }
    /* A missing base scenario file is named. */
    WfSweep *sw = NULL;
    WfError err = {0};
    CHECK(wf_sweep_load_text("t/s.yaml", "scenario: nowhere.yaml\n", NULL, &sw, &err) == WF_EINPUT &&
              strstr(err.msg, "t/nowhere.yaml") != NULL,
          "%s", err.msg);
}

/* The command is parsed back the way a POSIX shell would: words split at spaces, '...' literal, '\'' a quote. */
static void test_command_quoting(void)
{
    WfError err;
    WfSweep *sw = load("scenario: my base.yaml\nruns:\n  - {\"fleet.drivers[0].name\": \"it's\"}\n", &err);
    CHECK(sw != NULL, "%s", err.msg);
    if (!sw) return;
    char cmd[512];
    CHECK(wf_sweep_command(sw, 0, NULL, cmd, sizeof cmd) == 0, "fits");
    CHECK(!strcmp(cmd, "wavefuel run 't/my base.yaml' --set 'fleet.drivers[0].name=it'\\''s'"), "got: %s", cmd);
    /* Unquote it independently and compare the words. */
    const char *want[] = {"wavefuel", "run", "t/my base.yaml", "--set", "fleet.drivers[0].name=it's"};
    size_t nw = 0;
    char word[256];
    size_t wl = 0;
    int inq = 0, any = 0;
    for (const char *c = cmd;; c++) {
        if (!*c || (*c == ' ' && !inq)) {
            if (any) {
                word[wl] = '\0';
                CHECK(nw < 5 && !strcmp(word, want[nw]), "word %zu: %s", nw, word);
                nw++;
            }
            wl = 0, any = 0;
            if (!*c) break;
        } else if (*c == '\'') {
            inq = !inq, any = 1;
        } else if (*c == '\\' && !inq && c[1]) {
            word[wl++] = *++c, any = 1;
        } else {
            word[wl++] = *c, any = 1;
        }
    }
    CHECK(nw == 5, "%zu words", nw);
    CHECK(wf_sweep_command(sw, 0, NULL, cmd, 20) == WF_EINPUT, "too small a buffer is reported");
    wf_sweep_destroy(&sw);
}

/* The tiny ring sweep used by the run tests: 2 x 2 x 2 runs, the last axis value 0 vehicles (out of range: fails). */
static const char *run_sweep = "scenario: " TINY "\n"
                               "set: {time.duration_s: 20, output.trajectories: false}\n"
                               "axes:\n"
                               "  - {key: \"fleet.drivers[0].noise_mps2\", values: [0.1, 0.4]}\n"
                               "  - {key: fleet.vehicles, values: [20, 0]}\n"
                               "seeds: 2\n";

/* Each row against the same scenario loaded from the file with the same overrides and simulated on its own. */
static void test_runs_equal_single_runs(void)
{
    WfError err;
    WfSweep *sw = NULL;
    CHECK(wf_sweep_load_text("t/run_sweep.yaml", run_sweep, NULL, &sw, &err) == 0, "%s", err.msg);
    if (!sw) return;
    WfSweepRunOpts o = {.threads = 1};
    for (size_t i = 0; i < sw->n_runs; i++) {
        WfSweepResult r;
        wf_sweep_run(sw, i, &o, NULL, &r);
        int bad = !strcmp(sw->runs[i].value[1], "0");
        if (bad) {
            CHECK(r.status == WF_RUN_FAILED && strstr(r.error, "fleet.vehicles") != NULL, "run %zu: %d %s", i,
                  r.status, r.error);
            continue;
        }
        CHECK(r.status == WF_RUN_OK, "run %zu: %s", i, r.error);
        CHECK(r.seed == sw->runs[i].seed && r.n_classes == 2 && !strcmp(r.classes, "midsize_sedan,class8_tractor"),
              "run %zu: seed %lld classes %s", i, (long long)r.seed, r.classes);
        WfScenario *sc = NULL;
        WfSim *sim = NULL;
        int rc = wf_scenario_load(TINY, sw->runs[i].set, sw->runs[i].n_set, &sc, &err);
        if (!rc) rc = wf_sim_create(sc, &sim, &err);
        if (!rc) rc = wf_sim_run(sim, NULL, NULL, NULL, NULL, &err);
        CHECK(rc == 0, "%s", err.msg);
        if (!rc) {
            const WfSummary *s = wf_sim_summary(sim);
            CHECK(memcmp(s, &r.summary, sizeof *s) == 0, "run %zu: summary differs (fuel %.17g vs %.17g)", i,
                  s->fuel_g, r.summary.fuel_g);
            CHECK(s->fuel_g > 0 && s->vkt_km > 0, "run %zu: nothing simulated", i);
        }
        wf_sim_destroy(&sim);
        wf_scenario_destroy(&sc);
    }
    /* The noise axis changes the result, the seeds too: the comparison above could fail. */
    WfSweepResult a, b, c;
    wf_sweep_run(sw, 0, &o, NULL, &a);
    wf_sweep_run(sw, 1, &o, NULL, &b);
    wf_sweep_run(sw, 4, &o, NULL, &c);
    CHECK(a.summary.fuel_g != b.summary.fuel_g && a.summary.fuel_g != c.summary.fuel_g, "%.17g %.17g %.17g",
          a.summary.fuel_g, b.summary.fuel_g, c.summary.fuel_g);
    /* A stop flag already raised leaves the run pending. */
    volatile sig_atomic_t stop = SIGINT;
    wf_sweep_run(sw, 0, &o, &stop, &a);
    CHECK(a.status == WF_RUN_PENDING, "status %d", a.status);
    wf_sweep_destroy(&sw);
}

static int same_result(const WfSweepResult *a, const WfSweepResult *b)
{
    if (a->status != b->status || a->seed != b->seed || strcmp(a->error, b->error) || strcmp(a->classes, b->classes) ||
        a->n_classes != b->n_classes || strcmp(a->file, b->file))
        return 0;
    if (a->status != WF_RUN_OK) return 1;
    /* Every value of the sweep table (the ring's summary fields), bit for bit. */
    for (size_t m = 0; m < wf_summary_n_fields; m++) {
        const WfSummaryField *f = &wf_summary_fields[m];
        if (f->desc[WF_SUMMARY_RING] && memcmp((const char *)&a->summary + f->offset,
                                               (const char *)&b->summary + f->offset, sizeof(double)))
            return 0;
    }
    for (size_t c = 0; c < a->n_classes; c++)
        for (size_t m = 0; m < wf_summary_n_class_fields; m++) {
            const WfSummaryField *f = &wf_summary_class_fields[m];
            if (f->desc[WF_SUMMARY_RING] && memcmp((const char *)&a->summary.cls[c] + f->offset,
                                                   (const char *)&b->summary.cls[c] + f->offset, sizeof(double)))
                return 0;
        }
    return 1;
}

static void test_table_roundtrip_and_resume(void)
{
    char dir[] = "/tmp/wf_test_sweep.XXXXXX", path[128];
    if (!mkdtemp(dir)) return;
    snprintf(path, sizeof path, "%s/t.h5", dir);
    WfError err;
    WfSweep *sw = NULL;
    CHECK(wf_sweep_load_text("t/run_sweep.yaml", run_sweep, NULL, &sw, &err) == 0, "%s", err.msg);
    if (!sw) return;
    WfSweepResult *res = calloc(sw->n_runs, sizeof *res);
    WfSweepRunOpts o = {.threads = 1};
    /* Runs 0..5 done (2 and 3 fail: 0 vehicles), 6 and 7 pending. */
    for (size_t i = 0; i < 6; i++) wf_sweep_run(sw, i, &o, NULL, &res[i]);
    for (size_t i = 6; i < sw->n_runs; i++) res[i].seed = sw->runs[i].seed;
    snprintf(res[1].file, sizeof res[1].file, "runs/x.h5");
    WfSweepTiming t = {"threads", 2, 1, 1.5};
    CHECK(wf_sweep_table_write(path, sw, res, &t, &err) == 0, "%s", err.msg);
    CHECK(access(path, F_OK) == 0, "table written");
    char partial[160];
    snprintf(partial, sizeof partial, "%s.partial", path);
    CHECK(access(partial, F_OK) != 0, "no partial left");
    WfSweepSaved sv;
    CHECK(wf_sweep_table_read(path, &sv, &err) == 0, "%s", err.msg);
    CHECK(sv.n == sw->n_runs, "%zu rows", sv.n);
    for (size_t i = 0; i < sv.n && i < sw->n_runs; i++) {
        char *ov = NULL;
        wf_sweep_overrides(sw, i, &ov, &err);
        CHECK(ov && !strcmp(ov, sv.overrides[i]), "row %zu overrides", i);
        free(ov);
        CHECK(same_result(&res[i], &sv.res[i]), "row %zu differs after the round trip (status %d/%d)", i,
              res[i].status, sv.res[i].status);
    }
    CHECK(res[2].status == WF_RUN_FAILED && sv.res[2].status == WF_RUN_FAILED && sv.res[2].error[0], "failed row kept");
    CHECK(!strcmp(sv.scenario_text, sw->scenario_text), "scenario text kept");

    /* Resume: the finished rows come back, matched by overrides even in another order of the runs. */
    WfSweep *sw2 = NULL;
    const char *reordered = "scenario: " TINY "\n"
                            "set: {time.duration_s: 20, output.trajectories: false}\n"
                            "axes:\n"
                            "  - {key: \"fleet.drivers[0].noise_mps2\", values: [0.4, 0.1, 0.7]}\n"
                            "  - {key: fleet.vehicles, values: [20, 0]}\n"
                            "seeds: 2\n";
    CHECK(wf_sweep_load_text("t/run_sweep.yaml", reordered, NULL, &sw2, &err) == 0, "%s", err.msg);
    if (sw2) {
        WfSweepResult *r2 = calloc(sw2->n_runs, sizeof *r2);
        size_t reused = 0;
        CHECK(wf_sweep_resume(sw2, &sv, 0, r2, &reused, &err) == 0, "%s", err.msg);
        CHECK(reused == 6, "%zu reused", reused);
        /* noise 0.1 is now the second value: old run i (noise 0.1) is new run 4 + i; noise 0.4 is first. */
        for (size_t i = 0; i < 4; i++) CHECK(same_result(&r2[4 + i], &res[i]), "row %zu not carried over", i);
        CHECK(same_result(&r2[0], &res[4]) && same_result(&r2[1], &res[5]), "rows 4, 5 not carried over");
        CHECK(r2[2].status == WF_RUN_PENDING && r2[3].status == WF_RUN_PENDING && r2[8].status == WF_RUN_PENDING,
              "rows not done are pending");
        CHECK(wf_sweep_resume(sw2, &sv, 1, r2, &reused, &err) == 0 && reused == 4, "retry failed: %zu", reused);
        free(r2);
    }
    wf_sweep_destroy(&sw2);
    /* A sweep that dropped a finished run, or changed the base scenario, is refused. */
    const char *shrunk = "scenario: " TINY "\n"
                         "set: {time.duration_s: 20, output.trajectories: false}\n"
                         "axes:\n  - {key: \"fleet.drivers[0].noise_mps2\", values: [0.4]}\n"
                         "  - {key: fleet.vehicles, values: [20, 0]}\nseeds: 2\n";
    CHECK(wf_sweep_load_text("t/run_sweep.yaml", shrunk, NULL, &sw2, &err) == 0, "%s", err.msg);
    if (sw2) {
        WfSweepResult *r2 = calloc(sw2->n_runs, sizeof *r2);
        size_t reused = 0;
        CHECK(wf_sweep_resume(sw2, &sv, 0, r2, &reused, &err) == WF_EINPUT && strstr(err.msg, "no longer lists"),
              "%s", err.msg);
        free(r2);
    }
    wf_sweep_destroy(&sw2);
    CHECK(wf_sweep_load_text("t/run_sweep.yaml", run_sweep, "name: changed\n", &sw2, &err) == 0, "%s", err.msg);
    if (sw2) {
        WfSweepResult *r2 = calloc(sw2->n_runs, sizeof *r2);
        size_t reused = 0;
        CHECK(wf_sweep_resume(sw2, &sv, 0, r2, &reused, &err) == WF_EINPUT && strstr(err.msg, "base scenario"),
              "%s", err.msg);
        free(r2);
    }
    wf_sweep_destroy(&sw2);
    wf_sweep_saved_free(&sv);
    /* Not a sweep table. */
    WfSweepSaved none;
    CHECK(wf_sweep_table_read(TINY, &none, &err) == WF_EINPUT, "a YAML file read as a table");
    free(res);
    wf_sweep_destroy(&sw);
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    RUN(test_product_order);
    RUN(test_with_points_and_runs);
    RUN(test_parse_errors);
    RUN(test_command_quoting);
    RUN(test_runs_equal_single_runs);
    RUN(test_table_roundtrip_and_resume);
    TEST_EXIT();
}
