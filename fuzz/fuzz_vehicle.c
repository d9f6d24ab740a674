/* Fuzz target: the vehicle class loader (vehicles/NAME.yaml -> WfVehicleClass). Input: the class file's YAML.
 * Accepted classes must satisfy the documented ranges, and their energy model must give finite fuel rates
 * and valid flags over the driving envelope (speeds 0..40 m/s, accelerations -4..3 m/s^2, grades +-0.1 rad). */
#include <math.h>
#include <stdint.h>

#include "fuzz_common.h"
#include "wavefuel/vehicle.h"

static void check_class(const WfVehicleClass *vc)
{
    FUZZ_REQUIRE(vc->model != NULL, "no model");
    FUZZ_REQUIRE(vc->params != NULL || vc->model->param_size == 0, "no parameters");
    FUZZ_REQUIRE(vc->mass_kg >= 100 && vc->mass_kg <= 100000, "mass %g", vc->mass_kg);
    FUZZ_REQUIRE(vc->length_m >= 1 && vc->length_m <= 30, "length %g", vc->length_m);
    FUZZ_REQUIRE(vc->kw_per_gps >= 1 && vc->kw_per_gps <= 100, "kW per g/s %g", vc->kw_per_gps);
    FUZZ_REQUIRE(isfinite(vc->fuel_density_g_per_l) && vc->fuel_density_g_per_l > 0, "density %g",
                 vc->fuel_density_g_per_l);
    FUZZ_REQUIRE(vc->duty == WF_DUTY_LIGHT || vc->duty == WF_DUTY_HEAVY, "duty %d", (int)vc->duty);
    FUZZ_REQUIRE(vc->fuel == WF_FUEL_GASOLINE || vc->fuel == WF_FUEL_DIESEL, "fuel %d", (int)vc->fuel);
    FUZZ_REQUIRE(vc->name[0] != '\0' && vc->label[0] != '\0', "empty name or label");
    enum { NV = 9, NA = 8, NT = 3, N = NV * NA * NT };
    double v[N], a[N], th[N], fuel[N];
    uint8_t flag[N];
    size_t k = 0;
    for (int i = 0; i < NV; i++)
        for (int j = 0; j < NA; j++)
            for (int t = 0; t < NT; t++, k++) v[k] = 5.0 * i, a[k] = -4.0 + j, th[k] = 0.1 * (t - 1);
    for (int project = 0; project <= 1; project++) {
        wf_vehicle_fuel(vc, N, v, a, th, project, fuel, flag);
        for (k = 0; k < N; k++) {
            FUZZ_REQUIRE(isfinite(fuel[k]), "fuel(%g, %g, %g) = %g", v[k], a[k], th[k], fuel[k]);
            FUZZ_REQUIRE(flag[k] <= WF_NEGATIVE_SPEED, "flag %d", flag[k]);
        }
        double amax = vc->model->a_max(vc->params, v[0], th[0]);
        FUZZ_REQUIRE(!isnan(amax), "a_max is NaN");
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write("fuzzcls.yaml", data, size);
    WfVehicleClass vc;
    WfError err = {0};
    int rc = wf_vehicle_load(path, &vc, &err);
    if (rc) {
        fuzz_check_error("vehicle", rc, &err);
        FUZZ_REQUIRE(vc.params == NULL, "failed load kept its parameters");
        return 0;
    }
    fuzz_note("vehicle", 0, &err);
    check_class(&vc);
    wf_vehicle_free(&vc);
    return 0;
}
