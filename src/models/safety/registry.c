/* The list of safety-filter kinds (include/wavefuel/safety.h); adding one is one file and one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/safety.h"

extern const WfSafetyKind wf_safety_gipps, wf_safety_ttc;

const WfSafetyKind *const wf_safety_kinds[] = {&wf_safety_gipps, &wf_safety_ttc, NULL};

int wf_safety_find(const char *name, const WfSafetyKind **out, WfError *err)
{
    long i = wf_registry_find((const void *const *)wf_safety_kinds, offsetof(WfSafetyKind, name), name,
                              "safety filter kind", err);
    if (i >= 0) *out = wf_safety_kinds[i];
    return i < 0 ? WF_EINPUT : 0;
}
