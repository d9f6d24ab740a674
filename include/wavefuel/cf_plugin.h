/* Plug-in controllers: the ABI between wavefuel and a user's car-following model or controller compiled
 * into a shared library. This header is self-contained (C99/C11, only <stddef.h> and <stdint.h>) so a
 * plugin builds against it alone:
 *
 *     cc -std=c11 -O2 -fPIC -shared -I/path/to/wavefuel/include my_ctrl.c -o my_ctrl.so
 *
 * and a scenario names it:   drivers: [{name: av, model: plugin, path: my_ctrl.so, count: 1, params: {...}}]
 * (path relative to the scenario file). Full guide and example: docs/controllers.md,
 * examples/plugins/follower_stopper_plugin.c. */
#ifndef WAVEFUEL_CF_PLUGIN_H
#define WAVEFUEL_CF_PLUGIN_H

#include <stddef.h>
#include <stdint.h>

/* Bumped on any change of the structs or the entry point below. A plugin built for another version is
 * refused at load time with both numbers in the message. */
#define WF_CF_PLUGIN_ABI_VERSION 1u
/* The one symbol a plugin exports (a function of type WfCfPluginEntry). */
#define WF_CF_PLUGIN_ENTRY "wf_cf_plugin_entry"
/* Most parameters a plugin may declare (wavefuel stores them as doubles in a fixed block). */
#define WF_CF_PLUGIN_MAX_PARAMS 32

/* wavefuel's error record; plugins never see inside it, they fill it through WfCfPluginHost.error. */
struct WfError;

/* What wavefuel gives the plugin at load time. */
typedef struct WfCfPluginHost {
    uint32_t abi_version; /* WF_CF_PLUGIN_ABI_VERSION of the running wavefuel */
    /* Record an error (printf-style) and return `code` (1: system failure, 2: bad input). err may be NULL
     * (then nothing is recorded). Safe to keep and call from check() at any time while loaded. */
    int (*error)(struct WfError *err, int code, const char *fmt, ...);
} WfCfPluginHost;

/* One parameter. The values reach the plugin as an array of doubles in table order (declare a struct of
 * doubles in the same order and cast `params` to it). Keys carry their unit suffix (`T_s`, `U_mps`). */
typedef struct WfCfPluginParam {
    const char *key;
    double      def, min, max; /* default (within [min, max]) and accepted closed range */
    const char *unit;          /* SI unit text: "m/s", "1/s", "1" for dimensionless */
    const char *doc;           /* one line */
} WfCfPluginParam;

/* The controller. Every string and table must stay valid while the library is loaded (static storage).
 * The functions have exactly the shapes of wavefuel's built-in models (include/wavefuel/cf.h):
 *  - accel: acceleration (m/s^2) from the bumper-to-bumper gap to the leader (m, >= 0) and the own and
 *    leader's speeds (m/s, >= 0). Must be finite for all such inputs, and pure: the same inputs (state
 *    included) give the same result; it is called for every vehicle at every step, from several threads at
 *    once on different vehicles. wavefuel then clips the result to the group's accel/decel limits.
 *    `state` is NULL when state_size is 0, and also when wavefuel computes uniform-flow equilibria for the
 *    initial conditions (then answer for a settled controller: the sign of accel(s, v, v) must change once in
 *    the gap s, from negative to positive).
 *  - init_state / update_state: per-vehicle memory of state_size bytes (a multiple of 8, at most 1 MiB),
 *    allocated by wavefuel (8-byte aligned). init_state sets it at t = 0; update_state advances it once per
 *    completed step of dt_s with the inputs that step's accel saw. Both NULL when state_size is 0.
 *  - check: cross-field validation of one vehicle's parameters (ranges are checked by wavefuel from the
 *    table); returns 0, or reports through host->error and returns its result. May be NULL. */
typedef struct WfCfPlugin {
    uint32_t abi_version; /* WF_CF_PLUGIN_ABI_VERSION the plugin was built with */
    const char *name;     /* reported in outputs (/drivers/model), e.g. "my_controller" */
    const char *doc;      /* one line: model and reference */
    const WfCfPluginParam *params;
    size_t n_params;      /* <= WF_CF_PLUGIN_MAX_PARAMS */
    int (*check)(const void *params, struct WfError *err);
    double (*accel)(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps);
    size_t state_size;
    void (*init_state)(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps);
    void (*update_state)(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps,
                         double dt_s);
} WfCfPlugin;

/* The exported entry point, called once per load: store `host` if check() reports errors, set *out to the
 * plugin's (static) description and return 0; or report through host->error(err, ...) and return non-zero
 * (e.g. when host->abi_version is not one the plugin supports). */
typedef int (*WfCfPluginEntry)(const WfCfPluginHost *host, const WfCfPlugin **out, struct WfError *err);

/* ------------------------------------------------------------------------------------------------------
 * wavefuel's side (src/models/cf/plugin.c); plugins do not call these. */
struct WfCfModel;
typedef struct WfCfPluginLib WfCfPluginLib;

/* dlopen `path` (used as given: relative paths resolve against the working directory, a bare file name is
 * not searched on the library path), call its entry point, validate the description (ABI version, name,
 * accel, parameter table, state functions and size) and build a car-following model from it. Fails
 * (WF_EINPUT, message naming the path) on any of those; nothing stays loaded then. Ownership: *out is the
 * caller's until wf_cf_plugin_close(), which unloads the library; the model it gives (wf_cf_plugin_model) is
 * valid until then; path is copied. */
int wf_cf_plugin_load(const char *path, WfCfPluginLib **out, struct WfError *err);
/* The model built from the plugin: valid until wf_cf_plugin_close(). */
const struct WfCfModel *wf_cf_plugin_model(const WfCfPluginLib *lib);
/* The path it was loaded from. */
const char *wf_cf_plugin_path(const WfCfPluginLib *lib);
/* dlclose and free; accepts NULL and clears the pointer. */
void wf_cf_plugin_close(WfCfPluginLib **lib);

#endif
