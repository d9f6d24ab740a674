/* Parameter tables: every pluggable model (car-following, energy) describes its parameters as an array
 * of WfParamSpec (key, byte offset of a double in the model's parameter struct, default, range, unit).
 * One generic loader fills, checks, prints and writes any model's parameters from that table. */
#ifndef WAVEFUEL_PARAM_H
#define WAVEFUEL_PARAM_H

#include <stddef.h>
#include "wavefuel/err.h"

enum {
    WF_PARAM_REQUIRED = 1, /* no default: a file must give it */
    WF_PARAM_OPTIONAL = 2  /* may be absent: stays NaN, the model's check() decides */
};

typedef struct WfParamSpec {
    const char *key;    /* as written in files, unit suffix included where it names one: "T_s" */
    size_t      offset; /* offsetof(ModelParams, field); the field is a double */
    double      def;    /* default when absent (ignored with WF_PARAM_REQUIRED / _OPTIONAL) */
    double      min, max; /* closed range accepted */
    const char *unit;   /* SI unit text, "1" for dimensionless */
    int         flags;
    const char *doc;    /* one line: what it is */
} WfParamSpec;

/* Field access; p points to the model's parameter struct. */
static inline double *wf_param_ptr(void *p, const WfParamSpec *s) { return (double *)((char *)p + s->offset); }
static inline double wf_param_get(const void *p, const WfParamSpec *s)
{
    return *(const double *)((const char *)p + s->offset);
}

/* Look up a key; NULL if the table has none. */
const WfParamSpec *wf_param_find(const WfParamSpec *spec, size_t n, const char *key);
/* Fill every field with its default (NaN for required and optional ones). */
void wf_param_defaults(const WfParamSpec *spec, size_t n, void *params);
/* After filling: every WF_PARAM_REQUIRED field must be set (not NaN). */
int wf_param_check_complete(const WfParamSpec *spec, size_t n, const void *params, const char *where,
                            WfError *err);
/* The known key closest to `key` by edit distance (for "did you mean"), or NULL if none is close. */
const char *wf_param_suggest(const WfParamSpec *spec, size_t n, const char *key);
/* Edit distance helper shared by every "unknown key" message. */
size_t wf_edit_distance(const char *a, const char *b);

#endif
