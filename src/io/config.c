/* YAML configuration trees built from libyaml's event stream, with file:line on every node, --set
 * overrides, strict typed getters and detection of unknown keys. */
#include "wavefuel/config.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <yaml.h>

#include "util/numfmt.h"
#include "util/mem.h"
#include "util/registry.h"

static WfCfgNode *node_new(WfCfgKind kind, const char *file, int line)
{
    WfCfgNode *n = calloc(1, sizeof *n);
    if (!n) return NULL;
    n->kind = kind;
    n->file = file;
    n->line = line;
    return n;
}

static void node_free(WfCfgNode *n)
{
    if (!n) return;
    for (size_t i = 0; i < n->n_child; i++) node_free(n->child[i]);
    WF_FREE(n->child, n->asked, n->key, n->value, n);
}

static int node_add(WfCfgNode *parent, WfCfgNode *c)
{
    if (parent->n_child == parent->cap_child) {
        size_t cap = parent->cap_child ? 2 * parent->cap_child : 4;
        WfCfgNode **p = realloc(parent->child, cap * sizeof *p);
        if (!p) return -1;
        parent->child = p;
        parent->cap_child = cap;
    }
    parent->child[parent->n_child++] = c;
    c->parent = parent;
    return 0;
}

static void note_asked(WfCfgNode *map, const char *key)
{
    for (size_t i = 0; i < map->n_asked; i++)
        if (map->asked[i] == key || strcmp(map->asked[i], key) == 0) return;
    if (map->n_asked == map->cap_asked) {
        size_t cap = map->cap_asked ? 2 * map->cap_asked : 8;
        const char **p = realloc(map->asked, cap * sizeof *p);
        if (!p) return; /* suggestions are a convenience: losing one is harmless */
        map->asked = p;
        map->cap_asked = cap;
    }
    map->asked[map->n_asked++] = key;
}

void wf_cfg_destroy(WfCfg **cfg)
{
    if (!cfg || !*cfg) return;
    node_free((*cfg)->root);
    WF_FREE((*cfg)->path, (*cfg)->text, *cfg);
    *cfg = NULL;
}

/* Builds the tree from events. The parser is recursive over nesting depth, which is bounded to keep
 * hostile input from exhausting the stack; the node count is bounded too (each node costs ~150 bytes, so a
 * 64 MiB file of "1," would otherwise take gigabytes). Long tables belong in CSV files. */
enum { MAX_DEPTH = 64, MAX_NODES = 1000000 };

typedef struct Builder {
    yaml_parser_t parser;
    const char   *file;
    WfError      *err;
    size_t        n_nodes;
} Builder;

/* Duplicate keys of a finished map, found by sorting (a linear search per key made a map of n keys cost n^2
 * string compares: minutes for a hostile file). Reports the first key, in file order, that repeats an
 * earlier one, as the search did. */
typedef struct KeyRef {
    const WfCfgNode *node;
    size_t           order;
} KeyRef;

static int by_key_then_order(const void *pa, const void *pb)
{
    const KeyRef *a = pa, *b = pb;
    int c = strcmp(a->node->key, b->node->key);
    return c ? c : (a->order > b->order) - (a->order < b->order);
}

static int check_duplicate_keys(Builder *b, const WfCfgNode *map)
{
    if (map->n_child < 2) return 0;
    KeyRef *k = malloc(map->n_child * sizeof *k);
    if (!k) return wf_err(b->err, WF_ESYS, "out of memory");
    for (size_t i = 0; i < map->n_child; i++) k[i].node = map->child[i], k[i].order = i;
    qsort(k, map->n_child, sizeof *k, by_key_then_order);
    const WfCfgNode *dup = NULL;
    size_t dup_order = (size_t)-1;
    for (size_t i = 1; i < map->n_child; i++)
        if (strcmp(k[i].node->key, k[i - 1].node->key) == 0 && k[i].order < dup_order)
            dup = k[i].node, dup_order = k[i].order;
    free(k);
    if (!dup) return 0;
    return wf_err(b->err, WF_EINPUT, "%s:%d: key '%s' appears twice", b->file, dup->line, dup->key);
}

static int parse_node(Builder *b, yaml_event_t *ev, WfCfgNode **out, int depth);

static int yaml_fail(Builder *b)
{
    const char *what = b->parser.problem ? b->parser.problem : "invalid YAML";
    int line = (int)b->parser.problem_mark.line + 1;
    return wf_err(b->err, WF_EINPUT, "%s:%d: YAML syntax error: %s%s%s", b->file, line, what,
                  b->parser.context ? " " : "", b->parser.context ? b->parser.context : "");
}

static int next_event(Builder *b, yaml_event_t *ev)
{
    if (!yaml_parser_parse(&b->parser, ev)) return yaml_fail(b);
    return 0;
}

/* The next event's type and line; the event itself is dropped. */
static int skip_event(Builder *b, yaml_event_type_t *type, int *line)
{
    yaml_event_t ev;
    if (next_event(b, &ev)) return WF_EINPUT;
    *type = ev.type;
    *line = (int)ev.start_mark.line + 1;
    yaml_event_delete(&ev);
    return 0;
}

/* A double-quoted YAML scalar may hold "\0": strdup() would silently cut the text there ("230\0junk" read
 * as 230), so such keys and values are rejected. `what` names the key (or "a list item"). */
static int scalar_has_nul(Builder *b, const yaml_event_t *ev, const char *what)
{
    if (ev->type != YAML_SCALAR_EVENT || !memchr(ev->data.scalar.value, '\0', ev->data.scalar.length)) return 0;
    return wf_err(b->err, WF_EINPUT, "%s:%d: %s: contains a NUL character (\\0): not allowed in a key or value",
                  b->file, (int)ev->start_mark.line + 1, what);
}

static int parse_children(Builder *b, WfCfgNode *n, int depth)
{
    for (;;) {
        yaml_event_t ev;
        if (next_event(b, &ev)) return WF_EINPUT;
        if (ev.type == YAML_MAPPING_END_EVENT || ev.type == YAML_SEQUENCE_END_EVENT) {
            yaml_event_delete(&ev);
            return n->kind == WF_CFG_MAP ? check_duplicate_keys(b, n) : 0;
        }
        char *key = NULL;
        int key_line = (int)ev.start_mark.line + 1;
        if (n->kind == WF_CFG_MAP) {
            if (ev.type != YAML_SCALAR_EVENT) {
                yaml_event_delete(&ev);
                return wf_err(b->err, WF_EINPUT, "%s:%d: map keys must be plain words", b->file, key_line);
            }
            if (scalar_has_nul(b, &ev, "a key")) {
                yaml_event_delete(&ev);
                return WF_EINPUT;
            }
            key = strdup((const char *)ev.data.scalar.value);
            yaml_event_delete(&ev);
            if (!key) return wf_err(b->err, WF_ESYS, "out of memory");
            if (next_event(b, &ev)) {
                free(key);
                return WF_EINPUT;
            }
        }
        if (scalar_has_nul(b, &ev, key ? key : "a list item")) {
            yaml_event_delete(&ev);
            free(key);
            return WF_EINPUT;
        }
        WfCfgNode *c = NULL;
        int rc = parse_node(b, &ev, &c, depth + 1);
        if (rc) {
            free(key);
            return rc;
        }
        c->key = key;
        if (key) c->line = key_line;
        if (node_add(n, c)) {
            node_free(c);
            return wf_err(b->err, WF_ESYS, "out of memory");
        }
    }
}

/* Consumes `ev` (already parsed) and everything nested in it. */
static int parse_node(Builder *b, yaml_event_t *ev, WfCfgNode **out, int depth)
{
    int line = (int)ev->start_mark.line + 1;
    if (depth > MAX_DEPTH) {
        yaml_event_delete(ev);
        return wf_err(b->err, WF_EINPUT, "%s:%d: nesting deeper than %d levels", b->file, line, MAX_DEPTH);
    }
    if (++b->n_nodes > MAX_NODES) {
        yaml_event_delete(ev);
        return wf_err(b->err, WF_EINPUT, "%s:%d: more than %d values: not a configuration file (long tables "
                      "belong in CSV files)", b->file, line, MAX_NODES);
    }
    WfCfgNode *n = NULL;
    switch (ev->type) {
    case YAML_SCALAR_EVENT:
        n = node_new(WF_CFG_SCALAR, b->file, line);
        if (n) n->value = strdup((const char *)ev->data.scalar.value);
        yaml_event_delete(ev);
        if (!n || !n->value) {
            node_free(n);
            return wf_err(b->err, WF_ESYS, "out of memory");
        }
        *out = n;
        return 0;
    case YAML_MAPPING_START_EVENT:
    case YAML_SEQUENCE_START_EVENT:
        n = node_new(ev->type == YAML_MAPPING_START_EVENT ? WF_CFG_MAP : WF_CFG_SEQ, b->file, line);
        yaml_event_delete(ev);
        if (!n) return wf_err(b->err, WF_ESYS, "out of memory");
        if (parse_children(b, n, depth)) {
            node_free(n);
            return b->err ? b->err->code : WF_EINPUT;
        }
        *out = n;
        return 0;
    case YAML_ALIAS_EVENT:
        yaml_event_delete(ev);
        return wf_err(b->err, WF_EINPUT, "%s:%d: YAML aliases (*name) are not supported: write the value out",
                      b->file, line);
    default:
        yaml_event_delete(ev);
        return wf_err(b->err, WF_EINPUT, "%s:%d: unexpected YAML structure", b->file, line);
    }
}

int wf_cfg_load_string(const char *name, const char *text, size_t len, WfCfg **out, WfError *err)
{
    *out = NULL;
    WfCfg *cfg = calloc(1, sizeof *cfg);
    if (!cfg) return wf_err(err, WF_ESYS, "out of memory");
    cfg->path = strdup(name);
    cfg->text = malloc(len + 1);
    if (!cfg->path || !cfg->text) {
        wf_cfg_destroy(&cfg);
        return wf_err(err, WF_ESYS, "out of memory");
    }
    memcpy(cfg->text, text, len);
    cfg->text[len] = '\0';
    cfg->text_len = len;
    if (memchr(text, '\0', len)) {
        wf_cfg_destroy(&cfg);
        return wf_err(err, WF_EINPUT, "%s: contains a NUL byte: not a text file", name);
    }

    Builder b = {.file = cfg->path, .err = err};
    if (!yaml_parser_initialize(&b.parser)) {
        wf_cfg_destroy(&cfg);
        return wf_err(err, WF_ESYS, "libyaml: cannot initialise parser");
    }
    yaml_parser_set_input_string(&b.parser, (const unsigned char *)cfg->text, len);
    /* The stream's start, a document's start (or the stream's end: an empty file), the root map, the document's
     * end and the stream's end (anything else: a second document). */
    yaml_event_type_t type = YAML_NO_EVENT;
    yaml_event_t ev = {0};
    int line = 0, rc = skip_event(&b, &type, &line);
    if (!rc) rc = skip_event(&b, &type, &line);
    if (!rc && type == YAML_STREAM_END_EVENT)
        rc = wf_err(err, WF_EINPUT, "%s: empty file: expected a YAML mapping of keys", name);
    if (!rc) rc = next_event(&b, &ev);
    if (!rc && ev.type != YAML_MAPPING_START_EVENT) {
        line = (int)ev.start_mark.line + 1;
        yaml_event_delete(&ev);
        rc = wf_err(err, WF_EINPUT, "%s:%d: expected a YAML mapping (key: value lines) at the top", name, line);
    } else if (!rc) {
        rc = parse_node(&b, &ev, &cfg->root, 0);
    }
    if (!rc) rc = skip_event(&b, &type, &line);
    if (!rc) rc = skip_event(&b, &type, &line);
    if (!rc && type != YAML_STREAM_END_EVENT)
        rc = wf_err(err, WF_EINPUT, "%s:%d: more than one YAML document in the file", name, line);
    yaml_parser_delete(&b.parser);
    if (rc) {
        wf_cfg_destroy(&cfg);
        return rc;
    }
    *out = cfg;
    return 0;
}

int wf_cfg_load_file(const char *path, WfCfg **out, WfError *err)
{
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) return wf_err(err, WF_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    /* fopen() succeeds on a directory and the first read fails with EISDIR: name the user's mistake (exit 2)
     * instead of reporting a read error (exit 1). */
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
        fclose(f);
        return wf_err(err, WF_EINPUT, "%s: is a directory, not a file", path);
    }
    char *buf = NULL;
    size_t len = 0, cap = 0;
    for (;;) {
        if (len + 4096 > cap) {
            cap = cap ? 2 * cap : 16384;
            if (cap > (64u << 20)) {
                free(buf);
                fclose(f);
                return wf_err(err, WF_EINPUT, "%s: larger than 64 MiB: not a configuration file", path);
            }
            char *p = realloc(buf, cap);
            if (!p) {
                free(buf);
                fclose(f);
                return wf_err(err, WF_ESYS, "out of memory");
            }
            buf = p;
        }
        size_t got = fread(buf + len, 1, cap - len, f);
        len += got;
        if (got == 0) break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        return wf_err(err, WF_ESYS, "%s: read error", path);
    }
    int rc = wf_cfg_load_string(path, buf ? buf : "", len, out, err);
    free(buf);
    return rc;
}

WfCfgNode *wf_cfg_child(const WfCfgNode *map, const char *key)
{
    if (!map || map->kind != WF_CFG_MAP) return NULL;
    for (size_t i = 0; i < map->n_child; i++)
        if (strcmp(map->child[i]->key, key) == 0) return map->child[i];
    return NULL;
}

const char *wf_cfg_where(const WfCfgNode *n, char *buf, size_t len)
{
    if (n->line > 0)
        snprintf(buf, len, "%s:%d", n->file, n->line);
    else
        snprintf(buf, len, "%s", n->file);
    return buf;
}

const char *wf_cfg_path(const WfCfgNode *n, char *buf, size_t len)
{
    const WfCfgNode *chain[MAX_DEPTH + 2];
    size_t depth = 0;
    for (const WfCfgNode *p = n; p && p->parent && depth < MAX_DEPTH + 2; p = p->parent) chain[depth++] = p;
    size_t used = 0;
    buf[0] = '\0';
    while (depth-- > 0) {
        const WfCfgNode *c = chain[depth];
        int w;
        if (c->key)
            w = snprintf(buf + used, len - used, "%s%s", used ? "." : "", c->key);
        else {
            size_t idx = 0;
            while (idx < c->parent->n_child && c->parent->child[idx] != c) idx++;
            w = snprintf(buf + used, len - used, "[%zu]", idx);
        }
        if (w < 0 || (size_t)w >= len - used) break;
        used += (size_t)w;
    }
    return buf;
}

/* --set: walk "a.b[2].c", creating maps for missing keys; the last component gets a scalar. */
int wf_cfg_set(WfCfg *cfg, const char *assignment, WfError *err)
{
    const char *eq = strchr(assignment, '=');
    if (!eq || eq == assignment)
        return wf_err(err, WF_EINPUT, "--set %s: expected key.path=value", assignment);
    char path[512];
    size_t plen = (size_t)(eq - assignment);
    if (plen >= sizeof path) return wf_err(err, WF_EINPUT, "--set: key path too long");
    memcpy(path, assignment, plen);
    path[plen] = '\0';
    const char *value = eq + 1;

    WfCfgNode *cur = cfg->root;
    /* Split at every '.' by hand: strtok_r would skip empty components and accept "fleet..vehicles=3". */
    for (char *tok = path, *next = NULL; tok; tok = next) {
        char *dot = strchr(tok, '.');
        next = dot ? dot + 1 : NULL;
        if (dot) *dot = '\0';
        char *br = strchr(tok, '[');
        long idx = -1;
        if (br) {
            char *close = strchr(br, ']');
            if (!close || close[1] != '\0')
                return wf_err(err, WF_EINPUT, "--set %s: malformed index in '%s'", assignment, tok);
            *close = '\0';
            if (wf_parse_long(br + 1, 0, 1000000, &idx))
                return wf_err(err, WF_EINPUT, "--set %s: index must be a non-negative integer", assignment);
            *br = '\0';
        }
        if (!*tok) return wf_err(err, WF_EINPUT, "--set %s: empty key", assignment);
        if (cur->kind != WF_CFG_MAP)
            return wf_err(err, WF_EINPUT, "--set %s: '%s' is inside a value that is not a map", assignment, tok);
        int last = next == NULL && idx < 0;
        WfCfgNode *c = wf_cfg_child(cur, tok);
        if (!c) {
            if (idx >= 0)
                return wf_err(err, WF_EINPUT, "--set %s: '%s' is not a list in the scenario", assignment, tok);
            c = node_new(last ? WF_CFG_SCALAR : WF_CFG_MAP, "--set", 0);
            if (!c || !(c->key = strdup(tok)) || node_add(cur, c)) {
                node_free(c);
                return wf_err(err, WF_ESYS, "out of memory");
            }
        }
        if (idx >= 0) {
            if (c->kind != WF_CFG_SEQ)
                return wf_err(err, WF_EINPUT, "--set %s: '%s' is not a list", assignment, tok);
            if ((size_t)idx >= c->n_child)
                return wf_err(err, WF_EINPUT, "--set %s: '%s' has %zu items (index %ld)", assignment, tok,
                              c->n_child, idx);
            c = c->child[idx];
        }
        cur = c;
    }
    if (cur->kind != WF_CFG_SCALAR)
        return wf_err(err, WF_EINPUT, "--set %s: this key holds a map or list, not a single value", assignment);
    char *v = strdup(value);
    if (!v) return wf_err(err, WF_ESYS, "out of memory");
    free(cur->value);
    cur->value = v;
    cur->file = "--set";
    cur->line = 0;
    return 0;
}

static int bad_value(const WfCfgNode *n, const char *what, WfError *err)
{
    char where[600], path[512];
    return wf_err(err, WF_EINPUT, "%s: %s: expected %s (got '%s')", wf_cfg_where(n, where, sizeof where),
                  wf_cfg_path(n, path, sizeof path), what, n->kind == WF_CFG_SCALAR ? n->value : "a map or list");
}

static WfCfgNode *lookup(WfCfgNode *map, const char *key)
{
    if (!map || map->kind != WF_CFG_MAP) return NULL;
    note_asked(map, key);
    WfCfgNode *c = wf_cfg_child(map, key);
    if (c) c->used = 1;
    return c;
}

int wf_cfg_missing(WfCfgNode *map, const char *key, const char *what, WfError *err)
{
    note_asked(map, key);
    char where[600], path[512];
    /* A required key that is absent next to an unread key a typo away: report the typo, which is the cause. */
    size_t len = strlen(key);
    for (size_t i = 0; i < map->n_child; i++) {
        WfCfgNode *c = map->child[i];
        if (!c->used && c->key && wf_edit_distance(c->key, key) <= (len < 4 ? 1 : len / 3 + 1))
            return wf_err(err, WF_EINPUT, "%s: unknown key '%s' (did you mean '%s'?)", wf_cfg_where(c, where, sizeof where),
                          wf_cfg_path(c, path, sizeof path), key);
    }
    const char *p = map->parent ? wf_cfg_path(map, path, sizeof path) : "the top level";
    return wf_err(err, WF_EINPUT, "%s: missing key '%s' in %s (%s)", wf_cfg_where(map, where, sizeof where), key, p,
                  what);
}

int wf_cfg_node_double(WfCfgNode *n, double min, double max, const char *unit, double *out, WfError *err)
{
    double v;
    char what[160];
    n->used = 1;
    snprintf(what, sizeof what, "a number in [%s, %s] %s", WF_NUM(min), WF_NUM(max), unit);
    if (n->kind != WF_CFG_SCALAR || wf_parse_double(n->value, &v) || v < min || v > max)
        return bad_value(n, what, err);
    *out = v;
    return 0;
}

int wf_cfg_double_opt(WfCfgNode *map, const char *key, double min, double max, const char *unit, double *out,
                      WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    return c ? wf_cfg_node_double(c, min, max, unit, out, err) : 0;
}

int wf_cfg_double(WfCfgNode *map, const char *key, double min, double max, const char *unit, double *out,
                  WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    if (!c) {
        char what[160];
        snprintf(what, sizeof what, "a number in [%s, %s] %s", WF_NUM(min), WF_NUM(max), unit);
        return wf_cfg_missing(map, key, what, err);
    }
    return wf_cfg_node_double(c, min, max, unit, out, err);
}

int wf_cfg_long_opt(WfCfgNode *map, const char *key, long min, long max, long *out, WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    if (!c) return 0;
    long v;
    char what[128];
    snprintf(what, sizeof what, "an integer in [%ld, %ld]", min, max);
    if (c->kind != WF_CFG_SCALAR || wf_parse_long(c->value, min, max, &v)) return bad_value(c, what, err);
    *out = v;
    return 0;
}

int wf_cfg_string_opt(WfCfgNode *map, const char *key, const char **out, WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    if (!c) return 0;
    if (c->kind != WF_CFG_SCALAR || !c->value[0]) return bad_value(c, "a non-empty text value", err);
    *out = c->value;
    return 0;
}

int wf_cfg_string(WfCfgNode *map, const char *key, const char **out, WfError *err)
{
    if (!wf_cfg_child(map, key)) {
        note_asked(map, key);
        return wf_cfg_missing(map, key, "a text value", err);
    }
    return wf_cfg_string_opt(map, key, out, err);
}

int wf_cfg_bool_opt(WfCfgNode *map, const char *key, int *out, WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    if (!c) return 0;
    if (c->kind == WF_CFG_SCALAR && (!strcmp(c->value, "true") || !strcmp(c->value, "yes"))) *out = 1;
    else if (c->kind == WF_CFG_SCALAR && (!strcmp(c->value, "false") || !strcmp(c->value, "no"))) *out = 0;
    else return bad_value(c, "true or false", err);
    return 0;
}

int wf_cfg_enum_opt(WfCfgNode *map, const char *key, const char *const *choices, int *out, WfError *err)
{
    WfCfgNode *c = lookup(map, key);
    if (!c) return 0;
    const void *const *items = (const void *const *)choices;
    long i = c->kind == WF_CFG_SCALAR ? wf_registry_find(items, WF_REG_STRINGS, c->value, "", NULL) : -1;
    if (i >= 0) {
        *out = (int)i;
        return 0;
    }
    char names[1024], what[1040];
    snprintf(what, sizeof what, "one of %s", wf_registry_names(items, WF_REG_STRINGS, names, sizeof names));
    return bad_value(c, what, err);
}

static int container_opt(WfCfgNode *map, const char *key, WfCfgKind kind, WfCfgNode **out, WfError *err)
{
    *out = NULL;
    WfCfgNode *c = lookup(map, key);
    if (!c) return 0;
    if (c->kind != kind) return bad_value(c, kind == WF_CFG_MAP ? "a map of keys" : "a list", err);
    *out = c;
    return 0;
}

int wf_cfg_map_opt(WfCfgNode *map, const char *key, WfCfgNode **out, WfError *err)
{
    return container_opt(map, key, WF_CFG_MAP, out, err);
}

int wf_cfg_seq_opt(WfCfgNode *map, const char *key, WfCfgNode **out, WfError *err)
{
    return container_opt(map, key, WF_CFG_SEQ, out, err);
}

int wf_cfg_params(WfCfgNode *map, const WfParamSpec *spec, size_t n, void *params, WfError *err)
{
    wf_param_defaults(spec, n, params);
    if (!map) return 0;
    for (size_t i = 0; i < n; i++) {
        double v;
        WfCfgNode *c = lookup(map, spec[i].key);
        if (!c) continue;
        if (wf_cfg_node_double(c, spec[i].min, spec[i].max, spec[i].unit, &v, err)) return WF_EINPUT;
        *wf_param_ptr(params, &spec[i]) = v;
    }
    return 0;
}

void wf_cfg_mark_used(WfCfgNode *n)
{
    n->used = 1;
    for (size_t i = 0; i < n->n_child; i++) wf_cfg_mark_used(n->child[i]);
}

static int check_node(const WfCfgNode *n, WfError *err)
{
    for (size_t i = 0; i < n->n_child; i++) {
        const WfCfgNode *c = n->child[i];
        if (!c->used) {
            char where[600], path[512];
            const char *best = NULL;
            size_t best_d = (size_t)-1;
            for (size_t k = 0; c->key && k < n->n_asked; k++) {
                size_t d = wf_edit_distance(c->key, n->asked[k]);
                if (d < best_d) best_d = d, best = n->asked[k];
            }
            size_t len = c->key ? strlen(c->key) : 0;
            int close = best && best_d <= (len < 4 ? 2 : len / 2 + 1);
            return wf_err(err, WF_EINPUT, "%s: unknown key '%s'%s%s%s", wf_cfg_where(c, where, sizeof where),
                          c->key ? wf_cfg_path(c, path, sizeof path) : "(list item)", close ? " (did you mean '" : "",
                          close ? best : "", close ? "'?)" : "");
        }
        if (check_node(c, err)) return WF_EINPUT;
    }
    return 0;
}

int wf_cfg_check_unused(const WfCfg *cfg, WfError *err)
{
    return check_node(cfg->root, err);
}
