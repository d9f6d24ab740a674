/* The generic reader of scenario key tables (include/wavefuel/keys.h): defaults, typed and range-checked reads
 * through the config getters (so every message is theirs: file:line: path: expected ... (got ...)), sections,
 * hooks, and the keys of the other boundary. */
#include "wavefuel/keys.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wavefuel/config.h"
#include "wavefuel/scenario.h"

static double bound(WfKeyBound b, double fixed, const WfKeyEnv *env)
{
    const WfScenario *sc = env->sc;
    switch (b) {
    case WF_BOUND_LENGTH: return sc->road.length_m;
    case WF_BOUND_NEG_LENGTH: return -sc->road.length_m;
    case WF_BOUND_DURATION: return sc->duration_s;
    case WF_BOUND_VEHICLES: return (double)sc->n_vehicles;
    case WF_BOUND_LAST_VEHICLE: return (double)(sc->n_vehicles - 1);
    default: return fixed;
    }
}

void wf_key_range(const WfKeySpec *row, const WfKeyEnv *env, double *min, double *max)
{
    *min = bound(row->min_is, row->min, env);
    *max = bound(row->max_is, row->max, env);
}

static void *field(void *target, const WfKeySpec *row) { return (char *)target + row->offset; }

/* INTEGER fields are long or int by `size`; BOOL and CHOICE fields are int (enums of int size). */
static int int_sized(const WfKeySpec *row) { return row->type != WF_KEY_INTEGER || row->size == sizeof(int); }

static long get_int(void *target, const WfKeySpec *row)
{
    if (int_sized(row)) {
        int i;
        memcpy(&i, field(target, row), sizeof i);
        return i;
    }
    long v;
    memcpy(&v, field(target, row), sizeof v);
    return v;
}

static void put_int(void *target, const WfKeySpec *row, long v)
{
    if (int_sized(row)) {
        int i = (int)v;
        memcpy(field(target, row), &i, sizeof i);
    } else {
        memcpy(field(target, row), &v, sizeof v);
    }
}

/* The table default of a row, and those of a section's rows (its check runs too: derived defaults). */
static int set_default(WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err)
{
    if (row->flags & (WF_KEY_REQUIRED | WF_KEY_PRESET)) return 0;
    switch (row->type) {
    case WF_KEY_NUMBER: memcpy(field(target, row), &row->def, sizeof row->def); return 0;
    case WF_KEY_INTEGER:
    case WF_KEY_BOOL:
    case WF_KEY_CHOICE: put_int(target, row, (long)row->def); return 0;
    case WF_KEY_SECTION:
        for (size_t i = 0; i < row->sub->n; i++)
            if (set_default(NULL, &row->sub->keys[i], target, env, err)) return WF_EINPUT;
        return row->hook ? row->hook(map, row, target, env, err) : 0;
    default: return 0;
    }
}

static int read_section(WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err)
{
    WfCfgNode *sec = NULL;
    if (wf_cfg_map_opt(map, row->key, &sec, err)) return WF_EINPUT;
    if (!sec && (row->flags & WF_KEY_REQUIRED)) return wf_cfg_missing(map, row->key, row->need, err);
    if (!sec) return set_default(map, row, target, env, err);
    if (wf_keys_read(sec, row->sub, WF_KEYS_FIRST, target, env, err)) return WF_EINPUT;
    return row->hook ? row->hook(map, row, target, env, err) : 0;
}

static int read_choice(WfCfgNode *map, const WfKeySpec *row, void *target, WfError *err)
{
    if ((row->flags & WF_KEY_REQUIRED) && !wf_cfg_child(map, row->key))
        return wf_cfg_missing(map, row->key, row->need, err);
    int v = (int)get_int(target, row);
    if (wf_cfg_enum_opt(map, row->key, row->choices, &v, err)) return WF_EINPUT;
    put_int(target, row, v);
    return 0;
}

int wf_key_read(WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err)
{
    if (row->type == WF_KEY_SECTION) return read_section(map, row, target, env, err);
    if (row->type == WF_KEY_CUSTOM) return row->hook(map, row, target, env, err);
    set_default(NULL, row, target, env, err);
    if (!map) return 0;
    int req = row->flags & WF_KEY_REQUIRED;
    switch (row->type) {
    case WF_KEY_NUMBER: {
        double lo, hi;
        wf_key_range(row, env, &lo, &hi);
        double *p = field(target, row);
        return req ? wf_cfg_double(map, row->key, lo, hi, row->unit, p, err)
                   : wf_cfg_double_opt(map, row->key, lo, hi, row->unit, p, err);
    }
    case WF_KEY_INTEGER: {
        long lo = row->min_is ? (long)bound(row->min_is, 0, env) : row->imin;
        long hi = row->max_is ? (long)bound(row->max_is, 0, env) : row->imax;
        long v = get_int(target, row);
        if (wf_cfg_long_opt(map, row->key, lo, hi, &v, err)) return WF_EINPUT;
        put_int(target, row, v);
        return 0;
    }
    case WF_KEY_BOOL: return wf_cfg_bool_opt(map, row->key, (int *)field(target, row), err);
    case WF_KEY_CHOICE: return read_choice(map, row, target, err);
    case WF_KEY_TEXT: {
        const char *s = NULL;
        if (req ? wf_cfg_string(map, row->key, &s, err) : wf_cfg_string_opt(map, row->key, &s, err)) return WF_EINPUT;
        if (!s) return 0;
        /* Refused rather than cut: a cut path (output.path) would write somewhere else than asked. */
        if (strlen(s) >= row->size) {
            char w[600], p[512];
            const WfCfgNode *c = wf_cfg_child(map, row->key);
            return wf_err(err, WF_EINPUT, "%s: %s: too long (%zu bytes; at most %zu)", wf_cfg_where(c, w, sizeof w),
                          wf_cfg_path(c, p, sizeof p), strlen(s), row->size - 1);
        }
        memcpy(field(target, row), s, strlen(s) + 1);
        return 0;
    }
    default: return 0;
    }
}

/* A key of the other boundary: its own error when it has one; otherwise it stays unread (an unknown key). */
static int other_boundary(WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err)
{
    WfCfgNode *c = wf_cfg_child(map, row->key);
    if (c && row->off_msg) {
        char w[600], p[400];
        return wf_err(err, WF_EINPUT, "%s: %s: %s", wf_cfg_where(c, w, sizeof w), wf_cfg_path(c, p, sizeof p),
                      row->off_msg);
    }
    return row->type == WF_KEY_CUSTOM ? 0 : set_default(NULL, row, target, env, err);
}

int wf_keys_read(WfCfgNode *map, const WfKeyTable *t, int pass, void *target, WfKeyEnv *env, WfError *err)
{
    for (size_t i = 0; i < t->n; i++) {
        const WfKeySpec *row = &t->keys[i];
        if ((row->flags & WF_KEY_NOREAD) || !!(row->flags & WF_KEY_LATER) != (pass == WF_KEYS_LATER)) continue;
        int rc = (row->on & env->on) ? wf_key_read(map, row, target, env, err)
                                     : other_boundary(map, row, target, env, err);
        if (rc) return rc;
    }
    return 0;
}

const WfKeySpec *wf_keys_find(const WfKeyTable *t, const char *key, int on)
{
    for (size_t i = 0; i < t->n; i++)
        if (strcmp(t->keys[i].key, key) == 0 && (t->keys[i].on & on)) return &t->keys[i];
    return NULL;
}

const WfKeyTable *wf_key_table_find(const char *name)
{
    for (size_t i = 0; wf_key_tables[i]; i++)
        if (strcmp(wf_key_tables[i]->name, name) == 0) return wf_key_tables[i];
    return NULL;
}
