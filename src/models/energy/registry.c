/* The list of energy model families; adding one is one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/energy.h"
#include "wavefuel/tabulated.h"

const WfEnergyModel *const wf_energy_models[] = {&wf_energy_circles, &wf_energy_tabulated, NULL};

int wf_energy_model_find(const char *name, const WfEnergyModel **out, WfError *err)
{
    long i = wf_registry_find((const void *const *)wf_energy_models, offsetof(WfEnergyModel, name), name, "energy model", err);
    if (i >= 0) *out = wf_energy_models[i];
    return i < 0 ? WF_EINPUT : 0;
}
