/* Edie's generalized flow, density and speed of a corridor (/edie): the columns, and the fields on the
 * space-time grid from the cell sums the engine accumulates (src/core/corridor.c). Definitions:
 * docs/corridors.md. */
#include <math.h>

#include "observe/columns.h"

enum { E_XE, E_TE, E_X, E_T, E_GRADE, E_FLOW, E_DENS, E_SPEED, E_FUEL, E_DIST, E_TIME, E_FMASS, E_CFUEL, E_CDIST,
       E_CPK };

const WfObsColumn wf_edie_columns[WF_EDIE_N_COLS] = {
    {{"x_edges", "m", "cell edges along the road"}, WF_COL_F64, 1},
    {{"t_edges", "s", "cell edges in time"}, WF_COL_F64, 1},
    {{"x", "m", "cell centres along the road"}, WF_COL_F64, 1},
    {{"t", "s", "cell centres in time"}, WF_COL_F64, 1},
    {{"grade", "rad", "mean grade of each cell column"}, WF_COL_F64, 1},
    {{"flow", "1/h", "Edie flow q = sum of distances / |A| [t x x]"}, WF_COL_F64, 0},
    {{"density", "1/km", "Edie density k = sum of times / |A| [t x x]"}, WF_COL_F64, 0},
    {{"speed", "m/s", "Edie speed v = q / k [t x x] (NaN where k = 0)"}, WF_COL_F64, 0},
    {{"fuel", "g/(km h)", "fuel burnt in the cell per km of road per hour [t x x]"}, WF_COL_F64, 0},
    {{"distance", "m", "sum of distances travelled in the cell"}, WF_COL_F64, 0},
    {{"time", "s", "sum of times spent in the cell"}, WF_COL_F64, 0},
    {{"fuel_mass", "g", "fuel burnt in the cell"}, WF_COL_F64, 0},
    {{"class_fuel", "g", "fuel burnt per class and cell column in the statistics window [class x x]"}, WF_COL_F64, 0},
    {{"class_distance", "m", "distance per class and cell column in the statistics window [class x x]"},
     WF_COL_F64, 0},
    {{"class_fuel_per_km", "g/km", "fuel per vehicle-km per class and cell column in the window (NaN: no distance)"},
     WF_COL_F64, 0},
};

int wf_edie_is_field(size_t col) { return col >= E_FLOW && col <= E_FMASS; }

size_t wf_edie_scratch(const WfEdie *e, size_t n_classes)
{
    return 4 * e->nx * e->nt + 2 * (e->nx + 1) + 2 * (e->nt + 1) + n_classes * e->nx + 1;
}

void wf_edie_fields(const WfEdie *e, const WfScenario *sc, double *scratch, WfObsData *out)
{
    size_t nx = e->nx, nt = e->nt, n = nx * nt, nc = sc->n_classes;
    double L = sc->road.length_m;
    double *xe = scratch, *te = xe + nx + 1, *xc = te + nt + 1, *tc = xc + nx + 1, *q = tc + nt + 1, *k = q + n,
           *v = k + n, *f = v + n, *cpk = f + n;
    for (size_t i = 0; i <= nx; i++) xe[i] = i == nx ? L : (double)i * e->dx_m;
    for (size_t j = 0; j <= nt; j++) te[j] = j == nt ? sc->duration_s : (double)j * e->dt_s;
    for (size_t i = 0; i < nx; i++) xc[i] = 0.5 * (xe[i] + xe[i + 1]);
    for (size_t j = 0; j < nt; j++) tc[j] = 0.5 * (te[j] + te[j + 1]);
    /* |A| of each cell in m s (the last row and column may be shorter than dx, dt). */
    for (size_t j = 0; j < nt; j++)
        for (size_t i = 0; i < nx; i++) {
            size_t a = j * nx + i;
            double area = (xe[i + 1] - xe[i]) * (te[j + 1] - te[j]);
            q[a] = e->dist_m[a] / area * 3600.0; /* veh/s -> veh/h */
            k[a] = e->time_s[a] / area * 1000.0; /* veh/m -> veh/km */
            v[a] = e->time_s[a] > 0 ? e->dist_m[a] / e->time_s[a] : NAN;
            f[a] = e->fuel_g[a] / area * 3.6e6;  /* g/(m s) -> g/(km h) */
        }
    for (size_t a = 0; a < nc * nx; a++)
        cpk[a] = e->class_dist_m[a] > 0 ? e->class_fuel_g[a] / (e->class_dist_m[a] / 1000.0) : NAN;
    const double *grid[] = {xe, te, xc, tc, e->grade_mean_rad};
    size_t len[] = {nx + 1, nt + 1, nx, nt, nx};
    for (size_t c = E_XE; c <= E_GRADE; c++) out[c] = (WfObsData){grid[c], 1, {len[c], 0}};
    const double *field[] = {q, k, v, f, e->dist_m, e->time_s, e->fuel_g};
    for (size_t c = E_FLOW; c <= E_FMASS; c++) out[c] = (WfObsData){field[c - E_FLOW], 2, {nt, nx}};
    const double *cls[] = {e->class_fuel_g, e->class_dist_m, cpk};
    for (size_t c = E_CFUEL; c <= E_CPK; c++) out[c] = (WfObsData){cls[c - E_CFUEL], 2, {nc, nx}};
}
