/* The list of lane-change models (include/wavefuel/lanechange.h); adding one is one file and one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/lanechange.h"

extern const WfLaneChangeModel wf_lc_mobil;

const WfLaneChangeModel *const wf_lc_models[] = {&wf_lc_mobil, NULL};

WF_REGISTRY_FINDER(wf_lc_model_find, WfLaneChangeModel, wf_lc_models, "lane-change model")
