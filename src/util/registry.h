/* Lookup by name in a registry: a NULL-terminated array of pointers to structs that carry their name (models,
 * energy model families, integrators). One form of the "unknown X (known: ...)" message for all of them. */
#ifndef WAVEFUEL_UTIL_REGISTRY_H
#define WAVEFUEL_UTIL_REGISTRY_H

#include <stddef.h>

#include "wavefuel/err.h"

/* Index of the entry whose `const char *` member at name_offset equals name; else -1, with err set (WF_EINPUT) to
 * "unknown WHAT 'NAME' (known: a, b, c)". */
long wf_registry_find(const void *const *items, size_t name_offset, const char *name, const char *what, WfError *err);

#endif
