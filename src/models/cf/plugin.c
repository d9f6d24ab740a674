/* Plug-in controllers (include/wavefuel/cf_plugin.h): load a shared library with dlopen, check its ABI
 * version and its description, and present it as an ordinary WfCfModel. The plugin's functions have the
 * built-in models' exact signatures, so the engine calls them directly; the library stays loaded until the
 * scenario that named it is destroyed. */
#include "wavefuel/cf_plugin.h"

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wavefuel/err.h"
#include "util/numfmt.h"

#define PLUGIN_MAX_STATE_BYTES (1u << 20)

struct WfCfPluginLib {
    void       *handle;
    char        path[1024];
    WfCfModel   model; /* name, doc, accel... borrowed from the library */
    WfParamSpec spec[WF_CF_PLUGIN_MAX_PARAMS];
};

/* The host services handed to every plugin: static and constant, so plugins may keep the pointer. */
static const WfCfPluginHost plugin_host = {WF_CF_PLUGIN_ABI_VERSION, wf_err};

void wf_cf_plugin_close(WfCfPluginLib **plib)
{
    if (!plib || !*plib) return;
    if ((*plib)->handle) dlclose((*plib)->handle);
    free(*plib);
    *plib = NULL;
}

const WfCfModel *wf_cf_plugin_model(const WfCfPluginLib *lib) { return &lib->model; }
const char *wf_cf_plugin_path(const WfCfPluginLib *lib) { return lib->path; }

/* Everything wavefuel relies on, checked once so the step loop can trust it. */
static int validate(const char *path, const WfCfPlugin *d, WfError *err)
{
    if (d->abi_version != WF_CF_PLUGIN_ABI_VERSION)
        return wf_err(err, WF_EINPUT,
                      "plugin %s: built for controller ABI version %u, this wavefuel has version %u: rebuild it against "
                      "this wavefuel's include/wavefuel/cf_plugin.h",
                      path, (unsigned)d->abi_version, (unsigned)WF_CF_PLUGIN_ABI_VERSION);
    if (!d->name || !d->name[0]) return wf_err(err, WF_EINPUT, "plugin %s: its description has no name", path);
    if (!d->doc) return wf_err(err, WF_EINPUT, "plugin %s (%s): its description has no doc line", path, d->name);
    if (!d->accel) return wf_err(err, WF_EINPUT, "plugin %s (%s): accel is NULL", path, d->name);
    if (d->n_params > WF_CF_PLUGIN_MAX_PARAMS)
        return wf_err(err, WF_EINPUT, "plugin %s (%s): %zu parameters, at most %d", path, d->name, d->n_params,
                      WF_CF_PLUGIN_MAX_PARAMS);
    if (d->n_params && !d->params)
        return wf_err(err, WF_EINPUT, "plugin %s (%s): n_params is %zu but params is NULL", path, d->name,
                      d->n_params);
    for (size_t k = 0; k < d->n_params; k++) {
        const WfCfPluginParam *q = &d->params[k];
        if (!q->key || !q->key[0] || !q->unit || !q->doc)
            return wf_err(err, WF_EINPUT, "plugin %s (%s): parameter %zu lacks a key, unit or doc", path, d->name, k);
        if (!(isfinite(q->min) && isfinite(q->max) && q->min <= q->max && q->def >= q->min && q->def <= q->max))
            return wf_err(err, WF_EINPUT,
                          "plugin %s (%s): parameter '%s' needs finite min <= default <= max (got %s <= %s <= "
                          "%s)",
                          path, d->name, q->key, WF_NUM(q->min), WF_NUM(q->def), WF_NUM(q->max));
        for (size_t j = 0; j < k; j++)
            if (strcmp(d->params[j].key, q->key) == 0)
                return wf_err(err, WF_EINPUT, "plugin %s (%s): parameter '%s' declared twice", path, d->name, q->key);
    }
    if (d->state_size == 0 && (d->init_state || d->update_state))
        return wf_err(err, WF_EINPUT, "plugin %s (%s): state functions given but state_size is 0", path, d->name);
    if (d->state_size && (!d->init_state || !d->update_state))
        return wf_err(err, WF_EINPUT, "plugin %s (%s): state_size %zu needs both init_state and update_state", path,
                      d->name, d->state_size);
    /* Per-vehicle blocks are packed one after another: a multiple of 8 keeps each one aligned for doubles. */
    if (d->state_size % 8 != 0 || d->state_size > PLUGIN_MAX_STATE_BYTES)
        return wf_err(err, WF_EINPUT, "plugin %s (%s): state_size %zu must be a multiple of 8 and at most %u bytes",
                      path, d->name, d->state_size, PLUGIN_MAX_STATE_BYTES);
    return 0;
}

/* Opens the library named by path into lib (zeroed), checks its description and presents it as lib->model; each
 * error returned where it is found. */
static int open_plugin(WfCfPluginLib *lib, const char *path, WfError *err)
{
    int n = snprintf(lib->path, sizeof lib->path, "%s", path);
    if (n < 0 || (size_t)n >= sizeof lib->path)
        return wf_err(err, WF_EINPUT, "plugin path too long (%zu characters): %.80s...", strlen(path), path);
    /* Without a slash dlopen would search the system's library path instead of the file named. */
    if (!strchr(path, '/')) {
        n = snprintf(lib->path, sizeof lib->path, "./%s", path);
        if (n < 0 || (size_t)n >= sizeof lib->path)
            return wf_err(err, WF_EINPUT, "plugin path too long: %.80s...", path);
    }
    /* RTLD_NOW: a missing symbol fails here, with dlerror's message, not in the middle of a run. */
    lib->handle = dlopen(lib->path, RTLD_NOW | RTLD_LOCAL);
    if (!lib->handle) {
        const char *why = dlerror();
        return wf_err(err, WF_EINPUT, "cannot load plugin %s: %s", lib->path, why ? why : "unknown dlopen error");
    }
    dlerror();
    void *sym = dlsym(lib->handle, WF_CF_PLUGIN_ENTRY);
    if (!sym) {
        const char *why = dlerror();
        return wf_err(err, WF_EINPUT, "plugin %s does not export %s() (%s): see include/wavefuel/cf_plugin.h",
                      lib->path, WF_CF_PLUGIN_ENTRY, why ? why : "symbol is NULL");
    }
    /* ISO C has no cast from an object pointer to a function pointer; POSIX guarantees they have the same
     * representation for dlsym's results, so the bytes are copied. */
    WfCfPluginEntry entry;
    _Static_assert(sizeof entry == sizeof sym, "function and object pointers differ in size");
    memcpy(&entry, &sym, sizeof entry);
    const WfCfPlugin *d = NULL;
    WfError perr = {0};
    if (entry(&plugin_host, &d, &perr) != 0)
        return wf_err(err, WF_EINPUT, "plugin %s refused to load: %s", lib->path,
                      perr.msg[0] ? perr.msg : "(no message)");
    if (!d)
        return wf_err(err, WF_EINPUT, "plugin %s: %s() returned 0 without a description", lib->path,
                      WF_CF_PLUGIN_ENTRY);
    int rc = validate(lib->path, d, err);
    if (rc) return rc;

    /* Parameters are consecutive doubles in table order: offset k * sizeof(double). */
    for (size_t k = 0; k < d->n_params; k++) {
        const WfCfPluginParam *q = &d->params[k];
        lib->spec[k] = (WfParamSpec){q->key, k * sizeof(double), q->def, q->min, q->max, q->unit, 0, q->doc};
    }
    lib->model = (WfCfModel){
        .name = d->name,
        .doc = d->doc,
        .param_size = d->n_params * sizeof(double),
        .spec = lib->spec,
        .n_spec = d->n_params,
        .check = d->check,
        .accel = d->accel,
        .state_size = d->state_size,
        .init_state = d->init_state,
        .update_state = d->update_state,
    };
    return 0;
}

int wf_cf_plugin_load(const char *path, WfCfPluginLib **out, WfError *err)
{
    WfCfPluginLib *lib = calloc(1, sizeof *lib);
    int rc = lib ? open_plugin(lib, path, err) : wf_err(err, WF_ESYS, "out of memory");
    if (rc) wf_cf_plugin_close(&lib);
    *out = lib;
    return rc;
}
