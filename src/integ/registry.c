/* The list of fixed-step integrators; adding one is one line here. */
#include <stdio.h>
#include <string.h>

#include "wavefuel/integrator.h"

const WfIntegrator *const wf_integrators[] = {&wf_integ_ballistic, &wf_integ_euler, NULL};

int wf_integrator_find(const char *name, const WfIntegrator **out, WfError *err)
{
    char known[256] = "";
    size_t used = 0;
    for (size_t i = 0; wf_integrators[i]; i++) {
        if (strcmp(wf_integrators[i]->name, name) == 0) {
            *out = wf_integrators[i];
            return 0;
        }
        int w = snprintf(known + used, sizeof known - used, "%s%s", i ? ", " : "", wf_integrators[i]->name);
        if (w > 0 && (size_t)w < sizeof known - used) used += (size_t)w;
    }
    return wf_err(err, WF_EINPUT, "unknown integrator '%s' (known: %s)", name, known);
}
