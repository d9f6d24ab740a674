/* Vehicle classes: one YAML file per class in vehicles/ holding its energy model parameters, duty, fuel,
 * mass and default length. Classes are found by name along a search path or given as a file path. */
#ifndef WAVEFUEL_VEHICLE_H
#define WAVEFUEL_VEHICLE_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/energy.h"
#include "wavefuel/err.h"

typedef enum { WF_DUTY_LIGHT = 0, WF_DUTY_HEAVY = 1 } WfDuty;
typedef enum { WF_FUEL_GASOLINE = 0, WF_FUEL_DIESEL = 1 } WfFuelType;

typedef struct WfVehicleClass {
    char                 name[64];       /* file stem: "midsize_suv" */
    char                 label[96];      /* human name: "Midsize SUV" */
    char                 path[1024];     /* file it was loaded from */
    WfDuty               duty;
    WfFuelType           fuel;
    double               mass_kg;        /* test mass of the release's model header (enters no fuel rate) */
    double               paper_mass_kg;  /* the paper's Table 1 where it differs; NaN when the file omits it */
    double               length_m;       /* default vehicle length */
    double               fuel_density_g_per_l; /* converts g to L for L/100 km and mpg */
    double               kw_per_gps;     /* equivalent power per unit fuel rate, kW/(g/s) */
    const WfEnergyModel *model;          /* borrowed: a registry entry */
    void                *params;         /* owned: model->param_size bytes */
} WfVehicleClass;

/* Fuel densities used when a class file does not set fuel_density_g_per_l: the CIRCLES release's
 * 2839 g per US gallon of gasoline and 3217 g per US gallon of diesel (3.785411784 L per gallon). */
#define WF_GASOLINE_G_PER_GAL 2839.0
#define WF_DIESEL_G_PER_GAL   3217.0
#define WF_L_PER_US_GAL       3.785411784
#define WF_M_PER_MILE         1609.344

/* The numeric top-level keys of a class file (mass_kg, paper_mass_kg, length_m, kw_per_gps,
 * fuel_density_g_per_l): key, offset in WfVehicleClass, range, unit, required or optional, meaning. The loader
 * reads them from this table; docs/energy.md lists them (tests/test_vehicle.c checks). */
extern const WfParamSpec wf_vehicle_keys[];
extern const size_t      wf_vehicle_n_keys;

/* Load a class file into *vc (name = the file stem). vc->params is owned by *vc: free it with wf_vehicle_free()
 * (the struct itself is the caller's); vc->model is borrowed from the registry, valid for the process. On failure
 * nothing is left to free and the message names file, line and key. */
int wf_vehicle_load(const char *path, WfVehicleClass *vc, WfError *err);
/* The class search path: directories searched for NAME.yaml, in order, colon-separated ("DIR1:DIR2"; empty
 * entries and missing directories are skipped). A setting of the library for the whole process, empty by default:
 * until it is set, classes are found only by file path. `dirs` is copied (the caller keeps it); NULL or ""
 * empties the path. Set it at start-up, before any lookup, and not while another thread looks classes up. The
 * wavefuel programs set "$WAVEFUEL_VEHICLES:PREFIX/vehicles" for PREFIX/bin/wavefuel (docs/energy.md).
 * WF_EINPUT, and the path unchanged, if it has WF_VEHICLE_PATH_MAX bytes or more. */
#define WF_VEHICLE_PATH_MAX 8192
int wf_vehicle_search_path_set(const char *dirs, WfError *err);
/* The search path now ("" when empty); borrowed, valid until the next wf_vehicle_search_path_set(). */
const char *wf_vehicle_search_path(void);
/* Find a class: if `name_or_path` contains '/' or ends in .yaml it is a path; otherwise it is looked up as
 * NAME.yaml along the class search path (first match wins). Unknown names list the classes found there. *vc as
 * for wf_vehicle_load(). */
int wf_vehicle_find(const char *name_or_path, WfVehicleClass *vc, WfError *err);
void wf_vehicle_free(WfVehicleClass *vc);

/* Every class on the class search path (sorted by name, first occurrence wins). *out is owned by the caller:
 * free each with wf_vehicle_free() and the array with free(). */
int wf_vehicle_list(WfVehicleClass **out, size_t *n, WfError *err);

/* Evaluate n points of this class's model: fuel g/s and flags (flag may be NULL). */
static inline void wf_vehicle_fuel(const WfVehicleClass *vc, size_t n, const double *v_mps, const double *a_mps2,
                                   const double *theta_rad, int project, double *fuel_gps, uint8_t *flag)
{
    vc->model->eval(vc->params, n, v_mps, a_mps2, theta_rad, project, fuel_gps, flag);
}

/* Fuel economy from grams and metres: L/100 km and miles per US gallon (0 distance gives +inf / 0). */
double wf_l_per_100km(const WfVehicleClass *vc, double fuel_g, double dist_m);
double wf_mpg(const WfVehicleClass *vc, double fuel_g, double dist_m);

const char *wf_duty_name(WfDuty d);
const char *wf_fuel_name(WfFuelType f);

#endif
