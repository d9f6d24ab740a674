/* Scenario key tables: every section of a scenario file (top level, road, time, solver, fleet, ..., corridor)
 * declares its keys once, as an array of WfKeySpec: name, type, target field, default, range, unit, the boundary
 * it applies to and the text of its row in the docs. One generic reader fills a section's struct from its table
 * (defaults, type and range checks, "missing key" errors, keys of the other boundary rejected), and tools/keydoc
 * prints the markdown tables of docs/scenarios.md and docs/corridors.md from them (tools/gen-key-docs.sh). Keys whose
 * reading needs more than a type and a range (vehicle classes, driver models, lists, profiles) are `WF_KEY_CUSTOM`
 * rows: the table holds their docs and, through `hook`, the function that reads them. */
#ifndef WAVEFUEL_KEYS_H
#define WAVEFUEL_KEYS_H

#include <stddef.h>
#include "wavefuel/err.h"

struct WfCfgNode;
struct WfScenario;

typedef enum {
    WF_KEY_NUMBER,  /* double */
    WF_KEY_INTEGER, /* long (size 8) or int (size 4), by `size` */
    WF_KEY_BOOL,    /* int 0/1: true/false, yes/no */
    WF_KEY_CHOICE,  /* int: index into `choices` (an enum field) */
    WF_KEY_TEXT,    /* char[size], truncated to fit */
    WF_KEY_SECTION, /* a map read with the table `sub`; `hook` then checks it (also when absent) */
    WF_KEY_CUSTOM   /* read by `hook` alone; `sub`, when set, documents its entries */
} WfKeyType;

/* Boundaries a key applies to. */
enum { WF_ON_RING = 1, WF_ON_CORRIDOR = 2, WF_ON_BOTH = 3 };

enum {
    WF_KEY_REQUIRED = 1, /* no default: absent is an error naming `need` */
    WF_KEY_PRESET = 2,   /* no table default: the loader sets the field before the table is read */
    WF_KEY_NOREAD = 4,   /* not read by the table pass: a neighbouring row's hook reads it (docs only here) */
    WF_KEY_LATER = 8,    /* read by a second pass (wf_keys_read(..., WF_KEYS_LATER, ...)), after other sections */
    WF_KEY_NODOC = 16,   /* not a row of its section's doc table (a section with a table of its own) */
    WF_KEY_FLAT = 32     /* docs: the sub-table's rows appear in the parent's table as `key.sub` */
};

/* Ranges that depend on what was read before: the road length, the duration, the fleet size. */
typedef enum { WF_BOUND_FIXED = 0, WF_BOUND_LENGTH, WF_BOUND_NEG_LENGTH, WF_BOUND_DURATION, WF_BOUND_VEHICLES,
               WF_BOUND_LAST_VEHICLE } WfKeyBound;

/* What the reader carries through the sections. */
typedef struct WfKeyEnv {
    int                on; /* WF_ON_RING or WF_ON_CORRIDOR: set by road.type */
    struct WfScenario *sc; /* the scenario being read: dynamic bounds, hooks */
} WfKeyEnv;

typedef struct WfKeySpec WfKeySpec;
/* map: the map holding the row's key (for SECTION hooks too; the section node is wf_cfg_child(map, key), NULL
 * when absent). target: the struct the table's offsets refer to. */
typedef int (*WfKeyHook)(struct WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err);

typedef struct WfKeyTable {
    const char      *name; /* section path as in docs: "road", "fleet.drivers[i]" */
    const WfKeySpec *keys;
    size_t           n;
} WfKeyTable;

struct WfKeySpec {
    const char        *key;
    WfKeyType          type;
    int                on;      /* WF_ON_* */
    int                flags;   /* WF_KEY_* */
    size_t             offset;  /* offsetof(target struct, field) */
    size_t             size;    /* INTEGER: sizeof the field; TEXT: the buffer size */
    double             def;     /* NUMBER, INTEGER, BOOL, CHOICE: default (not with REQUIRED or PRESET) */
    double             min, max;        /* NUMBER: closed range; INTEGER: see imin, imax */
    WfKeyBound         min_is, max_is;  /* dynamic bounds replace min / max */
    long               imin, imax;      /* INTEGER range */
    const char        *unit;            /* NUMBER: unit text of error messages ("m/s^2", "(count)") */
    const char *const *choices;         /* CHOICE: NULL-terminated */
    const WfKeyTable  *sub;             /* SECTION: its keys; CUSTOM: the keys of each entry (docs) */
    WfKeyHook          hook;            /* CUSTOM: the reader; SECTION: a check after reading (may be NULL) */
    const char        *need;            /* REQUIRED: what a missing key should be ("a section") */
    const char        *off_msg;         /* present on the other boundary: this error, else an unknown key */
    /* The row in the docs; NULL: derived from type, unit, default and range. */
    const char *doc_type, *doc_default, *doc_range;
    const char *doc; /* meaning */
};

/* Passes of wf_keys_read. */
enum { WF_KEYS_FIRST = 0, WF_KEYS_LATER = 1 };

/* Read every row of `t` that applies to env->on from `map` (NULL: the section is absent, defaults only) into
 * `target`, in table order, so errors and suggestions follow the table. pass WF_KEYS_LATER reads only the rows
 * flagged WF_KEY_LATER. Errors name file:line: path and the allowed values or range. */
int wf_keys_read(struct WfCfgNode *map, const WfKeyTable *t, int pass, void *target, WfKeyEnv *env, WfError *err);
/* Read one row (what a hook uses for keys it reads conditionally). */
int wf_key_read(struct WfCfgNode *map, const WfKeySpec *row, void *target, WfKeyEnv *env, WfError *err);
/* Row of a table by key and boundary (first match); NULL if none. */
const WfKeySpec *wf_keys_find(const WfKeyTable *t, const char *key, int on);
/* Resolved range of a NUMBER row (dynamic bounds from env->sc). */
void wf_key_range(const WfKeySpec *row, const WfKeyEnv *env, double *min, double *max);

/* Every section table of a scenario, for the docs: NULL-terminated. */
extern const WfKeyTable *const wf_key_tables[];
const WfKeyTable *wf_key_table_find(const char *name);

#endif
