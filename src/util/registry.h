/* Lookup by name in a registry: a NULL-terminated array of pointers to structs that carry their name (models,
 * energy model families, integrators), or of the names themselves. One form of the "unknown X (known: ...)"
 * message for all of them. */
#ifndef WAVEFUEL_UTIL_REGISTRY_H
#define WAVEFUEL_UTIL_REGISTRY_H

#include <stddef.h>

#include "wavefuel/err.h"

/* name_offset for a NULL-terminated `const char *const[]` of the names themselves. */
#define WF_REG_STRINGS ((size_t)-1)

/* Index of the entry whose `const char *` member at name_offset equals name; else -1, with err set (WF_EINPUT) to
 * "unknown WHAT 'NAME' (known: a, b, c)". err may be NULL. */
long wf_registry_find(const void *const *items, size_t name_offset, const char *name, const char *what, WfError *err);

/* The entries' names joined with ", " into buf (size bytes, > 0), cut short if they do not fit. Returns buf. */
const char *wf_registry_names(const void *const *items, size_t name_offset, char *buf, size_t size);

/* Defines `int FN(const char *name, const TYPE **out, WfError *err)` over LIST (const TYPE *const[], NULL-terminated):
 * 0 with *out set, or WF_EINPUT with err set by wf_registry_find and *out untouched. */
#define WF_REGISTRY_FINDER(fn, type, list, what)                                                                      \
    int fn(const char *name, const type **out, WfError *err)                                                          \
    {                                                                                                                 \
        long i = wf_registry_find((const void *const *)(list), offsetof(type, name), name, what, err);               \
        if (i >= 0) *out = (list)[i];                                                                                 \
        return i < 0 ? WF_EINPUT : 0;                                                                                 \
    }

#endif
