/* wf_registry_find (registry.h). */
#include "util/registry.h"

#include <stdio.h>
#include <string.h>

long wf_registry_find(const void *const *items, size_t name_offset, const char *name, const char *what, WfError *err)
{
    char known[256] = "";
    size_t used = 0;
    for (size_t i = 0; items[i]; i++) {
        const char *entry = *(const char *const *)((const char *)items[i] + name_offset);
        if (strcmp(entry, name) == 0) return (long)i;
        int w = snprintf(known + used, sizeof known - used, "%s%s", i ? ", " : "", entry);
        if (w > 0 && (size_t)w < sizeof known - used) used += (size_t)w;
    }
    wf_err(err, WF_EINPUT, "unknown %s '%s' (known: %s)", what, name, known);
    return -1;
}
