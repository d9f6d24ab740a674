/* Numeric CSV reader: strict per-field parsing with file:line:field messages, no quoting. */
#include "wavefuel/csv.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Longest line accepted. Numeric rows are short; the bound keeps a binary file or a device without newlines
 * (/dev/zero) from being read into memory as one endless line. */
enum { MAX_LINE = 1 << 20 };

void wf_csv_free(WfCsv *csv)
{
    if (!csv) return;
    free(csv->data);
    free(csv->line);
    memset(csv, 0, sizeof *csv);
}

static char *trim(char *s)
{
    while (*s == ' ' || *s == '\t') s++;
    size_t n = strlen(s);
    while (n && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r' || s[n - 1] == '\n')) s[--n] = '\0';
    return s;
}

/* Reads one line (with its '\n', if any) into *buf, NUL-terminated. Returns its length, 0 at end of file,
 * -1 when the line exceeds MAX_LINE bytes and -2 when out of memory. Embedded NUL bytes are kept (the caller
 * rejects them). */
static long read_line(FILE *f, char **buf, size_t *cap)
{
    size_t len = 0;
    int ch;
    while ((ch = getc_unlocked(f)) != EOF) {
        if (len + 2 > *cap) {
            if (*cap >= MAX_LINE + 2) return -1;
            size_t ncap = *cap ? 2 * *cap : 256;
            if (ncap > MAX_LINE + 2) ncap = MAX_LINE + 2;
            char *p = realloc(*buf, ncap);
            if (!p) return -2;
            *buf = p;
            *cap = ncap;
        }
        (*buf)[len++] = (char)ch;
        if (ch == '\n') break;
    }
    if (len) (*buf)[len] = '\0';
    return (long)len;
}

/* A field as shown in a message: at most 40 characters, "..." when cut. */
static const char *shown_field(const char *field, char *out, size_t len)
{
    int w = snprintf(out, len, "%.40s", field);
    if (w >= 0 && strlen(field) > 40) snprintf(out + w, len - (size_t)w, "...");
    return out;
}

static int grow(WfCsv *c, size_t *cap, WfError *err)
{
    size_t ncap = *cap ? 2 * *cap : 1024;
    double *d = realloc(c->data, ncap * c->n_cols * sizeof *d);
    if (!d) return wf_err(err, WF_ESYS, "out of memory reading a table");
    c->data = d;
    int *l = realloc(c->line, ncap * sizeof *l);
    if (!l) return wf_err(err, WF_ESYS, "out of memory reading a table");
    c->line = l;
    *cap = ncap;
    return 0;
}

/* A header line: its column names must be `names` (when given), n_cols of them. s is modified. */
static int check_header(char *s, size_t n_cols, const char *const *names, const char *shown, int lineno, WfError *err)
{
    char fs[64];
    size_t col = 0;
    /* Split at every comma by hand (strtok_r would skip empty names and accept "v,,a,theta"). */
    for (char *tok = s, *next = NULL; tok; tok = next, col++) {
        char *comma = strchr(tok, ',');
        next = comma ? comma + 1 : NULL;
        if (comma) *comma = '\0';
        if (names && col < n_cols && strcmp(trim(tok), names[col]) != 0)
            return wf_err(err, WF_EINPUT, "%s:%d: header column %zu is '%s', expected '%s'", shown, lineno, col + 1,
                          shown_field(trim(tok), fs, sizeof fs), names[col]);
    }
    if (col != n_cols)
        return wf_err(err, WF_EINPUT, "%s:%d: header has %zu columns, expected %zu", shown, lineno, col, n_cols);
    return 0;
}

/* A data line into row[n_cols]: exactly n_cols finite numbers. s is modified. */
static int parse_row(char *s, double *row, size_t n_cols, const char *const *names, const char *shown, int lineno,
                     WfError *err)
{
    char fs[64];
    size_t col = 0;
    char *p = s;
    for (;;) {
        char *comma = strchr(p, ',');
        if (comma) *comma = '\0';
        if (col >= n_cols)
            return wf_err(err, WF_EINPUT, "%s:%d: field %zu: more than %zu fields", shown, lineno, col + 1, n_cols);
        char *field = trim(p);
        if (wf_parse_double(field, &row[col]))
            return wf_err(err, WF_EINPUT, "%s:%d: field %zu%s%s%s: expected a finite number (got '%s')", shown, lineno,
                          col + 1, names ? " (" : "", names ? names[col] : "", names ? ")" : "",
                          shown_field(field, fs, sizeof fs));
        col++;
        if (!comma) break;
        p = comma + 1;
    }
    if (col != n_cols)
        return wf_err(err, WF_EINPUT, "%s:%d: %zu fields, expected %zu%s%s", shown, lineno, col, n_cols,
                      names ? " after field " : "", names ? names[col - 1] : "");
    return 0;
}

int wf_csv_read(const char *path, size_t n_cols, const char *const *names, WfCsv *out, WfError *err)
{
    memset(out, 0, sizeof *out);
    out->n_cols = n_cols;
    int is_stdin = strcmp(path, "-") == 0;
    const char *shown = is_stdin ? "<stdin>" : path;
    FILE *f = is_stdin ? stdin : fopen(path, "r");
    if (!f) return wf_err(err, WF_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    /* fopen() succeeds on a directory and only the read fails (EISDIR): that is the user's mistake (exit 2). */
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
        if (!is_stdin) fclose(f);
        return wf_err(err, WF_EINPUT, "%s: is a directory, not a table", shown);
    }
    char *buf = NULL;
    size_t bufcap = 0, cap = 0;
    int lineno = 0, rc = 0, seen_data = 0;
    long len;
    while (!rc && (len = read_line(f, &buf, &bufcap)) > 0) {
        if (lineno == INT_MAX) {
            rc = wf_err(err, WF_EINPUT, "%s: more than %d lines", shown, INT_MAX);
            break;
        }
        lineno++;
        int has_nul = (size_t)len != strlen(buf);
        char *s = trim(buf);
        if (lineno == 1 && (unsigned char)s[0] == 0xEF && (unsigned char)s[1] == 0xBB && (unsigned char)s[2] == 0xBF)
            s += 3; /* UTF-8 byte-order mark written by spreadsheet programs */
        if (has_nul)
            rc = wf_err(err, WF_EINPUT, "%s:%d: contains a NUL byte: not a text table", shown, lineno);
        else if (!*s || *s == '#')
            continue;
        else if (strchr(s, '\r'))
            rc = wf_err(err, WF_EINPUT, "%s:%d: carriage return inside a line: lines must end in LF or CRLF", shown,
                        lineno);
        else if (strchr(s, '"'))
            rc = wf_err(err, WF_EINPUT, "%s:%d: quoted fields are not supported: numbers only", shown, lineno);
        /* Header: only before the first data row, recognised by a first field that does not start like a number
         * (a digit, sign or point): "0x10" or "1e999" on the first row is a bad number, not a header. */
        else if (!seen_data && !out->had_header && !strchr("0123456789+-.", *s)) {
            out->had_header = 1;
            rc = check_header(s, n_cols, names, shown, lineno, err);
        } else {
            seen_data = 1;
            if (out->n_rows == cap) rc = grow(out, &cap, err);
            if (!rc) rc = parse_row(s, out->data + out->n_rows * n_cols, n_cols, names, shown, lineno, err);
            if (!rc) out->line[out->n_rows++] = lineno;
        }
    }
    if (!rc && len == -1)
        rc = wf_err(err, WF_EINPUT, "%s:%d: line longer than %d bytes: not a numeric table", shown, lineno + 1,
                    (int)MAX_LINE);
    else if (!rc && len == -2)
        rc = wf_err(err, WF_ESYS, "out of memory reading %s", shown);
    else if (!rc && ferror(f))
        rc = wf_err(err, WF_ESYS, "%s: read error: %s", shown, strerror(errno));
    free(buf);
    if (!is_stdin) fclose(f);
    if (rc) wf_csv_free(out);
    return rc;
}

int wf_csv_check_ranges(const WfCsv *csv, const char *path, const char *const *names, const WfRange *const *ranges,
                        WfError *err)
{
    const char *shown = strcmp(path, "-") == 0 ? "<stdin>" : path;
    for (size_t r = 0; r < csv->n_rows; r++)
        for (size_t c = 0; c < csv->n_cols; c++) {
            double x = csv->data[r * csv->n_cols + c];
            if (!ranges[c] || (x >= ranges[c]->min && x <= ranges[c]->max)) continue;
            char where[1200];
            snprintf(where, sizeof where, "%s:%d: field %zu%s%s%s", shown, csv->line[r], c + 1, names ? " (" : "",
                     names ? names[c] : "", names ? ")" : "");
            return wf_range_check(ranges[c], x, where, err);
        }
    return 0;
}
