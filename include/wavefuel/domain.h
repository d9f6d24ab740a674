/* The operating points wavefuel accepts from files and arguments: speed, acceleration and road grade of an energy
 * query (`wavefuel energy` rows) and of a drive cycle (`wavefuel cycle` speeds and --grade). One table, so the
 * commands accept the same values; bounds are far beyond any road vehicle and keep every model's result finite. */
#ifndef WAVEFUEL_DOMAIN_H
#define WAVEFUEL_DOMAIN_H

#include "wavefuel/err.h"

typedef enum WfPointVar { WF_POINT_SPEED, WF_POINT_ACCEL, WF_POINT_GRADE, WF_N_POINT_VARS } WfPointVar;

typedef struct WfRange {
    const char *quantity; /* "speed" */
    double      min, max; /* inclusive bounds, in `unit` */
    const char *unit;     /* "m/s" */
} WfRange;

/* Indexed by WfPointVar: speed [0, 150] m/s, acceleration [-20, 20] m/s^2, grade [-0.5, 0.5] rad. */
extern const WfRange wf_point_range[WF_N_POINT_VARS];

/* 0 when min <= x <= max; else WF_EINPUT with "<where> must be in [min, max] unit (got x)", x printed in the
 * shortest form that reads back as x. `where` names the place: "cycle.csv:4: field 2 (speed_mps)". */
int wf_range_check(const WfRange *r, double x, const char *where, WfError *err);

#endif
