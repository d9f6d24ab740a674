/* wf_registry_find, wf_registry_names (registry.h). */
#include "util/registry.h"

#include <stdio.h>
#include <string.h>

static const char *name_at(const void *const *items, size_t name_offset, size_t i)
{
    if (name_offset == WF_REG_STRINGS) return items[i];
    return *(const char *const *)((const char *)items[i] + name_offset);
}

const char *wf_registry_names(const void *const *items, size_t name_offset, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (size_t i = 0; items[i]; i++) {
        int w = snprintf(buf + used, size - used, "%s%s", i ? ", " : "", name_at(items, name_offset, i));
        if (w > 0 && (size_t)w < size - used) used += (size_t)w;
    }
    return buf;
}

long wf_registry_find(const void *const *items, size_t name_offset, const char *name, const char *what, WfError *err)
{
    for (size_t i = 0; items[i]; i++)
        if (strcmp(name_at(items, name_offset, i), name) == 0) return (long)i;
    char known[1024];
    wf_err(err, WF_EINPUT, "unknown %s '%s' (known: %s)", what, name, wf_registry_names(items, name_offset, known, sizeof known));
    return -1;
}
