/* Tabulated (semi-principled) energy models: the CIRCLES release publishes each class's semi-principled model
 * as fuel rates on a regular grid (CSV `Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible`; m/s, m/s^2,
 * rad, g/s, 0/1). wavefuel imports such a table once into compressed HDF5 (grid, source, checksum) and
 * evaluates it as the release's MATLAB wrappers do: trilinear in (a, theta, v), clamped to the grid's edge. */
#ifndef WAVEFUEL_TABULATED_H
#define WAVEFUEL_TABULATED_H

#include <stddef.h>
#include <stdint.h>
#include "wavefuel/energy.h"
#include "wavefuel/err.h"
#include "wavefuel/vehicle.h"

/* One grid axis: n nodes in ascending order, evenly spaced or not (a rectilinear grid, as MATLAB's interp3
 * and SciPy's RegularGridInterpolator accept). A bucket index finds a coordinate's cell in O(1). */
typedef struct WfTableAxis {
    size_t    n;          /* number of nodes, >= 1 */
    double    lo, hi;     /* first and last node */
    size_t    kmax;       /* last cell index: n - 2, or 0 when n == 1 */
    size_t    up;         /* index offset of a cell's upper node: 1, or 0 when n == 1 (one node, no cell) */
    double   *x;          /* owned; n + 1 values: the nodes, then one padding value so x[k + 1] always exists */
    double   *inv_w;      /* owned; n values: 1 / (x[k + 1] - x[k]) */
    size_t    n_bucket;   /* buckets of equal width over [lo, hi], none narrower than the narrowest cell */
    double    bucket_scale; /* n_bucket / (hi - lo); 0 when n == 1 */
    uint32_t *bucket;     /* owned; n_bucket entries: a cell index at or below every coordinate of the bucket */
} WfTableAxis;

/* A loaded table. Node (iv, ia, it) is at index (iv * a.n + ia) * theta.n + it of fuel_gps and infeasible. */
typedef struct WfTable {
    WfTableAxis v, a, theta;  /* m/s, m/s^2, rad */
    double     *fuel_gps;     /* owned; v.n * a.n * theta.n fuel rates, g/s */
    uint8_t    *infeasible;   /* owned; same layout, 0 or 1 */
    double     *a_max_mps2;   /* owned; v.n * theta.n: largest feasible grid acceleration of each (v, theta)
                               * column; a column with no feasible node gets the lowest grid acceleration */
    char        source[1024]; /* CSV the table was imported from, as given to the import */
    uint64_t    source_fnv1a64; /* FNV-1a 64 of the source CSV's bytes */
    uint64_t    data_fnv1a64;   /* FNV-1a 64 of grid and values (wf_table_checksum), verified on load */
} WfTable;

/* Parse a table in the release's CSV format: header required and exact, rows in any order, every value
 * finite, Infeasible 0 or 1, and the rows must form a complete regular grid: each (v, a, theta) of the
 * product of the distinct values of each column exactly once (axes may be unevenly spaced). Errors
 * (WF_EINPUT) name the file and, where one exists, the line: "not a regular grid: no row for ...",
 * "duplicate row", the header, a non-number.
 * *out is owned by the caller (wf_table_destroy). */
int wf_table_read_csv(const char *path, WfTable **out, WfError *err);
/* Build a table from its grid (nv speeds, na accelerations, nt grades, each finite and strictly ascending)
 * and values laid out [iv][ia][it] (fuel finite, g/s; infeasible 0 or 1); everything is copied. `source`
 * labels where the values came from (source_fnv1a64 = 0: no file). For programs that sample a model. *out is
 * owned by the caller (wf_table_destroy). */
int wf_table_from_grid(size_t nv, const double *v_mps, size_t na, const double *a_mps2, size_t nt,
                       const double *theta_rad, const double *fuel_gps, const uint8_t *infeasible, const char *source,
                       WfTable **out, WfError *err);
/* Write the table as compressed HDF5 through the .partial protocol (refuses to overwrite unless force). */
int wf_table_write_h5(const WfTable *t, const char *path, int force, WfError *err);
/* Load a table written by wf_table_write_h5; a format, shape or checksum mismatch is an error (WF_EINPUT). *out
 * is owned by the caller (wf_table_destroy); NULL on failure. */
int wf_table_load_h5(const char *path, WfTable **out, WfError *err);
/* CSV -> HDF5 in one call (what `wavefuel table import` runs). */
int wf_table_import(const char *csv_path, const char *h5_path, int force, WfError *err);
void wf_table_destroy(WfTable **t);
/* FNV-1a 64 over the axis sizes and nodes, the fuel rates (IEEE bits, little-endian order) and the infeasible
 * bytes. */
uint64_t wf_table_checksum(const WfTable *t);

/* Scalar evaluation, the release's wrapper semantics (see docs/cycles.md): flag 2 if v < 0, else 1 if the
 * trilinear interpolation of Infeasible at the original (v, a, theta) is non-zero, else 0; v <- max(v, 0);
 * with project a <- min(a, a_max(v, theta)); fuel = trilinear interpolation at (v, a, theta). Coordinates
 * outside the grid are clamped to its edge; *outside (may be NULL) is set to 1 when that happened to the
 * point the fuel was read at. Returns fuel g/s; flag may be NULL. */
double wf_table_fuel(const WfTable *t, double v_mps, double a_mps2, double theta_rad, int project, uint8_t *flag,
                     int *outside);
/* Bilinear interpolation over (theta, v) of the per-column largest feasible grid acceleration, m/s^2
 * (v <- max(v, 0), both clamped to the grid). */
double wf_table_a_max(const WfTable *t, double v_mps, double theta_rad);
/* Array forms (structure of arrays; flag may be NULL). Pure; safe from any thread. */
void wf_table_eval(const WfTable *t, size_t n, const double *v_mps, const double *a_mps2, const double *theta_rad,
                   int project, double *fuel_gps, uint8_t *flag);
size_t wf_table_n_outside(const WfTable *t, size_t n, const double *v_mps, const double *a_mps2,
                          const double *theta_rad, int project);

/* The tabulated model as an energy-model family: `energy_model: tabulated` with `table: FILE.h5` in the class
 * file (relative to the class file's directory). No numeric parameters; the table is loaded by load(). */
typedef struct WfTabulatedParams {
    WfTable *table; /* owned: loaded by the load() hook, freed by release() */
} WfTabulatedParams;
extern const WfEnergyModel wf_energy_tabulated;

/* The table path a class file names with `table:` (resolved against the class file's directory), whether
 * the class's model is tabulated or explicit (a table beside the polynomial). path[0] = '\0' when the file
 * names none. Errors: the class file cannot be read, or the path is too long. */
int wf_tabulated_class_table(const WfVehicleClass *vc, char *path, size_t len, WfError *err);
/* A tabulated twin of a class: same name, duty, fuel, density and kW per g/s, model = the table at
 * table_path (HDF5). *out is freed with wf_vehicle_free. */
int wf_tabulated_class(const WfVehicleClass *base, const char *table_path, WfVehicleClass *out, WfError *err);

#endif
