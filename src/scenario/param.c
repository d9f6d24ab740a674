/* Generic parameter tables: defaults, range checks and "did you mean" for every model family. */
#include "wavefuel/param.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

const WfParamSpec *wf_param_find(const WfParamSpec *spec, size_t n, const char *key)
{
    for (size_t i = 0; i < n; i++)
        if (strcmp(spec[i].key, key) == 0) return &spec[i];
    return NULL;
}

void wf_param_defaults(const WfParamSpec *spec, size_t n, void *params)
{
    for (size_t i = 0; i < n; i++)
        *wf_param_ptr(params, &spec[i]) = (spec[i].flags & (WF_PARAM_REQUIRED | WF_PARAM_OPTIONAL)) ? NAN
                                                                                                    : spec[i].def;
}

int wf_param_check_complete(const WfParamSpec *spec, size_t n, const void *params, const char *where,
                            WfError *err)
{
    for (size_t i = 0; i < n; i++)
        if ((spec[i].flags & WF_PARAM_REQUIRED) && isnan(wf_param_get(params, &spec[i])))
            return wf_err(err, WF_EINPUT, "%smissing required key '%s' (%s, %s)", where, spec[i].key,
                          spec[i].doc ? spec[i].doc : "", spec[i].unit);
    return WF_OK;
}

size_t wf_edit_distance(const char *a, const char *b)
{
    size_t la = strlen(a), lb = strlen(b);
    if (la > 64 || lb > 64) return la > lb ? la : lb;
    size_t row[65];
    for (size_t j = 0; j <= lb; j++) row[j] = j;
    for (size_t i = 1; i <= la; i++) {
        size_t diag = row[0];
        row[0] = i;
        for (size_t j = 1; j <= lb; j++) {
            size_t up = row[j];
            size_t sub = diag + (a[i - 1] != b[j - 1]);
            size_t best = up + 1 < row[j - 1] + 1 ? up + 1 : row[j - 1] + 1;
            row[j] = sub < best ? sub : best;
            diag = up;
        }
    }
    return row[lb];
}

const char *wf_param_suggest(const WfParamSpec *spec, size_t n, const char *key)
{
    const char *best = NULL;
    size_t best_d = (size_t)-1;
    for (size_t i = 0; i < n; i++) {
        size_t d = wf_edit_distance(key, spec[i].key);
        if (d < best_d) best_d = d, best = spec[i].key;
    }
    size_t len = strlen(key);
    return (best && best_d <= (len < 4 ? 1 : len / 2)) ? best : NULL;
}
