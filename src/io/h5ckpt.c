/* Checkpoint files (FILE.h5.ckpt) shared by the ring and corridor result writers: atomic replacement (write a
 * temporary file, rename it), the checksum that tells a damaged checkpoint from a good one, the checks that a
 * checkpoint and a partial result belong to the run being resumed, and the series' rows: counted by cursors,
 * the pending rows of appended datasets saved with the state. Layout: src/io/h5ckpt.h. */
#include "io/h5ckpt.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "util/hash.h"

#define CKPT_PATH_MAX 1100

/* FILE.h5.ckpt and FILE.h5.ckpt.tmp of a result path. */
static int ckpt_paths(const char *result, char *ck, char *tmp, WfError *err)
{
    int a = snprintf(ck, CKPT_PATH_MAX, "%s.ckpt", result);
    int b = snprintf(tmp, CKPT_PATH_MAX, "%s.ckpt.tmp", result);
    if (a < 0 || a >= CKPT_PATH_MAX || b < 0 || b >= CKPT_PATH_MAX)
        return wf_err(err, WF_EINPUT, "result path too long for a checkpoint: %s", result);
    return 0;
}

/* A cursor: its name and the rows appended to its datasets. */
typedef struct WfCkptCursor {
    const char *name;
    int64_t     rows;
} WfCkptCursor;

/* FNV-1a over everything a checkpoint restores, in a fixed order; strings with their terminating NUL so that
 * moving bytes from one field to the next changes the sum. The head, then each block: its name, size and bytes. */
static uint64_t checksum_head(const char *kind, const WfScenario *sc, int64_t steps_done, const WfCkptCursor *cur,
                              size_t n_cur)
{
    uint64_t h = WF_FNV1A64_INIT;
    h = wf_fnv1a64(h, kind, strlen(kind) + 1);
    h = wf_fnv1a64(h, sc->text, strlen(sc->text) + 1);
    h = wf_fnv1a64(h, sc->overrides, strlen(sc->overrides) + 1);
    h = wf_fnv1a64(h, &steps_done, sizeof steps_done);
    for (size_t i = 0; i < n_cur; i++) {
        h = wf_fnv1a64(h, cur[i].name, strlen(cur[i].name) + 1);
        h = wf_fnv1a64(h, &cur[i].rows, sizeof cur[i].rows);
    }
    return h;
}

static uint64_t checksum_block(uint64_t h, const WfStateVar *v)
{
    uint64_t size = v->size;
    h = wf_fnv1a64(h, v->name, strlen(v->name) + 1);
    return wf_fnv1a64(h, &size, sizeof size);
}

static int cursor_attr(const char *name, char *out, size_t len, WfError *err)
{
    int w = snprintf(out, len, "rows_%s", name);
    return w < 0 || (size_t)w >= len ? wf_err(err, WF_ESYS, "checkpoint cursor name too long: %s", name) : 0;
}

int wf_ckpt_series_create(hid_t fid, const WfCkptSeries *sp, size_t n, WfError *err)
{
    int rc = 0;
    for (size_t i = 0; !rc && i < n; i++) {
        hid_t g = H5Gopen2(fid, sp[i].group, H5P_DEFAULT);
        if (g < 0) return wf_err(err, WF_ESYS, "HDF5: no group '%s'", sp[i].group);
        rc = wf_h5_series_create(g, sp[i].col->name, sp[i].cols, sp[i].fixed_rows, sp[i].chunk_rows, sp[i].compress,
                                 sp[i].col->units, sp[i].col->desc, sp[i].s, err);
        H5Gclose(g);
    }
    return rc;
}

/* The series' rows still in memory, as state blocks after the engine's n_vars (vars has WF_MAX_STATE_VARS). */
static int pending_blocks(const WfCkptSeries *sp, size_t ns, WfStateVar *vars, size_t *n_vars, WfError *err)
{
    if (*n_vars > WF_MAX_STATE_VARS)
        return wf_err(err, WF_ESYS, "checkpoint: the engine has %zu state blocks, at most %d", *n_vars,
                      WF_MAX_STATE_VARS);
    for (size_t i = 0; i < ns; i++) {
        const WfH5Series *s = sp[i].s;
        if (!s->pend) continue;
        if (*n_vars >= WF_MAX_STATE_VARS)
            return wf_err(err, WF_ESYS, "checkpoint: more than %d state blocks", WF_MAX_STATE_VARS);
        vars[(*n_vars)++] = (WfStateVar){.name = s->block, .data = s->pend,
                                         .size = s->n_pend * (s->cols ? s->cols : 1) * sizeof *s->pend};
    }
    return 0;
}

/* The blocks being saved: the dataset of the block being written (its pieces come in order) and the running
 * checksum, which covers each block's name, size and bytes as it is written. */
typedef struct SaveBlocks {
    hid_t             g, d;
    const WfStateVar *vars;
    size_t            open;
    uint64_t          h;
} SaveBlocks;

static int save_piece(void *ctx, size_t j, size_t lo, size_t hi, WfError *err)
{
    SaveBlocks *sb = ctx;
    const WfStateVar *v = &sb->vars[j];
    if (sb->d < 0 || sb->open != j) {
        if (sb->d >= 0) H5Dclose(sb->d);
        sb->open = j;
        sb->h = checksum_block(sb->h, v);
        sb->d = wf_h5_create_u8(sb->g, v->name, v->size, "1", "raw bytes of a state block", err);
        if (sb->d < 0) return WF_ESYS;
    }
    const unsigned char *p = (const unsigned char *)v->data + lo;
    sb->h = wf_fnv1a64(sb->h, p, hi - lo);
    return wf_h5_write_u8_at(sb->d, lo, hi - lo, p, err);
}

/* Blocks [j0, j1) of vars whole, from their memory (one process). */
static int walk_whole(const WfStateVar *vars, size_t j0, size_t j1, WfStatePieceFn put, void *ctx, WfError *err)
{
    int rc = 0;
    for (size_t j = j0; !rc && j < j1; j++) rc = put(ctx, j, 0, vars[j].size, err);
    return rc;
}

int wf_ckpt_save(const char *result, const char *kind, const WfScenario *sc, int64_t steps_done,
                 const char *const *cursor, size_t n_cur, const WfCkptSeries *sp, size_t ns, WfStateVar *vars,
                 size_t n_vars, WfCkptWalk walk, void *walk_ctx, WfError *err)
{
    char ck[CKPT_PATH_MAX], tmp[CKPT_PATH_MAX], sum[32], attr[96];
    WfCkptCursor cur[8];
    int rc = ckpt_paths(result, ck, tmp, err);
    if (!rc && n_cur > 8) rc = wf_err(err, WF_ESYS, "checkpoint: %zu cursors, at most 8", n_cur);
    for (size_t i = 0; !rc && i < n_cur; i++) {
        cur[i] = (WfCkptCursor){cursor[i], 0};
        for (size_t j = 0; j < ns; j++)
            if (sp[j].cursor == i) cur[i].rows = (int64_t)(sp[j].s->rows + sp[j].s->n_pend);
    }
    size_t n_engine = n_vars;
    if (!rc) rc = pending_blocks(sp, ns, vars, &n_vars, err);
    /* the engine's blocks must reach the walk's other processes even when this one cannot write */
    if (rc) return walk ? walk(walk_ctx, vars, n_engine, NULL, NULL, &(WfError){0}), rc : rc;
    errno = 0;
    hid_t f = H5Fcreate(tmp, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (f < 0)
        rc = wf_err(err, WF_ESYS, "%s: cannot create the checkpoint (%s)", tmp, errno ? strerror(errno) : "HDF5");
    if (!rc)
        rc = wf_h5_attr_str(f, "kind", kind, err) || wf_h5_attr_str(f, "scenario_path", sc->path, err) ||
             wf_h5_attr_i64(f, "steps_done", steps_done, err) ||
             wf_h5_scalar_str(f, "scenario_text", sc->text, "scenario file verbatim", err) ||
             wf_h5_scalar_str(f, "overrides", sc->overrides, "--set assignments, one per line", err);
    for (size_t i = 0; !rc && i < n_cur; i++)
        rc = cursor_attr(cur[i].name, attr, sizeof attr, err) || wf_h5_attr_i64(f, attr, cur[i].rows, err);
    SaveBlocks sb = {.vars = vars, .d = H5I_INVALID_HID, .h = checksum_head(kind, sc, steps_done, cur, n_cur)};
    sb.g = rc ? H5I_INVALID_HID : wf_h5_group(f, "state", err);
    if (!rc && sb.g < 0) rc = WF_ESYS;
    /* the engine's blocks (a piece at a time on a split ring: every process walks them), then the pending rows */
    WfError lost = {0};
    int wrc = walk ? walk(walk_ctx, vars, n_engine, rc ? NULL : save_piece, &sb, rc ? &lost : err)
                   : rc ? 0 : walk_whole(vars, 0, n_engine, save_piece, &sb, err);
    if (!rc) rc = wrc;
    if (!rc) rc = walk_whole(vars, n_engine, n_vars, save_piece, &sb, err);
    if (sb.d >= 0) H5Dclose(sb.d);
    if (sb.g >= 0) H5Gclose(sb.g);
    if (!rc) {
        snprintf(sum, sizeof sum, "%016llx", (unsigned long long)sb.h);
        rc = wf_h5_attr_str(f, "checksum", sum, err);
    }
    if (f < 0) return rc;
    if (H5Fclose(f) < 0 && !rc) rc = wf_err(err, WF_ESYS, "HDF5: close failed (disk full?)");
    if (rc) {
        unlink(tmp);
        return wf_err_prefix(err, "%s: ", tmp);
    }
    if (rename(tmp, ck) != 0) {
        rc = wf_err(err, WF_ESYS, "rename %s -> %s: %s", tmp, ck, strerror(errno));
        unlink(tmp);
    }
    return rc;
}

/* A state block's bytes into its memory, added to the checksum *h; a block of which this process keeps only
 * [lo, hi) (WfStateVar.partial) is read whole in pieces of at most `piece` bytes, each summed and only its part in
 * [lo, hi) kept, so the whole checkpoint is still checked. */
static herr_t read_block(hid_t d, hid_t fsp, const WfStateVar *v, unsigned char *buf, size_t piece, uint64_t *h)
{
    if (!v->partial) {
        herr_t e = H5Dread(d, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, v->data);
        if (e >= 0) *h = wf_fnv1a64(*h, v->data, v->size);
        return e;
    }
    for (size_t off = 0; off < v->size; off += piece) {
        hsize_t o = off, cnt = v->size - off < piece ? v->size - off : piece;
        hid_t msp = H5Screate_simple(1, &cnt, NULL);
        herr_t e = msp < 0 || H5Sselect_hyperslab(fsp, H5S_SELECT_SET, &o, NULL, &cnt, NULL) < 0
                       ? -1 : H5Dread(d, H5T_NATIVE_UINT8, msp, fsp, H5P_DEFAULT, buf);
        if (msp >= 0) H5Sclose(msp);
        if (e < 0) return e;
        *h = wf_fnv1a64(*h, buf, cnt);
        size_t a = off > v->lo ? off : v->lo, b = off + cnt < v->hi ? off + cnt : v->hi;
        if (a < b) memcpy((unsigned char *)v->data + a, buf + (a - off), b - a);
    }
    return 0;
}

/* The /state group must hold exactly the blocks the engine lists, each of exactly its size; *h: the checksum of
 * the head, then of every block read. */
static int load_blocks(hid_t f, const char *ck, const WfStateVar *vars, size_t n_vars, uint64_t *h, WfError *err)
{
    hid_t g = H5Lexists(f, "state", H5P_DEFAULT) > 0 ? H5Gopen2(f, "state", H5P_DEFAULT) : H5I_INVALID_HID;
    H5G_info_t info;
    if (g < 0 || H5Gget_info(g, &info) < 0) {
        if (g >= 0) H5Gclose(g);
        return wf_err(err, WF_EINPUT, "%s: no state group: damaged checkpoint", ck);
    }
    int rc = 0;
    enum { PIECE = 1 << 16 }; /* small: a process keeps a share of a split ring's blocks */
    unsigned char *buf = NULL;
    for (size_t i = 0; i < n_vars; i++)
        if (vars[i].partial && !buf && !(buf = malloc(PIECE))) rc = wf_err(err, WF_ESYS, "out of memory");
    if (!rc && info.nlinks != n_vars)
        rc = wf_err(err, WF_EINPUT, "%s: %llu state blocks where this run has %zu: a checkpoint of another "
                    "scenario or version", ck, (unsigned long long)info.nlinks, n_vars);
    for (size_t i = 0; !rc && i < n_vars; i++) {
        const char *name = vars[i].name;
        hid_t d = H5Lexists(g, name, H5P_DEFAULT) > 0 ? H5Dopen2(g, name, H5P_DEFAULT) : H5I_INVALID_HID;
        hid_t sp = d >= 0 ? H5Dget_space(d) : H5I_INVALID_HID;
        hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
        *h = checksum_block(*h, &vars[i]);
        if (d < 0 || np != (hssize_t)vars[i].size)
            rc = wf_err(err, WF_EINPUT, "%s: state block '%s' is missing or has %lld bytes, this scenario needs %zu",
                        ck, name, (long long)np, vars[i].size);
        else if (vars[i].size && read_block(d, sp, &vars[i], buf, PIECE, h) < 0)
            rc = wf_err(err, WF_EINPUT, "%s: cannot read state block '%s': damaged checkpoint", ck, name);
        if (sp >= 0) H5Sclose(sp);
        if (d >= 0) H5Dclose(d);
    }
    free(buf);
    H5Gclose(g);
    return rc;
}

static int read_cursors(hid_t f, const char *ck, WfCkptCursor *cur, size_t n_cur, WfError *err)
{
    char attr[96];
    int rc = 0;
    for (size_t i = 0; !rc && i < n_cur; i++) {
        rc = cursor_attr(cur[i].name, attr, sizeof attr, err);
        if (!rc) rc = wf_h5_read_attr_i64(f, ck, attr, &cur[i].rows, err);
        if (!rc && cur[i].rows < 0) rc = wf_err(err, WF_EINPUT, "%s: %s = %lld < 0", ck, attr, (long long)cur[i].rows);
    }
    return rc;
}

int wf_ckpt_restore(const char *result, const char *kind, const WfScenario *sc, const char *const *cursor,
                    size_t n_cur, const WfCkptSeries *sp, size_t ns, WfStateVar *vars, size_t n_vars, WfError *err)
{
    char ck[CKPT_PATH_MAX], tmp[CKPT_PATH_MAX], have_kind[16], stored[32], sum[32];
    WfCkptCursor cur[8];
    int rc = ckpt_paths(result, ck, tmp, err);
    if (!rc && n_cur > 8) rc = wf_err(err, WF_ESYS, "checkpoint: %zu cursors, at most 8", n_cur);
    if (rc) return rc;
    for (size_t i = 0; i < n_cur; i++) cur[i] = (WfCkptCursor){cursor[i], 0};
    wf_h5_library_init();
    hid_t f = H5Fopen(ck, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return wf_err(err, WF_EINPUT, "%s: not a readable checkpoint (damaged?)", ck);
    int64_t steps_done = 0;
    rc = wf_h5_read_attr_str(f, ck, "kind", have_kind, sizeof have_kind, err);
    if (!rc && strcmp(have_kind, kind) != 0)
        rc = wf_err(err, WF_EINPUT, "%s: a checkpoint of a %s run, but the scenario it holds is a %s (damaged or "
                    "edited checkpoint)", ck, have_kind, kind);
    if (!rc) rc = wf_h5_read_attr_str(f, ck, "checksum", stored, sizeof stored, err);
    if (!rc) rc = wf_h5_read_attr_i64(f, ck, "steps_done", &steps_done, err);
    if (!rc) rc = read_cursors(f, ck, cur, n_cur, err);
    /* The pending rows' sizes follow from the cursors: the series know their file rows and pending rows. */
    for (size_t i = 0; !rc && i < ns; i++) {
        char path[sizeof sp[i].s->name];
        int w = snprintf(path, sizeof path, "%s/%s", sp[i].group, sp[i].col->name);
        if (w < 0 || (size_t)w >= sizeof path) {
            rc = wf_err(err, WF_ESYS, "dataset path too long: %s/%s", sp[i].group, sp[i].col->name);
            break;
        }
        rc = wf_h5_series_resume(sp[i].s, path, sp[i].cols, sp[i].fixed_rows, sp[i].chunk_rows, sp[i].compress,
                                 (hsize_t)cur[sp[i].cursor].rows, err);
    }
    /* The scenario was rebuilt from this file's text and overrides: the sum covers them through sc, and the kind
     * through the one expected. */
    uint64_t h = checksum_head(kind, sc, steps_done, cur, n_cur);
    if (!rc) rc = pending_blocks(sp, ns, vars, &n_vars, err);
    if (!rc) rc = load_blocks(f, ck, vars, n_vars, &h, err);
    H5Fclose(f);
    if (rc) return rc;
    snprintf(sum, sizeof sum, "%016llx", (unsigned long long)h);
    if (strcmp(sum, stored) != 0)
        return wf_err(err, WF_EINPUT, "%s: checksum %s does not match the contents (%s): damaged checkpoint", ck,
                      stored, sum);
    return 0;
}

/* FILE.h5.partial, checked to be the result of the run `sc`. */
static int reopen_partial(const char *result, const WfScenario *sc, WfH5File **out, WfError *err)
{
    WfH5File *hf = NULL;
    int rc = wf_h5_reopen(result, &hf, err);
    if (rc) return rc;
    char *text = NULL, *ov = NULL;
    rc = wf_h5_read_scalar_str(hf->fid, hf->partial, "meta/scenario_text", &text, err);
    if (!rc) rc = wf_h5_read_scalar_str(hf->fid, hf->partial, "meta/overrides", &ov, err);
    if (!rc && (strcmp(text, sc->text) != 0 || strcmp(ov, sc->overrides) != 0))
        rc = wf_err(err, WF_EINPUT, "%s is the result of another run than %s.ckpt: its /meta/scenario_text or "
                    "/meta/overrides differ", hf->partial, result);
    free(text);
    free(ov);
    if (rc) {
        wf_h5_abandon(&hf, 0);
        return rc;
    }
    *out = hf;
    return 0;
}

int wf_ckpt_reopen(const char *result, const WfScenario *sc, const WfCkptSeries *sp, size_t ns, WfH5File **out,
                   WfError *err)
{
    WfH5File *hf = NULL;
    int rc = reopen_partial(result, sc, &hf, err);
    for (size_t i = 0; !rc && i < ns; i++) rc = wf_h5_series_reopen(hf->fid, sp[i].s, err);
    if (rc) {
        if (hf) {
            wf_err_prefix(err, "%s: ", hf->partial);
            wf_h5_abandon(&hf, 0);
        }
        return rc;
    }
    *out = hf;
    return 0;
}

void wf_ckpt_remove(const char *result)
{
    char ck[CKPT_PATH_MAX], tmp[CKPT_PATH_MAX];
    if (!ckpt_paths(result, ck, tmp, NULL)) unlink(ck);
}

void wf_checkpoint_info_free(WfCheckpointInfo *ck)
{
    free(ck->scenario_text);
    free(ck->overrides);
    ck->scenario_text = ck->overrides = NULL;
}

int wf_checkpoint_read_info(const char *result, WfCheckpointInfo *ck, WfError *err)
{
    memset(ck, 0, sizeof *ck);
    char path[CKPT_PATH_MAX], tmp[CKPT_PATH_MAX];
    int rc = ckpt_paths(result, path, tmp, err);
    if (rc) return rc;
    wf_h5_library_init();
    struct stat st;
    if (stat(result, &st) == 0) return wf_err(err, WF_EINPUT, "%s is complete: nothing to resume", result);
    if (stat(path, &st) != 0)
        return wf_err(err, WF_EINPUT, "%s: no checkpoint (runs leave one when interrupted, or with --checkpoint-every)",
                      path);
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return wf_err(err, WF_EINPUT, "%s: not a readable checkpoint (damaged?)", path);
    if (H5Aexists(f, "kind") <= 0)
        rc = wf_err(err, WF_EINPUT, "%s: not a checkpoint of this wavefuel version (no attribute 'kind')", path);
    if (!rc) rc = wf_h5_read_attr_str(f, path, "kind", ck->kind, sizeof ck->kind, err);
    if (!rc && strcmp(ck->kind, "ring") != 0 && strcmp(ck->kind, "corridor") != 0)
        rc = wf_err(err, WF_EINPUT, "%s: kind '%s' is neither ring nor corridor (damaged checkpoint)", path, ck->kind);
    if (!rc) rc = wf_h5_read_attr_str(f, path, "scenario_path", ck->scenario_path, sizeof ck->scenario_path, err);
    if (!rc) rc = wf_h5_read_scalar_str(f, path, "scenario_text", &ck->scenario_text, err);
    if (!rc) rc = wf_h5_read_scalar_str(f, path, "overrides", &ck->overrides, err);
    H5Fclose(f);
    if (rc) wf_checkpoint_info_free(ck);
    return rc;
}
