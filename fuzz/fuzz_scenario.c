/* Fuzz target: the scenario loader (YAML -> WfScenario, rings and corridors) including --set overrides.
 * Input: the scenario's YAML text, optionally followed by a NUL byte and newline-separated --set assignments
 * ("fleet.vehicles=30\ntime.dt_s=0.2"). Every input must either load into a scenario that satisfies the
 * loader's documented guarantees (checked below) or fail with WF_EINPUT and a message. The repository's
 * scenarios/data/ is copied beside the input, so relative CSV paths of the seeds resolve. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_common.h"
#include "wavefuel/corridor.h"
#include "wavefuel/scenario.h"

enum { MAX_SETS = 16 };

/* Corridors (docs/corridors.md): profiles increasing in x or t, grades within +-0.2 rad, demand >= 0. */
static void check_corridor(const WfScenario *sc)
{
    const WfCorridorSpec *cs = sc->corridor;
    double L = sc->road.length_m;
    for (size_t i = 0; i < cs->n_grade; i++) {
        FUZZ_REQUIRE(cs->grade_x_m[i] >= 0 && cs->grade_x_m[i] <= L, "corridor grade x %g", cs->grade_x_m[i]);
        FUZZ_REQUIRE(i == 0 || cs->grade_x_m[i] > cs->grade_x_m[i - 1], "corridor grade x not increasing at %zu", i);
        FUZZ_REQUIRE(fabs(cs->grade_rad[i]) <= 0.2, "corridor grade %g", cs->grade_rad[i]);
    }
    const WfProfile *p = &cs->inflow_vph;
    for (size_t i = 0; i < p->n; i++) {
        FUZZ_REQUIRE(isfinite(p->t[i]) && (i == 0 || p->t[i] > p->t[i - 1]), "inflow t[%zu] = %g", i, p->t[i]);
        FUZZ_REQUIRE(isfinite(p->y[i]) && p->y[i] >= 0, "inflow[%zu] = %g veh/h", i, p->y[i]);
        FUZZ_REQUIRE(isfinite(p->cum[i]), "inflow integral[%zu] = %g", i, p->cum[i]);
    }
    for (size_t z = 0; z < cs->n_zones; z++)
        FUZZ_REQUIRE(isfinite(cs->zones[z].from_m) && cs->zones[z].from_m < cs->zones[z].to_m, "zone %zu [%g, %g)", z,
                     cs->zones[z].from_m, cs->zones[z].to_m);
    for (size_t d = 0; d < cs->n_det; d++)
        FUZZ_REQUIRE(cs->det_x_m[d] >= 0 && cs->det_x_m[d] <= L, "detector at %g m", cs->det_x_m[d]);
}

static void check_scenario(const WfScenario *sc)
{
    FUZZ_REQUIRE(isfinite(sc->road.length_m) && sc->road.length_m > 0, "road.length_m %g", sc->road.length_m);
    FUZZ_REQUIRE(isfinite(sc->duration_s) && sc->duration_s > 0, "duration %g", sc->duration_s);
    FUZZ_REQUIRE(isfinite(sc->dt_s) && sc->dt_s > 0, "dt %g", sc->dt_s);
    FUZZ_REQUIRE(sc->dt_s <= sc->output_interval_s, "dt %g > output interval %g", sc->dt_s, sc->output_interval_s);
    FUZZ_REQUIRE(sc->warmup_s >= 0 && sc->warmup_s < sc->duration_s, "warmup %g", sc->warmup_s);
    FUZZ_REQUIRE(wf_scenario_n_steps(sc) >= 1, "n_steps %ld", wf_scenario_n_steps(sc));
    FUZZ_REQUIRE(wf_scenario_output_every(sc) >= 1, "output_every %ld", wf_scenario_output_every(sc));
    FUZZ_REQUIRE(sc->n_vehicles >= 1, "n_vehicles %ld", sc->n_vehicles);
    FUZZ_REQUIRE(sc->n_classes >= 1 && sc->n_classes <= WF_MAX_CLASSES, "n_classes %zu", sc->n_classes);
    FUZZ_REQUIRE(sc->n_groups >= 1 && sc->n_groups <= WF_MAX_GROUPS, "n_groups %zu", sc->n_groups);
    long sum = 0;
    double total_len_m = 0.0;
    for (size_t c = 0; c < sc->n_classes; c++) {
        const WfClassShare *cs = &sc->classes[c];
        FUZZ_REQUIRE(cs->count >= 0 && cs->count <= sc->n_vehicles, "class %zu count %ld", c, cs->count);
        FUZZ_REQUIRE(cs->vc.model && (cs->vc.params || cs->vc.model->param_size == 0), "class %zu model", c);
        FUZZ_REQUIRE(isfinite(cs->length_m) && cs->length_m > 0, "class %zu length %g", c, cs->length_m);
        for (size_t k = 0; k < cs->n_indices; k++)
            FUZZ_REQUIRE(cs->indices[k] >= 0 && cs->indices[k] < sc->n_vehicles, "class index %ld", cs->indices[k]);
        sum += cs->count;
        total_len_m += (double)cs->count * cs->length_m;
    }
    FUZZ_REQUIRE(sum == sc->n_vehicles, "class counts sum to %ld, fleet %ld", sum, sc->n_vehicles);
    if (!sc->corridor) /* a corridor's counts only resolve its shares (WF_CORRIDOR_SHARE_BASE): nothing to fit */
        FUZZ_REQUIRE(total_len_m < sc->road.length_m, "vehicles %g m on a %g m ring", total_len_m, sc->road.length_m);
    sum = 0;
    for (size_t g = 0; g < sc->n_groups; g++) {
        const WfDriverGroup *gr = &sc->groups[g];
        FUZZ_REQUIRE(gr->count >= 0 && gr->count <= sc->n_vehicles, "group %zu count %ld", g, gr->count);
        FUZZ_REQUIRE(gr->model != NULL, "group %zu has no model", g);
        for (size_t k = 0; k < gr->model->n_spec; k++)
            FUZZ_REQUIRE(isfinite(gr->spread[k]) && gr->spread[k] >= 0, "group %zu spread %g", g, gr->spread[k]);
        FUZZ_REQUIRE(isfinite(gr->noise_mps2) && gr->noise_mps2 >= 0, "noise %g", gr->noise_mps2);
        for (size_t k = 0; k < gr->n_indices; k++)
            FUZZ_REQUIRE(gr->indices[k] >= 0 && gr->indices[k] < sc->n_vehicles, "group index %ld", gr->indices[k]);
        sum += gr->count;
    }
    FUZZ_REQUIRE(sum == sc->n_vehicles, "group counts sum to %ld, fleet %ld", sum, sc->n_vehicles);
    FUZZ_REQUIRE(sc->perturb_vehicle >= -1 && sc->perturb_vehicle < sc->n_vehicles, "perturbed vehicle %ld",
                 sc->perturb_vehicle);
    FUZZ_REQUIRE(isfinite(sc->perturb_dx_m) && isfinite(sc->perturb_dv_mps) && isfinite(sc->jitter_m), "perturbation");
    FUZZ_REQUIRE(sc->v_go_mps > sc->v_stop_mps, "v_go %g <= v_stop %g", sc->v_go_mps, sc->v_stop_mps);
    if (sc->corridor) {
        check_corridor(sc);
        return;
    }
    const WfRoad *r = &sc->road;
    for (size_t i = 0; i < r->n_grade; i++) {
        FUZZ_REQUIRE(r->grade_x_m[i] >= 0 && r->grade_x_m[i] < r->length_m, "grade x %g", r->grade_x_m[i]);
        FUZZ_REQUIRE(i == 0 || r->grade_x_m[i] > r->grade_x_m[i - 1], "grade x not increasing at %zu", i);
        FUZZ_REQUIRE(fabs(r->grade_rad[i]) <= 0.2, "grade %g", r->grade_rad[i]);
    }
    /* The grade lookup the engine uses must stay within the profile's range anywhere on the unwrapped road. */
    uint32_t seg = 0;
    for (int k = -3; k <= 40; k++) {
        double x = r->length_m * k / 7.0;
        double th = wf_road_grade(r, x, &seg);
        FUZZ_REQUIRE(isfinite(th) && fabs(th) <= 0.2 + 1e-12, "grade(%g) = %g", x, th);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const uint8_t *nul = memchr(data, 0, size);
    size_t yaml_len = nul ? (size_t)(nul - data) : size;
    fuzz_copy_scenario_data();
    const char *path = fuzz_write("fuzz.yaml", data, yaml_len);

    /* --set assignments: the bytes after the NUL, one per line (at most MAX_SETS). */
    char *sets_text = NULL;
    const char *sets[MAX_SETS];
    size_t n_sets = 0;
    if (nul) {
        size_t n = size - yaml_len - 1;
        sets_text = malloc(n + 1);
        if (!sets_text) return 0;
        memcpy(sets_text, nul + 1, n);
        sets_text[n] = '\0';
        char *save = NULL;
        for (char *s = strtok_r(sets_text, "\n", &save); s && n_sets < MAX_SETS; s = strtok_r(NULL, "\n", &save))
            sets[n_sets++] = s;
    }

    WfScenario *sc = NULL;
    WfError err = {0};
    int rc = wf_scenario_load(path, sets, n_sets, &sc, &err);
    if (rc) {
        fuzz_check_error("scenario", rc, &err);
        FUZZ_REQUIRE(sc == NULL, "failed load returned a scenario");
    } else {
        FUZZ_REQUIRE(sc != NULL, "successful load returned no scenario");
        fuzz_note("scenario", 0, &err);
        check_scenario(sc);
    }
    wf_scenario_destroy(&sc);
    free(sets_text);
    return 0;
}
