/* The list of energy model families; adding one is one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/energy.h"
#include "wavefuel/tabulated.h"

const WfEnergyModel *const wf_energy_models[] = {&wf_energy_circles, &wf_energy_tabulated, NULL};

WF_REGISTRY_FINDER(wf_energy_model_find, WfEnergyModel, wf_energy_models, "energy model")
