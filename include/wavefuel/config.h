/* Configuration trees: a YAML file read by libyaml into a small tree of maps, sequences and scalars, each
 * node remembering its file and line, so every error can name file, line and key. Command-line overrides
 * (--set a.b[2].c=value) edit the tree before it is read. Typed getters parse strictly and mark the
 * nodes they consume; wf_cfg_check_unused() then rejects every key nobody read, with a suggestion. */
#ifndef WAVEFUEL_CONFIG_H
#define WAVEFUEL_CONFIG_H

#include <stddef.h>
#include "wavefuel/err.h"
#include "wavefuel/param.h"

typedef enum { WF_CFG_SCALAR, WF_CFG_MAP, WF_CFG_SEQ } WfCfgKind;

typedef struct WfCfgNode WfCfgNode;
struct WfCfgNode {
    WfCfgKind   kind;
    char       *key;      /* key in the parent map; NULL for sequence items and the root */
    char       *value;    /* scalar text; NULL for maps and sequences */
    int         line;     /* 1-based line in `file`; 0 for values from --set */
    const char *file;     /* borrowed from the WfCfg: the path, or "--set" */
    int         used;     /* set by getters; unread keys are errors */
    WfCfgNode  *parent;
    WfCfgNode **child;    /* map entries in file order, or sequence items */
    size_t      n_child;
    size_t      cap_child;
    const char **asked;   /* keys a getter looked up in this map (string literals): suggestions */
    size_t      n_asked, cap_asked;
};

typedef struct WfCfg {
    WfCfgNode *root;      /* a map */
    char      *path;      /* owned copy of the file path */
    char      *text;      /* the file's text verbatim, for provenance (written to /meta) */
    size_t     text_len;
} WfCfg;

/* Parse a YAML file (a mapping at the top). Errors name the file and libyaml's line and reason. Ownership (both
 * loaders): *out is the caller's until wf_cfg_destroy(), which frees every node; text is copied. */
int wf_cfg_load_file(const char *path, WfCfg **out, WfError *err);
/* Parse YAML text held in memory; `name` is used in messages. */
int wf_cfg_load_string(const char *name, const char *text, size_t len, WfCfg **out, WfError *err);
void wf_cfg_destroy(WfCfg **cfg);

/* Apply "a.b.c=value" or "a.list[2].c=value": replaces a scalar, or creates the missing maps on the way
 * (a new key must then be known to the reader, or wf_cfg_check_unused() rejects it). */
int wf_cfg_set(WfCfg *cfg, const char *assignment, WfError *err);

/* Child of a map by key, or NULL; does not mark it used. */
WfCfgNode *wf_cfg_child(const WfCfgNode *map, const char *key);
/* "file:line" of a node, into buf. */
const char *wf_cfg_where(const WfCfgNode *n, char *buf, size_t len);
/* Dotted path of a node ("fleet.drivers[1].params.T_s"), into buf. */
const char *wf_cfg_path(const WfCfgNode *n, char *buf, size_t len);

/* Typed getters on a map's key. Absent: *_opt return 0 and leave *out unchanged; the plain forms
 * fail naming the missing key. Present but malformed or out of range: error with file:line: path. */
int wf_cfg_double(WfCfgNode *map, const char *key, double min, double max, const char *unit, double *out,
                  WfError *err);
int wf_cfg_double_opt(WfCfgNode *map, const char *key, double min, double max, const char *unit, double *out,
                      WfError *err);
int wf_cfg_long_opt(WfCfgNode *map, const char *key, long min, long max, long *out, WfError *err);
int wf_cfg_string(WfCfgNode *map, const char *key, const char **out, WfError *err);
int wf_cfg_string_opt(WfCfgNode *map, const char *key, const char **out, WfError *err);
int wf_cfg_bool_opt(WfCfgNode *map, const char *key, int *out, WfError *err);
/* One of `choices` (NULL-terminated); *out is the index. */
int wf_cfg_enum_opt(WfCfgNode *map, const char *key, const char *const *choices, int *out, WfError *err);
/* A child that must be a map / a sequence; *out NULL when absent (the _opt forms). */
int wf_cfg_map_opt(WfCfgNode *map, const char *key, WfCfgNode **out, WfError *err);
int wf_cfg_seq_opt(WfCfgNode *map, const char *key, WfCfgNode **out, WfError *err);
/* A scalar node's value as a number (for sequence items). */
int wf_cfg_node_double(WfCfgNode *n, double min, double max, const char *unit, double *out, WfError *err);

/* Fill a model's parameters from a map using its spec table: defaults first, then each key present,
 * range-checked; keys not in the spec are left unread (so check_unused reports them). */
int wf_cfg_params(WfCfgNode *map, const WfParamSpec *spec, size_t n, void *params, WfError *err);

/* Every key in the tree that no getter read is an error: "file:line: unknown key 'T' in fleet.drivers[0]
 * (did you mean 'T_s'?)"; suggestions come from the keys the readers asked that map for. */
int wf_cfg_check_unused(const WfCfg *cfg, WfError *err);
/* The error for a required key that is absent from `map`: names the file and map, and when an unread key a typo
 * away is present, reports that key as unknown with the suggestion instead (the typo is the real cause). */
int wf_cfg_missing(WfCfgNode *map, const char *key, const char *what, WfError *err);
/* Mark a subtree used (for sections that are parsed elsewhere). */
void wf_cfg_mark_used(WfCfgNode *n);

#endif
