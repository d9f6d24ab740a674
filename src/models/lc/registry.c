/* The list of lane-change models (include/wavefuel/lanechange.h); adding one is one file and one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/lanechange.h"

extern const WfLaneChangeModel wf_lc_mobil;

const WfLaneChangeModel *const wf_lc_models[] = {&wf_lc_mobil, NULL};

int wf_lc_model_find(const char *name, const WfLaneChangeModel **out, WfError *err)
{
    long i = wf_registry_find((const void *const *)wf_lc_models, offsetof(WfLaneChangeModel, name), name,
                              "lane-change model", err);
    if (i >= 0) *out = wf_lc_models[i];
    return i < 0 ? WF_EINPUT : 0;
}
