/* The list of energy model families; adding one is one line here. */
#include <stdio.h>
#include <string.h>

#include "wavefuel/energy.h"
#include "wavefuel/tabulated.h"

const WfEnergyModel *const wf_energy_models[] = {&wf_energy_circles, &wf_energy_tabulated, NULL};

int wf_energy_model_find(const char *name, const WfEnergyModel **out, WfError *err)
{
    char known[256] = "";
    size_t used = 0;
    for (size_t i = 0; wf_energy_models[i]; i++) {
        if (strcmp(wf_energy_models[i]->name, name) == 0) {
            *out = wf_energy_models[i];
            return 0;
        }
        int w = snprintf(known + used, sizeof known - used, "%s%s", i ? ", " : "", wf_energy_models[i]->name);
        if (w > 0 && (size_t)w < sizeof known - used) used += (size_t)w;
    }
    return wf_err(err, WF_EINPUT, "unknown energy model '%s' (known: %s)", name, known);
}
