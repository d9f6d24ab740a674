/* The list of safety-filter kinds (include/wavefuel/safety.h); adding one is one file and one line here. */
#include <stddef.h>

#include "util/registry.h"
#include "wavefuel/safety.h"

extern const WfSafetyKind wf_safety_gipps, wf_safety_ttc;

const WfSafetyKind *const wf_safety_kinds[] = {&wf_safety_gipps, &wf_safety_ttc, NULL};

WF_REGISTRY_FINDER(wf_safety_find, WfSafetyKind, wf_safety_kinds, "safety filter kind")
